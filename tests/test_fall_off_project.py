"""`sensor.estimate_fall_off` from the project file to the result: the key's errors, the
option it builds, and the acceptance on `lightcal synth` data (tests/departure_suite.py:
12 views of a 480 x 360 camera with realistic noise, 400 pixels an image): with undeclared
vignetting of the issue's size (1 - 0.25 r^2 + 0.05 r^4) the light lands within 2 mm and
0.1 deg and the coefficients within their sigma; without vignetting the coefficients are
0 within their sigma and the pose moves by less than its sigma."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest

from lightcal.io.project import load_project
from lightcal.io.result_file import read_result, result_to_file, write_result
from lightcal.pipeline import calibrate_project
from lightcal.pipeline.fall_off_result import fall_off_text
from lightcal.synthetic.dataset import read_truth
from tests.departure_suite import CASES, Case, errors, exit_code, write_case
from tests.test_project import _doc, _error, _write
from tests.test_project import folder as folder

VIGNETTING = (-0.25, 0.05)


@pytest.mark.parametrize(
    ("fall_off", "message"),
    [
        ({"order": 0}, "order: Input should be greater than or equal to 1"),
        ({"order": -2}, "order: Input should be greater than or equal to 1"),
        ({"order": 4}, "order: Input should be less than or equal to 3"),
        (
            {"order": "two"},
            "order: Input should be a valid integer, unable to parse string as an integer",
        ),
        ({"order": math.nan}, "order: Input should be a finite number"),
        ({"model": "cos4"}, "model: Input should be 'radial'"),
        ({"centre": [1, 2]}, "centre: Extra inputs are not permitted"),
    ],
)
def test_bad_estimate_fall_off_names_the_key(folder, fall_off: dict, message: str):
    doc = _doc()
    doc["sensor"] = {"estimate_fall_off": fall_off}
    expected = f"{folder / 'project.json'}: sensor.estimate_fall_off.{message}"
    assert _error(folder, doc) == expected


def test_the_option_follows_the_camera_and_the_binning(folder):
    doc = _doc()
    assert load_project(_write(folder, doc)).solver.fall_off is None
    doc["sensor"] = {"estimate_fall_off": {"order": 3}}
    doc["selection"] = {"strategy": "all", "binning": 4}
    project = load_project(_write(folder, doc))
    f = project.solver.fall_off
    assert f is not None
    assert (f.order, f.width, f.height, f.binning) == (
        3,
        project.camera.width,
        project.camera.height,
        4,
    )
    doc["sensor"] = {"estimate_fall_off": {}}  # the default order, 2
    doc["selection"] = {"strategy": "random"}  # binning applies to `all` only
    f = load_project(_write(folder, doc)).solver.fall_off
    assert f is not None and (f.order, f.binning) == (2, 1)


def _case(name: str, *, estimate: bool) -> Case:
    case = next(c for c in CASES if c.name == name)
    if not estimate:
        return case
    declared = dict(case.declared or {}) | {"sensor": {"estimate_fall_off": {"order": 2}}}
    return dataclasses.replace(case, declared=declared)


def _calibrate(case: Case, folder: Path):
    project = write_case(case, folder)
    _, _, result = calibrate_project(load_project(project))
    return result, read_truth(project.parent / "truth.json")["lights"][0]


@pytest.fixture(scope="module")
def vignetted(tmp_path_factory: pytest.TempPathFactory):
    folder = tmp_path_factory.mktemp("vignetted")
    return _calibrate(_case("vignetting", estimate=True), folder), folder


def test_undeclared_vignetting_is_estimated_with_the_light(vignetted) -> None:
    (result, truth), folder = vignetted
    assert exit_code(result) == 0, result.warnings
    position, position_sigma, axis, axis_sigma = errors(result, truth)
    assert position < 2e-3 and axis < 0.1
    assert position < 3.0 * position_sigma and axis < 3.0 * axis_sigma
    f = result.fall_off
    assert f is not None and f["order"] == 2
    for c, s, true in zip(f["coefficients"], f["sigma"], VIGNETTING, strict=True):
        assert abs(c - true) < 3.0 * s and s < 0.02
    assert f["corner_value"] == pytest.approx(1.0 + sum(VIGNETTING), abs=3.0 * f["corner_sigma"])
    assert result.parameter_names[-2:] == ["fall_off.c1", "fall_off.c2"]
    # The result file keeps it; the text says it with its sigmas.
    path = folder / "result.json"
    write_result(result_to_file(result), path)
    read = read_result(path).fall_off
    assert read is not None and read["coefficients"] == f["coefficients"]
    assert read["sigma"] == f["sigma"] and read["corner_value"] == f["corner_value"]
    text = fall_off_text(f)
    assert text.startswith("fall-off: radial, V = 1 - 0.25") and "at the corners)" in text


def test_without_vignetting_the_fall_off_is_zero_and_the_pose_unchanged(tmp_path: Path) -> None:
    fixed, truth = _calibrate(_case("clean", estimate=False), tmp_path / "fixed")
    free, _ = _calibrate(_case("clean", estimate=True), tmp_path / "free")
    assert exit_code(fixed) == 0 and exit_code(free) == 0
    f = free.fall_off
    assert f is not None and fixed.fall_off is None
    for c, s in zip(f["coefficients"], f["sigma"], strict=True):
        assert abs(c) < 3.0 * s
    # The pose moves by less than its sigma; the sigma grows (the fall-off is estimated
    # from the same pixels), by at most 1.6x here.
    moved = fixed.lights[0].pose.t_camera_light - free.lights[0].pose.t_camera_light
    sigma_fixed = float(np.linalg.norm(fixed.lights[0].sigma.t_camera_light))
    sigma_free = float(np.linalg.norm(free.lights[0].sigma.t_camera_light))
    assert float(np.linalg.norm(moved)) < sigma_free
    assert sigma_fixed < sigma_free < 1.6 * sigma_fixed
    cos = float(fixed.lights[0].pose.axis_camera @ free.lights[0].pose.axis_camera)
    turned_deg = math.degrees(math.acos(min(cos, 1.0)))
    assert turned_deg < math.degrees(float(np.linalg.norm(free.lights[0].sigma.axis_camera)))
    del truth
