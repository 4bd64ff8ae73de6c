"""The bounce light over a whole image, for pictures of the model (the report's rendered
images, the page's overlays): the calibration's bounce term (`lightcal.core.bounce_term`)
at every pixel.

The term is computed exactly at the pixels of a lattice (every `step`-th pixel along both
axes and the last row and column; at most `max_pixels` of them) and interpolated
linearly between them: the bounce field is smooth on the wall but where a surface meets
it, where a lattice of a full-resolution image blurs it over `step` pixels.
"""

from __future__ import annotations

import math

import numpy as np

from lightcal.core.bounce_term import BounceTerm
from lightcal.core.camera import Camera
from lightcal.core.footprint import SensorModel, pixel_footprints
from lightcal.core.medium import AIR, Medium
from lightcal.core.scene import Rig, View
from lightcal.core.surroundings import Surroundings

__all__ = ["bounce_image"]

#: The most pixels at which the bounce term is computed exactly for one image.
MAX_PIXELS = 40_000


def bounce_image(
    camera: Camera,
    view: View,
    rig: Rig,
    surroundings: Surroundings,
    *,
    medium: Medium = AIR,
    sensor: SensorModel = "radiance",
    vignetting: np.ndarray | None = None,
    max_pixels: int = MAX_PIXELS,
) -> np.ndarray:
    """(H, W) the rig's bounce light in each pixel of `camera` at `view`, in the units of
    `render.render_image` (exposure and scales in; 0 where a pixel does not see the
    wall), through `medium`, with the sensor model's weights (module docstring)."""
    height, width = camera.height, camera.width
    step = max(1, math.ceil(math.sqrt(height * width / max_pixels)))
    us = np.unique(np.append(np.arange(0, width, step), width - 1))
    vs = np.unique(np.append(np.arange(0, height, step), height - 1))
    lattice = np.stack(np.meshgrid(us, vs), axis=-1).reshape(-1, 2)
    footprints = pixel_footprints(camera, view, lattice, sensor=sensor, vignetting=vignetting)
    term = BounceTerm(surroundings, [footprints])
    values = term.values(0, view, rig, medium).reshape(len(vs), len(us))
    values = np.where(footprints.valid.reshape(values.shape), values, 0.0)
    if step == 1:
        return values
    rows = np.stack([np.interp(np.arange(width), us, row) for row in values])  # (nv, W)
    return np.stack([np.interp(np.arange(height), vs, col) for col in rows.T], axis=1)
