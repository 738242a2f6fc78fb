"""UDAformer (Shen et al., Computers & Graphics 2023, doi:10.1016/j.cag.2023.01.009), exact and
checkpoint-compatible; a comparison baseline of the paper (Figs. 7, 8)."""

from murk.models.udaformer.checkpoint import load_udaformer, read_udaformer_state, save_weights_only
from murk.models.udaformer.network import UDAformer, UDAformerConfig, build_udaformer

__all__ = [
    "UDAformer",
    "UDAformerConfig",
    "build_udaformer",
    "load_udaformer",
    "read_udaformer_state",
    "save_weights_only",
]
