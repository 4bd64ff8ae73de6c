"""Accuracy of the calibration on synthetic data with known ground truth.

- Noise-free data rendered with the solver's own model (in memory): the truth comes back
  to round-off (position < 1e-6 m, axis < 1e-4 degrees) for every kind of light.
- Realistic datasets written by `lightcal synth` (`write_dataset`: shot and read noise,
  14 bits, 12 images at 0.8-2.5 m, measured poses off by 0.5 mm / 0.05 degrees), calibrated
  through the project file like a user would: position < 3 mm, axis < 0.2 degrees.
- A start 45 degrees and 1.5 m off (views at 2-4 m, where such a start is still in front
  of the wall) reaches the same minimum as a start at the truth.
- RID estimation recovers a cos^m exponent and a monotone curve.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from lightcal.core.pose import PoseKind
from lightcal.core.problem import LightUnknown, curve_rid
from lightcal.core.rid import CosPowerRID, SymmetricTableRID
from lightcal.core.scene import Rig
from lightcal.core.solver import run_least_squares
from lightcal.io.project import load_project
from lightcal.pipeline import build_model, calibrate_project, load_images
from lightcal.synthetic.dataset import SynthConfig, write_dataset
from lightcal.synthetic.scenes import RigConfig, SceneConfig, symmetric_profile_table
from tests import calib_scenes as cs

DISTORTED = cs.small_camera()


# ------------------------------------------------------------ noise-free, same model


@pytest.mark.parametrize("kind", ["symmetric", "general", "isotropic", "two_lights"])
def test_noise_free_recovery(kind):
    rigs = {
        "symmetric": Rig.single(cs.symmetric_light()),
        "general": Rig.single(cs.general_light()),
        "isotropic": Rig.single(cs.isotropic_light()),
        "two_lights": cs.two_light_rig(),
    }
    rig = rigs[kind]
    images = cs.observe(DISTORTED, cs.views(12, seed=6), rig, rng=np.random.default_rng(6))
    pose_kind: PoseKind | None = "isotropic" if kind == "isotropic" else None
    starts = [
        LightUnknown(cs.start_near(light, position_m=0.08, angle_deg=12.0), pose_kind=pose_kind)
        for light in rig.lights
    ]
    model = cs.model_of(images, starts)
    out = run_least_squares(model)
    assert out.success
    for est, truth in zip(model.layout.rig(out.x).lights, rig.lights, strict=True):
        position, axis = cs.pose_errors(est, truth)
        assert position < 1e-6
        if kind != "isotropic":
            assert axis < 1e-4
        if kind == "general":
            assert cs.rotation_error_deg(est, truth) < 1e-4  # the roll too
        assert est.scale == pytest.approx(truth.scale, rel=1e-6)


def test_noise_free_recovery_with_pose_kind_general_for_a_symmetric_light():
    """A full-pose model of a symmetric light: the axis is right, the roll is free."""
    light = cs.symmetric_light()
    images = cs.observe(
        DISTORTED, cs.views(12, seed=6), Rig.single(light), rng=np.random.default_rng(6)
    )
    start = LightUnknown(cs.start_near(light), pose_kind="general")
    model = cs.model_of(images, [start])
    out = run_least_squares(model)
    est = model.layout.rig(out.x).lights[0]
    position, axis = cs.pose_errors(est, light)
    assert position < 1e-6 and axis < 1e-4


# ------------------------------------------------------------- realistic synth datasets


def _dataset(tmp_path_factory, name: str, config: SynthConfig, selection: dict | None = None):
    """Write a synth dataset; optionally replace its project's selection."""
    ds = write_dataset(tmp_path_factory.mktemp(name) / "data", config)
    if selection is not None:
        doc = json.loads(ds.project_path.read_text())
        doc["selection"] = selection
        ds.project_path.write_text(json.dumps(doc))
    return ds


def _calibrate(ds):
    _, model, result = calibrate_project(load_project(ds.project_path))
    return model, result, model.layout.rig(np.array(result.x))


@pytest.fixture(scope="module")
def realistic(tmp_path_factory):
    """12 noisy 14-bit images at 0.8-2.5 m, poses 0.5 mm / 0.05 deg off, 400 pixels each."""
    config = SynthConfig(camera=DISTORTED, seed=3)
    assert config.sensor.bit_depth == 14 and config.sensor.noise
    assert config.scene.n_views == 12 and config.scene.distance_range_m == (0.8, 2.5)
    assert (config.pose_noise_m, config.pose_noise_deg) == (0.0005, 0.05)
    return _dataset(tmp_path_factory, "realistic", config, {"n_per_image": 400})


def test_realistic_noise(realistic):
    model, result, rig = _calibrate(realistic)
    assert result.converged
    assert result.warnings == []
    position, axis = cs.pose_errors(rig.lights[0], realistic.rig.lights[0])
    assert position < 0.003
    assert axis < 0.2
    assert rig.lights[0].scale == pytest.approx(realistic.rig.lights[0].scale, rel=0.02)
    # The weighted residuals look like the noise: reduced chi^2 ~ 1 (poses add a little).
    r = model.residuals(np.array(result.x))
    assert float(r @ r) / (model.m - model.layout.n) == pytest.approx(1.0, abs=0.3)


def test_start_45_degrees_and_1_5_m_off(tmp_path_factory):
    config = SynthConfig(
        camera=DISTORTED,
        scene=SceneConfig(distance_range_m=(2.0, 4.0)),
        init_offset_m=1.5,
        init_offset_deg=45.0,
        seed=1,
    )
    ds = _dataset(tmp_path_factory, "far", config, {"n_per_image": 400})
    truth = ds.rig.lights[0]
    initial = ds.initial_lights[0]
    position, axis = cs.pose_errors(initial, truth)
    assert position == pytest.approx(1.5) and axis == pytest.approx(45.0)
    _model, result, rig = _calibrate(ds)
    assert result.converged
    position, axis = cs.pose_errors(rig.lights[0], truth)
    assert position < 0.01 and axis < 0.3
    # The same minimum as from the truth.
    project = load_project(ds.project_path)
    at_truth = build_model(project, load_images(project), lights=[LightUnknown(truth)])
    near = run_least_squares(at_truth)
    np.testing.assert_allclose(result.x, near.x, atol=1e-6, rtol=1e-6)


def test_non_symmetric_light(tmp_path_factory):
    config = SynthConfig(camera=DISTORTED, rig=RigConfig(model="table2d"), seed=2)
    ds = _dataset(tmp_path_factory, "table2d", config, {"n_per_image": 400})
    _model, result, rig = _calibrate(ds)
    assert result.converged
    assert result.lights[0].pose_kind == "general"
    truth = ds.rig.lights[0]
    position, axis = cs.pose_errors(rig.lights[0], truth)
    assert position < 0.003 and axis < 0.2
    assert cs.rotation_error_deg(rig.lights[0], truth) < 0.3  # roll included


def test_two_lights_with_realistic_noise():
    """Two lights (30 and 40 degree beams either side of the camera), synth-like noise.

    Two lights are far less well conditioned than one (each pixel sees their sum): with
    100 pixels per image the position sigma is ~1 cm, so this uses 1500 per image.
    """
    rig = Rig(tuple(light.replace(scale=11.0 * light.scale) for light in cs.two_light_rig().lights))
    # The 14-bit sensor of `SynthConfig`: 0.79 DN per electron, read variance 5.75 DN^2,
    # peak ~11000 DN above black.
    images = cs.observe(
        DISTORTED,
        cs.views(12),
        rig,
        n_per_image=1500,
        rng=np.random.default_rng(1),
        noise=(0.79355, 5.7508),
    )
    model = cs.model_of(images, [cs.start_near(light) for light in rig.lights])
    out = run_least_squares(model)
    assert out.success
    for est, truth in zip(model.layout.rig(out.x).lights, rig.lights, strict=True):
        position, axis = cs.pose_errors(est, truth)
        assert position < 0.003 and axis < 0.3
        assert est.scale == pytest.approx(truth.scale, rel=0.02)


def test_two_light_synth_dataset_calibrates(tmp_path_factory):
    config = SynthConfig(camera=DISTORTED, rig=RigConfig(n_lights=2), seed=0)
    ds = _dataset(tmp_path_factory, "two", config)
    _, result, rig = _calibrate(ds)
    # Two identical 30-degree beams 8-12 cm apart are nearly interchangeable: this
    # dataset checks that the solve stays finite and positive (it used to overflow);
    # recovery of two distinct lights is in test_two_lights_with_realistic_noise.
    assert np.all(np.isfinite(result.x))
    assert all(est.scale > 0.0 and np.isfinite(est.scale) for est in rig.lights)


# ---------------------------------------------------------------------- RID estimation


def test_cos_power_exponent_noise_free():
    light = cs.symmetric_light(half_angle_deg=25.0)
    images = cs.observe(DISTORTED, cs.views(12), Rig.single(light), rng=np.random.default_rng(0))
    start = cs.start_near(light).replace(rid=CosPowerRID.from_half_angle(math.radians(40.0)))
    model = cs.model_of(images, [LightUnknown(start, estimate_rid="cos_power")])
    out = run_least_squares(model)
    est = model.layout.rig(out.x).lights[0]
    assert isinstance(est.rid, CosPowerRID) and isinstance(light.rid, CosPowerRID)
    assert est.rid.m == pytest.approx(light.rid.m, rel=1e-8)
    assert cs.pose_errors(est, light)[0] < 1e-6


def test_cos_power_exponent_with_noise():
    light = cs.symmetric_light(half_angle_deg=25.0)
    images = cs.observe(
        DISTORTED, cs.views(12), Rig.single(light), rng=np.random.default_rng(0), noise=(0.5, 4.0)
    )
    start = cs.start_near(light).replace(rid=CosPowerRID.from_half_angle(math.radians(40.0)))
    model = cs.model_of(images, [LightUnknown(start, estimate_rid="cos_power")])
    out = run_least_squares(model)
    est = model.layout.rig(out.x).lights[0]
    assert isinstance(est.rid, CosPowerRID) and isinstance(light.rid, CosPowerRID)
    assert est.rid.m == pytest.approx(light.rid.m, rel=0.01)
    assert math.degrees(est.rid.half_angle_rad) == pytest.approx(25.0, abs=0.2)


def test_curve_recovers_a_representable_profile():
    light = cs.symmetric_light()
    q = np.array([-3.0, -1.9, -1.2, -0.7, -0.3, 0.0])
    theta_max = math.radians(40.0)  # inside the angles the pixels see (up to ~43 degrees)
    truth = light.replace(rid=curve_rid(theta_max, q))
    images = cs.observe(
        DISTORTED, cs.views(12), Rig.single(truth), rng=np.random.default_rng(0), min_fraction=0
    )
    start = cs.start_near(truth).replace(rid=CosPowerRID.from_half_angle(math.radians(30.0)))
    unknown = LightUnknown(
        start, estimate_rid="curve", curve_knots=6, curve_max_angle_rad=theta_max
    )
    model = cs.model_of(images, [unknown])
    out = run_least_squares(model)
    assert out.success
    np.testing.assert_allclose(out.x[model.layout.blocks[0].rid], q, atol=1e-6)
    assert cs.pose_errors(model.layout.rig(out.x).lights[0], truth)[0] < 1e-6


def _smooth_profile_problem():
    theta_deg, values = symmetric_profile_table(30.0)
    truth = cs.symmetric_light().replace(rid=SymmetricTableRID(np.radians(theta_deg), values))
    images = cs.observe(
        DISTORTED,
        cs.views(12),
        Rig.single(truth),
        n_per_image=200,
        rng=np.random.default_rng(0),
        min_fraction=0,
    )
    start = cs.start_near(truth).replace(rid=CosPowerRID.from_half_angle(math.radians(22.0)))
    return truth, images, start


def test_curve_follows_a_smooth_profile():
    truth, images, start = _smooth_profile_problem()
    unknown = LightUnknown(
        start, estimate_rid="curve", curve_knots=6, curve_max_angle_rad=math.radians(40.0)
    )
    model = cs.model_of(images, [unknown])
    out = run_least_squares(model)
    assert out.success
    est = model.layout.rig(out.x).lights[0]
    theta = np.radians(np.linspace(0.0, 38.0, 39))
    assert np.abs(est.rid(theta) - truth.rid(theta)).max() < 0.01
    assert math.degrees(est.rid.half_angle_rad) == pytest.approx(30.0, abs=0.2)
    position, axis = cs.pose_errors(est, truth)
    assert position < 0.001 and axis < 0.02


@pytest.mark.slow
def test_curve_with_the_default_max_angle():
    truth, images, start = _smooth_profile_problem()
    model = cs.model_of(
        images, [LightUnknown(start, estimate_rid="curve", curve_knots=6)], max_iterations=30
    )
    out = run_least_squares(model)
    est = model.layout.rig(out.x).lights[0]
    theta = np.radians(np.linspace(0.0, 38.0, 39))
    assert out.success
    assert np.abs(est.rid(theta) - truth.rid(theta)).max() < 0.01
