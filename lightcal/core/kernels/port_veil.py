"""The veil of a light behind its flat port, compiled: the single-scattering integral of
the refracted beam along each pixel's ray, with its gradients
(`lightcal.core.light_port_veil`; docs/model.md, "The light's flat port").

Along the ray X(t) = C + t o from where it enters the water (the camera centre, or its
exit point from the camera's port) to the footprint centre P, the beam lights X with the
irradiance (per I0, normal to the beam)

    E(X) = f(u_a) T_F(theta_a) J exp(-c s_w),   J = dOmega_air / dA_perp,

u_a the solved air direction from the emitter to X (`kernels.port_paths.solve_paths`),
f the RID in air, T_F the port's Fresnel transmittance, s_w = H / cos(theta_w) the
beam's path in the water from the port's outer face (H = h - d - t) and J the refracted
bundle's Jacobian: the paths are axisymmetric about the port's normal, rho(theta_a) =
d tan(theta_a) + t tan(theta_g) + H tan(theta_w) = s q(s, H) at axial depth h, s =
sin(theta_a), so on the plane of constant h dA = rho drho dphi, dA_perp = dA cos(theta_w),
dOmega_air = sin(theta_a) dtheta_a dphi and

    J = sin(theta_a) / (rho (drho/dtheta_a) cos(theta_w)) = n_w / (q g_s c_a C_w),
    q = d / c_a + t / C_g + H / C_w,   g_s = d / c_a^3 + t n_g^2 / C_g^3 + H n_w^2 / C_w^3,

c_a = cos(theta_a), C_g = sqrt(n_g^2 - s^2), C_w = sqrt(n_w^2 - s^2) (indices relative to
the air's; g_s = drho/ds, the path equation's derivative): a smooth function of s^2 and
H, finite on the axis (1 / (d + t / n_g + H / n_w)^2), 1 / r^2 with the indices 1. The
veil is

    S = integral p(mu) E(X) exp(-c t) dt,   mu = -w . o,

p the Henyey-Greenstein phase function and w = (u_a + (C_w - c_a) n) / n_w the beam's
water direction at X (Snell's law in vector form), over the part of the ray in front of
the port's outer face (n . Y > d + t: behind it, in the housing's plane, the beam does not
reach). The 1 / r^2-like peak sits at the beam's paraxial virtual source V (the emitter
seen from the water, n_w (d + t / n_g) behind the outer face): equiangular Gauss-Legendre
nodes about V (as `kernels.backscatter.ray_integral` about the emitter).

The gradients in the light's pose are the rule applied to the integrand's derivatives in
the light-frame point Y = R^T (X - L) (through du_a/dY, ds/dY = a and dH/dY = n, as
`kernels.port_flux._pull_back`) plus the phase function's explicit rotation (w = R w_l),
and, where the outer face's plane cuts the ray, Leibniz's boundary term -+ E p
dt_c/d(L, delta), the integrand evaluated 1 nm in front of the face.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from lightcal.core.kernels.port_flux import _pull_back, to_light, transmittance
from lightcal.core.kernels.port_paths import PATH_SIZE, WORK_SIZE, solve_paths
from lightcal.core.rid_eval import RIDData, RIDTuple, rid_value_direction, rid_value_grad_direction

#: Below this many rays the kernels run on the calling thread (each ray solves a path per
#: node: 24 of them, about the work of 5 pixels' flux through the port).
VEIL_SERIAL_RAYS = 1_000

#: How far in front of the outer face the boundary term's integrand is taken, m (its
#: relative change over it is ~1e-9 / (d + t)).
_FACE_EPS_M = 1e-9

_FOUR_PI = 4.0 * math.pi


@numba.njit(cache=True, inline="always", error_model="numpy")
def bundle_jacobian(
    s: float, big_h: float, d: float, t: float, n_g: float, n_w: float
) -> tuple[float, float, float, float]:
    """J = dOmega_air / dA_perp of the path with sin(theta_a) = s reaching H beyond the
    outer face (module docstring), d ln J / ds, d ln J / dH and C_w = sqrt(n_w^2 - s^2)."""
    s2 = s * s
    i_a = 1.0 / math.sqrt(1.0 - s2)
    i_g = 1.0 / math.sqrt(n_g * n_g - s2)
    c_w = math.sqrt(n_w * n_w - s2)
    i_w = 1.0 / c_w
    a3, g3, w3 = i_a * i_a * i_a, i_g * i_g * i_g, i_w * i_w * i_w
    q = d * i_a + t * i_g + big_h * i_w
    g_s = d * a3 + t * n_g * n_g * g3 + big_h * n_w * n_w * w3
    jac = n_w * i_a * i_w / (q * g_s)
    q_s = s * (d * a3 + t * g3 + big_h * w3)
    g_ss = 3.0 * s * (d * a3 * i_a * i_a + t * n_g * n_g * g3 * i_g * i_g)
    g_ss += 3.0 * s * big_h * n_w * n_w * w3 * i_w * i_w
    dln_s = -q_s / q - g_ss / g_s + s * (i_a * i_a + i_w * i_w)
    dln_h = -i_w / q - n_w * n_w * w3 / g_s
    return jac, dln_s, dln_h, c_w


@numba.njit(cache=True, error_model="numpy")
def port_ray_integral(
    px: float, py: float, pz: float, camera: np.ndarray, light: np.ndarray, R: np.ndarray,
    rid: RIDData, normal: np.ndarray, geometry: np.ndarray, c: float, g: float,
    s_nodes: np.ndarray, s_weights: np.ndarray, want_grad: bool, grad: np.ndarray,
    ys: np.ndarray, work: np.ndarray, active: np.ndarray, ok: np.ndarray, paths: np.ndarray,
    ts: np.ndarray,
) -> float:  # fmt: skip
    """S of the ray from `camera` (3,) to the wall point (px, py, pz) (module docstring).

    Args:
        light, R: the emitter (3,) and R_world_light (3, 3); normal: the port's unit normal
            (3,), light frame; geometry: (7,) d, t, n_g / n_a, n_w / n_a, n_a, n_g, n_w.
        grad: with want_grad, (8,) receives dS / d (L_world, delta_world, c, g).
        ys .. ts: scratch of m + 1 rows (m the nodes): (m+1, 3), (m+1, 5), (m+1,),
            (m+1,) bool, (m+1,) bool, (m+1, PATH_SIZE), (m+1,).
    """
    if want_grad:
        grad[:] = 0.0
    d, th, n_g, n_w = geometry[0], geometry[1], geometry[2], geometry[3]
    n_a, i_g, i_w = geometry[4], geometry[5], geometry[6]
    o = np.empty(3)
    o[0], o[1], o[2] = px - camera[0], py - camera[1], pz - camera[2]
    t_w = math.sqrt(o[0] * o[0] + o[1] * o[1] + o[2] * o[2])
    if not (math.isfinite(t_w) and t_w > 0.0):
        return 0.0
    o /= t_w
    n_world = np.empty(3)
    o_l = np.empty(3)
    for k in range(3):
        n_world[k] = R[k, 0] * normal[0] + R[k, 1] * normal[1] + R[k, 2] * normal[2]
        o_l[k] = R[0, k] * o[0] + R[1, k] * o[1] + R[2, k] * o[2]
    face = d + th
    h_start = n_world[0] * (camera[0] - light[0]) + n_world[1] * (camera[1] - light[1])
    h_start += n_world[2] * (camera[2] - light[2]) - face
    h_o = n_world[0] * o[0] + n_world[1] * o[1] + n_world[2] * o[2]
    t_lo, t_hi, clip, t_c = 0.0, t_w, 0, 0.0
    if h_o != 0.0:
        t_c = -h_start / h_o
        if h_o > 0.0 and t_c > t_lo:
            t_lo, clip = t_c, -1
        elif h_o < 0.0 and t_c < t_hi:
            t_hi, clip = t_c, 1
    elif h_start <= 0.0:
        return 0.0
    if not t_hi > t_lo:
        return 0.0
    # Equiangular nodes about the paraxial virtual source V = L + h_v n.
    h_v = face - n_w * (d + th / n_g)
    v0 = light[0] + h_v * n_world[0] - camera[0]
    v1 = light[1] + h_v * n_world[1] - camera[1]
    v2 = light[2] + h_v * n_world[2] - camera[2]
    t0 = v0 * o[0] + v1 * o[1] + v2 * o[2]
    b = math.sqrt(max(v0 * v0 + v1 * v1 + v2 * v2 - t0 * t0, 1e-18))
    phi_a = math.atan2(t_lo - t0, b)
    span = math.atan2(t_hi - t0, b) - phi_a
    m = s_nodes.shape[0]
    x = np.empty(3)
    for j in range(m):
        phi = phi_a + span * s_nodes[j]
        ts[j] = t0 + b * math.tan(phi)
        for k in range(3):
            x[k] = camera[k] + ts[j] * o[k]
        to_light(x, light, R, ys[j])
    n_pts = m
    if clip != 0 and want_grad:  # the integrand at the face, 1 nm in front of it
        ts[m] = min(max(t_c - clip * _FACE_EPS_M / abs(h_o), t_lo), t_hi)
        for k in range(3):
            x[k] = camera[k] + ts[m] * o[k]
        to_light(x, light, R, ys[m])
        n_pts = m + 1
    solve_paths(ys, n_pts, normal, d, th, n_g, n_w, work, active, ok, paths)
    kp = (1.0 - g * g) / _FOUR_PI
    acc = np.zeros(6)
    acc_w = np.zeros(3)
    v = np.empty(3)
    total = 0.0
    at_face = 0.0
    for j in range(n_pts):
        if not ok[j]:
            continue
        p = paths[j]
        big_h = work[j, 4]
        s, c_a = p[11], p[12]
        jac, dln_s, dln_h, c_w = bundle_jacobian(s, big_h, d, th, n_g, n_w)
        water = big_h * n_w / c_w
        shift = c_w - c_a
        wl0 = (p[0] + shift * normal[0]) / n_w
        wl1 = (p[1] + shift * normal[1]) / n_w
        wl2 = (p[2] + shift * normal[2]) / n_w
        w0 = R[0, 0] * wl0 + R[0, 1] * wl1 + R[0, 2] * wl2
        w1 = R[1, 0] * wl0 + R[1, 1] * wl1 + R[1, 2] * wl2
        w2 = R[2, 0] * wl0 + R[2, 1] * wl1 + R[2, 2] * wl2
        wo = w0 * o[0] + w1 * o[1] + w2 * o[2]
        dd = 1.0 + g * g + 2.0 * g * wo
        ph = kp / (dd * math.sqrt(dd))
        if want_grad:
            f, f0, f1, f2 = rid_value_grad_direction(p[0], p[1], p[2], rid)
        else:
            f = rid_value_direction(p[0], p[1], p[2], rid)
        tf, dtf = transmittance(min(max(c_a, 1e-300), 1.0), n_a, i_g, i_w)
        e = math.exp(-c * (water + ts[j]))
        value = ph * f * tf * jac * e
        if j == m:
            at_face = value
            continue
        wt = s_weights[j] * span * b / math.cos(phi_a + span * s_nodes[j]) ** 2
        total += wt * value
        if not want_grad:
            continue
        # d/dY through u_a (RID, T_F, the phase's w), s (J, s_w, w) and H (J, s_w).
        wv = wt * value
        pw = wt * f * tf * jac * e * (-3.0 * g * kp / (dd * dd * math.sqrt(dd)))
        gu = wt * ph * tf * jac * e
        gn = wt * ph * f * jac * e * dtf
        gw_n = pw * (o_l[0] * normal[0] + o_l[1] * normal[1] + o_l[2] * normal[2]) / n_w
        _pull_back(
            p, normal, gu * f0 + gn * normal[0] + pw * o_l[0] / n_w,
            gu * f1 + gn * normal[1] + pw * o_l[1] / n_w,
            gu * f2 + gn * normal[2] + pw * o_l[2] / n_w, ys[j], acc,
        )  # fmt: skip
        sig_s = gw_n * (s / c_a - s / c_w) + wv * (dln_s - c * big_h * n_w * s / c_w**3)
        sig_h = wv * (dln_h - c * n_w / c_w)
        y = ys[j]
        for k in range(3):
            v[k] = sig_s * p[6 + k] + sig_h * normal[k]
            acc[k] += v[k]
        acc[3] += v[1] * y[2] - v[2] * y[1]
        acc[4] += v[2] * y[0] - v[0] * y[2]
        acc[5] += v[0] * y[1] - v[1] * y[0]
        # The phase's explicit rotation: dp = dp/dw . (delta x w) = delta . (w x dp/dw).
        acc_w[0] += pw * (w1 * o[2] - w2 * o[1])
        acc_w[1] += pw * (w2 * o[0] - w0 * o[2])
        acc_w[2] += pw * (w0 * o[1] - w1 * o[0])
        grad[6] -= wv * (water + ts[j])
        grad[7] += wv * (-2.0 * g / (1.0 - g * g) - 3.0 * (g + wo) / dd)
    if want_grad:
        for k in range(3):
            grad[k] = -(R[k, 0] * acc[0] + R[k, 1] * acc[1] + R[k, 2] * acc[2])
            grad[3 + k] = R[k, 0] * acc[3] + R[k, 1] * acc[4] + R[k, 2] * acc[5] + acc_w[k]
        if clip != 0:
            # Leibniz: the face's crossing t_c moves with the pose, dt_c/dL = n / (n . o),
            # dt_c/d delta = -(n x (X_c - L)) / (n . o); the clipped end is the lower
            # (clip -1: -E dt_c) or the upper (clip 1: +E dt_c).
            k_c = clip * at_face / h_o
            for k in range(3):
                x[k] = camera[k] + t_c * o[k] - light[k]
            grad[0] += k_c * n_world[0]
            grad[1] += k_c * n_world[1]
            grad[2] += k_c * n_world[2]
            grad[3] -= k_c * (n_world[1] * x[2] - n_world[2] * x[1])
            grad[4] -= k_c * (n_world[2] * x[0] - n_world[0] * x[2])
            grad[5] -= k_c * (n_world[0] * x[1] - n_world[1] * x[0])
    return total


@numba.njit(cache=True, error_model="numpy")
def _rays_range(
    lo: int, hi: int, points: np.ndarray, camera: np.ndarray, light: np.ndarray,
    R: np.ndarray, rid: RIDData, normal: np.ndarray, geometry: np.ndarray, c: float,
    g: float, s_nodes: np.ndarray, s_weights: np.ndarray, want_grad: bool, out: np.ndarray,
    out_grad: np.ndarray,
) -> None:  # fmt: skip
    """`port_scatter_points` of the rays lo..hi-1 (scratch buffers for the range)."""
    m1 = s_nodes.shape[0] + 1
    ys = np.empty((m1, 3))
    work = np.empty((m1, WORK_SIZE))
    active = np.empty(m1, dtype=np.bool_)
    ok = np.empty(m1, dtype=np.bool_)
    paths = np.empty((m1, PATH_SIZE))
    ts = np.empty(m1)
    g8 = np.zeros(8)
    per_ray = camera.shape[0] > 1
    for i in range(lo, hi):
        out[i] = port_ray_integral(
            points[i, 0], points[i, 1], points[i, 2], camera[i] if per_ray else camera[0],
            light, R, rid, normal, geometry, c, g, s_nodes, s_weights, want_grad, g8, ys,
            work, active, ok, paths, ts,
        )  # fmt: skip
        if want_grad:
            out_grad[i, :] = g8


@numba.njit(cache=True, parallel=True, error_model="numpy")
def _rays_parallel(
    points: np.ndarray, camera: np.ndarray, light: np.ndarray, R: np.ndarray,
    rid: RIDTuple, normal: np.ndarray, geometry: np.ndarray, c: float, g: float,
    s_nodes: np.ndarray, s_weights: np.ndarray, want_grad: bool, out: np.ndarray,
    out_grad: np.ndarray,
) -> None:  # fmt: skip
    """`_rays_range` on all threads, in chunks of rays."""
    n = points.shape[0]
    n_chunks = min(n, 64)
    for ch in numba.prange(n_chunks):
        _rays_range(
            ch * n // n_chunks, (ch + 1) * n // n_chunks, points, camera, light, R,
            RIDData(*rid), normal, geometry, c, g, s_nodes, s_weights, want_grad, out,
            out_grad,
        )  # fmt: skip


@numba.njit(cache=True, error_model="numpy")
def _rays_serial(
    points: np.ndarray, camera: np.ndarray, light: np.ndarray, R: np.ndarray,
    rid: RIDTuple, normal: np.ndarray, geometry: np.ndarray, c: float, g: float,
    s_nodes: np.ndarray, s_weights: np.ndarray, want_grad: bool, out: np.ndarray,
    out_grad: np.ndarray,
) -> None:  # fmt: skip
    """`_rays_range` on the calling thread."""
    _rays_range(
        int(0),  # noqa: UP018, RUF046 (not a literal type)
        points.shape[0], points, camera, light, R, RIDData(*rid), normal, geometry, c, g,
        s_nodes, s_weights, want_grad, out, out_grad,
    )  # fmt: skip


def port_scatter_points(
    points_world: np.ndarray,
    camera_world: np.ndarray,
    light_world: np.ndarray,
    R_world_light: np.ndarray,
    rid: RIDTuple,
    normal: np.ndarray,
    geometry: np.ndarray,
    attenuation_per_m: float,
    phase_g: float,
    s_nodes: np.ndarray,
    s_weights: np.ndarray,
    want_grad: bool,
) -> tuple[np.ndarray, np.ndarray]:
    """S (N,) of the rays to wall points (N, 3) from `camera_world`, (3,) one start for
    all or (N, 3) one per ray (`port_ray_integral`), and its gradients (N, 8) ((0, 8)
    unless want_grad).

    Args:
        rid: `rid_eval.rid_tuple` of the RID; normal: (3,) the port's unit normal (light
            frame); geometry: (7,) as `kernels.port_flux.port_flux_pixels`'.
        s_nodes, s_weights: Gauss-Legendre nodes and weights on [0, 1].
    """
    n = len(points_world)
    out = np.empty(n)
    out_grad = np.zeros((n, 8) if want_grad else (0, 8))
    kernel = _rays_serial if n < VEIL_SERIAL_RAYS else _rays_parallel
    kernel(
        np.ascontiguousarray(points_world, dtype=np.float64).reshape(-1, 3),
        np.ascontiguousarray(np.reshape(camera_world, (-1, 3)), dtype=np.float64),
        np.ascontiguousarray(light_world, dtype=np.float64),
        np.ascontiguousarray(R_world_light, dtype=np.float64), rid,
        np.ascontiguousarray(normal, dtype=np.float64),
        np.ascontiguousarray(geometry, dtype=np.float64), float(attenuation_per_m),
        float(phase_g), s_nodes, s_weights, bool(want_grad), out, out_grad,
    )  # fmt: skip
    return out, out_grad
