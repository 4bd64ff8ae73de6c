"""The light's flat port compiled: the path from the emitter to each point.

The path equation is docs/model.md's (`lightcal.core.light_port`): a point at radial
distance rho and axial distance h = d + t + H from the emitter is reached by the ray
whose air angle theta_a solves rho = d tan(theta_a) + t tan(theta_g) + H tan(theta_w).
It is solved here in the water's slope u = tan(theta_w), where the dominant term H u is
linear (s = sin(theta_a) = n_w u / sqrt(1 + u^2), relative indices):

    F(u) = H u + n_w u (d i_a + t i_g) - rho,
    i_a = (1 - k_a u^2)^(-1/2) = 1 / (cos(theta_a) sqrt(1 + u^2)),  k_a = n_w^2 - 1,
    i_g = (n_g^2 + k_g u^2)^(-1/2),                                   k_g = n_g^2 - n_w^2,
    F'(u) = H + n_w (d i_a^3 + t n_g^2 i_g^3) >= H > 0,
    F''(u) = 3 n_w u (d k_a i_a^5 - t n_g^2 k_g i_g^5),

two square roots a step where g(s) takes three. F is increasing, -rho at 0 and infinite
at the air's pole u = 1 / sqrt(k_a) (d > 0), so its root is unique and bracketed by
[0, rho / H] (the straight line from the axis' exit: F(rho / H) = n_w u (d i_a + t i_g)
>= 0). The start is the paraxial solution u_0 = rho / (H + n_w (d + t / n_g)), Newton's
step from 0, exact on the axis; the steps are Halley's (cubic), Newton's where Halley's
denominator is small, and bisection of the bracket, which every evaluation shrinks,
where a step would leave it. A point stops once Newton's step, below 1e-8 u, would leave
an error (F'' / 2F') e^2 below 1e-17 u, or when its steps stop shrinking below 1e-13 u
(round-off); the path's derivatives are then evaluated at its u.

Past GRAZING_TAN (air angles beyond 80 degrees, where the outputs amplify the last bits
of s by 1 / cos(theta_a)^2, and beyond the air's pole) a point is solved in s as before
(`_grazing`: Newton from the right of the root, monotone): by its start, or after the
solve in u. Measured (tests/test_light_port_start.py, random d 5-50 mm, t 3-20 mm,
acrylic or glass into fresh or sea water, points 0.3-5 m beyond the port): evaluations
mean 2.0 and at most 3 for air angles up to 30 degrees, 2.2 and 3 up to 60, 3.0 and 9 up
to 70, 5.6 and 12 up to 80 (then mostly in s); in s from the old start, 4.0, 4.4, 5.9
and 9.5 on average.

- `solve_paths`: the paths to m points of the light frame and du_a/dY's factors (rows of
  PATH_SIZE numbers; `kernels.port_water` adds the water's lengths and the exits:
  `light_port.port_paths`); `air_sines_into`: sin(theta_a) only (`light_port.air_sines`).
  Both solve BLOCK points together: each point takes its own steps, the points step in
  turn, so the CPU overlaps their chains of square roots and divisions.
"""

from __future__ import annotations

import math

import numba
import numpy as np

#: Evaluations of F at most (measured: 12 near the critical angle; bisection bounds it).
MAX_STEPS = 100

#: The numbers `solve_paths` writes per point (PATH_SIZE) and its scratch per point
#: (`work`, WORK_SIZE): the radial vector (3), rho, H, u (s where solved in s), the
#: bracket (2), the last step and 1 where solved in s.
PATH_SIZE, WORK_SIZE = 13, 10

#: Past this tan(theta_a) (80 degrees) a point's path is solved again in s, as before
#: the start in u (`_grazing`): its outputs amplify s's last bits by 1 / cos(theta_a)^2.
GRAZING_TAN = 5.67

#: Points solved together by `air_sines_into`, `kernels.port_water` (see the docstring).
BLOCK = 16


@numba.njit(cache=True, inline="always", error_model="numpy")
def _equation(
    u: float, rho: float, big_h: float, d: float, t: float, n_g: float, n_w: float,
    k_a: float, k_g: float,
) -> tuple[float, float, float]:  # fmt: skip
    """F(u), F'(u) and F''(u) (the module's docstring)."""
    i_a = 1.0 / math.sqrt(1.0 - k_a * u * u)
    i_a2 = i_a * i_a
    # The glass's term only with a glass (t = 0: no 0 * inf at its pole).
    i_g = 1.0 / math.sqrt(n_g * n_g + k_g * u * u) if t > 0.0 else 0.0
    i_g2 = i_g * i_g
    tg = t * n_g * n_g
    f = big_h * u + n_w * u * (d * i_a + t * i_g) - rho
    f_u = big_h + n_w * (d * i_a * i_a2 + tg * i_g * i_g2)
    f_uu = 3.0 * n_w * u * (d * k_a * i_a * i_a2 * i_a2 - tg * k_g * i_g * i_g2 * i_g2)
    return f, f_u, f_uu


@numba.njit(cache=True, inline="always", error_model="numpy")
def _right_start(rho: float, big_h: float, d: float, t: float, n_g: float, n_w: float) -> float:
    """The smallest s at which one term of the s-equation alone reaches rho: right of its
    root and below 1 (sqrt, not hypot: lengths of a scene, far from overflow)."""
    r2 = rho * rho
    s = min(rho / math.sqrt(r2 + d * d), n_w * rho / math.sqrt(r2 + big_h * big_h))
    if t > 0.0:
        s = min(s, n_g * rho / math.sqrt(r2 + t * t))
    return s


@numba.njit(cache=True, inline="always", error_model="numpy")
def _prepare(
    j: int, rho: float, h: float, d: float, t: float, n_g: float, n_w: float,
    work: np.ndarray, active: np.ndarray,
) -> bool:  # fmt: skip
    """work[j, 3:] for the point at (rho, h) (rho already in work[j, 3]): H, the start,
    the bracket; whether the point is finite and in front of the outer face. Points on
    the axis are solved (u = 0) and not active."""
    big_h = h - d - t
    work[j, 4] = big_h
    work[j, 5] = 0.0
    work[j, 8] = math.inf
    work[j, 9] = 0.0
    if not (math.isfinite(rho) and math.isfinite(big_h) and big_h > 0.0):
        active[j] = False
        return False
    k_a = n_w * n_w - 1.0
    t2 = GRAZING_TAN * GRAZING_TAN
    hi = rho / big_h
    u_0 = rho / (big_h + n_w * (d + t / n_g))
    if not k_a * hi * hi < 1.0 or u_0 * u_0 * (n_w * n_w + t2 * k_a) > t2:
        # Beyond the air's pole (or inf), or the start past GRAZING_TAN: solved in s.
        work[j, 9] = 1.0
        active[j] = False
        return True
    work[j, 5] = u_0
    work[j, 6] = 0.0
    work[j, 7] = hi
    active[j] = rho > 0.0
    return True


@numba.njit(cache=True, inline="always", error_model="numpy")
def _solve(work: np.ndarray, active: np.ndarray, m: int, d: float, t: float, n_g: float,
           n_w: float) -> int:  # fmt: skip
    """The safeguarded Halley steps on the active points among the first m rows of work
    (`_prepare`), in place: u and the bracket. Returns the evaluations of F the slowest
    point took."""
    k_a = n_w * n_w - 1.0
    k_g = n_g * n_g - n_w * n_w
    remaining = 0
    for j in range(m):
        remaining += active[j]
    evaluations = 0
    while remaining > 0 and evaluations < MAX_STEPS:
        evaluations += 1
        for j in range(m):
            if not active[j]:
                continue
            u, rho, big_h = work[j, 5], work[j, 3], work[j, 4]
            f, f_u, f_uu = _equation(u, rho, big_h, d, t, n_g, n_w, k_a, k_g)
            if f < 0.0:
                work[j, 6] = u
            else:
                work[j, 7] = u
            newton = f / f_u
            q = f_u * f_u - 0.5 * f * f_uu
            step = f * f_u / q if q > 0.5 * f_u * f_u else newton
            # Converged when Newton's step, below 1e-8 u, would leave an error
            # (F'' / 2F') e^2 below 1e-17 u (e ~ its step; Halley's, cubic, leaves less),
            # or when the steps stop shrinking below 1e-13 u (round-off): then the step is
            # taken where it stays in the bracket.
            a_step = abs(step)
            done = (abs(newton) <= 1e-8 * u and abs(f_uu) * newton * newton <= 2e-17 * f_u * u) or (
                a_step <= 1e-13 * u and a_step >= 0.5 * work[j, 8]
            )
            new = u - step
            if not (work[j, 6] <= new <= work[j, 7]):
                new = u if done else 0.5 * (work[j, 6] + work[j, 7])
            work[j, 5] = new
            work[j, 8] = a_step
            if done:
                active[j] = False
                remaining -= 1
    return evaluations


@numba.njit(cache=True, inline="always", error_model="numpy")
def path_equation(
    s: float, rho: float, big_h: float, d: float, t: float, n_g: float, n_w: float
) -> tuple[float, float]:
    """g(s) = d tan(theta_a) + t tan(theta_g) + H tan(theta_w) - rho and dg/ds."""
    c_a2 = 1.0 - s * s
    c_g2 = n_g * n_g - s * s
    c_w2 = n_w * n_w - s * s
    # 1 / sqrt(x) and its cube for x^-0.5 and x^-1.5: the same to round-off, with three
    # divisions and no pow.
    i_a, i_g, i_w = 1.0 / math.sqrt(c_a2), 1.0 / math.sqrt(c_g2), 1.0 / math.sqrt(c_w2)
    g = (d * i_a + t * i_g + big_h * i_w) * s - rho
    g_s = (
        d * (i_a * i_a * i_a)
        + t * n_g * n_g * (i_g * i_g * i_g)
        + big_h * n_w * n_w * (i_w * i_w * i_w)
    )
    return g, g_s


@numba.njit(cache=True, error_model="numpy")
def _grazing(work: np.ndarray, active: np.ndarray, m: int, d: float, t: float, n_g: float,
             n_w: float) -> int:  # fmt: skip
    """The points solved in u (`_solve`) past GRAZING_TAN solved again in s, as before
    the start in u (the start right of the root, `_right_start`, and Newton's steps,
    monotone, to a step <= 1e-15 s or <= 0: round-off), s into work[j, 5] and
    work[j, 9] = 1. Their s is then NumPy's (tests/light_port_numpy.py) to the last
    bits, which the outputs amplify there (tan(theta_a) by 1 / cos(theta_a)^2). Returns
    the evaluations of g the slowest point took."""
    k_a = n_w * n_w - 1.0
    t2 = GRAZING_TAN * GRAZING_TAN
    remaining = 0
    for j in range(m):
        u = work[j, 5]
        graze = work[j, 3] > 0.0 and (work[j, 9] or u * u * (n_w * n_w + t2 * k_a) > t2)
        work[j, 9] = 1.0 if graze else 0.0
        active[j] = graze
        if graze:
            work[j, 5] = _right_start(work[j, 3], work[j, 4], d, t, n_g, n_w)
            remaining += 1
    evaluations = 0
    for _ in range(MAX_STEPS):
        if remaining == 0:
            break
        evaluations += 1
        for j in range(m):
            if not active[j]:
                continue
            g, g_s = path_equation(work[j, 5], work[j, 3], work[j, 4], d, t, n_g, n_w)
            step = g / g_s
            work[j, 5] -= step
            # From the right every step is > 0: a step <= 0 is round-off at the root.
            if abs(step) <= 1e-15 * work[j, 5] or step <= 0.0:
                active[j] = False
                remaining -= 1
    return evaluations


@numba.njit(cache=True, error_model="numpy")
def air_sines_into(
    rho: np.ndarray,
    h: np.ndarray,
    d: float,
    t: float,
    n_g: float,
    n_w: float,
    out_s: np.ndarray,
    out_ok: np.ndarray,
) -> int:
    """sin(theta_a) of the paths to points at radial distances rho (M,) and axial
    distances h (M,) into out_s (NaN where not ok) and out_ok (M,) (`light_port.
    air_sines`), BLOCK points at a time. Returns the evaluations of F in u (and of g in s
    past GRAZING_TAN) the slowest point of a block took: one point's, when alone."""
    work = np.empty((BLOCK, WORK_SIZE))
    active = np.empty(BLOCK, dtype=np.bool_)
    most = 0
    for lo in range(0, rho.shape[0], BLOCK):
        m = min(BLOCK, rho.shape[0] - lo)
        for j in range(m):
            work[j, 3] = rho[lo + j]
            out_ok[lo + j] = _prepare(j, rho[lo + j], h[lo + j], d, t, n_g, n_w, work, active)
        evaluations = _solve(work, active, m, d, t, n_g, n_w)
        most = max(most, evaluations + _grazing(work, active, m, d, t, n_g, n_w))
        for j in range(m):
            u = work[j, 5]
            if not out_ok[lo + j]:
                out_s[lo + j] = math.nan
            else:
                out_s[lo + j] = u if work[j, 9] else n_w * u / math.sqrt(1.0 + u * u)
    return most


@numba.njit(cache=True, error_model="numpy")
def solve_paths(
    ys: np.ndarray, m: int, n: np.ndarray, d: float, t: float, n_g: float, n_w: float,
    work: np.ndarray, active: np.ndarray, ok: np.ndarray, out: np.ndarray,
) -> bool:  # fmt: skip
    """The paths to the first m points ys (m, 3) of the light frame (`light_port.
    port_paths`) into out (m, PATH_SIZE): u_a (3), rho_hat (3), a (3), k,
    s / cos(theta_a), s, cos(theta_a); ok (m,) each point's, and whether all are.
    work (m, WORK_SIZE) (H in column 4 after), active (m,): scratch. Rows not ok are
    left as they were."""
    for j in range(m):
        y = ys[j]
        h = y[0] * n[0] + y[1] * n[1] + y[2] * n[2]
        r0 = y[0] - h * n[0]
        r1 = y[1] - h * n[1]
        r2 = y[2] - h * n[2]
        rho = math.sqrt(r0 * r0 + r1 * r1 + r2 * r2)
        work[j, 0], work[j, 1], work[j, 2], work[j, 3] = r0, r1, r2, rho
        ok[j] = _prepare(j, rho, h, d, t, n_g, n_w, work, active)
    _solve(work, active, m, d, t, n_g, n_w)
    _grazing(work, active, m, d, t, n_g, n_w)
    k_a = n_w * n_w - 1.0
    k_g = n_g * n_g - n_w * n_w
    all_ok = True
    for j in range(m):
        if not ok[j]:
            all_ok = False
            continue
        r0, r1, r2, rho = work[j, 0], work[j, 1], work[j, 2], work[j, 3]
        u, big_h = work[j, 5], work[j, 4]
        if work[j, 9]:  # solved in s: the formulas in s, as before
            sj = u
            c_a = math.sqrt(1.0 - sj * sj)
            c_w = math.sqrt(1.0 - (sj / n_w) ** 2)
            u = sj / (n_w * c_w)
            _, g_s = path_equation(sj, 0.0, big_h, d, t, n_g, n_w)
            inv_g_s = 1.0 / g_s
            tan_a = sj / c_a
        else:
            # From u, i_a and F' at the solution: cos(theta_w) = 1 / r, s = n_w u / r,
            # cos(theta_a) = 1 / (i_a r), dg/ds = F'(u) / (ds/du) = F'(u) r^3 / n_w.
            i_a = 1.0 / math.sqrt(1.0 - k_a * u * u)
            i_g = 1.0 / math.sqrt(n_g * n_g + k_g * u * u) if t > 0.0 else 0.0
            f_u = big_h + n_w * (d * i_a * i_a * i_a + t * n_g * n_g * i_g * i_g * i_g)
            c_w = 1.0 / math.sqrt(1.0 + u * u)
            sj = n_w * u * c_w
            c_a = c_w / i_a
            inv_g_s = n_w * (c_w * c_w * c_w) / f_u
            tan_a = n_w * u * i_a
        if rho == 0.0:
            k = inv_g_s
            h0 = h1 = h2 = 0.0
        else:
            k = sj / rho
            h0, h1, h2 = r0 / rho, r1 / rho, r2 / rho
        out[j, 0] = k * r0 + c_a * n[0]
        out[j, 1] = k * r1 + c_a * n[1]
        out[j, 2] = k * r2 + c_a * n[2]
        out[j, 3], out[j, 4], out[j, 5] = h0, h1, h2
        out[j, 6] = (h0 - u * n[0]) * inv_g_s
        out[j, 7] = (h1 - u * n[1]) * inv_g_s
        out[j, 8] = (h2 - u * n[2]) * inv_g_s
        out[j, 9] = k
        out[j, 10] = tan_a
        out[j, 11] = sj
        out[j, 12] = c_a
    return all_ok
