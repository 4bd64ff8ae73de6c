"""The flux of pixel footprints lit through the light's flat port, with gradients.

`lightcal.core.render.light_flux` calls `port_light_flux` for a light with a port
(`Light.port`; docs/model.md, "The light's flat port"). As the in-air kernel
(`lightcal.core.kernels.quad_flux`), each footprint quad k of a pixel is cut into n x n
sub-quads (`rid_subsamples`, bilinear in the quad's corners), and the pixel's flux is

    sum_k weight_k sum_j Omega_j f(u_j) T_F(u_j . n)

with, for the light behind its port, Omega_j the solid angle *in the air* of the
spherical quad whose vertices are the sub-quad corners' air directions (the flux that
leaves the emitter into that solid angle lands on exactly that sub-quad: energy
preserving), u_j the air direction of the sub-quad's centroid (the mean of its corners),
f the RID (given in air) and T_F the port's Fresnel transmittance
(`lightcal.core.fresnel.port_transmittance`). The air directions come from
`lightcal.core.light_port.port_paths`. With the port's indices all 1 the air direction
is the straight one and the numbers are the in-air kernel's (to round-off).

Everything depends on the light's pose only through the light-frame points
Y = R_world_light^T (X - L_world), so the gradients are d flux / dY of every lattice point
and centroid (the spherical triangles' Van Oosterom-Strackee formula differentiated in
its unit vectors, the RID's and T_F's derivatives, pulled back through du_a/dY by
`PortPaths.pull_back`), then dY/dL = -R^T and, for a left perturbation R -> exp(delta) R,
dY/d delta = R^T [X - L]_x: d/dL = -R sum gY, d/d delta = R sum gY x Y.

In water the light's path starts at the exit point E of the footprint centre's ray from
the port's outer face: T = exp(-c (|P - E| + the camera's side)), |P - E| = H / cos
theta_w (`PortPaths.water_m`), with its derivatives in the pose and in c.

Not here (refused by `port_light_flux` and, naming the key, by the project file): a wall
mesh, a non-Lambertian wall, the medium's backscatter.
"""

from __future__ import annotations

import numba
import numpy as np

from lightcal.core.flat_port import FlatPort
from lightcal.core.footprint import Footprints
from lightcal.core.fresnel import port_transmittance
from lightcal.core.light_port import port_paths
from lightcal.core.medium import Medium
from lightcal.core.rid_eval import RIDData, rid_value_grad_direction
from lightcal.core.scene import Light, View
from lightcal.core.wall import WallReflectance


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


def port_light_flux(
    footprints: Footprints,
    view: View,
    light: Light,
    *,
    rid_subsamples: int,
    want_grad: bool,
    grad_out: np.ndarray | None,
    wall: WallReflectance,
    medium: Medium,
    medium_grad_out: np.ndarray | None,
) -> tuple[np.ndarray, np.ndarray | None]:
    """`lightcal.core.render.light_flux` for a light behind its flat port (`light.port`):
    the same arguments (checked there) and outputs."""
    port = light.port
    assert port is not None
    if footprints.normals_world is not None and footprints.port_exits_world is None:
        raise ValueError("light port: a wall mesh is not modelled behind a light's port")
    if not wall.is_lambertian:
        raise ValueError(
            "light port: only a Lambertian wall is modelled behind a light's port (the "
            "wall's B would need the water direction at the wall)"
        )
    if medium.scatters or (medium_grad_out is not None and medium_grad_out.shape[1] > 1):
        raise ValueError(
            "light port: the medium's backscatter is not modelled behind a light's port "
            "(the veil's beam is traced straight from the emitter)"
        )
    n = len(footprints)
    flux = np.zeros(n)
    grad = None
    if want_grad:
        grad = np.zeros((n, 6)) if grad_out is None else grad_out
        grad.fill(0.0)
    if medium_grad_out is not None:
        medium_grad_out.fill(0.0)
    L_world = light.position_world(view)
    R_world_light = light.rotation_world(view)
    if L_world[2] <= 0.0:
        return flux, grad
    corners = footprints.corners_world
    rows = np.flatnonzero(footprints.valid & np.isfinite(corners).reshape(n, -1).all(axis=1))
    f_rows, lit, g_rows = quads_flux(
        corners[rows], footprints.weights[rows], L_world, R_world_light,
        light.rid.data(), port, int(rid_subsamples), want_grad,
    )  # fmt: skip
    f_rows *= view.exposure
    if g_rows is not None:
        g_rows *= view.exposure
    want_c = want_grad and medium_grad_out is not None
    if not medium.is_clear or want_c:
        lit_rows = rows[lit]
        centers = footprints.centers_now()[lit_rows]
        camera = footprints.camera_side(view.center_world)
        camera = camera[lit_rows] if np.ndim(camera) == 2 else camera
        d_c = attenuate_through_port(
            centers, camera, L_world, R_world_light, port, medium.attenuation_per_m,
            f_rows, lit, g_rows,
        )  # fmt: skip
        if want_c and medium_grad_out is not None:
            medium_grad_out[lit_rows, 0] = d_c
    flux[rows] = f_rows
    if grad is not None and g_rows is not None:
        grad[rows] = g_rows
    return flux, grad


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
