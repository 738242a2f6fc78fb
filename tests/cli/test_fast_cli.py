"""A fast command line (issue 29): importing the CLI, --help, --version and usage errors of every command do not
import torch, onnxruntime, av, rosbags or ray. Each check runs in a fresh interpreter and reads ``sys.modules``
(how long it takes is measured by benchmarks/bench_cli.py, never here)."""

from __future__ import annotations

import json
import subprocess
import sys
import textwrap
from pathlib import Path

from murk.data import sample_rgbd_dir, sample_underwater_images

HEAVY = ("torch", "onnxruntime", "av", "rosbags", "ray")


def _fresh(code: str) -> str:
    """stdout of ``code`` run by a new interpreter (nothing imported yet)."""
    done = subprocess.run([sys.executable, "-c", textwrap.dedent(code)], capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    return done.stdout


def test_importing_the_cli_imports_no_heavy_module() -> None:
    out = _fresh(
        f"""
        import sys
        import murk.cli
        import murk.cli.main
        import murk.__main__
        print(sorted(m for m in {HEAVY!r} if m in sys.modules))
        """
    )
    assert out.strip() == "[]"


def test_a_synth_command_imports_neither_pydantic_nor_pillow(tmp_path: Path) -> None:
    """What a ``murk synth`` command imports beyond its work: typer 0.29+ builds a pydantic adapter per option
    (+75 ms per command; pyproject keeps typer below it), and PNG and JPEG headers are parsed without Pillow
    (murk.io.header). The sample RGB-D folder holds JPEG and PNG colour images and PNG depth maps."""
    out = _fresh(
        f"""
        import atexit, sys
        atexit.register(lambda: print(sorted(m for m in ("pydantic", "PIL", "torch", "scipy") if m in sys.modules)))
        sys.argv = ["murk", "synth", {str(sample_rgbd_dir())!r}, {str(tmp_path / "out")!r}, "--variants", "1", "-q"]
        from murk.cli.main import main
        main()
        """
    )
    assert out.strip().splitlines()[-1] == "[]"
    assert len(list((tmp_path / "out" / "degraded").iterdir())) >= 2


def test_usage_errors_of_every_command_answer_without_torch(tmp_path: Path) -> None:
    img = str(sample_underwater_images()[0])
    rgbd = str(sample_rgbd_dir())
    missing, out = str(tmp_path / "missing"), str(tmp_path / "out")
    bad = tmp_path / "bad.yaml"
    bad.write_text("stepz: 3\n")
    cases = [
        (["--help"], 0, "synth"),
        (["--version"], 0, "murk "),
        (["synth", "--help"], 0, "--depth-scale"),
        (["synth", rgbd, out, "--depth-scale", "0"], 2, "--depth-scale: expected a finite number > 0"),
        (["synth", rgbd, out, "--stages", "basic,foo"], 2, "unknown stage(s) 'foo'"),
        (["synth", missing, out], 2, "not found"),
        (["synth", rgbd, out, "--shard", "3/2"], 2, "expected 0 <= i < N"),
        (["scenes", out, "--size", "0x4"], 2, "--size: expected WxH"),
        (["snow", "extract", img, "--out", f"{out}.npz", "--method", "foo"], 2, "expected 'threshold'"),
        (["enhance", img, "--out", out, "--method", "jointd"], 2, "did you mean 'jointid'"),
        (["enhance", img, "--out", out, "--method", "post?lamda=1"], 2, "did you mean 'lam'"),
        (["enhance", img, "--out", out, "--device", "gpu"], 2, "--device: expected cpu, cuda or cuda:N"),
        (["enhance", missing, "--out", out], 2, "not found"),
        (["enhance", img, "--out", out, "--method", "jointid", "--checkpoint", missing], 2, "checkpoint not found"),
        (["live", img, "--method", "jointd", "--port", "0"], 2, "did you mean 'jointid'"),
        (["live", img, "--method", "jointid?checkpoint=" + missing, "--port", "0"], 2, "checkpoint not found"),
        (["eval", img, "--preset", "foo"], 2, "--preset: expected a UIQM preset"),
        (["compare", img, "--out", out, "--method", "post", "--method", "jointd"], 2, "did you mean 'jointid'"),
        (["compare", img, "--out", out, "--method", "post", "--uiqm-preset", "foo"], 2, "--uiqm-preset: expected"),
        (["study", str(bad), "--out", out], 2, "unknown key(s) stepz"),
        (["train", "--config", str(bad)], 2, "unknown key(s) stepz"),
        (["train", "--config", "configs/train-tiny-cpu.yaml", "--data", missing, "--out", out], 2, "data.source"),
        (["export", "-c", f"{missing}.pt", "-o", f"{out}.onnx"], 2, "checkpoint not found"),
        (["export", "-c", img, "-o", f"{out}.onnx", "--model", "foo"], 2, "--model: expected auto"),
        (["demo", "--help"], 0, "--quick"),
    ]
    got = _fresh(
        f"""
        import json, os, sys
        from typer.testing import CliRunner
        from murk.cli.main import app
        os.chdir({str(Path(__file__).resolve().parents[2])!r})
        rows = []
        for args, code, text in {cases!r}:
            r = CliRunner().invoke(app, args)
            rows.append([r.exit_code, text in r.output, r.output[-300:],
                         sorted(m for m in {HEAVY!r} if m in sys.modules)])
        print(json.dumps(rows))
        """
    )
    rows = json.loads(got)
    for (args, code, _), (exit_code, said, output, heavy) in zip(cases, rows, strict=True):
        assert (exit_code, said) == (code, True), (args, output)
        assert heavy == [], (args, heavy)  # nothing heavy so far, in this interpreter, after all earlier cases
    assert not Path(out).exists()  # no usage error wrote anything


def test_a_classical_enhance_command_does_not_import_torch(tmp_path: Path) -> None:
    """``murk enhance --method colorbalance`` (numpy and OpenCV) runs without importing torch: it neither pays
    torch's start-up nor books it in its restore step (issue 47)."""
    images = sample_underwater_images()[:1]
    out = _fresh(
        f"""
        import atexit, sys
        atexit.register(lambda: print(sorted(m for m in {HEAVY!r} if m in sys.modules)))
        sys.argv = ["murk", "enhance", {str(images[0].parent)!r}, "--out", {str(tmp_path / "out")!r},
                    "--method", "colorbalance", "-q"]
        from murk.cli.main import main
        main()
        """
    )
    assert out.strip().splitlines()[-1] == "[]"
    assert len(list((tmp_path / "out").glob("*.jpg"))) == 4  # the folder of images[0] (funie_euvp) holds 4


def test_classical_methods_run_without_torch_in_enhance_live_and_compare(tmp_path: Path) -> None:
    """Every classical method, a chain of them, and ``post`` on the CPU (its torch twin is imported only when
    used) restore through ``murk enhance``, ``murk live`` and ``murk compare`` without importing torch."""
    from testkit.video import make_video

    folder = tmp_path / "in"
    folder.mkdir()
    for src in sample_underwater_images()[3:5]:  # 256x256 and 640x480
        (folder / src.name).write_bytes(src.read_bytes())
    clip = make_video(tmp_path / "clip.avi", n=3, fps=30.0)
    methods = ["colorbalance", "greyworld", "clahe", "udcp", "post", "greyworld+clahe", "colorbalance+post"]
    cases = [["enhance", str(folder), "--out", str(tmp_path / m), "--method", m, "-q"] for m in methods]
    cases.append(["live", str(clip), "--method", "greyworld+post", "--port", "0", "--exit-at-end", "-q"])
    compare = ["compare", str(folder), "--out", str(tmp_path / "cmp"), "--method", "colorbalance", "--method", "post"]
    cases.append(compare)
    got = _fresh(
        f"""
        import json, sys
        from typer.testing import CliRunner
        from murk.cli.main import app
        rows = []
        for args in {cases!r}:
            r = CliRunner().invoke(app, args)
            rows.append([r.exit_code, r.output[-300:], sorted(m for m in {HEAVY!r} if m in sys.modules)])
        print(json.dumps(rows))
        """
    )
    for args, (exit_code, output, heavy) in zip(cases, json.loads(got), strict=True):
        assert exit_code == 0, (args, output)
        assert heavy == [], (args, heavy)
    for m in methods:
        assert sorted(p.name for p in (tmp_path / m).glob("*.jpg")) == sorted(p.name for p in folder.iterdir()), m
    assert (tmp_path / "cmp" / "metrics.json").is_file()
