"""Compiled solid angles of triangles and quads (Van Oosterom and Strackee, 1983).

The Omega_j of docs/model.md: a footprint quad's exact solid angle seen from the light.
For a triangle with vertices a, b, c relative to the viewpoint,

    tan(Omega / 2) = a . ((b - a) x (c - a)) / (|a||b||c| + (a.b)|c| + (a.c)|b| + (b.c)|a|),

signed; a quad (P1, P2, P3, P4) is the triangles (P1 P2 P3) and (P1 P3 P4), its solid
angle the absolute value of their sum. `lightcal.core.solid_angle` is the NumPy reference
of the same formulas.

- `triangle_omega`: any triangle, with the gradient with respect to the viewpoint (the
  plain quad loop of `kernels.quad_flux`);
- on the wall z = 0, the numerator a . ((b - a) x (c - a)) is a_z (e1 x e2)_z exactly:
  `quad_terms` / `wall_quad_terms` give the numerators n1, n2 and denominators d1, d2 of
  a quad's two triangles from shared corner vectors and norms;
- `quad_omega` adds the two triangles with one arctangent when d1, d2 > 0 and
  d1 d2 - n1 n2 > 0: atan2(n1, d1) + atan2(n2, d2) = atan((n1 d2 + n2 d1) / (d1 d2 - n1 n2)),
  and for |x| <= ATAN_SERIES_MAX (pixel footprints: x ~ 1e-8) atan x is its odd series,
  exact in double precision; the two atan2 otherwise (large solid angles);
  `omega_series` is its branch-free common case for vectorised loops.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from lightcal.core.kernels.fastmath import ATAN_SERIES_MAX, atan_series


@numba.njit(cache=True, inline="always", fastmath=False)
def triangle_omega(
    lx: float,
    ly: float,
    lz: float,
    p1: tuple[float, float, float],
    p2: tuple[float, float, float],
    p3: tuple[float, float, float],
    want_grad: bool,
) -> tuple[float, float, float, float]:
    """Signed solid angle of a triangle seen from (lx, ly, lz) and its gradient."""
    ax = p1[0] - lx
    ay = p1[1] - ly
    az = p1[2] - lz
    bx = p2[0] - lx
    by = p2[1] - ly
    bz = p2[2] - lz
    cx = p3[0] - lx
    cy = p3[1] - ly
    cz = p3[2] - lz
    e1x = p2[0] - p1[0]
    e1y = p2[1] - p1[1]
    e1z = p2[2] - p1[2]
    e2x = p3[0] - p1[0]
    e2y = p3[1] - p1[1]
    e2z = p3[2] - p1[2]
    nx = e1y * e2z - e1z * e2y
    ny = e1z * e2x - e1x * e2z
    nz = e1x * e2y - e1y * e2x
    num = ax * nx + ay * ny + az * nz
    la = math.sqrt(ax * ax + ay * ay + az * az)
    lb = math.sqrt(bx * bx + by * by + bz * bz)
    lc = math.sqrt(cx * cx + cy * cy + cz * cz)
    ab = ax * bx + ay * by + az * bz
    ac = ax * cx + ay * cy + az * cz
    bc = bx * cx + by * cy + bz * cz
    den = la * lb * lc + ab * lc + ac * lb + bc * la
    omega = 2.0 * math.atan2(num, den)
    if not want_grad:
        return omega, 0.0, 0.0, 0.0
    # d num / dL = -(e1 x e2); d den / dL = -(sum of the terms below).
    ka = lb * lc / la + bc / la
    kb = la * lc / lb + ac / lb
    kc = la * lb / lc + ab / lc
    gdx = ka * ax + kb * bx + kc * cx + (ax + bx) * lc + (ax + cx) * lb + (bx + cx) * la
    gdy = ka * ay + kb * by + kc * cy + (ay + by) * lc + (ay + cy) * lb + (by + cy) * la
    gdz = ka * az + kb * bz + kc * cz + (az + bz) * lc + (az + cz) * lb + (bz + cz) * la
    s = 2.0 / (num * num + den * den)
    # d omega = s (den d num - num d den), with d num = -n and d den = -gd.
    return (
        omega,
        s * (-den * nx + num * gdx),
        s * (-den * ny + num * gdy),
        s * (-den * nz + num * gdz),
    )


@numba.njit(cache=True, error_model="numpy")
def quad_omega_signed(n1: float, d1: float, n2: float, d2: float) -> float:
    """2 atan2(n1, d1) + 2 atan2(n2, d2): a quad's signed solid angle from its triangles.

    One arctangent when d1, d2 and the combined denominator d1 d2 - n1 n2 are > 0
    (the sum then lies in (-pi/2, pi/2)); the two atan2 otherwise (large solid angles).
    """
    if d1 > 0.0 and d2 > 0.0:
        den = d1 * d2 - n1 * n2
        if den > 0.0:
            x = (n1 * d2 + n2 * d1) / den
            if abs(x) <= ATAN_SERIES_MAX:
                return 2.0 * atan_series(x)
            return 2.0 * math.atan(x)
    return 2.0 * math.atan2(n1, d1) + 2.0 * math.atan2(n2, d2)


@numba.njit(cache=True, error_model="numpy")
def quad_omega(n1: float, d1: float, n2: float, d2: float) -> float:
    """|2 atan2(n1, d1) + 2 atan2(n2, d2)|: a quad's solid angle (`quad_omega_signed`)."""
    return abs(quad_omega_signed(n1, d1, n2, d2))


@numba.njit(cache=True, inline="always", error_model="numpy")
def omega_series(n1: float, d1: float, n2: float, d2: float) -> tuple[float, bool]:
    """Branch-free `quad_omega` for the common case; the flag says when it does not apply."""
    den = d1 * d2 - n1 * n2
    x = (n1 * d2 + n2 * d1) / den
    bad = (d1 <= 0.0) | (d2 <= 0.0) | (den <= 0.0) | (not abs(x) <= ATAN_SERIES_MAX)
    return abs(2.0 * atan_series(x)), bad


@numba.njit(cache=True, inline="always", error_model="numpy")
def quad_terms(
    x1: float,
    y1: float,
    x2: float,
    y2: float,
    x3: float,
    y3: float,
    x4: float,
    y4: float,
    a_x: float,
    a_y: float,
    l1: float,
    b_x: float,
    b_y: float,
    l2: float,
    c_x: float,
    c_y: float,
    l3: float,
    d_x: float,
    d_y: float,
    l4: float,
    az: float,
) -> tuple[float, float, float, float]:
    """Van Oosterom-Strackee numerators and denominators of triangles (P1 P2 P3), (P1 P3 P4).

    P_k = (x_k, y_k, 0) on the wall, (k_x, k_y, az) = P_k - L and l_k = |P_k - L| for
    k = a, b, c, d. The numerator a.((P2 - P1) x (P3 - P1)) reduces to a_z times the z
    component of the cross product, exactly, since the edges have zero z.
    """
    e1x = x2 - x1
    e1y = y2 - y1
    e2x = x3 - x1
    e2y = y3 - y1
    e3x = x4 - x1
    e3y = y4 - y1
    n1 = az * (e1x * e2y - e1y * e2x)
    n2 = az * (e2x * e3y - e2y * e3x)
    azz = az * az
    ab = a_x * b_x + a_y * b_y + azz
    ac = a_x * c_x + a_y * c_y + azz
    bc = b_x * c_x + b_y * c_y + azz
    ad = a_x * d_x + a_y * d_y + azz
    cd = c_x * d_x + c_y * d_y + azz
    d1 = l1 * l2 * l3 + ab * l3 + ac * l2 + bc * l1
    d2 = l1 * l3 * l4 + ac * l4 + ad * l3 + cd * l1
    return n1, d1, n2, d2


@numba.njit(cache=True, inline="always", error_model="numpy")
def wall_quad_terms(
    corners_world: np.ndarray, i: int, k: int, lx: float, ly: float, lz: float
) -> tuple[float, float, float, float]:
    """`quad_terms` (n1, d1, n2, d2) of quad corners_world[i, k] (4, 3) on the wall z = 0."""
    x1 = corners_world[i, k, 0, 0]
    y1 = corners_world[i, k, 0, 1]
    x2 = corners_world[i, k, 1, 0]
    y2 = corners_world[i, k, 1, 1]
    x3 = corners_world[i, k, 2, 0]
    y3 = corners_world[i, k, 2, 1]
    x4 = corners_world[i, k, 3, 0]
    y4 = corners_world[i, k, 3, 1]
    az = 0.0 - lz
    azz = az * az
    a_x = x1 - lx
    a_y = y1 - ly
    b_x = x2 - lx
    b_y = y2 - ly
    c_x = x3 - lx
    c_y = y3 - ly
    d_x = x4 - lx
    d_y = y4 - ly
    l1 = math.sqrt(a_x * a_x + a_y * a_y + azz)
    l2 = math.sqrt(b_x * b_x + b_y * b_y + azz)
    l3 = math.sqrt(c_x * c_x + c_y * c_y + azz)
    l4 = math.sqrt(d_x * d_x + d_y * d_y + azz)
    return quad_terms(
        x1, y1, x2, y2, x3, y3, x4, y4, a_x, a_y, l1, b_x, b_y, l2, c_x, c_y, l3, d_x, d_y, l4, az
    )


@numba.njit(cache=True, error_model="numpy")
def wall_quad_omega_signed(
    corners_world: np.ndarray, i: int, k: int, lx: float, ly: float, lz: float
) -> float:
    """Signed solid angle of quad corners_world[i, k] (4, 3) on the wall, any size."""
    return quad_omega_signed(*wall_quad_terms(corners_world, i, k, lx, ly, lz))
