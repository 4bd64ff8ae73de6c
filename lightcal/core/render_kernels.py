"""Compiled (numba) kernels of the energy-preserving renderer.

The model (see docs/conventions.md and MODEL.md): a footprint quad Q on the wall
receives the flux Phi_Q = I0 * sum_j Omega_j f(w_j) over its n x n sub-quads (n = 1:
the quad itself), Omega_j the exact solid angle of sub-quad j seen from the light and
w_j the direction from the light to its centroid. Pixel values are
offset + gain * sum_lights scale * sum_k weight_k Phi_k over the quads k of a pixel
(one quad, or the b x b pixels of a binned super-pixel), the weights carrying the
sensor model. These kernels compute the flux sums and, for the solver, their gradients
with respect to the light position (world frame) and a left rotation perturbation of
the light's orientation (world frame).

Entry points: `render_image_fused` (whole images, what `render.render_image` calls),
`flux_pixels` (any pixels, with gradients, what `render.shade` calls) and
`undistorted_corner_grid` (the per-camera corner grid). `geometry_image` + `flux_image`
are the plain full-image kernels, kept as the straightforward version of the fused one.

`lightcal.core.render_reference` is the plain NumPy implementation of the same model
that the tests compare these kernels against.
"""

from __future__ import annotations

import math
from typing import Any

import numba
import numpy as np
from numba import types
from numba.extending import intrinsic

from lightcal.core.distortion import undistort_normalized
from lightcal.core.rid_eval import (
    KIND_COS_POWER,
    KIND_GAUSSIAN,
    KIND_ISOTROPIC,
    KIND_TABLE_1D,
    RIDData,
    hermite,
    rid_value_grad,
    rid_value_grad_direction,
)

SENSOR_RADIANCE = 0
SENSOR_COS4 = 1
SENSOR_PAPER = 2
SENSOR_MAP = 3


@numba.njit(cache=True, inline="always", fastmath=False)
def _triangle(
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


@numba.njit(cache=True, inline="always")
def _bilerp(q: np.ndarray, s: float, t: float) -> tuple[float, float, float]:
    """Point (s, t) of the bilinear patch through the quad q (4, 3); corners at s, t in {0, 1}."""
    if s == 0.0 and t == 0.0:
        return q[0, 0], q[0, 1], q[0, 2]
    if s == 1.0 and t == 0.0:
        return q[1, 0], q[1, 1], q[1, 2]
    if s == 1.0 and t == 1.0:
        return q[2, 0], q[2, 1], q[2, 2]
    if s == 0.0 and t == 1.0:
        return q[3, 0], q[3, 1], q[3, 2]
    w1 = (1 - s) * (1 - t)
    w2 = s * (1 - t)
    w3 = s * t
    w4 = (1 - s) * t
    return (
        w1 * q[0, 0] + w2 * q[1, 0] + w3 * q[2, 0] + w4 * q[3, 0],
        w1 * q[0, 1] + w2 * q[1, 1] + w3 * q[2, 1] + w4 * q[3, 1],
        w1 * q[0, 2] + w2 * q[1, 2] + w3 * q[2, 2] + w4 * q[3, 2],
    )


@numba.njit(cache=True, inline="always")
def _quad_flux(
    q: np.ndarray,
    lx: float,
    ly: float,
    lz: float,
    R_world_light: np.ndarray,
    rid_kind: int,
    rid_params: np.ndarray,
    rid_theta: np.ndarray,
    rid_phi: np.ndarray,
    rid_values: np.ndarray,
    rid_slopes: np.ndarray,
    n_sub: int,
    want_grad: bool,
    grad: np.ndarray,
) -> float:
    """Flux sum_j Omega_j f(w_j) of one planar quad q (4, 3), split n_sub x n_sub.

    When want_grad, adds d flux / d L_world to grad[0:3] and d flux / d delta_world
    (left rotation perturbation of the light) to grad[3:6].
    """
    total = 0.0
    for jt in range(n_sub):
        # k / n (a division, not k * (1 / n)) so neighbouring sub-quads share exact edges.
        t0 = jt / n_sub
        t1 = (jt + 1) / n_sub
        for js in range(n_sub):
            s0 = js / n_sub
            s1 = (js + 1) / n_sub
            p1 = _bilerp(q, s0, t0)
            p2 = _bilerp(q, s1, t0)
            p3 = _bilerp(q, s1, t1)
            p4 = _bilerp(q, s0, t1)
            o1, g1x, g1y, g1z = _triangle(lx, ly, lz, p1, p2, p3, want_grad)
            o2, g2x, g2y, g2z = _triangle(lx, ly, lz, p1, p3, p4, want_grad)
            omega = o1 + o2
            sign = 1.0
            if omega < 0.0:
                omega = -omega
                sign = -1.0
            if rid_kind == KIND_ISOTROPIC:
                total += omega
                if want_grad:
                    grad[0] += sign * (g1x + g2x)
                    grad[1] += sign * (g1y + g2y)
                    grad[2] += sign * (g1z + g2z)
                continue
            # Direction from the light to the sub-quad's centroid, world and light frames.
            mx = 0.25 * (p1[0] + p2[0] + p3[0] + p4[0]) - lx
            my = 0.25 * (p1[1] + p2[1] + p3[1] + p4[1]) - ly
            mz = 0.25 * (p1[2] + p2[2] + p3[2] + p4[2]) - lz
            r = math.sqrt(mx * mx + my * my + mz * mz)
            wx = mx / r
            wy = my / r
            wz = mz / r
            ux = R_world_light[0, 0] * wx + R_world_light[1, 0] * wy + R_world_light[2, 0] * wz
            uy = R_world_light[0, 1] * wx + R_world_light[1, 1] * wy + R_world_light[2, 1] * wz
            uz = R_world_light[0, 2] * wx + R_world_light[1, 2] * wy + R_world_light[2, 2] * wz
            f, gux, guy, guz = rid_value_grad_direction(
                ux, uy, uz, rid_kind, rid_params, rid_theta, rid_phi, rid_values, rid_slopes
            )
            total += omega * f
            if want_grad:
                # Gradient of f with respect to the world direction w (tangential).
                gwx = (
                    R_world_light[0, 0] * gux
                    + R_world_light[0, 1] * guy
                    + R_world_light[0, 2] * guz
                )
                gwy = (
                    R_world_light[1, 0] * gux
                    + R_world_light[1, 1] * guy
                    + R_world_light[1, 2] * guz
                )
                gwz = (
                    R_world_light[2, 0] * gux
                    + R_world_light[2, 1] * guy
                    + R_world_light[2, 2] * guz
                )
                # d w / d L = -(I - w w^T) / r; gw is tangential, so d f / d L = -gw / r.
                grad[0] += f * sign * (g1x + g2x) - omega * gwx / r
                grad[1] += f * sign * (g1y + g2y) - omega * gwy / r
                grad[2] += f * sign * (g1z + g2z) - omega * gwz / r
                # Left perturbation R -> exp(delta) R moves w to w + w x delta,
                # so d f / d delta = gw x w.
                grad[3] += omega * (gwy * wz - gwz * wy)
                grad[4] += omega * (gwz * wx - gwx * wz)
                grad[5] += omega * (gwx * wy - gwy * wx)
    return total


# ---------------------------------------------------------------------------------------
# Fast paths. Everything below computes the same numbers as the kernels above (to a few
# ulp, see tests/test_render_kernels_speedpath.py) with less work per pixel:
# - a full image shares each pixel corner between four pixels: its back-projection, its
#   vector a = P - L and the norm |a| are computed once per corner and light;
# - the wall is z = 0, so a.((b - a) x (c - a)) = a_z (e1 x e2)_z exactly;
# - the two triangles of a quad need one arctangent, not two: with d1, d2 > 0,
#   atan2(n1, d1) + atan2(n2, d2) = atan((n1 d2 + n2 d1) / (d1 d2 - n1 n2)) while the
#   combined denominator is > 0 (else both atan2 are evaluated as before), and
#   atan(x) = x - x^3/3 + ... + x^9/9 to double precision for |x| <= ATAN_SERIES_MAX;
# - a cosine-power RID needs cos(theta) = u_z only, c^m = exp(m ln c) with the branch-free
#   `log_positive` / `exp_real` below, so that LLVM vectorises the whole pixel loop
#   (AVX2: 4 pixels per instruction; numba has no vector math library for libm calls).
# ---------------------------------------------------------------------------------------

#: |x| up to which the odd series of atan to x^9 is exact: the first omitted term is
#: x^11 / 11, below 1e-18 |x| there.
ATAN_SERIES_MAX = 0.02

_LN2_HI = 6.93147180369123816490e-01  # ln 2 rounded to 21 bits: k * _LN2_HI is exact
_LN2_LO = 1.90821492927058770002e-10  # ln 2 - _LN2_HI
_INV_LN2 = 1.4426950408889634
_SQRT2 = 1.4142135623730951
_TINY_NORMAL = 2.2250738585072014e-308


def _float_bits_typer(typingctx: Any, x: Any) -> Any:
    """The IEEE 754 bits of a float64 as an int64 (an LLVM bitcast, vectorisable)."""
    if not isinstance(x, types.Float):
        return None
    sig = types.int64(types.float64)

    def codegen(context: Any, builder: Any, signature: Any, args: Any) -> Any:
        return builder.bitcast(args[0], context.get_value_type(types.int64))

    return sig, codegen


def _bits_float_typer(typingctx: Any, n: Any) -> Any:
    """The float64 whose IEEE 754 bits are the int64 n (an LLVM bitcast)."""
    if not isinstance(n, types.Integer):
        return None
    sig = types.float64(types.int64)

    def codegen(context: Any, builder: Any, signature: Any, args: Any) -> Any:
        return builder.bitcast(args[0], context.get_value_type(types.float64))

    return sig, codegen


_float_bits: Any = intrinsic(_float_bits_typer)
_bits_float: Any = intrinsic(_bits_float_typer)


@numba.njit(cache=True, inline="always", error_model="numpy")
def log_positive(x: float) -> float:
    """Natural logarithm of a finite x > 0, within 2 ulp, without a libm call.

    x = 2^k m with m in [sqrt(1/2), sqrt(2)); ln m = 2 atanh(s), s = (m - 1) / (m + 1),
    |s| <= 0.172, summed to s^25 (the next term is below 1e-20 relative).
    """
    sub = x < _TINY_NORMAL
    x = x * 18014398509481984.0 if sub else x  # 2^54: subnormals become normal
    bits = _float_bits(x)
    m = _bits_float((bits & 0x000FFFFFFFFFFFFF) | 0x3FF0000000000000)
    # The biased exponent (11 bits) as a float, by the 2^52 trick: no int -> float
    # conversion, which AVX2 lacks for 64-bit integers and would stop vectorisation.
    kf = _bits_float((bits >> 52) | 0x4330000000000000) - 4503599627370496.0
    kf = kf - (1023.0 + 54.0 if sub else 1023.0)
    big = m > _SQRT2
    m = m * 0.5 if big else m
    kf = kf + 1.0 if big else kf
    f = m - 1.0
    s = f / (2.0 + f)
    z = s * s
    # p(z) = sum_i z^i / (2 i + 3), i = 0..11, by Estrin's scheme (short dependency chains:
    # the loop is latency bound with Horner's).
    z2 = z * z
    z4 = z2 * z2
    z8 = z4 * z4
    q0 = 1.0 / 3.0 + z * (1.0 / 5.0)
    q1 = 1.0 / 7.0 + z * (1.0 / 9.0)
    q2 = 1.0 / 11.0 + z * (1.0 / 13.0)
    q3 = 1.0 / 15.0 + z * (1.0 / 17.0)
    q4 = 1.0 / 19.0 + z * (1.0 / 21.0)
    q5 = 1.0 / 23.0 + z * (1.0 / 25.0)
    p = (q0 + q1 * z2) + (q2 + q3 * z2) * z4 + (q4 + q5 * z2) * z8
    return kf * _LN2_HI + (2.0 * s + (2.0 * s * z * p + kf * _LN2_LO))


@numba.njit(cache=True, inline="always", error_model="numpy")
def exp_real(y: float) -> float:
    """exp(y) for y <= 709, within 2 ulp, without a libm call; 0 below -1400.

    y = k ln 2 + r with |r| <= ln(2) / 2, exp(r) by its Taylor series to r^13 (the next
    term is below 1e-17 relative), times 2^k built from its bits in two factors so that
    results down to the subnormal range come out right.
    """
    kf = np.floor(y * _INV_LN2 + 0.5)  # np.floor stays a float (math.floor: an int)
    kf = max(kf, -2000.0)
    r = (y - kf * _LN2_HI) - kf * _LN2_LO
    # sum_i r^i / i!, i = 0..13, by Estrin's scheme.
    r2 = r * r
    r4 = r2 * r2
    r8 = r4 * r4
    q0 = 1.0 + r
    q1 = 1.0 / 2.0 + r * (1.0 / 6.0)
    q2 = 1.0 / 24.0 + r * (1.0 / 120.0)
    q3 = 1.0 / 720.0 + r * (1.0 / 5040.0)
    q4 = 1.0 / 40320.0 + r * (1.0 / 362880.0)
    q5 = 1.0 / 3628800.0 + r * (1.0 / 39916800.0)
    q6 = 1.0 / 479001600.0 + r * (1.0 / 6227020800.0)
    p = ((q0 + q1 * r2) + (q2 + q3 * r2) * r4) + ((q4 + q5 * r2) + q6 * r4) * r8
    # k = kf as an integer from the bits of kf + 1.5 * 2^52 (no float -> int conversion).
    k = _float_bits(kf + 6755399441055744.0) - 0x4338000000000000
    k1 = k >> 1
    k2 = k - k1
    res = p * _bits_float((k1 + 1023) << 52) * _bits_float((k2 + 1023) << 52)
    return res if y > -1400.0 else 0.0


@numba.njit(cache=True, inline="always", error_model="numpy")
def cos_power(c: float, m: float) -> float:
    """c^m for c > 0 (0 for c <= 0): the cosine-power RID at cos(theta) = c.

    exp(m ln c): relative error about (|m ln c| + 4) ulp against libm's pow, i.e. below
    1e-14 wherever c^m > 1e-40 and m <= 100.
    """
    pos = c > 0.0
    v = exp_real(m * log_positive(c if pos else 1.0))
    return v if pos else 0.0


@numba.njit(cache=True, inline="always", error_model="numpy")
def atan_series(x: float) -> float:
    """atan(x) for |x| <= ATAN_SERIES_MAX (odd series to x^9)."""
    x2 = x * x
    return x * (1.0 + x2 * (-1.0 / 3.0 + x2 * (0.2 + x2 * (-1.0 / 7.0 + x2 * (1.0 / 9.0)))))


@numba.njit(cache=True, error_model="numpy")
def quad_omega(n1: float, d1: float, n2: float, d2: float) -> float:
    """|2 atan2(n1, d1) + 2 atan2(n2, d2)|: a quad's solid angle from its two triangles.

    One arctangent when d1, d2 and the combined denominator d1 d2 - n1 n2 are > 0
    (the sum then lies in (-pi/2, pi/2)); the two atan2 otherwise (large solid angles).
    """
    if d1 > 0.0 and d2 > 0.0:
        den = d1 * d2 - n1 * n2
        if den > 0.0:
            x = (n1 * d2 + n2 * d1) / den
            if abs(x) <= ATAN_SERIES_MAX:
                return abs(2.0 * atan_series(x))
            return abs(2.0 * math.atan(x))
    return abs(2.0 * math.atan2(n1, d1) + 2.0 * math.atan2(n2, d2))


@numba.njit(cache=True, inline="always", error_model="numpy")
def _rid_value(
    ux: float,
    uy: float,
    uz: float,
    kind: int,
    params: np.ndarray,
    theta_knots: np.ndarray,
    phi_knots: np.ndarray,
    values: np.ndarray,
    slopes: np.ndarray,
) -> float:
    """RID value (no gradient) at a unit direction (ux, uy, uz) of the light frame."""
    if kind == KIND_ISOTROPIC:
        return 1.0
    if kind == KIND_COS_POWER:
        return cos_power(uz, params[0])
    rho = math.sqrt(ux * ux + uy * uy)
    theta = math.atan2(rho, uz)
    # Symmetric models inline (a call per pixel passing arrays costs their reference
    # counting); the same formulas as `rid_value_grad`.
    if kind == KIND_GAUSSIAN:
        return math.exp(-0.5 * (theta / params[0]) ** 2)
    if kind == KIND_TABLE_1D:
        return hermite(theta, theta_knots, values[0], slopes[0])[0]
    phi = math.atan2(uy, ux) if rho > 0.0 else 0.0
    return rid_value_grad(theta, phi, kind, params, theta_knots, phi_knots, values, slopes)[0]


@numba.njit(cache=True, inline="always", error_model="numpy")
def _quad_flux_fast(
    corners_world: np.ndarray,
    i: int,
    k: int,
    lx: float,
    ly: float,
    lz: float,
    R_world_light: np.ndarray,
    rid_kind: int,
    rid_params: np.ndarray,
    rid_theta: np.ndarray,
    rid_phi: np.ndarray,
    rid_values: np.ndarray,
    rid_slopes: np.ndarray,
) -> float:
    """Omega f of quad corners_world[i, k] (4, 3) on the wall z = 0.

    `_quad_flux` with n = 1 and no gradient; indices, not a view: a view per pixel costs.
    """
    omega = quad_omega(*_wall_quad_terms(corners_world, i, k, lx, ly, lz))
    if rid_kind == KIND_ISOTROPIC:
        return omega
    c = corners_world
    mx = 0.25 * (c[i, k, 0, 0] + c[i, k, 1, 0] + c[i, k, 2, 0] + c[i, k, 3, 0]) - lx
    my = 0.25 * (c[i, k, 0, 1] + c[i, k, 1, 1] + c[i, k, 2, 1] + c[i, k, 3, 1]) - ly
    az = 0.0 - lz
    r = math.sqrt(mx * mx + my * my + az * az)
    wx = mx / r
    wy = my / r
    wz = az / r
    ux = R_world_light[0, 0] * wx + R_world_light[1, 0] * wy + R_world_light[2, 0] * wz
    uy = R_world_light[0, 1] * wx + R_world_light[1, 1] * wy + R_world_light[2, 1] * wz
    uz = R_world_light[0, 2] * wx + R_world_light[1, 2] * wy + R_world_light[2, 2] * wz
    f = _rid_value(ux, uy, uz, rid_kind, rid_params, rid_theta, rid_phi, rid_values, rid_slopes)
    return omega * f


@numba.njit(cache=True, inline="always", error_model="numpy")
def _quad_terms(
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


@numba.njit(cache=True, inline="always")
def _pixel_flux(
    i: int,
    corners_world: np.ndarray,
    weights: np.ndarray,
    valid: np.ndarray,
    light_world: np.ndarray,
    R_world_light: np.ndarray,
    rid_kind: int,
    rid_params: np.ndarray,
    rid_theta: np.ndarray,
    rid_phi: np.ndarray,
    rid_values: np.ndarray,
    rid_slopes: np.ndarray,
    n_sub: int,
    want_grad: bool,
    allow_fast: bool,
    g: np.ndarray,
    gq: np.ndarray,
    out_flux: np.ndarray,
    out_grad: np.ndarray,
) -> None:
    """`flux_pixels` for pixel i, quad by quad; g and gq: (6,) scratch buffers.

    With allow_fast, n_sub = 1 and no gradients, quads on the wall take `_quad_flux_fast`;
    every other quad takes `_quad_flux` (the plain kernel).
    """
    n_k = corners_world.shape[1]
    lx = light_world[0]
    ly = light_world[1]
    lz = light_world[2]
    acc = 0.0
    if allow_fast and n_sub == 1 and not want_grad:
        if valid[i]:
            for k in range(n_k):
                on_wall = (
                    corners_world[i, k, 0, 2] == 0.0
                    and corners_world[i, k, 1, 2] == 0.0
                    and corners_world[i, k, 2, 2] == 0.0
                    and corners_world[i, k, 3, 2] == 0.0
                )
                if on_wall:
                    phi = _quad_flux_fast(
                        corners_world,
                        i,
                        k,
                        lx,
                        ly,
                        lz,
                        R_world_light,
                        rid_kind,
                        rid_params,
                        rid_theta,
                        rid_phi,
                        rid_values,
                        rid_slopes,
                    )
                else:
                    phi = _quad_flux(
                        corners_world[i, k],
                        lx,
                        ly,
                        lz,
                        R_world_light,
                        rid_kind,
                        rid_params,
                        rid_theta,
                        rid_phi,
                        rid_values,
                        rid_slopes,
                        1,
                        False,
                        gq,
                    )
                acc += weights[i, k] * phi
        out_flux[i] = acc
        return
    g[:] = 0.0
    if valid[i]:
        for k in range(n_k):
            if want_grad:
                gq[:] = 0.0
            phi = _quad_flux(
                corners_world[i, k],
                lx,
                ly,
                lz,
                R_world_light,
                rid_kind,
                rid_params,
                rid_theta,
                rid_phi,
                rid_values,
                rid_slopes,
                n_sub,
                want_grad,
                gq,
            )
            acc += weights[i, k] * phi
            if want_grad:
                for d in range(6):
                    g[d] += weights[i, k] * gq[d]
    out_flux[i] = acc
    if want_grad:
        for d in range(6):
            out_grad[i, d] = g[d]


# ---------------------------------------------------------------------------------------
# Fast gradient path of `flux_pixels` (n = 1, quads on the wall z = 0): the numbers of
# `_quad_flux` (same model, same formulas up to the order of a few additions), computed
# for blocks of GRAD_BLOCK pixels in branch-free loops that LLVM vectorises:
# - the two triangles' Van Oosterom-Strackee terms share the corner norms l_k, and with
#   the wall z = 0 the numerators are a_z (e1 x e2)_z with d num / d L = -(0, 0, (e1 x e2)_z);
# - d den / d L of a triangle (a, b, c) is -(alpha a + beta b + gamma c) with
#   alpha = (l_b l_c + b.c) / l_a + l_b + l_c (and cyclically), so the quad's gradient
#   d Omega / d L = sum over the 4 corners of a coefficient times the corner's vector,
#   minus the numerators' z terms;
# - Omega itself by the one-arctangent series (`quad_omega`'s common case), the quads
#   outside its range recomputed afterwards by `quad_omega_signed`;
# - cos^m: f = u_z^m and its tangential gradient m u_z^(m - 1) (e_z - u_z u), i.e. in the
#   world frame (m f / u_z) (axis - u_z w): no arctangent, no arccosine.
# Pixels with a quad off the wall take the quad loop (`_pixel_flux`) afterwards.
# ---------------------------------------------------------------------------------------

#: Pixels per block of the fast gradient path (its scratch rows stay in the L1 cache).
GRAD_BLOCK = 128
_N_SCRATCH = 28  # float rows of the block scratch (see `_wall_grad_block`)


@numba.njit(cache=True, error_model="numpy")
def quad_omega_signed(n1: float, d1: float, n2: float, d2: float) -> float:
    """2 atan2(n1, d1) + 2 atan2(n2, d2), by the branches of `quad_omega` (not its abs)."""
    if d1 > 0.0 and d2 > 0.0:
        den = d1 * d2 - n1 * n2
        if den > 0.0:
            x = (n1 * d2 + n2 * d1) / den
            if abs(x) <= ATAN_SERIES_MAX:
                return 2.0 * atan_series(x)
            return 2.0 * math.atan(x)
    return 2.0 * math.atan2(n1, d1) + 2.0 * math.atan2(n2, d2)


@numba.njit(cache=True, inline="always", error_model="numpy")
def _wall_quad_terms(
    corners_world: np.ndarray, i: int, k: int, lx: float, ly: float, lz: float
) -> tuple[float, float, float, float]:
    """`_quad_terms` (n1, d1, n2, d2) of quad corners_world[i, k] (4, 3) on the wall z = 0."""
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
    return _quad_terms(
        x1, y1, x2, y2, x3, y3, x4, y4, a_x, a_y, l1, b_x, b_y, l2, c_x, c_y, l3, d_x, d_y, l4, az
    )


@numba.njit(cache=True, error_model="numpy")
def _wall_quad_omega_signed(
    corners_world: np.ndarray, i: int, k: int, lx: float, ly: float, lz: float
) -> float:
    """Signed solid angle of quad corners_world[i, k] (4, 3) on the wall, any size."""
    return quad_omega_signed(*_wall_quad_terms(corners_world, i, k, lx, ly, lz))


@numba.njit(cache=True, error_model="numpy")
def _wall_grad_block(
    i0: int,
    i1: int,
    corners_world: np.ndarray,
    weights: np.ndarray,
    valid: np.ndarray,
    light_world: np.ndarray,
    R_world_light: np.ndarray,
    rid_kind: int,
    rid_params: np.ndarray,
    rid_theta: np.ndarray,
    rid_phi: np.ndarray,
    rid_values: np.ndarray,
    rid_slopes: np.ndarray,
    scratch: np.ndarray,
    flags: np.ndarray,
    out_flux: np.ndarray,
    out_grad: np.ndarray,
) -> int:
    """`flux_pixels` with gradients and n = 1 for pixels i0 .. i1 - 1 (at most GRAD_BLOCK).

    Writes out_flux[i0:i1] and out_grad[i0:i1] for pixels whose quads all lie on the wall
    (0 for invalid pixels) and returns how many valid pixels have a quad off the wall:
    the caller computes those (flags[0] False) by `_pixel_flux`.

    Args:
        scratch: (_N_SCRATCH, GRAD_BLOCK) float buffer; flags: (2, GRAD_BLOCK) bool buffer.
    """
    nb = i1 - i0
    n_k = corners_world.shape[1]
    lx = light_world[0]
    ly = light_world[1]
    lz = light_world[2]
    az = 0.0 - lz
    azz = az * az
    so = scratch[0]  # signed solid angle of quad k
    gox = scratch[1]  # its gradient d Omega / d L_world
    goy = scratch[2]
    goz = scratch[3]
    wxs = scratch[4]  # unit direction from the light to the quad's centroid
    wys = scratch[5]
    wzs = scratch[6]
    rs = scratch[7]  # distance from the light to the centroid
    fs = scratch[8]  # RID value
    gwx = scratch[9]  # its tangential gradient with respect to w, world frame
    gwy = scratch[10]
    gwz = scratch[11]
    acc = scratch[12]  # sum_k weight_k Phi_k
    ag0 = scratch[13]  # its gradient (L_world, delta_world)
    ag1 = scratch[14]
    ag2 = scratch[15]
    ag3 = scratch[16]
    ag4 = scratch[17]
    ag5 = scratch[18]
    xs1 = scratch[19]  # corners of quad k (unit stride: the geometry loop vectorises)
    ys1 = scratch[20]
    xs2 = scratch[21]
    ys2 = scratch[22]
    xs3 = scratch[23]
    ys3 = scratch[24]
    xs4 = scratch[25]
    ys4 = scratch[26]
    wts = scratch[27]  # weight of quad k
    on_wall = flags[0]
    bad = flags[1]
    for i in range(nb):
        acc[i] = 0.0
        ag0[i] = 0.0
        ag1[i] = 0.0
        ag2[i] = 0.0
        ag3[i] = 0.0
        ag4[i] = 0.0
        ag5[i] = 0.0
        on_wall[i] = True
    r00 = R_world_light[0, 0]
    r10 = R_world_light[1, 0]
    r20 = R_world_light[2, 0]
    r01 = R_world_light[0, 1]
    r11 = R_world_light[1, 1]
    r21 = R_world_light[2, 1]
    r02 = R_world_light[0, 2]
    r12 = R_world_light[1, 2]
    r22 = R_world_light[2, 2]
    for k in range(n_k):
        # Geometry: solid angle (series), its gradient, the direction to the centroid.
        for i in range(nb):
            p = i0 + i
            xs1[i] = corners_world[p, k, 0, 0]
            ys1[i] = corners_world[p, k, 0, 1]
            xs2[i] = corners_world[p, k, 1, 0]
            ys2[i] = corners_world[p, k, 1, 1]
            xs3[i] = corners_world[p, k, 2, 0]
            ys3[i] = corners_world[p, k, 2, 1]
            xs4[i] = corners_world[p, k, 3, 0]
            ys4[i] = corners_world[p, k, 3, 1]
            flat = (
                (corners_world[p, k, 0, 2] == 0.0)
                & (corners_world[p, k, 1, 2] == 0.0)
                & (corners_world[p, k, 2, 2] == 0.0)
                & (corners_world[p, k, 3, 2] == 0.0)
            )
            on_wall[i] = on_wall[i] & flat
            wts[i] = weights[p, k]
        n_bad = 0
        for i in range(nb):
            x1 = xs1[i]
            y1 = ys1[i]
            x2 = xs2[i]
            y2 = ys2[i]
            x3 = xs3[i]
            y3 = ys3[i]
            x4 = xs4[i]
            y4 = ys4[i]
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
            e1x = x2 - x1
            e1y = y2 - y1
            e2x = x3 - x1
            e2y = y3 - y1
            e3x = x4 - x1
            e3y = y4 - y1
            c1 = e1x * e2y - e1y * e2x
            c2 = e2x * e3y - e2y * e3x
            n1 = az * c1
            n2 = az * c2
            ab = a_x * b_x + a_y * b_y + azz
            ac = a_x * c_x + a_y * c_y + azz
            bc = b_x * c_x + b_y * c_y + azz
            ad = a_x * d_x + a_y * d_y + azz
            cd = c_x * d_x + c_y * d_y + azz
            d1 = l1 * l2 * l3 + ab * l3 + ac * l2 + bc * l1
            d2 = l1 * l3 * l4 + ac * l4 + ad * l3 + cd * l1
            den = d1 * d2 - n1 * n2
            x = (n1 * d2 + n2 * d1) / den
            b = (d1 <= 0.0) | (d2 <= 0.0) | (den <= 0.0) | (not abs(x) <= ATAN_SERIES_MAX)
            bad[i] = b
            n_bad += b
            so[i] = 2.0 * atan_series(x)
            # d omega_t = s_t (d_t d n_t - n_t d d_t), s_t = 2 / (n_t^2 + d_t^2).
            q1 = 1.0 / l1
            q2 = 1.0 / l2
            q3 = 1.0 / l3
            q4 = 1.0 / l4
            s1 = 2.0 / (n1 * n1 + d1 * d1)
            s2 = 2.0 / (n2 * n2 + d2 * d2)
            t1 = s1 * n1
            t2 = s2 * n2
            ca = t1 * ((l2 * l3 + bc) * q1 + l2 + l3) + t2 * ((l3 * l4 + cd) * q1 + l3 + l4)
            cb = t1 * ((l1 * l3 + ac) * q2 + l1 + l3)
            cc = t1 * ((l1 * l2 + ab) * q3 + l1 + l2) + t2 * ((l1 * l4 + ad) * q3 + l1 + l4)
            cdd = t2 * ((l1 * l3 + ac) * q4 + l1 + l3)
            gox[i] = ca * a_x + cb * b_x + cc * c_x + cdd * d_x
            goy[i] = ca * a_y + cb * b_y + cc * c_y + cdd * d_y
            goz[i] = az * (ca + cb + cc + cdd) - (s1 * d1 * c1 + s2 * d2 * c2)
            mx = 0.25 * (x1 + x2 + x3 + x4) - lx
            my = 0.25 * (y1 + y2 + y3 + y4) - ly
            r = math.sqrt(mx * mx + my * my + azz)
            wxs[i] = mx / r
            wys[i] = my / r
            wzs[i] = az / r
            rs[i] = r
        if n_bad > 0:
            # Large solid angles (light near the wall): the solid angle by `quad_omega`'s
            # branches; its gradient above holds everywhere.
            for i in range(nb):
                p = i0 + i
                if bad[i] and on_wall[i] and valid[p]:
                    so[i] = _wall_quad_omega_signed(corners_world, p, k, lx, ly, lz)
        # The RID and its gradient with respect to the world direction w.
        if rid_kind == KIND_ISOTROPIC:
            for i in range(nb):
                fs[i] = 1.0
                gwx[i] = 0.0
                gwy[i] = 0.0
                gwz[i] = 0.0
        elif rid_kind == KIND_COS_POWER:
            m = rid_params[0]
            for i in range(nb):
                wx = wxs[i]
                wy = wys[i]
                wz = wzs[i]
                uz = r02 * wx + r12 * wy + r22 * wz
                f = cos_power(uz, m)
                kf = m * f / (uz if uz > 0.0 else 1.0)
                fs[i] = f
                gwx[i] = kf * (r02 - uz * wx)
                gwy[i] = kf * (r12 - uz * wy)
                gwz[i] = kf * (r22 - uz * wz)
        else:
            for i in range(nb):
                if not (on_wall[i] and valid[i0 + i]):
                    fs[i] = 0.0
                    gwx[i] = 0.0
                    gwy[i] = 0.0
                    gwz[i] = 0.0
                    continue
                wx = wxs[i]
                wy = wys[i]
                wz = wzs[i]
                ux = r00 * wx + r10 * wy + r20 * wz
                uy = r01 * wx + r11 * wy + r21 * wz
                uz = r02 * wx + r12 * wy + r22 * wz
                f, gux, guy, guz = rid_value_grad_direction(
                    ux, uy, uz, rid_kind, rid_params, rid_theta, rid_phi, rid_values, rid_slopes
                )
                fs[i] = f
                gwx[i] = r00 * gux + r01 * guy + r02 * guz
                gwy[i] = r10 * gux + r11 * guy + r12 * guz
                gwz[i] = r20 * gux + r21 * guy + r22 * guz
        # Accumulate weight_k Omega f and its gradient (signs as in `_quad_flux`).
        for i in range(nb):
            wt = wts[i]
            s = so[i]
            omega = abs(s)
            f = fs[i]
            fsg = -f if s < 0.0 else f
            o_r = omega / rs[i]
            wx = wxs[i]
            wy = wys[i]
            wz = wzs[i]
            gx = gwx[i]
            gy = gwy[i]
            gz = gwz[i]
            acc[i] += wt * (omega * f)
            # d f / d L = -gw / r (gw tangential); d f / d delta = gw x w.
            ag0[i] += wt * (fsg * gox[i] - o_r * gx)
            ag1[i] += wt * (fsg * goy[i] - o_r * gy)
            ag2[i] += wt * (fsg * goz[i] - o_r * gz)
            ag3[i] += wt * (omega * (gy * wz - gz * wy))
            ag4[i] += wt * (omega * (gz * wx - gx * wz))
            ag5[i] += wt * (omega * (gx * wy - gy * wx))
    n_off = 0
    for i in range(nb):
        p = i0 + i
        ok = valid[p]
        out_flux[p] = acc[i] if ok else 0.0
        out_grad[p, 0] = ag0[i] if ok else 0.0
        out_grad[p, 1] = ag1[i] if ok else 0.0
        out_grad[p, 2] = ag2[i] if ok else 0.0
        out_grad[p, 3] = ag3[i] if ok else 0.0
        out_grad[p, 4] = ag4[i] if ok else 0.0
        out_grad[p, 5] = ag5[i] if ok else 0.0
        n_off += ok & (not on_wall[i])
    return n_off


@numba.njit(cache=True)
def _wall_grad_range(
    i0: int,
    i1: int,
    corners_world: np.ndarray,
    weights: np.ndarray,
    valid: np.ndarray,
    light_world: np.ndarray,
    R_world_light: np.ndarray,
    rid_kind: int,
    rid_params: np.ndarray,
    rid_theta: np.ndarray,
    rid_phi: np.ndarray,
    rid_values: np.ndarray,
    rid_slopes: np.ndarray,
    out_flux: np.ndarray,
    out_grad: np.ndarray,
) -> None:
    """`flux_pixels` with gradients and n = 1 for pixels i0 .. i1 - 1, block by block."""
    scratch = np.empty((_N_SCRATCH, GRAD_BLOCK))
    flags = np.empty((2, GRAD_BLOCK), dtype=np.bool_)
    on_wall = flags[0]
    g = np.zeros(6)
    gq = np.zeros(6)
    for b0 in range(i0, i1, GRAD_BLOCK):
        b1 = min(b0 + GRAD_BLOCK, i1)
        n_off = _wall_grad_block(
            b0,
            b1,
            corners_world,
            weights,
            valid,
            light_world,
            R_world_light,
            rid_kind,
            rid_params,
            rid_theta,
            rid_phi,
            rid_values,
            rid_slopes,
            scratch,
            flags,
            out_flux,
            out_grad,
        )
        if n_off == 0:
            continue
        for i in range(b0, b1):
            if valid[i] and not on_wall[i - b0]:
                _pixel_flux(
                    i,
                    corners_world,
                    weights,
                    valid,
                    light_world,
                    R_world_light,
                    rid_kind,
                    rid_params,
                    rid_theta,
                    rid_phi,
                    rid_values,
                    rid_slopes,
                    1,
                    True,
                    False,
                    g,
                    gq,
                    out_flux,
                    out_grad,
                )


@numba.njit(cache=True, inline="always")
def _flux_range(
    i0: int,
    i1: int,
    corners_world: np.ndarray,
    weights: np.ndarray,
    valid: np.ndarray,
    light_world: np.ndarray,
    R_world_light: np.ndarray,
    rid_kind: int,
    rid_params: np.ndarray,
    rid_theta: np.ndarray,
    rid_phi: np.ndarray,
    rid_values: np.ndarray,
    rid_slopes: np.ndarray,
    n_sub: int,
    want_grad: bool,
    allow_fast: bool,
    out_flux: np.ndarray,
    out_grad: np.ndarray,
) -> None:
    """`flux_pixels` for pixels i0 .. i1 - 1; without `allow_fast` no fast path is taken.

    The parallel, serial and plain entry points below inline it (they are separate
    functions: numba's cache does not tell apart compilations of one function with
    different options).
    """
    if allow_fast and want_grad and n_sub == 1:
        _wall_grad_range(
            i0,
            i1,
            corners_world,
            weights,
            valid,
            light_world,
            R_world_light,
            rid_kind,
            rid_params,
            rid_theta,
            rid_phi,
            rid_values,
            rid_slopes,
            out_flux,
            out_grad,
        )
    else:
        g = np.zeros(6)
        gq = np.zeros(6)
        for i in range(i0, i1):
            _pixel_flux(
                i,
                corners_world,
                weights,
                valid,
                light_world,
                R_world_light,
                rid_kind,
                rid_params,
                rid_theta,
                rid_phi,
                rid_values,
                rid_slopes,
                n_sub,
                want_grad,
                allow_fast,
                g,
                gq,
                out_flux,
                out_grad,
            )


@numba.njit(cache=True, parallel=True)
def _flux_pixels_parallel(
    corners_world: np.ndarray,
    weights: np.ndarray,
    valid: np.ndarray,
    light_world: np.ndarray,
    R_world_light: np.ndarray,
    rid_kind: int,
    rid_params: np.ndarray,
    rid_theta: np.ndarray,
    rid_phi: np.ndarray,
    rid_values: np.ndarray,
    rid_slopes: np.ndarray,
    n_sub: int,
    want_grad: bool,
    out_flux: np.ndarray,
    out_grad: np.ndarray,
) -> None:
    """`flux_pixels` on all threads, in chunks of pixels (scratch buffers per chunk)."""
    n = corners_world.shape[0]
    n_chunks = min(n, 256)
    for ch in numba.prange(n_chunks):
        _flux_range(
            ch * n // n_chunks,
            (ch + 1) * n // n_chunks,
            corners_world,
            weights,
            valid,
            light_world,
            R_world_light,
            rid_kind,
            rid_params,
            rid_theta,
            rid_phi,
            rid_values,
            rid_slopes,
            n_sub,
            want_grad,
            True,
            out_flux,
            out_grad,
        )


@numba.njit(cache=True)
def _flux_pixels_serial(
    corners_world: np.ndarray,
    weights: np.ndarray,
    valid: np.ndarray,
    light_world: np.ndarray,
    R_world_light: np.ndarray,
    rid_kind: int,
    rid_params: np.ndarray,
    rid_theta: np.ndarray,
    rid_phi: np.ndarray,
    rid_values: np.ndarray,
    rid_slopes: np.ndarray,
    n_sub: int,
    want_grad: bool,
    out_flux: np.ndarray,
    out_grad: np.ndarray,
) -> None:
    """`flux_pixels` on the calling thread (small sets: no thread launch)."""
    _flux_range(
        0,
        corners_world.shape[0],
        corners_world,
        weights,
        valid,
        light_world,
        R_world_light,
        rid_kind,
        rid_params,
        rid_theta,
        rid_phi,
        rid_values,
        rid_slopes,
        n_sub,
        want_grad,
        True,
        out_flux,
        out_grad,
    )


@numba.njit(cache=True)
def _flux_pixels_plain(
    corners_world: np.ndarray,
    weights: np.ndarray,
    valid: np.ndarray,
    light_world: np.ndarray,
    R_world_light: np.ndarray,
    rid_kind: int,
    rid_params: np.ndarray,
    rid_theta: np.ndarray,
    rid_phi: np.ndarray,
    rid_values: np.ndarray,
    rid_slopes: np.ndarray,
    n_sub: int,
    want_grad: bool,
    out_flux: np.ndarray,
    out_grad: np.ndarray,
) -> None:
    """`flux_pixels` without the fast paths: `_quad_flux` for every quad (for the tests)."""
    _flux_range(
        0,
        corners_world.shape[0],
        corners_world,
        weights,
        valid,
        light_world,
        R_world_light,
        rid_kind,
        rid_params,
        rid_theta,
        rid_phi,
        rid_values,
        rid_slopes,
        n_sub,
        want_grad,
        False,
        out_flux,
        out_grad,
    )


#: Below this many quad evaluations (pixels x quads x sub-quads, x 4 with gradients by
#: the quad loop: n > 1), `flux_pixels` runs on the calling thread: waking the thread pool
#: costs more. (With n = 1 a quad with gradients costs about one without.)
SERIAL_WORK = 20_000


def flux_pixels(
    corners_world: np.ndarray,
    weights: np.ndarray,
    valid: np.ndarray,
    light_world: np.ndarray,
    R_world_light: np.ndarray,
    rid_kind: int,
    rid_params: np.ndarray,
    rid_theta: np.ndarray,
    rid_phi: np.ndarray,
    rid_values: np.ndarray,
    rid_slopes: np.ndarray,
    n_sub: int,
    want_grad: bool,
    out_flux: np.ndarray,
    out_grad: np.ndarray,
) -> None:
    """Weighted footprint flux of pixels for one light; writes (not adds) the outputs.

    With n_sub = 1, quads on the wall (z = 0) take the fast paths: without gradients
    `_quad_flux_fast` (shared corner norms, one arctangent per quad, `cos_power`), with
    gradients `_wall_grad_block` (blocks of pixels in vectorised loops, see "Fast
    gradient path"). Other quads take the plain quad loop (`_quad_flux`).

    Args:
        corners_world: (N, K, 4, 3) the K footprint quads of each pixel, world frame, m.
        weights: (N, K) sensor weights of each quad.
        valid: (N,) pixels to compute; others get 0.
        light_world: (3,) emitter position, world frame, m. Must have z > 0.
        R_world_light: (3, 3) light orientation in the world frame.
        rid_*: the fields of `RIDData`.
        n_sub: RID sub-sampling per side of each quad.
        want_grad: compute out_grad.
        out_flux: (N,) sum_k weight_k Phi_k / I0.
        out_grad: (N, 6) d out_flux / d (L_world (3), delta_world (3)); untouched if not want_grad.
    """
    per_quad = 4 if want_grad and n_sub > 1 else 1
    work = corners_world.shape[0] * corners_world.shape[1] * n_sub * n_sub * per_quad
    kernel = _flux_pixels_serial if work < SERIAL_WORK else _flux_pixels_parallel
    kernel(
        corners_world,
        weights,
        valid,
        light_world,
        R_world_light,
        int(rid_kind),
        rid_params,
        rid_theta,
        rid_phi,
        rid_values,
        rid_slopes,
        int(n_sub),
        bool(want_grad),
        out_flux,
        out_grad,
    )


@numba.njit(cache=True, inline="always")
def _corner_world(
    x: float, y: float, R_camera_world: np.ndarray, center: np.ndarray, out: np.ndarray
) -> bool:
    """Intersect the ray of normalised camera coordinates (x, y) with z = 0; False on a miss."""
    dx = R_camera_world[0, 0] * x + R_camera_world[1, 0] * y + R_camera_world[2, 0]
    dy = R_camera_world[0, 1] * x + R_camera_world[1, 1] * y + R_camera_world[2, 1]
    dz = R_camera_world[0, 2] * x + R_camera_world[1, 2] * y + R_camera_world[2, 2]
    if not (dz < 0.0):
        return False
    lam = -center[2] / dz
    if not (lam > 0.0):
        return False
    out[0] = center[0] + lam * dx
    out[1] = center[1] + lam * dy
    out[2] = 0.0
    return True


@numba.njit(cache=True, parallel=True)
def geometry_image(
    grid_xy: np.ndarray,
    grid_ok: np.ndarray,
    R_camera_world: np.ndarray,
    center_world: np.ndarray,
    sensor: int,
    vignetting: np.ndarray,
    binning: int,
    out_weight: np.ndarray,
    out_valid: np.ndarray,
) -> None:
    """Per-pixel sensor weights of a (binned) full image; see `flux_image`.

    Args:
        grid_xy: (H+1, W+1, 2) undistorted normalised coordinates of the pixel corners.
        grid_ok: (H+1, W+1) corners whose undistortion succeeded.
        R_camera_world: (3, 3); center_world: (3,) camera centre, world frame, m.
        sensor: one of the SENSOR_* codes.
        vignetting: (H, W) fall-off map for SENSOR_MAP, else any (1, 1) array.
        binning: b, super-pixel side in pixels.
        out_weight: (H // b, W // b, b * b) weight of each member pixel's flux.
        out_valid: (H // b, W // b) pixels whose every corner lands on the wall.
    """
    hb = out_valid.shape[0]
    wb = out_valid.shape[1]
    b = binning
    for r in numba.prange(hb):
        q = np.empty((4, 3))
        for cidx in range(wb):
            ok = True
            area = 0.0
            vsum = 0.0
            for jj in range(b):
                v = r * b + jj
                for ii in range(b):
                    u = cidx * b + ii
                    xs = (
                        grid_xy[v, u, 0],
                        grid_xy[v, u + 1, 0],
                        grid_xy[v + 1, u + 1, 0],
                        grid_xy[v + 1, u, 0],
                    )
                    ys = (
                        grid_xy[v, u, 1],
                        grid_xy[v, u + 1, 1],
                        grid_xy[v + 1, u + 1, 1],
                        grid_xy[v + 1, u, 1],
                    )
                    oks = (
                        grid_ok[v, u]
                        and grid_ok[v, u + 1]
                        and grid_ok[v + 1, u + 1]
                        and grid_ok[v + 1, u]
                    )
                    if not oks:
                        ok = False
                        break
                    for k in range(4):
                        if not _corner_world(xs[k], ys[k], R_camera_world, center_world, q[k]):
                            ok = False
                    if not ok:
                        break
                    a = 0.5 * abs(
                        (q[2, 0] - q[0, 0]) * (q[3, 1] - q[1, 1])
                        - (q[2, 1] - q[0, 1]) * (q[3, 0] - q[1, 0])
                    )
                    k_idx = jj * b + ii
                    if sensor == SENSOR_PAPER:
                        mx = 0.25 * (q[0, 0] + q[1, 0] + q[2, 0] + q[3, 0]) - center_world[0]
                        my = 0.25 * (q[0, 1] + q[1, 1] + q[2, 1] + q[3, 1]) - center_world[1]
                        mz = -center_world[2]
                        d2 = mx * mx + my * my + mz * mz
                        out_weight[r, cidx, k_idx] = (
                            (center_world[2] / math.sqrt(d2)) / d2 / (b * b)
                        )
                    else:
                        area += a
                        if sensor == SENSOR_COS4:
                            xm = 0.25 * (xs[0] + xs[1] + xs[2] + xs[3])
                            ym = 0.25 * (ys[0] + ys[1] + ys[2] + ys[3])
                            c2 = 1.0 / (1.0 + xm * xm + ym * ym)
                            vsum += c2 * c2
                        elif sensor == SENSOR_MAP:
                            vsum += vignetting[v, u]
                        else:
                            vsum += 1.0
                if not ok:
                    break
            out_valid[r, cidx] = ok
            if ok and sensor != SENSOR_PAPER:
                w = (vsum / (b * b)) / area
                for k_idx in range(b * b):
                    out_weight[r, cidx, k_idx] = w


@numba.njit(cache=True, parallel=True)
def flux_image(
    grid_xy: np.ndarray,
    R_camera_world: np.ndarray,
    center_world: np.ndarray,
    weight: np.ndarray,
    valid: np.ndarray,
    light_world: np.ndarray,
    R_world_light: np.ndarray,
    rid_kind: int,
    rid_params: np.ndarray,
    rid_theta: np.ndarray,
    rid_phi: np.ndarray,
    rid_values: np.ndarray,
    rid_slopes: np.ndarray,
    n_sub: int,
    scale: float,
    out: np.ndarray,
) -> None:
    """Add scale * sum_k weight_k Phi_k / I0 of one light to every valid (super-)pixel.

    Args:
        grid_xy: (H+1, W+1, 2) undistorted normalised corner coordinates.
        R_camera_world, center_world: the view; light_world (3,), R_world_light (3, 3): the light.
        weight, valid: from `geometry_image`.
        rid_*: the fields of `RIDData`; n_sub: RID sub-sampling per side.
        scale: the light's scale.
        out: (H // b, W // b) accumulator.
    """
    hb = valid.shape[0]
    wb = valid.shape[1]
    b = round(math.sqrt(weight.shape[2]))
    lx = light_world[0]
    ly = light_world[1]
    lz = light_world[2]
    for r in numba.prange(hb):
        q = np.empty((4, 3))
        dummy = np.zeros(6)
        for cidx in range(wb):
            if not valid[r, cidx]:
                continue
            acc = 0.0
            for jj in range(b):
                v = r * b + jj
                for ii in range(b):
                    u = cidx * b + ii
                    _corner_world(
                        grid_xy[v, u, 0], grid_xy[v, u, 1], R_camera_world, center_world, q[0]
                    )
                    _corner_world(
                        grid_xy[v, u + 1, 0],
                        grid_xy[v, u + 1, 1],
                        R_camera_world,
                        center_world,
                        q[1],
                    )
                    _corner_world(
                        grid_xy[v + 1, u + 1, 0],
                        grid_xy[v + 1, u + 1, 1],
                        R_camera_world,
                        center_world,
                        q[2],
                    )
                    _corner_world(
                        grid_xy[v + 1, u, 0],
                        grid_xy[v + 1, u, 1],
                        R_camera_world,
                        center_world,
                        q[3],
                    )
                    phi = _quad_flux(
                        q,
                        lx,
                        ly,
                        lz,
                        R_world_light,
                        rid_kind,
                        rid_params,
                        rid_theta,
                        rid_phi,
                        rid_values,
                        rid_slopes,
                        n_sub,
                        False,
                        dummy,
                    )
                    acc += weight[r, cidx, jj * b + ii] * phi
            out[r, cidx] += scale * acc


@numba.njit(cache=True, inline="always", error_model="numpy")
def _corner_row(
    grid_xy: np.ndarray,
    grid_ok: np.ndarray,
    j: int,
    n: int,
    R_camera_world: np.ndarray,
    center_world: np.ndarray,
    px: np.ndarray,
    py: np.ndarray,
    ok: np.ndarray,
) -> None:
    """Wall points (px, py) and hit flags of corners (j, 0..n-1) (as `_corner_world`).

    Missed corners get (0, 0): finite, so that the vectorised pixel loops run through them.
    """
    r00 = R_camera_world[0, 0]
    r10 = R_camera_world[1, 0]
    r20 = R_camera_world[2, 0]
    r01 = R_camera_world[0, 1]
    r11 = R_camera_world[1, 1]
    r21 = R_camera_world[2, 1]
    r02 = R_camera_world[0, 2]
    r12 = R_camera_world[1, 2]
    r22 = R_camera_world[2, 2]
    c0 = center_world[0]
    c1 = center_world[1]
    c2 = center_world[2]
    for u in range(n):
        x = grid_xy[j, u, 0]
        y = grid_xy[j, u, 1]
        dx = r00 * x + r10 * y + r20
        dy = r01 * x + r11 * y + r21
        dz = r02 * x + r12 * y + r22
        lam = -c2 / dz
        hit = grid_ok[j, u] & (dz < 0.0) & (lam > 0.0)
        px[u] = c0 + lam * dx if hit else 0.0
        py[u] = c1 + lam * dy if hit else 0.0
        ok[u] = hit


@numba.njit(cache=True, inline="always", error_model="numpy")
def _light_row(
    px: np.ndarray,
    py: np.ndarray,
    lx: float,
    ly: float,
    lz: float,
    ax: np.ndarray,
    ay: np.ndarray,
    la: np.ndarray,
) -> None:
    """a = P - L (x, y components; a_z = -lz) and |a| for a row of corners."""
    az = 0.0 - lz
    azz = az * az
    for u in range(px.shape[0]):
        tx = px[u] - lx
        ty = py[u] - ly
        ax[u] = tx
        ay[u] = ty
        la[u] = math.sqrt(tx * tx + ty * ty + azz)


@numba.njit(cache=True, inline="always", error_model="numpy")
def _pixel_terms(
    tpx: np.ndarray,
    tpy: np.ndarray,
    bpx: np.ndarray,
    bpy: np.ndarray,
    tax: np.ndarray,
    tay: np.ndarray,
    tla: np.ndarray,
    bax: np.ndarray,
    bay: np.ndarray,
    bla: np.ndarray,
    u: int,
    az: float,
) -> tuple[float, float, float, float, float, float]:
    """Triangle terms (n1, d1, n2, d2) and the centroid (mx, my) of pixel u of a row.

    Corners P1 = top[u], P2 = top[u + 1], P3 = bottom[u + 1], P4 = bottom[u] (the cyclic
    order of `pixel_footprints`).
    """
    x1 = tpx[u]
    y1 = tpy[u]
    x2 = tpx[u + 1]
    y2 = tpy[u + 1]
    x3 = bpx[u + 1]
    y3 = bpy[u + 1]
    x4 = bpx[u]
    y4 = bpy[u]
    n1, d1, n2, d2 = _quad_terms(
        x1,
        y1,
        x2,
        y2,
        x3,
        y3,
        x4,
        y4,
        tax[u],
        tay[u],
        tla[u],
        tax[u + 1],
        tay[u + 1],
        tla[u + 1],
        bax[u + 1],
        bay[u + 1],
        bla[u + 1],
        bax[u],
        bay[u],
        bla[u],
        az,
    )
    mx = 0.25 * (x1 + x2 + x3 + x4)
    my = 0.25 * (y1 + y2 + y3 + y4)
    return n1, d1, n2, d2, mx, my


@numba.njit(cache=True, inline="always", error_model="numpy")
def _omega_series(n1: float, d1: float, n2: float, d2: float) -> tuple[float, bool]:
    """Branch-free `quad_omega` for the common case; the flag says when it does not apply."""
    den = d1 * d2 - n1 * n2
    x = (n1 * d2 + n2 * d1) / den
    bad = (d1 <= 0.0) | (d2 <= 0.0) | (den <= 0.0) | (not abs(x) <= ATAN_SERIES_MAX)
    return abs(2.0 * atan_series(x)), bad


@numba.njit(cache=True, error_model="numpy")
def _flux_row(
    tpx: np.ndarray,
    tpy: np.ndarray,
    bpx: np.ndarray,
    bpy: np.ndarray,
    tax: np.ndarray,
    tay: np.ndarray,
    tla: np.ndarray,
    bax: np.ndarray,
    bay: np.ndarray,
    bla: np.ndarray,
    light_world: np.ndarray,
    R_world_light: np.ndarray,
    kind: int,
    params: np.ndarray,
    theta_knots: np.ndarray,
    phi_knots: np.ndarray,
    values: np.ndarray,
    slopes: np.ndarray,
    n_sub: int,
    scale: float,
    ok_row: np.ndarray,
    om_row: np.ndarray,
    f_row: np.ndarray,
    bad_row: np.ndarray,
    q: np.ndarray,
    gdummy: np.ndarray,
    acc_row: np.ndarray,
) -> None:
    """Add scale * Phi / I0 of one light to acc_row (w,) for the pixels of a row.

    Only pixels with ok_row set are guaranteed; the others may receive any value.
    """
    w = acc_row.shape[0]
    lx = light_world[0]
    ly = light_world[1]
    lz = light_world[2]
    az = 0.0 - lz
    r02 = R_world_light[0, 2]
    r12 = R_world_light[1, 2]
    r22 = R_world_light[2, 2]
    if n_sub > 1:
        for u in range(w):
            if ok_row[u]:
                q[0, 0] = tpx[u]
                q[0, 1] = tpy[u]
                q[1, 0] = tpx[u + 1]
                q[1, 1] = tpy[u + 1]
                q[2, 0] = bpx[u + 1]
                q[2, 1] = bpy[u + 1]
                q[3, 0] = bpx[u]
                q[3, 1] = bpy[u]
                acc_row[u] += scale * _quad_flux(
                    q,
                    lx,
                    ly,
                    lz,
                    R_world_light,
                    kind,
                    params,
                    theta_knots,
                    phi_knots,
                    values,
                    slopes,
                    n_sub,
                    False,
                    gdummy,
                )
        return
    n_bad = 0
    if kind == KIND_ISOTROPIC:
        for u in range(w):
            n1, d1, n2, d2, mx, my = _pixel_terms(
                tpx, tpy, bpx, bpy, tax, tay, tla, bax, bay, bla, u, az
            )
            om, bad = _omega_series(n1, d1, n2, d2)
            acc_row[u] += 0.0 if bad else scale * om
            f_row[u] = 1.0
            bad_row[u] = bad
            n_bad += bad
    elif kind == KIND_COS_POWER:
        # Two loops: one loop with cos_power inline spills registers and runs slower.
        m = params[0]
        for u in range(w):
            n1, d1, n2, d2, mx, my = _pixel_terms(
                tpx, tpy, bpx, bpy, tax, tay, tla, bax, bay, bla, u, az
            )
            om, bad = _omega_series(n1, d1, n2, d2)
            mx = mx - lx
            my = my - ly
            rr = math.sqrt(mx * mx + my * my + az * az)
            f_row[u] = (r02 * mx + r12 * my + r22 * az) / rr  # cos(theta)
            om_row[u] = 0.0 if bad else om
            bad_row[u] = bad
            n_bad += bad
        for u in range(w):
            f = cos_power(f_row[u], m)
            acc_row[u] += scale * (om_row[u] * f)
            f_row[u] = f
    else:
        for u in range(w):
            n1, d1, n2, d2, mx, my = _pixel_terms(
                tpx, tpy, bpx, bpy, tax, tay, tla, bax, bay, bla, u, az
            )
            om_row[u], bad = _omega_series(n1, d1, n2, d2)
            bad_row[u] = bad
            n_bad += bad
        for u in range(w):
            mx = 0.25 * (tpx[u] + tpx[u + 1] + bpx[u + 1] + bpx[u]) - lx
            my = 0.25 * (tpy[u] + tpy[u + 1] + bpy[u + 1] + bpy[u]) - ly
            rr = math.sqrt(mx * mx + my * my + az * az)
            wx = mx / rr
            wy = my / rr
            wz = az / rr
            R = R_world_light
            ux = R[0, 0] * wx + R[1, 0] * wy + R[2, 0] * wz
            uy = R[0, 1] * wx + R[1, 1] * wy + R[2, 1] * wz
            uz = r02 * wx + r12 * wy + r22 * wz
            f = _rid_value(ux, uy, uz, kind, params, theta_knots, phi_knots, values, slopes)
            acc_row[u] += 0.0 if bad_row[u] else scale * (om_row[u] * f)
            f_row[u] = f
    if n_bad > 0:
        # Pixels outside the series' range (large solid angles): the general formula.
        for u in range(w):
            if bad_row[u] and ok_row[u]:
                n1, d1, n2, d2, mx, my = _pixel_terms(
                    tpx, tpy, bpx, bpy, tax, tay, tla, bax, bay, bla, u, az
                )
                acc_row[u] += scale * (quad_omega(n1, d1, n2, d2) * f_row[u])


@numba.njit(cache=True, error_model="numpy")
def _sensor_row(
    sensor: int,
    grid_xy: np.ndarray,
    vignetting: np.ndarray,
    v: int,
    tpx: np.ndarray,
    tpy: np.ndarray,
    bpx: np.ndarray,
    bpy: np.ndarray,
    center_world: np.ndarray,
    bb: int,
    v_row: np.ndarray,
) -> None:
    """Per-pixel sensor factor of row v: V (radiance, cos4, map) or the paper weight."""
    w = v_row.shape[0]
    if sensor == SENSOR_PAPER:
        c0 = center_world[0]
        c1 = center_world[1]
        cz = center_world[2]
        for u in range(w):
            mx = 0.25 * (tpx[u] + tpx[u + 1] + bpx[u + 1] + bpx[u]) - c0
            my = 0.25 * (tpy[u] + tpy[u + 1] + bpy[u + 1] + bpy[u]) - c1
            mz = -cz
            d2 = mx * mx + my * my + mz * mz
            v_row[u] = (cz / math.sqrt(d2)) / d2 / bb
    elif sensor == SENSOR_COS4:
        for u in range(w):
            xm = 0.25 * (
                grid_xy[v, u, 0]
                + grid_xy[v, u + 1, 0]
                + grid_xy[v + 1, u + 1, 0]
                + grid_xy[v + 1, u, 0]
            )
            ym = 0.25 * (
                grid_xy[v, u, 1]
                + grid_xy[v, u + 1, 1]
                + grid_xy[v + 1, u + 1, 1]
                + grid_xy[v + 1, u, 1]
            )
            c2 = 1.0 / (1.0 + xm * xm + ym * ym)
            v_row[u] = c2 * c2
    elif sensor == SENSOR_MAP:
        for u in range(w):
            v_row[u] = vignetting[v, u]
    else:
        for u in range(w):
            v_row[u] = 1.0


@numba.njit(cache=True, parallel=True, error_model="numpy")
def render_image_fused(
    grid_xy: np.ndarray,
    grid_ok: np.ndarray,
    R_camera_world: np.ndarray,
    center_world: np.ndarray,
    sensor: int,
    vignetting: np.ndarray,
    binning: int,
    lights_world: np.ndarray,
    R_world_lights: np.ndarray,
    light_scales: np.ndarray,
    rid_kind: np.ndarray,
    rid_params: np.ndarray,
    rid_theta: np.ndarray,
    rid_n_theta: np.ndarray,
    rid_phi: np.ndarray,
    rid_n_phi: np.ndarray,
    rid_values: np.ndarray,
    rid_slopes: np.ndarray,
    n_sub: int,
    exposure: float,
    offset: float,
    out: np.ndarray,
    out_invalid: np.ndarray,
) -> None:
    """Whole (binned) image of a rig in one pass: `geometry_image` + `flux_image` + finish.

    Rows of pixels run in parallel in chunks; within a chunk, each corner row is
    back-projected once, and per light its vectors to the light and their norms once.

    Args:
        grid_xy: (H+1, W+1, 2) undistorted normalised corner coordinates (`corner_grid`).
        grid_ok: (H+1, W+1) corners whose undistortion succeeded.
        R_camera_world: (3, 3); center_world: (3,) camera centre, world frame, m.
        sensor: one of the SENSOR_* codes; vignetting: (H, W) map for SENSOR_MAP, else (1, 1).
        binning: b, super-pixel side in pixels.
        lights_world: (L, 3) emitter positions, world frame, m, all with z > 0.
        R_world_lights: (L, 3, 3) light orientations; light_scales: (L,) scales.
        rid_*: the lights' `RIDData` stacked by `stack_rid_data`.
        n_sub: RID sub-sampling per side of each pixel's quad.
        exposure: the view's gain; offset: added to every valid value.
        out: (H // b, W // b) written: offset + exposure sum_l scale_l sum_k w_k Phi_k / I0,
            NaN where invalid.
        out_invalid: (H // b, W // b) written: True where some corner misses the wall.
    """
    hb = out.shape[0]
    wb = out.shape[1]
    b = binning
    bb = b * b
    w = wb * b
    n_l = lights_world.shape[0]
    n_chunks = min(hb, 64)
    per_pixel = b == 1 and sensor != SENSOR_PAPER
    for ch in numba.prange(n_chunks):
        r_begin = ch * hb // n_chunks
        r_end = (ch + 1) * hb // n_chunks
        px = np.empty((2, w + 1))
        py = np.empty((2, w + 1))
        cok = np.empty((2, w + 1), dtype=np.bool_)
        ax = np.empty((2, n_l, w + 1))
        ay = np.empty((2, n_l, w + 1))
        la = np.empty((2, n_l, w + 1))
        ok_row = np.empty(w, dtype=np.bool_)
        area_row = np.empty(w)
        v_row = np.empty(w)
        om_row = np.empty(w)
        f_row = np.empty(w)
        bad_row = np.empty(w, dtype=np.bool_)
        acc_row = np.empty(w)
        sp_phi = np.empty((n_l, wb))
        sp_area = np.empty(wb)
        sp_v = np.empty(wb)
        sp_ok = np.empty(wb, dtype=np.bool_)
        q = np.zeros((4, 3))
        gdummy = np.zeros(6)
        top = 0
        _corner_row(
            grid_xy, grid_ok, r_begin * b, w + 1, R_camera_world, center_world, px[0], py[0], cok[0]
        )
        for li in range(n_l):
            _light_row(
                px[0],
                py[0],
                lights_world[li, 0],
                lights_world[li, 1],
                lights_world[li, 2],
                ax[0, li],
                ay[0, li],
                la[0, li],
            )
        for r in range(r_begin, r_end):
            if not per_pixel:
                sp_phi[:] = 0.0
                sp_area[:] = 0.0
                sp_v[:] = 0.0
                sp_ok[:] = True
            for jj in range(b):
                v = r * b + jj
                bot = 1 - top
                tpx = px[top]
                tpy = py[top]
                bpx = px[bot]
                bpy = py[bot]
                tok = cok[top]
                bok = cok[bot]
                _corner_row(
                    grid_xy, grid_ok, v + 1, w + 1, R_camera_world, center_world, bpx, bpy, bok
                )
                # Geometry: validity, area and sensor factor of each pixel of row v.
                for u in range(w):
                    ok_row[u] = tok[u] & tok[u + 1] & bok[u + 1] & bok[u]
                    area_row[u] = 0.5 * abs(
                        (bpx[u + 1] - tpx[u]) * (bpy[u] - tpy[u + 1])
                        - (bpy[u + 1] - tpy[u]) * (bpx[u] - tpx[u + 1])
                    )
                _sensor_row(
                    sensor, grid_xy, vignetting, v, tpx, tpy, bpx, bpy, center_world, bb, v_row
                )
                if per_pixel:
                    acc_row[:] = 0.0
                for li in range(n_l):
                    _light_row(
                        bpx,
                        bpy,
                        lights_world[li, 0],
                        lights_world[li, 1],
                        lights_world[li, 2],
                        ax[bot, li],
                        ay[bot, li],
                        la[bot, li],
                    )
                    nt = rid_n_theta[li]
                    n_p = rid_n_phi[li]
                    if not per_pixel:
                        acc_row[:] = 0.0
                    _flux_row(
                        tpx,
                        tpy,
                        bpx,
                        bpy,
                        ax[top, li],
                        ay[top, li],
                        la[top, li],
                        ax[bot, li],
                        ay[bot, li],
                        la[bot, li],
                        lights_world[li],
                        R_world_lights[li],
                        rid_kind[li],
                        rid_params[li],
                        rid_theta[li, :nt],
                        rid_phi[li, :n_p],
                        rid_values[li, :n_p, :nt],
                        rid_slopes[li, :n_p, :nt],
                        n_sub,
                        light_scales[li] if per_pixel else 1.0,
                        ok_row,
                        om_row,
                        f_row,
                        bad_row,
                        q,
                        gdummy,
                        acc_row,
                    )
                    if per_pixel:
                        continue
                    # Binned or paper: Phi of each member pixel into its super-pixel.
                    if sensor == SENSOR_PAPER:
                        for c in range(wb):
                            for ii in range(b):
                                u = c * b + ii
                                sp_phi[li, c] += v_row[u] * acc_row[u]
                    else:
                        for c in range(wb):
                            for ii in range(b):
                                sp_phi[li, c] += acc_row[c * b + ii]
                if per_pixel:
                    # acc_row holds sum_l scale_l Phi_l / I0 of each pixel.
                    for u in range(w):
                        okp = ok_row[u]
                        value = offset + exposure * ((v_row[u] / area_row[u]) * acc_row[u])
                        out[r, u] = value if okp else np.nan
                        out_invalid[r, u] = not okp
                else:
                    for c in range(wb):
                        for ii in range(b):
                            u = c * b + ii
                            sp_ok[c] &= ok_row[u]
                            sp_area[c] += area_row[u]
                            sp_v[c] += v_row[u]
                top = bot
            if per_pixel:
                continue
            for c in range(wb):
                if sp_ok[c]:
                    total = 0.0
                    if sensor == SENSOR_PAPER:
                        for li in range(n_l):
                            total += light_scales[li] * sp_phi[li, c]
                    else:
                        wgt = (sp_v[c] / bb) / sp_area[c]
                        for li in range(n_l):
                            total += light_scales[li] * (wgt * sp_phi[li, c])
                    out[r, c] = offset + exposure * total
                    out_invalid[r, c] = False
                else:
                    out[r, c] = np.nan
                    out_invalid[r, c] = True


@numba.njit(cache=True, parallel=True)
def undistorted_corner_grid(
    K: np.ndarray, dist: np.ndarray, out_xy: np.ndarray, out_ok: np.ndarray
) -> None:
    """Undistorted normalised coordinates of every pixel corner, rows in parallel.

    The same arithmetic as `Camera.pixels_to_normalized` (bit for bit).

    Args:
        K: (3, 3) intrinsics; dist: (8,) OpenCV coefficients, zero padded.
        out_xy: (H+1, W+1, 2) written; corner (j, i) sits at pixel (i - 1/2, j - 1/2);
            (0, 0) where the undistortion fails.
        out_ok: (H+1, W+1) written: the undistortion succeeded.
    """
    n_rows = out_xy.shape[0]
    n_cols = out_xy.shape[1]
    fx = K[0, 0]
    s = K[0, 1]
    cx = K[0, 2]
    fy = K[1, 1]
    cy = K[1, 2]
    for j in numba.prange(n_rows):
        yd = (float(j) - 0.5 - cy) / fy
        for i in range(n_cols):
            xd = (float(i) - 0.5 - cx - s * yd) / fx
            x, y, ok = undistort_normalized(xd, yd, dist)
            out_ok[j, i] = ok
            out_xy[j, i, 0] = x if ok else 0.0
            out_xy[j, i, 1] = y if ok else 0.0


RIDStack = tuple[
    np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray
]


def stack_rid_data(rids: list[RIDData]) -> RIDStack:
    """Stack the `RIDData` of L lights into padded arrays for `render_image_fused`.

    Returns:
        kind (L,) int64, params (L, 2), theta (L, NT), n_theta (L,), phi (L, NP),
        n_phi (L,), values (L, NP, NT), slopes (L, NP, NT); light l uses
        theta[l, :n_theta[l]], phi[l, :n_phi[l]] and values[l, :n_phi[l], :n_theta[l]].
    """
    n_l = len(rids)
    nt = max([1, *(d.theta_knots.shape[0] for d in rids)])
    n_p = max([1, *(d.phi_knots.shape[0] for d in rids)])
    kind = np.array([d.kind for d in rids], dtype=np.int64)
    params = np.zeros((n_l, 2))
    theta = np.zeros((n_l, nt))
    phi = np.zeros((n_l, n_p))
    values = np.zeros((n_l, n_p, nt))
    slopes = np.zeros((n_l, n_p, nt))
    n_theta = np.zeros(n_l, dtype=np.int64)
    n_phi = np.zeros(n_l, dtype=np.int64)
    for i, d in enumerate(rids):
        k_t = d.theta_knots.shape[0]
        k_p = d.phi_knots.shape[0]
        params[i, : d.params.shape[0]] = d.params
        theta[i, :k_t] = d.theta_knots
        phi[i, :k_p] = d.phi_knots
        values[i, :k_p, :k_t] = d.values
        slopes[i, :k_p, :k_t] = d.slopes
        n_theta[i] = k_t
        n_phi[i] = k_p
    return kind, params, theta, n_theta, phi, n_phi, values, slopes
