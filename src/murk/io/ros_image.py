"""ROS image messages <-> RGB arrays: the encoding conversions of :mod:`murk.io.rosbag` (no ``rosbags`` needed).

Raw ``sensor_msgs/Image`` encodings read: ``rgb8``, ``bgr8``, ``rgba8``, ``bgra8``, ``mono8``, ``8UC1``, ``8UC3``
(BGR, as cv_bridge), ``8UC4``, ``mono16``, ``16UC1``, ``rgb16``, ``bgr16``, ``16UC3``, ``rgba16``, ``bgra16``,
``bayer_{rggb,bggr,gbrg,grbg}8`` (demosaiced by OpenCV). ``sensor_msgs/CompressedImage``: JPEG and PNG (decoded
like :func:`murk.io.images.read_image`: the same OpenCV flags, so a frame equals the same bytes read from a file).

A restored frame is written in the input's family (:func:`output_encoding`, :func:`encode_pixels`): an ``Image``
stays an ``Image`` (colour stays in its channel order, grey stays grey as the luma of the restored frame, 16-bit
stays 16-bit, alpha is dropped, Bayer becomes ``rgb8``); a ``CompressedImage`` stays compressed in the same format
(``rgb8; jpeg compressed bgr8`` / ``rgb8; png compressed bgr8``, as image_transport writes).
"""

from __future__ import annotations

from typing import Any, Literal

import cv2
import numpy as np

from murk.io.images import encode_png, swap_red_blue

IMAGE_MSG = "sensor_msgs/msg/Image"
COMPRESSED_MSG = "sensor_msgs/msg/CompressedImage"
CAMERA_INFO_MSG = "sensor_msgs/msg/CameraInfo"
IMAGE_MSGTYPES = (IMAGE_MSG, COMPRESSED_MSG)

# raw Image encodings -> (channels, bytes per sample, how to make RGB)
_RAW: dict[str, tuple[int, int, str]] = {
    "rgb8": (3, 1, "rgb"),
    "bgr8": (3, 1, "bgr"),
    "8UC3": (3, 1, "bgr"),
    "rgba8": (4, 1, "rgba"),
    "bgra8": (4, 1, "bgra"),
    "8UC4": (4, 1, "bgra"),
    "mono8": (1, 1, "mono"),
    "8UC1": (1, 1, "mono"),
    "rgb16": (3, 2, "rgb"),
    "bgr16": (3, 2, "bgr"),
    "16UC3": (3, 2, "bgr"),
    "rgba16": (4, 2, "rgba"),
    "bgra16": (4, 2, "bgra"),
    "mono16": (1, 2, "mono"),
    "16UC1": (1, 2, "mono"),
    # ROS names the first 2x2 block; OpenCV names the second row's pattern (as cv_bridge maps them)
    "bayer_rggb8": (1, 1, "bayer_bg"),
    "bayer_bggr8": (1, 1, "bayer_rg"),
    "bayer_gbrg8": (1, 1, "bayer_gr"),
    "bayer_grbg8": (1, 1, "bayer_gb"),
}
_BAYER = {
    "bayer_bg": cv2.COLOR_BayerBG2RGB,
    "bayer_rg": cv2.COLOR_BayerRG2RGB,
    "bayer_gr": cv2.COLOR_BayerGR2RGB,
    "bayer_gb": cv2.COLOR_BayerGB2RGB,
}
# encoding of the restored frame for each input encoding
_OUT_ENCODING = {
    "rgba8": "rgb8",
    "bgra8": "bgr8",
    "8UC4": "bgr8",
    "rgba16": "rgb16",
    "bgra16": "bgr16",
    **{k: "rgb8" for k in _RAW if k.startswith("bayer_")},
}
SUPPORTED_ENCODINGS = tuple(_RAW)


class UnsupportedEncoding(ValueError):
    """A message's encoding (or compressed format) that murk cannot convert."""


def compressed_kind(fmt: str) -> Literal["jpeg", "png"]:
    """``jpeg`` or ``png`` from a CompressedImage ``format`` (``jpeg``, ``png``, ``bgr8; jpeg compressed bgr8``).

    Raises:
        UnsupportedEncoding: another format (``compressedDepth``, ``tiff``, ...).
    """
    f = fmt.lower()
    if "compresseddepth" in f:
        raise UnsupportedEncoding(f"compressed format {fmt!r} (compressedDepth) is not supported")
    if "jpeg" in f or "jpg" in f:
        return "jpeg"
    if "png" in f:
        return "png"
    raise UnsupportedEncoding(f"compressed format {fmt!r} is not supported (expected jpeg or png)")


def check_encoding(msg: Any, msgtype: str) -> str:
    """The message's encoding (Image) or format (CompressedImage), after checking murk can convert it.

    Raises:
        UnsupportedEncoding: naming the encoding.
    """
    if msgtype == COMPRESSED_MSG:
        compressed_kind(str(msg.format))
        return str(msg.format)
    enc = str(msg.encoding)
    if enc not in _RAW:
        raise UnsupportedEncoding(f"encoding {enc!r} is not supported (murk reads {', '.join(SUPPORTED_ENCODINGS)})")
    return enc


def decode_image_msg(msg: Any, msgtype: str) -> np.ndarray:
    """An Image or CompressedImage message as an RGB array (H, W, 3) of uint8, or uint16 for 16-bit encodings.

    Raises:
        UnsupportedEncoding: an encoding murk cannot convert.
        ValueError: the data does not decode or does not match the declared size.
    """
    if msgtype == COMPRESSED_MSG:
        compressed_kind(str(msg.format))
        data = np.frombuffer(bytes(msg.data), dtype=np.uint8)
        bgr = cv2.imdecode(data, cv2.IMREAD_COLOR | cv2.IMREAD_ANYDEPTH) if data.size else None  # as read_image
        if bgr is None:
            raise ValueError("compressed image data could not be decoded")
        return swap_red_blue(bgr)
    if msgtype != IMAGE_MSG:
        raise UnsupportedEncoding(f"message type {msgtype} is not an image")
    enc = check_encoding(msg, msgtype)
    channels, size, order = _RAW[enc]
    h, w, step = int(msg.height), int(msg.width), int(msg.step)
    data = np.frombuffer(bytes(msg.data), dtype=np.uint8)
    row = w * channels * size
    if h <= 0 or w <= 0:
        raise ValueError(f"empty image ({w}x{h})")
    if step < row or data.size < step * (h - 1) + row:
        raise ValueError(f"{enc} {w}x{h}: {data.size} bytes of data with step {step} (expected {row} per row)")
    rows = np.lib.stride_tricks.as_strided(data, shape=(h, row), strides=(step, 1))
    dtype = np.dtype(np.uint8) if size == 1 else np.dtype(">u2" if msg.is_bigendian else "<u2")
    img = np.ascontiguousarray(rows).view(dtype).reshape(h, w, channels).astype(dtype.newbyteorder("="))
    if order.startswith("bayer_"):
        return cv2.cvtColor(img[:, :, 0], _BAYER[order])
    if order == "mono":
        return np.repeat(img, 3, axis=2)
    if order in ("bgr", "bgra"):
        img = img[:, :, 2::-1]
    return np.ascontiguousarray(img[:, :, :3])


def output_encoding(encoding: str) -> str:
    """The encoding a restored frame is written in, for a raw Image of ``encoding``."""
    return _OUT_ENCODING.get(encoding, encoding)


def output_bits(msgtype: str, encoding: str) -> Literal[8, 16]:
    """Bits per sample of the restored frame written for a message of this type/encoding."""
    if msgtype == COMPRESSED_MSG:
        return 8
    return 16 if _RAW.get(output_encoding(encoding), (0, 1, ""))[1] == 2 else 8


def encode_pixels(rgb: np.ndarray, msgtype: str, encoding: str, *, jpeg_quality: int = 95) -> tuple[str, bytes, int]:
    """Encode an RGB uint8/uint16 array for a message like the input's: returns (encoding or format, data, step).

    Image: the output encoding of :func:`output_encoding` (grey is the luma of the restored RGB).
    CompressedImage: JPEG (quality ``jpeg_quality``) or PNG, as the input's format.
    """
    if msgtype == COMPRESSED_MSG:
        kind = compressed_kind(encoding)
        if kind == "png":
            return f"rgb8; {kind} compressed bgr8", encode_png(rgb), 0
        bgr = swap_red_blue(rgb)
        ok, buf = cv2.imencode(".jpg", bgr, [cv2.IMWRITE_JPEG_QUALITY, int(jpeg_quality)])
        if not ok:
            raise ValueError(f"OpenCV could not encode a {kind} image ({rgb.dtype}, {rgb.shape})")
        return f"rgb8; {kind} compressed bgr8", buf.tobytes(), 0
    enc = output_encoding(encoding)
    channels, size, order = _RAW[enc]
    if order == "mono":
        px = cv2.cvtColor(rgb, cv2.COLOR_RGB2GRAY)[:, :, None]
    elif order == "bgr":
        px = swap_red_blue(rgb)
    else:
        px = rgb
    px = np.ascontiguousarray(px.astype("<u2" if size == 2 else np.uint8))
    return enc, px.tobytes(), int(rgb.shape[1]) * channels * size
