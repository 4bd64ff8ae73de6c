"""The light's flat port compiled: the flux of pixels lit through it.

The model is docs/model.md's "The light's flat port", written out in NumPy in
`lightcal.core.light_port` (the path equation, its solve and du_a/dY) and
`lightcal.core.light_port_flux` (the sub-quads' spherical-quad solid angles, the RID,
the port's Fresnel transmittance and the pull-back of the gradients to the pose). Here
the same formulas, in the same order, run point by point:

- the paths' directions and du_a/dY's factors come from `kernels.port_paths.solve_paths`
  (the path equation solved in the water's slope from the paraxial start);
- `port_flux_pixels`: the flux of pixels lit through the port and d flux / d (L, delta),
  quad by quad, sub-quad by sub-quad: the lattice's and centroids' paths, then the
  solid angles and their derivatives, the RID and T_F at the centroids, the pull-back
  through du_a/dY, summed per pixel (`light_port_flux.quads_flux`). On all threads in
  chunks of pixels (`numba.prange`) past `PORT_SERIAL_POINTS`.

The numbers are NumPy's to round-off (tests/test_light_port_kernels.py compares them
with the NumPy code kept in tests/light_port_numpy.py).
"""

from __future__ import annotations

import math

import numba
import numpy as np

from lightcal.core.kernels.port_paths import PATH_SIZE, WORK_SIZE, solve_paths
from lightcal.core.rid_eval import (
    AXIS_RHO,
    KIND_COS_POWER,
    RIDData,
    RIDTuple,
    rid_value_grad_direction,
)

#: Below this many path solves (pixels x quads x lattice points and centroids; about
#: 3 ms on one thread: 5,000 pixels at n = 1) the pixels run on the calling thread. On
#: 2 cores shared with other work the pool took 8-16 ms to come back (measured: 1,000
#: pixels 0.9 ms on one thread, 16 ms on the pool; 4,000 pixels 3.9 and 15 ms).
PORT_SERIAL_POINTS = 25_000


@numba.njit(cache=True, inline="always", error_model="numpy")
def _pull_back(
    p: np.ndarray, n: np.ndarray, g0: float, g1: float, g2: float, y: np.ndarray, acc: np.ndarray
) -> None:
    """(du_a/dY)^T g of one path p (`solve_paths`' row) added to acc[:3], and its cross
    product with the point y added to acc[3:] (`PortPaths.pull_back`)."""
    gu_n = g0 * n[0] + g1 * n[1] + g2 * n[2]
    gu_r = g0 * p[3] + g1 * p[4] + g2 * p[5]
    k = p[9]
    sc = p[10] * gu_n
    o0 = k * (g0 - gu_n * n[0]) + (p[6] - k * p[3]) * gu_r - sc * p[6]
    o1 = k * (g1 - gu_n * n[1]) + (p[7] - k * p[4]) * gu_r - sc * p[7]
    o2 = k * (g2 - gu_n * n[2]) + (p[8] - k * p[5]) * gu_r - sc * p[8]
    acc[0] += o0
    acc[1] += o1
    acc[2] += o2
    acc[3] += o1 * y[2] - o2 * y[1]
    acc[4] += o2 * y[0] - o0 * y[2]
    acc[5] += o0 * y[1] - o1 * y[0]


@numba.njit(cache=True, inline="always", error_model="numpy")
def _rid_at(ux: float, uy: float, uz: float, rid: RIDData) -> tuple[float, float, float, float]:
    """`rid_value_grad_direction` of the unit direction u, cos^m written in u: f = uz^m,
    grad = -m f (ux, uy, -rho^2 / uz) (tan(theta) = rho / uz), where the general code takes
    atan2, cos and tan of theta (the same to round-off); the other kinds and the axis as
    there."""
    if rid.kind == KIND_COS_POWER:
        rho2 = ux * ux + uy * uy
        if uz > 0.0 and rho2 >= AXIS_RHO * AXIS_RHO:
            m = rid.params[0]
            f = uz**m
            c = -m * f
            return f, c * ux, c * uy, -c * rho2 / uz
    return rid_value_grad_direction(ux, uy, uz, rid)


@numba.njit(cache=True, inline="always", error_model="numpy")
def _reflectance(
    n1: float, n2: float, c_i: float, dc_i: float, c_t: float, dc_t: float, s_pol: bool
) -> tuple[float, float]:
    """R = r^2 of one interface (`fresnel._reflectance`) and its derivative, given the
    cosines' derivatives dc_i, dc_t."""
    if s_pol:
        a, b = n1 * c_i - n2 * c_t, n1 * c_i + n2 * c_t
        da, db = n1 * dc_i - n2 * dc_t, n1 * dc_i + n2 * dc_t
    else:
        a, b = n2 * c_i - n1 * c_t, n2 * c_i + n1 * c_t
        da, db = n2 * dc_i - n1 * dc_t, n2 * dc_i + n1 * dc_t
    i_b = 1.0 / b
    r = a * i_b
    return r * r, 2.0 * r * (da - r * db) * i_b


@numba.njit(cache=True, error_model="numpy")
def transmittance(c: float, n_a: float, n_g: float, n_w: float) -> tuple[float, float]:
    """`fresnel.port_transmittance` of one cos_air: T and dT/dcos, differentiated by hand
    (the complex step it replaced took 0.3-0.4 us, this 0.03; the same to round-off:
    4e-15 in T and 7e-14 in dT/dcos for cos_air >= 0.01)."""
    sin2 = 1.0 - c * c
    k_g, k_w = (n_a / n_g) ** 2, (n_a / n_w) ** 2
    cos_g = math.sqrt(1.0 - k_g * sin2)
    cos_w = math.sqrt(1.0 - k_w * sin2)
    dcos_g, dcos_w = k_g * c / cos_g, k_w * c / cos_w
    total = 0.0
    d_total = 0.0
    for s_pol in (True, False):
        r1, dr1 = _reflectance(n_a, n_g, c, 1.0, cos_g, dcos_g, s_pol)
        r2, dr2 = _reflectance(n_g, n_w, cos_g, dcos_g, cos_w, dcos_w, s_pol)
        num = (1.0 - r1) * (1.0 - r2)
        d_num = -dr1 * (1.0 - r2) - (1.0 - r1) * dr2
        i_den = 1.0 / (1.0 - r1 * r2)
        term = num * i_den
        total += term
        d_total += (d_num + term * (dr1 * r2 + r1 * dr2)) * i_den
    return 0.5 * total, 0.5 * d_total


@numba.njit(cache=True, inline="always", error_model="numpy")
def _triangle(
    a: np.ndarray, b: np.ndarray, c: np.ndarray, grad: np.ndarray, want_grad: bool
) -> float:
    """Signed solid angle of the spherical triangle of unit vectors a, b, c (3,) (Van
    Oosterom-Strackee, as tests/light_port_numpy.py's `spherical_triangle`); when
    want_grad, dOmega/da, db, dc into grad (3, 3)."""
    e0, e1, e2 = b[0] - a[0], b[1] - a[1], b[2] - a[2]
    f0, f1, f2 = c[0] - a[0], c[1] - a[1], c[2] - a[2]
    num = a[0] * (e1 * f2 - e2 * f1) + a[1] * (e2 * f0 - e0 * f2) + a[2] * (e0 * f1 - e1 * f0)
    ab = a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
    ac = a[0] * c[0] + a[1] * c[1] + a[2] * c[2]
    bc = b[0] * c[0] + b[1] * c[1] + b[2] * c[2]
    den = 1.0 + ab + ac + bc
    if want_grad:
        sc = 2.0 / (num * num + den * den)
        for j in range(3):
            j1, j2 = (j + 1) % 3, (j + 2) % 3
            grad[0, j] = sc * (den * (b[j1] * c[j2] - b[j2] * c[j1]) - num * (b[j] + c[j]))
            grad[1, j] = sc * (den * (c[j1] * a[j2] - c[j2] * a[j1]) - num * (a[j] + c[j]))
            grad[2, j] = sc * (den * (a[j1] * b[j2] - a[j2] * b[j1]) - num * (a[j] + b[j]))
    return 2.0 * math.atan2(num, den)


@numba.njit(cache=True, inline="always", error_model="numpy")
def to_light(x: np.ndarray, light: np.ndarray, R: np.ndarray, out: np.ndarray) -> None:
    """out = R^T (x - L) (3,)."""
    x0, x1, x2 = x[0] - light[0], x[1] - light[1], x[2] - light[2]
    for j in range(3):
        out[j] = x0 * R[0, j] + x1 * R[1, j] + x2 * R[2, j]


@numba.njit(cache=True, error_model="numpy")
def _pixels_range(
    lo: int, hi: int, corners: np.ndarray, weights: np.ndarray, light: np.ndarray,
    R: np.ndarray, rid: RIDData, normal: np.ndarray, geometry: np.ndarray, n_sub: int,
    want_grad: bool, out_flux: np.ndarray, out_lit: np.ndarray, out_grad: np.ndarray,
) -> None:  # fmt: skip
    """`port_flux_pixels` of the pixels lo..hi-1 (scratch buffers for the range)."""
    d, t, n_g, n_w = geometry[0], geometry[1], geometry[2], geometry[3]
    n_a, i_g, i_w = geometry[4], geometry[5], geometry[6]
    m1 = n_sub + 1
    n_lat = m1 * m1
    n_pts = n_lat + n_sub * n_sub  # the lattice's points, then the centroids
    lat_w = np.empty((m1, m1, 3))
    ys = np.empty((n_pts, 3))
    paths = np.empty((n_pts, PATH_SIZE))
    g_lat = np.empty((n_lat, 3))
    xw = np.empty(3)
    work = np.empty((n_pts, WORK_SIZE))
    active = np.empty(n_pts, dtype=np.bool_)
    ok = np.empty(n_pts, dtype=np.bool_)
    d1 = np.empty((3, 3))
    d2 = np.empty((3, 3))
    acc = np.empty(6)
    for i in range(lo, hi):
        flux = 0.0
        acc[:] = 0.0
        lit = True
        for kq in range(corners.shape[1]):
            w = weights[i, kq]
            for ti in range(m1):
                tt = ti / n_sub
                for si in range(m1):
                    ss = si / n_sub
                    w1, w2, w3, w4 = (1 - ss) * (1 - tt), ss * (1 - tt), ss * tt, (1 - ss) * tt
                    for j in range(3):
                        lat_w[ti, si, j] = (
                            w1 * corners[i, kq, 0, j] + w2 * corners[i, kq, 1, j]
                            + w3 * corners[i, kq, 2, j] + w4 * corners[i, kq, 3, j]
                        )  # fmt: skip
                        g_lat[ti * m1 + si, j] = 0.0
                    to_light(lat_w[ti, si], light, R, ys[ti * m1 + si])
            for ti in range(n_sub):
                for si in range(n_sub):
                    for j in range(3):
                        xw[j] = 0.25 * (
                            lat_w[ti, si, j] + lat_w[ti, si + 1, j]
                            + lat_w[ti + 1, si + 1, j] + lat_w[ti + 1, si, j]
                        )  # fmt: skip
                    to_light(xw, light, R, ys[n_lat + ti * n_sub + si])
            if not solve_paths(ys, n_pts, normal, d, t, n_g, n_w, work, active, ok, paths):
                lit = False
                break
            for ti in range(n_sub):
                for si in range(n_sub):
                    c00, c01 = ti * m1 + si, ti * m1 + si + 1
                    c11, c10 = c01 + m1, c00 + m1
                    cj = n_lat + ti * n_sub + si
                    cp = paths[cj]
                    p1, p3 = paths[c00], paths[c11]
                    signed = _triangle(p1, paths[c01], p3, d1, want_grad)
                    signed += _triangle(p1, p3, paths[c10], d2, want_grad)
                    omega = abs(signed)
                    f, f0, f1, f2 = _rid_at(cp[0], cp[1], cp[2], rid)
                    cos_c = cp[0] * normal[0] + cp[1] * normal[1] + cp[2] * normal[2]
                    tf, dtf = transmittance(min(max(cos_c, 1e-300), 1.0), n_a, i_g, i_w)
                    ft = f * tf
                    flux += w * omega * ft
                    if not want_grad:
                        continue
                    sign = 1.0 if signed > 0.0 else (-1.0 if signed < 0.0 else 0.0)
                    c = w * ft * sign
                    for j in range(3):
                        g_lat[c00, j] += c * (d1[0, j] + d2[0, j])
                        g_lat[c01, j] += c * d1[1, j]
                        g_lat[c11, j] += c * (d1[2, j] + d2[1, j])
                        g_lat[c10, j] += c * d2[2, j]
                    wo = w * omega
                    fd = f * dtf
                    _pull_back(
                        cp, normal, wo * (tf * f0 + fd * normal[0]),
                        wo * (tf * f1 + fd * normal[1]), wo * (tf * f2 + fd * normal[2]),
                        ys[cj], acc,
                    )  # fmt: skip
            if want_grad:
                for c0 in range(n_lat):
                    g = g_lat[c0]
                    _pull_back(paths[c0], normal, g[0], g[1], g[2], ys[c0], acc)
        out_lit[i] = lit
        out_flux[i] = flux if lit else 0.0
        if want_grad:
            for j in range(3):
                out_grad[i, j] = 0.0
                out_grad[i, 3 + j] = 0.0
                if lit:
                    out_grad[i, j] = -(acc[0] * R[j, 0] + acc[1] * R[j, 1] + acc[2] * R[j, 2])
                    out_grad[i, 3 + j] = acc[3] * R[j, 0] + acc[4] * R[j, 1] + acc[5] * R[j, 2]


@numba.njit(cache=True, parallel=True, error_model="numpy")
def _pixels_parallel(
    corners: np.ndarray, weights: np.ndarray, light: np.ndarray, R: np.ndarray,
    rid: RIDTuple, normal: np.ndarray, geometry: np.ndarray, n_sub: int, want_grad: bool,
    out_flux: np.ndarray, out_lit: np.ndarray, out_grad: np.ndarray,
) -> None:  # fmt: skip
    """`_pixels_range` on all threads, in chunks of pixels."""
    n = corners.shape[0]
    n_chunks = min(n, 256)
    for ch in numba.prange(n_chunks):
        _pixels_range(
            ch * n // n_chunks, (ch + 1) * n // n_chunks, corners, weights, light, R,
            RIDData(*rid), normal, geometry, n_sub, want_grad, out_flux, out_lit, out_grad,
        )  # fmt: skip


@numba.njit(cache=True, error_model="numpy")
def _pixels_serial(
    corners: np.ndarray, weights: np.ndarray, light: np.ndarray, R: np.ndarray,
    rid: RIDTuple, normal: np.ndarray, geometry: np.ndarray, n_sub: int, want_grad: bool,
    out_flux: np.ndarray, out_lit: np.ndarray, out_grad: np.ndarray,
) -> None:  # fmt: skip
    """`_pixels_range` on the calling thread."""
    _pixels_range(
        int(0),  # noqa: UP018, RUF046 (not a literal type)
        corners.shape[0], corners, weights, light, R, RIDData(*rid), normal, geometry,
        n_sub, want_grad, out_flux, out_lit, out_grad,
    )  # fmt: skip


def port_flux_pixels(
    corners_world: np.ndarray,
    weights: np.ndarray,
    light_world: np.ndarray,
    R_world_light: np.ndarray,
    rid: RIDTuple,
    normal: np.ndarray,
    geometry: np.ndarray,
    n_sub: int,
    want_grad: bool,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """sum_k weight_k Phi_k / I0 of M pixels lit through the light's port and its
    gradients (`light_port_flux.quads_flux`, which documents the arguments).

    Args:
        rid: `rid_eval.rid_tuple` of the RID; normal: (3,) the port's unit normal (light
            frame); geometry: (7,) d, t, n_g / n_a, n_w / n_a, n_a, n_g, n_w.

    Returns:
        flux (M,), lit (M,) and grad (M, 6) ((0, 6) when not want_grad).
    """
    m, k = corners_world.shape[:2]
    flux = np.empty(m)
    lit = np.empty(m, dtype=np.bool_)
    grad = np.zeros((m, 6) if want_grad else (0, 6))
    points = m * k * ((n_sub + 1) ** 2 + n_sub * n_sub)
    kernel = _pixels_serial if points < PORT_SERIAL_POINTS else _pixels_parallel
    kernel(
        np.ascontiguousarray(corners_world, dtype=np.float64),
        np.ascontiguousarray(weights, dtype=np.float64),
        np.ascontiguousarray(light_world, dtype=np.float64),
        np.ascontiguousarray(R_world_light, dtype=np.float64),
        rid, np.ascontiguousarray(normal, dtype=np.float64),
        np.ascontiguousarray(geometry, dtype=np.float64), int(n_sub), bool(want_grad),
        flux, lit, grad,
    )  # fmt: skip
    return flux, lit, grad
