"""Tests of the renderer (lightcal.core.render) against its NumPy twin and the physics.

The compiled kernels are tested only through the public functions (`render_pixels`,
`render_image`, `shade`), so any rewrite of `lightcal.core.kernels` must keep every number here.
"""

from __future__ import annotations

import dataclasses
import math
import re
from typing import Any

import numpy as np
import pytest

from lightcal.core.camera import Camera
from lightcal.core.footprint import SensorModel, pixel_footprints
from lightcal.core.render import render_image, render_pixels, shade
from lightcal.core.render_reference import render_image_reference, render_pixels_reference
from lightcal.core.rid import (
    RID,
    CosPowerRID,
    GaussianRID,
    IsotropicRID,
    SymmetricTableRID,
    Table2DRID,
)
from lightcal.core.scene import Light, Rig, View
from lightcal.core.solid_angle import quad_solid_angle
from tests.scenes import (
    MILD_DISTORTION,
    RID_NAMES,
    all_pixels,
    distorted_camera,
    horizon_view,
    light_fixed_in_world,
    mixed_rig,
    oblique_view,
    pinhole_camera,
    rid_model,
    rotation_about,
    rotation_with_z,
    straight_down_view,
    table_2d_values,
    telephoto_camera,
    two_light_rig,
    wide_camera,
)

SENSORS: tuple[SensorModel, ...] = ("radiance", "cos4", "paper", "map")


def _exact(message: str) -> str:
    return "^" + re.escape(message) + "$"


def _vignetting(camera: Camera) -> np.ndarray:
    """(H, W) a smooth fall-off map in (0.4, 1]."""
    vv, uu = np.mgrid[0 : camera.height, 0 : camera.width]
    r2 = ((uu - camera.cx) / camera.width) ** 2 + ((vv - camera.cy) / camera.height) ** 2
    return 1.0 - 1.5 * r2 + 0.01 * np.sin(uu)


def _assert_masked_close(actual: np.ma.MaskedArray, expected: np.ma.MaskedArray, rtol: float):
    """Same mask; every unmasked value within rtol of the expected one (0 only matches 0)."""
    assert actual.shape == expected.shape
    np.testing.assert_array_equal(np.ma.getmaskarray(actual), np.ma.getmaskarray(expected))
    valid = ~np.ma.getmaskarray(expected)
    a = np.asarray(actual.data)[valid]
    e = np.asarray(expected.data)[valid]
    assert np.all(np.isfinite(a))
    bad = ~(np.abs(a - e) <= rtol * np.abs(e))
    if np.any(bad):
        i = int(np.argmax(bad))
        raise AssertionError(
            f"{bad.sum()} of {a.size} values differ by more than {rtol:g} relative; "
            f"first: {a[i]!r} vs expected {e[i]!r}"
        )


def _point_irradiance(rid: RID, L_world: np.ndarray, R_world_light: np.ndarray, P: np.ndarray):
    """(N,) E = f(theta, phi) cos(theta_i) / r^2 at wall points P (N, 3), I0 = 1."""
    w = P - L_world
    r = np.linalg.norm(w, axis=1)
    u = (w / r[:, None]) @ R_world_light  # light frame
    theta = np.arctan2(np.hypot(u[:, 0], u[:, 1]), u[:, 2])
    phi = np.arctan2(u[:, 1], u[:, 0])
    return rid(theta, phi) * (L_world[2] / r) / r**2


def _pixel_center_on_wall(camera: Camera, view: View, pixels: np.ndarray) -> np.ndarray:
    """(N, 3) where the rays through the pixel centres hit the wall."""
    rays, ok = camera.rays_camera(pixels.astype(np.float64))
    assert ok.all()
    d = rays @ view.R_camera_world
    lam = -view.center_world[2] / d[:, 2]
    return view.center_world + lam[:, None] * d


# ---------------------------------------------------------------- kernels vs NumPy reference


@pytest.mark.parametrize("rid_subsamples", [1, 3])
@pytest.mark.parametrize("binning", [1, 3])
@pytest.mark.parametrize("sensor", SENSORS)
@pytest.mark.parametrize("rid_name", RID_NAMES)
def test_kernels_match_the_numpy_reference(
    rid_name: str, sensor: SensorModel, binning: int, rid_subsamples: int
) -> None:
    camera = distorted_camera()
    view = oblique_view(exposure=0.8)
    rig = two_light_rig(rid_model(rid_name))
    options: dict[str, Any] = {
        "sensor": sensor,
        "vignetting": _vignetting(camera) if sensor == "map" else None,
        "binning": binning,
        "offset": 0.0,  # an offset would hide relative errors of small values
        "rid_subsamples": rid_subsamples,
    }
    image = render_image(camera, view, rig, **options)
    reference = render_image_reference(camera, view, rig, **options)
    assert image.shape == (48 // binning, 64 // binning)
    _assert_masked_close(image, reference, 1e-12)
    # render_pixels at (u, v) is render_image at (u, v) and matches its twin; the pixels
    # are shuffled (order must not matter).
    subset = np.random.default_rng(20).permutation(all_pixels(64 // binning, 48 // binning))[:97]
    values = render_pixels(camera, view, rig, subset, **options)
    _assert_masked_close(values, image[subset[:, 1], subset[:, 0]], 1e-12)
    _assert_masked_close(
        values, render_pixels_reference(camera, view, rig, subset, **options), 1e-12
    )


def _stress_scene(name: str) -> tuple[Camera, View, Rig]:
    """Scenes at the edges of the kernels' numerical regimes."""
    if name == "telephoto":  # footprints of ~1e-9 sr
        camera = telephoto_camera()
        view = View.looking_at(np.array([0.4, -0.6, 4.5]), np.array([0.2, 0.3, 0.0]))
        axis = rotation_with_z((0.02, 0.35, 1.0))
        lights = (
            Light(CosPowerRID(12.0), np.array([0.25, -0.1, 0.02]), axis),
            Light(rid_model("table_2d"), np.array([-0.2, 0.1, 0.0]), axis, scale=0.3),
        )
    elif name == "light_near_wall":  # 1 mm above the wall: pixels subtend up to ~pi sr
        camera = wide_camera()
        view = straight_down_view(height_m=1.0)
        lights = (
            Light(IsotropicRID(), np.array([0.013, -0.021, 0.999])),
            Light(CosPowerRID(1.0), np.array([-0.004, 0.002, 0.9995]), scale=2.0),
        )
    elif name == "grazing":  # near the horizon, the lights' axes skim the wall
        camera = pinhole_camera()
        view = horizon_view()
        lights = (
            Light(CosPowerRID(2.0), np.array([0.05, 0.0, 0.0]), rotation_with_z((0.0, -1.0, 0.3))),
            Light(rid_model("gaussian"), np.zeros(3), rotation_with_z((0.2, -0.25, 1.0))),
        )
    elif name == "narrow_beams":  # values spanning a hundred decades
        camera = distorted_camera()
        view = oblique_view()
        lights = (
            Light(CosPowerRID(400.0), np.array([0.1, 0.0, 0.0]), rotation_with_z((0.1, 0.05, 1.0))),
            Light(
                GaussianRID(0.06),
                np.array([-0.1, 0.0, 0.0]),
                rotation_with_z((-0.1, -0.1, 1.0)),
            ),
        )
    else:  # "table_edges": the tables end inside the image (f = 0 beyond the last knot)
        camera = distorted_camera()
        view = oblique_view()
        theta = np.radians([0.0, 5.0, 12.0, 20.0])
        phi = np.array([0.0, 1.5, 3.0, 4.5])
        lights = (
            Light(SymmetricTableRID(theta, np.array([1.0, 0.9, 0.5, 0.2])), np.zeros(3)),
            Light(
                Table2DRID(theta, phi, table_2d_values(theta, phi) + 0.1),
                np.array([0.05, 0.05, 0.0]),
                rotation_with_z((0.1, 0.05, 1.0)),
            ),
        )
    return camera, view, Rig(lights)


@pytest.mark.parametrize(
    "scene", ["telephoto", "light_near_wall", "grazing", "narrow_beams", "table_edges"]
)
def test_kernels_match_the_numpy_reference_in_stress_scenes(scene: str) -> None:
    camera, view, rig = _stress_scene(scene)
    for binning, n_sub in ((1, 1), (2, 2)):
        image = render_image(camera, view, rig, binning=binning, rid_subsamples=n_sub)
        reference = render_image_reference(camera, view, rig, binning=binning, rid_subsamples=n_sub)
        _assert_masked_close(image, reference, 1e-12)
        pixels = all_pixels(64 // binning, 48 // binning)
        values = render_pixels(camera, view, rig, pixels, binning=binning, rid_subsamples=n_sub)
        _assert_masked_close(values, reference.reshape(-1), 1e-12)
        paper = render_image(camera, view, rig, binning=binning, sensor="paper")
        _assert_masked_close(
            paper, render_image_reference(camera, view, rig, binning=binning, sensor="paper"), 1e-12
        )
    valid = reference.compressed()
    assert valid.size > 0
    if scene == "light_near_wall":
        fp = pixel_footprints(camera, view, all_pixels(64, 48))
        unit = dataclasses.replace(fp, weights=np.ones_like(fp.weights))
        omega = shade(unit, view, Rig.single(rig.lights[0])).flux[0]
        assert omega.max() > 2.0  # the regime of large solid angles is really exercised
    if scene == "narrow_beams":
        assert valid.min() < 1e-20 * valid.max()
    if scene in ("grazing", "table_edges"):
        alone = render_image(camera, view, Rig.single(rig.lights[0])).compressed()
        assert np.any(alone == 0.0)
        assert np.any(alone > 0.0)


@pytest.mark.parametrize(
    ("skew", "dist"),
    [
        (0.0, (0.2, -0.05, 0.001, -0.002, 0.01, 0.15, -0.02, 0.005)),  # rational model
        (3.5, ()),
        (-2.0, MILD_DISTORTION),
        (0.0, (-0.5, 0.0, 0.0, 0.0)),  # folds over: the image corners do not undistort
    ],
)
def test_kernels_match_the_numpy_reference_for_any_camera_model(
    skew: float, dist: tuple[float, ...]
) -> None:
    folds = dist[:1] == (-0.5,)
    camera = Camera.from_params(
        fx=60.0, fy=61.2, cx=32.3, cy=22.7, width=64, height=48, dist=dist, skew=skew
    )
    view = straight_down_view(height_m=1.2) if folds else oblique_view()
    rig = two_light_rig(rid_model("cos_power"))
    for binning in (1, 2):
        image = render_image(camera, view, rig, binning=binning, sensor="cos4")
        reference = render_image_reference(camera, view, rig, binning=binning, sensor="cos4")
        _assert_masked_close(image, reference, 1e-12)
        if folds:
            assert 0 < image.mask.sum() < image.size // 2


def test_a_tall_image_matches_the_numpy_reference() -> None:
    # More rows than the kernels' parallel chunks, sizes not divisible by the binning.
    camera = pinhole_camera(width=203, height=151, focal_px=150.0, dist=MILD_DISTORTION)
    view = oblique_view(exposure=0.9)
    rig = two_light_rig(rid_model("table_2d"))
    for binning in (1, 2):
        image = render_image(camera, view, rig, binning=binning, sensor="cos4")
        assert image.shape == (151 // binning, 203 // binning)
        reference = render_image_reference(camera, view, rig, binning=binning, sensor="cos4")
        _assert_masked_close(image, reference, 1e-12)


@pytest.mark.parametrize("sensor", SENSORS)
def test_a_rig_mixing_every_rid_model_matches_the_numpy_reference(sensor: SensorModel) -> None:
    camera = distorted_camera()
    view = oblique_view(exposure=1.1)
    rig = mixed_rig()
    vignetting = _vignetting(camera) if sensor == "map" else None
    for binning, n_sub in ((1, 2), (3, 1)):
        options: dict[str, Any] = {
            "sensor": sensor,
            "vignetting": vignetting,
            "binning": binning,
            "rid_subsamples": n_sub,
            "offset": 0.0,
        }
        image = render_image(camera, view, rig, **options)
        _assert_masked_close(image, render_image_reference(camera, view, rig, **options), 1e-12)
        pixels = np.random.default_rng(21).permutation(all_pixels(64 // binning, 48 // binning))
        _assert_masked_close(
            render_pixels(camera, view, rig, pixels[:120], **options),
            render_pixels_reference(camera, view, rig, pixels[:120], **options),
            1e-12,
        )
    # Every light contributes: the rig is the sum of its lights rendered alone.
    alone = np.sum(
        [
            render_image(camera, view, Rig.single(light), sensor=sensor, vignetting=vignetting).data
            for light in rig.lights
        ],
        axis=0,
    )
    np.testing.assert_allclose(
        render_image(camera, view, rig, sensor=sensor, vignetting=vignetting).data,
        alone,
        rtol=1e-13,
    )


@pytest.mark.parametrize("binning", [1, 3])
def test_invalid_pixels_are_masked_where_rays_miss_the_wall(binning: int) -> None:
    camera = pinhole_camera()
    view = horizon_view()
    rig = two_light_rig(rid_model("cos_power"))
    pixels = all_pixels(64 // binning, 48 // binning)
    # Independent check: a (super-)pixel is valid iff every corner ray points down at z = 0.
    invalid = np.zeros(len(pixels), dtype=bool)
    for du in np.arange(binning + 1) - 0.5:
        for dv in np.arange(binning + 1) - 0.5:
            rays, _ = camera.rays_camera(pixels * binning + np.array([du, dv]))
            invalid |= ~((rays @ view.R_camera_world)[:, 2] < 0.0)
    assert 0.1 * len(pixels) < invalid.sum() < 0.9 * len(pixels)
    image = render_image(camera, view, rig, binning=binning)
    values = render_pixels(camera, view, rig, pixels, binning=binning)
    for result in (image.reshape(-1), values):
        np.testing.assert_array_equal(np.ma.getmaskarray(result), invalid)
        assert np.all(np.isnan(result.data[invalid]))
        assert np.all(np.isfinite(result.data[~invalid]))
        assert np.all(result.data[~invalid] > 0.0)
    _assert_masked_close(image, render_image_reference(camera, view, rig, binning=binning), 1e-12)


def test_light_on_or_behind_the_wall_illuminates_nothing() -> None:
    camera = pinhole_camera()
    view = straight_down_view(height_m=1.0)
    rid = IsotropicRID()
    on_wall = Light(rid, np.array([0.0, 0.0, 1.0]))  # camera frame z = 1 m below it: world z = 0
    assert on_wall.position_world(view)[2] == 0.0
    behind = light_fixed_in_world(rid, view, np.array([0.1, -0.2, -0.05]), np.eye(3))
    front = Light(rid, np.array([0.1, 0.0, 0.0]))
    pixels = all_pixels(64, 48)[::7]
    for light in (on_wall, behind):
        rig = Rig((light,))
        image = render_image(camera, view, rig, offset=0.25)
        assert not image.mask.any()
        np.testing.assert_array_equal(image.data, 0.25)
        np.testing.assert_array_equal(render_pixels(camera, view, rig, pixels, offset=0.25), 0.25)
        np.testing.assert_array_equal(
            render_pixels_reference(camera, view, rig, pixels, offset=0.25), 0.25
        )
        fp = pixel_footprints(camera, view, pixels)
        shading = shade(fp, view, rig, want_grad=True)
        np.testing.assert_array_equal(shading.flux, 0.0)
        assert shading.grad_position is not None and shading.grad_rotation is not None
        np.testing.assert_array_equal(shading.grad_position, 0.0)
        np.testing.assert_array_equal(shading.grad_rotation, 0.0)
        # Next to a light in front of the wall, it adds nothing.
        np.testing.assert_array_equal(
            render_image(camera, view, Rig((front, light))).data,
            render_image(camera, view, Rig((front,))).data,
        )


def test_exposure_offset_scale_and_lights_act_linearly() -> None:
    camera = distorted_camera()
    rid = rid_model("table_2d")
    rig = two_light_rig(rid)
    first, second = rig.lights
    pixels = all_pixels(64, 48)[::5]
    base_view = oblique_view(exposure=1.0)
    base = render_image(camera, base_view, rig, binning=3)
    bright = render_image(camera, oblique_view(exposure=2.5), rig, binning=3, offset=0.03)
    np.testing.assert_allclose(bright.data, 0.03 + 2.5 * base.data, rtol=1e-14)
    values = render_pixels(camera, base_view, rig, pixels)
    shifted = render_pixels(camera, oblique_view(exposure=0.4), rig, pixels, offset=-0.5)
    np.testing.assert_allclose(shifted.data, -0.5 + 0.4 * values.data, rtol=1e-13)
    # Lights add up and each one is linear in its scale.
    only_first = render_pixels(camera, base_view, Rig((first,)), pixels)
    only_second = render_pixels(camera, base_view, Rig((second,)), pixels)
    np.testing.assert_allclose(values.data, only_first.data + only_second.data, rtol=1e-14)
    tripled = render_pixels(camera, base_view, Rig((first.replace(scale=3 * first.scale),)), pixels)
    np.testing.assert_allclose(tripled.data, 3 * only_first.data, rtol=1e-14)
    image_sum = (
        render_image(camera, base_view, Rig((first,))).data
        + render_image(camera, base_view, Rig((second,))).data
    )
    np.testing.assert_allclose(render_image(camera, base_view, rig).data, image_sum, rtol=1e-14)


def test_shade_values_are_offset_plus_scales_times_flux() -> None:
    camera = distorted_camera()
    view = oblique_view(exposure=1.7)
    rig = two_light_rig(rid_model("gaussian"))
    pixels = all_pixels(64, 48)[::11]
    fp = pixel_footprints(camera, view, pixels, sensor="cos4")
    shading = shade(fp, view, rig, offset=0.2)
    assert shading.flux.shape == (2, len(pixels))
    assert shading.grad_position is None and shading.grad_rotation is None
    scales = np.array([light.scale for light in rig.lights])
    np.testing.assert_allclose(shading.values.data, 0.2 + scales @ shading.flux, rtol=1e-15)
    _assert_masked_close(
        shading.values,
        render_pixels(camera, view, rig, pixels, sensor="cos4", offset=0.2),
        1e-15,
    )


# ---------------------------------------------------------------- invariant: 2 pi and outlines


def test_wide_angle_footprints_sum_to_the_solid_angle_of_the_image() -> None:
    # A light at the camera centre sees each pixel's footprint under that pixel's own solid
    # angle: the sum is the solid angle of the image rectangle, 4 asin(sin a sin b).
    camera = wide_camera()
    view = straight_down_view(height_m=0.8)
    rig = Rig.single(Light(IsotropicRID(), np.zeros(3)))
    fp = pixel_footprints(camera, view, all_pixels(64, 48))
    assert fp.valid.all()
    unit = dataclasses.replace(fp, weights=np.ones_like(fp.weights))
    a = math.atan(64 / (2 * camera.fx))
    b = math.atan(48 / (2 * camera.fy))
    expected = 4 * math.asin(math.sin(a) * math.sin(b))
    assert expected > 2.0  # a wide angle: about a third of the hemisphere
    for n_sub in (1, 3):
        total = shade(unit, view, rig, rid_subsamples=n_sub).flux.sum()
        assert total == pytest.approx(expected, rel=1e-12)


def test_footprint_solid_angles_sum_to_the_image_outline_seen_from_the_light() -> None:
    camera = wide_camera()
    view = View.looking_at(np.array([0.2, -0.3, 1.1]), np.array([0.1, 0.2, 0.0]))
    light = Light(IsotropicRID(), np.array([0.3, -0.2, 0.1]))
    rig = Rig.single(light)
    fp = pixel_footprints(camera, view, all_pixels(64, 48))
    assert fp.valid.all()
    corners = np.array([[-0.5, -0.5], [63.5, -0.5], [63.5, 47.5], [-0.5, 47.5]])
    rays, _ = camera.rays_camera(corners)
    d = rays @ view.R_camera_world
    outline = view.center_world - (view.center_world[2] / d[:, 2])[:, None] * d
    expected = quad_solid_angle(light.position_world(view), outline[None])[0]
    unit = dataclasses.replace(fp, weights=np.ones_like(fp.weights))
    assert shade(unit, view, rig).flux.sum() == pytest.approx(expected, rel=1e-12)
    # The same through render_image: radiance values times footprint areas are fluxes.
    image = render_image(camera, view, rig, rid_subsamples=2)
    flux = (image.data.reshape(-1) * fp.area_m2).sum()
    assert flux == pytest.approx(expected, rel=1e-12)


# ---------------------------------------------------------------- invariant: additivity


@pytest.mark.parametrize("rid_name", ["isotropic", "cos_power", "table_2d"])
def test_super_pixel_flux_is_the_sum_of_its_pixels(rid_name: str) -> None:
    camera = distorted_camera()
    view = oblique_view()
    rig = two_light_rig(rid_model(rid_name))
    b = 3
    fine = pixel_footprints(camera, view, all_pixels(64, 48))
    coarse = pixel_footprints(camera, view, all_pixels(64 // b, 48 // b), binning=b)
    for n_sub in (1, 3):
        # Radiance weights are 1 / area: flux x area is the footprint flux / I0.
        phi_fine = shade(fine, view, rig, rid_subsamples=n_sub).flux * fine.area_m2
        phi_coarse = shade(coarse, view, rig, rid_subsamples=n_sub).flux * coarse.area_m2
        blocks = phi_fine.reshape(2, 48, 64)[:, : 16 * b, : 21 * b]
        summed = blocks.reshape(2, 16, b, 21, b).sum(axis=(2, 4)).reshape(2, -1)
        np.testing.assert_allclose(phi_coarse, summed, rtol=1e-12)


def test_binned_images_follow_the_sensor_rules() -> None:
    # radiance/cos4/map: one big pixel (mean V times the union's irradiance); paper: the mean.
    camera = distorted_camera()
    view = oblique_view()
    rig = two_light_rig(rid_model("table_1d"))
    vignetting = _vignetting(camera)
    b = 3
    area_fine = pixel_footprints(camera, view, all_pixels(64, 48)).area_m2.reshape(48, 64)
    area_fine = area_fine[: 16 * b, : 21 * b]
    area_coarse = pixel_footprints(camera, view, all_pixels(21, 16), binning=b).area_m2

    def block_sum(x: np.ndarray) -> np.ndarray:
        return x.reshape(16, b, 21, b).sum(axis=(1, 3)).reshape(-1)

    paper1 = render_image(camera, view, rig, sensor="paper").data[: 16 * b, : 21 * b]
    paper3 = render_image(camera, view, rig, sensor="paper", binning=b).data.reshape(-1)
    np.testing.assert_allclose(paper3, block_sum(paper1) / b**2, rtol=1e-12)

    rad1 = render_image(camera, view, rig).data[: 16 * b, : 21 * b]
    map1 = render_image(camera, view, rig, sensor="map", vignetting=vignetting).data
    map3 = render_image(camera, view, rig, sensor="map", vignetting=vignetting, binning=b)
    flux = block_sum(rad1 * area_fine)
    v_mean = block_sum(vignetting[: 16 * b, : 21 * b]) / b**2
    np.testing.assert_allclose(map3.data.reshape(-1), v_mean * flux / area_coarse, rtol=1e-12)
    np.testing.assert_allclose(
        map1[: 16 * b, : 21 * b], vignetting[: 16 * b, : 21 * b] * rad1, rtol=1e-12
    )
    rad3 = render_image(camera, view, rig, binning=b).data.reshape(-1)
    np.testing.assert_allclose(rad3, flux / area_coarse, rtol=1e-12)
    cos4_fine = render_image(camera, view, rig, sensor="cos4").data[: 16 * b, : 21 * b]
    cos4_mean = block_sum(cos4_fine / rad1) / b**2  # the pixels' own cos^4 factors
    cos4_3 = render_image(camera, view, rig, sensor="cos4", binning=b).data.reshape(-1)
    np.testing.assert_allclose(cos4_3, cos4_mean * flux / area_coarse, rtol=1e-12)


@pytest.mark.parametrize("n_sub", [2, 3, 5])
def test_rid_subsampling_conserves_isotropic_flux(n_sub: int) -> None:
    camera = distorted_camera()
    view = oblique_view()
    rig = two_light_rig(IsotropicRID())
    pixels = all_pixels(64, 48)[::3]
    sensors: tuple[SensorModel, ...] = ("radiance", "paper")
    for sensor in sensors:
        one = render_pixels(camera, view, rig, pixels, sensor=sensor)
        many = render_pixels(camera, view, rig, pixels, sensor=sensor, rid_subsamples=n_sub)
        _assert_masked_close(many, one, 1e-12)
    _assert_masked_close(
        render_image(camera, view, rig, binning=3, rid_subsamples=n_sub),
        render_image(camera, view, rig, binning=3),
        1e-12,
    )


def test_rid_subsampling_converges_for_a_sharp_profile() -> None:
    # A narrow beam over big footprints: refining the RID sampling converges like 1 / n^2.
    camera = pinhole_camera(width=24, height=18, focal_px=18.0)
    view = oblique_view()
    light = Light(CosPowerRID(400.0), np.zeros(3), rotation_with_z((0.05, 0.1, 1.0)))
    rig = Rig.single(light)
    pixels = all_pixels(24, 18)
    fine = render_pixels(camera, view, rig, pixels, rid_subsamples=24).data
    errors = [
        np.abs(render_pixels(camera, view, rig, pixels, rid_subsamples=n).data - fine).max()
        for n in (1, 2, 4)
    ]
    assert errors[0] > 1e-3 * fine.max()  # the test scene is sharp enough to matter
    assert errors[1] < 0.4 * errors[0]
    assert errors[2] < 0.4 * errors[1]


# ---------------------------------------------------------------- invariant: point formula


def _telephoto_scene(rid: RID) -> tuple[Camera, View, Light]:
    camera = telephoto_camera()
    view = View.looking_at(np.array([0.4, -0.6, 4.5]), np.array([0.2, 0.3, 0.0]), exposure=1.3)
    axis_camera = np.array([0.02, 0.35, 1.0])  # the wall point is ~20 degrees off the axis
    light = Light(
        rid,
        np.array([0.25, -0.1, 0.02]),
        rotation_with_z(axis_camera) @ rotation_about((0, 0, 1), 0.6),
        scale=2.2,
    )
    return camera, view, light


@pytest.mark.parametrize("rid_name", ["cos_power_12", "table_2d"])
def test_tiny_pixels_converge_to_the_point_formula(rid_name: str) -> None:
    rid = CosPowerRID(12.0) if rid_name == "cos_power_12" else rid_model("table_2d")
    camera, view, light = _telephoto_scene(rid)
    rig = Rig.single(light)
    pixels = np.array([[31, 23], [0, 0], [63, 47], [5, 40], [50, 9]])
    P = _pixel_center_on_wall(camera, view, pixels)
    L = light.position_world(view)
    E = _point_irradiance(rid, L, light.rotation_world(view), P)
    w = (P[0] - L) / np.linalg.norm(P[0] - L)
    theta_deg = math.degrees(math.acos(w @ light.rotation_world(view)[:, 2]))
    assert 10.0 < theta_deg < 30.0  # off-axis, where f varies strongly
    scale = light.scale * view.exposure
    for n_sub in (1, 3):
        radiance = render_pixels(camera, view, rig, pixels, rid_subsamples=n_sub)
        np.testing.assert_allclose(radiance.data, scale * E, rtol=1e-6)
    # cos4 adds cos^4 of the ray angle; paper multiplies by the pixel's solid angle from
    # the camera centre, cos^3(alpha) / (fx fy) for a pinhole.
    rays, _ = camera.rays_camera(pixels.astype(np.float64))
    cos_alpha = 1.0 / np.linalg.norm(rays, axis=1)
    cos4 = render_pixels(camera, view, rig, pixels, sensor="cos4")
    np.testing.assert_allclose(cos4.data, scale * E * cos_alpha**4, rtol=1e-6)
    paper = render_pixels(camera, view, rig, pixels, sensor="paper")
    pixel_omega = cos_alpha**3 / (camera.fx * camera.fy)
    np.testing.assert_allclose(paper.data, scale * E * pixel_omega, rtol=1e-6)
    image = render_image(camera, view, rig)
    np.testing.assert_allclose(image.data[pixels[:, 1], pixels[:, 0]], scale * E, rtol=1e-6)


@pytest.mark.parametrize("rid_name", ["cos_power", "table_2d"])
def test_one_wall_point_seen_from_two_poses_has_one_radiance(rid_name: str) -> None:
    # A light fixed in the world (mounted differently on each camera): under "radiance"
    # the value of a wall point does not depend on where it is seen from.
    rid = rid_model(rid_name)
    camera = telephoto_camera()
    X = np.array([0.15, 0.35, 0.0])
    L_world = np.array([0.3, -0.5, 2.0])
    R_world_light = rotation_with_z(np.array([-0.2, 0.5, -2.0])) @ rotation_about((0, 0, 1), 1.0)
    first = View.looking_at(np.array([-0.8, -1.2, 3.5]), X)
    second = View.looking_at(np.array([1.1, 0.9, 2.4]), X, up_world=(1.0, 0.0, 0.0), exposure=1.0)
    center_pixel = np.array([[31, 23]])  # the principal point: X is on both optical axes
    values = []
    for view in (first, second):
        light = light_fixed_in_world(rid, view, L_world, R_world_light, scale=0.7)
        np.testing.assert_allclose(light.position_world(view), L_world, atol=1e-15)
        values.append(render_pixels(camera, view, Rig.single(light), center_pixel).data[0])
    assert values[0] == pytest.approx(values[1], rel=1e-6)
    E = _point_irradiance(rid, L_world, R_world_light, X[None])[0]
    assert values[0] == pytest.approx(0.7 * E, rel=1e-6)
    # At the principal point the paper value is E times the pixel's solid angle from the
    # camera centre, 1 / (fx fy), whatever the distance and the viewing angle.
    for view in (first, second):
        light = light_fixed_in_world(rid, view, L_world, R_world_light)
        paper = render_pixels(camera, view, Rig.single(light), center_pixel, sensor="paper")
        assert paper.data[0] == pytest.approx(E / (camera.fx * camera.fy), rel=1e-6)


# ---------------------------------------------------------------- invariant: symmetric lights


@pytest.mark.parametrize("rid_name", ["isotropic", "cos_power", "gaussian", "table_1d"])
def test_rotating_a_symmetric_light_about_its_axis_changes_nothing(rid_name: str) -> None:
    camera = distorted_camera()
    view = oblique_view()
    rig = two_light_rig(rid_model(rid_name))
    reference = render_image(camera, view, rig, rid_subsamples=2)
    pixels = all_pixels(64, 48)[::13]
    reference_pixels = render_pixels(camera, view, rig, pixels, sensor="paper", binning=1)
    for angle in (0.7, 2.0, -2.9):
        rolled = Rig(
            tuple(
                light.replace(
                    R_camera_light=light.R_camera_light @ rotation_about((0, 0, 1), angle)
                )
                for light in rig.lights
            )
        )
        _assert_masked_close(render_image(camera, view, rolled, rid_subsamples=2), reference, 1e-12)
        _assert_masked_close(
            render_pixels(camera, view, rolled, pixels, sensor="paper"), reference_pixels, 1e-12
        )


def test_rotating_a_2d_table_light_about_its_axis_changes_the_image() -> None:
    # The converse: the invariance test above would notice a renderer that ignores phi.
    camera = distorted_camera()
    view = oblique_view()
    rig = two_light_rig(rid_model("table_2d"))
    reference = render_image(camera, view, rig)
    rolled = Rig(
        tuple(
            light.replace(R_camera_light=light.R_camera_light @ rotation_about((0, 0, 1), 0.7))
            for light in rig.lights
        )
    )
    change = np.abs(render_image(camera, view, rolled).data / reference.data - 1.0)
    assert change.max() > 1e-2


# ---------------------------------------------------------------- gradients


def _values(fp, view: View, lights: list[Light], n_sub: int) -> np.ndarray:
    return shade(fp, view, Rig(tuple(lights)), offset=0.05, rid_subsamples=n_sub).values.data


@pytest.mark.parametrize(
    ("rid_name", "n_sub", "binning", "sensor"),
    [
        ("isotropic", 1, 1, "cos4"),
        ("isotropic", 2, 1, "radiance"),
        ("cos_power", 1, 1, "cos4"),
        ("cos_power", 2, 2, "paper"),
        ("gaussian", 1, 1, "radiance"),
        ("table_1d", 1, 1, "cos4"),
        ("table_1d", 2, 1, "radiance"),
        ("table_2d", 1, 1, "cos4"),
        ("table_2d", 2, 1, "radiance"),
        ("table_2d", 1, 2, "paper"),
    ],
)
def test_analytic_gradients_match_central_differences(
    rid_name: str, n_sub: int, binning: int, sensor: SensorModel
) -> None:
    camera = distorted_camera()
    view = oblique_view(exposure=1.4)
    lights = list(two_light_rig(rid_model(rid_name)).lights)
    pixels = np.random.default_rng(30).permutation(all_pixels(64 // binning, 48 // binning))[:25]
    fp = pixel_footprints(camera, view, pixels, sensor=sensor, binning=binning)
    shading = shade(fp, view, Rig(tuple(lights)), offset=0.05, rid_subsamples=n_sub, want_grad=True)
    assert shading.grad_position is not None and shading.grad_rotation is not None
    assert shading.grad_position.shape == (2, 25, 3)
    assert shading.grad_rotation.shape == (2, 25, 3)
    # want_grad does not change the values.
    np.testing.assert_allclose(shading.values.data, _values(fp, view, lights, n_sub), rtol=1e-12)
    h = 1e-6
    for i, light in enumerate(lights):
        fd_pos = np.zeros((25, 3))
        fd_rot = np.zeros((25, 3))
        for k in range(3):
            e = np.zeros(3)
            e[k] = h
            plus = lights.copy()
            minus = lights.copy()
            plus[i] = light.replace(t_camera_light=light.t_camera_light + e)
            minus[i] = light.replace(t_camera_light=light.t_camera_light - e)
            fd_pos[:, k] = (_values(fp, view, plus, n_sub) - _values(fp, view, minus, n_sub)) / (
                2 * h
            )
            plus[i] = light.replace(R_camera_light=rotation_about(e, h) @ light.R_camera_light)
            minus[i] = light.replace(R_camera_light=rotation_about(e, -h) @ light.R_camera_light)
            fd_rot[:, k] = (_values(fp, view, plus, n_sub) - _values(fp, view, minus, n_sub)) / (
                2 * h
            )
        for analytic, numeric in (
            (shading.grad_position[i], fd_pos),
            (shading.grad_rotation[i], fd_rot),
        ):
            size = np.linalg.norm(numeric, axis=1, keepdims=True)
            if rid_name == "isotropic" and numeric is fd_rot:
                np.testing.assert_array_equal(analytic, 0.0)
                assert np.abs(numeric).max() < 1e-9
                continue
            assert np.all(size > 0.0)
            assert np.all(np.abs(analytic - numeric) <= 1e-6 * size)
        # flux is d value / d scale (values are linear in the scales).
        bumped = lights.copy()
        bumped[i] = light.replace(scale=light.scale + 0.5)
        np.testing.assert_allclose(
            (_values(fp, view, bumped, n_sub) - shading.values.data) / 0.5,
            shading.flux[i],
            rtol=1e-9,
        )


def test_gradients_are_zero_for_masked_pixels() -> None:
    camera = pinhole_camera()
    view = horizon_view()
    fp = pixel_footprints(camera, view, all_pixels(64, 48)[::17])
    assert 0 < fp.valid.sum() < len(fp)
    shading = shade(fp, view, two_light_rig(rid_model("table_2d")), want_grad=True)
    assert shading.grad_position is not None and shading.grad_rotation is not None
    np.testing.assert_array_equal(shading.flux[:, ~fp.valid], 0.0)
    np.testing.assert_array_equal(shading.grad_position[:, ~fp.valid], 0.0)
    np.testing.assert_array_equal(shading.grad_rotation[:, ~fp.valid], 0.0)
    assert np.all(np.ma.getmaskarray(shading.values) == ~fp.valid)


# ---------------------------------------------------------------- validation


def test_render_option_validation_messages() -> None:
    camera = pinhole_camera()
    view = oblique_view()
    rig = two_light_rig(IsotropicRID())
    pixels = np.array([[1, 2]])
    fp = pixel_footprints(camera, view, pixels)
    for bad in (0, -2, 1.5):
        message = _exact(f"rid_subsamples: expected an integer >= 1, got {bad!r}")
        with pytest.raises(ValueError, match=message):
            render_image(camera, view, rig, rid_subsamples=bad)  # type: ignore[arg-type]
        with pytest.raises(ValueError, match=message):
            render_pixels(camera, view, rig, pixels, rid_subsamples=bad)  # type: ignore[arg-type]
        with pytest.raises(ValueError, match=message):
            shade(fp, view, rig, rid_subsamples=bad)  # type: ignore[arg-type]
    with pytest.raises(ValueError, match=_exact("binning: expected an integer >= 1, got 0")):
        render_image(camera, view, rig, binning=0)
    with pytest.raises(
        ValueError, match=_exact("sensor: expected one of radiance, cos4, paper, map, got 'raw'")
    ):
        render_image(camera, view, rig, sensor="raw")  # type: ignore[arg-type]
    with pytest.raises(
        ValueError,
        match=_exact("vignetting: the 'map' sensor model needs a fall-off map, got none"),
    ):
        render_image(camera, view, rig, sensor="map")
    with pytest.raises(
        ValueError, match=_exact("pixels: pixel (0, 48) lies outside the 64x48 image")
    ):
        render_pixels(camera, view, rig, np.array([[0, 48]]))
    with pytest.raises(
        ValueError,
        match=_exact("pixels: expected integer pixel indices (pixel centres are at integers)"),
    ):
        render_pixels(camera, view, rig, np.array([[0.5, 3.0]]))


def test_an_empty_pixel_selection_renders_to_an_empty_array() -> None:
    camera = distorted_camera()
    view = oblique_view()
    rig = two_light_rig(rid_model("table_2d"))
    none = np.zeros((0, 2), dtype=np.int64)
    for binning in (1, 3):
        values = render_pixels(camera, view, rig, none, binning=binning)
        assert isinstance(values, np.ma.MaskedArray)
        assert values.shape == (0,)
    assert render_pixels_reference(camera, view, rig, none).shape == (0,)
    shading = shade(pixel_footprints(camera, view, none), view, rig, want_grad=True)
    assert shading.flux.shape == (2, 0)
    assert shading.grad_position is not None and shading.grad_position.shape == (2, 0, 3)
    assert shading.grad_rotation is not None and shading.grad_rotation.shape == (2, 0, 3)


def test_light_flux_writes_into_a_given_buffer_and_checks_it() -> None:
    from lightcal.core.render import light_flux

    camera = pinhole_camera()
    view = oblique_view()
    light = two_light_rig(rid_model("cos_power")).lights[0]
    fp = pixel_footprints(camera, view, all_pixels(camera.width, camera.height)[::7])
    flux, grad = light_flux(fp, view, light, want_grad=True)
    assert grad is not None
    buffer = np.full((len(fp), 6), np.nan)
    flux2, grad2 = light_flux(fp, view, light, want_grad=True, grad_out=buffer)
    assert grad2 is buffer
    np.testing.assert_array_equal(flux2, flux)
    np.testing.assert_array_equal(grad2, grad)
    # A light behind the wall lights nothing: the buffer is zeroed, not left as it was.
    behind = light.replace(t_camera_light=light.t_camera_light + np.array([0.0, 0.0, 50.0]))
    assert behind.position_world(view)[2] <= 0.0
    buffer[:] = np.nan
    flux3, _ = light_flux(fp, view, behind, want_grad=True, grad_out=buffer)
    assert np.all(flux3 == 0.0) and np.all(buffer == 0.0)
    with pytest.raises(
        ValueError, match=_exact(f"grad_out: expected a C-contiguous float64 ({len(fp)}, 6) array")
    ):
        light_flux(fp, view, light, want_grad=True, grad_out=np.zeros((len(fp), 6)).T.copy().T)
