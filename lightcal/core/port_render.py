"""Rendering through the camera's flat port (docs/model.md, "The camera's flat port").

`render_pixels` and `render_image` with a `FlatPort`: the footprints through the port
(`lightcal.core.port_footprints`) shaded as `lightcal.core.render.shade` shades any
footprints (each pixel's camera-side path in the medium from its exit point from the
port). The whole image is every pixel's footprint, exact, as on a wall mesh: the fused
whole-image kernel knows rays from the camera centre only.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from lightcal.core.camera import Camera
from lightcal.core.flat_port import FlatPort
from lightcal.core.footprint import SensorModel, room_light_image
from lightcal.core.medium import AIR, Medium
from lightcal.core.port_footprints import (
    image_footprints_through_port,
    port_footprints,
    port_transmittance_image,
)
from lightcal.core.render import render_image, shade
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
    (super-)pixel's exact footprint. Returns (H // b, W // b), masked where invalid."""
    if not (isinstance(binning, int | np.integer) and binning >= 1):
        raise ValueError(f"binning: expected an integer >= 1, got {binning!r}")
    hb, wb = camera.height // int(binning), camera.width // int(binning)
    fp = image_footprints_through_port(
        camera, view, port, sensor=sensor, vignetting=vignetting, binning=int(binning)
    )
    values = shade(
        fp, view, rig, offset=offset, rid_subsamples=rid_subsamples, wall=wall, medium=medium
    ).values
    return values.reshape(hb, wb)


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
    offset, rid_subsamples, wall, medium). Returns (H, W), masked where invalid."""
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
