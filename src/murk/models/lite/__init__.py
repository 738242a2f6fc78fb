"""``lite``: a small re-parameterisable convolutional restorer for real-time CPU inference (docs/models.md)."""

from murk.models.lite.checkpoint import (
    LiteCheckpointInfo,
    load_lite,
    read_lite_checkpoint,
    save_lite_checkpoint,
    slim_lite_checkpoint,
)
from murk.models.lite.network import (
    SIZE_MULTIPLE,
    VARIANTS,
    LiteConfig,
    LiteNet,
    build_lite,
    parameter_count,
    reparameterize,
)

__all__ = [
    "SIZE_MULTIPLE",
    "VARIANTS",
    "LiteCheckpointInfo",
    "LiteConfig",
    "LiteNet",
    "build_lite",
    "load_lite",
    "parameter_count",
    "read_lite_checkpoint",
    "reparameterize",
    "save_lite_checkpoint",
    "slim_lite_checkpoint",
]
