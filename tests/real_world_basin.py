"""The basin of convergence on `lightcal synth --real-world`'s data (issue 25): random starts
around the light, solved as `lightcal calibrate` solves the project `lightcal init` made.

`prepare` writes the dataset, fits the response curve of its bracket and runs `init` on
its photos (no flag but the curve), as the user would, then builds the project's model on
`PIXELS_PER_IMAGE` random pixels of each photo (the basin is the cost's shape; every pixel,
as init selects them, costs ten times more per solve). `reach` solves from one start:
alone (`run_least_squares`) or with the pipeline's multi-start (`lightcal.pipeline.solve`,
half of the extra starts across the cap in front of the camera); a start reaches the
solution when the solve ends within 0.1 mm and 0.01 degrees of the minimum found from the
truth. Starts are drawn as `benchmarks/calibrate.py`'s basin draws them: a position error
uniform up to `max_m` in a random direction, the axis turned by an angle uniform up to
`max_deg`, again while the start is behind the wall in a view.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from lightcal.capture.project_init import init_project
from lightcal.core.calibration_model import CalibrationModel
from lightcal.core.rotations import matrix_from_rotvec
from lightcal.core.scene import Light, View
from lightcal.core.solver import run_least_squares
from lightcal.io.project import Project, load_project
from lightcal.io.response_bracket import fit_bracket_curve, read_bracket_image
from lightcal.pipeline import build_model, load_images
from lightcal.pipeline.load import LoadedImages
from lightcal.pipeline.solve import solve
from lightcal.synthetic.real_world import RealWorldConfig, write_real_world

PIXELS_PER_IMAGE = 2000


@dataclass(frozen=True, eq=False)
class Basin:
    """The project of the dataset, its images and the minimum found from the truth."""

    project: Project
    loaded: LoadedImages
    truth: Light
    minimum: Light


def _axis_angle_deg(a: np.ndarray, b: np.ndarray) -> float:
    c = float(a @ b / (np.linalg.norm(a) * np.linalg.norm(b)))
    return math.degrees(math.acos(min(1.0, max(-1.0, c))))


def _model(basin_project: Project, loaded: LoadedImages, start: Light) -> CalibrationModel:
    """The project's model started at `start` (its scale fitted, as init's project does)."""
    unknown = basin_project.lights[0]
    light = unknown.initial.replace(
        t_camera_light=start.t_camera_light, R_camera_light=start.R_camera_light
    )
    project = replace(basin_project, lights=[replace(unknown, initial=light)])
    return build_model(project, loaded)


def prepare(folder: Path, config: RealWorldConfig | None = None) -> Basin:
    """The dataset, curve, project (`folder/project.json`) and the minimum from the truth."""
    dataset = write_real_world(folder / "data", config or RealWorldConfig())
    truth_doc = json.loads(dataset.truth_path.read_text())["bracket"]
    bracket = [read_bracket_image(p) for p in dataset.bracket_paths]
    fit_bracket_curve(bracket, truth_doc["exposure_times_s"]).save(folder / "curve.json")
    init_project(
        dataset.folder / "images",
        camera_path=dataset.camera_path,
        board_path=dataset.board_path,
        out_path=folder / "project.json",
        response_path=folder / "curve.json",
    )
    project = load_project(folder / "project.json")
    selection = replace(project.selection, strategy="random", n_per_image=PIXELS_PER_IMAGE)
    project = replace(project, selection=selection)
    loaded = load_images(project)
    truth = dataset.light
    model = _model(project, loaded, truth)
    out = run_least_squares(model)
    return Basin(project, loaded, truth, model.layout.rig(out.x).lights[0])


def random_start(basin: Basin, rng: np.random.Generator, max_m: float, max_deg: float) -> Light:
    """A start within the limits (module docstring), in front of the wall in every view."""
    return start_within(basin.truth, basin.project.views, rng, max_m, max_deg)[0]


def start_within(
    light: Light, views: list[View], rng: np.random.Generator, max_m: float, max_deg: float
) -> tuple[Light, float, float]:
    """`light` moved by up to `max_m` and its axis turned by up to `max_deg` (not its
    roll), in front of the wall in every view: (the start, its shift m, its turn deg)."""
    while True:
        d = rng.normal(size=3)
        shift = d / np.linalg.norm(d) * rng.uniform(0.0, max_m)
        w = rng.normal(size=3)
        w -= (w @ light.axis_camera) * light.axis_camera  # turn the axis, not the roll
        angle = math.radians(rng.uniform(0.0, max_deg))
        R = matrix_from_rotvec(w / np.linalg.norm(w) * angle) @ light.R_camera_light
        start = light.replace(t_camera_light=light.t_camera_light + shift, R_camera_light=R)
        if all(start.position_world(v)[2] > 0.0 for v in views):
            return start, float(np.linalg.norm(shift)), math.degrees(angle)


def reach(basin: Basin, start: Light, *, multistart: int, seed: int) -> tuple[bool, float, float]:
    """Whether the solve from `start` reaches the minimum; its distance (mm, degrees)."""
    model = _model(basin.project, basin.loaded, start)
    try:
        out = (
            run_least_squares(model)
            if multistart == 0
            else solve(model, multistart=multistart, seed=seed)
        )
    except ValueError:
        return False, math.inf, math.inf
    end = model.layout.rig(out.x).lights[0]
    mm = 1e3 * float(np.linalg.norm(end.t_camera_light - basin.minimum.t_camera_light))
    deg = _axis_angle_deg(end.axis_camera, basin.minimum.axis_camera)
    return bool(out.success and mm < 0.1 and deg < 0.01), mm, deg
