"""The camera after the water: white-balance error, exposure, sensor noise and JPEG (the ``camera`` stage).

Real underwater footage passes through a camera that the paper's Eq. (1) does not model: an automatic white
balance that partly (or wrongly) compensates the water's colour, an exposure that rescales everything, sensor
noise that grows with the signal, and lossy compression. A restorer trained without them sees inputs that no
real camera produces. The model, applied to the sRGB image that Eqs. (1)-(8) give, in this order:

1. white balance and exposure: ``x_c = clip(e * g_c * I_c, 0, 1)`` with per-channel gains ``g`` (log-normal,
   geometric mean 1) and exposure ``e``;
2. sensor noise, heteroscedastic Gaussian (the Poisson-Gaussian model of Foi et al., IEEE TIP 17(10), 2008,
   doi:10.1109/TIP.2008.2001399, in its Gaussian approximation): ``x + n * sqrt(read^2 + shot * x)`` with
   ``n ~ N(0, 1)`` per pixel and channel, clipped to [0, 1];
3. quantisation to 8 bits and, when ``jpeg_quality > 0``, a JPEG round trip at that quality (OpenCV's codec,
   4:2:0 chroma subsampling as most cameras store it).

The noise field is drawn from ``noise_seed`` with numpy in both twins, and the JPEG round trip is OpenCV's in
both, so :func:`apply_camera` and :func:`apply_camera_torch` agree to float rounding (``tests/twins.py``).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import cv2
import numpy as np

from murk.io.images import swap_red_blue

if TYPE_CHECKING:
    import torch


def noise_field(seed: int, shape: tuple[int, ...]) -> np.ndarray:
    """Standard normal float32 noise of ``shape`` from ``seed`` (shared by both twins)."""
    return np.random.default_rng(int(seed)).standard_normal(shape, dtype=np.float32)


def jpeg_round_trip(image_u8: np.ndarray, quality: int) -> np.ndarray:
    """Encode RGB uint8 ``image_u8`` as JPEG at ``quality`` (1-100) and decode it (RGB uint8)."""
    ok, buf = cv2.imencode(".jpg", swap_red_blue(image_u8), [cv2.IMWRITE_JPEG_QUALITY, int(quality)])
    if not ok:
        raise RuntimeError("jpeg_round_trip: OpenCV could not encode the image")
    out = cv2.imdecode(buf, cv2.IMREAD_COLOR)
    if out is None:
        raise RuntimeError("jpeg_round_trip: OpenCV could not decode its own JPEG")
    return swap_red_blue(out)


def _quantise(x: np.ndarray, quality: int) -> np.ndarray:
    u8 = np.rint(x * np.float32(255.0)).astype(np.uint8)
    if quality > 0:
        u8 = jpeg_round_trip(u8, quality)
    return u8.astype(np.float32) * np.float32(1.0 / 255.0)


def apply_camera(image: np.ndarray, params: Any) -> np.ndarray:
    """The camera model above on float32 RGB ``image`` (H, W, 3) in [0, 1]; returns float32 (H, W, 3).

    ``params`` has ``wb_gains`` (3), ``exposure``, ``read_noise``, ``shot_noise``, ``noise_seed`` and
    ``jpeg_quality`` (0 = no JPEG), e.g. :class:`murk.synth.params.CameraParams`.
    """
    gain = np.asarray([params.exposure * g for g in params.wb_gains], np.float32)
    x = np.clip(np.asarray(image, np.float32) * gain, 0.0, 1.0)
    n = noise_field(params.noise_seed, x.shape)
    sd = np.sqrt(np.float32(params.read_noise) ** 2 + np.float32(params.shot_noise) * x)
    x = np.clip(x + n * sd, 0.0, 1.0)
    return _quantise(x, int(params.jpeg_quality))


def apply_camera_torch(images: torch.Tensor, params: Sequence[Any]) -> torch.Tensor:
    """Torch twin of :func:`apply_camera` for a batch (B, 3, H, W), one parameter set per sample.

    Gains and noise are applied on the batch's device; the 8-bit quantisation and JPEG round trip go through
    OpenCV on the CPU (there is no JPEG codec in torch), then back to the device.
    """
    import torch

    dev, dt = images.device, images.dtype
    gains = torch.tensor([[p.exposure * g for g in p.wb_gains] for p in params], dtype=torch.float32)
    x = (images.float() * gains.to(dev)[:, :, None, None]).clamp(0.0, 1.0)
    _, _, h, w = x.shape
    n = torch.from_numpy(np.stack([noise_field(p.noise_seed, (h, w, 3)) for p in params])).permute(0, 3, 1, 2)
    read = torch.tensor([p.read_noise for p in params], dtype=torch.float32, device=dev)[:, None, None, None]
    shot = torch.tensor([p.shot_noise for p in params], dtype=torch.float32, device=dev)[:, None, None, None]
    x = (x + n.to(dev) * torch.sqrt(read**2 + shot * x)).clamp(0.0, 1.0)
    host = x.permute(0, 2, 3, 1).cpu().numpy()
    out = np.stack([_quantise(host[i], int(p.jpeg_quality)) for i, p in enumerate(params)])
    return torch.from_numpy(out).permute(0, 3, 1, 2).to(device=dev, dtype=dt)
