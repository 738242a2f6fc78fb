"""Loading URSCT-SESR weights: the official release (``*_bestSSIM.pth``, ``checkpoint['state_dict']``) or a bare
state dict, through murk's safe checkpoint I/O (:mod:`murk.models.checkpoint_io`).

Official files are ``{'epoch', 'state_dict', 'PSNR', 'SSIM'}`` (+ ``'optimizer'`` state for per-epoch files),
keys possibly prefixed ``module.`` (DataParallel). The state dict carries 84 buffers that depend on the input
size only (``relative_position_index``, ``attn_mask``): they are dropped (the index is checked against the
architecture's) and the 899 learnable tensors load strictly, so a checkpoint of any IMG_SIZE loads into a
model for any other. murk never bundles or downloads these weights; see ``docs/baselines.md``.
"""

from __future__ import annotations

from pathlib import Path

import torch

from murk.errors import InputFileError
from murk.models.checkpoint_io import check_state_dict, extract_state_dict, strip_prefixes, torch_load
from murk.models.ursct_sesr.network import BUFFER_SUFFIXES, URSCT, URSCTConfig, relative_position_index

HINT = "Released URSCT-SESR files hold only tensors and numbers; a file that pickles more is not the release."
_PREFIXES = ("module.", "_orig_mod.")


def read_ursct_state(path: str | Path, *, trust: bool = False) -> dict[str, torch.Tensor]:
    """The learnable URSCT state dict of ``path`` (``['state_dict']``, ``['model']`` or a bare state dict;
    ``module.`` prefixes stripped; buffers dropped), checked against the official names and shapes.

    Raises:
        InputFileError: missing/unreadable file, a pickle ``weights_only`` refuses (naming ``--trust-checkpoint``),
            names/shapes that are not URSCT's (Enh_opt.yaml), or relative-position indices of another window.
    """
    path = Path(path)
    obj = torch_load(path, trust=trust, hint=HINT)
    raw, _ = extract_state_dict(obj, path, ("state_dict", "model"), "URSCT-SESR")
    full = {strip_prefixes(k, _PREFIXES): v for k, v in raw.items()}
    reference = relative_position_index()
    for key, value in full.items():
        if key.endswith("relative_position_index") and not torch.equal(value.long(), reference):
            raise InputFileError(path, f"{key}: not the 8x8-window index of URSCT-SESR (Enh_opt.yaml)")
    state = {k: v for k, v in full.items() if not k.endswith(BUFFER_SUFFIXES)}
    with torch.device("meta"):
        expected = {k: tuple(v.shape) for k, v in URSCT().named_parameters()}
    check_state_dict(path, state, expected, "URSCT-SESR (Enh_opt.yaml)")
    return state


def load_ursct(
    path: str | Path,
    *,
    trust: bool = False,
    device: str | torch.device = "cpu",
    img_size: int = 256,
    batch_coupled: bool = False,
) -> URSCT:
    """URSCT-SESR for ``img_size`` x ``img_size`` inputs with the weights of ``path`` (strict), float32, eval
    mode, on ``device``.

    Raises:
        InputFileError: see :func:`read_ursct_state`.
        ValueError: ``img_size`` is not a positive multiple of 128.
    """
    config = URSCTConfig(img_size=img_size, batch_coupled=batch_coupled)
    state = read_ursct_state(path, trust=trust)
    model = URSCT(config)
    model.load_state_dict({k: v.float() for k, v in state.items()}, strict=True)
    return model.to(device).eval()
