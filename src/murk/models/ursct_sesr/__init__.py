"""URSCT-SESR (Ren et al., IEEE TGRS 2022, doi:10.1109/TGRS.2022.3205061), enhancement-only configuration,
exact and checkpoint-compatible; a comparison baseline of the paper (Figs. 7, 8)."""

from murk.models.ursct_sesr.checkpoint import load_ursct, read_ursct_state
from murk.models.ursct_sesr.network import URSCT, URSCTConfig, build_ursct

__all__ = ["URSCT", "URSCTConfig", "build_ursct", "load_ursct", "read_ursct_state"]
