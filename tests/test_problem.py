"""The calibration problem: parameter layout, RID parameterisations, ImageData checks."""

from __future__ import annotations

import math

import numpy as np
import pytest

from lightcal.core.footprint import pixel_footprints
from lightcal.core.pose import angles_from_axis
from lightcal.core.problem import (
    ImageData,
    LightUnknown,
    ParameterLayout,
    curve_params_from_rid,
    curve_rid,
    with_view,
)
from lightcal.core.rid import CosPowerRID, GaussianRID, SymmetricTableRID
from lightcal.core.scene import Light
from tests import calib_scenes as cs


def _layout(unknowns, n_images=1, *, gains=False, offset=False, offset0=0.0):
    return ParameterLayout.build(
        unknowns, n_images, estimate_gains=gains, estimate_offset=offset, offset0=offset0
    )


# ------------------------------------------------------------------------- pose blocks


def test_symmetric_light_layout_names_and_start():
    light = cs.symmetric_light(scale=250.0)
    lay = _layout([LightUnknown(light)])
    assert lay.n == 6
    assert lay.names == [
        "light.x_m",
        "light.y_m",
        "light.z_m",
        "light.a_rad",
        "light.b_rad",
        "light.log_scale",
    ]
    np.testing.assert_allclose(lay.x0[:3], light.t_camera_light, rtol=0, atol=0)
    np.testing.assert_allclose(lay.x0[3:5], angles_from_axis(light.axis_camera), atol=1e-15)
    assert lay.x0[5] == pytest.approx(math.log(250.0), abs=1e-15)
    back = lay.rig(lay.x0).lights[0]
    np.testing.assert_allclose(back.axis_camera, light.axis_camera, atol=1e-14)
    np.testing.assert_allclose(back.t_camera_light, light.t_camera_light, atol=0)
    assert back.scale == pytest.approx(250.0, rel=1e-14)
    assert back.rid is light.rid
    assert back.name == "light"
    np.testing.assert_array_equal(lay.gain_factors(lay.x0), [1.0])
    assert lay.offset_index is None
    assert lay.offset(lay.x0) == 0.0


def test_isotropic_and_general_pose_sizes():
    iso = _layout([LightUnknown(cs.isotropic_light(), pose_kind="isotropic")])
    assert iso.n == 4
    assert iso.names == ["light.x_m", "light.y_m", "light.z_m", "light.log_scale"]
    np.testing.assert_array_equal(iso.rig(iso.x0).lights[0].R_camera_light, np.eye(3))

    light = cs.general_light()
    gen = _layout([LightUnknown(light)])
    assert gen.n == 7
    assert gen.names[3:6] == ["light.dx_rad", "light.dy_rad", "light.dz_rad"]
    # The general chart is centred on the initial rotation: delta starts at 0.
    np.testing.assert_array_equal(gen.x0[3:6], 0.0)
    np.testing.assert_allclose(gen.rig(gen.x0).lights[0].R_camera_light, light.R_camera_light)


def test_pose_kind_follows_the_rid_unless_given():
    assert LightUnknown(cs.symmetric_light()).kind() == "symmetric"
    assert LightUnknown(cs.general_light()).kind() == "general"
    assert LightUnknown(cs.isotropic_light(), pose_kind="isotropic").kind() == "isotropic"
    # A symmetric light may be given a full pose (its roll is then unobservable).
    lay = _layout([LightUnknown(cs.symmetric_light(), pose_kind="general")])
    assert lay.n == 7


def test_isotropic_rid_defaults_to_the_isotropic_pose():
    unknown = LightUnknown(cs.isotropic_light())
    assert unknown.kind() == "isotropic"
    assert _layout([unknown]).n == 4


def test_two_lights_have_consecutive_blocks():
    rig = cs.two_light_rig()
    lay = _layout([LightUnknown(light) for light in rig.lights], 3, gains=True, offset=True)
    b0, b1 = lay.blocks
    assert (b0.pose, b0.log_scale) == (slice(0, 5), 5)
    assert (b1.pose, b1.log_scale) == (slice(6, 11), 11)
    assert lay.gains == slice(12, 14)
    assert lay.offset_index == 14
    assert lay.n == 15
    assert lay.names[6] == "right.x_m"
    assert lay.names[12:] == ["image1.log_gain", "image2.log_gain", "offset"]
    lights = lay.rig(lay.x0).lights
    assert [light.name for light in lights] == ["left", "right"]
    assert lights[1].scale == pytest.approx(0.7 * cs.SCALE)


# ----------------------------------------------------------------------- gains, offset


def test_gains_fix_the_first_image():
    lay = _layout([LightUnknown(cs.symmetric_light())], 4, gains=True)
    assert lay.gains == slice(6, 9)
    x = lay.x0.copy()
    x[lay.gains] = np.log([2.0, 3.0, 0.5])
    np.testing.assert_allclose(lay.gain_factors(x), [1.0, 2.0, 3.0, 0.5], rtol=1e-15)
    np.testing.assert_array_equal(lay.gain_factors(lay.x0), np.ones(4))


def test_a_single_image_has_no_free_gain():
    lay = _layout([LightUnknown(cs.symmetric_light())], 1, gains=True)
    assert lay.gains.stop == lay.gains.start
    assert lay.n == 6


def test_offset_known_or_estimated():
    known = _layout([LightUnknown(cs.symmetric_light())], offset0=12.5)
    assert known.offset(known.x0) == 12.5
    est = _layout([LightUnknown(cs.symmetric_light())], offset=True, offset0=12.5)
    assert est.offset_index == 6 and est.x0[6] == 12.5
    x = est.x0.copy()
    x[6] = -3.0
    assert est.offset(x) == -3.0


# ------------------------------------------------------------------------ RID estimation


def test_cos_power_estimate_holds_log_m():
    light = cs.symmetric_light()
    assert isinstance(light.rid, CosPowerRID)
    lay = _layout([LightUnknown(light, estimate_rid="cos_power")])
    assert lay.names[-1] == "light.log_m"
    assert lay.blocks[0].rid == slice(6, 7)
    assert lay.x0[6] == pytest.approx(math.log(light.rid.m), abs=1e-15)
    x = lay.x0.copy()
    x[6] = math.log(7.0)
    rid = lay.rid_of(lay.blocks[0], x)
    assert isinstance(rid, CosPowerRID)
    assert rid.m == pytest.approx(7.0, rel=1e-14)
    assert lay.rig(x).lights[0].rid.m == pytest.approx(7.0, rel=1e-14)


def test_cos_power_start_from_another_profile_keeps_its_half_angle():
    gauss = GaussianRID.from_half_angle(math.radians(22.0))
    light = cs.symmetric_light().replace(rid=gauss)
    lay = _layout([LightUnknown(light, estimate_rid="cos_power")])
    rid = lay.rid_of(lay.blocks[0], lay.x0)
    assert math.degrees(rid.half_angle_rad) == pytest.approx(22.0, abs=1e-6)


def test_curve_rid_is_monotone_with_unit_axis():
    q = np.array([-3.0, -2.0, -1.0, -0.5, 0.0, 0.3])
    rid = curve_rid(math.radians(60.0), q)
    assert isinstance(rid, SymmetricTableRID)
    np.testing.assert_allclose(rid.theta_rad, np.radians(np.arange(0.0, 61.0, 10.0)))
    expected = np.concatenate([[1.0], np.exp(-np.cumsum(np.exp(q)))])
    np.testing.assert_allclose(rid.values, expected, rtol=1e-14)
    theta = np.linspace(0.0, math.radians(60.0), 500)
    f = rid(theta)
    assert f[0] == 1.0
    assert np.all(np.diff(f) <= 1e-15)
    assert rid(np.array(math.radians(61.0))) == 0.0  # beyond theta_max


def test_curve_parameters_round_trip():
    q = np.array([-2.5, -1.7, -1.1, -0.4, 0.2])
    theta_max = math.radians(70.0)
    back = curve_params_from_rid(curve_rid(theta_max, q), theta_max, 5)
    np.testing.assert_allclose(back, q, atol=1e-9)


def test_curve_estimate_starts_on_the_initial_profile():
    light = cs.symmetric_light(half_angle_deg=30.0)
    lay = _layout([LightUnknown(light, estimate_rid="curve", curve_knots=8)])
    block = lay.blocks[0]
    assert block.rid == slice(6, 14)
    assert lay.names[6:8] == ["light.curve_q1", "light.curve_q2"]
    # Default theta_max: where the initial profile falls to 1 %.
    assert block.curve_theta_max == pytest.approx(light.rid.angle_at_level_rad(0.01))
    rid = lay.rid_of(block, lay.x0)
    knots = np.linspace(0.0, block.curve_theta_max, 9)
    exact = rid.value_and_derivatives(knots, exact=True)[0]
    np.testing.assert_allclose(exact, light.rid(knots), rtol=1e-9)
    np.testing.assert_allclose(rid(knots), light.rid(knots), rtol=0, atol=5e-6)  # its grid


def test_curve_max_angle_is_capped_at_89_degrees():
    wide = cs.symmetric_light().replace(rid=CosPowerRID(0.5))
    lay = _layout([LightUnknown(wide, estimate_rid="curve")])
    assert lay.blocks[0].curve_theta_max == pytest.approx(math.radians(89.0))
    given = _layout([LightUnknown(wide, estimate_rid="curve", curve_max_angle_rad=1.0)])
    assert given.blocks[0].curve_theta_max == 1.0


def test_rid_estimation_needs_a_symmetric_light():
    with pytest.raises(
        ValueError,
        match=r"^light light: RID estimation \(curve\) needs a rotationally symmetric light$",
    ):
        _layout([LightUnknown(cs.general_light(), estimate_rid="curve")])


# ---------------------------------------------------------------------------- ImageData


@pytest.fixture(scope="module")
def footprints():
    cam = cs.small_camera()
    view = cs.views(1)[0]
    fp = pixel_footprints(cam, view, np.array([[10, 20], [160, 120], [300, 200]]))
    assert fp.valid.all()
    return view, fp


def test_image_data_converts_to_float(footprints):
    view, fp = footprints
    im = ImageData("a", view, fp, np.array([1, 2, 3]), np.array([1, 1, 2]))
    assert im.observed.dtype == np.float64 and im.sigma.dtype == np.float64


@pytest.mark.parametrize(
    ("observed", "sigma", "message"),
    [
        ([1.0, 2.0], [1.0, 1.0, 1.0], r"^a: observed: expected shape \(3,\), got \(2,\)$"),
        ([1.0, 2.0, 3.0], [1.0], r"^a: sigma: expected shape \(3,\), got \(1,\)$"),
        (
            [1.0, np.nan, 3.0],
            [1.0, 1.0, 1.0],
            r"^a: observed: expected finite values, got NaN or inf$",
        ),
        ([1.0, 2.0, 3.0], [1.0, 0.0, 1.0], r"^a: sigma: expected values > 0$"),
    ],
)
def test_image_data_errors(footprints, observed, sigma, message):
    view, fp = footprints
    with pytest.raises(ValueError, match=message):
        ImageData("a", view, fp, np.array(observed), np.array(sigma))


def test_image_data_refuses_invalid_footprints():
    cam = cs.small_camera()
    # Grazing view of the wall; image "down" points away from it: the bottom rows see the sky.
    view = cs.View.looking_at(np.array([0.0, -1.5, 0.3]), np.array([0.0, 0.0, 0.0]))
    fp = pixel_footprints(cam, view, np.array([[160, 239], [160, 0]]))
    assert fp.valid.tolist() == [False, True]
    with pytest.raises(
        ValueError, match=r"^top: expected only valid footprints \(select valid pixels\)$"
    ):
        ImageData("top", view, fp, np.ones(2), np.ones(2))


def test_with_view_replaces_only_what_is_given():
    view = cs.views(1)[0]
    v2 = with_view(view, exposure=2.5)
    assert v2.exposure == 2.5
    np.testing.assert_array_equal(v2.R_camera_world, view.R_camera_world)
    np.testing.assert_array_equal(v2.t_camera_world, view.t_camera_world)


def test_light_scale_round_trips_through_log_scale():
    light = Light(cs.symmetric_light().rid, np.array([0.0, 0.1, 0.0]), scale=1e-7)
    lay = _layout([LightUnknown(light)])
    assert lay.rig(lay.x0).lights[0].scale == pytest.approx(1e-7, rel=1e-14)


def test_wild_log_scales_stay_finite_and_their_squares_too():
    light = Light(cs.symmetric_light().rid, np.array([0.0, 0.1, 0.0]), scale=1.0)
    lay = _layout([LightUnknown(light)])
    x = lay.x0.copy()
    block = lay.blocks[0]
    for v, expected in ((1e4, math.exp(300.0)), (-1e4, math.exp(-300.0))):
        x[block.log_scale] = v
        scale = lay.rig(x).lights[0].scale
        assert scale == expected
        assert math.isfinite(1e7 * (1e3 * scale) ** 2)  # a cost of 1e7 residuals stays finite
