"""The fall-off estimated with the light (`lightcal.core.fall_off`): V's convention, the
analytic Jacobian of its coefficients against finite differences, the rendered values,
recovery of a synthetic truth and the bad-input errors."""

from __future__ import annotations

import math

import numpy as np
import pytest

from lightcal.core.fall_off import FALL_OFF_BOUND, FallOffUnknown
from lightcal.core.problem import ImageData, LightUnknown, WallUnknown
from lightcal.core.render import shade
from lightcal.core.scene import Rig
from lightcal.core.solver import CalibrationModel, SolverOptions, run_least_squares
from lightcal.core.vignetting import RadialVignetting
from lightcal.core.wall import PlasticWall
from tests import calib_scenes as cs
from tests.test_solver import _numeric_jacobian

CAMERA = cs.small_camera()
TRUE_COEFFS = np.array([-0.25, 0.05])


def _fall_off(order: int = 2, binning: int = 1) -> FallOffUnknown:
    return FallOffUnknown(order, CAMERA.width, CAMERA.height, binning)


def _vignetted(images: list[ImageData], coeffs: np.ndarray) -> list[ImageData]:
    """The images with their values (offset 0) times V of `coeffs`, sigma likewise."""
    f = FallOffUnknown(len(coeffs), CAMERA.width, CAMERA.height)
    out = []
    for im in images:
        v = f.factor(im.footprints.pixels, coeffs)
        out.append(ImageData(im.name, im.view, im.footprints, im.observed * v, im.sigma, im.noise))
    return out


def test_r_is_one_at_the_sensor_corners_and_zero_at_its_centre():
    f = _fall_off()
    w, h = CAMERA.width, CAMERA.height
    r2 = f.r2(np.array([[0, 0], [w - 1, h - 1], [0, h - 1]]))
    # Pixel centres: the corner pixel's centre sits half a pixel inside the sensor's corner.
    corner = math.hypot(w / 2 - 0.5, h / 2 - 0.5) ** 2 / math.hypot(w / 2, h / 2) ** 2
    np.testing.assert_allclose(r2, corner, rtol=1e-14)
    np.testing.assert_allclose(f.powers(np.array([[0, 0]])), [[corner, corner**2]], rtol=1e-14)


def test_v_is_radial_vignettings_at_the_super_pixel_centre():
    coeffs = np.array([-0.3, 0.1, -0.02])
    pixels = np.array([[0, 0], [17, 5], [39, 29]])
    binned = FallOffUnknown(3, CAMERA.width, CAMERA.height, binning=8)
    centres = pixels * 8 + 3.5  # the full-resolution centre of each 8 x 8 super-pixel
    reference = RadialVignetting.centered(coeffs, width=CAMERA.width, height=CAMERA.height)
    np.testing.assert_allclose(
        binned.factor(pixels, coeffs), reference.evaluate(centres), rtol=1e-14
    )


def test_extremes_and_implausible_coefficients():
    f = _fall_off()
    assert f.extremes(TRUE_COEFFS) == pytest.approx((0.8, 1.0))
    assert f.implausible(TRUE_COEFFS) is None
    assert "reaches" in (f.implausible(np.array([-1.5, 0.0])) or "")
    assert "bound" in (f.implausible(np.array([-FALL_OFF_BOUND, FALL_OFF_BOUND])) or "")


@pytest.mark.parametrize(
    ("options", "wall", "last"),
    [
        # Equal exposures: the estimated offset is the room light too (no "ambient").
        ({"estimate_gains": True, "estimate_offset": True, "offset": 3.0}, None, "offset"),
        (
            {"estimate_ambient": False},
            WallUnknown(PlasticWall(0.3, 1.5, 2.0), ("roughness", "specular_weight")),
            "wall.specular_weight",
        ),
        ({"estimate_ambient": True, "estimate_gains": True}, None, "ambient"),
    ],
    ids=["gains_offset", "plastic_wall", "ambient_gains"],
)
def test_jacobian_matches_finite_differences(options: dict, wall: WallUnknown | None, last: str):
    light = cs.symmetric_light()
    images = cs.observe(
        CAMERA, cs.views(3, seed=2), Rig.single(light), n_per_image=40,
        rng=np.random.default_rng(1), noise=(0.5, 4.0),
    )  # fmt: skip
    opts = SolverOptions(fall_off=_fall_off(3), **options)
    model = CalibrationModel(images, [LightUnknown(cs.start_near(light))], opts, wall)
    names = ["fall_off.c1", "fall_off.c2", "fall_off.c3"]
    tail = [*names, last] if last == "ambient" else [last, *names]
    assert model.layout.names[-4:] == tail
    x = model.layout.x0.copy()
    x[model.layout.fall_off] = [-0.3, 0.08, 0.01]  # away from 0: products with V tested
    if model.layout.ambient_index is not None:
        x[model.layout.ambient_index] = 40.0
        x[model.layout.gains] = [0.2, -0.3]
    J = model.jacobian(x)
    Jn = _numeric_jacobian(model, x)
    for k, name in enumerate(model.layout.names):
        scale = np.abs(Jn[:, k]).max()
        assert scale > 0.0, name
        assert np.abs(J[:, k] - Jn[:, k]).max() <= 1e-6 * scale, name


def test_residuals_are_the_rendered_values_times_v():
    light = cs.symmetric_light()
    images = cs.observe(CAMERA, cs.views(2, seed=4), Rig.single(light), n_per_image=30,
                        rng=np.random.default_rng(3))  # fmt: skip
    model = CalibrationModel(
        images, [LightUnknown(light)], SolverOptions(offset=2.0, fall_off=_fall_off())
    )
    x = model.layout.x0.copy()
    x[model.layout.fall_off] = TRUE_COEFFS
    r = model.residuals(x)
    reference = RadialVignetting.centered(TRUE_COEFFS, width=CAMERA.width, height=CAMERA.height)
    for i, im in enumerate(images):
        v = reference.evaluate(im.footprints.pixels)
        rendered = 2.0 + v * shade(im.footprints, im.view, Rig.single(light)).values
        expected = (im.observed - rendered) / im.sigma
        np.testing.assert_allclose(r[model.bounds[i] : model.bounds[i + 1]], expected, rtol=1e-12)


def test_recovers_the_fall_off_and_the_light_from_noise_free_data():
    light = cs.symmetric_light()
    clean = cs.observe(CAMERA, cs.views(12, seed=5), Rig.single(light), n_per_image=150,
                       rng=np.random.default_rng(6))  # fmt: skip
    images = _vignetted(clean, TRUE_COEFFS)
    model = CalibrationModel(
        images, [LightUnknown(cs.start_near(light))], SolverOptions(fall_off=_fall_off())
    )
    lo, hi = model.parameter_bounds()
    assert np.all(lo[model.layout.fall_off] == -FALL_OFF_BOUND)
    assert np.all(hi[model.layout.fall_off] == FALL_OFF_BOUND)
    out = run_least_squares(model)
    np.testing.assert_allclose(out.x[model.layout.fall_off], TRUE_COEFFS, atol=1e-6)
    position, axis = cs.pose_errors(model.layout.rig(out.x).lights[0], light)
    assert position < 1e-6 and axis < 1e-5


@pytest.mark.parametrize(
    ("fields", "message"),
    [
        ({"order": 0}, "fall-off: order: expected an integer >= 1, got 0"),
        ({"order": -1}, "fall-off: order: expected an integer >= 1, got -1"),
        ({"order": 4}, "fall-off: order: expected at most 3, got 4"),
        ({"order": True}, "fall-off: order: expected an integer >= 1, got True"),
        ({"order": 2.0}, "fall-off: order: expected an integer >= 1, got 2.0"),
        ({"binning": 0}, "fall-off: binning: expected an integer >= 1, got 0"),
        ({"width": -3}, "fall-off: width: expected an integer >= 1, got -3"),
    ],
)
def test_bad_fall_off_is_an_error_naming_the_field(fields: dict, message: str):
    args = {"order": 2, "width": 320, "height": 240, "binning": 1} | fields
    with pytest.raises(ValueError) as info:
        FallOffUnknown(**args)
    assert str(info.value) == message


def test_room_light_grows_with_the_exposure_and_goes_through_v():
    """m = b + g_i (lights + e_i a) V: the closed form, with images of different exposures."""
    light = cs.symmetric_light()
    views = [cs.with_exposure(v, e) for v, e in zip(cs.views(2, seed=4), (1.0, 0.5), strict=True)]
    images = cs.observe(CAMERA, views, Rig.single(light), n_per_image=30,
                        rng=np.random.default_rng(3))  # fmt: skip
    options = SolverOptions(
        offset=2.0, fall_off=_fall_off(), estimate_ambient=True, estimate_gains=True
    )
    model = CalibrationModel(images, [LightUnknown(light)], options)
    x = model.layout.x0.copy()
    x[model.layout.fall_off] = TRUE_COEFFS
    x[model.layout.ambient_index] = 30.0
    x[model.layout.gains] = [math.log(1.5)]
    r = model.residuals(x)
    reference = RadialVignetting.centered(TRUE_COEFFS, width=CAMERA.width, height=CAMERA.height)
    for i, (im, g, e) in enumerate(zip(images, (1.0, 1.5), (1.0, 0.5), strict=True)):
        v = reference.evaluate(im.footprints.pixels)
        lights = g * shade(im.footprints, im.view, Rig.single(light)).values
        rendered = 2.0 + v * (lights + g * e * 30.0)
        expected = (im.observed - rendered) / im.sigma
        np.testing.assert_allclose(r[model.bounds[i] : model.bounds[i + 1]], expected, rtol=1e-12)


def test_recovers_the_room_light_beside_the_offset_when_exposures_differ():
    """Room light (g_i e_i a) and a black-level error (b) are told apart by the exposures."""
    light = cs.symmetric_light()
    exposures = np.linspace(0.5, 2.0, 8)
    views = [cs.with_exposure(v, e) for v, e in zip(cs.views(8, seed=7), exposures, strict=True)]
    clean = cs.observe(CAMERA, views, Rig.single(light), n_per_image=150,
                       rng=np.random.default_rng(8))  # fmt: skip
    peak = max(float(im.observed.max()) for im in clean)
    a, b = 0.05 * peak, 3.0
    images = [
        ImageData(im.name, im.view, im.footprints, im.observed + im.view.exposure * a + b, im.sigma)
        for im in clean
    ]
    options = SolverOptions(estimate_ambient=True, estimate_offset=True)
    model = CalibrationModel(images, [LightUnknown(cs.start_near(light))], options)
    out = run_least_squares(model)
    assert model.layout.ambient(out.x) == pytest.approx(a, rel=1e-6)
    assert model.layout.offset(out.x) == pytest.approx(b, rel=1e-6)
    position, axis = cs.pose_errors(model.layout.rig(out.x).lights[0], light)
    assert position < 1e-6 and axis < 1e-5


def test_a_planned_view_takes_v_at_the_camera_s_pixels():
    """The selection works in 4 x 4 super-pixels, a planned view in the camera's pixels:
    its rendered values carry V of those pixels (`camera_pixel_model`)."""
    from lightcal.pipeline.plan import camera_pixel_model, camera_pixel_options
    from lightcal.pipeline.plan_candidates import PlanGrid, candidate_image

    light = cs.symmetric_light()
    views = cs.views(3, seed=2)
    images = cs.observe(CAMERA, views, Rig.single(light), n_per_image=40,
                        rng=np.random.default_rng(1))  # fmt: skip
    options = SolverOptions(fall_off=_fall_off(binning=4))
    model = CalibrationModel(images, [LightUnknown(light)], options)
    unbinned = camera_pixel_options(options).fall_off
    assert unbinned is not None and unbinned.binning == 1 and unbinned.order == 2
    x = model.layout.x0.copy()
    x[model.layout.fall_off] = TRUE_COEFFS
    planned = camera_pixel_model(model)
    assert planned.layout.names == model.layout.names
    image = candidate_image(planned, x, CAMERA, views[0], PlanGrid(), "plan")
    assert image is not None
    lights = shade(image.footprints, image.view, Rig.single(light)).values
    v = _fall_off(binning=1).factor(image.footprints.pixels, TRUE_COEFFS)
    np.testing.assert_allclose(image.observed, lights * v, rtol=1e-12)
    assert (
        np.abs(v - _fall_off(binning=4).factor(image.footprints.pixels, TRUE_COEFFS)).max() > 0.05
    )
