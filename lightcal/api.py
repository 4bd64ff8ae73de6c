"""lightcal's Python API: the few functions a calibration needs, with typed results.

`import lightcal` gives them (lazily: importing the package stays cheap). Each does what
the command of the same name does, through the same pipeline, so a result of
`lightcal.calibrate` is the CLI's result. docs/api.md shows them at work.

| function | does | returns |
|---|---|---|
| `load_project(path)` | read and check a project file | `Project` |
| `calibrate(project, ...)` | load the images, select pixels, solve, summarise | `Calibration` |
| `read_result(path)` / `Calibration.write(path)` | the result file | `ResultFile` |
| `render(project, result)` | the images the calibrated lights give | `list[MaskedArray]` |
| `export(result, fmt, out, ...)` | opencv, blender, mitsuba, ros, ies, ldt | `list[Path]` |
| `plan(project, result, n=...)` | the next views that shrink the sigmas most | `Plan` |
| `ensure_compiled(notify=...)` | compile the numba kernels now (once per install) | seconds |

The numerical kernels are compiled by numba on their first use after an install
(minutes on a small machine). Every function above that needs them calls
`ensure_compiled` first, which says so in one line through `notify` (default: a line
on stderr) before it starts, and returns at once when they are cached.
"""

from __future__ import annotations

import sys
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from lightcal import API
from lightcal.errors import InputError
from lightcal.io.project import Project, load_project
from lightcal.io.result_file import ResultFile, read_result

if TYPE_CHECKING:
    import numpy as np

    from lightcal.core.solver import CalibrationModel, IterationReport
    from lightcal.pipeline.load import LoadedImages
    from lightcal.pipeline.plan import PlannedView, Sigmas
    from lightcal.pipeline.results import CalibrationResult

__all__ = list(API)  # the names `import lightcal` gives (lightcal.API)

Notify = Callable[[str], None]
"""Where a one-line message goes (`print`, a logger's `info`, a GUI's status line)."""

ProgressFn = Callable[[str, int, int], None]
"""progress(stage, done, total): e.g. ("reading images", 3, 12)."""

COMPILE_MESSAGE = (
    "lightcal: compiling the numba kernels (once per install, minutes on a small machine; "
    "`lightcal warmup` does it ahead)"
)


def _stderr(message: str) -> None:
    print(message, file=sys.stderr, flush=True)


def ensure_compiled(notify: Notify | None = _stderr) -> float:
    """Compile the numba kernels now unless they are cached; the seconds it took.

    Args:
        notify: Told `COMPILE_MESSAGE` before compiling and one line when done (nothing
            when the kernels are cached); None: silent.
    """
    from lightcal.warmup import kernels_ready, warm_up

    if kernels_ready():
        return 0.0
    if notify is not None:
        notify(COMPILE_MESSAGE)
    seconds = warm_up()
    if notify is not None:
        notify(f"lightcal: kernels compiled in {seconds:.0f} s (cached from now on)")
    return seconds


def _as_project(project: Project | str | Path) -> Project:
    return project if isinstance(project, Project) else load_project(project)


@dataclass(frozen=True, eq=False)
class Calibration:
    """What `calibrate` found.

    Attributes:
        file: The result as `lightcal calibrate` writes it (`ResultFile`: per light its
            pose, sigmas and scale in `file.lights`; the fit test in `file.fit`).
        result: The same in memory (`lightcal.pipeline.CalibrationResult`: numpy arrays).
        project: The project calibrated.
        model: The calibration model (selected pixels, parameter layout).
        loaded: The images as read.
    """

    file: ResultFile
    result: CalibrationResult
    project: Project
    model: CalibrationModel = field(repr=False)
    loaded: LoadedImages = field(repr=False)

    @property
    def converged(self) -> bool:
        return bool(self.file.converged)

    def write(self, path: str | Path) -> Path:
        """Write the result file (JSON, atomically); returns its path."""
        from lightcal.io.result_file import write_result

        write_result(self.file, path)
        return Path(path)


def calibrate(
    project: Project | str | Path,
    *,
    progress: ProgressFn | None = None,
    on_iteration: Callable[[IterationReport], None] | None = None,
    on_stage: Notify | None = None,
    notify: Notify | None = _stderr,
) -> Calibration:
    """Calibrate a project's lights, as `lightcal calibrate` does.

    Args:
        project: A `Project` or the path of a project file.
        progress: Called as images are read and pixels selected: (stage, done, total).
        on_iteration: Called after each solver iteration with its `IterationReport`
            (`iteration`, `cost`, `gradient_norm`, `nfev`, `x`).
        on_stage: Told each step of the solve in a line (random starts, the wall choice).
        notify: Where the kernels' compile message goes (`ensure_compiled`).
    """
    from lightcal.io.project_identity import project_identity
    from lightcal.io.result_file import result_to_file
    from lightcal.pipeline import build_model, load_images
    from lightcal.pipeline import calibrate as solve
    from lightcal.pipeline.load import prepare_solve

    project = _as_project(project)
    ensure_compiled(notify)
    loaded = load_images(project, progress=progress, meanwhile=lambda: prepare_solve(project))
    model = build_model(project, loaded, progress=progress)
    cal = solve(project, loaded, model, on_iteration=on_iteration, on_stage=on_stage)
    file = result_to_file(cal.result, project=project.path, project_id=project_identity(project))
    return Calibration(file, cal.result, project, cal.model, loaded)


def _result_file(result: ResultFile | Calibration | str | Path) -> tuple[ResultFile, str | Path]:
    if isinstance(result, Calibration):
        return result.file, "the calibration"
    if isinstance(result, ResultFile):
        return result, "the result"
    return read_result(result), result


def render(
    project: Project | str | Path,
    result: ResultFile | Calibration | str | Path,
    *,
    progress: ProgressFn | None = None,
    notify: Notify | None = _stderr,
) -> list[np.ma.MaskedArray]:
    """Every project image rendered with the calibrated lights, as `lightcal render` does:
    (H, W) masked arrays (masked off the wall), in the images' units, with each image's
    gain, the offset, the fitted wall and the room light and fall-off of the result."""
    import numpy as np

    from lightcal.core.medium import medium_from_description
    from lightcal.core.scene import Rig
    from lightcal.core.wall import wall_from_description
    from lightcal.io.project_identity import check_result_of
    from lightcal.pipeline import load_images
    from lightcal.pipeline.channel_result import channel_scenes, estimated_surroundings
    from lightcal.pipeline.fall_off_result import fall_off_map
    from lightcal.report import render_views

    project = _as_project(project)
    file, source = _result_file(result)
    check_result_of(project, Path(source), file.project_id)
    by_name = {lr.name: lr for lr in file.lights}
    lights = []
    for unknown in project.lights:
        lr = by_name.get(unknown.initial.name)
        if lr is None:
            raise InputError(source, f"no result for light {unknown.initial.name!r}")
        position, R = np.array(lr.position_m), np.array(lr.R_camera_light)
        lights.append(unknown.initial.replace(t_camera_light=position, R_camera_light=R,
                                              scale=lr.scale, name=lr.name))  # fmt: skip
    try:
        wall = wall_from_description(file.wall)
    except ValueError as exc:
        raise InputError(source, f"wall: {exc}") from exc
    try:
        medium = medium_from_description(file.medium)
        channels = channel_scenes(file.channels, lights, project.channels)
        surroundings = estimated_surroundings(project.surroundings, file.surroundings)
    except ValueError as exc:
        raise InputError(source, str(exc)) from exc
    try:  # the sensor terms the result estimated (checked before any work)
        fall_off_map(file.fall_off, project.camera.width, project.camera.height)
    except ValueError as exc:
        raise InputError(source, str(exc)) from exc
    gains = {im.name: im.gain for im in file.images}
    ensure_compiled(notify)
    loaded = load_images(project, progress=progress)
    # On the images' grid (a raw reader's binned one when it binned): r is the same.
    fall_off = fall_off_map(file.fall_off, loaded.camera.width, loaded.camera.height)
    return render_views(
        project,
        loaded,
        Rig(tuple(lights)),
        gains=[gains.get(n, 1.0) for n in project.names],
        offset=file.offset,
        progress=progress,
        wall=wall,
        medium=medium,
        fall_off=fall_off,
        ambient=file.ambient or 0.0,
        channels=channels,
        surroundings=surroundings,
    )


def export(
    result: ResultFile | Calibration | str | Path,
    fmt: str,
    out: str | Path,
    *,
    project: Project | str | Path | None = None,
    light: str | None = None,
    wall_albedo: float | None = None,
    force: bool = False,
    notify: Notify | None = _stderr,
) -> list[Path]:
    """Write a result for another tool, as `lightcal export` does; the files written.

    Args:
        result: A `Calibration`, a `ResultFile` or a result file's path.
        fmt: "opencv", "blender", "mitsuba", "ros", "ies" or "ldt" (docs/conventions.md).
        out: The main file (Mitsuba's textures, ROS's URDF go beside it).
        project: The project: its camera (Mitsuba's sensor, Blender's camera), its camera's
            and lights' flat ports (`camera.port`, `lights[i].port`) and the RIDs the
            calibration did not estimate (a Calibration brings its own).
        light: The light to write as ies/ldt when several have a RID.
        wall_albedo: The wall's albedo rho, for Mitsuba's and Blender's scattering
            coefficient beta rho / pi of a medium that scatters (default: the project's
            `surroundings.wall_albedo`; `lightcal.io.export_medium`).
        force: Replace existing files.
    """
    from lightcal.io.export import export_result, with_given_rids

    file, source = _result_file(result)
    if project is None and isinstance(result, Calibration):
        project = result.project
    from lightcal.io.export_light_port import light_ports_of

    camera, port, light_ports = None, None, {}
    if project is not None:
        project = _as_project(project)
        camera, port = project.camera, project.camera_port
        light_ports = light_ports_of([(u.initial.name, u.initial.port) for u in project.lights])
        ensure_compiled(notify)  # analytic RIDs are sampled with the compiled evaluator
        file = with_given_rids(file, {u.initial.name: u.initial.rid for u in project.lights})
        if wall_albedo is None and project.surroundings is not None:
            wall_albedo = project.surroundings.wall_albedo
    elif fmt == "mitsuba":
        ensure_compiled(notify)  # the RID texture: the compiled table evaluator
    return export_result(
        file,
        fmt,
        out,
        source=source,
        light_name=light,
        camera=camera,
        wall_albedo=wall_albedo,
        port=port,
        light_ports=light_ports,
        force=force,
    )


@dataclass(frozen=True, eq=False)
class Plan:
    """What `plan` suggests.

    Attributes:
        current: Per light, the position (m) and axis (deg) 1-sigma now.
        views: The next views, best first: each `candidate` (its `instruction()` in
            words, its `view` pose) with the sigmas `before` and `after` taking it.
        light_names: The lights, in the order of the sigmas.
    """

    current: Sigmas
    views: list[PlannedView]
    light_names: list[str]

    def to_dict(self) -> dict[str, Any]:
        """The plan as `lightcal plan --out` writes it (JSON-ready)."""
        from lightcal.pipeline.plan import plan_to_dict

        return plan_to_dict(self.current, self.views, self.light_names)


def plan(
    project: Project | str | Path,
    result: ResultFile | Calibration | str | Path | None = None,
    *,
    n: int = 3,
    wall_size_m: float | None = None,
    progress: ProgressFn | None = None,
    notify: Notify | None = _stderr,
) -> Plan:
    """The `n` next camera views that shrink the pose's sigmas most, as `lightcal plan`
    does: at the result's estimate, or at the project's initial guess without one."""
    from lightcal.io.project_identity import check_result_of
    from lightcal.pipeline import build_model, load_images, measurements_for
    from lightcal.pipeline.plan import PlanGrid, noise_variance, plan_views, start_vector

    project = _as_project(project)
    names = x = None
    if result is not None:
        file, source = _result_file(result)
        check_result_of(project, Path(source), file.project_id)
        names, x = file.parameters.names, file.parameters.x
    grid = PlanGrid() if wall_size_m is None else PlanGrid(wall_size_m=wall_size_m)
    ensure_compiled(notify)
    loaded = load_images(project, progress=progress)
    model = build_model(project, loaded, progress=progress)
    x0 = start_vector(model, names, x, "result")
    s2 = None
    if result is None:  # the guess's misfit is no noise: the noise models' variance
        s2 = noise_variance(model, measurements_for(project, loaded, model).noise) or 1.0
    current, planned = plan_views(
        model,
        x0,
        loaded.camera,
        n=n,
        grid=grid,
        noise_scale2=s2,
        progress=progress,
        mesh=project.wall_mesh,
    )
    return Plan(current, planned, [u.initial.name for u in model.unknowns])
