"""The veil (single-scattering backscatter) of a light behind its flat port.

Each light adds exposure x beta x S to a pixel (docs/model.md, "Medium"), S the
single-scattering integral of its beam along the pixel's ray in the water. Behind the
light's port the beam at a point X in the water is the refracted one: its irradiance
normal to the beam is I0 f(u_air) T_F(theta_a) (dOmega_air / dA_perp)(X) exp(-c s_w(X)),
u_air the solved air direction to X (`lightcal.core.light_port`), T_F the port's Fresnel
transmittance, dOmega_air / dA_perp the refracted bundle's Jacobian and s_w the beam's
path in the water from the port's outer face; it scatters towards the camera by the
phase function of the angle between its water direction at X and the ray; only the part
of the ray in front of the outer face is lit. `lightcal.core.kernels.port_veil` holds
the formulas and computes S per ray with its gradients in the light's pose, c and g
(d/dbeta is S itself).

`add_port_veil` adds it to the flux of a light behind its port (`light_port_flux.
port_light_flux`): per pixel with gradients (the solver), or, for a whole image without
gradients, exactly on the nodes of `medium.scatter_grid` and interpolated bilinearly
between them (as the in-air veil of `render_image`), exactly beside an invalid node.
Behind the camera's flat port each ray starts where it leaves that port and the veil is
carried into the camera by its Fresnel transmittance (`veil_factor`), as in air.
"""

from __future__ import annotations

import numpy as np

from lightcal.core.flat_port import FlatPort
from lightcal.core.kernels.port_veil import port_scatter_points
from lightcal.core.light_port import port_geometry
from lightcal.core.medium import Medium, scatter_grid, scatter_nodes
from lightcal.core.rid_eval import RIDData, rid_tuple
from lightcal.core.scene import Light, View

__all__ = ["add_port_veil", "port_backscatter", "port_scatter"]


def port_scatter(
    points_world: np.ndarray,
    camera_world: np.ndarray,
    light_world: np.ndarray,
    R_world_light: np.ndarray,
    rid: RIDData,
    port: FlatPort,
    medium: Medium,
    want_grad: bool,
) -> tuple[np.ndarray, np.ndarray | None]:
    """S of the rays to wall points (N, 3) from `camera_world` ((3,) one start for all,
    or (N, 3) one per ray), world frame, m, for the light at light_world (3,) with
    orientation R_world_light (3, 3), RID `rid` and port `port` (light frame).

    Returns:
        S: (N,) 0 where a point is not finite or the ray is nowhere in front of the port.
        grad: (N, 8) dS / d (L_world, delta_world, c, g) (delta_world a left rotation
            perturbation), or None unless want_grad.
    """
    nodes, weights = scatter_nodes()
    s, grad = port_scatter_points(
        points_world, camera_world, light_world, R_world_light, rid_tuple(rid),
        port.normal_camera, port_geometry(port), medium.attenuation_per_m, medium.phase_g,
        nodes, weights, want_grad,
    )  # fmt: skip
    return s, grad if want_grad else None


def port_backscatter(
    points_world: np.ndarray,
    camera_world: np.ndarray,
    light: Light,
    view: View,
    medium: Medium,
) -> np.ndarray:
    """(N,) S of `light` (behind its port, `light.port`) along the rays from
    `camera_world` ((3,) or (N, 3)) to wall points (N, 3): `medium.backscatter` of a
    ported light; a pixel's veil is scale x exposure x beta x S."""
    assert light.port is not None
    s, _ = port_scatter(
        points_world, camera_world, light.position_world(view), light.rotation_world(view),
        light.rid.data(), light.port, medium, want_grad=False,
    )  # fmt: skip
    return s


def _on_grid(
    shape: tuple[int, int],
    centers_world: np.ndarray,
    camera_world: np.ndarray,
    ok: np.ndarray,
    exact: tuple[np.ndarray, np.ndarray, RIDData, FlatPort, Medium],
) -> np.ndarray:
    """(hb * wb,) S of a whole image's rays (row-major centres (hb * wb, 3), `ok` where
    finite): exact at `scatter_grid`'s nodes, bilinear between them, exact where a
    neighbouring node is not ok; 0 where not ok. `exact` = the arguments of
    `port_scatter` after the points and starts."""
    hb, wb = shape
    rows, cols = scatter_grid(shape)
    node = (rows[:, None] * wb + cols[None, :]).ravel()
    node = node[ok[node]]

    def at(index: np.ndarray) -> np.ndarray:
        start = camera_world if np.ndim(camera_world) == 1 else camera_world[index]
        return port_scatter(centers_world[index], start, *exact, want_grad=False)[0]

    at_nodes = np.full(hb * wb, np.nan)
    at_nodes[node] = at(node)
    grid = at_nodes[(rows[:, None] * wb + cols[None, :])]

    def bracket(nodes: np.ndarray, size: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        k = np.clip(np.searchsorted(nodes, np.arange(size), side="right") - 1, 0, None)
        k = np.minimum(k, max(len(nodes) - 2, 0))
        k1 = np.minimum(k + 1, len(nodes) - 1)
        span = np.maximum(nodes[k1] - nodes[k], 1)
        return k, k1, np.where(k1 > k, (np.arange(size) - nodes[k]) / span, 0.0)

    i0, i1, fy = bracket(rows, hb)
    j0, j1, fx = bracket(cols, wb)
    fy, fx = fy[:, None], fx[None, :]
    top = (1.0 - fx) * grid[i0][:, j0] + fx * grid[i0][:, j1]
    bottom = (1.0 - fx) * grid[i1][:, j0] + fx * grid[i1][:, j1]
    out = ((1.0 - fy) * top + fy * bottom).ravel()
    redo = np.flatnonzero(ok & ~np.isfinite(out))
    out[redo] = at(redo)
    out[~ok] = 0.0
    return out


def add_port_veil(
    centers_world: np.ndarray,
    camera_world: np.ndarray,
    light_world: np.ndarray,
    R_world_light: np.ndarray,
    light: Light,
    medium: Medium,
    *,
    exposure: float,
    flux: np.ndarray,
    grad: np.ndarray | None,
    medium_grad_out: np.ndarray | None,
    veil_factor: np.ndarray | None,
    image_shape: tuple[int, int] | None = None,
) -> None:
    """Add a ported light's veil exposure x beta x S to its flux (N,) in place, with its
    gradients (module docstring).

    Args:
        centers_world: (N, 3) footprint centres (NaN where invalid: no veil), m.
        camera_world: (3,) the camera centre, or (N, 3) where each pixel's ray leaves
            the camera's flat port (`Footprints.camera_side`).
        light_world, R_world_light: the light's pose in the view; light: the light
            (its RID and `port`).
        medium: the medium (beta, c, g).
        exposure: the view's exposure.
        flux: (N,) the light's flux, exposure included.
        grad: (N, 6) d flux / d (L_world, delta_world), or None.
        medium_grad_out: with grad, (N, 1) d/dc, (N, 2) d/d(c, beta) or (N, 3)
            d/d(c, beta, g), added to (d/dc) and written (d/dbeta, d/dg); or None.
        veil_factor: (N,) the camera's port's Fresnel transmittance of each pixel's
            rays (`Footprints.port_transmittance`), or None (1).
        image_shape: (hb, wb) when the N pixels are a whole image in row-major order
            (`Footprints.image_shape`): without grad, S on `scatter_grid`'s nodes only.
    """
    assert light.port is not None
    ok = np.isfinite(centers_world).all(axis=1)
    two_d = np.ndim(camera_world) == 2
    if two_d:
        ok &= np.isfinite(camera_world).all(axis=1)
    exact = (light_world, R_world_light, light.rid.data(), light.port, medium)
    if grad is None and image_shape is not None:
        s = _on_grid(image_shape, centers_world, camera_world, ok, exact)
        if veil_factor is not None:
            s = s * np.where(ok, veil_factor, 0.0)
        flux += exposure * medium.backscatter_per_m * s
        return
    rows = np.flatnonzero(ok)
    start = camera_world[rows] if two_d else camera_world
    s, ds = port_scatter(centers_world[rows], start, *exact, want_grad=grad is not None)
    if veil_factor is not None:
        s *= veil_factor[rows]
        if ds is not None:
            ds *= veil_factor[rows, None]
    k = exposure * medium.backscatter_per_m
    flux[rows] += k * s
    if grad is None or ds is None:
        return
    grad[rows] += k * ds[:, :6]
    if medium_grad_out is not None:
        medium_grad_out[rows, 0] += k * ds[:, 6]
        if medium_grad_out.shape[1] > 1:
            medium_grad_out[rows, 1] = exposure * s
        if medium_grad_out.shape[1] > 2:
            medium_grad_out[rows, 2] = k * ds[:, 7]
