"""Image operations of restoration, below the layers that use them (enhance's restorers, the networks' ONNX graphs in
models, training's input balance) and beside physics, which holds the water model: the simplest colour balance
(:mod:`murk.restore_ops.balance`) and the locally affine transfer of a restoration onto its input with the particle
guard (:mod:`murk.restore_ops.affine_transfer`). Each holds its numpy/OpenCV and torch twins; torch is imported inside
the torch twins."""
