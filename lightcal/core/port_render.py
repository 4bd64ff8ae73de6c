"""Rendering through the camera's flat port (docs/model.md, "The camera's flat port").

`render_pixels` and `render_image` with a `FlatPort`. Any pixels: their footprints
through the port (`lightcal.core.port_footprints`) shaded as `lightcal.core.render.shade`
shades any footprints (each pixel's camera-side path in the medium from its exit point
from the port). The whole image: the fused kernel (`kernels.port_image`) on the
camera's port lattice (traced once per camera and port, cached, moved to each view),
whose corners four pixels share, the veil exact on `medium.scatter_grid`'s nodes and
interpolated between them as in air; a rig with a light behind its own port
(`lights[i].port`) takes every pixel's footprint, shaded
(`render_image_per_pixel_through_port`, also the fused kernel's reference in the tests).
"""

from __future__ import annotations

from typing import Any

import numba
import numpy as np

from lightcal.core.camera import Camera
from lightcal.core.flat_port import FlatPort
from lightcal.core.footprint import (
    SENSOR_CODES,
    SENSOR_MODELS,
    SensorModel,
    check_vignetting,
    room_light_image,
)
from lightcal.core.kernels.port_image import port_veil_nodes, render_image_port_fused
from lightcal.core.light_port_frame import render_frame_with_ported_lights
from lightcal.core.medium import AIR, Medium, scatter_grid, scatter_nodes
from lightcal.core.port_footprints import (
    camera_port_rays,
    image_footprints_through_port,
    port_footprints,
    port_transmittance_image,
)
from lightcal.core.render import render_image, shade
from lightcal.core.rid_stack import stack_rid_data
from lightcal.core.scene import Rig, View
from lightcal.core.wall import LAMBERTIAN, WallReflectance
from lightcal.core.wall_mesh import WallMesh


def render_pixels_through_port(
    camera: Camera,
    view: View,
    rig: Rig,
    pixels: np.ndarray,
    port: FlatPort,
    *,
    sensor: SensorModel = "radiance",
    vignetting: np.ndarray | None = None,
    binning: int = 1,
    offset: float = 0.0,
    rid_subsamples: int = 1,
    wall: WallReflectance = LAMBERTIAN,
    medium: Medium = AIR,
) -> np.ma.MaskedArray:
    """`lightcal.core.render.render_pixels` through the camera's flat `port` (on the
    plane z = 0). Returns (N,) values, masked where invalid."""
    fp = port_footprints(
        camera, view, pixels, port, sensor=sensor, vignetting=vignetting, binning=binning
    )
    return shade(
        fp, view, rig, offset=offset, rid_subsamples=rid_subsamples, wall=wall, medium=medium
    ).values


def render_image_through_port(
    camera: Camera,
    view: View,
    rig: Rig,
    port: FlatPort,
    *,
    sensor: SensorModel = "radiance",
    vignetting: np.ndarray | None = None,
    binning: int = 1,
    offset: float = 0.0,
    rid_subsamples: int = 1,
    wall: WallReflectance = LAMBERTIAN,
    medium: Medium = AIR,
) -> np.ma.MaskedArray:
    """`lightcal.core.render.render_image` through the camera's flat `port`: every
    (super-)pixel's exact footprint, by the fused kernel (`kernels.port_image`) or, for a
    rig with a light behind its own port, shaded footprints
    (`render_image_per_pixel_through_port`): the same numbers to round-off. Returns
    (H // b, W // b), masked where invalid."""
    if sensor == "paper" or any(light.port is not None for light in rig.lights):
        return render_image_per_pixel_through_port(
            camera, view, rig, port, sensor=sensor, vignetting=vignetting, binning=binning,
            offset=offset, rid_subsamples=rid_subsamples, wall=wall, medium=medium,
        )  # fmt: skip
    b = _checked_binning(binning)
    if not (isinstance(rid_subsamples, int | np.integer) and rid_subsamples >= 1):
        raise ValueError(f"rid_subsamples: expected an integer >= 1, got {rid_subsamples!r}")
    if sensor not in SENSOR_MODELS:
        raise ValueError(f"sensor: expected one of {', '.join(SENSOR_MODELS)}, got {sensor!r}")
    vmap = check_vignetting(vignetting, camera) if sensor == "map" else np.ones((1, 1))
    lights = rig.lights
    wd = wall.data()
    out = np.empty((camera.height // b, camera.width // b))
    invalid = np.empty(out.shape, dtype=np.bool_)
    rays = camera_port_rays(camera, port)  # exits, directions, coordinates, ok, Fresnel
    pose = (np.ascontiguousarray(view.R_camera_world), np.ascontiguousarray(view.center_world))
    lit = (
        np.array([light.position_world(view) for light in lights]),
        np.array([light.rotation_world(view) for light in lights]),
    )
    rids = stack_rid_data([light.rid.data() for light in lights])
    node_rows, node_cols = scatter_grid(out.shape)
    veil = np.empty((len(lights), len(node_rows), len(node_cols)) if medium.scatters else (0, 1, 1))
    # Dynamic scheduling of the row chunks: the machine's cores may be shared.
    with numba.parallel_chunksize(1):
        if medium.scatters:  # the veil on the nodes, interpolated between them below
            port_veil_nodes(
                rays[0], rays[1], rays[3], *pose, b, node_rows, node_cols, *lit, rids,
                medium.attenuation_per_m, medium.phase_g, *scatter_nodes(), veil,
            )  # fmt: skip
        render_image_port_fused(
            *rays, *pose, SENSOR_CODES[sensor], vmap, b, *lit,
            np.array([light.scale for light in lights], dtype=np.float64),
            rids, int(rid_subsamples), float(view.exposure), float(offset),
            wd.kind, wd.params, wd.tables,
            np.array([medium.attenuation_per_m, medium.backscatter_per_m, medium.phase_g]),
            *scatter_nodes(), node_rows, node_cols, veil, out, invalid,
        )  # fmt: skip
    return np.ma.masked_array(out, mask=invalid, copy=False)


def _checked_binning(binning: int) -> int:
    if not (isinstance(binning, int | np.integer) and binning >= 1):
        raise ValueError(f"binning: expected an integer >= 1, got {binning!r}")
    return int(binning)


def render_image_per_pixel_through_port(
    camera: Camera,
    view: View,
    rig: Rig,
    port: FlatPort,
    *,
    sensor: SensorModel = "radiance",
    vignetting: np.ndarray | None = None,
    binning: int = 1,
    offset: float = 0.0,
    rid_subsamples: int = 1,
    wall: WallReflectance = LAMBERTIAN,
    medium: Medium = AIR,
) -> np.ma.MaskedArray:
    """`render_image_through_port` by every (super-)pixel's footprint
    (`image_footprints_through_port`) shaded by `lightcal.core.render.shade`: what a rig
    with a light behind its own port takes. Returns (H // b, W // b), masked where
    invalid."""
    b = _checked_binning(binning)
    fp = image_footprints_through_port(
        camera, view, port, sensor=sensor, vignetting=vignetting, binning=b
    )
    values = shade(
        fp, view, rig, offset=offset, rid_subsamples=rid_subsamples, wall=wall, medium=medium
    ).values
    return values.reshape(camera.height // b, camera.width // b)


def render_view_image(
    camera: Camera,
    view: View,
    rig: Rig,
    *,
    port: FlatPort | None = None,
    mesh: WallMesh | None = None,
    **options: Any,
) -> np.ma.MaskedArray:
    """The whole image of a view as the model renders it: through the camera's flat
    `port` (`render_image_through_port`), else on the wall `mesh` or the plane z = 0
    (`lightcal.core.render.render_image`); `options` are theirs (sensor, vignetting,
    offset, rid_subsamples, wall, medium). A rig with a light behind its own port, on the
    plane: the fused kernels' image of its straight twin times the port's ratio, exact on
    a node grid (`lightcal.core.light_port_frame`; the exact image is
    `render_image`'s, or `render_image_through_port`'s). Returns (H, W), masked where
    invalid."""
    if (
        mesh is None
        and options.get("sensor", "radiance") != "paper"
        and any(light.port is not None for light in rig.lights)
    ):
        fixed = {k: v for k, v in options.items() if k not in ("medium", "offset")}

        def frame(part: Rig, medium: Medium, offset: float) -> np.ma.MaskedArray:
            if port is not None:
                return render_image_through_port(
                    camera, view, part, port, medium=medium, offset=offset, **fixed
                )
            return render_image(camera, view, part, medium=medium, offset=offset, **fixed)

        return render_frame_with_ported_lights(camera, view, rig, frame, port=port, **options)
    if port is not None:
        return render_image_through_port(camera, view, rig, port, **options)
    return render_image(camera, view, rig, mesh=mesh, **options)


def room_light_view(
    camera: Camera,
    sensor: SensorModel,
    vignetting: np.ndarray | None = None,
    port: FlatPort | None = None,
) -> np.ndarray | None:
    """(H, W) what each pixel makes of a uniform unit radiance on the wall (the room
    light): `lightcal.core.footprint.room_light_image`, times the camera's flat port's
    Fresnel transmittance of each pixel's rays behind one (as
    `Footprints.room_light_factor`); None where uniform (`radiance` without a port)."""
    room = room_light_image(camera, sensor, vignetting)
    if port is None:
        return room
    transmittance = port_transmittance_image(camera, port)
    return transmittance if room is None else room * transmittance
