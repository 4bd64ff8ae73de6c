"""The columns of an estimated RID's parameters, by central differences of the renderer."""

from __future__ import annotations

import functools

import numpy as np

from lightcal.core.problem import ImageData, ParameterLayout
from lightcal.core.render import shade
from lightcal.core.scene import Rig


def rid_columns(
    layout: ParameterLayout,
    image: ImageData,
    x: np.ndarray,
    j: int,
    gain: float,
    rid_subsamples: int,
) -> np.ndarray:
    """(N, k) d m_render / d (light j's k RID parameters) on `image` of gain `gain` at x,
    by central differences (V = 1: the sensor terms scale these columns with the others)."""
    block = layout.blocks[j]
    out = np.empty((len(image.observed), block.rid.stop - block.rid.start))
    lights = list(layout.rig(x, image.channel).lights)
    render = functools.partial(
        shade,
        image.footprints,
        image.view,
        rid_subsamples=rid_subsamples,
        wall=layout.wall_of(x),
        medium=layout.medium_of(x, image.channel),
    )
    for c, k in enumerate(range(block.rid.start, block.rid.stop)):
        h = 1e-6 * max(1.0, abs(x[k]))
        vals = []
        for sgn in (1.0, -1.0):
            xs = x.copy()
            xs[k] += sgn * h
            lights[j] = layout.light_of(block, xs, channel=image.channel)
            vals.append(gain * render(Rig(tuple(lights))).values.filled(np.nan))
        out[:, c] = (vals[0] - vals[1]) / (2 * h)
    return out
