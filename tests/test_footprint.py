"""Tests of lightcal.core.footprint: pixel footprints on the wall and sensor weights."""

from __future__ import annotations

import math
import re

import numpy as np
import pytest

from lightcal.core.camera import Camera
from lightcal.core.footprint import SensorModel, check_pixels, pixel_footprints
from lightcal.core.solid_angle import quad_area_in_plane
from tests.scenes import (
    all_pixels,
    distorted_camera,
    horizon_view,
    oblique_view,
    pinhole_camera,
    straight_down_view,
)

FX, FY, CX, CY = 50.0, 40.0, 10.5, 7.25
HEIGHT_M = 2.0


def _exact(message: str) -> str:
    return "^" + re.escape(message) + "$"


def _down_camera() -> Camera:
    return Camera.from_params(fx=FX, fy=FY, cx=CX, cy=CY, width=20, height=16)


def _hand_corners(u: float, v: float) -> np.ndarray:
    """(4, 3) footprint of pixel (u, v) for `_down_camera` at HEIGHT_M looking straight down."""
    out = []
    for du, dv in ((-0.5, -0.5), (0.5, -0.5), (0.5, 0.5), (-0.5, 0.5)):
        x = (u + du - CX) / FX
        y = (v + dv - CY) / FY
        out.append([x * HEIGHT_M, -y * HEIGHT_M, 0.0])  # camera y is world -y
    return np.array(out)


def _miss_mask(camera: Camera, view, pixels: np.ndarray, binning: int = 1) -> np.ndarray:
    """(N,) True where some corner ray of some member pixel does not point down at the wall."""
    b = binning
    bad = np.zeros(len(pixels), dtype=bool)
    for du in np.arange(b + 1) - 0.5:
        for dv in np.arange(b + 1) - 0.5:
            corner = pixels * b + np.array([du, dv])
            rays, ok = camera.rays_camera(corner)
            d_world = rays @ view.R_camera_world
            bad |= ~ok | ~(d_world[:, 2] < 0.0)
    return bad


# ---------------------------------------------------------------- hand-computed case


def test_footprints_by_hand_straight_down() -> None:
    camera = _down_camera()
    view = straight_down_view(height_m=HEIGHT_M)
    pixels = np.array([[0, 0], [10, 7], [19, 15], [3, 12]])
    fp = pixel_footprints(camera, view, pixels)
    assert len(fp) == 4
    assert fp.corners_world.shape == (4, 1, 4, 3)
    assert fp.weights.shape == (4, 1)
    np.testing.assert_array_equal(fp.pixels, pixels)
    assert fp.valid.all()
    for i, (u, v) in enumerate(pixels):
        np.testing.assert_allclose(fp.corners_world[i, 0], _hand_corners(u, v), atol=1e-15)
    area = HEIGHT_M**2 / (FX * FY)
    np.testing.assert_allclose(fp.area_m2, area, rtol=1e-13)
    np.testing.assert_allclose(fp.weights[:, 0], 1.0 / area, rtol=1e-13)


def test_sensor_weights_by_hand() -> None:
    camera = _down_camera()
    view = straight_down_view(height_m=HEIGHT_M)
    pixels = np.array([[0, 0], [10, 7], [19, 15], [3, 12]])
    area = HEIGHT_M**2 / (FX * FY)
    x = (pixels[:, 0] - CX) / FX
    y = (pixels[:, 1] - CY) / FY
    cos2 = 1.0 / (1.0 + x * x + y * y)  # of the pixel centre ray (mean of its corners)
    cos4 = pixel_footprints(camera, view, pixels, sensor="cos4")
    np.testing.assert_allclose(cos4.weights[:, 0], cos2**2 / area, rtol=1e-13)
    paper = pixel_footprints(camera, view, pixels, sensor="paper")
    d2 = HEIGHT_M**2 / cos2
    np.testing.assert_allclose(paper.weights[:, 0], np.sqrt(cos2) / d2, rtol=1e-13)
    vignetting = np.linspace(0.5, 1.0, 20 * 16).reshape(16, 20)
    vmap = pixel_footprints(camera, view, pixels, sensor="map", vignetting=vignetting)
    expected = vignetting[pixels[:, 1], pixels[:, 0]] / area
    np.testing.assert_allclose(vmap.weights[:, 0], expected, rtol=1e-13)
    # The footprints themselves do not depend on the sensor model.
    np.testing.assert_array_equal(paper.corners_world, cos4.corners_world)
    np.testing.assert_array_equal(paper.area_m2, vmap.area_m2)


@pytest.mark.parametrize("sensor", ["radiance", "cos4", "paper", "map"])
def test_binned_super_pixel_by_hand(sensor: SensorModel) -> None:
    camera = _down_camera()
    view = straight_down_view(height_m=HEIGHT_M)
    b = 3
    vignetting = np.linspace(0.5, 1.0, 20 * 16).reshape(16, 20)
    fp = pixel_footprints(
        camera, view, np.array([[2, 1], [5, 4]]), sensor=sensor, vignetting=vignetting, binning=b
    )
    assert fp.corners_world.shape == (2, 9, 4, 3)
    area = HEIGHT_M**2 / (FX * FY)
    np.testing.assert_allclose(fp.area_m2, 9 * area, rtol=1e-13)
    for i, (bu, bv) in enumerate([(2, 1), (5, 4)]):
        members = [(bu * b + ii, bv * b + jj) for jj in range(b) for ii in range(b)]
        quads = {tuple(np.round(q[0], 12)) for q in fp.corners_world[i]}
        assert quads == {tuple(np.round(_hand_corners(u, v)[0], 12)) for u, v in members}
        u = np.array([m[0] for m in members])
        v = np.array([m[1] for m in members])
        x, y = (u - CX) / FX, (v - CY) / FY
        cos2 = 1.0 / (1.0 + x * x + y * y)
        if sensor == "radiance":
            expected = np.full(9, 1.0 / (9 * area))
        elif sensor == "cos4":
            expected = np.full(9, np.mean(cos2**2) / (9 * area))
        elif sensor == "map":
            expected = np.full(9, np.mean(vignetting[v, u]) / (9 * area))
        else:  # paper: per quad, averaged over the b^2 members
            expected = np.sqrt(cos2) * cos2 / HEIGHT_M**2 / 9
        # Match each weight to its member through the quad's first corner.
        order = [
            members.index(
                (
                    round(q[0, 0] / HEIGHT_M * FX + CX + 0.5),
                    round(-q[0, 1] / HEIGHT_M * FY + CY + 0.5),
                )
            )
            for q in fp.corners_world[i]
        ]
        np.testing.assert_allclose(fp.weights[i], expected[order], rtol=1e-13)


# ---------------------------------------------------------------- geometry


def test_footprint_corners_project_back_to_the_pixel_corners() -> None:
    camera = distorted_camera()
    view = oblique_view()
    pixels = np.array([[0, 0], [63, 0], [0, 47], [63, 47], [31, 20], [7, 33]])
    fp = pixel_footprints(camera, view, pixels)
    assert fp.valid.all()
    points_camera = fp.corners_world.reshape(-1, 3) @ view.R_camera_world.T + view.t_camera_world
    projected, ok = camera.project(points_camera)
    assert ok.all()
    offsets = np.array([[-0.5, -0.5], [0.5, -0.5], [0.5, 0.5], [-0.5, 0.5]])
    expected = (pixels[:, None, :] + offsets[None]).reshape(-1, 2)
    np.testing.assert_allclose(projected, expected, atol=1e-9)
    np.testing.assert_array_equal(fp.corners_world[..., 2], 0.0)


def test_neighbouring_footprints_share_corners_and_tile_the_image_outline() -> None:
    camera = pinhole_camera(width=24, height=18)
    view = oblique_view()
    pixels = all_pixels(24, 18)
    fp = pixel_footprints(camera, view, pixels)
    quads = fp.corners_world[:, 0].reshape(18, 24, 4, 3)
    np.testing.assert_array_equal(quads[:, :-1, 1], quads[:, 1:, 0])  # right edge = left edge
    np.testing.assert_array_equal(quads[:, :-1, 2], quads[:, 1:, 3])
    np.testing.assert_array_equal(quads[:-1, :, 3], quads[1:, :, 0])  # bottom edge = top edge
    # Without distortion the image outline is a quad on the wall; the pixels tile it.
    outline = np.stack([quads[0, 0, 0], quads[0, -1, 1], quads[-1, -1, 2], quads[-1, 0, 3]])
    np.testing.assert_allclose(fp.area_m2.sum(), quad_area_in_plane(outline[None])[0], rtol=1e-12)
    np.testing.assert_allclose(fp.area_m2, quad_area_in_plane(fp.corners_world[:, 0]), rtol=1e-14)


@pytest.mark.parametrize("binning", [1, 3])
def test_pixels_whose_rays_miss_the_wall_are_invalid(binning: int) -> None:
    camera = pinhole_camera()
    view = horizon_view()
    pixels = all_pixels(64 // binning, 48 // binning)
    fp = pixel_footprints(camera, view, pixels, binning=binning, sensor="paper")
    expected_invalid = _miss_mask(camera, view, pixels, binning)
    assert 0 < expected_invalid.sum() < len(pixels)  # the horizon crosses the image
    np.testing.assert_array_equal(fp.valid, ~expected_invalid)
    assert np.all(np.isnan(fp.corners_world[~fp.valid]))
    assert np.all(fp.weights[~fp.valid] == 0.0)
    assert np.all(np.isnan(fp.area_m2[~fp.valid]))
    assert np.all(np.isfinite(fp.corners_world[fp.valid]))
    assert np.all(fp.weights[fp.valid] > 0.0)
    assert np.all(fp.area_m2[fp.valid] > 0.0)


def test_pixels_outside_the_distortion_domain_are_invalid() -> None:
    # Strong barrel distortion folds over near the image corners: those corners do not
    # undistort, and their pixels are invalid (masked), never a fallback value.
    camera = Camera.from_params(
        fx=20.0, fy=20.0, cx=31.5, cy=23.5, width=64, height=48, dist=(-0.5, 0.0, 0.0, 0.0)
    )
    view = straight_down_view()
    pixels = all_pixels(64, 48)
    fp = pixel_footprints(camera, view, pixels)
    expected_invalid = _miss_mask(camera, view, pixels)
    assert expected_invalid.sum() > 0
    np.testing.assert_array_equal(fp.valid, ~expected_invalid)
    assert not fp.valid[0] and fp.valid[24 * 64 + 32]


# ---------------------------------------------------------------- validation


def test_pixel_index_validation_messages() -> None:
    camera = pinhole_camera()
    view = oblique_view()
    cases = [
        (np.array([[64, 0]]), "pixels: pixel (64, 0) lies outside the 64x48 image"),
        (np.array([[3, 4], [-1, 5]]), "pixels: pixel (-1, 5) lies outside the 64x48 image"),
        (np.array([[0, 48]]), "pixels: pixel (0, 48) lies outside the 64x48 image"),
        (
            np.array([[0.5, 1.0]]),
            "pixels: expected integer pixel indices (pixel centres are at integers)",
        ),
        (
            np.array([[math.nan, 1.0]]),
            "pixels: expected integer pixel indices (pixel centres are at integers)",
        ),
        (np.array([1, 2]), "pixels: expected an (N, 2) array of (u, v) indices, got shape (2,)"),
        (
            np.zeros((2, 3), dtype=int),
            "pixels: expected an (N, 2) array of (u, v) indices, got shape (2, 3)",
        ),
        (np.array([["a", "b"]]), "pixels: expected integer pixel indices, got dtype <U1"),
    ]
    for pixels, message in cases:
        with pytest.raises(ValueError, match=_exact(message)):
            pixel_footprints(camera, view, pixels)
    # Integral floats are accepted; with binning the bound is the binned image.
    fp = pixel_footprints(camera, view, np.array([[2.0, 3.0]]))
    np.testing.assert_array_equal(fp.pixels, [[2, 3]])
    assert fp.pixels.dtype == np.int32  # 8 bytes a pixel: dense selections hold millions
    with pytest.raises(
        ValueError, match=_exact("pixels: pixel (21, 0) lies outside the 21x16 image")
    ):
        pixel_footprints(camera, view, np.array([[21, 0]]), binning=3)
    with pytest.raises(ValueError, match=_exact("px: pixel (5, 5) lies outside the 4x4 image")):
        check_pixels(np.array([[5, 5]]), 4, 4, "px")


def test_option_validation_messages() -> None:
    camera = pinhole_camera()
    view = oblique_view()
    pixels = np.array([[1, 1]])
    with pytest.raises(ValueError, match=_exact("binning: expected an integer >= 1, got 0")):
        pixel_footprints(camera, view, pixels, binning=0)
    with pytest.raises(ValueError, match=_exact("binning: expected an integer >= 1, got 2.0")):
        pixel_footprints(camera, view, pixels, binning=2.0)  # type: ignore[arg-type]
    with pytest.raises(
        ValueError,
        match=_exact("sensor: expected one of radiance, cos4, paper, map, got 'flat'"),
    ):
        pixel_footprints(camera, view, pixels, sensor="flat")  # type: ignore[arg-type]
    with pytest.raises(
        ValueError,
        match=_exact("vignetting: the 'map' sensor model needs a fall-off map, got none"),
    ):
        pixel_footprints(camera, view, pixels, sensor="map")
    with pytest.raises(
        ValueError,
        match=_exact(
            "vignetting: expected a map of shape (48, 64) (the camera's image), got (64, 48)"
        ),
    ):
        pixel_footprints(camera, view, pixels, sensor="map", vignetting=np.ones((64, 48)))
    bad = np.ones((48, 64))
    bad[3, 4] = 0.0
    with pytest.raises(ValueError, match=_exact("vignetting: expected finite values > 0")):
        pixel_footprints(camera, view, pixels, sensor="map", vignetting=bad)
