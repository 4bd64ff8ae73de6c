"""The surroundings' shadows (docs/model.md, "Inter-reflection"): the model renders the
wall as the beam lights it, so pixels a declared surface shadows from a light are out of
the solve. Where the shadow falls depends on the light's pose, so the pixels are dropped
at an estimate (`calibrate` drops them at its first solution and solves again)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from lightcal.core.solver import CalibrationModel
from lightcal.core.surroundings import screened_footprints
from lightcal.errors import InputError
from lightcal.pipeline.wall_choice import restarted

__all__ = ["shadowed", "without_shadows"]


def shadowed(model: CalibrationModel, x: np.ndarray) -> list[np.ndarray]:
    """Per image (N_i,) the pixels a surface shadows, even in part, from a light of the rig
    at x (none without surroundings)."""
    if model.surroundings is None:
        return [np.zeros(len(im.observed), dtype=bool) for im in model.images]
    rig = model.layout.rig(x)
    out = []
    for im in model.images:
        hit = np.zeros(len(im.observed), dtype=bool)
        for light in rig.lights:
            hit |= screened_footprints(
                model.surroundings, light.position_world(im.view), im.footprints.corners_world
            )
        out.append(hit)
    return out


def without_shadows(
    model: CalibrationModel, x: np.ndarray, source: str | Path
) -> tuple[CalibrationModel, int]:
    """The model without the pixels the surroundings shadow from a light at x (its lights
    starting there), and how many it dropped (0: `model` itself).

    Raises:
        InputError: too few pixels are left for the parameters.
    """
    masks = shadowed(model, x)
    dropped = int(sum(np.count_nonzero(m) for m in masks))
    if dropped == 0:
        return model, 0
    images = [im.subset(~m) for im, m in zip(model.images, masks, strict=True) if not m.all()]
    if not images or sum(len(im.observed) for im in images) <= model.layout.n:
        raise InputError(
            source,
            "surroundings: the surfaces' shadows leave fewer pixels than the "
            f"{model.layout.n} parameters; check the surfaces and the selection",
        )
    return restarted(model, x, images=images), dropped
