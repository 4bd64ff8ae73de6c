"""An image's rendered values at x, for the noise model's re-weighting
(`CalibrationModel.set_weights_at`)."""

from __future__ import annotations

from dataclasses import replace
from typing import TYPE_CHECKING

import numpy as np

from lightcal.core.albedo_map import AlbedoMap, with_albedo
from lightcal.core.medium import Medium
from lightcal.core.render import shade

if TYPE_CHECKING:
    from lightcal.core.calibration_model import CalibrationModel

__all__ = ["rendered_signal"]


def rendered_signal(
    model: CalibrationModel, x: np.ndarray, i: int, gain: float, albedo_map: AlbedoMap | None
) -> np.ndarray:
    """(N_i,) image i's rendered values above the offset at x, with its gain `gain`: its
    channel's lights and medium, the bounce, room light, fall-off and albedo in."""
    im, lay = model.images[i], model.layout
    rig = lay.rig(x, im.channel)

    def render(medium: Medium) -> np.ndarray:
        sh = shade(
            im.footprints,
            im.view,
            rig,
            rid_subsamples=model.options.rid_subsamples,
            wall=lay.wall_of(x),
            medium=medium,
        )
        if model.bounce is not None:
            albedos = lay.surface_albedos(x)
            bounce = model.bounce.values(i, im.view, rig, medium, albedos)
            sh = replace(sh, values=sh.values + bounce)
        return lay.image_values(sh.values, im, x, gain)

    medium = lay.medium_of(x, im.channel)
    if model.albedo is None or albedo_map is None:
        return render(medium)
    return with_albedo(render, medium, model.albedo.factor(i, albedo_map))
