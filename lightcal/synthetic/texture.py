"""A smooth random albedo texture of the wall (the `albedo_texture` departure).

The albedo relative to its mean is 1 + A t(x, y), with

    t(x, y) = sum_k w_k sin(k_k . (x, y) + phase_k),   sum_k w_k = 1,

a few plane waves of random directions, wavelengths between 20 and 60 cm (a bright or
dark patch is half a wavelength: features of 10-30 cm), phases and positive weights.
|t| <= 1 by construction, so the albedo stays within [1 - A, 1 + A]. The texture lives on
the wall (world x, y, metres): every view sees the same one.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

__all__ = ["WAVELENGTH_RANGE_M", "AlbedoTexture", "sample_albedo_texture"]

WAVELENGTH_RANGE_M = (0.2, 0.6)
"""(min, max) wavelength of the texture's waves, metres: features of 10-30 cm."""

_N_WAVES = 6
"""Plane waves summed."""


@dataclass(frozen=True, eq=False)
class AlbedoTexture:
    """The albedo factor 1 + A t(x, y) (module docstring).

    Attributes:
        amplitude: A in [0, 1).
        wavevectors_per_m: (K, 2) 2 pi / wavelength times each wave's unit direction, rad/m.
        phases_rad: (K,) the waves' phases.
        weights: (K,) positive weights summing to 1.
    """

    amplitude: float
    wavevectors_per_m: NDArray[np.float64]
    phases_rad: NDArray[np.float64]
    weights: NDArray[np.float64]

    def field(self, xy_m: NDArray[np.float64]) -> NDArray[np.float64]:
        """t at wall points (..., 2) (x, y), metres -> (...) in [-1, 1]."""
        xy = np.asarray(xy_m, dtype=np.float64)
        phase = xy @ self.wavevectors_per_m.T + self.phases_rad  # (..., K)
        return np.sin(phase) @ self.weights

    def factor(self, xy_m: NDArray[np.float64]) -> NDArray[np.float64]:
        """1 + A t at wall points (..., 2), metres -> (...)."""
        return 1.0 + self.amplitude * self.field(xy_m)

    def describe(self) -> dict[str, Any]:
        """Its parameters for truth.json (wavelengths in metres, directions in degrees)."""
        k = self.wavevectors_per_m
        return {
            "amplitude": self.amplitude,
            "wavelengths_m": (2.0 * math.pi / np.linalg.norm(k, axis=1)).tolist(),
            "directions_deg": np.degrees(np.arctan2(k[:, 1], k[:, 0])).tolist(),
            "phases_rad": self.phases_rad.tolist(),
            "weights": self.weights.tolist(),
            "formula": "1 + amplitude * sum_k weights_k sin(2 pi / wavelength_k "
            "(x cos(direction_k) + y sin(direction_k)) + phase_k), x, y on the wall in metres",
        }


def sample_albedo_texture(amplitude: float, rng: np.random.Generator) -> AlbedoTexture:
    """A random texture of amplitude A (module docstring).

    Args:
        amplitude: A in [0, 1).
        rng: Randomness.
    """
    wavelengths = rng.uniform(*WAVELENGTH_RANGE_M, size=_N_WAVES)
    directions = rng.uniform(0.0, 2.0 * math.pi, size=_N_WAVES)
    phases = rng.uniform(0.0, 2.0 * math.pi, size=_N_WAVES)
    weights = rng.uniform(0.5, 1.0, size=_N_WAVES)
    wavevectors = (2.0 * math.pi / wavelengths)[:, None] * np.stack(
        [np.cos(directions), np.sin(directions)], axis=1
    )
    return AlbedoTexture(float(amplitude), wavevectors, phases, weights / weights.sum())
