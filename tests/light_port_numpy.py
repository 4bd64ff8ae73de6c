"""The light's flat port in NumPy, as it was before its kernels
(`lightcal.core.kernels.port_flux`, `port_water`): the reference
tests/test_light_port_kernels.py holds the compiled path to (the code of
`lightcal.core.light_port` and `lightcal.core.light_port_flux.quads_flux`,
`attenuate_through_port` at the time, unchanged)."""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np

from lightcal.core.flat_port import FlatPort
from lightcal.core.fresnel import port_transmittance
from lightcal.core.rid_eval import RIDData, rid_value_grad_direction

#: Newton iterations at most (measured: 11 for d = 2 cm, 13 for d = 2 mm, up to 70 deg).
MAX_NEWTON = 100


def _indices(port: FlatPort) -> tuple[float, float]:
    """The glass's and the water's indices relative to the air's."""
    return port.glass_index / port.air_index, port.water_index / port.air_index


def air_sines(rho_m: np.ndarray, h_m: np.ndarray, port: FlatPort) -> tuple[np.ndarray, np.ndarray]:
    """sin(theta_a) of the refracted paths from the emitter to points at radial distance
    rho_m (M,) and axial distance h_m (M,) from it (port frame, m).

    Returns:
        s: (M,) the sine of the air ray's angle to the port's normal (NaN where not ok).
        ok: (M,) the point is finite and in front of the port's outer face (h > d + t).
    """
    rho = np.asarray(rho_m, dtype=np.float64)
    h = np.asarray(h_m, dtype=np.float64)
    d, t = port.distance_m, port.thickness_m
    n_g, n_w = _indices(port)
    big_h = h - d - t
    ok = np.isfinite(rho) & np.isfinite(big_h) & (big_h > 0.0)
    r = np.where(ok, rho, 0.0)
    hh = np.where(ok, big_h, 1.0)
    # Right of the root: the smallest s at which one term alone reaches rho.
    s = r / np.hypot(r, d)
    s = np.minimum(s, n_w * r / np.hypot(r, hh))
    if t > 0.0:
        s = np.minimum(s, n_g * r / np.hypot(r, t))
    active = r > 0.0
    for _ in range(MAX_NEWTON):
        if not np.any(active):
            break
        sa = s[active]
        g, g_s = _path_equation(sa, r[active], hh[active], d, t, n_g, n_w)
        step = g / g_s
        new = sa - step
        s[active] = new
        # Quadratic convergence: a step this small leaves an error far below it; a step
        # <= 0 is round-off at the root (from the right every step is > 0).
        done = (np.abs(step) <= 1e-15 * new) | (step <= 0.0)
        idx = np.flatnonzero(active)
        active[idx[done]] = False
    s = np.where(ok, s, np.nan)
    return s, ok


def _path_equation(
    s: np.ndarray, rho: np.ndarray, big_h: np.ndarray, d: float, t: float, n_g: float, n_w: float
) -> tuple[np.ndarray, np.ndarray]:
    """g(s) = d tan(theta_a) + t tan(theta_g) + H tan(theta_w) - rho and dg/ds, (M,) each."""
    c_a2 = 1.0 - s * s
    c_g2 = n_g * n_g - s * s
    c_w2 = n_w * n_w - s * s
    g = d * s / np.sqrt(c_a2) + t * s / np.sqrt(c_g2) + big_h * s / np.sqrt(c_w2) - rho
    g_s = d / c_a2**1.5 + t * n_g * n_g / c_g2**1.5 + big_h * n_w * n_w / c_w2**1.5
    return g, g_s


@dataclass(frozen=True, eq=False)
class PortPaths:
    """The refracted paths from the emitter to M points, port frame = light frame.

    Attributes:
        directions_light: (M, 3) u_a, the unit air direction leaving the emitter (NaN
            where not ok).
        cos_air: (M,) cos(theta_a) = u_a . n.
        ok: (M,) the point is in front of the port (h > d + t).
        water_m: (M,) the path's length in the water, from the exit point on the outer
            face, m.
        exits_light: (M, 3) the exit points E on the outer face, light frame, m.
    """

    directions_light: np.ndarray
    cos_air: np.ndarray
    ok: np.ndarray
    water_m: np.ndarray
    exits_light: np.ndarray
    _normal: np.ndarray
    _k: np.ndarray
    _rho_hat: np.ndarray
    _a: np.ndarray
    _sin_air: np.ndarray
    _water_grad: np.ndarray

    def pull_back(self, g_u: np.ndarray) -> np.ndarray:
        """(du_a/dY)^T g_u: a gradient (M, 3) with respect to u_a turned into one with
        respect to the point Y (M, 3) (0 where not ok)."""
        n = self._normal
        gu_n = g_u @ n
        gu_r = np.einsum("ij,ij->i", g_u, self._rho_hat)
        s_over_c = self._sin_air / self.cos_air
        out = self._k[:, None] * (g_u - gu_n[:, None] * n)
        out += (self._a - self._k[:, None] * self._rho_hat) * gu_r[:, None]
        out -= (s_over_c * gu_n)[:, None] * self._a
        out[~self.ok] = 0.0
        return out

    @property
    def water_grad(self) -> np.ndarray:
        """(M, 3) d water_m / dY (0 where not ok)."""
        return self._water_grad


def port_paths(points_light: np.ndarray, port: FlatPort) -> PortPaths:
    """The refracted paths from the emitter to points (M, 3) of the light frame, m."""
    Y = np.asarray(points_light, dtype=np.float64).reshape(-1, 3)
    n = np.asarray(port.normal_camera, dtype=np.float64)
    d, t = port.distance_m, port.thickness_m
    n_g, n_w = _indices(port)
    h = Y @ n
    radial = Y - h[:, None] * n
    rho = np.linalg.norm(radial, axis=1)
    s, ok = air_sines(rho, h, port)
    s0 = np.where(ok, s, 0.0)
    big_h = np.where(ok, h - d - t, 1.0)
    c_a = np.sqrt(1.0 - s0 * s0)
    c_w = np.sqrt(1.0 - (s0 / n_w) ** 2)
    tan_w = s0 / (n_w * c_w)
    _, g_s = _path_equation(s0, np.zeros_like(s0), big_h, d, t, n_g, n_w)
    with np.errstate(invalid="ignore", divide="ignore"):
        on_axis = rho == 0.0
        k = np.where(on_axis, 1.0 / g_s, s0 / np.where(on_axis, 1.0, rho))
        rho_hat = np.where(on_axis[:, None], 0.0, radial / np.where(on_axis, 1.0, rho)[:, None])
    u = k[:, None] * radial + c_a[:, None] * n
    a = (rho_hat - tan_w[:, None] * n) / g_s[:, None]
    water = big_h / c_w
    # d(H / c_w) = dH / c_w + H (s / n_w^2) / c_w^3 ds, dH = n . dY, ds = a . dY.
    water_grad = n[None, :] / c_w[:, None] + (big_h * s0 / (n_w * n_w * c_w**3))[:, None] * a
    tan_a = s0 / c_a
    tan_g = s0 / np.sqrt(n_g * n_g - s0 * s0)
    exits = (d * tan_a + t * tan_g)[:, None] * rho_hat + (d + t) * n
    for arr in (u, exits, water_grad):
        arr[~ok] = np.nan
    water = np.where(ok, water, np.nan)
    water_grad[~ok] = 0.0
    return PortPaths(
        u, np.where(ok, c_a, np.nan), ok, water, exits, n, k, rho_hat, a, s0, water_grad
    )


@numba.njit(cache=True)
def rid_many(directions: np.ndarray, rid: RIDData) -> tuple[np.ndarray, np.ndarray]:
    """RID values (M,) and tangential gradients (M, 3) at unit directions (M, 3) of the
    light frame (`rid_value_grad_direction`, row by row)."""
    m = directions.shape[0]
    f = np.empty(m)
    g = np.empty((m, 3))
    for i in range(m):
        f[i], g[i, 0], g[i, 1], g[i, 2] = rid_value_grad_direction(
            directions[i, 0], directions[i, 1], directions[i, 2], rid
        )
    return f, g


def spherical_triangle(
    a: np.ndarray, b: np.ndarray, c: np.ndarray, want_grad: bool
) -> tuple[np.ndarray, tuple[np.ndarray, np.ndarray, np.ndarray] | None]:
    """Signed solid angles (...,) of spherical triangles of unit vectors a, b, c (..., 3):
    tan(Omega / 2) = a . (b x c) / (1 + a . b + a . c + b . c), the triple product as
    a . ((b - a) x (c - a)) (no cancellation for small triangles); and, when want_grad,
    dOmega / da, db, dc (..., 3) (tangential parts are what matter: unit vectors)."""
    num = np.einsum("...i,...i->...", a, np.cross(b - a, c - a))
    ab = np.einsum("...i,...i->...", a, b)
    ac = np.einsum("...i,...i->...", a, c)
    bc = np.einsum("...i,...i->...", b, c)
    den = 1.0 + ab + ac + bc
    omega = 2.0 * np.arctan2(num, den)
    if not want_grad:
        return omega, None
    scale = (2.0 / (num * num + den * den))[..., None]
    nn = num[..., None]
    dd = den[..., None]
    da = scale * (dd * np.cross(b, c) - nn * (b + c))
    db = scale * (dd * np.cross(c, a) - nn * (a + c))
    dc = scale * (dd * np.cross(a, b) - nn * (a + b))
    return omega, (da, db, dc)


def _lattice(corners: np.ndarray, n_sub: int) -> tuple[np.ndarray, np.ndarray]:
    """The sub-quads' corners (M, K, n+1, n+1, 3) (index [t, s], bilinear in the quad's
    corners P1..P4 as `kernels.quad_flux` cuts it) and centroids (M, K, n, n, 3)."""
    st = np.arange(n_sub + 1) / n_sub
    s = st[None, :, None]
    t = st[:, None, None]
    q = corners[:, :, None, None]  # (M, K, 1, 1, 4, 3)
    lat = (
        ((1 - s) * (1 - t)) * q[..., 0, :]
        + (s * (1 - t)) * q[..., 1, :]
        + (s * t) * q[..., 2, :]
        + ((1 - s) * t) * q[..., 3, :]
    )
    cen = 0.25 * (lat[:, :, :-1, :-1] + lat[:, :, :-1, 1:] + lat[:, :, 1:, 1:] + lat[:, :, 1:, :-1])
    return lat, cen


def quads_flux(
    corners_world: np.ndarray,
    weights: np.ndarray,
    light_world: np.ndarray,
    R_world_light: np.ndarray,
    rid: RIDData,
    port: FlatPort,
    n_sub: int,
    want_grad: bool,
) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    """sum_k weight_k Phi_k / I0 of M pixels lit through the light's port.

    Args:
        corners_world: (M, K, 4, 3) finite footprint quads, world frame, m.
        weights: (M, K) their sensor weights.
        light_world: (3,) the emitter; R_world_light: (3, 3) the light's orientation.
        rid: its RID; port: its flat port (light frame); n_sub: sub-quads per side.
        want_grad: also the gradients.

    Returns:
        flux: (M,) 0 where a point is not in front of the port.
        lit: (M,) every point of the pixel is in front of the port.
        grad: (M, 6) d flux / d (L_world, delta_world), or None.
    """
    m, k = corners_world.shape[:2]
    lat_w, cen_w = _lattice(corners_world, n_sub)
    R = np.asarray(R_world_light, dtype=np.float64)
    lat = (lat_w - light_world) @ R  # R^T (X - L), row by row
    cen = (cen_w - light_world) @ R
    n_lat = (n_sub + 1) ** 2
    points = np.concatenate([lat.reshape(m, k * n_lat, 3), cen.reshape(m, -1, 3)], axis=1)
    paths = port_paths(points.reshape(-1, 3), port)
    lit = np.asarray(paths.ok.reshape(m, -1).all(axis=1), dtype=np.bool_)
    u_all = np.where(paths.ok[:, None], paths.directions_light, 0.0)
    u_all[~paths.ok, 2] = 1.0  # placeholders where unlit (their pixels are zeroed)
    u_all = u_all.reshape(m, -1, 3)
    u_lat = u_all[:, : k * n_lat].reshape(lat.shape)
    u_cen = u_all[:, k * n_lat :].reshape(cen.shape)
    p1, p2 = u_lat[:, :, :-1, :-1], u_lat[:, :, :-1, 1:]
    p3, p4 = u_lat[:, :, 1:, 1:], u_lat[:, :, 1:, :-1]
    o1, d1 = spherical_triangle(p1, p2, p3, want_grad)
    o2, d2 = spherical_triangle(p1, p3, p4, want_grad)
    signed = o1 + o2
    omega = np.abs(signed)
    f, df = rid_many(np.ascontiguousarray(u_cen.reshape(-1, 3)), rid)
    cos_c = np.clip(u_cen.reshape(-1, 3) @ port.normal_camera, 1e-300, 1.0)
    tf, dtf = port_transmittance(cos_c, port.air_index, port.glass_index, port.water_index)
    ft = (f * tf).reshape(omega.shape)
    w = weights[:, :, None, None]
    flux = np.where(lit, np.sum(w * omega * ft, axis=(1, 2, 3)), 0.0)
    if not want_grad:
        return flux, lit, None
    assert d1 is not None and d2 is not None
    c = (w * ft * np.sign(signed))[..., None]
    g_lat = np.zeros_like(u_lat)
    g_lat[:, :, :-1, :-1] += c * (d1[0] + d2[0])
    g_lat[:, :, :-1, 1:] += c * d1[1]
    g_lat[:, :, 1:, 1:] += c * (d1[2] + d2[1])
    g_lat[:, :, 1:, :-1] += c * d2[2]
    g_cen_u = (tf[:, None] * df + (f * dtf)[:, None] * port.normal_camera).reshape(cen.shape)
    g_cen = (w * omega)[..., None] * g_cen_u
    g_u = np.concatenate([g_lat.reshape(m, -1, 3), g_cen.reshape(m, -1, 3)], axis=1)
    g_y = paths.pull_back(g_u.reshape(-1, 3)).reshape(m, -1, 3)
    grad = np.empty((m, 6))
    grad[:, :3] = -np.sum(g_y, axis=1) @ R.T
    grad[:, 3:] = np.sum(np.cross(g_y, points), axis=1) @ R.T
    grad[~lit] = 0.0
    return flux, lit, grad


def attenuate_through_port(
    centers_world: np.ndarray,
    camera_world: np.ndarray,
    light_world: np.ndarray,
    R_world_light: np.ndarray,
    port: FlatPort,
    c_per_m: float,
    flux: np.ndarray,
    lit: np.ndarray,
    grad: np.ndarray | None,
) -> np.ndarray:
    """Multiply flux[lit] (M,) by T = exp(-c (|P - E| + |P - camera|)) in place, with the
    chain rule on grad[lit] (M, 6) (E the exit point of the centre's refracted ray from
    the port); returns d (flux T) / dc (L,) of the lit rows (L of them).

    Args:
        centers_world: (L, 3) the lit footprints' centres P; camera_world: (3,) or (L, 3)
            where the camera's side of the path starts, m.
    """
    R = np.asarray(R_world_light, dtype=np.float64)
    Y = (centers_world - light_world) @ R
    paths = port_paths(Y, port)
    camera_m = np.linalg.norm(centers_world - camera_world, axis=-1)
    length = paths.water_m + camera_m
    t = np.exp(-c_per_m * length)
    f = flux[lit]
    if grad is not None:
        g = grad[lit] * t[:, None]
        g_y = (-c_per_m * t * f)[:, None] * paths.water_grad
        g[:, :3] -= g_y @ R.T
        g[:, 3:] += np.cross(g_y, Y) @ R.T
        grad[lit] = g
    flux[lit] = f * t
    return -length * flux[lit]
