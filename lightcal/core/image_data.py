"""The selected pixels of one image (`ImageData`) and their Poisson-Gaussian noise."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from lightcal.core.footprint import Footprints
from lightcal.core.scene import View

__all__ = ["ImageData", "poisson_gaussian_sigma"]


def poisson_gaussian_sigma(signal: np.ndarray, noise: tuple[float, float]) -> np.ndarray:
    """(N,) noise sigma of values whose `signal` (N,) above the offset is given.

    sigma = sqrt(gain * max(signal, 0) + read_variance), noise = (gain, read_variance).
    """
    gain, read_variance = noise
    return np.sqrt(gain * np.maximum(signal, 0.0) + read_variance)


@dataclass(frozen=True, eq=False)
class ImageData:
    """The selected pixels of one image.

    Attributes:
        name: image label (file name).
        view: camera pose and exposure.
        footprints: footprints of the N selected pixels (all valid).
        observed: (N,) measured linear pixel values.
        sigma: (N,) noise standard deviation of each value (1 when unweighted).
        noise: (gain, read_variance) of a Poisson-Gaussian sensor, in the units of
            `observed`: variance = gain * (value - offset) + read_variance. When given, the
            solver re-weights from rendered values (`SolverOptions.reweight`).
        channel: the index of its colour channel among the layout's `channels` (0 for
            a single-channel calibration): its lights' scales, medium and room light.
    """

    name: str
    view: View
    footprints: Footprints
    observed: np.ndarray
    sigma: np.ndarray
    noise: tuple[float, float] | None = None
    channel: int = 0

    def __post_init__(self) -> None:
        if isinstance(self.channel, bool) or not isinstance(self.channel, int | np.integer):
            raise ValueError(f"{self.name}: channel: expected an int, got {self.channel!r}")
        if self.channel < 0:
            raise ValueError(f"{self.name}: channel: expected an index >= 0, got {self.channel}")
        object.__setattr__(self, "channel", int(self.channel))
        n = len(self.footprints)
        for label, arr in (("observed", self.observed), ("sigma", self.sigma)):
            a = np.asarray(arr, dtype=np.float64)
            if a.shape != (n,):
                raise ValueError(f"{self.name}: {label}: expected shape ({n},), got {a.shape}")
            if not np.all(np.isfinite(a)):
                raise ValueError(f"{self.name}: {label}: expected finite values, got NaN or inf")
            object.__setattr__(self, label, a)
        if np.any(self.sigma <= 0.0):
            raise ValueError(f"{self.name}: sigma: expected values > 0")
        if not np.all(self.footprints.valid):
            raise ValueError(f"{self.name}: expected only valid footprints (select valid pixels)")
        if self.noise is not None:
            gain, read_variance = (float(v) for v in self.noise)
            if not (math.isfinite(gain) and gain >= 0.0):
                raise ValueError(f"{self.name}: noise: expected a finite gain >= 0, got {gain}")
            if not (math.isfinite(read_variance) and read_variance > 0.0):
                raise ValueError(
                    f"{self.name}: noise: expected a finite read variance > 0, got {read_variance}"
                )
            object.__setattr__(self, "noise", (gain, read_variance))

    def subset(self, rows: np.ndarray) -> ImageData:
        """The same image with only rows (k,) (indices or a boolean mask) of its pixels."""
        return ImageData(
            self.name,
            self.view,
            self.footprints.subset(rows),
            self.observed[rows],
            self.sigma[rows],
            self.noise,
            self.channel,
        )
