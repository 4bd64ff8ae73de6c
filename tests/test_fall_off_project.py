"""`sensor.estimate_fall_off` from the project file to the result: the key's errors, the
option it builds, and the acceptance on `lightcal synth` data (tests/departure_suite.py:
12 views of a 480 x 360 camera with realistic noise, 400 pixels an image): with undeclared
vignetting of the issue's size (1 - 0.25 r^2 + 0.05 r^4) the light lands within 2 mm and
0.1 deg and the coefficients within their sigma; without vignetting the coefficients are
0 within their sigma and the pose moves by less than its sigma."""

from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path

import numpy as np
import pytest

from lightcal.core.fall_off import FallOffUnknown
from lightcal.core.problem import ImageData, LightUnknown, poisson_gaussian_sigma
from lightcal.core.scene import Rig
from lightcal.core.solver import CalibrationModel, SolverOptions
from lightcal.core.vignetting import RadialVignetting
from lightcal.errors import InputError
from lightcal.io.project import load_project
from lightcal.io.result_file import read_result, result_to_file, write_result
from lightcal.pipeline import calibrate_project
from lightcal.pipeline.fall_off_result import (
    LOOSE_CORNER_SIGMA,
    fall_off_problems,
    fall_off_summary,
    fall_off_text,
)
from lightcal.synthetic.dataset import SynthConfig, read_truth, write_dataset
from lightcal.synthetic.departures import Departures
from lightcal.synthetic.views import SceneConfig
from tests import calib_scenes as cs
from tests.departure_suite import CASES, Case, camera, errors, exit_code, write_case
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


def test_views_at_one_distance_facing_the_wall_leave_the_fall_off_loose(tmp_path: Path) -> None:
    """The light sits 10 cm from the camera: in views all at one distance, facing the
    wall, the beam's fall-off across the image and V are nearly the same radial pattern.
    Estimated, the fall-off widens the pose's sigma instead of biasing it, and says so;
    not estimated, the pose is 109 mm off with a 2.2 mm sigma (measured)."""
    config = SynthConfig(
        camera=camera(),
        seed=5,
        scene=SceneConfig(distance_range_m=(1.5, 1.5), tilt_range_deg=(0.0, 0.0)),
        departures=Departures(undeclared_vignetting=VIGNETTING),
    )
    ds = write_dataset(tmp_path / "facing", config)
    doc = json.loads(ds.project_path.read_text())
    doc["selection"]["n_per_image"] = 400
    doc["sensor"]["estimate_fall_off"] = {"order": 2}
    ds.project_path.write_text(json.dumps(doc))
    _, _, result = calibrate_project(load_project(ds.project_path))
    truth = read_truth(ds.truth_path)["lights"][0]
    position, position_sigma, axis, axis_sigma = errors(result, truth)
    # Measured: 21 mm (sigma 26 mm), 0.17 deg (0.30); corner sigma 0.037.
    assert position < 2.0 * position_sigma and axis < 2.0 * axis_sigma
    assert position_sigma > 10e-3
    f = result.fall_off
    assert f is not None and f["corner_sigma"] > LOOSE_CORNER_SIGMA
    assert any(w.startswith("the camera's fall-off is loosely determined") for w in result.warnings)


def test_view_variety_decides_how_much_the_fall_off_costs() -> None:
    """The pixel-noise sigma of the position with the fall-off estimated over the one
    with V known (12 views, 400 pixels each, at the truth): 1.16x with distances
    0.8-2.5 m and tilts 0-35 deg, 1.35x at one distance with tilts, 12x at one
    distance facing the wall (measured)."""

    def ratio(distance_m: tuple[float, float], tilt_deg: tuple[float, float]) -> float:
        views = cs.views(12, distance_range_m=distance_m, tilt_range_deg=tilt_deg, seed=0)
        light = cs.symmetric_light()
        clean = cs.observe(camera(), views, Rig.single(light), n_per_image=400,
                           rng=np.random.default_rng(1))  # fmt: skip
        images = [
            ImageData(im.name, im.view, im.footprints, im.observed,
                      poisson_gaussian_sigma(im.observed, (0.5, 4.0)))
            for im in clean
        ]  # fmt: skip
        sigmas = []
        for fall_off in (None, FallOffUnknown(2, camera().width, camera().height)):
            model = CalibrationModel(
                images,
                [LightUnknown(light)],
                SolverOptions(fall_off=fall_off, estimate_ambient=False),
            )
            C = np.linalg.inv(model.normal_matrix(model.layout.x0))
            sigmas.append(math.sqrt(np.trace(C[:3, :3])))
        return sigmas[1] / sigmas[0]

    assert 1.0 < ratio((0.8, 2.5), (0.0, 35.0)) < 1.3
    assert 1.0 < ratio((1.5, 1.5), (0.0, 35.0)) < 1.6
    assert ratio((1.5, 1.5), (0.0, 0.01)) > 5.0


def test_a_fall_off_no_lens_has_makes_the_result_undetermined() -> None:
    light = cs.symmetric_light()
    images = cs.observe(cs.small_camera(), cs.views(3), Rig.single(light), n_per_image=50,
                        rng=np.random.default_rng(2))  # fmt: skip
    f = FallOffUnknown(2, cs.small_camera().width, cs.small_camera().height)
    options = SolverOptions(fall_off=f, estimate_ambient=False)
    model = CalibrationModel(images, [LightUnknown(light)], options)
    x = model.layout.x0.copy()
    cov = np.eye(model.layout.n) * 1e-6
    assert fall_off_problems(model, x, fall_off_summary(model, x, cov)) == []
    x[model.layout.fall_off] = [-1.5, 0.2]  # V = -0.3 at the corners
    (problem,) = fall_off_problems(model, x, fall_off_summary(model, x, cov))
    assert problem.startswith(
        "the data do not determine the camera's fall-off (the fall-off reaches -0.3 to 1 "
        "over the image), so neither the light's pose found with it"
    )
    x[model.layout.fall_off] = [-0.2, 0.0]
    cov[-1, -1] = np.nan  # an undetermined sigma
    (problem,) = fall_off_problems(model, x, fall_off_summary(model, x, cov))
    assert "(its sigma is undetermined)" in problem


def test_room_light_and_vignetting_together(tmp_path: Path) -> None:
    """Both departures at once, both terms estimated: measured 0.70 mm and 0.020 deg,
    c = -0.250 +- 0.005, 0.047 +- 0.005 (with the fall-off alone the fit test names
    `ambient`, 120 mm off; with the room light alone `vignetting`, 64 mm off)."""
    both = {"sensor": {"estimate_ambient": True, "estimate_fall_off": {"order": 2}}}
    departures = Departures(ambient_fraction=0.05, undeclared_vignetting=VIGNETTING)
    result, truth = _calibrate(Case("both", None, departures, declared=both), tmp_path)
    assert exit_code(result) == 0, result.warnings
    position, position_sigma, axis, axis_sigma = errors(result, truth)
    assert position < 2e-3 and axis < 0.1
    assert position < 3.0 * position_sigma and axis < 3.0 * axis_sigma
    f = result.fall_off
    assert f is not None
    for c, s, true in zip(f["coefficients"], f["sigma"], VIGNETTING, strict=True):
        assert abs(c - true) < 3.0 * s
    assert result.ambient is not None and result.ambient_sigma is not None
    assert result.ambient > 10.0 * result.ambient_sigma


def test_render_applies_the_estimated_fall_off(vignetted) -> None:
    """`lightcal render` (the API's `render`) draws the result's fall-off: the render with
    it over the one without is V of its coefficients, pixel by pixel (offset 0)."""
    from lightcal import api

    (result, _), folder = vignetted
    file = result_to_file(result)
    with_v = api.render(folder / "project.json", file, notify=None)
    without = api.render(folder / "project.json", file.model_copy(update={"fall_off": None}),
                         notify=None)  # fmt: skip
    project = load_project(folder / "project.json")
    f = result.fall_off
    assert f is not None and result.offset == 0.0
    v = RadialVignetting.centered(
        f["coefficients"], width=project.camera.width, height=project.camera.height
    ).image()
    for a, b in zip(with_v, without, strict=True):
        lit = ~np.ma.getmaskarray(b) & (np.ma.filled(b, 0.0) > 0.0)
        np.testing.assert_allclose(a[lit] / b[lit], v[lit], rtol=1e-6)
    bad = file.model_copy(update={"fall_off": {"coefficients": "none"}})
    with pytest.raises(InputError) as info:
        api.render(folder / "project.json", bad, notify=None)
    assert str(info.value) == (
        "the result: fall_off.coefficients: expected a list of 1 to 3 numbers, got 'none'"
    )


@pytest.mark.parametrize(
    ("name", "key"),
    [
        ("vignetting", "`sensor.estimate_fall_off: {order: 2}`"),
        ("room light", "`sensor.estimate_ambient: true`"),
    ],
)
def test_the_fit_test_names_the_key_that_models_the_departure(
    tmp_path: Path, name: str, key: str
) -> None:
    result, _ = _calibrate(_case(name, estimate=False), tmp_path)
    (finding, *_) = result.fit["findings"]
    assert key in finding, finding


def test_a_dense_binned_selection_recovers_the_fall_off(tmp_path: Path) -> None:
    """Every pixel in 4 x 4 super-pixels (129,600 in all): V is taken at each
    super-pixel's centre in the full image. Measured: c = -0.2531 +- 0.0031,
    0.0512 +- 0.0013, 1.13 mm (sigma 1.28, mostly the camera poses'), 0.015 deg;
    binning 2 (518,400 pixels) gives the same to 1e-5."""
    case = _case("vignetting", estimate=True)
    dense = {**(case.declared or {}), "selection": {"strategy": "all", "binning": 4}}
    result, truth = _calibrate(dataclasses.replace(case, declared=dense), tmp_path)
    assert exit_code(result) == 0, result.warnings
    assert sum(result.pixels_used) > 100_000
    position, position_sigma, axis, axis_sigma = errors(result, truth)
    assert position < 2e-3 and axis < 0.1
    assert position < 3.0 * position_sigma and axis < 3.0 * axis_sigma
    f = result.fall_off
    assert f is not None
    for c, s, true in zip(f["coefficients"], f["sigma"], VIGNETTING, strict=True):
        assert abs(c - true) < 3.0 * s and s < 0.005


def test_the_fall_off_follows_the_grid_the_images_are_read_on(folder) -> None:
    """A raw reader that bins 2 x 2 gives images of the camera binned: r is measured on
    that grid (its centre and half diagonal are the sensor's), so the model's fall-off
    takes the images' size."""
    from lightcal.pipeline.load import LoadedImages
    from lightcal.pipeline.model import solver_options

    doc = _doc()
    doc["sensor"] = {"estimate_fall_off": {"order": 2}}
    project = load_project(_write(folder, doc))
    cam = project.camera
    same = solver_options(project, LoadedImages([], [], cam))
    assert same is project.solver
    binned = solver_options(project, LoadedImages([], [], cam.binned(2))).fall_off
    assert binned is not None
    assert (binned.width, binned.height) == (cam.width // 2, cam.height // 2)
    # The super-pixel (0, 0) of the binned grid is the full sensor's pixel (0.5, 0.5):
    # the same r either way.
    full = project.solver.fall_off
    assert full is not None
    corner = full.r2(np.array([[0.5, 0.5]]))
    np.testing.assert_allclose(binned.r2(np.array([[0, 0]])), corner, rtol=1e-12)
