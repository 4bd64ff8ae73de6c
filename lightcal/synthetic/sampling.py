"""Small helpers of the synthetic scenes: range checks and random directions."""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from lightcal.errors import InputError


def check_range(name: str, value: tuple[float, float], *, low: float, high: float) -> None:
    """Raise InputError unless `low <= value[0] <= value[1] <= high`, both finite."""
    if len(value) != 2 or not all(math.isfinite(v) for v in value):
        raise InputError(name, f"expected two finite numbers (min, max), got {value!r}")
    lo, hi = value
    if not (low <= lo <= hi <= high):
        raise InputError(name, f"expected {low:g} <= min <= max <= {high:g}, got ({lo:g}, {hi:g})")


def check_positive_int(name: str, value: int) -> None:
    if isinstance(value, bool) or not isinstance(value, int | np.integer) or value < 1:
        raise InputError(name, f"expected an integer >= 1, got {value!r}")


def random_unit_perpendicular(
    axis: NDArray[np.float64], rng: np.random.Generator
) -> NDArray[np.float64]:
    """A uniformly random unit vector perpendicular to the unit vector `axis` (3,)."""
    while True:
        v = rng.normal(size=3)
        v -= (v @ axis) * axis
        norm = float(np.linalg.norm(v))
        if norm > 1e-6:
            return v / norm


def random_unit_vector(rng: np.random.Generator) -> NDArray[np.float64]:
    """A uniformly random unit vector (3,)."""
    while True:
        v = rng.normal(size=3)
        norm = float(np.linalg.norm(v))
        if norm > 1e-6:
            return v / norm


def rotation_z(angle_rad: float) -> NDArray[np.float64]:
    """(3, 3) rotation by `angle_rad` about +z."""
    c, s = math.cos(angle_rad), math.sin(angle_rad)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
