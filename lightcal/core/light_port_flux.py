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

`quads_flux` runs it compiled, pixel by pixel (`lightcal.core.kernels.port_flux`, the
same formulas in the same order; tests/light_port_numpy.py keeps the NumPy code it
replaced, which the tests hold it to).

The medium's backscatter, the beam scattered towards the camera along each pixel's ray
in the water, is added by `lightcal.core.light_port_veil.add_port_veil` (per pixel with
its gradients; a whole image on `medium.scatter_grid`'s nodes).

Not here (refused by `port_light_flux` and, naming the key, by the project file): a wall
mesh, a non-Lambertian wall.
"""

from __future__ import annotations

import numpy as np

from lightcal.core.flat_port import FlatPort
from lightcal.core.footprint import Footprints
from lightcal.core.kernels.port_flux import port_flux_pixels
from lightcal.core.kernels.port_water import attenuate_rows
from lightcal.core.light_port import port_geometry
from lightcal.core.light_port_veil import add_port_veil
from lightcal.core.medium import Medium
from lightcal.core.rid_eval import RIDData, rid_tuple
from lightcal.core.scene import Light, View
from lightcal.core.wall import WallReflectance


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
    geometry = port_geometry(port)
    flux, lit, grad = port_flux_pixels(
        corners_world, weights, light_world, R_world_light, rid_tuple(rid),
        port.normal_camera, geometry, n_sub, want_grad,
    )  # fmt: skip
    return flux, lit, grad if want_grad else None


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
    corners, weights = footprints.corners_world, footprints.weights
    # A pixel with a non-finite corner comes out unlit (`solve_paths` refuses the point):
    # only the invalid ones are left out, and no copy is made when every pixel is valid.
    rows = np.flatnonzero(footprints.valid)
    if len(rows) < n:
        corners, weights = corners[rows], weights[rows]
    f_rows, lit, g_rows = quads_flux(
        corners, weights, L_world, R_world_light, light.rid.data(), port,
        int(rid_subsamples), want_grad,
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
    if medium.scatters or (want_c and medium_grad_out is not None and medium_grad_out.shape[1] > 1):
        add_port_veil(
            footprints.centers_now(), footprints.camera_side(view.center_world), L_world,
            R_world_light, light, medium, exposure=view.exposure, flux=flux, grad=grad,
            medium_grad_out=medium_grad_out if want_c else None,
            veil_factor=footprints.port_transmittance,
            image_shape=None if want_grad else footprints.image_shape,
        )  # fmt: skip
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
    the port); returns d (flux T) / dc (L,) of the lit rows (L of them). Compiled:
    `lightcal.core.kernels.port_water.attenuate_rows`.

    Args:
        centers_world: (L, 3) the lit footprints' centres P; camera_world: (3,) or (L, 3)
            where the camera's side of the path starts, m.
    """
    return attenuate_rows(
        np.flatnonzero(lit), centers_world, camera_world, light_world, R_world_light,
        port.normal_camera, port_geometry(port), c_per_m, flux, grad,
    )  # fmt: skip
