"""Relative radiant intensity distributions (RIDs) of a light: one interface, five models.

A RID f(theta, phi) is the light's radiant intensity towards a direction relative to
its intensity along its own axis (f = 1 at theta = 0 by convention). theta is the angle
from the light's +z axis, phi the azimuth in the light frame from +x towards +y, both
in radians. Models:

- `IsotropicRID`: f = 1 everywhere.
- `CosPowerRID`: f = cos(theta)^m; `CosPowerRID.from_half_angle` takes the datasheet
  half-intensity angle theta_half and sets m = -ln 2 / ln cos(theta_half).
- `GaussianRID`: f = exp(-theta^2 / (2 sigma^2)); `from_half_angle` likewise.
- `SymmetricTableRID`: a measured profile f(theta) (e.g. a CSV, an axially symmetric
  IES file), interpolated by a monotonicity-preserving cubic (PCHIP) with zero slope on
  the axis, so the rotationally symmetric surface is smooth there.
- `Table2DRID`: a measured f(theta, phi) without rotational symmetry.

Every model evaluates through the compiled functions of `lightcal.core.rid_eval`, so the
renderer and Python callers agree exactly. The tables render from a uniform grid filled
from their interpolation on the first call of `RID.data` (`lightcal.core.rid_tabulate`:
no angle and no knot search per pixel; a compiled kernel, so reading a project starts no
numba); `RID.exact_data` keeps the knot interpolation itself.
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from dataclasses import dataclass, field

import numpy as np

from lightcal.core import rid_eval
from lightcal.core.rid_eval import RIDData
from lightcal.core.rid_tabulate import tabulate_1d, tabulate_2d

__all__ = [
    "RID",
    "CosPowerRID",
    "GaussianRID",
    "IsotropicRID",
    "SymmetricTableRID",
    "Table2DRID",
]


class RID(ABC):
    """A relative radiant intensity distribution, f = 1 on the axis."""

    #: True when f depends on theta only (roll about the axis is unobservable).
    symmetric: bool = True

    @abstractmethod
    def data(self) -> RIDData:
        """The arrays the compiled evaluators use (a table RID's uniform grid)."""

    def exact_data(self) -> RIDData:
        """The arrays of the exact model: a table RID's knot interpolation, which `data`
        resamples on a grid (`lightcal.core.rid_tabulate`); the other models' `data`."""
        return rid_eval.exact_rid_data(self.data())

    def __call__(self, theta_rad: np.ndarray, phi_rad: np.ndarray | None = None) -> np.ndarray:
        """Evaluate f.

        Args:
            theta_rad: (...) angles from the light axis, radians.
            phi_rad: (...) azimuths, radians (broadcast with theta); 0 if omitted.

        Returns:
            (...) relative intensity.
        """
        return self.value_and_derivatives(theta_rad, phi_rad)[0]

    def value_and_derivatives(
        self, theta_rad: np.ndarray, phi_rad: np.ndarray | None = None, *, exact: bool = False
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """f, df/dtheta and df/dphi at (...) directions.

        exact: evaluate `exact_data` (a table's knot interpolation) instead of `data`
        (what the renderer uses: a table's grid, within `rid_tabulate`'s accuracy).
        """
        theta = np.asarray(theta_rad, dtype=np.float64)
        phi = np.zeros_like(theta) if phi_rad is None else np.asarray(phi_rad, dtype=np.float64)
        theta, phi = np.broadcast_arrays(theta, phi)
        d = self.exact_data() if exact else self.data()
        f, ft, fp = rid_eval.rid_eval_many(
            np.ascontiguousarray(theta.ravel()), np.ascontiguousarray(phi.ravel()), d
        )
        return f.reshape(theta.shape), ft.reshape(theta.shape), fp.reshape(theta.shape)

    def angle_at_level_rad(self, level: float) -> float:
        """Largest angle from the axis at which f (maximised over phi) still reaches `level`.

        Used for the half-intensity angle (level 0.5) and the cone drawn in the viewer
        (a cut-off level such as 0.01). Returns pi for a light that never drops that low.
        A table is read exactly (its knot interpolation), not on the renderer's grid.
        """
        if not 0.0 < level < 1.0:
            raise ValueError(f"level: expected a value in (0, 1), got {level}")
        theta = np.linspace(0.0, math.pi, 3601)
        phi = np.linspace(0.0, 2 * math.pi, 1 if self.symmetric else 73, endpoint=False)
        tt, pp = np.meshgrid(theta, phi)

        def f(t: np.ndarray, p: np.ndarray | None = None) -> np.ndarray:
            return self.value_and_derivatives(t, p, exact=True)[0]  # a table's own knots

        fmax = f(tt, pp).max(axis=0)
        above = np.nonzero(fmax >= level)[0]
        if above.size == 0:
            return 0.0
        i = int(above[-1])
        if i == theta.size - 1:
            return math.pi
        if self.symmetric:
            from scipy.optimize import brentq  # see lightcal.core.solver on SciPy's optimize

            return float(brentq(lambda t: float(f(np.array(t))) - level, theta[i], theta[i + 1]))
        return float(
            theta[i] + (theta[i + 1] - theta[i]) * (fmax[i] - level) / (fmax[i] - fmax[i + 1])
        )

    @property
    def half_angle_rad(self) -> float:
        """Half-intensity angle (f = 0.5), radians."""
        return self.angle_at_level_rad(0.5)


def _scalar_data(kind: int, param: float) -> RIDData:
    return RIDData(
        kind,
        np.array([param, 0.0, 0.0, 0.0, 0.0]),
        np.zeros(1),
        np.zeros(1),
        np.ones((1, 1)),
        np.zeros((1, 1)),
        rid_eval.NO_GRID,
    )


def _check_half_angle(theta_half_rad: float) -> float:
    if not (math.isfinite(theta_half_rad) and 0.0 < theta_half_rad < math.pi / 2):
        raise ValueError(
            "half-intensity angle: expected a value in (0, 90) degrees, "
            f"got {math.degrees(theta_half_rad):g} degrees"
        )
    return theta_half_rad


@dataclass(frozen=True)
class IsotropicRID(RID):
    """f = 1 in every direction (a bare point source)."""

    symmetric = True

    def data(self) -> RIDData:
        return _scalar_data(rid_eval.KIND_ISOTROPIC, 0.0)


@dataclass(frozen=True)
class CosPowerRID(RID):
    """f = cos(theta)^m in front of the light, 0 behind it (m >= 0)."""

    m: float
    symmetric = True

    def __post_init__(self) -> None:
        if not (math.isfinite(self.m) and self.m >= 0.0):
            raise ValueError(f"cos-power exponent m: expected a finite value >= 0, got {self.m}")

    @classmethod
    def from_half_angle(cls, theta_half_rad: float) -> CosPowerRID:
        """The profile whose intensity halves at theta_half: m = -ln 2 / ln cos(theta_half)."""
        t = _check_half_angle(theta_half_rad)
        return cls(-math.log(2.0) / math.log(math.cos(t)))

    def data(self) -> RIDData:
        return _scalar_data(rid_eval.KIND_COS_POWER, self.m)


@dataclass(frozen=True)
class GaussianRID(RID):
    """f = exp(-theta^2 / (2 sigma^2)), sigma in radians."""

    sigma_rad: float
    symmetric = True

    def __post_init__(self) -> None:
        if not (math.isfinite(self.sigma_rad) and self.sigma_rad > 0.0):
            raise ValueError(f"Gaussian sigma: expected a finite value > 0, got {self.sigma_rad}")

    @classmethod
    def from_half_angle(cls, theta_half_rad: float) -> GaussianRID:
        """The Gaussian whose intensity halves at theta_half: sigma = theta_half / sqrt(2 ln 2)."""
        t = _check_half_angle(theta_half_rad)
        return cls(t / math.sqrt(2.0 * math.log(2.0)))

    def data(self) -> RIDData:
        return _scalar_data(rid_eval.KIND_GAUSSIAN, self.sigma_rad)


def _check_theta_knots(theta_rad: np.ndarray, name: str) -> np.ndarray:
    theta = np.asarray(theta_rad, dtype=np.float64)
    if theta.ndim != 1 or theta.size < 2:
        raise ValueError(
            f"{name}: expected at least 2 angles in a 1-D array, got shape {theta.shape}"
        )
    if not np.all(np.isfinite(theta)):
        raise ValueError(f"{name}: expected finite angles, got NaN or inf")
    if theta[0] != 0.0:
        raise ValueError(
            f"{name}: expected the first angle to be 0 (the light axis), got {theta[0]:g}"
        )
    if np.any(np.diff(theta) <= 0.0):
        raise ValueError(f"{name}: expected strictly increasing angles")
    if theta[-1] > math.pi + 1e-12:
        raise ValueError(f"{name}: expected angles <= pi radians, got {theta[-1]:g}")
    return theta


def pchip_slopes(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Knot slopes of the monotone piecewise-cubic Hermite interpolant (PCHIP).

    Fritsch and Butland's choice, as MATLAB's `pchip` and SciPy's `PchipInterpolator`
    make it (tested against SciPy): inside, the weighted harmonic mean of the two secant
    slopes where they have one sign, else 0; at the ends a one-sided three-point slope,
    clipped so the curve stays monotone. Written here so that start-up does not import
    `scipy.interpolate` (a third of a second).

    Args:
        x: (n,) strictly increasing knots, n >= 2.
        y: (..., n) values at the knots (the last axis runs along x).

    Returns:
        (..., n) slopes dy/dx at the knots.
    """
    h = np.diff(x)
    m = np.diff(y, axis=-1) / h
    if x.size == 2:
        return np.repeat(m, 2, axis=-1)
    w1 = 2.0 * h[1:] + h[:-1]
    w2 = h[1:] + 2.0 * h[:-1]
    left, right = m[..., :-1], m[..., 1:]
    same_sign = (np.sign(left) == np.sign(right)) & (left != 0.0) & (right != 0.0)
    safe_left = np.where(same_sign, left, 1.0)
    safe_right = np.where(same_sign, right, 1.0)
    inner = np.where(same_sign, (w1 + w2) / (w1 / safe_left + w2 / safe_right), 0.0)
    first = _pchip_end_slope(h[0], h[1], m[..., 0], m[..., 1])
    last = _pchip_end_slope(h[-1], h[-2], m[..., -1], m[..., -2])
    return np.concatenate([first[..., None], inner, last[..., None]], axis=-1)


def _pchip_end_slope(h0: float, h1: float, m0: np.ndarray, m1: np.ndarray) -> np.ndarray:
    """The end slope of `pchip_slopes`: three-point, 0 if it opposes the end secant m0,
    at most 3 m0 where the secants change sign."""
    d = ((2.0 * h0 + h1) * m0 - h0 * m1) / (h0 + h1)
    opposed = np.sign(d) != np.sign(m0)
    overshoot = (np.sign(m0) != np.sign(m1)) & (np.abs(d) > 3.0 * np.abs(m0))
    return np.where(opposed, 0.0, np.where(overshoot, 3.0 * m0, d))


def _pchip_slopes_even(theta: np.ndarray, values: np.ndarray) -> np.ndarray:
    """PCHIP knot slopes with the slope on the axis forced to 0 (even extension)."""
    slopes = np.array(pchip_slopes(theta, values), dtype=np.float64, order="C")
    slopes[..., 0] = 0.0
    return slopes


@dataclass(frozen=True, eq=False)
class SymmetricTableRID(RID):
    """A rotationally symmetric profile sampled at angles from the axis.

    Args:
        theta_rad: (n,) strictly increasing angles from the axis, radians, starting at 0.
        values: (n,) relative (or absolute) intensities >= 0, values[0] > 0; normalised so f(0) = 1.
            Beyond the last angle f = 0.
    """

    theta_rad: np.ndarray
    values: np.ndarray
    _knots: RIDData = field(init=False, repr=False)
    _data: RIDData | None = field(init=False, repr=False)
    symmetric = True

    def __post_init__(self) -> None:
        theta = _check_theta_knots(self.theta_rad, "RID table angles")
        values = np.asarray(self.values, dtype=np.float64)
        if values.shape != theta.shape:
            raise ValueError(
                f"RID table values: expected {theta.size} values (one per angle), "
                f"got shape {values.shape}"
            )
        if not np.all(np.isfinite(values)) or np.any(values < 0.0):
            raise ValueError("RID table values: expected finite values >= 0")
        if values[0] <= 0.0:
            raise ValueError("RID table values: expected a positive value on the axis (theta = 0)")
        values = values / values[0]
        object.__setattr__(self, "theta_rad", theta)
        object.__setattr__(self, "values", values)
        slopes = _pchip_slopes_even(theta, values)
        knots = RIDData(
            rid_eval.KIND_TABLE_1D,
            rid_eval.table_params(theta),
            theta,
            np.zeros(1),
            values[None, :].copy(),
            slopes[None, :].copy(),
            rid_eval.NO_GRID,
        )
        object.__setattr__(self, "_knots", knots)
        object.__setattr__(self, "_data", None)

    def data(self) -> RIDData:
        """The knot table's uniform grids, filled on the first call (by a compiled
        kernel: reading a project starts no numba)."""
        if self._data is None:
            object.__setattr__(self, "_data", tabulate_1d(self._knots))
        assert self._data is not None
        return self._data

    def exact_data(self) -> RIDData:
        """The knot interpolation, as made (no grid filled for it)."""
        return self._knots


@dataclass(frozen=True, eq=False)
class Table2DRID(RID):
    """A profile without rotational symmetry, sampled on a (phi, theta) grid.

    Args:
        theta_rad: (n_t,) strictly increasing angles from the axis, radians, starting at 0.
        phi_rad: (n_p,) strictly increasing azimuths in [0, 2 pi), radians (periodic), n_p >= 2.
        values: (n_p, n_t) intensities >= 0. The axis column (theta = 0) is one direction:
            its values are averaged over phi, and the table is normalised so f = 1 there.
    """

    theta_rad: np.ndarray
    phi_rad: np.ndarray
    values: np.ndarray
    _knots: RIDData = field(init=False, repr=False)
    _data: RIDData | None = field(init=False, repr=False)
    symmetric = False

    def __post_init__(self) -> None:
        theta = _check_theta_knots(self.theta_rad, "RID table angles")
        phi = np.asarray(self.phi_rad, dtype=np.float64)
        if phi.ndim != 1 or phi.size < 2:
            raise ValueError(
                f"RID table azimuths: expected at least 2 azimuths, got shape {phi.shape}"
            )
        if (
            not np.all(np.isfinite(phi))
            or phi[0] < 0.0
            or phi[-1] >= 2 * math.pi
            or np.any(np.diff(phi) <= 0.0)
        ):
            raise ValueError("RID table azimuths: expected strictly increasing values in [0, 2 pi)")
        values = np.asarray(self.values, dtype=np.float64)
        if values.shape != (phi.size, theta.size):
            raise ValueError(
                f"RID table values: expected shape ({phi.size}, {theta.size}) (azimuths, angles), "
                f"got {values.shape}"
            )
        if not np.all(np.isfinite(values)) or np.any(values < 0.0):
            raise ValueError("RID table values: expected finite values >= 0")
        axis_value = float(values[:, 0].mean())
        if axis_value <= 0.0:
            raise ValueError("RID table values: expected a positive value on the axis (theta = 0)")
        values = values / axis_value
        values[:, 0] = 1.0
        object.__setattr__(self, "theta_rad", theta)
        object.__setattr__(self, "phi_rad", phi)
        object.__setattr__(self, "values", values)
        slopes = _pchip_slopes_even(theta, values)
        knots = RIDData(
            rid_eval.KIND_TABLE_2D,
            rid_eval.table_params(theta, phi),
            theta,
            phi,
            values,
            slopes,
            rid_eval.NO_GRID,
        )
        object.__setattr__(self, "_knots", knots)
        object.__setattr__(self, "_data", None)

    def data(self) -> RIDData:
        """The knot table's equal-area grids, filled on the first call (as
        `SymmetricTableRID.data`)."""
        if self._data is None:
            object.__setattr__(self, "_data", tabulate_2d(self._knots))
        assert self._data is not None
        return self._data

    def exact_data(self) -> RIDData:
        """The knot interpolation, as made (no grid filled for it)."""
        return self._knots
