"""Loading UDAformer weights: the official release (``checkpoint_489_epoch.pkl``, ``check['model']``) or a bare
state dict, through murk's safe checkpoint I/O (:mod:`murk.models.checkpoint_io`).

The official file is ``{'model': state_dict, 'optimizer': <the torch.optim.Adam object itself>, 'epoch': int}``
with CUDA tensors and no ``module.`` prefix. The pickled optimiser object makes ``weights_only=True`` refuse
the file: murk says so and loads it only with ``trust=True`` (``--trust-checkpoint``), keeping ``['model']``.
:func:`save_weights_only` writes a copy that later loads without trust. murk never bundles or downloads these
weights (they carry no licence); see ``docs/baselines.md`` for where users get them.
"""

from __future__ import annotations

import os
from pathlib import Path

import torch

from murk.io.atomic import atomic_path
from murk.models.checkpoint_io import check_state_dict, extract_state_dict, strip_prefixes, torch_load
from murk.models.udaformer.network import UDAformer, UDAformerConfig

HINT = (
    "The official UDAformer checkpoint pickles its Adam optimiser object next to the weights; murk keeps only "
    "['model']. To get a file that loads without trust, run once: murk.models.udaformer.save_weights_only(SRC, DST, "
    "trust=True)."
)
_PREFIXES = ("module.", "_orig_mod.")


def read_udaformer_state(path: str | Path, *, trust: bool = False) -> dict[str, torch.Tensor]:
    """The UDAformer state dict of ``path`` (``['model']``, ``['state_dict']`` or a bare state dict; ``module.``
    prefixes stripped), checked against the official names and shapes.

    Raises:
        InputFileError: missing/unreadable file, a pickle ``weights_only`` refuses (naming ``--trust-checkpoint``
            and why), or names/shapes that are not UDAformer's.
    """
    path = Path(path)
    obj = torch_load(path, trust=trust, hint=HINT)
    raw, _ = extract_state_dict(obj, path, ("model", "state_dict"), "UDAformer")
    state = {strip_prefixes(k, _PREFIXES): v for k, v in raw.items()}
    with torch.device("meta"):
        expected = {k: tuple(v.shape) for k, v in UDAformer().state_dict().items()}
    check_state_dict(path, state, expected, "UDAformer")
    return state


def load_udaformer(path: str | Path, *, trust: bool = False, device: str | torch.device = "cpu") -> UDAformer:
    """The official UDAformer with the weights of ``path`` (strict), float32, in eval mode on ``device``.

    Raises:
        InputFileError: see :func:`read_udaformer_state`.
    """
    state = read_udaformer_state(path, trust=trust)
    with torch.device("meta"):  # UDAformer has no buffers: every tensor comes from the file
        model = UDAformer(UDAformerConfig())
    model.load_state_dict({k: v.float() for k, v in state.items()}, strict=True, assign=True)
    return model.to(device).eval()


def save_weights_only(src: str | Path, dst: str | Path, *, trust: bool = False) -> Path:
    """Write the weights of ``src`` as ``{'model': state_dict}`` (float32, CPU) to ``dst``, atomically: a file
    that loads with ``weights_only=True``. Use ``trust=True`` once on the official file you downloaded.

    Raises:
        InputFileError: ``src`` cannot be read (see :func:`read_udaformer_state`).
    """
    state = read_udaformer_state(src, trust=trust)
    dst = Path(dst)
    with atomic_path(dst) as tmp:
        with open(tmp, "wb") as f:
            torch.save({"model": {k: v.float().contiguous() for k, v in state.items()}}, f)
            f.flush()
            os.fsync(f.fileno())
    return dst
