"""Camera raw files (DNG, CR2, NEF, ARW, ...) as linear values, through rawpy (LibRaw).

Nothing non-linear is applied: no gamma, no auto-brightness, no white-balance scaling
unless asked, no orientation flip. The camera's black level (per colour filter
channel, `black_level_per_channel`) is subtracted; its white level (`white_level`) is
kept for the saturation mask: a source pixel is saturated at or above
`white - SATURATION_MARGIN * (white - black)`.

Channels (`RawChannel`):

- "green_binned" (default): each 2x2 cell of the Bayer colour filter array gives one
  pixel, the mean of its two green sites; the image is half size (rows and columns;
  an odd last row or column is dropped). It is saturated when either green is.
  No demosaicing, no interpolation: the best signal for fitting. The two greens sit on
  a diagonal, so their mean samples the cell's centre, and the image is that of a
  "binned camera": pixel (u, v) covers source pixels 2u..2u+1, 2v..2v+1, and the
  intrinsics must be those of the binned camera, `Camera.binned(2)`
  (`lightcal.core.camera`): fx' = fx / 2, fy' = fy / 2, cx' = (cx + 0.5) / 2 - 0.5,
  cy' = (cy + 0.5) / 2 - 0.5 (pixel centres at integers, see docs/conventions.md).
- "R", "G1", "G2", "B": one site of each cell, also half size and of the binned camera.
  G1 is the green on the red site's row, G2 the one on the blue site's row. A single
  site is half a source pixel off the cell centre: it is treated as sampling the cell.
- "luminance": LibRaw's demosaiced image in the camera's raw colour space (linear,
  `output_color=raw`), 0.2126 R + 0.7152 G + 0.0722 B, full size, in source units
  (the same scale as the raw values). A pixel is saturated when a source pixel within
  the demosaicing reach (`DEMOSAIC_REACH`) is, or an output channel clipped. LibRaw
  subtracts nothing (`user_black=0`); the black levels are subtracted after
  demosaicing, which is exact when they are equal for all colours and close otherwise
  (demosaicing interpolates within a colour and along colour differences). The camera's
  raw R, G, B are not sRGB's, so this "luminance" is a convenient linear mix, not a
  photometric quantity. `use_camera_wb=True` scales the colours by the as-shot white
  balance first.

Exposure settings come from the file's EXIF tags (`lightcal.io.exif`); formats that
are not TIFF-based (e.g. CR3, RAF) give `exposure=None`.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, Literal

import numpy as np
import rawpy
from numpy.typing import NDArray

from lightcal.errors import InputError
from lightcal.io.exif import read_exposure
from lightcal.io.linear_image import (
    LUMINANCE_WEIGHTS_RGB,
    SATURATION_MARGIN,
    LinearImage,
    saturation_threshold,
)

__all__ = ["DEMOSAIC_REACH", "RawChannel", "read_raw"]

RawChannel = Literal["green_binned", "luminance", "R", "G1", "G2", "B"]
"""Which light of a camera raw file to read: see the module docstring."""

DEMOSAIC_REACH = 2
"""Source pixels a demosaiced value may draw from on each side (AHD: a 5 x 5 window)."""

_OUTPUT_FULL_SCALE = 65535.0
_RAW_CHANNELS = ("green_binned", "luminance", "R", "G1", "G2", "B")


def read_raw(
    path: str | Path,
    *,
    channel: RawChannel = "green_binned",
    user_black: float | None = None,
    user_white: float | None = None,
    use_camera_wb: bool = False,
) -> LinearImage:
    """Read a camera raw file as linear single-channel values.

    Args:
        path: The raw file.
        channel: Which light to read (see the module docstring).
        user_black: Black level for every channel instead of the camera's (raw units).
        user_white: White (clipping) level instead of the camera's (raw units).
        use_camera_wb: For "luminance", scale R, G, B by the camera's white balance
            (as shot), normalised so the smallest gain is 1. Ignored by the CFA channels.

    Returns:
        The linear image; `binning` is 2 for the half-size CFA channels, 1 for "luminance".

    Raises:
        InputError: Missing, truncated or non-raw file; a CFA channel of a file without a
            2x2 Bayer filter; levels with white <= black; no usable camera white balance.
    """
    path = Path(path)
    if not path.is_file():
        raise InputError(path, "file not found")
    if channel not in _RAW_CHANNELS:
        raise InputError(
            path,
            f"unknown raw channel {channel!r}; "
            f"expected one of {', '.join(map(repr, _RAW_CHANNELS))}",
        )
    try:
        with rawpy.imread(str(path)) as raw:
            return _read_open_raw(path, raw, channel, user_black, user_white, use_camera_wb)
    except (rawpy.LibRawError, rawpy.NotSupportedError) as error:
        raise InputError(
            path, f"not a readable camera raw file ({_libraw_message(error)})"
        ) from None


def _libraw_message(error: Exception) -> str:
    """LibRaw's message as text (rawpy passes bytes)."""
    message: Any = error.args[0] if error.args else type(error).__name__
    if isinstance(message, bytes):
        message = message.decode("utf-8", errors="replace")
    return f"LibRaw: {message}"


def _read_open_raw(
    path: Path,
    raw: Any,
    channel: str,
    user_black: float | None,
    user_white: float | None,
    use_camera_wb: bool,
) -> LinearImage:
    if raw.raw_type != rawpy.RawType.Flat:
        raise InputError(
            path,
            "holds no colour filter mosaic (a linear DNG or a Foveon image); "
            "convert it to a 16-bit or float TIFF and read that",
        )
    blacks = np.array(raw.black_level_per_channel, dtype=np.float64)  # by colour index
    if user_black is not None:
        blacks = np.full(4, float(user_black))
    white = float(raw.white_level if user_white is None else user_white)
    if not np.all(np.isfinite(blacks)) or not np.isfinite(white) or white <= float(np.max(blacks)):
        raise InputError(
            path,
            "expected a white level above every black level, "
            f"got white {white} and black {blacks.tolist()}",
        )
    colors = np.asarray(raw.raw_colors_visible)
    exposure = read_exposure(path)
    if channel == "luminance":
        data = np.array(raw.raw_image_visible, dtype=np.float64)
        return _luminance(path, raw, data, colors, blacks, white, use_camera_wb, exposure)

    # The CFA channels read their sites straight from the sensor's integers: a 24 MP
    # frame is never converted to float as a whole (0.23 -> 0.05 s a file).
    data = np.asarray(raw.raw_image_visible)
    sites = _bayer_sites(path, raw, colors, channel)
    rows, cols = (data.shape[0] // 2) * 2, (data.shape[1] // 2) * 2
    names = ("G1", "G2") if channel == "green_binned" else (channel,)
    values: NDArray[np.float64] | None = None
    saturated = np.zeros((rows // 2, cols // 2), dtype=np.bool_)
    site_blacks = []
    for dy, dx in (sites[name] for name in names):
        black = float(blacks[colors[dy, dx]])
        plane = data[dy:rows:2, dx:cols:2]
        saturated |= plane >= saturation_threshold(white, black)
        if values is None:
            values = np.subtract(plane, black, dtype=np.float64)
        else:
            values += np.subtract(plane, black, dtype=np.float64)
        site_blacks.append(black)
    assert values is not None
    if len(names) == 2:
        values *= 0.5  # the mean of the two greens, as (a + b) / 2
    black_mean = float(np.mean(site_blacks))
    return LinearImage(
        values=values,
        saturated=saturated,
        white_level=white - black_mean,
        black_level=black_mean,
        exposure=exposure,
        source=str(path),
        bit_depth=_bit_depth(white),
        channel=channel,
        binning=2,
    )


def _bit_depth(white: float) -> int:
    """Bits needed for the white level (e.g. 4095 -> 12, 16383 -> 14)."""
    return max(1, int(np.ceil(np.log2(white + 1.0))))


def _bayer_sites(
    path: Path, raw: Any, colors: NDArray[Any], channel: str
) -> dict[str, tuple[int, int]]:
    """Offsets (row, col) within each 2x2 cell of the sites "G1", "G2", "R", "B".

    Raises:
        InputError: The file has no 2x2 Bayer pattern (e.g. X-Trans, linear DNG, Foveon).
    """
    description = bytes(raw.color_desc).decode("ascii", errors="replace")
    problem = None
    if colors.ndim != 2 or colors.shape[0] < 2 or colors.shape[1] < 2:
        problem = "it has no colour filter array"
    else:
        cell = colors[:2, :2]
        rows, cols = (colors.shape[0] // 2) * 2, (colors.shape[1] // 2) * 2
        letters = [description[int(c)] if int(c) < len(description) else "?" for c in cell.flat]
        one_bayer_cell = sorted(letters) == ["B", "G", "G", "R"]
        repeats = all(
            np.all(colors[dy:rows:2, dx:cols:2] == cell[dy, dx]) for dy in (0, 1) for dx in (0, 1)
        )
        if not one_bayer_cell or not repeats:
            problem = "its colour filter array is not a 2x2 Bayer pattern"
    if problem is not None:
        raise InputError(
            path,
            f"channel {channel!r} needs a 2x2 Bayer colour filter array but {problem}; "
            "use channel='luminance'",
        )
    positions = [(0, 0), (0, 1), (1, 0), (1, 1)]
    by_letter: dict[str, list[tuple[int, int]]] = {"R": [], "G": [], "B": []}
    for position, letter in zip(positions, letters, strict=True):
        by_letter[letter].append(position)
    red, blue = by_letter["R"][0], by_letter["B"][0]
    green_on_red_row = next(p for p in by_letter["G"] if p[0] == red[0])
    green_on_blue_row = next(p for p in by_letter["G"] if p[0] == blue[0])
    return {"G1": green_on_red_row, "G2": green_on_blue_row, "R": red, "B": blue}


def _luminance(
    path: Path,
    raw: Any,
    data: NDArray[np.float64],
    colors: NDArray[Any],
    blacks: NDArray[np.float64],
    white: float,
    use_camera_wb: bool,
    exposure: Any,
) -> LinearImage:
    """Demosaiced luminance in raw units (see the module docstring)."""
    gains = np.ones(4)
    if use_camera_wb:
        gains = _camera_gains(path, raw)
    # LibRaw subtracts nothing (user_black=0) and scales by 65535 / white * gain.
    rgb = raw.postprocess(
        gamma=(1, 1),
        no_auto_bright=True,
        output_bps=16,
        use_camera_wb=False,
        use_auto_wb=False,
        user_wb=[float(g) for g in gains],
        output_color=rawpy.ColorSpace.raw,
        user_black=0,
        user_sat=round(white),
        adjust_maximum_thr=0.0,
        user_flip=0,
        half_size=False,
        four_color_rgb=False,
    )
    if rgb.shape[:2] != data.shape:
        raise InputError(
            path,
            f"demosaiced image {rgb.shape[:2]} differs from the sensor's visible area {data.shape} "
            "(non-square pixels or a rotated sensor); use a CFA channel such as 'green_binned'",
        )
    # Output channel c = (raw - black_c) * gain_c in raw units, once black is subtracted.
    green_black = float(
        np.mean([blacks[c] for c in np.unique(colors) if c in (1, 3)] or [blacks[1]])
    )
    channel_blacks = np.array([blacks[0], green_black, blacks[2]]) * gains[:3]
    linear_rgb = rgb.astype(np.float64) * (white / _OUTPUT_FULL_SCALE) - channel_blacks
    weights = np.asarray(LUMINANCE_WEIGHTS_RGB)
    values = linear_rgb @ weights

    thresholds = np.array([saturation_threshold(white, float(blacks[c])) for c in range(4)])
    source_saturated = data >= thresholds[np.clip(colors, 0, 3)]
    reach = 2 * DEMOSAIC_REACH + 1
    from scipy import ndimage  # 50 ms to import: only demosaiced reads need it

    saturated = ndimage.binary_dilation(
        source_saturated, structure=np.ones((reach, reach), dtype=bool)
    )
    saturated |= np.any(rgb >= (1.0 - SATURATION_MARGIN) * _OUTPUT_FULL_SCALE, axis=-1)
    # Every output channel clips at `white` in raw units (gains >= 1 reach it first).
    white_luminance = float(weights @ (white - channel_blacks))
    black_luminance = float(weights @ channel_blacks)
    return LinearImage(
        values=values,
        saturated=saturated,
        white_level=white_luminance,
        black_level=black_luminance,
        exposure=exposure,
        source=str(path),
        bit_depth=_bit_depth(white),
        channel="luminance",
        binning=1,
    )


def _camera_gains(path: Path, raw: Any) -> NDArray[np.float64]:
    """(4,) as-shot white balance gains by colour index, smallest 1 (LibRaw's convention)."""
    gains = np.array(raw.camera_whitebalance, dtype=np.float64)
    if gains.shape != (4,):
        gains = np.resize(gains, 4)
    if gains[3] == 0:
        gains[3] = gains[1]
    if not np.all(np.isfinite(gains)) or np.any(gains <= 0):
        raise InputError(
            path,
            "use_camera_wb: the file has no usable camera white balance; "
            "read it without white balance",
        )
    return gains / float(np.min(gains))
