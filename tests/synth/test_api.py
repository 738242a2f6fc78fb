from __future__ import annotations

import subprocess
import sys

import numpy as np

import murk
from murk.data import default_snow_bank
from murk.synth.config import SynthConfig
from murk.synth.params import sample_variant


def test_synthesize_is_sample_then_render(rng: np.random.Generator) -> None:
    clean = rng.random((30, 40, 3)).astype(np.float32)
    depth = (rng.random((30, 40)) * 5 + 0.5).astype(np.float32)
    res = murk.synthesize(clean, depth, rng=9)
    same = murk.render(clean, depth, sample_variant(9, SynthConfig()))
    assert res.params == same.params
    assert res.degraded.tobytes() == same.degraded.tobytes()


def test_synthesize_with_snow_uses_the_default_bank(rng: np.random.Generator) -> None:
    clean = rng.random((30, 40, 3)).astype(np.float32)
    cfg = SynthConfig(stages=("basic", "forward_scatter", "marine_snow"))
    res = murk.synthesize(clean, np.full((30, 40), 2.0, np.float32), rng=1, config=cfg)
    assert res.snow_alpha is not None and res.snow_alpha.max() > 0
    assert res.params.snow.bank_id == murk.load_bank(default_snow_bank()).bank_id


def test_import_murk_is_light() -> None:
    code = "import sys, murk; print('torch' in sys.modules, 'cv2' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout.split()
    assert out == ["False", "False"]


def test_a_numpy_synthesis_job_imports_neither_torch_nor_scipy(tmp_path) -> None:  # type: ignore[no-untyped-def]
    """Every stage on the sample RGB-D pairs (the Redwood depth has holes, filled by OpenCV's distance transform):
    a worker of such a job starts without torch (1.5 s) and scipy (0.1 s) (issue 29, worker start)."""
    code = (
        "import sys\n"
        "from murk.data import sample_rgbd_dir\n"
        "from murk.synth.config import SynthConfig\n"
        "from murk.synth.runner import synthesize\n"
        "cfg = SynthConfig(stages=('basic', 'forward_scatter', 'marine_snow'), variants=1)\n"
        f"summary = synthesize({str(tmp_path / 'out')!r}, cfg, rgbd=sample_rgbd_dir())\n"
        "print(summary.processed, 'torch' in sys.modules, 'scipy' in sys.modules)"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert out.returncode == 0, out.stderr
    variants, torch_seen, scipy_seen = out.stdout.split()
    assert int(variants) >= 2 and (torch_seen, scipy_seen) == ("False", "False")


def test_every_top_level_export_resolves() -> None:
    for name in murk.__all__:
        assert getattr(murk, name) is not None, name
    assert murk.create_restorer("post").name == "post"
    assert "lam" in murk.restorer_options("post")
    assert "uiqm" in dir(murk)
