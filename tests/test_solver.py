"""The calibration solver: residuals, analytic Jacobian, bounds, losses, iteration reports."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest

from lightcal.core import calibration_model
from lightcal.core.problem import ImageData, LightUnknown
from lightcal.core.qr_factors import economic_r, stack_r_factors
from lightcal.core.render import shade
from lightcal.core.scene import Rig
from lightcal.core.solver import (
    CONVERGED_AHEAD,
    CalibrationModel,
    IterationReport,
    SolverOptions,
    run_least_squares,
)
from tests import calib_scenes as cs

CAMERA = cs.small_camera()


def _numeric_jacobian(model: CalibrationModel, x: np.ndarray) -> np.ndarray:
    """Central differences of the weighted residuals, step 1e-6 relative."""
    J = np.zeros((model.m, x.size))
    for k in range(x.size):
        h = 1e-6 * max(1.0, abs(x[k]))
        xp, xm = x.copy(), x.copy()
        xp[k] += h
        xm[k] -= h
        J[:, k] = (model.residuals(xp) - model.residuals(xm)) / (2 * h)
    return J


def _three_views():
    return cs.views(3, seed=2)


def _jacobian_case(name: str) -> tuple[Rig, list[LightUnknown], dict]:
    sym = cs.symmetric_light()
    gen = cs.general_light()
    iso = cs.isotropic_light()
    two = cs.two_light_rig()
    cases: dict[str, tuple[Rig, list[LightUnknown], dict]] = {
        "symmetric_gains_offset": (
            Rig.single(sym),
            [LightUnknown(cs.start_near(sym))],
            {"estimate_gains": True, "estimate_offset": True, "offset": 3.0},
        ),
        "isotropic": (
            Rig.single(iso),
            [LightUnknown(cs.start_near(iso), pose_kind="isotropic")],
            {},
        ),
        "general": (Rig.single(gen), [LightUnknown(cs.start_near(gen))], {}),
        "general_subsampled": (
            Rig.single(gen),
            [LightUnknown(cs.start_near(gen))],
            {"rid_subsamples": 3},
        ),
        "symmetric_as_general": (
            Rig.single(sym),
            [LightUnknown(cs.start_near(sym), pose_kind="general")],
            {},
        ),
        "cos_power": (
            Rig.single(sym),
            [LightUnknown(cs.start_near(sym), estimate_rid="cos_power")],
            {},
        ),
        "curve": (
            Rig.single(sym),
            [LightUnknown(cs.start_near(sym), estimate_rid="curve", curve_knots=4)],
            {},
        ),
        "two_lights_gains": (
            two,
            [LightUnknown(cs.start_near(light)) for light in two.lights],
            {"estimate_gains": True},
        ),
    }
    return cases[name]


@pytest.mark.parametrize(
    "case",
    [
        "symmetric_gains_offset",
        "isotropic",
        "general",
        "general_subsampled",
        "symmetric_as_general",
        "cos_power",
        "curve",
        "two_lights_gains",
    ],
)
def test_jacobian_matches_finite_differences(case):
    rig, unknowns, options = _jacobian_case(case)
    images = cs.observe(
        CAMERA, _three_views(), rig, n_per_image=40, rng=np.random.default_rng(1), noise=(0.5, 4.0)
    )
    model = CalibrationModel(images, unknowns, SolverOptions(**options))
    x = model.layout.x0.copy()
    J = model.jacobian(x)
    Jn = _numeric_jacobian(model, x)
    assert J.shape == (model.m, model.layout.n)
    for k, name in enumerate(model.layout.names):
        scale = np.abs(Jn[:, k]).max()
        assert scale > 0.0, name
        assert np.abs(J[:, k] - Jn[:, k]).max() <= 1e-6 * scale, name


def test_residuals_are_weighted_differences():
    light = cs.symmetric_light()
    images = cs.observe(
        CAMERA, _three_views(), Rig.single(light), n_per_image=30, rng=np.random.default_rng(4),
        noise=(0.8, 9.0),
    )  # fmt: skip
    start = cs.start_near(light)
    model = cs.model_of(images, [start], estimate_gains=True, offset=2.0)
    x = model.layout.x0.copy()
    x[model.layout.gains] = np.log([1.5, 0.5])
    r = model.residuals(x)
    gains = [1.0, 1.5, 0.5]
    for i, im in enumerate(images):
        rendered = 2.0 + gains[i] * shade(im.footprints, im.view, Rig.single(start)).values
        expected = (im.observed - rendered) / im.sigma
        np.testing.assert_allclose(r[model.bounds[i] : model.bounds[i + 1]], expected, rtol=1e-12)
    rms = model.per_image_rms(x)
    for i, im in enumerate(images):
        d = r[model.bounds[i] : model.bounds[i + 1]] * im.sigma
        assert rms[i] == pytest.approx(math.sqrt(np.mean(d**2)), rel=1e-12)


# ---------------------------------------------------------------------- options, errors


@pytest.mark.parametrize(
    ("options", "message"),
    [
        ({"loss": "l2"}, r"^loss: expected one of linear, huber, soft_l1, cauchy, got 'l2'$"),
        ({"f_scale": 0.0}, r'^f_scale: expected "auto" or a finite value > 0, got 0.0$'),
        ({"f_scale": math.inf}, r'^f_scale: expected "auto" or a finite value > 0, got inf$'),
        ({"f_scale": "huber"}, r"^f_scale: expected \"auto\" or a finite value > 0, got 'huber'$"),
        ({"max_iterations": 0}, r"^max_iterations: expected >= 1, got 0$"),
        ({"compress": 0}, r"^compress: expected true, false or null, got 0$"),
    ],
)
def test_solver_option_errors(options, message):
    with pytest.raises(ValueError, match=message):
        SolverOptions(**options)


def test_model_needs_images_and_lights():
    light = cs.symmetric_light()
    images = cs.observe(CAMERA, _three_views(), Rig.single(light), rng=np.random.default_rng(0))
    with pytest.raises(ValueError, match=r"^calibration: expected at least one image"):
        CalibrationModel([], [LightUnknown(light)], SolverOptions())
    with pytest.raises(ValueError, match=r"^calibration: expected at least one light$"):
        CalibrationModel(images, [], SolverOptions())


# ---------------------------------------------------------------------- solves, reports


@pytest.fixture(scope="module")
def noisy_problem():
    """12 views, 100 pixels each, Poisson-Gaussian noise, a symmetric light."""
    light = cs.symmetric_light()
    images = cs.observe(
        CAMERA, cs.views(12), Rig.single(light), rng=np.random.default_rng(7), noise=(0.5, 4.0)
    )
    return light, images


def test_noise_free_solve_recovers_the_truth():
    light = cs.symmetric_light()
    images = cs.observe(CAMERA, cs.views(12), Rig.single(light), rng=np.random.default_rng(3))
    model = cs.model_of(images, [cs.start_near(light)])
    out = run_least_squares(model)
    assert out.success and out.status > 0
    est = model.layout.rig(out.x).lights[0]
    position_err, axis_err = cs.pose_errors(est, light)
    assert position_err < 1e-9
    assert axis_err < 1e-6
    assert est.scale == pytest.approx(light.scale, rel=1e-9)
    assert out.cost < 1e-12


def test_iteration_reports(noisy_problem):
    light, images = noisy_problem
    model = cs.model_of(images, [cs.start_near(light)])
    seen: list[IterationReport] = []
    out = run_least_squares(model, on_iteration=seen.append)
    assert seen == out.history
    assert [rep.iteration for rep in seen] == list(range(len(seen)))
    assert out.iterations == seen[-1].iteration >= 3
    np.testing.assert_array_equal(seen[0].x, model.layout.x0)
    costs = [rep.cost for rep in seen]
    assert all(b <= a for a, b in itertools.pairwise(costs))
    assert [rep.nfev for rep in seen] == sorted(rep.nfev for rep in seen)
    for rep in (seen[0], seen[-1]):
        r = model.residuals(rep.x)
        J = model.jacobian(rep.x)
        assert rep.cost == pytest.approx(0.5 * r @ r, rel=1e-12)
        assert rep.gradient_norm == pytest.approx(np.abs(J.T @ r).max(), rel=1e-12)
        np.testing.assert_allclose(rep.per_image_rms, model.per_image_rms(rep.x), rtol=1e-12)
        assert rep.per_image_rms.shape == (12,)
    # Converged: the gradient is tiny compared with the start's, the cost is chi^2 / 2.
    assert seen[-1].gradient_norm < 1e-6 * seen[0].gradient_norm
    assert out.cost == pytest.approx(seen[-1].cost, rel=1e-12)


def test_poisson_gaussian_weights_give_unit_variance_residuals(noisy_problem):
    light, images = noisy_problem
    model = cs.model_of(images, [light])
    # At the truth the weighted residuals are standard normal: 2 cost / m ~ 1 +- sqrt(2 / m).
    r = model.residuals(model.layout.x0)
    assert np.mean(r**2) == pytest.approx(1.0, abs=4 * math.sqrt(2 / model.m))
    # The sigmas follow the noise model: sigma^2 = 0.5 * signal + 4.
    im = images[0]
    np.testing.assert_allclose(im.sigma**2, 0.5 * np.maximum(im.observed, 0) + 4.0)
    out = run_least_squares(cs.model_of(images, [cs.start_near(light)]))
    dof = model.m - model.layout.n
    assert 2 * out.cost / dof == pytest.approx(1.0, abs=4 * math.sqrt(2 / dof))


def test_max_iterations_stops_the_solve(noisy_problem):
    light, images = noisy_problem
    model = cs.model_of(images, [cs.start_near(light)], max_iterations=2)
    out = run_least_squares(model)
    assert out.status == 0
    assert not out.success
    assert out.message == "stopped after the maximum of 2 iterations"
    assert out.iterations == 2
    assert [rep.iteration for rep in out.history] == [0, 1, 2]
    np.testing.assert_array_equal(out.x, out.history[-1].x)


def test_callback_can_stop_the_solve(noisy_problem):
    light, images = noisy_problem
    model = cs.model_of(images, [cs.start_near(light)])

    def stop_at_1(rep: IterationReport) -> None:
        if rep.iteration == 1:
            raise StopIteration

    out = run_least_squares(model, on_iteration=stop_at_1)
    assert out.status == -2
    assert not out.success
    assert out.iterations == 1
    np.testing.assert_array_equal(out.x, out.history[-1].x)

    def stop_at_start(rep: IterationReport) -> None:
        raise StopIteration

    out = run_least_squares(model, on_iteration=stop_at_start)
    assert (out.status, out.iterations) == (-2, 0)
    assert out.message == "stopped before the first iteration"
    np.testing.assert_array_equal(out.x, model.layout.x0)


def test_explicit_start_vector(noisy_problem):
    light, images = noisy_problem
    model = cs.model_of(images, [light])
    x0 = model.layout.x0.copy()
    x0[:3] += [0.03, -0.02, 0.01]
    out = run_least_squares(model, x0)
    np.testing.assert_array_equal(out.history[0].x, x0)
    assert out.success
    est = model.layout.rig(out.x).lights[0]
    assert cs.pose_errors(est, light)[0] < 0.01


# ------------------------------------------------------------------------- robust losses


def _with_outliers(images, rng, fraction=0.1):
    """Copies of images with `fraction` of their pixels tripled (specular glints)."""
    out = []
    for im in images:
        obs = im.observed.copy()
        bad = rng.random(obs.size) < fraction
        obs[bad] *= 3.0
        out.append(ImageData(im.name, im.view, im.footprints, obs, im.sigma))
    return out


@pytest.mark.parametrize("loss", ["huber", "soft_l1", "cauchy"])
def test_robust_losses_resist_outliers(noisy_problem, loss):
    light, images = noisy_problem
    dirty = _with_outliers(images, np.random.default_rng(11))
    start = cs.start_near(light)
    plain = run_least_squares(cs.model_of(dirty, [start]))
    model = cs.model_of(dirty, [start], loss=loss, f_scale=3.0)
    robust = run_least_squares(model)
    assert robust.success
    plain_err = cs.pose_errors(model.layout.rig(plain.x).lights[0], light)
    robust_err = cs.pose_errors(model.layout.rig(robust.x).lights[0], light)
    assert robust_err[0] < 0.01
    assert robust_err[0] < 0.5 * plain_err[0]
    assert robust_err[1] < 0.5 * plain_err[1]


def test_reported_cost_follows_the_robust_loss(noisy_problem):
    light, images = noisy_problem
    dirty = _with_outliers(images, np.random.default_rng(11))
    out = run_least_squares(cs.model_of(dirty, [cs.start_near(light)], loss="cauchy", f_scale=3))
    assert out.history[-1].cost == pytest.approx(out.cost, rel=1e-9)


# --------------------------------------------------------------------------------- bounds


def _lowest_world_z(model: CalibrationModel, lo: np.ndarray, hi: np.ndarray) -> float:
    """The smallest world z any position in the box [lo, hi] (first light) gets in any view."""
    worst = math.inf
    for im in model.images:
        R = im.view.R_camera_world
        z = im.view.center_world[2] + sum(min(R[k, 2] * lo[k], R[k, 2] * hi[k]) for k in range(3))
        worst = min(worst, z)
    return worst


@pytest.mark.parametrize("distance_range_m", [(0.8, 2.5), (2.0, 4.0)])
def test_bounds_keep_the_light_in_front_of_the_wall(distance_range_m):
    light = cs.symmetric_light()
    vs = cs.views(8, distance_range_m=distance_range_m, seed=3)
    images = cs.observe(CAMERA, vs, Rig.single(light), n_per_image=20, rng=np.random.default_rng(0))
    model = cs.model_of(images, [cs.start_near(light)])
    lo, hi = model.parameter_bounds()
    assert lo.shape == hi.shape == (model.layout.n,)
    assert np.all(lo[:3] >= -5.0) and np.all(hi[:3] <= 5.0)
    assert np.all(lo[:3] < model.layout.x0[:3]) and np.all(model.layout.x0[:3] < hi[:3])
    # Angles and scale are free.
    assert np.all(np.isinf(lo[3:])) and np.all(np.isinf(hi[3:]))
    assert _lowest_world_z(model, lo, hi) > 0.0
    # Random positions in the box render in every view (none is behind the wall).
    rng = np.random.default_rng(5)
    for _ in range(50):
        x = model.layout.x0.copy()
        x[:3] = rng.uniform(lo[:3], hi[:3])
        est = model.layout.rig(x).lights[0]
        assert all(est.position_world(im.view)[2] > 0.0 for im in model.images)


def test_bounds_with_close_views():
    light = cs.symmetric_light()
    vs = cs.views(8, distance_range_m=(0.3, 0.6), seed=3)
    images = cs.observe(CAMERA, vs, Rig.single(light), n_per_image=20, rng=np.random.default_rng(0))
    model = cs.model_of(images, [cs.start_near(light, position_m=0.02)])
    lo, hi = model.parameter_bounds()
    assert _lowest_world_z(model, lo, hi) > 0.0


def test_start_outside_the_bounds_is_clipped(noisy_problem):
    light, images = noisy_problem
    model = cs.model_of(images, [light], position_bound_m=0.2)
    lo, hi = model.parameter_bounds()
    assert hi[0] == pytest.approx(0.2)
    x0 = model.layout.x0.copy()
    x0[0] = 0.5
    out = run_least_squares(model, x0)
    assert out.history[0].x[0] == pytest.approx(0.2, abs=1e-9)
    assert np.all(out.x >= lo) and np.all(out.x <= hi)


# ------------------------------------------------------------- the QR-compressed problem


@pytest.mark.parametrize("case", ["symmetric_gains_offset", "two_lights_gains", "curve"])
def test_reduced_problem_has_the_full_problems_model(case):
    rig, unknowns, options = _jacobian_case(case)
    images = cs.observe(
        CAMERA, _three_views(), rig, n_per_image=40, rng=np.random.default_rng(1), noise=(0.5, 4.0)
    )
    model = CalibrationModel(images, unknowns, SolverOptions(**options, compress=True))
    assert model.compressed
    x = model.layout.x0.copy()
    r, J = model.residuals(x), model.jacobian(x)
    r_red, J_red = model.reduced(x)
    n = model.layout.n
    assert r_red.shape == (n + 1,) and J_red.shape == (n + 1, n)
    assert np.all(J_red[-1] == 0.0)
    assert r_red @ r_red == pytest.approx(r @ r, rel=1e-12)
    np.testing.assert_allclose(
        J_red.T @ r_red, J.T @ r, rtol=1e-9, atol=1e-9 * np.abs(J.T @ r).max()
    )
    JtJ = J.T @ J
    np.testing.assert_allclose(J_red.T @ J_red, JtJ, rtol=1e-9, atol=1e-12 * np.abs(JtJ).max())
    # trf's quadratic model of any step is the full problem's.
    for p in np.random.default_rng(0).normal(size=(5, n)) * 1e-3:
        full = J @ p + r
        red = J_red @ p + r_red
        assert red @ red == pytest.approx(full @ full, rel=1e-10)


def test_compressed_solve_follows_the_full_solve(noisy_problem):
    light, images = noisy_problem
    start = [cs.start_near(light)]
    full = cs.model_of(images, start, compress=False)
    reduced = cs.model_of(images, start, compress=True)
    assert reduced.compressed and not full.compressed
    out_full = run_least_squares(full)
    out_red = run_least_squares(reduced)
    assert out_red.success and out_full.success
    assert out_red.iterations == out_full.iterations
    np.testing.assert_allclose(out_red.x, out_full.x, rtol=0, atol=1e-9)
    for a, b in zip(out_red.history, out_full.history, strict=True):
        assert a.cost == pytest.approx(b.cost, rel=1e-9)
        np.testing.assert_allclose(a.x, b.x, rtol=0, atol=1e-9)


def test_a_report_after_a_trial_point_evaluates_nothing(noisy_problem):
    """trf may evaluate a trial point after the one an iteration reports: the report comes
    from the last two compressed evaluations, equal to the full problem's numbers."""
    light, images = noisy_problem
    start = [cs.start_near(light)]
    model = cs.model_of(images, start, compress=True)
    full = cs.model_of(images, start, compress=False)
    x1 = model.layout.x0.copy()
    x2 = x1 + 1e-4
    model.solver_residuals(x1)
    model.solver_residuals(x2)  # the trial: the cache now holds x2
    evaluations = model.nfev
    got = model.report(x1, 3)
    assert model.nfev == evaluations  # no evaluation for the report
    want = full.report(x1, 3)
    assert got.cost == pytest.approx(want.cost, rel=1e-10)
    assert got.gradient_norm == pytest.approx(want.gradient_norm, rel=1e-7)
    np.testing.assert_allclose(got.per_image_rms, want.per_image_rms, rtol=1e-12)
    # Three points back is out of the cache: evaluated again, the same numbers.
    model.solver_residuals(x2 + 1e-4)
    again = model.report(x1, 3)
    assert model.nfev == evaluations + 2
    assert again.cost == pytest.approx(got.cost, rel=1e-10)


def test_the_compressed_problem_is_chosen_by_pixel_count(noisy_problem, monkeypatch):
    light, images = noisy_problem
    start = [cs.start_near(light)]
    m = sum(len(im.observed) for im in images)
    monkeypatch.setattr(calibration_model, "COMPRESS_MIN_PIXELS", m + 1)
    assert not cs.model_of(images, start).compressed
    assert cs.model_of(images, start, compress=True).compressed
    monkeypatch.setattr(calibration_model, "COMPRESS_MIN_PIXELS", m)
    model = cs.model_of(images, start)
    assert model.compressed
    assert model.solver_residuals(model.layout.x0).shape == (model.layout.n + 1,)
    assert not cs.model_of(images, start, compress=False).compressed


def test_robust_losses_use_the_full_problem(noisy_problem):
    light, images = noisy_problem
    model = cs.model_of(images, [cs.start_near(light)], loss="huber", compress=True)
    assert not model.compressed
    x = model.layout.x0
    assert model.solver_residuals(x).shape == (model.m,)
    assert model.solver_jacobian(x).shape == (model.m, model.layout.n)


def test_stacked_r_factors_equal_the_r_factor_of_the_stack():
    rng = np.random.default_rng(3)
    blocks = [rng.normal(size=(k, 4)) for k in (50, 2, 7)]
    tops = [economic_r(np.asfortranarray(b)) for b in blocks]
    assert [t.shape for t in tops] == [(4, 4), (2, 4), (4, 4)]
    R = stack_r_factors(tops, 4)
    whole = np.linalg.qr(np.concatenate(blocks), mode="r")
    # Unique up to the sign of each row.
    np.testing.assert_allclose(np.abs(R), np.abs(whole), atol=1e-12)
    np.testing.assert_allclose(R.T @ R, whole.T @ whole, atol=1e-10)
    # Fewer rows than columns in all: zero rows pad the factor.
    assert stack_r_factors([tops[1]], 4)[2:].tolist() == [[0.0] * 4] * 2
    # A block with non-finite residuals makes the whole problem NaN (trf: a failed step).
    assert np.all(np.isnan(stack_r_factors([tops[0], None], 4)))


def test_tall_systems_are_reduced_in_blocks_to_the_same_r_factor():
    from lightcal.core import qr_factors

    rng = np.random.default_rng(4)
    # 4.3 blocks of rows (the last one partial), columns of very different scales as in
    # [J r] (metres, radians, a log scale, residuals).
    n = int(4.3 * qr_factors.QR_BLOCK_ROWS)
    A = rng.normal(size=(n, 9)) * np.logspace(-4, 3, 9)
    whole = np.linalg.qr(A, mode="r")
    R = economic_r(np.asfortranarray(A))
    assert R.shape == (9, 9)
    assert np.array_equal(R, np.triu(R))
    # Unique up to the sign of each row.
    np.testing.assert_allclose(
        np.abs(R), np.abs(whole), rtol=1e-11, atol=1e-9 * np.abs(whole).max()
    )
    np.testing.assert_allclose(R.T @ R, A.T @ A, rtol=1e-11)
    # Below four blocks: one LAPACK call, which overwrites its (Fortran) input.
    small = np.asfortranarray(A[: 3 * qr_factors.QR_BLOCK_ROWS])
    before = small.copy()
    np.testing.assert_allclose(
        np.abs(economic_r(small)),
        np.abs(np.linalg.qr(before, mode="r")),
        rtol=1e-11,
        atol=1e-9 * np.abs(whole).max(),
    )
    assert not np.array_equal(small, before)


# ------------------------------------------------------------------ re-weighting


def test_weights_from_rendered_values(noisy_problem):
    light, images = noisy_problem
    noise = (0.5, 4.0)
    with_model = [
        ImageData(im.name, im.view, im.footprints, im.observed, im.sigma, noise) for im in images
    ]
    model = cs.model_of(with_model, [cs.start_near(light)], estimate_offset=True, offset=2.0)
    assert model.reweights
    x = model.layout.x0.copy()
    r_data = model.residuals(x).copy()
    model.set_weights_at(x)
    np.testing.assert_array_equal(model.weights_at, x)
    rig = model.layout.rig(x)
    for i, im in enumerate(with_model):
        v = shade(im.footprints, im.view, rig).values.filled(np.nan)  # offset excluded
        np.testing.assert_allclose(model.sigmas[i], np.sqrt(0.5 * v + 4.0), rtol=1e-12)
    # The residuals use the new sigmas (the cache was dropped) ...
    r = model.residuals(x)
    assert not np.allclose(r, r_data)
    difference = r_data * np.concatenate([im.sigma for im in with_model])
    np.testing.assert_allclose(r * np.concatenate(model.sigmas), difference, rtol=1e-9)
    # ... and None restores the data's.
    model.set_weights_at(None)
    assert model.weights_at is None
    np.testing.assert_array_equal(model.residuals(x), r_data)
    # Images without a noise model, or re-weighting switched off: nothing to do.
    assert not cs.model_of(images, [cs.start_near(light)]).reweights
    assert not cs.model_of(with_model, [cs.start_near(light)], reweight=False).reweights


def test_image_noise_model_is_validated(noisy_problem):
    _, images = noisy_problem
    im = images[0]
    with pytest.raises(
        ValueError, match=r"^view_00: noise: expected a finite gain >= 0, got -1.0$"
    ):
        ImageData(im.name, im.view, im.footprints, im.observed, im.sigma, (-1.0, 4.0))
    with pytest.raises(
        ValueError, match=r"^view_00: noise: expected a finite read variance > 0, got 0.0$"
    ):
        ImageData(im.name, im.view, im.footprints, im.observed, im.sigma, (0.5, 0.0))


def test_reweighting_solves_again_and_numbers_the_iterations_on():
    light = cs.symmetric_light()
    images = cs.observe(
        CAMERA,
        cs.views(12),
        Rig.single(light),
        rng=np.random.default_rng(7),
        noise=(0.5, 4.0),
        noise_model=True,
    )
    model = cs.model_of(images, [cs.start_near(light)])
    plain = run_least_squares(cs.model_of(images, [cs.start_near(light)], reweight=False))
    out = run_least_squares(model)
    assert out.success
    assert [rep.iteration for rep in out.history] == list(range(len(out.history)))
    assert out.iterations > plain.iterations
    flags = [rep.reweighted for rep in out.history]
    assert flags == [False] * (plain.iterations + 1) + [True] * (out.iterations - plain.iterations)
    np.testing.assert_array_equal(model.weights_at, plain.x)
    assert not np.allclose(out.x, plain.x, rtol=0, atol=1e-12)
    # Converged under the weights rendered at the first solution.
    assert out.history[-1].gradient_norm < 1e-6 * out.history[0].gradient_norm
    # A new solve starts from the data's weights again.
    again = run_least_squares(model)
    np.testing.assert_allclose(again.x, out.x, rtol=0, atol=1e-10)


def test_reweighting_removes_the_bias_of_weights_from_noisy_values():
    """Sigmas from the noisy observations favour pixels whose noise was negative; the
    bias (mean error over seeds) is several times the seeds' standard error at this SNR
    (~35 at the brightest pixel); re-weighting from rendered values removes it."""
    light = cs.symmetric_light()
    errors: dict[bool, list[np.ndarray]] = {False: [], True: []}
    for seed in range(30):
        images = cs.observe(
            CAMERA,
            cs.views(12),
            Rig.single(light),
            rng=np.random.default_rng(seed),
            noise=(0.8, 9.0),
            noise_model=True,
        )
        for reweight in (False, True):
            model = cs.model_of(images, [cs.start_near(light)], reweight=reweight)
            est = model.layout.rig(run_least_squares(model).x).lights[0]
            errors[reweight].append(est.t_camera_light - light.t_camera_light)
    bias = {k: np.linalg.norm(np.mean(v, axis=0)) * 1e3 for k, v in errors.items()}
    standard_error = np.linalg.norm(np.std(errors[True], axis=0)) / np.sqrt(30) * 1e3
    assert bias[False] > 2.5 * standard_error  # the bias is real (measured 3.2 mm vs 0.96) ...
    assert bias[True] < standard_error  # ... and gone (measured 0.49 mm)


@pytest.mark.parametrize("compress", [False, True])
def test_evaluate_visiting_shows_each_image_system_and_caches_the_evaluation(
    compress: bool,
) -> None:
    rig = cs.two_light_rig()
    images = cs.observe(
        cs.small_camera(), cs.views(4), rig, n_per_image=50, rng=np.random.default_rng(2)
    )
    images = cs.add_noise(images, (0.5, 4.0), np.random.default_rng(3))
    starts = [cs.start_near(light) for light in rig.lights]
    x = cs.model_of(images, starts).layout.x0 + 1e-3
    reference = cs.model_of(images, starts, compress=compress)
    r, J = reference.residuals(x).copy(), reference.jacobian(x).copy()
    normal = reference.normal_matrix(x)
    model = cs.model_of(images, starts, compress=compress)
    seen: list[int] = []
    lay = model.layout

    def visit(i: int, A: np.ndarray, fluxes: np.ndarray) -> None:
        rows = slice(model.bounds[i], model.bounds[i + 1])
        np.testing.assert_array_equal(A[:, lay.n], r[rows])
        np.testing.assert_array_equal(A[:, : lay.n], J[rows])
        unit = Rig(tuple(light.replace(scale=1.0) for light in lay.rig(x).lights))
        expected = shade(images[i].footprints, images[i].view, unit).flux
        np.testing.assert_array_equal(fluxes, expected)
        seen.append(i)

    model.evaluate_visiting(x, visit)
    assert seen == list(range(len(images)))
    nfev = model.nfev
    np.testing.assert_array_equal(model.residuals(x), r)  # cached: no new evaluation
    np.testing.assert_array_equal(model.normal_matrix(x), normal)
    assert model.nfev == nfev


# ------------------------------------------------------- stopping one evaluation early


@pytest.mark.parametrize("compress", [False, True])
def test_gauss_newton_decrease_is_half_the_squared_projection_of_r(noisy_problem, compress):
    light, images = noisy_problem
    model = cs.model_of(images, [cs.start_near(light)], compress=compress)
    x = model.layout.x0 + 1e-4
    assert model.gauss_newton_decrease(x) is None  # nothing evaluated at x yet
    r, J = model.residuals(x).copy(), model.jacobian(x).copy()
    step = np.linalg.lstsq(J, -r, rcond=None)[0]
    want = 0.5 * (r @ r - (J @ step + r) @ (J @ step + r))
    assert model.gauss_newton_decrease(x) == pytest.approx(want, rel=1e-8)
    robust = cs.model_of(images, [cs.start_near(light)], loss="soft_l1")
    robust.residuals(x)
    assert robust.gauss_newton_decrease(x) is None


@pytest.mark.parametrize("compress", [False, True])
def test_the_solve_stops_when_the_next_step_would_only_confirm_convergence(
    noisy_problem, monkeypatch, compress
):
    light, images = noisy_problem
    start = [cs.start_near(light)]
    early = cs.model_of(images, start, compress=compress)
    out = run_least_squares(early)
    monkeypatch.setattr(CalibrationModel, "gauss_newton_decrease", lambda self, x: None)
    plain = cs.model_of(images, start, compress=compress)
    ref = run_least_squares(plain)
    assert (out.status, out.success, out.message) == (2, True, CONVERGED_AHEAD)
    assert ref.status > 0 and ref.message != CONVERGED_AHEAD
    # trf took one more step and evaluation, then stopped on it: the same iterates up to
    # there, a cost change below the tolerance, a step of |J dx| <= sqrt(2 tol cost).
    assert (out.iterations, out.nfev) == (ref.iterations - 1, ref.nfev - 1)
    for a, b in zip(out.history, ref.history, strict=False):
        np.testing.assert_array_equal(a.x, b.x)
    tol = early.options.tolerance
    assert 0.0 <= out.cost - ref.cost < tol * out.cost
    J = plain.jacobian(ref.x)
    assert np.linalg.norm(J @ (out.x - ref.x)) < 1.01 * math.sqrt(2 * tol * out.cost)
    assert np.abs(out.x - ref.x).max() < 1e-6


def test_image_systems_zero_only_the_columns_they_do_not_assign(noisy_problem):
    """The work array is reused: columns no image writes (other images' gains) are zeroed,
    the others overwritten; a buffer left full of NaN gives the same systems."""
    light, images = noisy_problem
    start = [cs.start_near(light)]
    fresh = cs.model_of(images, start, estimate_gains=True, compress=True)
    reused = cs.model_of(images, start, estimate_gains=True, compress=True)
    x = fresh.layout.x0 + 1e-4
    reused.residuals(x - 1e-4)
    reused._buffers._system[:] = np.nan
    reused._buffers._grad[:] = np.nan
    np.testing.assert_array_equal(reused.reduced(x)[1], fresh.reduced(x)[1])
    np.testing.assert_array_equal(reused.reduced(x)[0], fresh.reduced(x)[0])
    gains = fresh.layout.gains
    assert gains.stop - gains.start == len(images) - 1  # image 0 sets the scale
    assert fresh._unwritten_columns(-1, -1) == list(range(gains.start, gains.stop))
