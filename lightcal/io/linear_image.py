"""`LinearImage`: one image as linear single-channel values, and the saturation rule.

What every image reader returns (`lightcal.io.images.read_image` for developed files,
`lightcal.io.raw.read_raw` for camera raw), kept apart from both readers so that each
imports it without importing the other's module back.

A source value counts as saturated at or above
`saturation_threshold(white, black) = white - SATURATION_MARGIN * (white - black)`;
colour is combined with the Rec. 709 weights `LUMINANCE_WEIGHTS_RGB`.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from lightcal.core.quantiles import percentile
from lightcal.errors import InputError
from lightcal.io.exif import Exposure

__all__ = ["LUMINANCE_WEIGHTS_RGB", "SATURATION_MARGIN", "LinearImage", "saturation_threshold"]

LUMINANCE_WEIGHTS_RGB = (0.2126, 0.7152, 0.0722)
"""Rec. 709 luminance weights of linear R, G, B."""

SATURATION_MARGIN = 0.005
"""Fraction of the range (white - black) below the white level from which a pixel counts
as saturated: sensors often clip a little below their nominal white level."""


@dataclass(frozen=True)
class LinearImage:
    """One image as linear single-channel values, ready for fitting.

    Attributes:
        values: (H, W) float64, proportional to the light on each pixel, black level
            already subtracted (may be slightly negative from noise). Read-only.
        saturated: (H, W) bool, True where the value is clipped (at or near the white
            level, or any source pixel of a binned pixel was). Read-only.
        white_level: Clipping level in the units of `values` (after black subtraction);
            `math.inf` when unknown (float images without a given white level).
        black_level: What was subtracted, in the units of the source data.
        exposure: Exposure settings from EXIF, or None when the file has none.
        source: The file read.
        bit_depth: Bits per sample of integer source data, None for float data.
        channel: Which channel was read (`Channel`, "auto" resolved).
        binning: Source pixels per output pixel along each axis: 2 for the half-size
            raw channels (use the binned camera, `Camera.binned(2)`), else 1.
    """

    values: NDArray[np.float64]
    saturated: NDArray[np.bool_]
    white_level: float
    black_level: float
    exposure: Exposure | None
    source: str
    bit_depth: int | None
    channel: str = "luminance"
    binning: int = 1

    def __post_init__(self) -> None:
        # Read-only views (no copy when the dtype already fits).
        values = np.asarray(self.values, dtype=np.float64).view()
        saturated = np.asarray(self.saturated, dtype=np.bool_).view()
        if values.ndim != 2:
            raise InputError(
                self.source, f"expected (H, W) linear values, got shape {values.shape}"
            )
        if saturated.shape != values.shape:
            raise InputError(
                self.source,
                f"saturation mask shape {saturated.shape} differs from values {values.shape}",
            )
        values.setflags(write=False)
        saturated.setflags(write=False)
        object.__setattr__(self, "values", values)
        object.__setattr__(self, "saturated", saturated)
        object.__setattr__(self, "white_level", float(self.white_level))
        object.__setattr__(self, "black_level", float(self.black_level))

    @property
    def shape(self) -> tuple[int, int]:
        """(H, W)."""
        return (int(self.values.shape[0]), int(self.values.shape[1]))

    @functools.cached_property
    def percentile_99(self) -> float | None:
        """The 99th percentile of the finite values (None when there are none); computed
        once (the values are read-only). Beyond PERCENTILE_SAMPLES values, of a regular
        subsample of them (a 24 MP frame: 60 ms instead of 0.6 s; it sets a threshold
        at 1 % of it, which moves by a fraction of a percent)."""
        flat = self.values.reshape(-1)
        step = -(-flat.size // PERCENTILE_SAMPLES)
        sample = flat[::step] if step > 1 else flat
        finite = sample[np.isfinite(sample)]
        # np.percentile's value, from order statistics (several times faster on a million
        # values).
        return percentile(finite, 99.0) if finite.size else None


PERCENTILE_SAMPLES = 1 << 20
"""Most values `LinearImage.percentile_99` reads (a regular subsample beyond)."""


def saturation_threshold(white_level: float, black_level: float) -> float:
    """Source value from which a pixel counts as saturated: white - margin * (white - black)."""
    return white_level - SATURATION_MARGIN * (white_level - black_level)
