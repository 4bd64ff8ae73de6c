"""Solving: the multi-start least-squares solve of a model, and `calibrate_project`, the
whole pipeline from a project to a `CalibrationResult`."""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, replace

import numpy as np

from lightcal.core.light_axis import rotation_from_axis
from lightcal.core.model_rebuild import rebuilt
from lightcal.core.rotations import matrix_from_rotvec
from lightcal.core.solver import CalibrationModel, IterationReport, SolveOutcome, run_least_squares
from lightcal.io.project import Project, SolverSpec
from lightcal.pipeline.auto_start import with_auto_initial
from lightcal.pipeline.capture_checks import same_pose_warnings
from lightcal.pipeline.load import LoadedImages, ProgressFn, load_images
from lightcal.pipeline.measurements import measurements_for
from lightcal.pipeline.model import build_model
from lightcal.pipeline.results import CalibrationResult, summarise
from lightcal.pipeline.shadows import without_shadows
from lightcal.pipeline.wall_choice import (
    Candidate,
    auto_candidates,
    bic,
    choice_note,
    start_from,
    undetermined_wall,
    wall_candidate,
    without_mirror,
)

#: `SolveOutcome.status` of a solve its caller stopped (StopIteration from on_iteration).
STOPPED = -2

#: Solves again after dropping the pixels the surroundings shadow at the estimate, at most
#: this many times (the shadows move with the light's estimate).
SHADOW_PASSES = 2

# The multi-start defaults are the project file's (defined once).
_SOLVER_SPEC = SolverSpec()


def perturbed_start(
    model: CalibrationModel, rng: np.random.Generator, *, shift_m: float, angle_deg: float
) -> np.ndarray:
    """A random start near the initial guess: each light's `t_camera_light` moved by up to
    `shift_m`, light axes/orientations rotated by up to `angle_deg`."""
    x = model.layout.x0.copy()
    for block in model.layout.blocks:
        p = x[block.pose].copy()
        d = rng.normal(size=3)
        p[:3] += d / np.linalg.norm(d) * rng.uniform(0, shift_m)
        R, t = block.param.to_pose(p)
        if block.param.n_rot:
            w = rng.normal(size=3)
            w *= math.radians(rng.uniform(0, angle_deg)) / np.linalg.norm(w)
            R = matrix_from_rotvec(w) @ R
        x[block.pose] = block.param.from_pose(R, t)
    return x


#: The cap in front of the camera (half-angle about its optical axis, deg) from which
#: every other random start draws the light's axis (`hemisphere_start`).
HEMISPHERE_DEG = 70.0


def hemisphere_start(
    model: CalibrationModel, rng: np.random.Generator, *, max_angle_deg: float = HEMISPHERE_DEG
) -> np.ndarray:
    """A random start with each light at its initial position and its axis drawn
    uniformly from the cap within `max_angle_deg` of the camera's optical axis (+z): a
    narrow beam whose guess points away from where it falls on the wall is found from one
    of them, where starts around the guess all miss it. A general light keeps its spin
    about its own axis."""
    x = model.layout.x0.copy()
    lo = math.cos(math.radians(max_angle_deg))
    for block in model.layout.blocks:
        if not block.param.n_rot:
            continue
        R, t = block.param.to_pose(x[block.pose])
        cos_theta = rng.uniform(lo, 1.0)
        phi = rng.uniform(0.0, 2.0 * math.pi)
        sin_theta = math.sqrt(max(0.0, 1.0 - cos_theta**2))
        axis = np.array([sin_theta * math.cos(phi), sin_theta * math.sin(phi), cos_theta])
        R_new = rotation_from_axis(axis) @ rotation_from_axis(R[:, 2]).T @ R
        x[block.pose] = block.param.from_pose(R_new, t)
    return x


def start_words(k: int, n: int) -> str:
    """Start k of n of `solve`, in words ("start 2 of 3: a random start near it")."""
    if k == 0:
        what = "the initial guess"
    elif k % 2:
        what = "a random start near it"
    else:
        what = "a random axis in front of the camera"
    return f"start {k + 1} of {n}: {what}"


#: From this many pixels a solve starts from the solution of a regular subsample of them.
COARSE_MIN_PIXELS = 1_000_000
#: About how many pixels the subsample keeps.
COARSE_PIXELS = 250_000


def coarse_start(
    model: CalibrationModel, on_stage: Callable[[str], None] | None = None
) -> tuple[np.ndarray, str, list[float]] | None:
    """Where to start the solve of a large model: the solution of the same problem on
    every k-th pixel of each image (about COARSE_PIXELS in all), from the initial guess;
    None (the initial guess) below COARSE_MIN_PIXELS or when that solve fails.

    Each of its evaluations costs about 1 / k of a full one, and the full problem's
    minimum lies within a few of its standard errors of the subsample's: from there the
    full solve takes a Gauss-Newton step or two instead of every iteration from the
    guess. Only the start changes: the full solve converges by its own test, and its
    iterations are the ones reported. `on_stage` hears what runs, in words.

    Returns:
        (x, what it is in words: `SolveOutcome.start`, that solve's cost per iteration
        times m / m_subsample: `SolveOutcome.start_costs`), or None.
    """
    if model.m < COARSE_MIN_PIXELS:
        return None
    k = max(2, model.m // COARSE_PIXELS)
    # Indices, not strided views: the kernels take contiguous arrays.
    images = [im.subset(np.arange(0, len(im.observed), k)) for im in model.images]
    coarse = rebuilt(model, images=images)
    if coarse.layout.names != model.layout.names or coarse.m <= coarse.layout.n:
        return None
    if on_stage is not None:
        on_stage(
            f"a first solve on one pixel in {k} ({coarse.m} of {model.m}), "
            "then the full solve from its estimate"
        )
    try:
        out = run_least_squares(coarse)
    except ValueError:
        return None
    if not (out.success and np.all(np.isfinite(out.x))):
        return None
    # On the full problem's scale: the same mean squared residual over m pixels.
    costs = [rep.cost * model.m / coarse.m for rep in out.history]
    return (
        out.x,
        f"the estimate of a first solve on one pixel in {k} ({coarse.m} of {model.m} "
        f"pixels, {out.iterations} iterations)",
        costs,
    )


def solve(
    model: CalibrationModel,
    *,
    multistart: int = _SOLVER_SPEC.multistart,
    multistart_position_m: float = _SOLVER_SPEC.multistart_position_m,
    multistart_angle_deg: float = _SOLVER_SPEC.multistart_angle_deg,
    seed: int = 0,
    x0: np.ndarray | None = None,
    on_iteration: Callable[[IterationReport], None] | None = None,
    on_start: Callable[[int, int], None] | None = None,
    on_stage: Callable[[str], None] | None = None,
) -> SolveOutcome:
    """Solve from the initial guess and `multistart` random starts; keep the best. The
    odd starts are `perturbed_start`s around the guess, the even ones `hemisphere_start`s.

    `x0` (n,), when given, is where the first solve starts instead of the initial guess
    (an estimate to continue from; the random starts stay around the initial guess). A
    first solve its caller stopped (status -2, `on_iteration` raised StopIteration) is
    returned as it is: no random start follows.

    A large model's first solve starts where its subsample's solution is (`coarse_start`).
    With a robust loss's f_scale "auto", every start uses the f_scale the first one took
    from its linear stage (`run_least_squares`): costs compare only under one f_scale.

    `on_iteration` sees every start's iterations (each numbered from 0); `on_start(k, n)`
    is called before start k of n (0: the initial guess).
    """
    n_starts = 1 + multistart
    if on_start is not None:
        on_start(0, n_starts)
    coarse = coarse_start(model, on_stage) if x0 is None else None
    if coarse is not None:
        x0 = coarse[0]
    best = run_least_squares(model, x0, on_iteration=on_iteration)
    if coarse is not None:
        best.start, best.start_costs = coarse[1], coarse[2]
    if best.status == STOPPED:
        return best
    rng = np.random.default_rng(seed)
    f_scale = best.f_scale_used if model.options.f_scale == "auto" else None
    for k in range(1, n_starts):
        # Around the guess, and (every second start) anywhere in front of the camera.
        if k % 2 == 0:
            x0 = hemisphere_start(model, rng)
        else:
            x0 = perturbed_start(
                model, rng, shift_m=multistart_position_m, angle_deg=multistart_angle_deg
            )
        if on_start is not None:
            on_start(k, n_starts)
        try:
            out = run_least_squares(model, x0, on_iteration=on_iteration, f_scale=f_scale)
        except ValueError:
            continue
        if out.status == STOPPED:
            break
        if out.cost < best.cost:
            best = out
    if multistart:
        model.set_weights_at(best.weights_at)  # the weights the best solve ended with
    return best


def solve_project(
    project: Project,
    model: CalibrationModel,
    *,
    x0: np.ndarray | None = None,
    on_iteration: Callable[[IterationReport], None] | None = None,
    on_start: Callable[[int, int], None] | None = None,
    on_stage: Callable[[str], None] | None = None,
) -> SolveOutcome:
    """`solve` with the project's multi-start settings."""
    so = project.spec.solver
    return solve(
        model,
        multistart=so.multistart,
        multistart_position_m=so.multistart_position_m,
        multistart_angle_deg=so.multistart_angle_deg,
        seed=project.selection.seed,
        x0=x0,
        on_iteration=on_iteration,
        on_start=on_start,
        on_stage=on_stage,
    )


@dataclass(frozen=True)
class Calibration:
    """The solved model, its solve and its result."""

    model: CalibrationModel
    outcome: SolveOutcome
    result: CalibrationResult


def calibrate(
    project: Project,
    loaded: LoadedImages,
    model: CalibrationModel,
    *,
    x0: np.ndarray | None = None,
    on_iteration: Callable[[IterationReport], None] | None = None,
    on_start: Callable[[int, int], None] | None = None,
    on_stage: Callable[[str], None] | None = None,
    on_model: Callable[[CalibrationModel], None] | None = None,
) -> Calibration:
    """Solve a project's model the way the project says, test the fit and summarise.

    Beyond `solve_project`: `selection.exclude_mirror_deg` (drop pixels near the mirror
    direction of the first estimate, solve again from it) and `wall: {model: auto}`
    (where the Lambertian fit has a finding and the fit test's gloss or rough-matte cause
    is significant, also fit plastic or oren_nayar and keep the lowest BIC among the fits
    whose wall parameters are determined; docs/model.md). `on_stage` hears each extra
    stage in words; `on_model` gets each model before it is solved (the trimmed one, each
    wall's: their parameter vectors differ), so a caller drawing the iterations of
    `on_iteration` knows which model an `x` belongs to. `lightcal calibrate` and the
    app's Run both solve through here.

    `x0`: where the first solve starts (`solve`). A solve its caller stopped (status -2)
    ends the pipeline there: its result is summarised, no further stage runs.
    """

    def stage(text: str) -> None:
        if on_stage is not None:
            on_stage(text)

    def run(m: CalibrationModel, start: np.ndarray | None = None) -> SolveOutcome:
        if on_model is not None:
            on_model(m)
        if start is None:
            return solve_project(
                project,
                m,
                x0=x0,
                on_iteration=on_iteration,
                on_start=on_start,
                on_stage=on_stage,
            )
        return run_least_squares(m, start, on_iteration=on_iteration)

    # Images the selection left without a usable pixel are out of the solve: say which.
    used = {im.name for im in model.images}
    notes: list[str] = [
        f"image {name}: no usable pixels (all saturated, masked, below the noise floor or "
        "off the wall): left out of the solve"
        for name in project.names
        if name not in used
    ]
    notes += same_pose_warnings(project, used)
    outcome = run(model)
    for _ in range(SHADOW_PASSES):
        if outcome.status == STOPPED:
            break
        unshadowed, dropped = without_shadows(model, outcome.x, project.path)
        if dropped == 0:
            break
        stage(f"dropping {dropped} pixels the surroundings shadow from the light")
        notes.append(
            f"surroundings: {dropped} pixels in the surfaces' shadows from the light at the "
            "estimate were dropped"
        )
        outcome = run(unshadowed, start_from(unshadowed, model, outcome.x))
        model = unshadowed
    limit = project.spec.selection.exclude_mirror_deg
    if limit and outcome.status != STOPPED:
        stage(f"dropping pixels within {limit:g} deg of the mirror direction")
        trimmed, dropped = without_mirror(model, outcome.x, limit, project.path)
        notes.append(
            f"selection: {dropped} pixels within {limit:g} deg of the mirror direction "
            "of the first estimate were dropped"
        )
        outcome = run(trimmed, start_from(trimmed, model, outcome.x))
        model = trimmed
    result = summarise(model, outcome, measurements_for(project, loaded, model), notes=notes)
    if project.spec.wall.model != "auto" or outcome.status == STOPPED:
        return Calibration(model, outcome, result)
    tried = [Candidate("lambertian", model, outcome, result, bic(result, model))]
    if result.fit_adequate:
        note = "wall: auto kept lambertian: no misfit moves the pose beyond its sigma"
        return Calibration(model, outcome, replace(result, warnings=[*result.warnings, note]))
    wanted = auto_candidates(result.fit)
    if not wanted:
        note = (
            "wall: auto kept lambertian: the fit test does not point at the wall's "
            "reflectance (no significant gloss or rough-matte cause)"
        )
        return Calibration(model, outcome, replace(result, warnings=[*result.warnings, note]))
    for name in wanted:
        stage(f"the fit test points at the wall: trying the {name} wall")
        candidate = wall_candidate(model, outcome.x, name)
        out = run(candidate, start_from(candidate, model, outcome.x))
        if out.status == STOPPED:
            return Calibration(candidate, out, summarise(candidate, out, notes=notes))
        res = summarise(candidate, out, measurements_for(project, loaded, candidate), notes=notes)
        tried.append(Candidate(name, candidate, out, res, bic(res, candidate)))
    determined = [c for c in tried if not undetermined_wall(c.result.wall)]
    best = min(determined, key=lambda c: c.bic)
    note = choice_note(best, tried)
    return Calibration(
        best.model, best.outcome, replace(best.result, warnings=[*best.result.warnings, note])
    )


def calibrate_project(
    project: Project,
    *,
    progress: ProgressFn | None = None,
    on_iteration: Callable[[IterationReport], None] | None = None,
) -> tuple[LoadedImages, CalibrationModel, CalibrationResult]:
    """Load, select, solve (`calibrate`) and summarise a project."""
    loaded = load_images(project, progress=progress)
    project = with_auto_initial(project, loaded)
    model = build_model(project, loaded, progress=progress)
    cal = calibrate(project, loaded, model, on_iteration=on_iteration)
    return loaded, cal.model, cal.result
