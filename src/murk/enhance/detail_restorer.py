"""The ``detail`` method: the learned local residual of :mod:`murk.models.detail` added to the image it is given,
``clamp(x + strength R(x), 0, 1)``, one image at a time at full resolution (no tiles, no resampling).

It is a stage to chain after a restorer (``lite+detail``, ``jointid+detail``): the shipped network learned to
improve ``lite``'s restorations of murk's synthetic water where a global colour map cannot, leaving the colour as it
was; measured, it takes out marine snow and some forward-scatter blur, not the haze that grows with distance. Alone
(``--method detail``) it works on the raw input, which it was not trained for. Its cost grows with the pixels: about
70 ms for a 640x480 frame and 0.8 s for 1920x1080 on two CPU cores (docs/models/detail.md), so it is for files, not
the live view.
"""

from __future__ import annotations

from pathlib import Path

import torch

from murk.enhance.declare import Checked
from murk.enhance.restorer import NetworkRestorer, RestoredTensor, torch_device
from murk.models.detail.network import DetailNet, load_detail


class DetailRestorer(NetworkRestorer):
    """Holds the network and the ``strength`` of its residual (0: the image unchanged; 1: as trained)."""

    name = "detail"

    def __init__(self, net: DetailNet, *, strength: float = 1.0, device: str | torch.device = "cpu") -> None:
        if isinstance(strength, bool) or not 0.0 <= float(strength) <= 2.0:
            raise ValueError(f"strength: expected a number in [0, 2], got {strength!r}")
        self.strength = float(strength)
        self.device = torch_device(device)
        self.net = net.to(self.device).eval()

    def _restore_network(self, images: torch.Tensor, x: torch.Tensor) -> RestoredTensor:
        if self.strength == 0.0:
            return RestoredTensor(x.clamp(0.0, 1.0))
        return RestoredTensor(torch.cat([self.net.detailed(x[i : i + 1], self.strength) for i in range(x.shape[0])]))


def create_detail(o: Checked) -> DetailRestorer:
    """Implementation of ``detail`` (declared in :mod:`murk.enhance.methods`).

    Raises:
        InputFileError: the weights file cannot be read as a detail network.
        ValueError: a bad ``strength`` or ``device``.
    """
    from murk.data import shipped_detail_weights

    path = Path(o.weights) if o.weights is not None else shipped_detail_weights()
    net, _meta = load_detail(path)
    restorer = DetailRestorer(net, strength=o.strength, device=o.device)
    restorer.weights = str(path)
    return restorer
