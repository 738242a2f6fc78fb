"""Joint-ID (Yang et al., IEEE Sensors Journal 2023, doi:10.1109/JSEN.2023.3338730), exact and
checkpoint-compatible."""

from murk.models.jointid.checkpoint import (
    CheckpointInfo,
    average_checkpoints,
    load_checkpoint,
    read_checkpoint,
    save_checkpoint,
    slim_checkpoint,
)
from murk.models.jointid.golden import fill_golden_, golden_input
from murk.models.jointid.network import (
    INPUT_MEAN,
    INPUT_STD,
    SIZE_MULTIPLE,
    VARIANTS,
    JointID,
    JointIDConfig,
    JointIDOutput,
    build_jointid,
    depth_head_parameter_names,
    enhance_head_parameter_names,
    init_weights,
    normalize_input,
    normalize_input_np,
    unused_parameter_names,
)

__all__ = [
    "INPUT_MEAN",
    "INPUT_STD",
    "SIZE_MULTIPLE",
    "VARIANTS",
    "CheckpointInfo",
    "JointID",
    "JointIDConfig",
    "JointIDOutput",
    "average_checkpoints",
    "build_jointid",
    "depth_head_parameter_names",
    "enhance_head_parameter_names",
    "fill_golden_",
    "golden_input",
    "init_weights",
    "load_checkpoint",
    "normalize_input",
    "normalize_input_np",
    "read_checkpoint",
    "save_checkpoint",
    "slim_checkpoint",
    "unused_parameter_names",
]
