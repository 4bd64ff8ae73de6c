"""Image sizes from file headers, without decoding: checked before any image is read.

A PNG header can claim 100,000 x 100,000 pixels in a few bytes; decoding it would take
tens of gigabytes before any size check. `header_size` reads the width and height of
PNG (IHDR), NPY (array header), OpenEXR (dataWindow), JPEG and TIFF (Pillow, lazily:
nothing decoded); `check_image_size` refuses more than a limit. Camera raw files are
left to LibRaw, which checks its own.
"""

from __future__ import annotations

import struct
from pathlib import Path

from lightcal.errors import InputError

MAX_IMAGE_SIDE = 65_535
"""The longest image side read (the largest a PNG or JPEG encoder writes)."""
MAX_IMAGE_PIXELS = 400_000_000
"""The most pixels an image may have (400 MP: above every camera sensor made)."""


def header_size(path: Path) -> tuple[int, int] | None:
    """(width, height) from an image file's header without decoding it; None when the
    format has no header read here (camera raw files)."""
    suffix = path.suffix.lower()
    if suffix == ".npy":
        return _npy_size(path)
    if suffix == ".exr":
        return _exr_size(path)
    if suffix == ".png":
        return _png_size(path)
    if suffix in (".jpg", ".jpeg", ".tif", ".tiff"):
        from PIL import Image

        Image.MAX_IMAGE_PIXELS = None  # the size is checked below, nothing is decoded
        try:
            with Image.open(path) as im:
                return int(im.size[0]), int(im.size[1])
        except Exception:
            return None  # the image reader says what is wrong
    return None


def _png_size(path: Path) -> tuple[int, int] | None:
    """Width and height of a PNG's IHDR chunk (its first, at byte 8)."""
    try:
        with path.open("rb") as f:
            head = f.read(24)
    except OSError:
        return None
    if len(head) < 24 or head[:8] != b"\x89PNG\r\n\x1a\n" or head[12:16] != b"IHDR":
        return None
    w, h = struct.unpack(">II", head[16:24])
    return int(w), int(h)


def _npy_size(path: Path) -> tuple[int, int] | None:
    import numpy as np

    try:
        with path.open("rb") as f:
            version = np.lib.format.read_magic(f)
            read = {
                (1, 0): np.lib.format.read_array_header_1_0,
                (2, 0): np.lib.format.read_array_header_2_0,
            }.get(version)
            if read is None:
                return None
            shape, _, _ = read(f)
    except Exception:
        return None
    if len(shape) < 2:
        return None
    return int(shape[1]), int(shape[0])


def _exr_size(path: Path) -> tuple[int, int] | None:
    """The dataWindow of an OpenEXR header (attributes: name, type, size, value)."""
    try:
        with path.open("rb") as f:
            head = f.read(1 << 16)
    except OSError:
        return None
    if head[:4] != b"\x76\x2f\x31\x01":
        return None
    pos = 8
    while pos < len(head) and head[pos] != 0:
        name_end = head.find(b"\0", pos)
        type_end = head.find(b"\0", name_end + 1)
        if name_end < 0 or type_end < 0 or type_end + 5 > len(head):
            return None
        (size,) = struct.unpack_from("<i", head, type_end + 1)
        value = type_end + 5
        if head[pos:name_end] == b"dataWindow" and size == 16 and value + 16 <= len(head):
            x0, y0, x1, y1 = struct.unpack_from("<4i", head, value)
            return x1 - x0 + 1, y1 - y0 + 1
        pos = value + max(size, 0)
    return None


def check_image_size(
    path: Path,
    *,
    max_side: int = MAX_IMAGE_SIDE,
    max_pixels: int = MAX_IMAGE_PIXELS,
    source: str | Path | None = None,
) -> None:
    """InputError (naming `source`, default the file) when the header declares more."""
    size = header_size(path)
    if size is None:
        return
    w, h = size
    if w > max_side or h > max_side or w * h > max_pixels:
        where = path if source is None else source
        prefix = "" if source is None else f"{path.name}: "
        raise InputError(
            where,
            f"{prefix}the image is {w} x {h} pixels; at most {max_side} a side and "
            f"{max_pixels // 1_000_000} megapixels",
        )
