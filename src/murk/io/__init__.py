"""I/O edge: images, depth formats and validity, RGB-D pair discovery, atomic writes, JSON lines."""

from murk.io.atomic import atomic_path, write_bytes_atomic, write_text_atomic
from murk.io.depth import read_depth, resolve_invalid, validity_mask, write_depth_png
from murk.io.images import (
    ImageInfo,
    list_images,
    max_pixels,
    read_image,
    read_rgb,
    set_max_pixels,
    to_float,
    to_uint,
    write_rgb,
    write_uint,
)
from murk.io.jsonl import append_jsonl, read_jsonl, write_jsonl
from murk.io.pairs import DepthOptions, RGBDSource, discover, load_pair, read_list

__all__ = [
    "DepthOptions",
    "ImageInfo",
    "RGBDSource",
    "append_jsonl",
    "atomic_path",
    "discover",
    "list_images",
    "load_pair",
    "max_pixels",
    "read_depth",
    "read_image",
    "read_jsonl",
    "read_list",
    "read_rgb",
    "resolve_invalid",
    "set_max_pixels",
    "to_float",
    "to_uint",
    "validity_mask",
    "write_bytes_atomic",
    "write_depth_png",
    "write_jsonl",
    "write_rgb",
    "write_text_atomic",
    "write_uint",
]
