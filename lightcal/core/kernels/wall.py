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
def _plastic_core(
    mu_l: float,
    q: float,
    mu_v: float,
    alpha: float,
    eta: float,
    w: float,
    t_l: float,
    t_l_mu: float,
    t_v: float,
    t1: float,
    want_params: bool,
    ta_l: float,
    ta_v: float,
    te_l: float,
    te_v: float,
    ta1: float,
    te1: float,
) -> tuple[float, float, float, float, float, float]:
    """Rough plastic B, dB/dmu_l, dB/dq, dB/d(alpha, eta, w) from the table reads.

    t_l, t_l_mu, t_v: T(mu_l), dT/dmu(mu_l), T(mu_v); t1 = T(1); with want_params
    ta_x, te_x = dT/dalpha, dT/deta at mu_x and ta1, te1 at 1 (else their dB/dp are 0).
    Branch-free arithmetic: loops calling it vectorise.
    """
    # Diffuse base seen through the coat, normalised to 1 at normal incidence.
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
    dp0 = 0.0
    dp1 = 0.0
    dp2 = 0.0
    if want_params:
        diffuse_a = (ta_l * t_v + t_l * ta_v) * inv_t1_2 - 2.0 * diffuse * ta1 / t1
        diffuse_e = (te_l * t_v + t_l * te_v) * inv_t1_2 - 2.0 * diffuse * te1 / t1
        spec_a = k * f * (d_a * g_l * g_v + d * g_l_a * g_v + d * g_l * g_v_a)
        spec_e = k * f_e * d * g_l * g_v
        dp0 = diffuse_a + w * spec_a
        dp1 = diffuse_e + w * spec_e
        dp2 = spec
    return (
        diffuse + w * spec,
        t_l_mu * t_v * inv_t1_2 + w * spec_mu,
        w * spec_q,
        dp0,
        dp1,
        dp2,
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
    last = TABLE_SIZE - 1
    t_l, t_l_mu = _lerp_table(tables[0], mu_l)
    t_v, _ = _lerp_table(tables[0], mu_v)
    ta_l = ta_v = te_l = te_v = 0.0
    if want_params:
        ta_l, _ = _lerp_table(tables[1], mu_l)
        ta_v, _ = _lerp_table(tables[1], mu_v)
        te_l, _ = _lerp_table(tables[2], mu_l)
        te_v, _ = _lerp_table(tables[2], mu_v)
    b, b_mu, b_q, dp0, dp1, dp2 = _plastic_core(
        mu_l, q, mu_v, params[0], params[1], params[2], t_l, t_l_mu, t_v, tables[0, last],
        want_params, ta_l, ta_v, te_l, te_v, tables[1, last], tables[2, last],
    )  # fmt: skip
    if want_params:
        dp[0] = dp0
        dp[1] = dp1
        dp[2] = dp2
    return b, b_mu, b_q


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
def _oren_nayar_scalars(params: np.ndarray) -> tuple[float, float, float, float]:
    """(A, B, dA/dsigma, dB/dsigma) of the Oren-Nayar model for sigma = params[0]."""
    sigma = params[0]
    s2 = sigma * sigma
    return (
        1.0 - 0.5 * s2 / (s2 + 0.33),
        0.45 * s2 / (s2 + 0.09),
        -0.33 * sigma / ((s2 + 0.33) * (s2 + 0.33)),
        0.081 * sigma / ((s2 + 0.09) * (s2 + 0.09)),
    )


#: Smallest cosine a branch-free loop feeds a model (misses are masked to B = 0 after).
_MU_FLOOR = 1e-12
MU_FLOOR = _MU_FLOOR  # (the mesh's wall factor, `lightcal.core.wall_mesh`)


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
        a, b_on, _, _ = _oren_nayar_scalars(params)
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
        a, b, _, _ = _oren_nayar_scalars(params)
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
    Returns B, dB/dmu_l, dB/dq; dp[0] receives dB/dsigma.
    """
    a, b, a_s, b_s = _oren_nayar_scalars(params)
    value, d_mu, d_q, dp[0] = _oren_nayar_branch_free(mu_l, q, mu_v, a, b, a_s, b_s)
    return value, d_mu, d_q


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
def _oren_nayar_branch_free(
    mu_l: float, q: float, mu_v: float, a: float, b: float, a_s: float, b_s: float
) -> tuple[float, float, float, float]:
    """Oren-Nayar B, dB/dmu_l, dB/dq, dB/dsigma, with selects for branches (vectorises);
    a, b, a_s, b_s: `_oren_nayar_scalars`."""
    u = q - mu_l * mu_v
    m = mu_l if mu_l >= mu_v else mu_v
    lit = u > 0.0
    u_pos = u if lit else 0.0
    d_mu = -b * mu_v / m - (b * u / (m * m) if mu_l >= mu_v else 0.0)
    return (
        a + b * u_pos / m,
        d_mu if lit else 0.0,
        b / m if lit else 0.0,
        a_s + b_s * u_pos / m,
    )


#: Points per block of the wall kernels' passes (their work rows stay in L1).
_BLOCK = 256
# Offsets of the work rows of `_model_block`: unit l (3), unit v (3), |L - P|, l . v, in
# front (1 / 0), the table reads (7), and B, dB/dmu_l, dB/dq, dB/dp (MAX_PARAMS).
_LX, _LY, _LZ, _VX, _VY, _VZ, _RL, _Q, _OK = (r * _BLOCK for r in range(9))
_T_L, _T_L_MU, _T_V, _TA_L, _TA_V, _TE_L, _TE_V = (r * _BLOCK for r in range(9, 16))
_B, _B_MU, _B_Q, _DP = (r * _BLOCK for r in range(16, 20))
_WORK_SIZE = _DP + MAX_PARAMS * _BLOCK


@numba.njit(cache=True, inline="always", error_model="numpy")
def _model_block(
    b0: int,
    b1: int,
    points: np.ndarray,
    light: np.ndarray,
    camera: np.ndarray,
    kind: int,
    params: np.ndarray,
    tables: np.ndarray,
    want_params: bool,
    work: np.ndarray,
) -> None:
    """B and its derivatives at points b0..b1 - 1 into the rows of work (_WORK_SIZE,).

    work holds its rows one after the other (row r's value for point j at r * _BLOCK + j): one
    array with constant offsets, so that LLVM sees the rows do not overlap.

    Three passes: directions (vectorised), the plastic table reads (scalar: LLVM does not
    gather on current x86) and the model (vectorised, branch-free). B and all its
    derivatives are 0 where the light or the camera is not in front of the wall (or the
    point is NaN); the models see cosines floored at _MU_FLOOR there, to stay finite.
    """
    m = b1 - b0
    l0, l1, l2 = light[0], light[1], light[2]
    c0, c1, c2 = camera[0], camera[1], camera[2]
    for j in range(m):
        i = b0 + j
        lx = l0 - points[i, 0]
        ly = l1 - points[i, 1]
        lz = l2 - points[i, 2]
        vx = c0 - points[i, 0]
        vy = c1 - points[i, 1]
        vz = c2 - points[i, 2]
        r_l = math.sqrt(lx * lx + ly * ly + lz * lz)
        inv_v = 1.0 / math.sqrt(vx * vx + vy * vy + vz * vz)
        ulx, uly, ulz = lx / r_l, ly / r_l, lz / r_l
        uvx, uvy, uvz = vx * inv_v, vy * inv_v, vz * inv_v
        work[_LX + j] = ulx
        work[_LY + j] = uly
        work[_LZ + j] = ulz
        work[_VX + j] = uvx
        work[_VY + j] = uvy
        work[_VZ + j] = uvz
        work[_RL + j] = r_l
        work[_Q + j] = ulx * uvx + uly * uvy + ulz * uvz
        work[_OK + j] = 1.0 if (ulz > 0.0) & (uvz > 0.0) else 0.0
    if kind == KIND_PLASTIC:
        for j in range(m):  # scalar: the table reads
            mu_l = _floor_mu(work[_LZ + j])
            mu_v = _floor_mu(work[_VZ + j])
            work[_T_L + j], work[_T_L_MU + j] = _lerp_table(tables[0], mu_l)
            work[_T_V + j], _ = _lerp_table(tables[0], mu_v)
            if want_params:
                work[_TA_L + j], _ = _lerp_table(tables[1], mu_l)
                work[_TA_V + j], _ = _lerp_table(tables[1], mu_v)
                work[_TE_L + j], _ = _lerp_table(tables[2], mu_l)
                work[_TE_V + j], _ = _lerp_table(tables[2], mu_v)
            else:
                work[_TA_L + j] = work[_TA_V + j] = work[_TE_L + j] = work[_TE_V + j] = 0.0
        last = TABLE_SIZE - 1
        alpha, eta, w = params[0], params[1], params[2]
        t1, ta1, te1 = tables[0, last], tables[1, last], tables[2, last]
        for j in range(m):
            b, b_mu, b_q, dp0, dp1, dp2 = _plastic_core(
                _floor_mu(work[_LZ + j]), work[_Q + j], _floor_mu(work[_VZ + j]), alpha, eta, w,
                work[_T_L + j], work[_T_L_MU + j], work[_T_V + j], t1, want_params,
                work[_TA_L + j], work[_TA_V + j], work[_TE_L + j], work[_TE_V + j], ta1, te1,
            )  # fmt: skip
            ok = work[_OK + j] != 0.0
            work[_B + j] = b if ok else 0.0
            work[_B_MU + j] = b_mu if ok else 0.0
            work[_B_Q + j] = b_q if ok else 0.0
            work[_DP + j] = dp0 if ok else 0.0
            work[_DP + 1 * _BLOCK + j] = dp1 if ok else 0.0
            work[_DP + 2 * _BLOCK + j] = dp2 if ok else 0.0
    elif kind == KIND_OREN_NAYAR:
        a, bb, a_s, b_s = _oren_nayar_scalars(params)
        for j in range(m):
            b, b_mu, b_q, dp0 = _oren_nayar_branch_free(
                _floor_mu(work[_LZ + j]), work[_Q + j], _floor_mu(work[_VZ + j]), a, bb, a_s, b_s
            )
            ok = work[_OK + j] != 0.0
            work[_B + j] = b if ok else 0.0
            work[_B_MU + j] = b_mu if ok else 0.0
            work[_B_Q + j] = b_q if ok else 0.0
            work[_DP + j] = dp0 if ok else 0.0
            work[_DP + 1 * _BLOCK + j] = 0.0
            work[_DP + 2 * _BLOCK + j] = 0.0
    else:
        for j in range(m):
            ok = work[_OK + j] != 0.0
            work[_B + j] = 1.0 if ok else 0.0
            work[_B_MU + j] = work[_B_Q + j] = 0.0
            work[_DP + j] = work[_DP + 1 * _BLOCK + j] = work[_DP + 2 * _BLOCK + j] = 0.0


@numba.njit(cache=True, inline="always", error_model="numpy")
def _floor_mu(mu: float) -> float:
    """mu where it is above _MU_FLOOR, else _MU_FLOOR (NaN included)."""
    return mu if mu > _MU_FLOOR else _MU_FLOOR


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
    work = np.empty(_WORK_SIZE)
    for b0 in range(i0, i1, _BLOCK):
        b1 = min(b0 + _BLOCK, i1)
        _model_block(b0, b1, points, light, camera, kind, params, tables, False, work)
        for j in range(b1 - b0):
            out[b0 + j] = work[_B + j]


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
    n_p = out_d_params.shape[1]
    want_params = want_grad and n_p > 0
    work = np.empty(_WORK_SIZE)
    for b0 in range(i0, i1, _BLOCK):
        b1 = min(b0 + _BLOCK, i1)
        _model_block(b0, b1, points, light, camera, kind, params, tables, want_params, work)
        for j in range(b1 - b0):
            i = b0 + j
            b = work[_B + j]
            f0 = flux[i] if work[_OK + j] != 0.0 else 0.0
            flux[i] = f0 * b
            if want_grad:
                # dB/dL = (I - l l^T) (dB/dmu e_z + dB/dq v) / |L - P|.
                lx, ly, lz = work[_LX + j], work[_LY + j], work[_LZ + j]
                b_q = work[_B_Q + j]
                gx = b_q * work[_VX + j]
                gy = b_q * work[_VY + j]
                gz = work[_B_MU + j] + b_q * work[_VZ + j]
                lg = lx * gx + ly * gy + lz * gz
                s = f0 / work[_RL + j] if b != 0.0 else 0.0
                grad[i, 0] = b * grad[i, 0] + s * (gx - lx * lg)
                grad[i, 1] = b * grad[i, 1] + s * (gy - ly * lg)
                grad[i, 2] = b * grad[i, 2] + s * (gz - lz * lg)
                grad[i, 3] *= b
                grad[i, 4] *= b
                grad[i, 5] *= b
                for d in range(n_p):
                    out_d_params[i, d] = f0 * work[_DP + d * _BLOCK + j]


@numba.njit(cache=True, parallel=True, error_model="numpy")
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


@numba.njit(cache=True, error_model="numpy")
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


@numba.njit(cache=True, parallel=True, error_model="numpy")
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


@numba.njit(cache=True, error_model="numpy")
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
