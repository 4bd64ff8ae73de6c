"""A light whose profile has a bright rim (the `rid_rim` departure).

Many LEDs behind a lens or a reflector show a brighter ring near the beam's edge. The true
profile is the declared one times

    1 + A exp(-((theta - theta_half) / w)^2),   w = RIM_WIDTH_FRACTION theta_half,

theta_half the declared profile's half-intensity angle: a ring of relative height A whose
1/e half width is 15 % of the half angle (4.5 degrees for a 30 degree beam). For a 2-D
table theta_half is that of each azimuth. The result is a table: the declared profile (a
table's own interpolation, `RID.exact_data`) times the rim, sampled every
`SYMMETRIC_STEP_DEG` degrees from the axis to 180 (`SymmetricTableRID`), or every
`TABLE2D_STEP_DEG` in theta (0-90) and `AZIMUTH_STEP_DEG` in phi (`Table2DRID`).
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from lightcal.core.rid import RID, IsotropicRID, SymmetricTableRID, Table2DRID
from lightcal.errors import InputError
from lightcal.synthetic.departures import RIM_WIDTH_FRACTION

__all__ = [
    "AZIMUTH_STEP_DEG",
    "SYMMETRIC_STEP_DEG",
    "TABLE2D_STEP_DEG",
    "half_angles_rad",
    "rim_factor",
    "rimmed_rid",
]

SYMMETRIC_STEP_DEG = 0.25
"""Angular step of a rimmed symmetric profile (0..180 degrees)."""

TABLE2D_STEP_DEG = 0.5
"""Step in theta of a rimmed 2-D table (0..90 degrees)."""

AZIMUTH_STEP_DEG = 5.0
"""Step in phi of a rimmed 2-D table (0..355 degrees)."""

_CROSSING_STEP_DEG = 0.01
"""Resolution of the per-azimuth half-intensity angles of a 2-D table."""


def rim_factor(
    theta_rad: NDArray[np.float64], theta_half_rad: NDArray[np.float64] | float, amplitude: float
) -> NDArray[np.float64]:
    """1 + A exp(-((theta - theta_half) / w)^2), w = RIM_WIDTH_FRACTION theta_half (broadcast)."""
    width = RIM_WIDTH_FRACTION * np.asarray(theta_half_rad)
    return 1.0 + amplitude * np.exp(-(((theta_rad - theta_half_rad) / width) ** 2))


def half_angles_rad(rid: Table2DRID, phi_rad: NDArray[np.float64]) -> NDArray[np.float64]:
    """(n_p,) the half-intensity angle of a 2-D table along each azimuth (n_p,), radians:
    the first theta where its interpolation falls to 0.5 (pi / 2 if it never does)."""
    theta = np.radians(np.arange(0.0, 90.0 + _CROSSING_STEP_DEG / 2, _CROSSING_STEP_DEG))
    f = rid.value_and_derivatives(theta[None, :], phi_rad[:, None], exact=True)[0]
    out = np.full(phi_rad.shape, math.pi / 2)
    for k, row in enumerate(f):
        below = np.nonzero(row < 0.5)[0]
        if below.size:
            i = int(below[0])
            t = (row[i - 1] - 0.5) / (row[i - 1] - row[i])
            out[k] = theta[i - 1] + t * (theta[i] - theta[i - 1])
    return out


def rimmed_rid(rid: RID, amplitude: float) -> RID:
    """The declared profile `rid` with a bright rim of relative height `amplitude`.

    Raises:
        InputError: an isotropic light (it has no half-intensity angle).
    """
    if isinstance(rid, IsotropicRID):
        raise InputError(
            "rid_rim_amplitude",
            "expected a light with a half-intensity angle, got an isotropic light",
        )
    if rid.symmetric:
        theta = np.radians(np.arange(0.0, 180.0 + SYMMETRIC_STEP_DEG / 2, SYMMETRIC_STEP_DEG))
        plain = rid.value_and_derivatives(theta, exact=True)[0]
        return SymmetricTableRID(theta, plain * rim_factor(theta, rid.half_angle_rad, amplitude))
    if not isinstance(rid, Table2DRID):
        raise InputError("rid", f"expected a lightcal RID model, got {type(rid).__name__}")
    theta = np.radians(np.arange(0.0, 90.0 + TABLE2D_STEP_DEG / 2, TABLE2D_STEP_DEG))
    phi = np.radians(np.arange(0.0, 360.0 - AZIMUTH_STEP_DEG / 2, AZIMUTH_STEP_DEG))
    # Catmull-Rom in phi may dip a hair below 0 where the table ends (f = 0 at 90 degrees).
    plain = np.clip(rid.value_and_derivatives(theta[None, :], phi[:, None], exact=True)[0], 0, None)
    halves = half_angles_rad(rid, phi)
    return Table2DRID(theta, phi, plain * rim_factor(theta[None, :], halves[:, None], amplitude))
