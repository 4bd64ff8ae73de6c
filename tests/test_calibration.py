"""From a project to a result: scales, solve (multistart), uncertainties and warnings."""

from __future__ import annotations

import dataclasses
import json
import math

import numpy as np
import pytest

from lightcal.core.pose import describe_pose, rotation_from_axis
from lightcal.core.problem import ImageData, LightUnknown
from lightcal.core.rid import CosPowerRID
from lightcal.core.scene import Rig
from lightcal.core.solver import IterationReport, run_least_squares
from lightcal.errors import InputError
from lightcal.io.project import load_project
from lightcal.pipeline import (
    CalibrationResult,
    PoseSummary,
    build_model,
    calibrate_project,
    covariance,
    dark_light_warnings,
    fit_scales,
    load_images,
    perturbed_start,
    solve,
    summarise,
)
from tests import calib_scenes as cs

CAMERA = cs.small_camera()
NOISE = (0.5, 4.0)


@pytest.fixture(scope="module")
def clean():
    """Noise-free pixels (100 per image) of 12 good views of a symmetric light."""
    light = cs.symmetric_light()
    return light, cs.observe(CAMERA, cs.views(12), Rig.single(light), rng=np.random.default_rng(0))


def _solve(images, starts, **options):
    model = cs.model_of(images, starts, **options)
    return model, summarise(model, run_least_squares(model))


# --------------------------------------------------------------------------- fit_scales


def test_fit_scales_at_the_true_poses():
    rig = cs.two_light_rig()
    images = cs.observe(CAMERA, cs.views(6), rig, n_per_image=60, rng=np.random.default_rng(1))
    unknowns = [LightUnknown(light.replace(scale=1.0)) for light in rig.lights]
    scales = fit_scales(images, unknowns, 0.0)
    np.testing.assert_allclose(scales, [light.scale for light in rig.lights], rtol=1e-9)
    # With an offset in the data.
    shifted = [ImageData(i.name, i.view, i.footprints, i.observed + 7.0, i.sigma) for i in images]
    np.testing.assert_allclose(
        fit_scales(shifted, unknowns, 7.0), [light.scale for light in rig.lights], rtol=1e-9
    )


def test_fit_scales_of_large_images_read_a_regular_subsample(monkeypatch):
    from scipy.optimize import nnls

    from lightcal.core.render import shade
    from lightcal.pipeline import model as model_module

    rig = cs.two_light_rig()
    clean_images = cs.observe(
        CAMERA, cs.views(5), rig, n_per_image=80, rng=np.random.default_rng(3)
    )
    images = cs.add_noise(clean_images, NOISE, np.random.default_rng(4))
    unknowns = [LightUnknown(cs.start_near(light)) for light in rig.lights]
    monkeypatch.setattr(model_module, "SCALE_FIT_PIXELS", 30)  # every third pixel of 80
    start = Rig(tuple(u.initial.replace(scale=1.0) for u in unknowns))
    A = np.concatenate([(shade(i.footprints, i.view, start).flux / i.sigma).T[::3] for i in images])
    y = np.concatenate([((i.observed - 2.0) / i.sigma)[::3] for i in images])
    expected, _ = nnls(A, y)
    np.testing.assert_allclose(fit_scales(images, unknowns, 2.0), expected, rtol=1e-12)
    # At the true poses a subsample gives the exact scales.
    truth = [LightUnknown(light.replace(scale=1.0)) for light in rig.lights]
    np.testing.assert_allclose(
        fit_scales(clean_images, truth, 0.0), [light.scale for light in rig.lights], rtol=1e-9
    )


def test_large_models_start_from_the_solution_of_a_subsample(monkeypatch):
    import importlib

    solve_module = importlib.import_module("lightcal.pipeline.solve")  # not the function
    light = cs.symmetric_light()
    images = cs.observe(
        CAMERA, cs.views(12), Rig.single(light), n_per_image=400, rng=np.random.default_rng(5)
    )
    images = cs.add_noise(images, NOISE, np.random.default_rng(6))
    start = [cs.start_near(light)]
    monkeypatch.setattr(solve_module, "COARSE_MIN_PIXELS", 1000)
    monkeypatch.setattr(solve_module, "COARSE_PIXELS", 600)  # every 8th of 4800 pixels
    model = cs.model_of(images, start)
    assert model.m == 4800
    every_8th = [im.subset(np.arange(0, len(im.observed), 8)) for im in images]
    coarse = solve_module.coarse_start(model)
    assert coarse is not None
    first = run_least_squares(cs.model_of(every_8th, start))
    np.testing.assert_array_equal(coarse[0], first.x)
    # Its costs on the full problem's scale: x 4800 / 600 pixels.
    assert coarse[2] == [rep.cost * 8.0 for rep in first.history]
    out = solve(model)
    assert out.start.startswith("the estimate of a first solve on one pixel in 8 (600 of 4800")
    assert out.start_costs == coarse[2]
    plain = cs.model_of(images, start)
    ref = run_least_squares(plain)
    assert out.success and ref.success
    assert out.nfev < ref.nfev  # the full problem's evaluations: from near its minimum
    # The same minimum, to the tolerance: each stop leaves |J dx| <= sqrt(2 tol cost).
    bound = 2 * math.sqrt(2 * plain.options.tolerance * ref.cost)
    assert np.linalg.norm(plain.jacobian(ref.x) @ (out.x - ref.x)) < bound
    assert abs(out.cost - ref.cost) < plain.options.tolerance * ref.cost
    # Below the threshold, the initial guess.
    monkeypatch.setattr(solve_module, "COARSE_MIN_PIXELS", model.m + 1)
    assert solve_module.coarse_start(model) is None
    below = solve(cs.model_of(images, start))
    assert below.start == "" and below.start_costs == []


def test_fit_scales_on_the_reduced_system_match_nnls_of_every_pixel():
    # Noisy data and a start off the truth: the scales are those of NNLS on all rows.
    from scipy.optimize import nnls

    from lightcal.core.render import shade

    rig = cs.two_light_rig()
    clean_images = cs.observe(
        CAMERA, cs.views(5), rig, n_per_image=80, rng=np.random.default_rng(3)
    )
    images = cs.add_noise(clean_images, NOISE, np.random.default_rng(4))
    unknowns = [LightUnknown(cs.start_near(light)) for light in rig.lights]
    start = Rig(tuple(u.initial.replace(scale=1.0) for u in unknowns))
    A = np.concatenate([(shade(i.footprints, i.view, start).flux / i.sigma).T for i in images])
    y = np.concatenate([(i.observed - 2.0) / i.sigma for i in images])
    expected, _ = nnls(A, y)
    assert np.all(expected > 0.0)
    np.testing.assert_allclose(fit_scales(images, unknowns, 2.0), expected, rtol=1e-12)


def test_fit_scales_stay_positive(clean):
    light, images = clean
    dark = [ImageData(i.name, i.view, i.footprints, -i.observed, i.sigma) for i in images]
    (scale,) = fit_scales(dark, [LightUnknown(light)], 0.0)
    assert scale > 0.0


# ----------------------------------------------------------------------------- summarise


def test_summary_fields(clean):
    light, images = clean
    noisy = cs.add_noise(images, NOISE, np.random.default_rng(5))
    model, res = _solve(noisy, [cs.start_near(light)], estimate_offset=True)
    assert isinstance(res, CalibrationResult)
    (lr,) = res.lights
    est = model.layout.rig(np.array(res.x)).lights[0]
    assert lr.name == "light" and lr.pose_kind == "symmetric" and lr.rid is None
    assert lr.pose.to_dict() == describe_pose(est.R_camera_light, est.t_camera_light)
    assert lr.pose == PoseSummary.of_pose(est.R_camera_light, est.t_camera_light)
    assert set(lr.sigma.to_dict()) == set(lr.pose.to_dict())
    assert lr.scale == pytest.approx(est.scale)
    cov = np.array(res.covariance)
    n = model.layout.n
    assert cov.shape == (n, n)
    np.testing.assert_allclose(cov, cov.T, rtol=1e-10, atol=0)
    assert np.all(np.linalg.eigvalsh(cov) > 0)
    # Position sigmas are the covariance's (the position parameters are x, y, z).
    np.testing.assert_allclose(lr.sigma.t_camera_light, np.sqrt(np.diag(cov)[:3]), rtol=1e-6)
    assert lr.scale_sigma == pytest.approx(est.scale * math.sqrt(cov[5, 5]), rel=1e-12)
    for key in ("roll_deg", "pitch_deg", "axis_angle_from_optical_axis_deg"):
        assert 0.0 < getattr(lr.sigma, key) < 1.0
    assert np.all(np.array(lr.sigma.axis_camera) >= 0)
    assert res.offset == pytest.approx(float(res.x[6]))
    assert res.offset_sigma == pytest.approx(math.sqrt(cov[6, 6]))
    assert res.gains == [1.0] * 12
    assert res.image_names == [f"view_{i:02d}" for i in range(12)]
    assert res.pixels_used == [100] * 12
    np.testing.assert_allclose(res.per_image_rms, model.per_image_rms(np.array(res.x)))
    assert res.converged and res.status > 0 and res.iterations == res.history[-1].iteration
    assert res.nfev >= res.iterations and res.time_s > 0
    assert res.cost == pytest.approx(res.history[-1].cost)
    assert res.parameter_names == model.layout.names
    assert res.warnings == []
    # Covariance: s^2 (J^T J)^-1 with s^2 the reduced chi^2 (~1 for correct sigmas).
    r = model.residuals(np.array(res.x))
    s2 = float(r @ r) / (model.m - n)
    assert s2 == pytest.approx(1.0, abs=0.15)
    np.testing.assert_allclose(covariance(model, np.array(res.x)), cov, rtol=1e-12)


def test_pose_summary_vector_and_dict_round_trip():
    axis = np.array([0.2, -0.1, 1.0])
    R = rotation_from_axis(axis / np.linalg.norm(axis))
    t = np.array([0.1, -0.02, 0.03])
    pose = PoseSummary.of_pose(R, t)
    assert list(PoseSummary.SHAPES) == [f.name for f in dataclasses.fields(PoseSummary)]
    v = pose.to_vector()
    assert v.shape == (PoseSummary.SIZE,) == (22,)
    np.testing.assert_array_equal(v[:3], t)
    np.testing.assert_array_equal(v[3:12], np.ravel(R))
    assert PoseSummary.from_vector(v) == pose
    # to_dict is describe_pose's JSON-ready form, to the bit.
    d = pose.to_dict()
    assert d == describe_pose(R, t)
    assert json.loads(json.dumps(d)) == d
    assert PoseSummary.from_dict(d) == pose
    assert not hasattr(pose, "position_m")  # one name inside: t_camera_light
    assert isinstance(d["roll_deg"], float) and isinstance(d["R_camera_light"][0][0], float)
    assert pose.R_camera_light.shape == (3, 3) and not pose.t_camera_light.flags.writeable
    assert pose != PoseSummary.from_vector(v + 1e-12)
    with pytest.raises(ValueError, match="shape"):
        PoseSummary.from_vector(v[:-1])
    with pytest.raises(ValueError, match="t_camera_light"):
        PoseSummary.from_dict({**d, "position_m": [0.0, 0.0]})


def test_summary_of_an_estimated_rid(clean):
    light, images = clean
    start = cs.start_near(light).replace(rid=CosPowerRID(2.0))
    _, res = _solve(images, [LightUnknown(start, estimate_rid="cos_power")])
    rid = res.lights[0].rid
    assert rid is not None
    assert rid["model"] == "cos_power"
    assert rid["m"] == pytest.approx(light.rid.m, rel=1e-8)
    assert rid["half_angle_deg"] == pytest.approx(30.0, abs=1e-6)
    assert len(rid["theta_deg"]) == len(rid["values"]) == 90
    assert rid["values"][0] == 1.0


def test_summary_of_gains_and_two_lights():
    rig = cs.two_light_rig()
    vs = cs.views(8, seed=4)
    gains = np.array([1.0, 1.3, 0.8, 1.1, 0.9, 1.2, 0.7, 1.0])
    images = cs.observe(CAMERA, vs, rig, n_per_image=80, rng=np.random.default_rng(2), gains=gains)
    _, res = _solve(images, [cs.start_near(light) for light in rig.lights], estimate_gains=True)
    assert [lr.name for lr in res.lights] == ["left", "right"]
    np.testing.assert_allclose(res.gains, gains, rtol=1e-8)
    for lr, light in zip(res.lights, rig.lights, strict=True):
        np.testing.assert_allclose(lr.pose.t_camera_light, light.t_camera_light, atol=1e-9)
        assert lr.scale == pytest.approx(light.scale, rel=1e-8)


def test_warning_for_a_light_that_lights_no_pixel():
    rig = cs.two_light_rig()
    images = cs.observe(CAMERA, cs.views(6, seed=4), rig, rng=np.random.default_rng(2))
    left, right = rig.lights
    model = cs.model_of(images, [left, right])
    assert dark_light_warnings(model, model.layout.x0) == []
    # The right light turned to face away from the wall: it lights nothing.
    away = right.replace(R_camera_light=rotation_from_axis(np.array([0.0, 0.6, -0.8])))
    model = cs.model_of(images, [left, away])
    assert dark_light_warnings(model, model.layout.x0) == [
        "light 'right' lights none of the selected pixels at the solution (it points away "
        "or sits behind the wall): its pose is not determined; start it nearer its true "
        "pose, or calibrate the lights one at a time"
    ]


# ------------------------------------------------------------------------ uncertainties


def _position_sigma(images, light) -> float:
    """The statistical 1-sigma norm of the light position (the systematic terms, which a
    fit test may add where noisy weights bias the fit, do not scale with the noise)."""
    _, res = _solve(images, [light])
    terms = [b for b in res.uncertainty_breakdown if not b["systematic"]]
    return float(np.sqrt(sum(b["lights"][0]["position_sigma_m"] ** 2 for b in terms)))


def test_uncertainty_shrinks_with_more_pixels_and_less_noise():
    light = cs.symmetric_light()
    vs = cs.views(12)
    few = cs.observe(CAMERA, vs, Rig.single(light), n_per_image=50, rng=np.random.default_rng(3))
    many = cs.observe(CAMERA, vs, Rig.single(light), n_per_image=400, rng=np.random.default_rng(3))
    rng = np.random.default_rng(8)
    s_few = _position_sigma(cs.add_noise(few, NOISE, rng), light)
    s_many = _position_sigma(cs.add_noise(many, NOISE, rng), light)
    # 8 x the pixels: ~sqrt(8) smaller.
    assert np.all(s_many < 0.5 * s_few)
    assert np.all(s_many > 0.2 * s_few)
    s_noisy = _position_sigma(cs.add_noise(many, (4 * NOISE[0], 4 * NOISE[1]), rng), light)
    # 4 x the variance: ~2 x the sigma.
    np.testing.assert_allclose(s_noisy / s_many, 2.0, rtol=0.2)


def test_uncertainty_matches_the_monte_carlo_spread(clean):
    light, images = clean
    estimates, sigmas, angles, angle_sigmas = [], [], [], []
    for seed in range(20):
        noisy = cs.add_noise(images, NOISE, np.random.default_rng(100 + seed))
        _, res = _solve(noisy, [light])
        lr = res.lights[0]
        estimates.append(lr.pose.t_camera_light)
        sigmas.append(lr.sigma.t_camera_light)
        angles.append([lr.pose.roll_deg, lr.pose.pitch_deg])
        angle_sigmas.append([lr.sigma.roll_deg, lr.sigma.pitch_deg])
    spread = np.std(estimates, axis=0, ddof=1)
    ratio = np.mean(sigmas, axis=0) / spread
    assert np.all((ratio > 1 / 1.5) & (ratio < 1.5)), ratio
    angle_ratio = np.mean(angle_sigmas, axis=0) / np.std(angles, axis=0, ddof=1)
    assert np.all((angle_ratio > 1 / 1.5) & (angle_ratio < 1.5)), angle_ratio


# ------------------------------------------------------------------------------ warnings


def _warnings(vs) -> list[str]:
    light = cs.symmetric_light()
    images = cs.observe(CAMERA, vs, Rig.single(light), rng=np.random.default_rng(0))
    images = cs.add_noise(images, NOISE, np.random.default_rng(1))
    return _solve(images, [cs.start_near(light)])[1].warnings


def test_no_warning_for_a_good_set_of_views():
    assert _warnings(cs.views(12, distance_range_m=(0.8, 2.5))) == []


def test_warning_for_views_at_one_distance():
    warnings = _warnings(cs.views(12, distance_range_m=(1.5, 1.5)))
    assert warnings == [
        "camera-to-wall distances span only 1.50-1.50 m: the light's position along the view "
        "direction and its scale are poorly separated; add views nearer and farther from the wall"
    ]


def test_warning_for_views_in_one_direction():
    warnings = _warnings(cs.views(12, tilt_range_deg=(0.0, 2.0), target_spread_m=0.0))
    assert len(warnings) == 1
    assert warnings[0].startswith("the views' directions differ by at most ")
    assert warnings[0].endswith(
        " degrees: the light's orientation and lateral position are poorly separated; "
        "tilt the camera more"
    )


def test_warning_for_too_few_images():
    warnings = _warnings(cs.views(2, distance_range_m=(0.8, 2.5), seed=5))
    assert warnings[0] == (
        "only 2 image(s): the paper used 12; use several views at different distances and angles"
    )


# --------------------------------------------------------------------- solve, multistart


def test_perturbed_start_stays_within_the_limits(clean):
    light, images = clean
    model = cs.model_of(images, [light])
    rng = np.random.default_rng(0)
    x0 = model.layout.x0
    for _ in range(30):
        x = perturbed_start(model, rng, shift_m=0.3, angle_deg=30.0)
        est = model.layout.rig(x).lights[0]
        position, axis = cs.pose_errors(est, light)
        assert position <= 0.3 + 1e-12
        assert axis <= 30.0 + 1e-9
        assert x[5] == x0[5]  # the scale is kept
    iso = cs.model_of(images, [LightUnknown(light, pose_kind="isotropic")])
    x = perturbed_start(iso, rng, shift_m=0.1, angle_deg=30.0)
    assert x.shape == (4,) and np.linalg.norm(x[:3] - iso.layout.x0[:3]) <= 0.1


def test_multistart_keeps_the_best(clean):
    light, images = clean
    noisy = cs.add_noise(images, NOISE, np.random.default_rng(2))
    model = cs.model_of(noisy, [cs.start_near(light, position_m=0.2, angle_deg=25.0)])
    single = solve(model)
    reports: list[IterationReport] = []
    starts: list[tuple[int, int]] = []
    multi = solve(
        model,
        multistart=3,
        seed=4,
        on_iteration=reports.append,
        on_start=lambda k, n: starts.append((k, n)),
    )
    again = solve(model, multistart=3, seed=4)
    assert multi.cost <= single.cost * (1 + 1e-12)
    np.testing.assert_array_equal(multi.x, again.x)
    # Every start is reported, each numbered from 0.
    assert starts == [(0, 4), (1, 4), (2, 4), (3, 4)]
    assert [rep.iteration for rep in reports].count(0) == 4
    est = model.layout.rig(multi.x).lights[0]
    assert cs.pose_errors(est, light)[0] < 0.01


def test_multistart_leaves_the_best_solves_weights(clean):
    light, images = clean
    noisy = [
        ImageData(im.name, im.view, im.footprints, im.observed, im.sigma, NOISE)
        for im in cs.add_noise(images, NOISE, np.random.default_rng(2))
    ]
    model = cs.model_of(noisy, [cs.start_near(light, position_m=0.2, angle_deg=25.0)])
    assert model.reweights
    best = solve(model, multistart=3, seed=4)
    assert best.weights_at is not None
    np.testing.assert_array_equal(model.weights_at, best.weights_at)
    # The summary sees the residuals the best solve converged with.
    r = model.residuals(best.x)
    assert 0.5 * float(r @ r) == pytest.approx(best.cost, rel=1e-9)


# ---------------------------------------------------------------------- whole projects


@pytest.fixture(scope="module")
def npy_project(tmp_path_factory):
    """Noise-free float images of 6 views (160 x 120); the light's scale left to fit."""
    folder = tmp_path_factory.mktemp("npy_project")
    camera = cs.small_camera(width=160, height=120)
    light = cs.symmetric_light()
    start = cs.start_near(light)
    path = cs.write_npy_project(
        folder,
        camera,
        cs.views(6, seed=2),
        Rig.single(light),
        initial=[start],
        rid_specs=[{"type": "half_angle", "half_angle_deg": 30}],
        extra={"selection": {"n_per_image": 80, "min_signal": 1.0}},
    )
    doc = json.loads(path.read_text())
    del doc["lights"][0]["initial"]["scale"]
    path.write_text(json.dumps(doc))
    return path, light, start


def test_build_model_fits_the_initial_scale(npy_project):
    path, _light, start = npy_project
    project = load_project(path)
    loaded = load_images(project)
    stages = []
    model = build_model(project, loaded, progress=lambda s, d, t: stages.append((s, d, t)))
    assert ("selecting pixels", 0, 6) in stages
    assert len(model.images) == 6 and model.sizes.tolist() == [80] * 6
    scale = model.unknowns[0].initial.scale
    expected = fit_scales(model.images, [LightUnknown(start.replace(scale=1.0))], 0.0)[0]
    assert scale == pytest.approx(expected, rel=1e-9)
    # Explicit lights are used as given (no scale fit).
    mine = [LightUnknown(start)]
    assert build_model(project, loaded, lights=mine).unknowns[0].initial.scale == start.scale


def test_calibrate_project_end_to_end(npy_project):
    path, light, _ = npy_project
    stages = set()
    reports: list[IterationReport] = []
    loaded, model, res = calibrate_project(
        load_project(path),
        progress=lambda s, d, t: stages.add(s),
        on_iteration=reports.append,
    )
    assert stages == {"reading images", "selecting pixels"}
    assert len(loaded.images) == 6
    assert reports == res.history
    assert res.converged
    est = model.layout.rig(np.array(res.x)).lights[0]
    position, axis = cs.pose_errors(est, light)
    assert position < 1e-6 and axis < 1e-4
    assert res.lights[0].scale == pytest.approx(light.scale, rel=1e-6)


def test_build_model_without_usable_pixels(npy_project):
    path, _, _ = npy_project
    doc = json.loads(path.read_text())
    doc["selection"]["min_signal"] = 1e9
    dark = path.with_name("dark.json")
    dark.write_text(json.dumps(doc))
    project = load_project(dark)
    with pytest.raises(InputError, match=r"dark\.json: no usable pixels in any image"):
        build_model(project, load_images(project))
