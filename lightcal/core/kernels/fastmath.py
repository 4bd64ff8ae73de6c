"""Branch-free elementary functions for the vectorised kernels (no libm calls).

numba has no vector math library: a libm call per pixel (log, exp, pow, atan) stops LLVM
from vectorising a loop. The functions here are written out in arithmetic and IEEE 754
bit manipulation only, so that pixel loops calling them run 4 pixels per AVX2
instruction, and they carry the accuracy the renderer needs (a few ulp):

- `log_positive`, `exp_real`: ln x and e^y within 2 ulp;
- `cos_power`: c^m = exp(m ln c), the cosine-power RID of docs/model.md;
- `atan_series`: atan x by its odd series for |x| <= `ATAN_SERIES_MAX`, where it is exact
  in double precision (the one-arctangent quad solid angle, `kernels.solid_angle`).
"""

from __future__ import annotations

from typing import Any

import numba
import numpy as np
from numba import types
from numba.extending import intrinsic

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


def _fma_typer(typingctx: Any, a: Any, b: Any, c: Any) -> Any:
    """a * b + c of float64s with one rounding (LLVM's fma: the FMA instruction, or libm's)."""
    if not all(t == types.float64 for t in (a, b, c)):
        return None
    sig = types.float64(types.float64, types.float64, types.float64)

    def codegen(context: Any, builder: Any, signature: Any, args: Any) -> Any:
        return builder.fma(*args)

    return sig, codegen


float_bits: Any = intrinsic(_float_bits_typer)
bits_float: Any = intrinsic(_bits_float_typer)
fma: Any = intrinsic(_fma_typer)


@numba.njit(cache=True, inline="always", error_model="numpy")
def log_positive(x: float) -> float:
    """Natural logarithm of a finite x > 0, within 2 ulp, without a libm call.

    x = 2^k m with m in [sqrt(1/2), sqrt(2)); ln m = 2 atanh(s), s = (m - 1) / (m + 1),
    |s| <= 0.172, summed to s^25 (the next term is below 1e-20 relative).
    """
    sub = x < _TINY_NORMAL
    x = x * 18014398509481984.0 if sub else x  # 2^54: subnormals become normal
    bits = float_bits(x)
    m = bits_float((bits & 0x000FFFFFFFFFFFFF) | 0x3FF0000000000000)
    # The biased exponent (11 bits) as a float, by the 2^52 trick: no int -> float
    # conversion, which AVX2 lacks for 64-bit integers and would stop vectorisation.
    kf = bits_float((bits >> 52) | 0x4330000000000000) - 4503599627370496.0
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
    k = float_bits(kf + 6755399441055744.0) - 0x4338000000000000
    k1 = k >> 1
    k2 = k - k1
    res = p * bits_float((k1 + 1023) << 52) * bits_float((k2 + 1023) << 52)
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


# Cephes' atan: atan(x) = x + x z P(z) / Q(z), z = x^2, for |x| <= 0.66 (Q monic).
_ATAN_P = (
    -8.750608600031904122785e-01,
    -1.615753718733365076637e01,
    -7.500855792314704667340e01,
    -1.228866684490136173410e02,
    -6.485021904942025371773e01,
)
_ATAN_Q = (
    2.485846490142306297962e01,
    1.650270098316988542046e02,
    4.328810604912902668951e02,
    4.853903996359136964868e02,
    1.945506571482613964425e02,
)
_PI_2_LO = 6.123233995736765886130e-17  # pi / 2 - float(pi / 2)
_PI_2 = 1.5707963267948966
_PI_4 = 0.7853981633974483


@numba.njit(cache=True, inline="always", error_model="numpy")
def atan2_nonneg(y: float, x: float) -> float:
    """atan2(y, x) for y >= 0 (an angle in [0, pi]), within 2 ulp, branch-free.

    For the angle theta from a light's axis, atan2(rho, u_z), in pixel loops that must
    vectorise (libm's atan2 is a call per pixel). a = min(y, |x|) / max(y, |x|) in
    [0, 1], atan(a) by Cephes' rational approximation (reduced by pi / 4 above 0.66),
    then the octant: pi / 2 - atan(a) where y > |x|, pi - that where x < 0.
    """
    ax = abs(x)
    hi = max(y, ax)
    lo = min(y, ax)
    a = lo / hi if hi > 0.0 else 0.0
    big = a > 0.66
    t = (a - 1.0) / (a + 1.0) if big else a
    z = t * t
    p = (((_ATAN_P[0] * z + _ATAN_P[1]) * z + _ATAN_P[2]) * z + _ATAN_P[3]) * z + _ATAN_P[4]
    q = ((((z + _ATAN_Q[0]) * z + _ATAN_Q[1]) * z + _ATAN_Q[2]) * z + _ATAN_Q[3]) * z
    q = q + _ATAN_Q[4]
    r = t + t * (z * p / q)
    r = (_PI_4 + (r + 0.5 * _PI_2_LO)) if big else r
    r = ((_PI_2 - r) + _PI_2_LO) if y > ax else r
    return ((2.0 * _PI_2 - r) + 2.0 * _PI_2_LO) if x < 0.0 else r


@numba.njit(cache=True, inline="always", error_model="numpy")
def rotate_transposed(
    x: float,
    y: float,
    z: float,
    R9: tuple[float, float, float, float, float, float, float, float, float],
) -> tuple[float, float, float]:
    """R.T @ (x, y, z) for R given by columns as R9 = (r00, r10, r20, r01, ..., r22).

    A world direction to the light frame with R = R_world_light, without array reads in
    the pixel loop.
    """
    return (
        R9[0] * x + R9[1] * y + R9[2] * z,
        R9[3] * x + R9[4] * y + R9[5] * z,
        R9[6] * x + R9[7] * y + R9[8] * z,
    )
