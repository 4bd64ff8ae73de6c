"""The RIDs the solver estimates for a symmetric light: the monotone "curve" of K + 1
knots and the cos^m start of a "cos_power" (`lightcal.core.problem`'s docstring)."""

from __future__ import annotations

import math

import numpy as np

from lightcal.core.rid import RID, SymmetricTableRID

__all__ = ["curve_params_from_rid", "curve_rid", "fit_cos_power"]


def curve_rid(theta_max_rad: float, q: np.ndarray) -> SymmetricTableRID:
    """The monotone "curve" RID of `q` (K,) free parameters on [0, theta_max]."""
    k = q.shape[0]
    theta = np.linspace(0.0, theta_max_rad, k + 1)
    values = np.concatenate([[1.0], np.exp(-np.cumsum(np.exp(np.clip(q, -700.0, 6.0))))])
    return SymmetricTableRID(theta, values)


def curve_params_from_rid(rid: RID, theta_max_rad: float, k: int) -> np.ndarray:
    """Initial "curve" parameters (K,) that follow `rid` at the knots (a table's exact
    interpolation, not its rendering grid: a curve's own parameters come back exactly)."""
    theta = np.linspace(0.0, theta_max_rad, k + 1)
    f = np.clip(rid.value_and_derivatives(theta, exact=True)[0], 1e-6, None)
    f = np.minimum.accumulate(f)
    ratio = np.clip(f[1:] / f[:-1], 1e-12, 1.0 - 1e-6)
    return np.log(-np.log(ratio))


def fit_cos_power(rid: RID) -> float:
    """The cos^m exponent with the same half-intensity angle as `rid`."""
    half = rid.half_angle_rad
    if not 0.0 < half < math.pi / 2:
        return 1.0
    return -math.log(2.0) / math.log(math.cos(half))
