"""Compiled (numba) evaluation of the wall's relative reflectance B(l, v).

Over 500 lines for a reason: each model's value, derivative and one-division forms sit
beside the kernels that inline them, with numba's parallel/serial twins.

The renderer's footprint irradiance E (docs/model.md, "Rendering one pixel") is that of
a Lambertian wall; a wall model multiplies each pixel's flux by

    B(l, v) = pi f_r(l, v) / k_d,

its BRDF relative to a Lambertian one whose albedo the light's scale absorbs (B = 1 for
a Lambertian wall), evaluated with the light direction l and the view direction v at the
pixel's footprint centre (see `lightcal.core.wall` for the models and their formulas).

B depends on l only through mu_l = l_z (the wall normal is +z) and q = l . v, so every
model returns B with dB/dmu_l, dB/dq and dB/d(parameters); `wall_factor` turns those into
the gradient with respect to the light's world position:

    dB/dL = (I - l l^T) (dB/dmu_l e_z + dB/dq v) / |L - P|.

Models (``kind``): 0 Lambertian, 1 rough plastic (GGX coat over a diffuse base),
2 Oren-Nayar (qualitative model). Parameters (``params``):
plastic (alpha, eta, w), Oren-Nayar (sigma_rad,). Plastic tables: `tables` (3, 64),
rows T(mu), dT/dalpha, dT/deta of the coat's rough transmittance on mu_k = k / 63.
"""

from __future__ import annotations

import math

import numba
import numpy as np

KIND_LAMBERTIAN = 0
KIND_PLASTIC = 1
KIND_OREN_NAYAR = 2

#: Nodes of the transmittance table (mu = k / (TABLE_SIZE - 1)), as Mitsuba's roughplastic.
TABLE_SIZE = 64
#: Most parameters of any model (the width of the parameter-gradient output).
MAX_PARAMS = 3


@numba.njit(cache=True, inline="always", error_model="numpy")
def _lerp_table(row: np.ndarray, mu: float) -> tuple[float, float]:
    """Linear interpolation of a (TABLE_SIZE,) table at mu in [0, 1]: value and slope."""
    x = mu * (TABLE_SIZE - 1)
    k = min(max(int(x), 0), TABLE_SIZE - 2)
    w = x - k
    slope = (row[k + 1] - row[k]) * (TABLE_SIZE - 1)
    return (1.0 - w) * row[k] + w * row[k + 1], slope


@numba.njit(cache=True, inline="always", error_model="numpy")
def fresnel_dielectric(c: float, eta: float) -> tuple[float, float, float]:
    """Unpolarised Fresnel reflectance of light arriving from outside at cos c > 0.

    With g = sqrt(eta^2 - 1 + c^2): r_s = (c - g) / (c + g),
    r_p = (eta^2 c - g) / (eta^2 c + g), F = (r_s^2 + r_p^2) / 2 (eta > 1).

    Returns:
        F, dF/dc, dF/deta.
    """
    g = math.sqrt(eta * eta - 1.0 + c * c)
    g_c = c / g
    g_e = eta / g
    den_s = c + g
    rs = (c - g) / den_s
    rs_c = (2.0 * g - 2.0 * c * g_c) / (den_s * den_s)
    rs_e = -2.0 * c * g_e / (den_s * den_s)
    e2 = eta * eta
    num_p = e2 * c - g
    den_p = e2 * c + g
    rp = num_p / den_p
    rp_c = ((e2 - g_c) * den_p - num_p * (e2 + g_c)) / (den_p * den_p)
    rp_e = ((2.0 * eta * c - g_e) * den_p - num_p * (2.0 * eta * c + g_e)) / (den_p * den_p)
    return 0.5 * (rs * rs + rp * rp), rs * rs_c + rp * rp_c, rs * rs_e + rp * rp_e


@numba.njit(cache=True, inline="always", error_model="numpy")
def ggx_d(h_z: float, alpha: float) -> tuple[float, float, float]:
    """GGX normal distribution D = alpha^2 / (pi (1 + (alpha^2 - 1) h_z^2)^2).

    Returns:
        D, dD/dh_z, dD/dalpha.
    """
    a2 = alpha * alpha
    k = 1.0 + (a2 - 1.0) * h_z * h_z
    d = a2 / (math.pi * k * k)
    d_h = -4.0 * a2 * (a2 - 1.0) * h_z / (math.pi * k * k * k)
    d_a = 2.0 * alpha / (math.pi * k * k) * (1.0 - 2.0 * a2 * h_z * h_z / k)
    return d, d_h, d_a


@numba.njit(cache=True, inline="always", error_model="numpy")
def smith_g1(mu: float, alpha: float) -> tuple[float, float, float]:
    """GGX Smith masking G1 = 2 / (1 + sqrt(1 + alpha^2 (1 - mu^2) / mu^2)), mu > 0.

    Returns:
        G1, dG1/dmu, dG1/dalpha.
    """
    t = (1.0 - mu * mu) / (mu * mu)
    s = math.sqrt(1.0 + alpha * alpha * t)
    inv = 1.0 / ((1.0 + s) * (1.0 + s))
    return (
        2.0 * inv * (1.0 + s),
        2.0 * alpha * alpha * inv / (s * mu * mu * mu),
        (-2.0 * inv * alpha * t / s),
    )


@numba.njit(cache=True, inline="always", error_model="numpy")
def _plastic(
    mu_l: float,
    q: float,
    mu_v: float,
    params: np.ndarray,
    tables: np.ndarray,
    want_params: bool,
    dp: np.ndarray,
) -> tuple[float, float, float]:
    """Rough plastic B, dB/dmu_l, dB/dq; with want_params dp[:3] = dB/d(alpha, eta, w)."""
    alpha = params[0]
    eta = params[1]
    w = params[2]
    # Diffuse base seen through the coat, normalised to 1 at normal incidence.
    t_l, t_l_mu = _lerp_table(tables[0], mu_l)
    t_v, _ = _lerp_table(tables[0], mu_v)
    t1 = tables[0, TABLE_SIZE - 1]
    inv_t1_2 = 1.0 / (t1 * t1)
    diffuse = t_l * t_v * inv_t1_2
    # Specular coat: pi F D G1(l) G1(v) / (4 mu_l mu_v), half vector h = (l + v) / |l + v|.
    n = math.sqrt(2.0 + 2.0 * q)
    c = 0.5 * n  # l . h
    h_z = (mu_l + mu_v) / n
    f, f_c, f_e = fresnel_dielectric(c, eta)
    d, d_h, d_a = ggx_d(h_z, alpha)
    g_l, g_l_mu, g_l_a = smith_g1(mu_l, alpha)
    g_v, _, g_v_a = smith_g1(mu_v, alpha)
    k = math.pi / (4.0 * mu_l * mu_v)
    spec = k * f * d * g_l * g_v
    spec_mu = k * f * g_v * (d_h * g_l / n + d * g_l_mu) - spec / mu_l
    spec_q = k * g_l * g_v * (f_c * d / (4.0 * c) - f * d_h * (mu_l + mu_v) / (n * n * n))
    if want_params:
        last = TABLE_SIZE - 1
        ta_l, _ = _lerp_table(tables[1], mu_l)
        ta_v, _ = _lerp_table(tables[1], mu_v)
        te_l, _ = _lerp_table(tables[2], mu_l)
        te_v, _ = _lerp_table(tables[2], mu_v)
        diffuse_a = (ta_l * t_v + t_l * ta_v) * inv_t1_2 - 2.0 * diffuse * tables[1, last] / t1
        diffuse_e = (te_l * t_v + t_l * te_v) * inv_t1_2 - 2.0 * diffuse * tables[2, last] / t1
        spec_a = k * f * (d_a * g_l * g_v + d * g_l_a * g_v + d * g_l * g_v_a)
        spec_e = k * f_e * d * g_l * g_v
        dp[0] = diffuse_a + w * spec_a
        dp[1] = diffuse_e + w * spec_e
        dp[2] = spec
    return diffuse + w * spec, t_l_mu * t_v * inv_t1_2 + w * spec_mu, w * spec_q


@numba.njit(cache=True, inline="always", error_model="numpy")
def _plastic_value(
    mu_l: float,
    q: float,
    mu_v: float,
    a2: float,
    e2: float,
    w_spec: float,
    diffuse: float,
) -> float:
    """Rough plastic B alone (no derivatives): what whole images need.

    diffuse = T(mu_l) T(mu_v) / T(1)^2 (`_diffuse_value`), read from the tables apart:
    LLVM does not vectorise the table reads (it avoids gathers on current x86), and the
    rest, with the scalars hoisted by the caller (a2 = alpha^2, e2 = eta^2, w_spec = w),
    is branch-free so that pixel loops calling it run 4 pixels per AVX2 instruction. The
    specular term rearranged to one division (the
    same value as `_plastic`): with n2 = |l + v|^2, s = mu_l + mu_v and
    S_x = sqrt(mu_x^2 (1 - a^2) + a^2), D = a^2 n2^2 / (pi (n2 + (a^2 - 1) s^2)^2),
    G1(x) / mu_x = 2 / (mu_x + S_x), so pi F D G1(l) G1(v) / (4 mu_l mu_v)
    = F a^2 n2^2 / ((n2 + (a^2 - 1) s^2)^2 (mu_l + S_l) (mu_v + S_v)), and
    F = (r_s^2 + r_p^2) / 2 over one common denominator.
    """
    n2 = 2.0 + 2.0 * q
    c2 = 0.25 * n2
    c = math.sqrt(c2)
    g = math.sqrt(e2 - 1.0 + c2)
    # r_s = A / B, r_p = C / E.
    sa = c - g
    sb = c + g
    pc = e2 * c - g
    pe = e2 * c + g
    sum_lv = mu_l + mu_v
    kd = n2 + (a2 - 1.0) * sum_lv * sum_lv
    s_l = math.sqrt(mu_l * mu_l * (1.0 - a2) + a2)
    s_v = math.sqrt(mu_v * mu_v * (1.0 - a2) + a2)
    den_f = sb * sb * pe * pe
    num = 0.5 * (sa * sa * pe * pe + pc * pc * sb * sb) * a2 * n2 * n2
    spec = num / (den_f * kd * kd * (mu_l + s_l) * (mu_v + s_v))
    return diffuse + w_spec * spec


@numba.njit(cache=True, inline="always", error_model="numpy")
def _diffuse_value(mu_l: float, mu_v: float, transmittance: np.ndarray, inv_t1_2: float) -> float:
    """T(mu_l) T(mu_v) / T(1)^2: the plastic wall's diffuse base seen through its coat."""
    x = mu_l * (TABLE_SIZE - 1)
    k = min(max(int(x), 0), TABLE_SIZE - 2)
    w = x - k
    t_l = (1.0 - w) * transmittance[k] + w * transmittance[k + 1]
    x = mu_v * (TABLE_SIZE - 1)
    k = min(max(int(x), 0), TABLE_SIZE - 2)
    w = x - k
    t_v = (1.0 - w) * transmittance[k] + w * transmittance[k + 1]
    return t_l * t_v * inv_t1_2


@numba.njit(cache=True, inline="always", error_model="numpy")
def _oren_nayar_value(mu_l: float, q: float, mu_v: float, a: float, b: float) -> float:
    """Oren-Nayar B alone, branch-free; a, b the model's A and B (see `_oren_nayar`)."""
    u = q - mu_l * mu_v
    return a + b * max(u, 0.0) / max(mu_l, mu_v)


@numba.njit(cache=True, inline="always", error_model="numpy")
def _plastic_scalars(params: np.ndarray, tables: np.ndarray) -> tuple[float, float, float, float]:
    """(alpha^2, eta^2, w, 1 / T(1)^2): the loop invariants of `_plastic_value`."""
    t1 = tables[0, TABLE_SIZE - 1]
    return params[0] * params[0], params[1] * params[1], params[2], 1.0 / (t1 * t1)


@numba.njit(cache=True, inline="always", error_model="numpy")
def _oren_nayar_scalars(params: np.ndarray) -> tuple[float, float]:
    """(A, B) of the Oren-Nayar model for sigma = params[0]."""
    s2 = params[0] * params[0]
    return 1.0 - 0.5 * s2 / (s2 + 0.33), 0.45 * s2 / (s2 + 0.09)


#: Smallest cosine a branch-free loop feeds a model (misses are masked to B = 0 after).
_MU_FLOOR = 1e-12


@numba.njit(cache=True, inline="always", error_model="numpy")
def _point_cosines(
    x: float, y: float, l0: float, l1: float, l2: float, c0: float, c1: float, c2: float
) -> tuple[float, float, float]:
    """(mu_l, q, mu_v) at the wall point (x, y, 0) for light L and camera centre C (m)."""
    lx = l0 - x
    ly = l1 - y
    vx = c0 - x
    vy = c1 - y
    rl = 1.0 / math.sqrt(lx * lx + ly * ly + l2 * l2)
    rv = 1.0 / math.sqrt(vx * vx + vy * vy + c2 * c2)
    lz = l2 * rl
    vz = c2 * rv
    return lz, (lx * vx + ly * vy) * rl * rv + lz * vz, vz


@numba.njit(cache=True, inline="always", error_model="numpy")
def add_factor_row(
    kind: int,
    params: np.ndarray,
    tables: np.ndarray,
    light: np.ndarray,
    center: np.ndarray,
    tpx: np.ndarray,
    tpy: np.ndarray,
    bpx: np.ndarray,
    bpy: np.ndarray,
    flux_row: np.ndarray,
    total_row: np.ndarray,
    w: int,
    scratch: np.ndarray,
) -> None:
    """total_row[u] += flux_row[u] B_u for the w pixels of a row.

    B_u is B at pixel u's footprint centre, the mean of its corners (tpx, tpy: top row of
    corners, (w + 1,); bpx, bpy: bottom row), for the light at `light` and the camera
    centre `center` (world frame, m); 0 where either is not in front of the wall.
    scratch: (5, >= w) work space. Branch-free loops with the invariants hoisted, so that
    they run 4 pixels per AVX2 instruction; the plastic table reads in a loop of their own.
    """
    l0, l1, l2 = light[0], light[1], light[2]
    c0, c1, c2 = center[0], center[1], center[2]
    if kind == KIND_LAMBERTIAN:
        for u in range(w):
            total_row[u] += flux_row[u]
        return
    mu_l_row = scratch[0]
    q_row = scratch[1]
    mu_v_row = scratch[2]
    extra_row = scratch[3]
    diffuse_row = scratch[4]
    for u in range(w):
        mu_l, q, mu_v = _point_cosines(
            0.25 * (tpx[u] + tpx[u + 1] + bpx[u] + bpx[u + 1]),
            0.25 * (tpy[u] + tpy[u + 1] + bpy[u] + bpy[u + 1]),
            l0, l1, l2, c0, c1, c2,
        )  # fmt: skip
        # Misses get B = 0 below; their cosines are floored to keep the loops finite.
        extra_row[u] = 1.0 if (mu_l > 0.0) & (mu_v > 0.0) else 0.0
        mu_l_row[u] = max(mu_l, _MU_FLOOR)
        q_row[u] = q
        mu_v_row[u] = max(mu_v, _MU_FLOOR)
    if kind == KIND_PLASTIC:
        a2, e2, w_spec, inv_t1_2 = _plastic_scalars(params, tables)
        transmittance = tables[0]
        for u in range(w):
            extra_row[u] *= flux_row[u]
        for u in range(w):  # scalar: the table reads
            diffuse_row[u] = _diffuse_value(mu_l_row[u], mu_v_row[u], transmittance, inv_t1_2)
        for u in range(w):
            total_row[u] += extra_row[u] * _plastic_value(
                mu_l_row[u], q_row[u], mu_v_row[u], a2, e2, w_spec, diffuse_row[u]
            )
    else:
        a, b_on = _oren_nayar_scalars(params)
        for u in range(w):
            b = _oren_nayar_value(mu_l_row[u], q_row[u], mu_v_row[u], a, b_on)
            total_row[u] += flux_row[u] * extra_row[u] * b


@numba.njit(cache=True, inline="always", error_model="numpy")
def brdf_value(
    kind: int, mu_l: float, q: float, mu_v: float, params: np.ndarray, tables: np.ndarray
) -> float:
    """B of model `kind` without derivatives."""
    if kind == KIND_PLASTIC:
        a2, e2, w_spec, inv_t1_2 = _plastic_scalars(params, tables)
        diffuse = _diffuse_value(mu_l, mu_v, tables[0], inv_t1_2)
        return _plastic_value(mu_l, q, mu_v, a2, e2, w_spec, diffuse)
    if kind == KIND_OREN_NAYAR:
        a, b = _oren_nayar_scalars(params)
        return _oren_nayar_value(mu_l, q, mu_v, a, b)
    return 1.0


@numba.njit(cache=True, inline="always", error_model="numpy")
def point_factor(
    x: float,
    y: float,
    light: np.ndarray,
    center: np.ndarray,
    kind: int,
    params: np.ndarray,
    tables: np.ndarray,
) -> float:
    """B at the wall point (x, y, 0) for a light and a camera centre (world frame, m)."""
    lz, q, vz = _point_cosines(x, y, light[0], light[1], light[2], center[0], center[1], center[2])
    if not (lz > 0.0 and vz > 0.0):
        return 0.0
    return brdf_value(kind, lz, q, vz, params, tables)


@numba.njit(cache=True, inline="always", error_model="numpy")
def _oren_nayar(
    mu_l: float, q: float, mu_v: float, params: np.ndarray, dp: np.ndarray
) -> tuple[float, float, float]:
    """Oren-Nayar (qualitative) B = A + B_on max(0, cos(phi_l - phi_v)) sin(a) tan(b).

    sin(a) tan(b) cos(dphi) = (l_t . v_t) / max(mu_l, mu_v) with l_t . v_t = q - mu_l mu_v
    the tangential components' product, a = max(theta_l, theta_v), b = min(...).
    dp[0] receives dB/dsigma.
    """
    s2 = params[0] * params[0]
    a = 1.0 - 0.5 * s2 / (s2 + 0.33)
    b = 0.45 * s2 / (s2 + 0.09)
    a_s = -0.33 * params[0] / ((s2 + 0.33) * (s2 + 0.33))
    b_s = 0.081 * params[0] / ((s2 + 0.09) * (s2 + 0.09))
    u = q - mu_l * mu_v
    m = max(mu_l, mu_v)
    if u <= 0.0:
        dp[0] = a_s
        return a, 0.0, 0.0
    dp[0] = a_s + b_s * u / m
    d_mu = -b * mu_v / m
    if mu_l >= mu_v:
        d_mu -= b * u / (m * m)
    return a + b * u / m, d_mu, b / m


@numba.njit(cache=True, inline="always", error_model="numpy")
def brdf_terms(
    kind: int,
    mu_l: float,
    q: float,
    mu_v: float,
    params: np.ndarray,
    tables: np.ndarray,
    dp: np.ndarray,
    want_params: bool = True,
) -> tuple[float, float, float]:
    """B, dB/dmu_l, dB/dq of model `kind`; dp (MAX_PARAMS,) receives dB/d(parameters)
    (plastic: only with want_params)."""
    if kind == KIND_PLASTIC:
        return _plastic(mu_l, q, mu_v, params, tables, want_params, dp)
    if kind == KIND_OREN_NAYAR:
        return _oren_nayar(mu_l, q, mu_v, params, dp)
    return 1.0, 0.0, 0.0


@numba.njit(cache=True, inline="always", error_model="numpy")
def _directions(
    i: int, points: np.ndarray, light: np.ndarray, camera: np.ndarray
) -> tuple[float, float, float, float, float, float, float]:
    """Unit directions from wall point i to the light (l) and the camera (v), and |L - P|."""
    lx = light[0] - points[i, 0]
    ly = light[1] - points[i, 1]
    lz = light[2] - points[i, 2]
    vx = camera[0] - points[i, 0]
    vy = camera[1] - points[i, 1]
    vz = camera[2] - points[i, 2]
    r_l = math.sqrt(lx * lx + ly * ly + lz * lz)
    inv_v = 1.0 / math.sqrt(vx * vx + vy * vy + vz * vz)
    return lx / r_l, ly / r_l, lz / r_l, vx * inv_v, vy * inv_v, vz * inv_v, r_l


@numba.njit(cache=True, inline="always", error_model="numpy")
def _factor_range(
    i0: int,
    i1: int,
    points: np.ndarray,
    light: np.ndarray,
    camera: np.ndarray,
    kind: int,
    params: np.ndarray,
    tables: np.ndarray,
    out: np.ndarray,
) -> None:
    for i in range(i0, i1):
        lx, ly, lz, vx, vy, vz, _ = _directions(i, points, light, camera)
        if lz > 0.0 and vz > 0.0:
            q = lx * vx + ly * vy + lz * vz
            out[i] = brdf_value(kind, lz, q, vz, params, tables)
        else:  # light or camera not in front of the wall (or an invalid footprint)
            out[i] = 0.0


@numba.njit(cache=True, inline="always", error_model="numpy")
def _apply_range(
    i0: int,
    i1: int,
    points: np.ndarray,
    light: np.ndarray,
    camera: np.ndarray,
    kind: int,
    params: np.ndarray,
    tables: np.ndarray,
    flux: np.ndarray,
    grad: np.ndarray,
    want_grad: bool,
    out_d_params: np.ndarray,
) -> None:
    """flux *= B in place and, with want_grad, the chain rule on grad (N, 6) in place:
    d(flux B)/dL = B dflux/dL + flux dB/dL, d(flux B)/d delta = B dflux/d delta, and
    out_d_params (N, P) = flux dB/dp (P = 0: no parameters wanted)."""
    dp = np.zeros(MAX_PARAMS)
    n_p = out_d_params.shape[1]
    want_params = want_grad and n_p > 0
    for i in range(i0, i1):
        lx, ly, lz, vx, vy, vz, r_l = _directions(i, points, light, camera)
        if not (lz > 0.0 and vz > 0.0):
            f0 = 0.0
            b = 0.0
            b_mu = 0.0
            b_q = 0.0
            for d in range(n_p):
                dp[d] = 0.0
        else:
            f0 = flux[i]
            q = lx * vx + ly * vy + lz * vz
            b, b_mu, b_q = brdf_terms(kind, lz, q, vz, params, tables, dp, want_params)
        flux[i] = f0 * b
        if want_grad:
            # dB/dL = (I - l l^T) (dB/dmu e_z + dB/dq v) / |L - P|.
            gx = b_q * vx
            gy = b_q * vy
            gz = b_mu + b_q * vz
            lg = lx * gx + ly * gy + lz * gz
            s = f0 / r_l if b != 0.0 else 0.0
            grad[i, 0] = b * grad[i, 0] + s * (gx - lx * lg)
            grad[i, 1] = b * grad[i, 1] + s * (gy - ly * lg)
            grad[i, 2] = b * grad[i, 2] + s * (gz - lz * lg)
            grad[i, 3] *= b
            grad[i, 4] *= b
            grad[i, 5] *= b
            for d in range(n_p):
                out_d_params[i, d] = f0 * dp[d]


@numba.njit(cache=True, parallel=True)
def _wall_factor_parallel(
    points: np.ndarray,
    light: np.ndarray,
    camera: np.ndarray,
    kind: int,
    params: np.ndarray,
    tables: np.ndarray,
    out: np.ndarray,
) -> None:
    n = points.shape[0]
    n_chunks = min(n, 64)
    for ch in numba.prange(n_chunks):
        _factor_range(
            ch * n // n_chunks,
            (ch + 1) * n // n_chunks,
            points,
            light,
            camera,
            kind,
            params,
            tables,
            out,
        )


@numba.njit(cache=True)
def _wall_factor_serial(
    points: np.ndarray,
    light: np.ndarray,
    camera: np.ndarray,
    kind: int,
    params: np.ndarray,
    tables: np.ndarray,
    out: np.ndarray,
) -> None:
    _factor_range(0, points.shape[0], points, light, camera, kind, params, tables, out)


@numba.njit(cache=True, parallel=True)
def _apply_wall_parallel(
    points: np.ndarray,
    light: np.ndarray,
    camera: np.ndarray,
    kind: int,
    params: np.ndarray,
    tables: np.ndarray,
    flux: np.ndarray,
    grad: np.ndarray,
    want_grad: bool,
    out_d_params: np.ndarray,
) -> None:
    n = points.shape[0]
    n_chunks = min(n, 64)
    for ch in numba.prange(n_chunks):
        _apply_range(
            ch * n // n_chunks,
            (ch + 1) * n // n_chunks,
            points,
            light,
            camera,
            kind,
            params,
            tables,
            flux,
            grad,
            want_grad,
            out_d_params,
        )


@numba.njit(cache=True)
def _apply_wall_serial(
    points: np.ndarray,
    light: np.ndarray,
    camera: np.ndarray,
    kind: int,
    params: np.ndarray,
    tables: np.ndarray,
    flux: np.ndarray,
    grad: np.ndarray,
    want_grad: bool,
    out_d_params: np.ndarray,
) -> None:
    _apply_range(
        0,
        points.shape[0],
        points,
        light,
        camera,
        kind,
        params,
        tables,
        flux,
        grad,
        want_grad,
        out_d_params,
    )


#: Below this many points the kernels run on the calling thread.
SERIAL_POINTS = 20_000


def wall_factor(
    points_world: np.ndarray,
    light_world: np.ndarray,
    camera_world: np.ndarray,
    kind: int,
    params: np.ndarray,
    tables: np.ndarray,
    out: np.ndarray,
) -> None:
    """Relative reflectance B (N,) at wall points (N, 3), written to `out`.

    Args:
        points_world: (N, 3) points on the wall (z = 0), world frame, m.
        light_world: (3,) light position, world frame, m.
        camera_world: (3,) camera centre, world frame, m.
        kind, params, tables: the model (`WallReflectance.data()`).
        out: (N,) B; 0 where the light or camera is not in front of the wall or the
            point is NaN.
    """
    kernel = _wall_factor_serial if len(points_world) < SERIAL_POINTS else _wall_factor_parallel
    kernel(points_world, light_world, camera_world, int(kind), params, tables, out)


def apply_wall(
    points_world: np.ndarray,
    light_world: np.ndarray,
    camera_world: np.ndarray,
    kind: int,
    params: np.ndarray,
    tables: np.ndarray,
    flux: np.ndarray,
    grad: np.ndarray,
    *,
    want_grad: bool,
    out_d_params: np.ndarray,
) -> None:
    """Multiply one light's flux by B at the footprint centres, gradients chained, in place.

    Args:
        points_world: (N, 3) footprint centres; light_world, camera_world: (3,), m.
        kind, params, tables: the model (`WallReflectance.data()`).
        flux: (N,) the light's flux, multiplied in place.
        grad: (N, 6) d flux / d (L_world, delta_world), chained in place (want_grad).
        out_d_params: (N, P) receives flux dB/d(parameters) (P = 0: none wanted).
    """
    kernel = _apply_wall_serial if len(points_world) < SERIAL_POINTS else _apply_wall_parallel
    kernel(
        points_world,
        light_world,
        camera_world,
        int(kind),
        params,
        tables,
        flux,
        grad,
        bool(want_grad),
        out_d_params,
    )


@numba.njit(cache=True)
def brdf_many(
    mu_l: np.ndarray,
    q: np.ndarray,
    mu_v: np.ndarray,
    kind: int,
    params: np.ndarray,
    tables: np.ndarray,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """`brdf_terms` at N direction pairs (mu_l, q, mu_v (N,) each, all mu > 0).

    Returns:
        B, dB/dmu_l, dB/dq (N,) and dB/d(parameters) (N, MAX_PARAMS).
    """
    n = mu_l.shape[0]
    b = np.empty(n)
    b_mu = np.empty(n)
    b_q = np.empty(n)
    dp = np.zeros((n, MAX_PARAMS))
    for i in range(n):
        b[i], b_mu[i], b_q[i] = brdf_terms(kind, mu_l[i], q[i], mu_v[i], params, tables, dp[i])
    return b, b_mu, b_q, dp
