"""Compiled evaluation of relative radiant intensity distributions (RIDs).

Every RID model in :mod:`lightcal.core.rid` compiles down to one representation,
`RIDData`, that these numba functions evaluate, so the renderer's kernels and the
Python-level `RID.__call__` share one implementation:

- ``kind`` 0 isotropic: f = 1 in every direction;
- ``kind`` 1 cosine power: f = cos(theta)^m for theta < pi/2, else 0 (``params[0] = m``);
- ``kind`` 2 Gaussian: f = exp(-theta^2 / (2 sigma^2)) (``params[0] = sigma``, radians);
- ``kind`` 3 symmetric table: cubic Hermite in theta on ``theta_knots`` with
  ``values[0]`` and ``slopes[0]``; 0 beyond the last knot (``params``: `table_params`);
- ``kind`` 4 2-D table: cubic Hermite in theta on each azimuth row (rows at
  ``phi_knots``, periodic over 2 pi), then cubic Hermite in phi through the rows with
  centred finite-difference slopes (C1 everywhere off the pole);
- ``kind`` 5 and 6: the tables of kinds 3 and 4 resampled on a uniform grid
  (`lightcal.core.rid_grid`, filled by `lightcal.core.rid_tabulate`): ``grid`` holds
  the nodes, ``params[2:5]`` = (1 / h, s_max, s_back); the knot arrays and ``params[0:2]`` are
  the table's, so `exact_rid_data` gives the table back. What the table RIDs render with.

Angles: theta from the light's +z axis, phi the azimuth from +x towards +y (radians).

The kernels pass a RID around as one record, the `RIDData` named tuple (numba types it
as a heterogeneous tuple); `lightcal.core.rid_stack` pads the RIDs of several lights
into one record for the fused image kernel.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numba
import numpy as np

from lightcal.core.kernels.fastmath import cos_power
from lightcal.core.rid_grid import grid1d_value_grad, grid2d_value_grad

KIND_ISOTROPIC = 0
KIND_COS_POWER = 1
KIND_GAUSSIAN = 2
KIND_TABLE_1D = 3
KIND_TABLE_2D = 4
KIND_GRID_1D = 5
KIND_GRID_2D = 6

TWO_PI = 2.0 * math.pi
#: Directions with sin(theta) below AXIS_RHO count as on the axis, where the RID's
#: gradient takes the limit f_theta / sin(theta) -> f_theta(AXIS_EPS) / AXIS_EPS.
AXIS_RHO = 1e-9
AXIS_EPS = 1e-6


class RIDData(NamedTuple):
    """Arrays describing a RID for the compiled evaluators.

    Attributes:
        kind: One of the ``KIND_*`` constants.
        params: (5,) model parameters (see module docstring; unused entries 0).
        theta_knots: (n_t,) increasing knot angles from the axis, radians; theta_knots[0] = 0.
        phi_knots: (n_p,) increasing azimuths in [0, 2 pi), radians ((1,) for symmetric RIDs).
        values: (n_p, n_t) relative intensity at the knots.
        slopes: (n_p, n_t) d values / d theta at the knots.
        grid: (a, b, c) nodes of the grid kinds (`rid_grid`); (1, 1, 1) zeros otherwise.
    """

    kind: int
    params: np.ndarray
    theta_knots: np.ndarray
    phi_knots: np.ndarray
    values: np.ndarray
    slopes: np.ndarray
    grid: np.ndarray


RIDTuple = tuple[int, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]
"""The fields of a `RIDData` as a plain tuple (how kernels called from Python take it)."""


def rid_tuple(rid: RIDData) -> RIDTuple:
    """The fields of `rid` as a plain tuple: what the kernels called from Python take.

    numba's dispatcher types a plain tuple in C, a NamedTuple in Python: 1 us more per
    call (~1 % of the solver's call of `flux_pixels` on 1,000 pixels). The kernels
    rebuild the record inside, `RIDData(*rid)`.
    """
    return (
        int(rid.kind),
        rid.params,
        rid.theta_knots,
        rid.phi_knots,
        rid.values,
        rid.slopes,
        rid.grid,
    )


#: `RIDData.grid` of the kinds without a grid.
NO_GRID = np.zeros((1, 1, 1))


def exact_rid_data(rid: RIDData) -> RIDData:
    """The exactly interpolated table of a grid kind (kinds 5, 6 -> 3, 4); others as given."""
    if rid.kind == KIND_GRID_1D:
        return rid._replace(kind=KIND_TABLE_1D, grid=NO_GRID)
    if rid.kind == KIND_GRID_2D:
        return rid._replace(kind=KIND_TABLE_2D, grid=NO_GRID)
    return rid


def _uniform_step(knots: np.ndarray, start: float, span: float) -> float:
    """1 / h when knots[k] = start + k h (to 1e-9 h) with h = span / (number of steps),
    else 0."""
    n = knots.shape[0]
    steps = n - 1 if span == 0.0 else n
    if steps < 1:
        return 0.0
    h = (knots[-1] - start) / (n - 1) if span == 0.0 else span / n
    ok = h > 0.0 and bool(np.all(np.abs(knots - start - h * np.arange(n)) <= 1e-9 * h))
    return 1.0 / h if ok else 0.0


def table_params(theta_knots: np.ndarray, phi_knots: np.ndarray | None = None) -> np.ndarray:
    """`RIDData.params` of a table RID: (1 / h_theta, 1 / h_phi, 0, 0, 0), each 0 where
    not uniform.

    1 / h_theta > 0 when the theta knots are 0, h, 2h, ... (to 1e-9 h: IES and EULUMDAT
    files); 1 / h_phi > 0 when the azimuths of a 2-D table are phi_0 + k 2 pi / n_p, the
    full circle in equal steps. The kernels then find a knot interval by one
    multiplication and a comparison instead of a search: the same interval, the same
    numbers.
    """
    t = np.asarray(theta_knots, dtype=np.float64)
    inv_t = _uniform_step(t, 0.0, 0.0) if t.shape[0] >= 2 and t[0] == 0.0 else 0.0
    inv_p = 0.0
    if phi_knots is not None:
        p = np.asarray(phi_knots, dtype=np.float64)
        inv_p = _uniform_step(p, float(p[0]), TWO_PI) if p.shape[0] >= 2 else 0.0
    return np.array([inv_t, inv_p, 0.0, 0.0, 0.0])


@numba.njit(cache=True, error_model="numpy")
def _knot_search(x: float, knots: np.ndarray) -> int:
    """lo with knots[lo] <= x < knots[lo + 1] (lo = n - 2 at x = knots[n - 1]) for
    knots[0] <= x <= knots[n - 1], by binary search."""
    lo = 0
    hi = knots.shape[0] - 1
    while hi - lo > 1:
        mid = (lo + hi) >> 1
        if knots[mid] <= x:
            lo = mid
        else:
            hi = mid
    return lo


@numba.njit(cache=True, inline="always", error_model="numpy")
def hermite(
    x: float, knots: np.ndarray, values: np.ndarray, slopes: np.ndarray, inv_h: float
) -> tuple[float, float]:
    """Cubic Hermite value and derivative at x; (values[0], slopes[0]) at and before the
    first knot, 0 beyond the last, NaN at NaN.

    inv_h: `table_params`' first entry: > 0 for uniform knots, whose interval comes from
    x / h (corrected by one knot where rounding put it across); 0: a binary search.
    Written out in one function: numba's inlining of a second function taking arrays
    costs a pixel loop 3x (reference counts).
    """
    n = knots.shape[0]
    beyond = x > knots[n - 1]
    inside = (x > knots[0]) & (not beyond)  # False for NaN: xc stays a knot
    xc = x if inside else (knots[n - 1] if beyond else knots[0])
    if inv_h > 0.0:
        lo = min(int(xc * inv_h), n - 2)
        if knots[lo] > xc and lo > 0:
            lo -= 1
        elif lo < n - 2 and knots[lo + 1] <= xc:
            lo += 1
    else:
        lo = _knot_search(xc, knots)
    hi = lo + 1
    h = knots[hi] - knots[lo]
    t = (xc - knots[lo]) / h
    t2 = t * t
    t3 = t2 * t
    v0 = values[lo]
    v1 = values[hi]
    m0 = slopes[lo] * h
    m1 = slopes[hi] * h
    f = (
        (2 * t3 - 3 * t2 + 1) * v0
        + (t3 - 2 * t2 + t) * m0
        + (-2 * t3 + 3 * t2) * v1
        + (t3 - t2) * m1
    )
    df = (
        (6 * t2 - 6 * t) * v0
        + (3 * t2 - 4 * t + 1) * m0
        + (-6 * t2 + 6 * t) * v1
        + (3 * t2 - 2 * t) * m1
    ) / h
    f = f if inside else (0.0 if beyond else values[0])
    df = df if inside else (0.0 if beyond else slopes[0])
    nan = x != x
    return (x if nan else f), (x if nan else df)


@numba.njit(cache=True)
def rid_value_grad(theta: float, phi: float, rid: RIDData) -> tuple[float, float, float]:
    """RID value and its partial derivatives at one direction.

    Args:
        theta: Angle from the light axis, radians, in [0, pi].
        phi: Azimuth in the light frame, radians (any real; wrapped).
        rid: the RID.

    Returns:
        (f, df/dtheta, df/dphi).
    """
    kind, params, theta_knots, _, values, slopes, _ = rid
    if kind == KIND_ISOTROPIC:
        return 1.0, 0.0, 0.0
    if kind == KIND_COS_POWER:
        c = math.cos(theta)
        if c <= 0.0:
            return 0.0, 0.0, 0.0
        m = params[0]
        f = c**m
        return f, -m * f * math.tan(theta), 0.0
    if kind == KIND_GAUSSIAN:
        s = params[0]
        f = math.exp(-0.5 * (theta / s) ** 2)
        return f, -f * theta / (s * s), 0.0
    if kind == KIND_TABLE_1D:
        f, df = hermite(theta, theta_knots, values[0], slopes[0], params[0])
        return f, df, 0.0
    if kind == KIND_TABLE_2D:  # periodic rows in phi
        return table2d_value_grad(theta, phi, rid)
    # The grids: at u(theta, phi); df/dtheta = g . e_theta, df/dphi = sin(theta) g . e_phi.
    st = math.sin(theta)
    ct = math.cos(theta)
    sp = math.sin(phi)
    cp = math.cos(phi)
    if kind == KIND_GRID_1D:
        f, g = grid1d_value_grad(ct, rid.grid, params[2], params[3], params[4])
        return f, -g * st, 0.0
    f, gx, gy, gz = grid2d_value_grad(
        st * cp, st * sp, ct, rid.grid, params[2], params[3], params[4]
    )
    return f, ct * (gx * cp + gy * sp) - gz * st, st * (gy * cp - gx * sp)


@numba.njit(cache=True, inline="always", error_model="numpy")
def _phi_interval(p: float, phi_knots: np.ndarray, inv_h: float) -> int:
    """j with phi_knots[j] <= p < phi_knots[j + 1] on the circle, p in [0, 2 pi): the last
    knot's interval (j = n_p - 1) wraps to phi_knots[0] + 2 pi. inv_h: `table_params`'
    second entry (> 0: equal steps, the interval by one multiplication)."""
    n_p = phi_knots.shape[0]
    if inv_h > 0.0:
        if p < phi_knots[0]:
            return n_p - 1
        j = min(int((p - phi_knots[0]) * inv_h), n_p - 1)
        # Rounding may put p one interval off: the linear scan's answer, exactly.
        if phi_knots[j] > p:
            j -= 1
        elif j < n_p - 1 and phi_knots[j + 1] <= p:
            j += 1
        return j
    j = n_p - 1
    for k in range(n_p - 1):
        if phi_knots[k + 1] > p:
            j = k
            break
    if p < phi_knots[0]:
        j = n_p - 1
    return j


@numba.njit(cache=True, inline="always", error_model="numpy")
def table2d_value_grad(theta: float, phi: float, rid: RIDData) -> tuple[float, float, float]:
    """`rid_value_grad` of a 2-D table: cubic Hermite in theta along the four rows around
    phi (one knot interval and one basis for the four), Catmull-Rom-like in phi."""
    params, theta_knots, phi_knots = rid.params, rid.theta_knots, rid.phi_knots
    values, slopes = rid.values, rid.slopes
    n_p = phi_knots.shape[0]
    p = phi - TWO_PI * math.floor(phi / TWO_PI)
    j = _phi_interval(p, phi_knots, params[1])
    jm = (j - 1) % n_p
    j1 = (j + 1) % n_p
    j2 = (j + 2) % n_p
    # Azimuth offsets of the four rows relative to row j, unwrapped.
    pj = phi_knots[j]
    if p < pj:
        p += TWO_PI
    d_m = pj - phi_knots[jm]
    if d_m <= 0.0:
        d_m += TWO_PI
    d_1 = phi_knots[j1] - pj
    if d_1 <= 0.0:
        d_1 += TWO_PI
    d_2 = phi_knots[j2] - phi_knots[j1]
    if d_2 <= 0.0:
        d_2 += TWO_PI
    # The theta interval and Hermite basis once (as `hermite` computes them), four rows.
    # Written out, not shared with `hermite` through a helper: an inlined helper taking
    # the knots array made the 1-D table's full frame 1.4x slower (measured).
    x = theta
    knots = theta_knots
    n = knots.shape[0]
    beyond = x > knots[n - 1]
    inside = (x > knots[0]) & (not beyond)
    xc = x if inside else (knots[n - 1] if beyond else knots[0])
    inv_h = params[0]
    if inv_h > 0.0:
        lo = min(int(xc * inv_h), n - 2)
        if knots[lo] > xc and lo > 0:
            lo -= 1
        elif lo < n - 2 and knots[lo + 1] <= xc:
            lo += 1
    else:
        lo = _knot_search(xc, knots)
    hi = lo + 1
    h_t = knots[hi] - knots[lo]
    u = (xc - knots[lo]) / h_t
    u2 = u * u
    u3 = u2 * u
    b0 = 2 * u3 - 3 * u2 + 1
    b1 = u3 - 2 * u2 + u
    b2 = -2 * u3 + 3 * u2
    b3 = u3 - u2
    e0 = 6 * u2 - 6 * u
    e1 = 3 * u2 - 4 * u + 1
    e2 = -6 * u2 + 6 * u
    e3 = 3 * u2 - 2 * u
    gm = g0 = g1 = g2 = dgm = dg0 = dg1 = dg2 = 0.0
    for r in range(4):  # scalars, no array: this runs once per pixel
        row = jm if r == 0 else (j if r == 1 else (j1 if r == 2 else j2))
        v0 = values[row, lo]
        v1 = values[row, hi]
        m0 = slopes[row, lo] * h_t
        m1 = slopes[row, hi] * h_t
        f_r = b0 * v0 + b1 * m0 + b2 * v1 + b3 * m1
        df_r = (e0 * v0 + e1 * m0 + e2 * v1 + e3 * m1) / h_t
        f_r = f_r if inside else (0.0 if beyond else values[row, 0])
        df_r = df_r if inside else (0.0 if beyond else slopes[row, 0])
        if r == 0:
            gm, dgm = f_r, df_r
        elif r == 1:
            g0, dg0 = f_r, df_r
        elif r == 2:
            g1, dg1 = f_r, df_r
        else:
            g2, dg2 = f_r, df_r
    if x != x:
        gm = g0 = g1 = g2 = dgm = dg0 = dg1 = dg2 = x
    s0 = (g1 - gm) / (d_m + d_1)
    s1 = (g2 - g0) / (d_1 + d_2)
    ds0 = (dg1 - dgm) / (d_m + d_1)
    ds1 = (dg2 - dg0) / (d_1 + d_2)
    h = d_1
    t = (p - pj) / h
    t2 = t * t
    t3 = t2 * t
    h00 = 2 * t3 - 3 * t2 + 1
    h10 = (t3 - 2 * t2 + t) * h
    h01 = -2 * t3 + 3 * t2
    h11 = (t3 - t2) * h
    f = h00 * g0 + h10 * s0 + h01 * g1 + h11 * s1
    df_dtheta = h00 * dg0 + h10 * ds0 + h01 * dg1 + h11 * ds1
    df_dphi = (
        (6 * t2 - 6 * t) * g0
        + (3 * t2 - 4 * t + 1) * h * s0
        + (-6 * t2 + 6 * t) * g1
        + (3 * t2 - 2 * t) * h * s1
    ) / h
    return f, df_dtheta, df_dphi


@numba.njit(cache=True)
def rid_value_grad_direction(
    ux: float, uy: float, uz: float, rid: RIDData
) -> tuple[float, float, float, float]:
    """RID value and gradient with respect to a unit direction in the light frame.

    The gradient is the tangential one (perpendicular to u): moving u on the unit
    sphere by du changes f by grad . du.

    Args:
        ux, uy, uz: Unit direction from the emitter, light frame.
        rid: the RID.

    Returns:
        (f, gx, gy, gz).
    """
    kind = rid.kind
    if kind == KIND_ISOTROPIC:
        return 1.0, 0.0, 0.0, 0.0
    if kind == KIND_GRID_1D:
        f, g = grid1d_value_grad(uz, rid.grid, rid.params[2], rid.params[3], rid.params[4])
        return f, -g * uz * ux, -g * uz * uy, g * (1.0 - uz * uz)
    if kind == KIND_GRID_2D:
        return grid2d_value_grad(ux, uy, uz, rid.grid, rid.params[2], rid.params[3], rid.params[4])
    rho = math.sqrt(ux * ux + uy * uy)
    theta = math.atan2(rho, uz)
    # Only 2-D tables depend on the azimuth (an atan2 saved for the symmetric kinds).
    phi = math.atan2(uy, ux) if rho > 0.0 and kind == KIND_TABLE_2D else 0.0
    f, f_t, f_p = rid_value_grad(theta, phi, rid)
    # grad = f_t e_theta + (f_p / sin theta) e_phi, written without dividing by zero:
    # e_theta = (cos t cos p, cos t sin p, -sin t) = (uz ux / rho, uz uy / rho, -rho),
    # e_phi = (-sin p, cos p, 0) = (-uy / rho, ux / rho, 0).
    if rho < AXIS_RHO:
        # On the axis: the limit of f_t / sin(theta) is f''(0) for a smooth profile.
        _, f_t_eps, _ = rid_value_grad(AXIS_EPS, phi, rid)
        a = f_t_eps / AXIS_EPS
        return f, a * ux * uz, a * uy * uz, 0.0
    a = f_t / rho
    b = f_p / (rho * rho)
    return f, a * uz * ux - b * uy, a * uz * uy + b * ux, -f_t * rho


@numba.njit(cache=True, inline="always", error_model="numpy")
def rid_value_direction(ux: float, uy: float, uz: float, rid: RIDData) -> float:
    """RID value (no gradient) at a unit direction (ux, uy, uz) of the light frame.

    For the renderer's pixel loops: cos^m by `cos_power` (no libm call: the loop
    vectorises), the other symmetric models inline (a call per pixel passing arrays
    costs their reference counting), with the formulas of `rid_value_grad`.
    """
    kind = rid.kind
    if kind == KIND_ISOTROPIC:
        return 1.0
    if kind == KIND_COS_POWER:
        return cos_power(uz, rid.params[0])
    if kind == KIND_GRID_1D:
        return grid1d_value_grad(uz, rid.grid, rid.params[2], rid.params[3], rid.params[4])[0]
    if kind == KIND_GRID_2D:
        return grid2d_value_grad(ux, uy, uz, rid.grid, rid.params[2], rid.params[3], rid.params[4])[
            0
        ]
    rho = math.sqrt(ux * ux + uy * uy)
    theta = math.atan2(rho, uz)
    if kind == KIND_GAUSSIAN:
        return math.exp(-0.5 * (theta / rid.params[0]) ** 2)
    if kind == KIND_TABLE_1D:
        return hermite(theta, rid.theta_knots, rid.values[0], rid.slopes[0], rid.params[0])[0]
    phi = math.atan2(uy, ux) if rho > 0.0 else 0.0
    return rid_value_grad(theta, phi, rid)[0]


@numba.njit(cache=True)
def rid_eval_many(
    theta: np.ndarray, phi: np.ndarray, rid: RIDData
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Vectorised `rid_value_grad` over (N,) arrays: returns (f, df/dtheta, df/dphi)."""
    n = theta.shape[0]
    f = np.empty(n)
    ft = np.empty(n)
    fp = np.empty(n)
    for i in range(n):
        f[i], ft[i], fp[i] = rid_value_grad(theta[i], phi[i], rid)
    return f, ft, fp
