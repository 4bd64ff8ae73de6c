"""The energy-preserving renderer: pixel values of the wall lit by a rig of lights.

Two entry points over one model (docs/model.md, "Rendering one pixel"):

- `render_pixels` / `shade`: any set of (super-)pixels of any image. The solver builds
  the light-independent `Footprints` once and calls `shade` with new light poses; `shade`
  also returns the analytic gradients of every value with respect to each light's
  position and orientation (camera frame) and scale.
- `render_image`: whole images, optionally binned b x b into super-pixels.

Invalid pixels (a corner ray misses the wall) come back masked, never as zeros. A light
on or behind the wall (z <= 0 in the world frame of a view) illuminates nothing there:
its contribution is 0, as the physics says. On a wall mesh (`lightcal.core.wall_mesh`)
that is decided per pixel: a light behind the footprint's plane lights nothing there.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from functools import partial

import numpy as np

from lightcal.core.camera import Camera
from lightcal.core.corner_grid import corner_grid as corner_grid  # re-exported
from lightcal.core.footprint import (
    SENSOR_MODELS,
    Footprints,
    SensorModel,
    check_vignetting,
)
from lightcal.core.footprint import pixel_footprints as pixel_footprints  # re-exported
from lightcal.core.kernels.flux import flux_pixels, flux_pixels_grid
from lightcal.core.kernels.wall import apply_wall
from lightcal.core.light_port_dense import dense_applies, dense_port_flux
from lightcal.core.light_port_flux import port_light_flux
from lightcal.core.medium import AIR, Medium, apply_medium
from lightcal.core.render_fused import render_fused, render_in_medium
from lightcal.core.scene import Light, Rig, View
from lightcal.core.wall import LAMBERTIAN, WallReflectance
from lightcal.core.wall_mesh import (
    WallMesh,
    apply_wall_on_mesh,
    light_behind_mesh,
    mesh_footprints,
    wall_footprints,
)


def _check_subsamples(rid_subsamples: int) -> int:
    if not (isinstance(rid_subsamples, int | np.integer) and rid_subsamples >= 1):
        raise ValueError(f"rid_subsamples: expected an integer >= 1, got {rid_subsamples!r}")
    return int(rid_subsamples)


def _check_scatter_sensor(medium: Medium, sensor: str) -> None:
    """The backscatter is a radiance: rendered for the `radiance` sensor model only."""
    if medium.scatters and sensor != "radiance":
        raise ValueError(
            f"medium: backscatter_per_m: the backscatter is rendered for the radiance "
            f"sensor model; got {sensor!r}"
        )


@dataclass(frozen=True, eq=False)
class Shading:
    """Rendered values of N pixels and, optionally, their derivatives.

    Attributes:
        values: (N,) masked array of pixel values (masked where invalid).
        flux: (L, N) per light: gain * sum_k weight_k Phi_k / I0, i.e. d value / d scale.
        grad_position: (L, N, 3) d value / d t_camera_light, or None.
        grad_rotation: (L, N, 3) d value / d delta, delta a left rotation perturbation of
            R_camera_light in the camera frame (R -> exp(delta) R), or None.
        grad_wall: (N, P) d value / d (the wall model's parameters), or None.
        grad_medium: (N, 2) d value / d (the medium's attenuation and backscatter
            coefficients, 1/m) in a medium that scatters, (N, 1) d value / d c in one
            that does not, or None (without gradients, or in air).
    """

    values: np.ma.MaskedArray
    flux: np.ndarray
    grad_position: np.ndarray | None
    grad_rotation: np.ndarray | None
    grad_wall: np.ndarray | None = None
    grad_medium: np.ndarray | None = None


def light_in_view(light: Light, view: View) -> tuple[np.ndarray, np.ndarray]:
    """The light's world position (3,) and R_world_light (3, 3) for a view."""
    return light.position_world(view), light.rotation_world(view)


def light_flux(
    footprints: Footprints,
    view: View,
    light: Light,
    *,
    rid_subsamples: int = 1,
    want_grad: bool = False,
    grad_out: np.ndarray | None = None,
    wall: WallReflectance = LAMBERTIAN,
    wall_grad_out: np.ndarray | None = None,
    medium: Medium = AIR,
    medium_grad_out: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray | None]:
    """One light's flux into pixels per unit scale, and its world-frame gradients.

    A wall model other than Lambertian multiplies each pixel's flux by its relative
    reflectance B (`lightcal.core.wall`) at the footprint centre, a medium other than
    air by its transmittance T (`lightcal.core.medium`) there. A light behind a flat
    port (`light.port`) is lit through it (`lightcal.core.light_port_flux`; a
    Lambertian wall on the plane; its veil `lightcal.core.light_port_veil`).

    Args:
        footprints: from `pixel_footprints` for this view.
        view: the camera pose and exposure.
        light: the light (its scale is not applied).
        rid_subsamples: n, RID sub-sampling of each footprint quad (n x n).
        want_grad: also compute the gradients.
        grad_out: (N, 6) C-contiguous float64 array the gradients are written to (a
            reused buffer spares the page faults of a fresh one); default a new one.
        wall: the wall's reflectance model.
        wall_grad_out: (N, P) array receiving d flux / d (wall parameters) when want_grad
            (P the model's parameter count); ignored for a Lambertian wall.
        medium: the medium between the rig and the wall.
        medium_grad_out: with want_grad, (N, 1) receiving d flux / d c (the medium's
            attenuation coefficient), (N, 2) d flux / d (c, beta) (its backscatter) or
            (N, 3) d flux / d (c, beta, g) (its phase function); computed in air too.

    Returns:
        flux: (N,) exposure * sum_k weight_k Phi_k / I0; 0 where the footprint is invalid
            or the light is on or behind the wall.
        grad_world: (N, 6) d flux / d (L_world (3), delta_world (3)), delta_world a left
            rotation perturbation of R_world_light; None unless want_grad.
    """
    n_sub = _check_subsamples(rid_subsamples)
    n = len(footprints)
    flux = np.zeros(n)
    grad = None
    if want_grad:
        grad = np.empty((n, 6)) if grad_out is None else grad_out
        if grad.shape != (n, 6) or grad.dtype != np.float64 or not grad.flags.c_contiguous:
            raise ValueError(f"grad_out: expected a C-contiguous float64 ({n}, 6) array")
    if light.port is not None:
        in_front = light.position_world(view)[2] > 0.0  # else it lights nothing
        if in_front and wall.is_lambertian and dense_applies(footprints, medium, medium_grad_out):
            # A dense selection: the straight twin's flux times the port's ratio, exact
            # on a node grid (`lightcal.core.light_port_dense`).
            def exact(
                fp: Footprints, lit: Light, g: np.ndarray | None, g_c: np.ndarray | None
            ) -> tuple[np.ndarray, np.ndarray | None]:
                return light_flux(
                    fp, view, lit, rid_subsamples=n_sub, want_grad=g is not None,
                    grad_out=g, medium=medium, medium_grad_out=g_c,
                )  # fmt: skip

            return dense_port_flux(
                footprints, view, light, exact, want_grad=want_grad, grad_out=grad,
                medium=medium, medium_grad_out=medium_grad_out,
            )  # fmt: skip
        return port_light_flux(
            footprints, view, light, rid_subsamples=n_sub, want_grad=want_grad,
            grad_out=grad, wall=wall, medium=medium, medium_grad_out=medium_grad_out,
        )  # fmt: skip
    L_world, R_world_light = light_in_view(light, view)
    # Footprints through the camera's port carry normals (+z, for a glossy wall's B from
    # their exit points) but lie on the plane z = 0 like the others. There a light on or
    # behind the wall lights nothing: not the wall, nor the water in front of it.
    on_mesh = footprints.normals_world is not None and footprints.port_exits_world is None
    if not on_mesh and L_world[2] <= 0.0:
        if grad is not None:
            grad.fill(0.0)
        if wall_grad_out is not None:
            wall_grad_out.fill(0.0)
        if medium_grad_out is not None:
            medium_grad_out.fill(0.0)
        return flux, grad
    outputs = (flux, grad if grad is not None else np.zeros((1, 6)))
    light_args = (L_world, np.ascontiguousarray(R_world_light), light.rid.data(), n_sub, want_grad)
    source = footprints.grid
    if source is None:
        flux_pixels(
            footprints.corners_world, footprints.weights, footprints.valid, *light_args, *outputs
        )
    else:
        grid = (source.grid_xy, source.grid_ok, source.R_camera_world, source.center_world)
        flux_pixels_grid(
            footprints.pixels,
            source.binning,
            grid,
            footprints.weights,
            footprints.valid,
            *light_args,
            *outputs,
        )
    flux *= view.exposure
    if grad is not None:
        grad *= view.exposure
    if on_mesh:
        light_behind_mesh(footprints, L_world, flux, grad)
    if not wall.is_lambertian:
        _apply_wall(footprints, view, L_world, wall, flux, grad, wall_grad_out)
    if not medium.is_clear or (grad is not None and medium_grad_out is not None):
        # In air (T = 1 exactly: the values unchanged) only for the derivatives.
        apply_medium(
            footprints.centers_world,
            L_world,
            R_world_light,
            light.rid.data(),
            footprints.camera_side(view.center_world),
            medium,
            flux,
            grad,
            exposure=view.exposure,
            extra_grads=None if wall.is_lambertian else wall_grad_out,
            d_medium_out=medium_grad_out if grad is not None else None,
            veil_factor=footprints.port_transmittance,
        )
    return flux, grad


def _apply_wall(
    footprints: Footprints,
    view: View,
    L_world: np.ndarray,
    wall: WallReflectance,
    flux: np.ndarray,
    grad: np.ndarray | None,
    wall_grad_out: np.ndarray | None,
) -> None:
    """Multiply flux (N,) by the wall's B at the footprint centres; chain the gradients.

    d(flux B)/dL = B d flux/dL + flux dB/dL; d(flux B)/d delta = B d flux/d delta;
    d(flux B)/d p = flux dB/dp (written to wall_grad_out (N, P)).
    """
    if footprints.normals_world is not None:  # each footprint's own normal (or a port's)
        camera = footprints.camera_side(view.center_world)
        apply_wall_on_mesh(footprints, L_world, camera, wall, flux, grad, wall_grad_out)
        return
    d = wall.data()
    want_grad = grad is not None
    apply_wall(
        footprints.centers_world,
        L_world,
        np.ascontiguousarray(view.center_world),
        d.kind,
        d.params,
        d.tables,
        flux,
        grad if grad is not None else _NO_GRAD,
        want_grad=want_grad,
        out_d_params=wall_grad_out if want_grad and wall_grad_out is not None else _NO_PARAMS,
    )


_NO_GRAD, _NO_PARAMS = np.zeros((1, 6)), np.zeros((1, 0))  # apply_wall's unused outputs


def shade(
    footprints: Footprints,
    view: View,
    rig: Rig,
    *,
    offset: float = 0.0,
    rid_subsamples: int = 1,
    want_grad: bool = False,
    wall: WallReflectance = LAMBERTIAN,
    medium: Medium = AIR,
) -> Shading:
    """Render pixel values from precomputed footprints.

    Args:
        footprints: from `pixel_footprints` for this view.
        view: the camera pose and exposure.
        rig: the lights.
        offset: black level / ambient offset b added to every value.
        rid_subsamples: n, RID sub-sampling of each footprint quad (n x n).
        want_grad: also compute the gradients (see `Shading`).
        wall: the wall's reflectance model.
        medium: the medium between the rig and the wall.

    Returns:
        The shading.
    """
    n = len(footprints)
    n_l = len(rig.lights)
    n_p = len(wall.parameter_names)
    flux = np.zeros((n_l, n))
    gpos = np.zeros((n_l, n, 3)) if want_grad else None
    grot = np.zeros((n_l, n, 3)) if want_grad else None
    gwall = np.zeros((n, n_p)) if want_grad else None
    wall_grad = np.zeros((n, n_p)) if want_grad and not wall.is_lambertian else None
    # d/dbeta and d/dg only where it scatters (at beta = 0 they cost the integral).
    gmedium = None
    if want_grad and not medium.is_clear:
        gmedium = np.zeros((n, 3 if medium.scatters else 1))
    medium_grad = np.zeros_like(gmedium) if gmedium is not None else None
    R = view.R_camera_world
    for i, light in enumerate(rig.lights):
        flux[i], grad = light_flux(
            footprints,
            view,
            light,
            rid_subsamples=rid_subsamples,
            want_grad=want_grad,
            wall=wall,
            wall_grad_out=wall_grad,
            medium=medium,
            medium_grad_out=medium_grad,
        )
        if grad is not None:
            assert gpos is not None and grot is not None
            # L_world = C + R^T t  =>  d/dt = R d/dL_world;  delta_world = R^T delta_camera.
            gpos[i] = grad[:, :3] @ (light.scale * R.T)
            grot[i] = grad[:, 3:] @ (light.scale * R.T)
        if wall_grad is not None and gwall is not None:
            gwall += light.scale * wall_grad
        if medium_grad is not None and gmedium is not None:
            gmedium += light.scale * medium_grad
    scales = np.array([light.scale for light in rig.lights])
    total = offset + scales @ flux
    values = np.ma.masked_array(np.where(footprints.valid, total, np.nan), mask=~footprints.valid)
    return Shading(values, flux, gpos, grot, gwall, gmedium)


def render_pixels(
    camera: Camera,
    view: View,
    rig: Rig,
    pixels: np.ndarray,
    *,
    sensor: SensorModel = "radiance",
    vignetting: np.ndarray | None = None,
    binning: int = 1,
    offset: float = 0.0,
    rid_subsamples: int = 1,
    wall: WallReflectance = LAMBERTIAN,
    medium: Medium = AIR,
    mesh: WallMesh | None = None,
) -> np.ma.MaskedArray:
    """Render (super-)pixels of one view.

    Args:
        camera: intrinsics of the full-resolution image.
        view: camera pose and exposure.
        rig: the lights.
        pixels: (N, 2) integer (u, v) indices in the image binned by `binning`.
        sensor: sensor fall-off model ("radiance", "cos4", "paper", "map").
        vignetting: (H, W) fall-off map for "map".
        binning: super-pixel side b.
        offset: black level / ambient offset.
        rid_subsamples: RID sub-sampling n per footprint (n x n).
        wall: the wall's reflectance model.
        medium: the medium between the rig and the wall.
        mesh: the wall's shape as a mesh (`lightcal.core.wall_mesh`); None: z = 0.

    Returns:
        (N,) masked array of values, masked where the footprint is invalid.
    """
    _check_scatter_sensor(medium, sensor)
    fp = wall_footprints(
        camera, view, pixels, mesh=mesh, sensor=sensor, vignetting=vignetting, binning=binning
    )
    return shade(
        fp, view, rig, offset=offset, rid_subsamples=rid_subsamples, wall=wall, medium=medium
    ).values


def render_image(
    camera: Camera,
    view: View,
    rig: Rig,
    *,
    sensor: SensorModel = "radiance",
    vignetting: np.ndarray | None = None,
    binning: int = 1,
    offset: float = 0.0,
    rid_subsamples: int = 1,
    wall: WallReflectance = LAMBERTIAN,
    medium: Medium = AIR,
    mesh: WallMesh | None = None,
) -> np.ma.MaskedArray:
    """Render a whole image, optionally binned.

    Args: as `render_pixels`, without `pixels`. On a `mesh` every pixel's footprint is
        built on it (`mesh_footprints`, exact flux) and shaded as `render_pixels` does:
        the fused whole-image kernel knows the plane z = 0 only.

    Returns:
        (H // b, W // b) masked array, masked where the footprint is invalid.
    """
    if not (isinstance(binning, int | np.integer) and binning >= 1):
        raise ValueError(f"binning: expected an integer >= 1, got {binning!r}")
    if mesh is not None or any(light.port is not None for light in rig.lights):
        # On a mesh, or with a light behind its port: every pixel's footprint, shaded.
        hb, wb = camera.height // binning, camera.width // binning
        v, u = np.mgrid[0:hb, 0:wb]
        every = np.stack([u.ravel(), v.ravel()], axis=1)
        fp = (pixel_footprints if mesh is None else partial(mesh_footprints, mesh=mesh))(
            camera, view, every, sensor=sensor, vignetting=vignetting, binning=int(binning),
            max_quads_per_side=None,
        )  # fmt: skip
        fp = replace(fp, image_shape=(hb, wb))  # a ported light's veil on a node grid
        _check_scatter_sensor(medium, sensor)
        on_mesh = shade(fp, view, rig, offset=offset, rid_subsamples=rid_subsamples,
                        wall=wall, medium=medium).values  # fmt: skip
        return on_mesh.reshape(hb, wb)
    if sensor not in SENSOR_MODELS:
        raise ValueError(f"sensor: expected one of {', '.join(SENSOR_MODELS)}, got {sensor!r}")
    n_sub = _check_subsamples(rid_subsamples)
    _check_scatter_sensor(medium, sensor)
    b = int(binning)
    vmap = check_vignetting(vignetting, camera) if sensor == "map" else np.ones((1, 1))
    # Lights on or behind the wall illuminate nothing in this view.
    lit = [
        (light, *light_in_view(light, view))
        for light in rig.lights
        if light.position_world(view)[2] > 0.0
    ]
    if medium.is_clear or not lit:
        out, invalid = render_fused(camera, view, lit, sensor, vmap, b, n_sub, offset, wall)
    else:
        out, invalid = render_in_medium(
            camera, view, lit, sensor, vmap, b, n_sub, offset, wall, medium
        )
    return np.ma.masked_array(out, mask=invalid, copy=False)
