"""The bounce light over whole images, for pictures of the model (the report's rendered
images, the page's overlays): the calibration's bounce term (`lightcal.core.bounce_term`)
at every pixel.

The term is computed exactly at the pixels of a lattice (every `step`-th pixel along both
axes and the last row and column; at most `max_pixels` of them) and interpolated
linearly between them: the bounce field is smooth on the wall but where a surface meets
it, where a lattice of a full-resolution image blurs it over `step` pixels. One
`BounceImages` serves every view of a project: one bounce map covers all their lattices
(built on first use, a second or more), and each picture after costs a few hundredths of
a second.
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

__all__ = ["BounceImages"]

#: The most pixels at which the bounce term is computed exactly for one image.
MAX_PIXELS = 40_000


class BounceImages:
    """The bounce light of `surroundings` in the images of `camera` at `views` (module
    docstring), with the sensor model's weights."""

    def __init__(
        self,
        camera: Camera,
        views: list[View],
        surroundings: Surroundings,
        *,
        sensor: SensorModel = "radiance",
        vignetting: np.ndarray | None = None,
        max_pixels: int = MAX_PIXELS,
    ) -> None:
        height, width = camera.height, camera.width
        step = max(1, math.ceil(math.sqrt(height * width / max_pixels)))
        self.shape = (height, width)
        self.us = np.unique(np.append(np.arange(0, width, step), width - 1))
        self.vs = np.unique(np.append(np.arange(0, height, step), height - 1))
        lattice = np.stack(np.meshgrid(self.us, self.vs), axis=-1).reshape(-1, 2)
        self._footprints = [
            pixel_footprints(camera, view, lattice, sensor=sensor, vignetting=vignetting)
            for view in views
        ]
        self._surroundings = surroundings
        self._term: BounceTerm | None = None

    def image(
        self,
        i: int,
        view: View,
        rig: Rig,
        medium: Medium = AIR,
        albedos: np.ndarray | None = None,
    ) -> np.ndarray:
        """(H, W) the rig's bounce light in image i seen from `view` (its pose, with the
        exposure to render at), in the units of `render.render_image` (exposure and
        scales in; 0 where a pixel does not see the wall), through `medium`, the
        surfaces' albedos `albedos` (S,) (None: the declared)."""
        if self._term is None:
            self._term = BounceTerm(self._surroundings, self._footprints)
        values = self._term.values(i, view, rig, medium, albedos)
        values = values.reshape(len(self.vs), len(self.us))
        values = np.where(self._footprints[i].valid.reshape(values.shape), values, 0.0)
        height, width = self.shape
        if len(self.us) == width and len(self.vs) == height:
            return values
        rows = np.stack([np.interp(np.arange(width), self.us, row) for row in values])
        return np.stack([np.interp(np.arange(height), self.vs, col) for col in rows.T], axis=1)
