"""Capture planning (lightcal.pipeline.plan): the predicted covariance, the greedy choice,
`lightcal plan`. Small synthetic problems (~150 pixels per image) from tests/calib_scenes."""

from __future__ import annotations

import json

import numpy as np
import pytest

from lightcal.core.problem import LightUnknown
from lightcal.core.solver import CalibrationModel, SolverOptions
from lightcal.pipeline.plan import (
    InformationState,
    PlanGrid,
    candidate_image,
    candidate_view,
    greedy_plan,
    plan_views,
    typical_peak,
)
from tests import calib_scenes as cs

GRID = PlanGrid(pixels_per_view=150, distances_m=(0.9, 1.8), tilts_deg=(0.0, 30.0))


def _problem(n_views: int = 3, *, estimate_gains: bool = False, views=None):
    camera = cs.small_camera()
    light = cs.symmetric_light()
    images = cs.observe(
        camera,
        views or cs.views(n_views, seed=3),
        cs.Rig((light,)),
        n_per_image=150,
        rng=np.random.default_rng(0),
    )
    # Noise-free values with the noise model's sigma: s^2 = 1 is exact.
    images = [
        cs.ImageData(im.name, im.view, im.footprints, im.observed, np.sqrt(im.observed + 4.0))
        for im in images
    ]
    model = CalibrationModel(
        images, [LightUnknown(light)], SolverOptions(estimate_gains=estimate_gains)
    )
    return camera, light, model, model.layout.x0.copy()


@pytest.mark.parametrize("estimate_gains", [False, True])
def test_predicted_covariance_is_the_solvers_after_adding_the_view(estimate_gains):
    camera, _light, model, x = _problem(estimate_gains=estimate_gains)
    state = InformationState(model, x)
    view = candidate_view(1.3, 30.0, 45.0, 90.0, np.zeros(3)).view
    image = candidate_image(model, x, camera, view, GRID, peak=typical_peak(model, x))
    assert image is not None
    predicted = np.linalg.inv(state.view_information(image))
    bigger = CalibrationModel([*model.images, image], model.unknowns, model.options)
    x_big = np.concatenate([x, [0.0]]) if estimate_gains else x
    # The extended layout puts the new gain among the gains: map by names.
    names = bigger.layout.names
    order = [*model.layout.names, *[nm for nm in names if nm not in model.layout.names]]
    x_big = np.array([dict(zip(order, x_big, strict=True))[nm] for nm in names])
    assert np.abs(bigger.residuals(x_big)).max() < 1e-9  # the data at the truth
    actual = np.linalg.inv(bigger.normal_matrix(x_big))
    idx = [order.index(nm) for nm in names]
    predicted = predicted[np.ix_(idx, idx)]
    pose = np.arange(5)
    rel = np.abs(predicted[np.ix_(pose, pose)] - actual[np.ix_(pose, pose)]).max()
    assert rel / np.abs(actual[np.ix_(pose, pose)]).max() < 1e-6
    assert state.sigmas(state.view_information(image)).position_m[0] < state.sigmas().position_m[0]


def test_greedy_prefers_an_informative_view_over_a_redundant_one():
    # Three views from about 1 m, nearly square to the wall: the distance and the angle
    # variety are missing. Another such view is redundant; one from 2.4 m, tilted 35 deg,
    # adds what they lack.
    similar = [candidate_view(1.0 + 0.05 * k, 5.0, 120.0 * k, 0.0, np.zeros(3)) for k in range(3)]
    camera, _light, model, x = _problem(views=[c.view for c in similar])
    state = InformationState(model, x)
    redundant = candidate_view(1.05, 5.0, 60.0, 0.0, np.zeros(3))
    informative = candidate_view(2.4, 35.0, 200.0, 0.0, np.zeros(3))
    pool = [redundant, informative]
    peak = typical_peak(model, x)
    images = [candidate_image(model, x, camera, c.view, GRID, peak=peak) for c in pool]
    assert all(im is not None and len(im.observed) == 150 for im in images)
    chosen = greedy_plan(state, images, pool, 2)
    assert [pv.candidate for pv in chosen] == [informative, redundant]
    assert chosen[0].after.position_m[0] < 0.8 * chosen[0].before.position_m[0]
    assert chosen[1].before == chosen[0].after


@pytest.fixture(scope="module")
def project(tmp_path_factory):
    folder = tmp_path_factory.mktemp("plan_project")
    camera = cs.small_camera(width=160, height=120)
    light = cs.symmetric_light()
    return cs.write_npy_project(
        folder,
        camera,
        cs.views(3, seed=2),
        cs.Rig((light,)),
        initial=[cs.start_near(light)],
        rid_specs=[{"type": "half_angle", "half_angle_deg": 30}],
        extra={"selection": {"n_per_image": 80, "min_signal": 1.0}},
    )


def test_plan_views_of_a_project_shrink_the_sigmas(project):
    from lightcal.io.project import load_project
    from lightcal.pipeline import build_model, load_images

    p = load_project(project)
    loaded = load_images(p)
    model = build_model(p, loaded)
    grid = PlanGrid(pixels_per_view=100, distances_m=(0.9, 1.8), tilts_deg=(0.0, 30.0))
    current, planned = plan_views(model, model.layout.x0, loaded.camera, n=2, grid=grid)
    assert len(planned) == 2
    assert planned[0].after.position_m[0] < current.position_m[0]
    assert planned[1].before == planned[0].after
    assert planned[1].after.log_det < planned[0].after.log_det


def test_cli_writes_plan_and_refuses_to_overwrite(project, tmp_path, capsys):
    from lightcal.cli.main import main

    out = tmp_path / "plan.json"
    assert main(["plan", str(project), "--n", "1", "--out", str(out)]) == 0
    plan = json.loads(out.read_text())
    assert len(plan["views"]) == 1 and plan["views"][0]["rank"] == 1
    assert "m from the wall" in plan["views"][0]["instruction"]
    assert "after:" in capsys.readouterr().err
    before = out.read_text()
    assert main(["plan", str(project), "--n", "1", "--out", str(out)]) == 2
    assert capsys.readouterr().err == (
        f"lightcal plan: error: {out}: --out: exists; use --force to replace it\n"
    )
    # Never over an input of the project (the common output checks of every command).
    assert main(["plan", str(project), "--out", str(project), "--force"]) == 2
    assert capsys.readouterr().err == (
        f"lightcal plan: error: {project}: --out: is the project file, an input of the "
        "project; write elsewhere\n"
    )
    assert out.read_text() == before
    assert main(["plan", str(project), "--n", "1", "--out", str(out), "--force"]) == 0


def test_cli_project_without_usable_images(project, tmp_path, capsys):
    from lightcal.cli.main import main

    doc = json.loads(project.read_text())
    doc["selection"]["min_signal"] = 1e9
    dark = project.with_name("dark.json")
    dark.write_text(json.dumps(doc))
    assert main(["plan", str(dark)]) == 2
    assert capsys.readouterr().err == (
        f"lightcal plan: error: {dark}: no usable pixels in any image (all saturated, masked, "
        "below the noise floor or off the wall); check the selection and sensor settings\n"
    )


def test_cli_plans_from_a_result(project, tmp_path, capsys):
    from lightcal.cli.main import main
    from lightcal.io.project import load_project
    from lightcal.io.result_file import result_to_file, write_result
    from lightcal.pipeline import calibrate_project

    _, _, cal = calibrate_project(load_project(project))
    result = tmp_path / "result.json"
    write_result(result_to_file(cal, project=project), result)
    out = tmp_path / "plan.json"
    assert main(["plan", str(project), "--result", str(result), "--n", "1", "--out", str(out)]) == 0
    plan = json.loads(out.read_text())
    after = plan["views"][0]["after"][0]
    assert after["position_sigma_m"] < plan["current"][0]["position_sigma_m"]
    capsys.readouterr()
    # A result of another project (its parameters do not match) is refused.
    doc = json.loads(result.read_text())
    doc["parameters"]["names"] = ["other." + nm for nm in doc["parameters"]["names"]]
    result.write_text(json.dumps(doc))
    assert main(["plan", str(project), "--result", str(result)]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"lightcal plan: error: {result}: parameters light.x_m, ")
    assert err.endswith("are not in the result: solve this project\n")


def test_sigmas_before_a_solve_are_in_mm_from_the_images_noise(tmp_path, capsys):
    """Before any solve the plan weighs the pixels by the noise each image shows (a synth
    dataset with Poisson-Gaussian noise): its sigma is within 20 % of the one the solved
    estimate gives, in mm and deg (not in units of a 1-DN pixel noise)."""
    from lightcal.cli.main import main

    folder = tmp_path / "data"
    argv = ["synth", str(folder), "--views", "6", "--width", "160", "--height", "120"]
    assert main([*argv, "--quiet"]) == 0
    project = folder / "project.json"
    doc = json.loads(project.read_text())
    del doc["sensor"]["noise"]  # unknown sensor: the noise is estimated from the images
    project.write_text(json.dumps(doc))
    before, after, result = tmp_path / "before.json", tmp_path / "after.json", tmp_path / "r.json"
    assert main(["plan", str(project), "--n", "1", "--out", str(before)]) == 0
    assert "noise: estimated from each image" in capsys.readouterr().err
    assert main(["calibrate", str(project), "--out", str(result), "--quiet"]) == 0
    assert (
        main(["plan", str(project), "--result", str(result), "--n", "1", "--out", str(after)]) == 0
    )
    pre = json.loads(before.read_text())["current"][0]
    post = json.loads(after.read_text())["current"][0]
    assert 0.8 < pre["position_sigma_m"] / post["position_sigma_m"] < 1.25
    assert 0.8 < pre["axis_sigma_deg"] / post["axis_sigma_deg"] < 1.25
