"""Robust losses with `f_scale: auto` (issue 24): the linear loss first, then the robust
loss from its solution with f_scale = c * 1.4826 MAD of its weighted residuals."""

from __future__ import annotations

import json
import math
import sys
from pathlib import Path

import numpy as np
import pytest
from scipy import integrate

from lightcal.cli.main import main
from lightcal.core.problem import ImageData
from lightcal.core.scene import Rig
from lightcal.core.solver import (
    CalibrationModel,
    SolveOutcome,
    SolverOptions,
    auto_f_scale,
    robust_cost,
    run_least_squares,
)
from lightcal.core.solver_options import AUTO_F_SCALE_FACTORS, MAD_TO_SIGMA
from lightcal.core.wall import PlasticWall
from lightcal.errors import InputError
from lightcal.io.project import SensorSpec, SolverSpec
from lightcal.io.project_spec import parse_project
from lightcal.io.result_file import read_result
from lightcal.pipeline.solve import solve
from tests import calib_scenes as cs

CAMERA = cs.small_camera()
ROBUST = ["huber", "soft_l1", "cauchy"]
# psi(u) of each loss at f_scale c (least_squares' rho applied to (u / c)^2).
PSI = {
    "huber": lambda u, c: np.clip(u, -c, c),
    "soft_l1": lambda u, c: u / np.sqrt(1.0 + (u / c) ** 2),
    "cauchy": lambda u, c: u / (1.0 + (u / c) ** 2),
}


def _light_error_m(model: CalibrationModel, x: np.ndarray, reference) -> float:
    """Distance (m) of the first light's position at x from `reference`'s."""
    est = model.layout.rig(x).lights[0]
    return float(np.linalg.norm(est.t_camera_light - reference.t_camera_light))


def _on_bound(model: CalibrationModel, x: np.ndarray) -> bool:
    lo, hi = model.parameter_bounds()
    span = np.where(np.isfinite(hi - lo), hi - lo, 1.0)
    return bool(np.any((x - lo < 1e-6 * span) | (hi - x < 1e-6 * span)))


# ------------------------------------------------------------------------ the constants


@pytest.mark.parametrize("loss", ROBUST)
def test_auto_constants_give_95_percent_efficiency_at_the_gaussian(loss):
    """E[psi']^2 / E[psi^2] for N(0, 1) residuals: 0.95 at each loss's constant (to the
    constants' 4 digits), less for a smaller c and more for a larger one."""

    def efficiency(c: float) -> float:
        psi = PSI[loss]
        h = 1e-6
        gauss = lambda u: math.exp(-0.5 * u * u) / math.sqrt(2 * math.pi)  # noqa: E731
        points = [-c, c] if loss == "huber" else None  # huber's psi' jumps at +-c
        d_psi = integrate.quad(
            lambda u: (psi(u + h, c) - psi(u - h, c)) / (2 * h) * gauss(u), -12, 12, points=points
        )[0]
        psi2 = integrate.quad(lambda u: psi(u, c) ** 2 * gauss(u), -12, 12, points=points)[0]
        return d_psi**2 / psi2

    c = AUTO_F_SCALE_FACTORS[loss]
    assert efficiency(c) == pytest.approx(0.95, abs=2e-4)
    assert efficiency(0.9 * c) < 0.95 < efficiency(1.1 * c)


def test_auto_f_scale_by_hand():
    r = np.array([3.0, -1.0, 0.0, 1.0, 5.0, np.nan])  # median 1; |r - 1| = 2 2 1 0 4: MAD 2
    assert auto_f_scale(r, "huber") == pytest.approx(1.345 * MAD_TO_SIGMA * 2.0, rel=1e-12)
    assert auto_f_scale(r, "cauchy") == pytest.approx(2.385 * MAD_TO_SIGMA * 2.0, rel=1e-12)
    # No spread (an exact fit) or no finite residual: the noise's own scale, c.
    assert auto_f_scale(np.zeros(5), "soft_l1") == AUTO_F_SCALE_FACTORS["soft_l1"]
    assert auto_f_scale(np.full(3, np.nan), "huber") == AUTO_F_SCALE_FACTORS["huber"]


def test_auto_f_scale_of_gaussian_residuals_is_c():
    r = np.random.default_rng(0).normal(size=200_000)
    for loss in ROBUST:
        assert auto_f_scale(r, loss) == pytest.approx(AUTO_F_SCALE_FACTORS[loss], rel=0.01)
        assert auto_f_scale(37.0 * r + 5.0, loss) == pytest.approx(
            37.0 * AUTO_F_SCALE_FACTORS[loss], rel=0.01
        )


def test_robust_cost_of_the_linear_loss_ignores_f_scale():
    r = np.array([1.0, -2.0, 3.0])
    assert robust_cost(r, "linear", "auto") == robust_cost(r, "linear", 7.0) == 7.0
    with pytest.raises(ValueError, match=r"^robust_cost: the huber loss needs a numeric f_scale"):
        robust_cost(r, "huber", "auto")


# ------------------------------------------------------------------------- the options


def test_auto_is_the_default_and_a_number_is_kept():
    assert SolverOptions().f_scale == "auto"
    assert SolverSpec().f_scale == "auto"
    assert SolverSpec(f_scale=2).to_options(SensorSpec()).f_scale == 2.0
    assert SolverSpec(f_scale="auto").to_options(SensorSpec()) == SolverOptions()


@pytest.mark.parametrize("value", ["automatic", "", None, True, [1.0], math.nan, -math.inf])
def test_solver_options_refuse_anything_but_auto_or_a_positive_number(value):
    with pytest.raises(ValueError, match=r'^f_scale: expected "auto" or a finite value > 0, got'):
        SolverOptions(loss="huber", f_scale=value)


def _project_doc(**solver) -> dict:
    """A minimal valid project document (parse_project does not open its files)."""
    return {
        "version": 1,
        "camera": {"fx": 300, "fy": 300, "cx": 160, "cy": 120, "width": 320, "height": 240},
        "images": [{"path": "a.npy", "T_camera_world": {"R": np.eye(3).tolist(), "t": [0, 0, 1]}}],
        "lights": [
            {"name": "led", "rid": {"type": "isotropic"}, "initial": {"position_m": [0, 0, 0]}}
        ],
        "solver": solver,
    }


@pytest.mark.parametrize(
    ("value", "message"),
    [
        (0, 'solver.f_scale: Input should be greater than 0 or "auto", got 0'),
        (-2.5, 'solver.f_scale: Input should be greater than 0 or "auto", got -2.5'),
        ("Auto", "solver.f_scale: Input should be a number > 0 or \"auto\", got 'Auto'"),
        ("2", "solver.f_scale: Input should be a number > 0 or \"auto\", got '2'"),
        (True, 'solver.f_scale: Input should be a number > 0 or "auto", got True'),
        (None, 'solver.f_scale: Input should be a number > 0 or "auto", got None'),
        (math.inf, 'solver.f_scale: Input should be a finite number > 0 or "auto", got inf'),
    ],
)
def test_project_file_f_scale_errors_are_one_line(value, message):
    with pytest.raises(InputError) as info:
        parse_project(_project_doc(loss="huber", f_scale=value), "p.json")
    assert str(info.value) == f"p.json: {message}"  # one problem, not one per form


def test_project_file_reads_auto_and_numbers():
    for value, expected in (("auto", "auto"), (3, 3.0), (0.5, 0.5)):
        solver = parse_project(_project_doc(loss="cauchy", f_scale=value), "p.json").solver
        assert solver.f_scale == expected and isinstance(solver.f_scale, type(expected))
    assert parse_project(_project_doc(), "p.json").solver.f_scale == "auto"


def test_schema_offers_auto_or_a_positive_number():
    from lightcal.io.project_spec import project_schema

    prop = project_schema()["$defs"]["SolverSpec"]["properties"]["f_scale"]
    assert prop["default"] == "auto"
    assert {"type": "number", "exclusiveMinimum": 0} in prop["anyOf"]
    assert {"type": "string", "const": "auto"} in prop["anyOf"]
    assert "1.345 (huber)" in prop["description"]


# ---------------------------------------------------------------- a clean noisy problem


@pytest.fixture(scope="module")
def noisy_problem():
    """12 views, 100 pixels each, Poisson-Gaussian noise, a symmetric light, Lambertian."""
    light = cs.symmetric_light()
    images = cs.observe(
        CAMERA, cs.views(12), Rig.single(light), rng=np.random.default_rng(7), noise=(0.5, 4.0)
    )
    return light, images


@pytest.mark.parametrize("loss", ROBUST)
def test_auto_on_clean_data_picks_about_c(noisy_problem, loss):
    """The residuals are the noise, ~N(0, 1): f_scale ~ c, and the estimate about the
    linear loss's (measured: f_scale / c = 1.02 for each loss; 1.2-1.5 mm from the
    linear solution, which is 3.1 mm from the truth)."""
    light, images = noisy_problem
    start = cs.start_near(light)
    model = cs.model_of(images, [start], loss=loss)
    out = run_least_squares(model)
    assert out.success
    assert out.f_scale_used == pytest.approx(AUTO_F_SCALE_FACTORS[loss], rel=0.1)
    linear_model = cs.model_of(images, [start])
    linear = run_least_squares(linear_model)
    reference = linear_model.layout.rig(linear.x).lights[0]
    assert _light_error_m(model, out.x, reference) < 3e-3
    assert _light_error_m(model, out.x, light) < 0.01


def test_first_iterations_are_the_linear_loss_s(noisy_problem):
    """Iteration 0 and the linear stage report the linear cost; the rest the robust one
    with the chosen f_scale; numbering runs on; the model keeps its options."""
    light, images = noisy_problem
    model = cs.model_of(images, [cs.start_near(light)], loss="cauchy")
    reports = []
    out = run_least_squares(model, on_iteration=reports.append)
    assert model.options.f_scale == "auto" and model.options.loss == "cauchy"
    assert [rep.iteration for rep in reports] == list(range(len(reports)))
    assert out.iterations == reports[-1].iteration
    linear = run_least_squares(cs.model_of(images, [cs.start_near(light)]))
    n_linear = linear.iterations  # the linear stage is that solve's iterations
    for rep in reports[: n_linear + 1]:
        r = model.residuals(rep.x)
        assert rep.cost == pytest.approx(0.5 * float(r @ r), rel=1e-9)
    np.testing.assert_allclose(reports[n_linear].x, linear.x, rtol=0, atol=1e-12)
    for rep in reports[n_linear + 1 :]:
        cost = robust_cost(model.residuals(rep.x), "cauchy", out.f_scale_used)
        assert rep.cost == pytest.approx(cost, rel=1e-9)
    assert out.cost == pytest.approx(reports[-1].cost, rel=1e-9)


def test_compressed_linear_stage_gives_the_same_solve(noisy_problem):
    """With `compress` the linear stage runs on the QR-compressed problem; the robust
    stage (never compressed) and its reported costs are the same."""
    light, images = noisy_problem
    start = cs.start_near(light)
    plain = run_least_squares(cs.model_of(images, [start], loss="huber", compress=False))
    model = cs.model_of(images, [start], loss="huber", compress=True)
    packed = run_least_squares(model)
    assert packed.f_scale_used == pytest.approx(plain.f_scale_used, rel=1e-6)
    np.testing.assert_allclose(packed.x, plain.x, rtol=0, atol=1e-6)
    assert packed.cost == pytest.approx(packed.history[-1].cost, rel=1e-9)
    cost = robust_cost(model.residuals(packed.x), "huber", packed.f_scale_used)
    assert packed.cost == pytest.approx(cost, rel=1e-9)


def test_f_scale_used_is_the_given_one_or_none(noisy_problem):
    light, images = noisy_problem
    start = cs.start_near(light)
    assert (
        run_least_squares(cs.model_of(images, [start], loss="huber", f_scale=3)).f_scale_used == 3
    )
    assert run_least_squares(cs.model_of(images, [start])).f_scale_used is None
    fixed = run_least_squares(cs.model_of(images, [start], loss="huber"), f_scale=2.5)
    assert fixed.f_scale_used == 2.5  # a caller's f_scale for auto (multi-start)


def test_stopped_in_the_linear_stage_has_no_f_scale(noisy_problem):
    light, images = noisy_problem
    model = cs.model_of(images, [cs.start_near(light)], loss="huber")

    def stop_at_2(rep):
        if rep.iteration == 2:
            raise StopIteration

    out = run_least_squares(model, on_iteration=stop_at_2)
    assert out.status == -2 and out.f_scale_used is None
    assert model.options.f_scale == "auto"
    limited = run_least_squares(
        cs.model_of(images, [cs.start_near(light)], loss="huber", max_iterations=2)
    )
    assert limited.status == 0 and limited.f_scale_used is None


def test_reweighted_auto_solve_ends_on_rendered_weights():
    light = cs.symmetric_light()
    images = cs.observe(
        CAMERA, cs.views(12), Rig.single(light), rng=np.random.default_rng(5), noise=(0.5, 4.0),
        noise_model=True,
    )  # fmt: skip
    model = cs.model_of(images, [cs.start_near(light)], loss="soft_l1")
    out = run_least_squares(model)
    assert out.success and out.weights_at is not None and out.history[-1].reweighted
    assert out.f_scale_used == pytest.approx(AUTO_F_SCALE_FACTORS["soft_l1"], rel=0.1)
    assert _light_error_m(model, out.x, light) < 0.01


def test_multistart_keeps_the_first_start_s_f_scale(noisy_problem, monkeypatch):
    """Costs compare only under one f_scale: every start uses the first one's."""
    light, images = noisy_problem
    model = cs.model_of(images, [cs.start_near(light)], loss="huber")
    first = run_least_squares(model)
    seen: list[SolveOutcome] = []
    module = sys.modules["lightcal.pipeline.solve"]  # `lightcal.pipeline.solve` is `solve`

    def spy(*args, **kwargs):
        out = run_least_squares(*args, **kwargs)
        seen.append(out)
        return out

    monkeypatch.setattr(module, "run_least_squares", spy)
    best = solve(model, multistart=2, seed=1)
    assert len(seen) == 3
    assert {out.f_scale_used for out in seen} == {first.f_scale_used}
    assert best.f_scale_used == first.f_scale_used


# --------------------------------------------------------------- a systematic model error


@pytest.fixture(scope="module")
def glossy_problem():
    """A glossy (plastic) wall fitted as Lambertian, with noise so small that the misfit is
    ~200 noise sigmas (MAD of the linear fit's weighted residuals; real photos: ~140)."""
    light = cs.symmetric_light()
    images = cs.observe(
        CAMERA, cs.views(12), Rig.single(light), rng=np.random.default_rng(7), noise=(1e-5, 1e-5),
        wall=PlasticWall.from_albedo(0.3, 1.5, 0.8),
    )  # fmt: skip
    start = cs.start_near(light)
    model = cs.model_of(images, [start])
    linear = run_least_squares(model)
    assert linear.success
    r = model.residuals(linear.x)
    assert MAD_TO_SIGMA * np.median(np.abs(r - np.median(r))) > 100
    return images, start, model.layout.rig(linear.x).lights[0]


@pytest.mark.parametrize("loss", ROBUST)
def test_auto_stays_by_the_linear_solution_under_model_error(glossy_problem, loss):
    """Measured: 3.6-3.9 mm from the linear solution in 11 iterations (6 linear), f_scale
    283 (huber), 271 (soft_l1), 503 (cauchy) noise sigmas."""
    images, start, linear = glossy_problem
    model = cs.model_of(images, [start], loss=loss)
    out = run_least_squares(model)
    assert out.success and out.iterations <= 20
    assert out.f_scale_used is not None and out.f_scale_used > 100 * AUTO_F_SCALE_FACTORS[loss]
    assert _light_error_m(model, out.x, linear) < 0.006
    assert not _on_bound(model, out.x)


def test_f_scale_of_one_sigma_fails_under_model_error(glossy_problem):
    """Every pixel an outlier: huber with f_scale = 1 sigma fits ~L1 with a poor quadratic
    model. Measured: 100 iterations without converging (it needs ~240), 21 mm from the
    linear solution; auto: 11 iterations, 3.6 mm. (Cauchy at 1 sigma: 68 mm.)"""
    images, start, linear = glossy_problem
    auto_model = cs.model_of(images, [start], loss="huber")
    auto = run_least_squares(auto_model)
    one_model = cs.model_of(images, [start], loss="huber", f_scale=1.0)
    one = run_least_squares(one_model)
    assert one.status == 0  # the iteration limit
    assert _light_error_m(one_model, one.x, linear) > 3 * _light_error_m(auto_model, auto.x, linear)


# --------------------------------------------------------------------------- outliers


@pytest.mark.parametrize("loss", ROBUST)
@pytest.mark.parametrize("seed", [7, 8])
def test_auto_down_weights_saturated_pixels(loss, seed):
    """3 % of each image's pixels read 4000 (4 x the brightest: a clipped glint). Measured
    (seeds 7, 8): linear 0.54 and 0.60 m off; auto 2.2-7.0 mm."""
    light = cs.symmetric_light()
    images = cs.observe(
        CAMERA, cs.views(12), Rig.single(light), rng=np.random.default_rng(seed), noise=(0.5, 4.0)
    )
    rng = np.random.default_rng(seed + 100)
    dirty = []
    for im in images:
        observed = im.observed.copy()
        observed[rng.choice(observed.size, size=round(0.03 * observed.size), replace=False)] = 4e3
        dirty.append(ImageData(im.name, im.view, im.footprints, observed, im.sigma))
    start = cs.start_near(light)
    linear_model = cs.model_of(dirty, [start])
    linear = run_least_squares(linear_model)
    model = cs.model_of(dirty, [start], loss=loss)
    out = run_least_squares(model)
    assert out.success
    robust_err = _light_error_m(model, out.x, light)
    assert robust_err < 0.01
    assert robust_err < 0.1 * _light_error_m(linear_model, linear.x, light)


# ---------------------------------------------------------------------------- the CLI


@pytest.fixture(scope="module")
def npy_project(tmp_path_factory) -> Path:
    """Noise-free float images of 6 views (160 x 120), one symmetric light."""
    light = cs.symmetric_light()
    return cs.write_npy_project(
        tmp_path_factory.mktemp("robust_cli"),
        cs.small_camera(width=160, height=120),
        cs.views(6, seed=2),
        Rig.single(light),
        initial=[cs.start_near(light)],
        rid_specs=[{"type": "half_angle", "half_angle_deg": 30}],
        extra={"selection": {"n_per_image": 80, "min_signal": 1.0}},
    )


@pytest.mark.parametrize(
    ("f_scale", "expected"),
    [("auto", "(auto, from the linear solve's residuals)"), (2.0, "f_scale = 2 (given)")],
)
def test_cli_prints_the_f_scale(npy_project: Path, tmp_path: Path, capsys, f_scale, expected):
    doc = json.loads(npy_project.read_text())
    doc["solver"] = {"loss": "huber", "f_scale": f_scale}
    project = npy_project.parent / f"robust_{tmp_path.name}.json"
    project.write_text(json.dumps(doc))
    argv = ["calibrate", str(project), "--out", str(tmp_path / "r.json"), "--allow-misfit"]
    code = main([*argv, "--quiet"])
    said = capsys.readouterr()
    err = " ".join(said.out.split())  # the command's answer: stdout
    assert code == 0, said.err
    assert "robust loss huber: f_scale = " in err and expected in err
    used = read_result(tmp_path / "r.json").f_scale_used
    assert used is not None and f"f_scale = {used:.4g} " in err
