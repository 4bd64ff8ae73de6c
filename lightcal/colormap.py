"""Colour maps for residuals and images (NumPy only; used by reports and the app)."""

from __future__ import annotations

import math

import numpy as np

# A diverging blue - white - red map (ColorBrewer RdBu, reversed so positive is red),
# as RGB anchor colours at evenly spaced positions over [-1, 1].
_DIVERGING_RGB = np.array(
    [
        [5, 48, 97],
        [33, 102, 172],
        [67, 147, 195],
        [146, 197, 222],
        [209, 229, 240],
        [247, 247, 247],
        [253, 219, 199],
        [244, 165, 130],
        [214, 96, 77],
        [178, 24, 43],
        [103, 0, 31],
    ],
    dtype=np.float64,
)
MASKED_RGB = np.array([40, 40, 40], dtype=np.uint8)


def diverging_rgb(values: np.ndarray, vmax: float) -> np.ndarray:
    """Map values in [-vmax, vmax] to RGB (blue negative, white zero, red positive).

    Args:
        values: (...) values; NaN or masked entries become dark grey.
        vmax: the magnitude mapped to the darkest colours (> 0).

    Returns:
        (..., 3) uint8 RGB.
    """
    if not vmax > 0:
        raise ValueError(f"vmax: expected a value > 0, got {vmax}")
    data = np.ma.filled(np.ma.asarray(values, dtype=np.float64), np.nan)
    t = np.clip(data / vmax, -1.0, 1.0)
    pos = (t + 1.0) * 0.5 * (len(_DIVERGING_RGB) - 1)
    bad = ~np.isfinite(pos)
    pos = np.where(bad, 0.0, pos)
    i0 = np.clip(np.floor(pos).astype(int), 0, len(_DIVERGING_RGB) - 2)
    frac = (pos - i0)[..., None]
    rgb = _DIVERGING_RGB[i0] * (1 - frac) + _DIVERGING_RGB[i0 + 1] * frac
    out = np.round(rgb).astype(np.uint8)
    out[bad] = MASKED_RGB
    return out


def grey_rgb(
    values: np.ndarray, vmax: float | None = None, *, gamma: float = 1 / 2.2
) -> np.ndarray:
    """Linear values to display grey (gamma-encoded) RGB uint8; NaN/masked dark red.

    Args:
        values: (H, W) linear values.
        vmax: value shown as white; default the 99.5th percentile.
        gamma: display encoding exponent.
    """
    data = np.ma.filled(np.ma.asarray(values, dtype=np.float64), np.nan)
    finite = data[np.isfinite(data)]
    if vmax is None:
        vmax = float(np.percentile(finite, 99.5)) if finite.size else 1.0
    vmax = vmax if vmax > 0 else 1.0
    g = np.clip(np.nan_to_num(data, nan=0.0) / vmax, 0.0, 1.0) ** gamma
    out = np.repeat(np.round(g * 255).astype(np.uint8)[..., None], 3, axis=-1)
    out[~np.isfinite(data)] = (60, 0, 0)
    return out


def robust_vmax(residual: np.ndarray, *, percentile: float = 99.0) -> float:
    """A symmetric colour scale for residuals: the given percentile of |residual|."""
    data = np.ma.filled(np.ma.asarray(residual, dtype=np.float64), np.nan)
    finite = np.abs(data[np.isfinite(data)])
    if finite.size == 0:
        return 1.0
    v = float(np.percentile(finite, percentile))
    return v if v > 0 else float(finite.max()) or 1.0


#: Colour steps of a residual map on each side of zero: each colour is a band of
#: vmax / RESIDUAL_STEPS (read like contours; and a map of noise compresses ~5x better).
RESIDUAL_STEPS = 8


def stepped(values: np.ndarray, vmax: float) -> np.ndarray:
    """`values` rounded to the nearest of 2 RESIDUAL_STEPS + 1 levels in [-vmax, vmax]
    (NaN kept)."""
    if not (math.isfinite(vmax) and vmax > 0):
        return values
    step = vmax / RESIDUAL_STEPS
    with np.errstate(invalid="ignore"):
        return np.clip(np.round(values / step), -RESIDUAL_STEPS, RESIDUAL_STEPS) * step


def block_nanmean(values: np.ndarray, b: int) -> np.ndarray:
    """(H // b, W // b) mean of the finite values of each b x b block (NaN: none)."""
    h, w = values.shape
    v = values[: h // b * b, : w // b * b].reshape(h // b, b, w // b, b)
    finite = np.isfinite(v)
    count = finite.sum(axis=(1, 3))
    total = np.where(finite, v, 0.0).sum(axis=(1, 3))
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(count > 0, total / np.maximum(count, 1), np.nan)


def means_to_width(values: np.ndarray, width: int) -> np.ndarray:
    """(H', W') `values` (masked/NaN where invalid) as block means no wider than about
    `width`: each pixel of a residual map the mean residual of the image pixels it covers
    (not a mean of their colours), so the noise averages out and the systematic structure
    stays (and a map's PNG compresses several times better than one of pixel noise)."""
    filled = np.ma.filled(np.ma.asarray(values, dtype=np.float64), np.nan)
    b = math.ceil(filled.shape[1] / max(width, 1))
    return block_nanmean(filled, b) if b >= 2 else filled
