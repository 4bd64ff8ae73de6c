"""Every image's system with the wall's albedo map projected out
(`lightcal.core.albedo_map`), the water's veil parted from the wall's light.

The albedo scales what the wall reflects (the lights' flux, the room light, the bounce
light) and not the backscatter, which the water in front of the wall sends to the camera.
In a medium that scatters (beta > 0, or beta estimated) each image's system is evaluated
twice: as it is, and with beta = 0 (the wall's light alone); their difference is the
veil's [J r], which the projection leaves unscaled. The derivative with respect to beta
is the veil's alone (at beta = 0 the second pass still holds it), so it is taken whole
from the first pass.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace

import numpy as np

from lightcal.core.albedo_map import AlbedoMap, AlbedoProjection
from lightcal.core.problem import ParameterLayout
from lightcal.core.system_buffers import StateAtX

__all__ = ["SystemOf", "projected_systems"]

SystemOf = Callable[[int, StateAtX, list[np.ndarray] | None], np.ndarray]
"""system(i, state, fluxes): image i's [J_i r_i] (N_i, n + 1) at `state` (a buffer the
next call may reuse), each light's flux (N_i,) appended to `fluxes` when given."""


def projected_systems(
    projection: AlbedoProjection,
    layout: ParameterLayout,
    measured: list[tuple[np.ndarray, np.ndarray]],
    at_x: StateAtX,
    system: SystemOf,
    want_fluxes: bool,
) -> tuple[list[np.ndarray], list[list[np.ndarray] | None], AlbedoMap, np.ndarray]:
    """The images' systems with the albedo projected out (`AlbedoProjection.project`).

    Args:
        projection: the albedo's projection over the images' pixels.
        layout: the parameter vector's layout.
        measured: per image (observed values (N_i,), their sigmas (N_i,)).
        at_x: the state at x.
        system: renders image i's system (`SystemOf`).
        want_fluxes: also return each image's per-light fluxes, albedo and veil in.

    Returns:
        (per image [J_i r_i] (N_i, n + 1), Fortran order; per image its lights' fluxes
        (N_i,) or None; the map at its minimiser; the prior's rows (rows, n + 1)).
    """
    n = layout.n
    k = layout.medium_unknown.position("backscatter_per_m")
    veil_column = None if k is None else layout.medium.start + k
    at_wall = None
    if at_x.medium.scatters or veil_column is not None:
        at_wall = replace(at_x, medium=replace(at_x.medium, backscatter_per_m=0.0))
    systems: list[np.ndarray] = []
    veils: list[np.ndarray | None] = []
    scaled: list[np.ndarray] = []
    walls: list[list[np.ndarray] | None] = []
    all_fluxes: list[list[np.ndarray] | None] = []
    for i, (observed, sigma) in enumerate(measured):
        fluxes: list[np.ndarray] | None = [] if want_fluxes else None
        A = np.array(system(i, at_x, fluxes), order="F")
        u = (observed - at_x.offset) / sigma - A[:, n]  # values above the offset / sigma
        veil: np.ndarray | None = None
        wall_fluxes: list[np.ndarray] | None = None
        if at_wall is not None:
            wall_fluxes = [] if want_fluxes else None
            veil = A - system(i, at_wall, wall_fluxes)
            if veil_column is not None:
                veil[:, veil_column] = A[:, veil_column]
            u = u + veil[:, n]
        systems.append(A)
        veils.append(veil)
        scaled.append(u)
        walls.append(wall_fluxes)
        all_fluxes.append(fluxes)
    offset_column = -1 if layout.offset_index is None else layout.offset_index
    albedo, factors, prior = projection.project(systems, scaled, offset_column, veils)
    for fluxes, wall_fluxes, a in zip(all_fluxes, walls, factors, strict=True):
        if fluxes is None:
            continue
        if wall_fluxes is None:  # all of it the wall's
            fluxes[:] = [flux * a for flux in fluxes]
        else:  # the veil's as it is, the wall's times a
            fluxes[:] = [f + (a - 1.0) * w for f, w in zip(fluxes, wall_fluxes, strict=True)]
    return systems, all_fluxes, albedo, prior
