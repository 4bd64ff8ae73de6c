"""What the page shows of a solve: the guess and the estimate as a `Display`, the light
axes of the history as roll and pitch, and Run's pace. Pure functions of the model and
its parameter vectors (no state, no viser)."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from lightcal.core.footprint import SensorModel
from lightcal.core.light_axis import paper_angles_from_axis
from lightcal.core.scene import Rig
from lightcal.core.solver import CalibrationModel
from lightcal.io.project import Project
from lightcal.pipeline.channel_result import channel_scenes_at
from lightcal_app.state import MAX_ITERATION_S, Display


def pace_wait_s(running: bool, min_iteration_s: float, shown_s: float) -> float:
    """How long the next iteration waits so that the last one stayed `min_iteration_s`
    (at most MAX_ITERATION_S) on the page, `shown_s` after it was drawn; only Run is
    paced (`running`): a Step shows its iteration as soon as it is computed."""
    if not running:
        return 0.0
    return max(min(min_iteration_s, MAX_ITERATION_S) - shown_s, 0.0)


def estimate_display(
    model: CalibrationModel,
    x: np.ndarray,
    *,
    n_images: int,
    model_index: Sequence[int],
    setup_rev: int,
    fall_off: SensorModel,
) -> Display:
    """The page's `Display` of the estimate `x` (n,) of `model`, whose image k is the
    project's image `model_index[k]` (of `n_images`; the others keep gain 1)."""
    gains = np.ones(n_images)
    g_model = model.layout.gain_factors(x)
    for k, i in enumerate(model_index):
        gains[i] = g_model[k]
    return Display(
        model.layout.rig(x),
        tuple(float(g) for g in gains),
        model.layout.offset(x),
        "estimate",
        setup_rev,
        model.layout.wall_of(x),
        fall_off,
        model.layout.medium_of(x),
        tuple(float(c) for c in x[model.layout.fall_off]),
        model.layout.ambient(x),
        model.albedo_map(x),
        model.surroundings,
        tuple(channel_scenes_at(model, x)),
        _albedos_at(model, x),
    )


def guess_display(project: Project, rig: Rig, setup_rev: int) -> Display:
    """The page's `Display` of the guess `rig` (its scales fitted) in `project`, the
    project the solve uses: its wall, fall-off, water and surroundings."""
    return Display(
        rig,
        tuple(1.0 for _ in project.names),
        project.solver.offset,
        "guess",
        setup_rev,
        project.wall.initial,
        project.spec.sensor.model,
        project.medium.initial,
        surroundings=project.surroundings,
        channels=tuple((rig, m.initial, 0.0) for m in project.media),
    )


def light_angles_deg(
    model: CalibrationModel | None, xs: Sequence[np.ndarray]
) -> list[tuple[str, np.ndarray]] | None:
    """Per light with an axis, (name, (T, 2) roll and pitch in degrees) of each x of a
    solve's history (the result's convention, as the Light tab shows them). `model` is
    the model the solve began with: a later stage's x (a wall `auto` tries) begins with
    its parameters. None without a model, or for vectors of another layout."""
    if model is None:
        return None
    n = model.layout.n
    if any(len(x) < n for x in xs):
        return None
    rigs = [model.layout.rig(np.asarray(x[:n], dtype=np.float64)) for x in xs]
    out = []
    for j, unknown in enumerate(model.unknowns):
        if unknown.kind() == "isotropic":
            continue
        angles = np.array(
            [paper_angles_from_axis(rig.lights[j].R_camera_light[:, 2]) for rig in rigs]
        ).reshape(-1, 2)
        out.append((unknown.initial.name, np.degrees(angles)))
    return out


def _albedos_at(model: CalibrationModel, x: np.ndarray) -> tuple[float, ...]:
    """The surroundings' surfaces' albedos the model estimates at x (empty: none)."""
    albedos = model.layout.surface_albedos(x)
    return () if albedos is None else tuple(float(a) for a in albedos)
