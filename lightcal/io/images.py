"""Read an image file as linear single-channel pixel values (`LinearImage`).

Dispatch by extension:

| extension | reader | notes |
|---|---|---|
| `.png`, `.jpg`, `.jpeg` | `cv2.imread(IMREAD_UNCHANGED)` | 8/16-bit, grey or colour (B, G, R) |
| `.tif`, `.tiff` | `tifffile` (first page) | 8/16/32-bit integer or float, grey or colour |
| `.npy` | `numpy.load(allow_pickle=False)` | (H, W) float or unsigned integer array |
| `.exr` | `cv2.imread` with `OPENCV_IO_ENABLE_OPENEXR=1` | only if the OpenCV build has OpenEXR |
| camera raw (`RAW_EXTENSIONS`) | `lightcal.io.raw.read_raw` | linear, through rawpy / LibRaw |

What "linear" needs, per kind of data:

- Integer data: black level 0 and white level 2^bits - 1 unless given (`bits` is the
  file's bits per sample; a 12-bit sensor stored in 16-bit PNG needs
  `white_level=4095`). Pixels at or above `white - SATURATION_MARGIN * (white - black)`
  in the integer domain are saturated; in a colour image a pixel is saturated when any
  of the channels used is.
- 8-bit data is gamma-encoded by almost every camera, so it is refused unless a
  response curve (`lightcal.io.response`) linearises it, or the caller vouches that it
  is linear with `assume_linear=True`. With a curve, `black_level` is in linear units,
  and codes from `RESPONSE_SATURATION_CODE` up count as saturated: a curve fitted from a
  bracket (Debevec) gives its top codes almost no weight, and a JPEG's ringing beside a
  clipped area makes codes there that are neither the clip nor the scene.
- Float data: no white level unless given (then nothing is saturated and `white_level`
  is `math.inf`); NaN or infinite pixels are an error.
- Colour images give luminance 0.2126 R + 0.7152 G + 0.0722 B of the (linear) channels,
  or one channel with `channel="R" | "G" | "B"`.

No orientation tag is applied anywhere: pixel (u, v) is column u, row v of the stored
pixel array, the frame in which the camera's intrinsics must be given.
"""

from __future__ import annotations

import math
import os
from pathlib import Path
from typing import Any, Literal, cast

# OpenCV reads OpenEXR only when this is set (before cv2 is imported, to be safe).
os.environ.setdefault("OPENCV_IO_ENABLE_OPENEXR", "1")

import cv2
import numpy as np
from numpy.typing import NDArray

from lightcal.errors import InputError
from lightcal.io.exif import Exposure, read_exposure
from lightcal.io.image_header import check_image_size
from lightcal.io.linear_image import (
    LUMINANCE_WEIGHTS_RGB,
    LinearImage,
    saturation_threshold,
)
from lightcal.io.raw import RawChannel, read_raw
from lightcal.io.response import ResponseCurve

__all__ = ["RAW_EXTENSIONS", "SUPPORTED_EXTENSIONS", "Channel", "read_image", "read_mask"]

RESPONSE_SATURATION_CODE = 243
"""An 8-bit code from which a pixel read through a response curve counts as saturated
(the top 5 % of the codes). On `lightcal synth --real-world` (sRGB JPEGs of quality 90, a
beam clipped at its centre, a curve of `lightcal response` within 1 % of sRGB below code
240), the light lands 12.8 mm from the truth with codes 254-255 saturated, 1.0 mm with
codes 243-255."""

Channel = Literal["auto", "green_binned", "luminance", "R", "G", "G1", "G2", "B"]
"""Which light to read: see `read_image`."""

RAW_EXTENSIONS = frozenset(
    {
        ".3fr", ".ari", ".arw", ".cr2", ".cr3", ".crw", ".dcr", ".dng", ".erf", ".fff",
        ".iiq", ".k25", ".kdc", ".mef", ".mos", ".mrw", ".nef", ".nrw", ".orf", ".pef",
        ".raf", ".raw", ".rw2", ".rwl", ".sr2", ".srf", ".srw", ".x3f",
    }
)  # fmt: skip
"""Extensions read as camera raw through rawpy."""

_CV2_EXTENSIONS = frozenset({".png", ".jpg", ".jpeg"})
_TIFF_EXTENSIONS = frozenset({".tif", ".tiff"})
SUPPORTED_EXTENSIONS = _CV2_EXTENSIONS | _TIFF_EXTENSIONS | {".npy", ".exr"} | RAW_EXTENSIONS
"""Every extension `read_image` accepts (compared lower-case)."""

_DEVELOPED_CHANNELS = ("auto", "luminance", "R", "G", "B")


def read_image(
    path: str | Path,
    *,
    channel: Channel = "auto",
    black_level: float | None = None,
    white_level: float | None = None,
    response: ResponseCurve | None = None,
    assume_linear: bool = False,
) -> LinearImage:
    """Read an image or camera raw file as linear single-channel values.

    Args:
        path: The file; its extension (any case) selects the reader.
        channel: Which light to read.
            "auto": "green_binned" for camera raw, "luminance" otherwise (grey images as is).
            "luminance": 0.2126 R + 0.7152 G + 0.0722 B (camera raw: demosaiced, full size).
            "R", "G", "B": one channel of a developed colour image.
            "green_binned", "G1", "G2", also "R" and "B" for camera raw: colour filter
            array sites, half size (see `lightcal.io.raw`).
        black_level: Subtracted from the data (source units; linear units with a
            response curve). Default: 0, or the camera's for raw files.
        white_level: Clipping level of the data before black subtraction. Default:
            2^bits - 1 for integer data, the camera's for raw, none for float data.
        response: Curve that linearises 8-bit data (required for 8-bit images unless
            `assume_linear`).
        assume_linear: Treat 8-bit data as linear without a curve.

    Returns:
        The linear image with its saturation mask, levels and EXIF exposure.

    Raises:
        InputError: Missing or unreadable file, unsupported extension or content, 8-bit
            data without a response curve, non-finite float pixels, a channel the file
            does not have, or inconsistent levels.
    """
    path = Path(path)
    suffix = _checked_suffix(path)
    if suffix in RAW_EXTENSIONS:
        if response is not None:
            raise InputError(
                path,
                "camera raw data is already linear; a response curve applies only to 8-bit images",
            )
        return read_raw(
            path,
            channel=cast("RawChannel", "green_binned" if channel == "auto" else channel),
            user_black=black_level,
            user_white=white_level,
        )

    data, bit_depth = _decode(path, suffix)
    resolved = _resolve_developed_channel(path, channel, data.ndim == 3)
    exposure = None if suffix == ".npy" else read_exposure(path)

    if np.issubdtype(data.dtype, np.floating):
        return _from_float(path, data, resolved, black_level, white_level, response, exposure)
    if bit_depth is None:
        bit_depth = int(data.dtype.itemsize * 8)
    if bit_depth == 8 and not assume_linear and response is None:
        raise InputError(
            path,
            "8-bit image values are gamma-encoded by the camera, not proportional to light; "
            "supply a camera response curve fitted from an exposure bracket "
            "(lightcal.io.response.fit_response_debevec, Debevec & Malik 1997) as response=..., "
            "or pass assume_linear=True if the camera really wrote linear values",
        )
    if response is not None and bit_depth != 8:
        raise InputError(
            path, f"a response curve applies only to 8-bit images; this image has {bit_depth} bits"
        )
    return _from_integer(
        path, data, resolved, bit_depth, black_level, white_level, response, exposure
    )


def read_mask(path: str | Path) -> NDArray[np.bool_]:
    """Read a mask image: (H, W) bool, True where the image is not 0.

    Any format `read_image` reads; a pixel of a colour image is in the mask when any of
    its colour channels is not 0 (alpha is ignored), as its luminance read by
    `read_image(path, assume_linear=True)` is > 0, without the float image and the EXIF.

    Raises:
        InputError: as `read_image`.
    """
    path = Path(path)
    suffix = _checked_suffix(path)
    if suffix in RAW_EXTENSIONS:
        return np.asarray(read_image(path, assume_linear=True).values > 0)
    data, _ = _decode(path, suffix)
    if data.dtype.kind == "f":
        # Signed values: the luminance decides, as for read_image.
        _check_finite(path, data)
        return np.asarray(_combine(data, "luminance") > 0)
    return np.asarray(data > 0 if data.ndim == 2 else np.any(data > 0, axis=2))


def _checked_suffix(path: Path) -> str:
    """The lower-case extension of an existing image file `read_image` can read."""
    if not path.exists():
        raise InputError(path, "file not found")
    if not path.is_file():
        raise InputError(path, "not a file; expected an image file")
    suffix = path.suffix.lower()
    if suffix not in SUPPORTED_EXTENSIONS:
        raise InputError(
            path,
            f"unsupported image extension {path.suffix!r}; expected .png, .jpg, .tif, .tiff, "
            ".npy, .exr or a camera raw extension such as .dng, .cr2, .nef, .arw",
        )
    return suffix


def _decode(path: Path, suffix: str) -> tuple[NDArray[Any], int | None]:
    """The pixels of a developed (non-raw) image: (H, W) grey or (H, W, 3) B, G, R, and the
    TIFF's bits per sample (None for other files)."""
    check_image_size(path)  # before decoding: a header may claim 10^10 pixels
    # Colour data is kept in OpenCV's B, G, R order from here on.
    bit_depth: int | None = None
    if suffix in _CV2_EXTENSIONS:
        data = _read_cv2(path)
    elif suffix == ".exr":
        data = _read_exr(path)
    elif suffix in _TIFF_EXTENSIONS:
        data, bit_depth = _read_tiff(path)
    else:
        data = _read_npy(path)
    return _drop_alpha(path, data), bit_depth


def _resolve_developed_channel(path: Path, channel: str, colour: bool) -> str:
    """The channel to read from a developed (non-raw) image."""
    if channel not in _DEVELOPED_CHANNELS:
        raise InputError(
            path,
            f"channel {channel!r} needs a camera raw file with a colour filter array; "
            "for this image use 'auto', 'luminance', 'R', 'G' or 'B'",
        )
    if not colour:
        if channel not in ("auto", "luminance"):
            raise InputError(
                path, f"single-channel image has no channel {channel!r}; use 'auto' or 'luminance'"
            )
        return "luminance"
    return "luminance" if channel == "auto" else channel


def _channel_weights_bgr(channel: str) -> NDArray[np.float64]:
    """(3,) weights of the B, G, R channels that make `channel`."""
    if channel == "luminance":
        return np.array(LUMINANCE_WEIGHTS_RGB[::-1], dtype=np.float64)
    weights = np.zeros(3, dtype=np.float64)
    weights["BGR".index(channel)] = 1.0
    return weights


def _combine(data: NDArray[Any], channel: str) -> NDArray[np.float64]:
    """(H, W) float64 from (H, W) grey or (H, W, 3) B, G, R data: the channel or the luminance."""
    if data.ndim == 2:
        return data.astype(np.float64)
    if channel == "luminance":
        return np.asarray(data.astype(np.float64) @ _channel_weights_bgr(channel), dtype=np.float64)
    return data[..., "BGR".index(channel)].astype(np.float64)


def _saturated(data: NDArray[Any], channel: str, threshold: float) -> NDArray[np.bool_]:
    """(H, W) bool: the pixels where a channel that contributes reaches `threshold`."""
    at_white = data >= threshold
    if data.ndim == 2:
        return np.asarray(at_white)
    used = _channel_weights_bgr(channel) != 0
    return np.asarray(np.any(at_white[..., used], axis=-1))


def _from_integer(
    path: Path,
    data: NDArray[Any],
    channel: str,
    bit_depth: int,
    black_level: float | None,
    white_level: float | None,
    response: ResponseCurve | None,
    exposure: Exposure | None,
) -> LinearImage:
    """LinearImage from unsigned integer data (optionally through a response curve)."""
    code_white = float(2**bit_depth - 1)
    if response is not None:
        if white_level is not None:
            raise InputError(
                "white_level", "with a response curve the white level is code 255; do not give one"
            )
        try:
            linear = response.linearize(data)
        except InputError as error:
            raise InputError(path, error.detail) from None
        saturated = _saturated(data, channel, RESPONSE_SATURATION_CODE)
        black = 0.0 if black_level is None else float(black_level)
        full_scale = response.values[-1]
        weights = _channel_weights_bgr(channel)
        white_linear = (
            float(full_scale[0])
            if linear.ndim == 2
            else float(weights @ np.broadcast_to(full_scale, (3,)))
        )
        return LinearImage(
            values=_combine(linear, channel) - black,
            saturated=saturated,
            white_level=white_linear - black,
            black_level=black,
            exposure=exposure,
            source=str(path),
            bit_depth=bit_depth,
            channel=channel,
        )
    white = code_white if white_level is None else float(white_level)
    black = 0.0 if black_level is None else float(black_level)
    _check_levels(black, white)
    return LinearImage(
        values=_combine(data, channel) - black,
        saturated=_saturated(data, channel, saturation_threshold(white, black)),
        white_level=white - black,
        black_level=black,
        exposure=exposure,
        source=str(path),
        bit_depth=bit_depth,
        channel=channel,
    )


def _from_float(
    path: Path,
    data: NDArray[Any],
    channel: str,
    black_level: float | None,
    white_level: float | None,
    response: ResponseCurve | None,
    exposure: Exposure | None,
) -> LinearImage:
    """LinearImage from float data (already linear)."""
    if response is not None:
        raise InputError(
            path, "a response curve applies only to 8-bit images; this image has float values"
        )
    _check_finite(path, data)
    black = 0.0 if black_level is None else float(black_level)
    if white_level is None:
        saturated = np.zeros(data.shape[:2], dtype=np.bool_)
        white = math.inf
    else:
        white = float(white_level)
        _check_levels(black, white)
        saturated = _saturated(data, channel, saturation_threshold(white, black))
    return LinearImage(
        values=_combine(data, channel) - black,
        saturated=saturated,
        white_level=white - black,
        black_level=black,
        exposure=exposure,
        source=str(path),
        bit_depth=None,
        channel=channel,
    )


def _check_finite(path: Path, data: NDArray[Any]) -> None:
    bad = int(np.count_nonzero(~np.isfinite(data)))
    if bad:
        raise InputError(
            path, f"{bad} pixel values are NaN or infinite; expected finite linear values"
        )


def _check_levels(black: float, white: float) -> None:
    if not (math.isfinite(black) and math.isfinite(white)) or white <= black:
        raise InputError(
            "white_level",
            f"expected finite levels with white > black, got white {white} and black {black}",
        )


def _drop_alpha(path: Path, data: NDArray[Any]) -> NDArray[Any]:
    """(H, W) or (H, W, 3): grey kept, grey + alpha and colour + alpha lose the alpha."""
    if data.ndim == 3 and data.shape[2] == 1:
        return data[..., 0]
    if data.ndim == 3 and data.shape[2] == 2:
        return data[..., 0]
    if data.ndim == 3 and data.shape[2] == 4:
        return data[..., :3]
    if data.ndim == 2 or (data.ndim == 3 and data.shape[2] == 3):
        return data
    raise InputError(
        path, f"expected a grey or colour image of shape (H, W) or (H, W, 3), got {data.shape}"
    )


def _check_dtype(path: Path, data: NDArray[Any]) -> NDArray[Any]:
    """Accept unsigned integer and float data."""
    if data.dtype.kind == "u" or data.dtype.kind == "f":
        if data.dtype == np.float16:
            return data.astype(np.float32)
        return data
    raise InputError(
        path, f"unsupported pixel type {data.dtype}; expected unsigned integers or floats"
    )


def _read_cv2(path: Path) -> NDArray[Any]:
    """PNG / JPEG through OpenCV: (H, W) or (H, W, C), B, G, R order."""
    try:
        data = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
    except cv2.error:  # OpenCV's own checks (e.g. its pixel limit) raise instead of None
        data = None
    if data is None:
        raise InputError(path, f"not a readable {path.suffix.lower().lstrip('.').upper()} image")
    return _check_dtype(path, np.asarray(data))


def _read_exr(path: Path) -> NDArray[Any]:
    """OpenEXR through OpenCV, if the build can."""
    data = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
    if data is None:
        if not _opencv_has_openexr():
            raise InputError(
                path,
                "this OpenCV build cannot read OpenEXR; "
                "convert the image to a 32-bit float TIFF or a .npy array",
            )
        raise InputError(path, "not a readable OpenEXR image")
    return _check_dtype(path, np.asarray(data))


def _opencv_has_openexr() -> bool:
    for line in cv2.getBuildInformation().splitlines():
        if line.strip().startswith("OpenEXR:"):
            return "NO" not in line.split(":", 1)[1]
    return False


def _read_tiff(path: Path) -> tuple[NDArray[Any], int | None]:
    """First page of a TIFF: (H, W) or (H, W, C) turned to B, G, R order, and bits per sample."""
    import tifffile

    try:
        with tifffile.TiffFile(path) as tif:
            page = tif.pages.first
            data = np.asarray(page.asarray())
            axes = str(page.axes)
            bits = int(page.bitspersample)
    except Exception as error:
        raise InputError(path, f"not a readable TIFF image ({error})") from None
    if axes.startswith("S") and data.ndim == 3:  # planar configuration: samples first
        data = np.moveaxis(data, 0, -1)
    if data.ndim == 3 and data.shape[2] in (3, 4):  # R, G, B[, A] -> B, G, R[, A]
        data = np.concatenate([data[..., 2::-1], data[..., 3:]], axis=-1)
    data = _check_dtype(path, data)
    return data, (bits if data.dtype.kind == "u" else None)


def _read_npy(path: Path) -> NDArray[Any]:
    """(H, W) float or unsigned integer array; pickles are refused."""
    with path.open("rb") as f:
        magic = f.read(6)
    if magic != b"\x93NUMPY":
        raise InputError(path, "not a NumPy .npy file (no .npy header); expected an (H, W) array")
    try:
        data = np.load(path, allow_pickle=False)
    except ValueError as error:
        if "pickle" in str(error):
            raise InputError(
                path,
                "contains Python objects (pickle), which are not read; "
                "expected a numeric (H, W) array",
            ) from None
        raise InputError(path, f"not a readable .npy array ({error})") from None
    except (OSError, EOFError) as error:
        raise InputError(path, f"not a readable .npy array ({error})") from None
    if not isinstance(data, np.ndarray):
        raise InputError(path, "expected a single (H, W) array, got an archive")
    if data.ndim != 2:
        raise InputError(path, f"expected an (H, W) array, got shape {data.shape}")
    return _check_dtype(path, data)
