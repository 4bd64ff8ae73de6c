"""The attribution suite: `lightcal synth` datasets with one known departure from their
project each, calibrated as a user would, and what lightcal says about them.

Used by `tests/test_attribution.py` (the confusion table of departure vs the fit test's
first finding, and the sigma's coverage) and `benchmarks/honesty.py`. Each case is a
480 x 360 camera's 12 views at 0.8-2.5 m with realistic 14-bit noise and camera poses
measured to 0.5 mm / 0.05 deg (declared), 400 random pixels an image; the departure's
size is an everyday one.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from lightcal.core.camera import Camera
from lightcal.core.wall import LAMBERTIAN, OrenNayarWall, PlasticWall, WallReflectance
from lightcal.io.project import load_project
from lightcal.pipeline import calibrate_project
from lightcal.pipeline.results import CalibrationResult
from lightcal.synthetic.dataset import SynthConfig, read_truth, write_dataset
from lightcal.synthetic.departures import Departures


@dataclass(frozen=True)
class Case:
    """One departure: how the data are made, which cause the fit test should name
    first (None: no finding) and what the user's project declares beyond `lightcal
    synth`'s (a wall's flatness, which no image reveals)."""

    name: str
    expected: str | None
    departures: Departures = field(default_factory=Departures)
    wall: WallReflectance = LAMBERTIAN
    declared: dict | None = None


CASES = (
    Case("clean", None),
    Case("glossy paint", "gloss", wall=PlasticWall.from_albedo(0.25, 1.5, 0.8)),
    Case("rough matte", "rough_matte", wall=OrenNayarWall(math.radians(25.0))),
    Case("bright rim", "profile", Departures(rid_rim_amplitude=0.3)),
    Case("room light", "ambient", Departures(ambient_fraction=0.05)),
    Case(
        "room light, est.",
        None,
        Departures(ambient_fraction=0.05),
        declared={"sensor": {"estimate_ambient": True}},
    ),
    Case("vignetting", "vignetting", Departures(undeclared_vignetting=(-0.25, 0.05))),
    Case("gamma 1.5", "response", Departures(gamma=1.5)),
    Case("bad poses", "images", Departures(pose_error_m=0.004, pose_error_deg=0.4)),
    # A bow is geometry the light's pose absorbs: no residual shows it (no finding), and
    # only the declared flatness covers it.
    Case("bowed wall", None, Departures(bow_m=0.005), declared={"wall": {"flatness_mm": 5.0}}),
    Case("albedo +-10 %", "wall", Departures(albedo_texture_amplitude=0.1)),
    Case("water", "medium", Departures(attenuation_per_m=0.2)),
)


def camera() -> Camera:
    return Camera.from_params(
        fx=432.0, fy=432.0, cx=239.5, cy=179.5, width=480, height=360, dist=(-0.05, 0.01, 0, 0, 0)
    )


@dataclass(frozen=True)
class Outcome:
    """What lightcal said about one case.

    Attributes:
        case: the case.
        result: the calibration result.
        exit_code: what `lightcal calibrate` would return (0, 1 not converged, 3 finding).
        first_cause: the cause of the first finding (None: no finding).
        position_error_m, position_sigma_m: |error| and the 1-sigma norm of the position.
        axis_error_deg, axis_sigma_deg: the axis' angle error and its 1-sigma norm.
    """

    case: Case
    result: CalibrationResult
    exit_code: int
    first_cause: str | None
    position_error_m: float
    position_sigma_m: float
    axis_error_deg: float
    axis_sigma_deg: float

    @property
    def position_z(self) -> float:
        return self.position_error_m / self.position_sigma_m

    @property
    def axis_z(self) -> float:
        return self.axis_error_deg / self.axis_sigma_deg


def write_case(case: Case, folder: Path, *, seed: int = 5) -> Path:
    """Write the case's dataset into `folder` (new); its project path."""
    config = SynthConfig(camera=camera(), seed=seed, wall=case.wall, departures=case.departures)
    ds = write_dataset(folder, config)
    doc = json.loads(ds.project_path.read_text())
    doc.setdefault("selection", {})["n_per_image"] = 400
    for key, value in (case.declared or {}).items():
        doc.setdefault(key, {}).update(value)
    ds.project_path.write_text(json.dumps(doc))
    return ds.project_path


def first_cause(result: CalibrationResult) -> str | None:
    """The cause of the fit test's first finding (None: none; "level": no cause named)."""
    if result.fit_adequate:
        return None
    material = [c["cause"] for c in result.fit["causes"] if c["material"]]
    return material[0] if material else "level"


def run_case(case: Case, folder: Path, *, seed: int = 5) -> Outcome:
    """Write and calibrate one case; what lightcal says about it."""
    result, found = calibrated(write_case(case, folder, seed=seed))
    return Outcome(case, result, exit_code(result), first_cause(result), *found)


def calibrated(project: Path) -> tuple[CalibrationResult, tuple[float, float, float, float]]:
    """Calibrate a project file beside its truth.json: the result and its `errors`."""
    _, _, result = calibrate_project(load_project(project))
    truth = read_truth(project.parent / "truth.json")["lights"][0]
    return result, errors(result, truth)


def exit_code(result: CalibrationResult) -> int:
    """What `lightcal calibrate` returns for the result: 1 not converged, 3 a finding, 0."""
    return 1 if not result.converged else (3 if not result.fit_adequate else 0)


def errors(result: CalibrationResult, truth: dict) -> tuple[float, float, float, float]:
    """The first light's (position error, its 1-sigma norm (m), axis error, its 1-sigma
    norm (deg)) against a truth.json light."""
    light = result.lights[0]
    position = float(np.linalg.norm(light.pose.t_camera_light - truth["position_m"]))
    cos = float(np.clip(light.pose.axis_camera @ np.array(truth["axis_camera"]), -1.0, 1.0))
    return (
        position,
        float(np.linalg.norm(light.sigma.t_camera_light)),
        math.degrees(math.acos(cos)),
        math.degrees(float(np.linalg.norm(light.sigma.axis_camera))),
    )


def table(outcomes: list[Outcome]) -> str:
    """The outcomes as a text table: case, expected and named cause, exit code, errors
    against sigmas."""
    lines = [
        f"{'case':16s} {'expected':12s} {'named':12s} exit  pos err/sigma mm     "
        "axis err/sigma deg",
    ]
    for o in outcomes:
        lines.append(
            f"{o.case.name:16s} {o.case.expected or '-':12s} {o.first_cause or '-':12s} "
            f"{o.exit_code:4d}  {1e3 * o.position_error_m:7.2f} / {1e3 * o.position_sigma_m:6.2f}"
            f" ({o.position_z:4.1f})  {o.axis_error_deg:6.3f} / {o.axis_sigma_deg:6.3f}"
            f" ({o.axis_z:4.1f})"
        )
    return "\n".join(lines)
