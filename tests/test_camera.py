"""Tests of lightcal.core.camera.Camera against OpenCV and by hand."""

from __future__ import annotations

import dataclasses
import math

import cv2
import numpy as np
import pytest

from lightcal.core.camera import Camera
from lightcal.errors import InputError

DIST_SETS = {
    "none": [],
    "4 coefficients": [-0.28, 0.09, 0.0012, -0.0021],
    "5 strong barrel": [-0.45, 0.2, 0.0005, 0.001, -0.03],
    "5 pincushion": [0.35, 0.1, -0.001, 0.002, 0.05],
    "8 rational": [0.8, -0.2, 0.001, -0.0015, 0.02, 0.6, -0.05, 0.01],
}

TIGHT_CRITERIA = (cv2.TERM_CRITERIA_COUNT + cv2.TERM_CRITERIA_EPS, 100, 1e-14)


def _camera(dist: list[float], *, skew: float = 0.0) -> Camera:
    return Camera.from_params(
        fx=1210.5, fy=1195.25, cx=963.7, cy=541.2, width=1920, height=1080, dist=dist, skew=skew
    )


def _points_in_view(seed: int, n: int = 1000) -> np.ndarray:
    """(n, 3) camera-frame points within +-0.6 of the axis in normalised coordinates."""
    rng = np.random.default_rng(seed)
    xy = rng.uniform(-0.6, 0.6, (n, 2))
    z = rng.uniform(0.5, 5.0, n)
    return np.column_stack([xy * z[:, None], z])


def _cv2_undistort(pixels: np.ndarray, camera: Camera) -> np.ndarray:
    src = pixels.reshape(-1, 1, 2)
    dist = camera.dist_opencv
    if hasattr(cv2, "undistortPointsIter"):  # OpenCV 4
        out = cv2.undistortPointsIter(src, camera.K, dist, None, None, TIGHT_CRITERIA)
    else:  # OpenCV 5 takes the criteria in undistortPoints
        out = cv2.undistortPoints(src, camera.K, dist, criteria=TIGHT_CRITERIA)
    return out[:, 0, :]


@pytest.mark.parametrize("name", list(DIST_SETS))
def test_project_matches_cv2_project_points(name: str) -> None:
    camera = _camera(DIST_SETS[name])
    points = _points_in_view(10)
    expected, _ = cv2.projectPoints(points, np.zeros(3), np.zeros(3), camera.K, camera.dist_opencv)
    pixels, valid = camera.project(points)
    assert valid.all()
    np.testing.assert_allclose(pixels, expected[:, 0, :], rtol=0, atol=1e-6)


@pytest.mark.parametrize("name", list(DIST_SETS))
def test_pixels_to_normalized_matches_cv2_undistort_points(name: str) -> None:
    camera = _camera(DIST_SETS[name])
    pixels, _ = camera.project(_points_in_view(11))
    xy, valid = camera.pixels_to_normalized(pixels)
    assert valid.all()
    xy_cv = _cv2_undistort(pixels, camera)

    def linear(p: np.ndarray) -> np.ndarray:
        return np.column_stack([camera.fx * p[:, 0] + camera.cx, camera.fy * p[:, 1] + camera.cy])

    np.testing.assert_allclose(linear(xy), linear(xy_cv), rtol=0, atol=1e-6)


@pytest.mark.parametrize("name", list(DIST_SETS))
@pytest.mark.parametrize("skew", [0.0, 3.5])
def test_pixels_normalized_pixels_round_trip(name: str, skew: float) -> None:
    camera = _camera(DIST_SETS[name], skew=skew)
    rng = np.random.default_rng(12)
    # Pixels all over the image (the 5-coefficient barrel folds only beyond it).
    pixels = rng.uniform([0.0, 0.0], [camera.width - 1, camera.height - 1], (1000, 2))
    xy, valid = camera.pixels_to_normalized(pixels)
    assert valid.all()
    np.testing.assert_allclose(camera.normalized_to_pixels(xy), pixels, rtol=0, atol=1e-9)


def test_project_with_skew_hand_computed() -> None:
    camera = Camera.from_params(
        fx=100.0, fy=200.0, cx=50.0, cy=40.0, width=100, height=80, skew=2.0
    )
    pixels, valid = camera.project(np.array([[0.2, -0.1, 2.0]]))
    # x = 0.1, y = -0.05: u = 100 * 0.1 + 2 * (-0.05) + 50, v = 200 * (-0.05) + 40.
    assert valid.tolist() == [True]
    np.testing.assert_allclose(pixels, [[59.9, 30.0]], rtol=0, atol=1e-12)


def test_project_hand_computed_k1_only() -> None:
    camera = Camera.from_params(
        fx=1000.0, fy=1000.0, cx=500.0, cy=400.0, width=1000, height=800, dist=[0.1, 0, 0, 0]
    )
    # x = 0.3, y = 0.4, factor 1.025: (0.3075, 0.41) * 1000 + (500, 400).
    pixels, valid = camera.project(np.array([[0.6, 0.8, 2.0]]))
    assert valid.all()
    np.testing.assert_allclose(pixels, [[807.5, 810.0]], rtol=0, atol=1e-9)


def test_project_marks_points_behind_or_non_finite_invalid() -> None:
    camera = _camera(DIST_SETS["5 pincushion"])
    points = np.array(
        [[0.1, 0.2, 1.0], [0.1, 0.2, 0.0], [0.1, 0.2, -1.0], [np.nan, 0.0, 1.0], [0, np.inf, 1]]
    )
    pixels, valid = camera.project(points)
    assert valid.tolist() == [True, False, False, False, False]
    assert np.isfinite(pixels[0]).all()
    assert np.isnan(pixels[1:]).all()


def test_pixels_to_normalized_beyond_the_fold_is_invalid() -> None:
    # k1 = -0.4 folds at distorted radius 0.6086: a pixel at normalised radius 0.7 has no
    # preimage in the valid region.
    camera = Camera.from_params(
        fx=1000.0, fy=1000.0, cx=1000.0, cy=1000.0, width=2001, height=2001, dist=[-0.4, 0, 0, 0]
    )
    pixels = np.array([[1700.0, 1000.0], [1300.0, 1000.0], [np.nan, 3.0]])
    xy, valid = camera.pixels_to_normalized(pixels)
    assert valid.tolist() == [False, True, False]
    assert np.isnan(xy[[0, 2]]).all()
    rays, valid_rays = camera.rays_camera(pixels)
    assert valid_rays.tolist() == [False, True, False]
    assert np.isnan(rays[[0, 2]]).all()


def test_rays_camera_project_back_to_their_pixels() -> None:
    camera = _camera(DIST_SETS["8 rational"], skew=1.5)
    pixels = np.array([[0.0, 0.0], [963.7, 541.2], [1919.0, 1079.0], [100.5, 900.25]])
    rays, valid = camera.rays_camera(pixels)
    assert valid.all()
    assert np.array_equal(rays[:, 2], np.ones(4))
    np.testing.assert_allclose(rays[1], [0.0, 0.0, 1.0], atol=1e-15)
    back, _ = camera.project(rays * 3.0)
    np.testing.assert_allclose(back, pixels, rtol=0, atol=1e-9)


@pytest.mark.parametrize("b", [1, 2, 3, 4])
def test_binned_camera_maps_pixels_as_the_convention_says(b: int) -> None:
    camera = _camera(DIST_SETS["5 strong barrel"], skew=0.7)
    binned = camera.binned(b)
    assert (binned.width, binned.height) == (1920 // b, 1080 // b)
    assert binned.fx == camera.fx / b and binned.fy == camera.fy / b
    assert binned.skew == camera.skew / b
    assert binned.cx == pytest.approx((963.7 + 0.5) / b - 0.5, abs=1e-12)
    assert binned.n_dist == 5 and np.array_equal(binned.dist, camera.dist)
    points = _points_in_view(13, n=200)
    full, _ = camera.project(points)
    small, _ = binned.project(points)
    np.testing.assert_allclose(small, (full + 0.5) / b - 0.5, rtol=0, atol=1e-9)


def test_binned_by_one_is_equal() -> None:
    camera = _camera(DIST_SETS["4 coefficients"])
    assert camera.binned(1) == camera


def test_binned_hand_computed() -> None:
    camera = Camera.from_params(fx=100.0, fy=80.0, cx=9.5, cy=5.5, width=21, height=11)
    binned = camera.binned(2)
    # The centre of a 20 x 10 sensor, 9.5, becomes the centre of a 10 x 5 one, 4.5.
    assert (binned.fx, binned.fy, binned.cx, binned.cy) == (50.0, 40.0, 4.5, 2.5)
    assert (binned.width, binned.height) == (10, 5)


@pytest.mark.parametrize("b", [0, -2, 2.0, True])
def test_binned_rejects_bad_factor(b: object) -> None:
    camera = _camera([])
    with pytest.raises(InputError, match=r"^b: expected a positive int binning factor, got "):
        camera.binned(b)  # type: ignore[arg-type]


def test_binned_rejects_factor_larger_than_image() -> None:
    camera = Camera.from_params(fx=10.0, fy=10.0, cx=1.0, cy=1.0, width=4, height=3)
    with pytest.raises(
        InputError, match=r"^b: expected a binning factor <= min\(width, height\) = 3, got 4$"
    ):
        camera.binned(4)


def test_fov_and_aspect() -> None:
    camera = Camera.from_params(fx=500.0, fy=400.0, cx=319.5, cy=239.5, width=640, height=480)
    assert camera.fov_y_rad == pytest.approx(2.0 * math.atan(480 / 800))
    assert camera.aspect == pytest.approx(4 / 3)


def test_properties_and_storage() -> None:
    camera = _camera([0.1, 0.2, 0.3, 0.4, 0.5], skew=0.25)
    assert (camera.fx, camera.fy, camera.cx, camera.cy, camera.skew) == (
        1210.5,
        1195.25,
        963.7,
        541.2,
        0.25,
    )
    assert camera.n_dist == 5
    assert camera.dist.shape == (8,) and camera.dist.dtype == np.float64
    assert np.array_equal(camera.dist_opencv, [0.1, 0.2, 0.3, 0.4, 0.5])
    with pytest.raises(ValueError, match="read-only"):
        camera.K[0, 0] = 1.0
    with pytest.raises(ValueError, match="read-only"):
        camera.dist[0] = 1.0
    assert camera == _camera([0.1, 0.2, 0.3, 0.4, 0.5], skew=0.25)
    assert camera != _camera([0.1, 0.2, 0.3, 0.4, 0.5, 0.0, 0.0, 0.0], skew=0.25)  # n_dist
    assert camera != _camera([0.1, 0.2, 0.3, 0.4, 0.5])


def test_constructor_copies_inputs() -> None:
    K = np.array([[100.0, 0.0, 50.0], [0.0, 100.0, 40.0], [0.0, 0.0, 1.0]])
    camera = Camera(K=K, dist=np.zeros(4), width=100, height=80)
    K[0, 0] = 7.0
    assert camera.fx == 100.0
    assert camera.n_dist == 4


def test_explicit_n_dist_coeffs() -> None:
    K = np.array([[100.0, 0.0, 50.0], [0.0, 100.0, 40.0], [0.0, 0.0, 1.0]])
    dist = np.array([0.1, 0, 0, 0, 0, 0, 0, 0])
    camera = Camera(K=K, dist=dist, width=100, height=80, n_dist_coeffs=4)
    assert camera.n_dist == 4 and np.array_equal(camera.dist_opencv, [0.1, 0, 0, 0])
    with pytest.raises(
        InputError, match=r"^dist: expected zeros beyond the first n_dist_coeffs=4 coefficients"
    ):
        Camera(K=K, dist=dist[::-1].copy(), width=100, height=80, n_dist_coeffs=4)
    with pytest.raises(InputError, match=r"^n_dist_coeffs: expected 0, 4, 5 or 8, got 6$"):
        Camera(K=K, dist=np.zeros(8), width=100, height=80, n_dist_coeffs=6)


GOOD_K = [[100.0, 0.0, 50.0], [0.0, 100.0, 40.0], [0.0, 0.0, 1.0]]


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"K": np.eye(2)}, r"^K: expected a 3x3 matrix, got shape \(2, 2\)$"),
        (
            {"K": [[100.0, 0, np.nan], [0, 100.0, 40.0], [0, 0, 1]]},
            r"^K: expected finite values, got NaN or infinity$",
        ),
        (
            {"K": [[-100.0, 0, 50], [0, 100.0, 40.0], [0, 0, 1]]},
            r"^K: expected fx > 0 and fy > 0, got fx=-100\.0, fy=100\.0$",
        ),
        (
            {"K": [[100.0, 0, 50], [0, 100.0, 40.0], [0, 0, 2]]},
            r"^K: expected the form \[\[fx, s, cx\], \[0, fy, cy\], \[0, 0, 1\]\], got "
            r"K\[1, 0\]=0\.0, K\[2, 0\]=0\.0, K\[2, 1\]=0\.0, K\[2, 2\]=2\.0$",
        ),
        ({"dist": [0.1, 0.2, 0.3]}, r"^dist: expected 0, 4, 5 or 8 coefficients, got 3$"),
        (
            {"dist": [0.1, np.inf, 0.0, 0.0]},
            r"^dist: expected finite values, got NaN or infinity$",
        ),
        ({"dist": np.zeros((2, 4))}, r"^dist: expected a vector of coefficients, got shape"),
        ({"width": 0}, r"^width: expected a positive int, got 0$"),
        ({"height": 4.0}, r"^height: expected a positive int, got 4\.0$"),
        ({"width": True}, r"^width: expected a positive int, got True$"),
    ],
)
def test_validation_errors(kwargs: dict[str, object], message: str) -> None:
    args: dict[str, object] = {"K": GOOD_K, "dist": [], "width": 100, "height": 80}
    args.update(kwargs)
    with pytest.raises(InputError, match=message):
        Camera(**args)  # type: ignore[arg-type]


def test_from_params_rejects_zero_focal_length() -> None:
    with pytest.raises(
        InputError, match=r"^K: expected fx > 0 and fy > 0, got fx=100\.0, fy=0\.0$"
    ):
        Camera.from_params(fx=100.0, fy=0.0, cx=1.0, cy=1.0, width=10, height=10)


@pytest.mark.parametrize(
    ("method", "array", "message"),
    [
        (
            "project",
            np.zeros((5, 2)),
            r"^points_camera: expected an \(N, 3\) array, got shape \(5, 2\)$",
        ),
        ("project", np.zeros(3), r"^points_camera: expected an \(N, 3\) array, got shape \(3,\)$"),
        ("pixels_to_normalized", np.zeros((1, 3)), r"^pixels: expected an \(N, 2\) array"),
        (
            "rays_camera",
            np.zeros((2, 2, 2)),
            r"^pixels: expected an \(N, 2\) array, got shape \(2, 2, 2\)$",
        ),
        (
            "normalized_to_pixels",
            np.zeros(2),
            r"^xy: expected an \(N, 2\) array, got shape \(2,\)$",
        ),
    ],
)
def test_shape_errors(method: str, array: np.ndarray, message: str) -> None:
    camera = _camera([])
    with pytest.raises(InputError, match=message):
        getattr(camera, method)(array)


def test_intrinsic_params_and_their_covariance_under_binning():
    cov = np.diag([4.0, 4.0, 9.0, 1.0, 1e-4, 1e-5, 1e-8, 1e-8, 1e-6])
    camera = Camera.from_params(
        fx=4000.0,
        fy=4001.0,
        cx=3000.0,
        cy=2000.0,
        width=6000,
        height=4000,
        dist=(-0.08, 0.02, 2e-4, -1e-4, 0.0),
    )
    camera = dataclasses.replace(camera, intrinsics_covariance=cov)
    np.testing.assert_array_equal(
        camera.intrinsic_params, [4000, 4001, 3000, 2000, -0.08, 0.02, 2e-4, -1e-4, 0]
    )
    moved = camera.with_intrinsic_params(camera.intrinsic_params + np.arange(9) * 1e-3)
    assert moved.fx == 4000.0 and moved.fy == 4001.001 and moved.dist[0] == -0.08 + 0.004
    np.testing.assert_array_equal(moved.intrinsics_covariance, cov)
    binned = camera.binned(5)
    # fx / 5 and cx / 5 (+ a constant): their variances / 25; the distortion's unchanged.
    np.testing.assert_allclose(
        np.diag(binned.intrinsics_covariance), np.r_[cov.diagonal()[:4] / 25, cov.diagonal()[4:]]
    )
    with pytest.raises(InputError, match="intrinsics_covariance: expected a 9x9 matrix"):
        dataclasses.replace(camera, intrinsics_covariance=np.eye(8))
    with pytest.raises(InputError, match="expected 9 intrinsic parameters, got 8"):
        camera.with_intrinsic_params(np.ones(8))
