"""Tests of lightcal.capture.intrinsics on synthetic, distorted views of boards."""

from __future__ import annotations

import functools
import re

import cv2
import numpy as np
import pytest

from lightcal.capture.boards import ArucoGridBoard, CharucoBoard, Chessboard
from lightcal.capture.intrinsics import _calibrate, calibrate_intrinsics
from lightcal.capture.plane_texture import look_at_pose, render_plane_image
from lightcal.core.camera import Camera
from lightcal.errors import InputError

WIDTH, HEIGHT = 800, 600
CAMERA = Camera.from_params(
    fx=720.0,
    fy=721.0,
    cx=403.2,
    cy=297.6,
    width=WIDTH,
    height=HEIGHT,
    dist=(-0.15, 0.08, 5e-4, -3e-4, 0.0),
)
CHESSBOARD = Chessboard(9, 6, 0.03)
CHARUCO = CharucoBoard("DICT_4X4_50", 10, 7, 0.03, 0.022, origin_world_m=(-0.15, 0.105))


def _center(board):
    if isinstance(board, Chessboard):
        s = board.square_length_m
        return np.array([(board.inner_x - 1) * s / 2, -(board.inner_y - 1) * s / 2, 0.0])
    width, height = board.size_m
    return np.array([board.origin_world_m[0] + width / 2, board.origin_world_m[1] - height / 2, 0])


def _pose(board, k, n_views, rng):
    """(R, t) of view k of `n_views` from all around `board`, tilted 20 - 40 degrees."""
    center = _center(board)
    azimuth = 2 * np.pi * k / n_views + rng.uniform(-0.2, 0.2)
    tilt = np.radians(rng.uniform(20.0, 40.0))
    distance = rng.uniform(0.35, 0.5)
    direction = [np.sin(tilt) * np.cos(azimuth), np.sin(tilt) * np.sin(azimuth), np.cos(tilt)]
    target = center + np.r_[rng.uniform(-0.04, 0.04, 2), 0.0]
    return look_at_pose(
        center + distance * np.array(direction), target, roll_rad=rng.uniform(-0.5, 0.5)
    )


@functools.cache
def views(board, n_views, seed):
    """`n_views` uint8 views of `board` from all around, tilted 20 - 40 degrees."""
    rng = np.random.default_rng(seed)
    rendering = board.render(2000)
    texture = 0.05 + 0.85 * rendering.image / 255.0
    images = []
    for k in range(n_views):
        R, t = _pose(board, k, n_views, rng)
        image = render_plane_image(
            CAMERA, R, t, texture, rendering.px_per_m, rendering.top_left_world_m
        )
        image += rng.normal(0.0, 0.005, image.shape)
        images.append(np.clip(np.rint(image * 255.0), 0, 255).astype(np.uint8))
    return tuple(images)


def _torn(image):
    """The view with its right half shifted 8 px sideways (a corrupted frame)."""
    torn = image.copy()
    torn[:, WIDTH // 2 :] = np.roll(torn[:, WIDTH // 2 :], 8, axis=1)
    return torn


def test_chessboard_calibration_recovers_the_camera_and_rejects_bad_views():
    good = list(views(CHESSBOARD, 12, 3))
    blank = np.full((HEIGHT, WIDTH), 128, dtype=np.uint8)
    images = [*good[:5], blank, *good[5:], _torn(good[0])]
    names = [f"view_{i:02d}.png" for i in range(len(images))]
    result = calibrate_intrinsics(images, CHESSBOARD, sources=names)

    camera = result.camera
    fx_error, fy_error = camera.fx / CAMERA.fx - 1.0, camera.fy / CAMERA.fy - 1.0
    print(
        f"fx {100 * fx_error:+.4f} %, fy {100 * fy_error:+.4f} %, "
        f"cx {camera.cx - CAMERA.cx:+.3f} px, cy {camera.cy - CAMERA.cy:+.3f} px, "
        f"rms {result.rms_px:.3f} px"
    )
    assert abs(fx_error) < 1e-3
    assert abs(fy_error) < 1e-3
    assert abs(camera.cx - CAMERA.cx) < 1.0
    assert abs(camera.cy - CAMERA.cy) < 1.0
    assert (camera.width, camera.height) == (WIDTH, HEIGHT)
    assert camera.n_dist == 5
    np.testing.assert_allclose(camera.dist[:4], CAMERA.dist[:4], atol=0.01)
    # Projections agree with the true camera to a fraction of a pixel over the image.
    xs, ys = np.meshgrid(np.linspace(-0.5, 0.5, 9), np.linspace(-0.38, 0.38, 7))
    rays = np.column_stack([xs.ravel(), ys.ravel(), np.ones(xs.size)])
    assert np.max(np.abs(camera.project(rays)[0] - CAMERA.project(rays)[0])) < 0.3

    assert result.rms_px < 0.2
    assert result.used == tuple(n for n in names if n not in ("view_05.png", "view_13.png"))
    assert len(result.per_image_rms_px) == len(result.used) == 12
    assert max(result.per_image_rms_px) < 0.2
    expected_rms = np.sqrt(np.mean(np.square(result.per_image_rms_px)))  # equal corner counts
    assert result.rms_px == pytest.approx(expected_rms, rel=1e-9)
    assert [name for name, _ in result.rejected] == ["view_05.png", "view_13.png"]
    assert result.rejected[0][1] == "no chessboard with 9x6 inner corners found"
    reason = result.rejected[1][1]
    assert re.fullmatch(
        r"reprojection RMS (\d+\.\d{3}) px above the limit 1\.000 px "
        r"\(max of 3 x the median and max_rms_px=1\)",
        reason,
    ), reason
    assert float(reason.split()[2]) > 1.5


def test_charuco_calibration():
    result = calibrate_intrinsics(list(views(CHARUCO, 8, 5)), CHARUCO, n_dist=4)
    camera = result.camera
    assert abs(camera.fx / CAMERA.fx - 1.0) < 2e-3
    assert abs(camera.fy / CAMERA.fy - 1.0) < 2e-3
    assert abs(camera.cx - CAMERA.cx) < 1.0
    assert abs(camera.cy - CAMERA.cy) < 1.0
    assert camera.n_dist == 4
    assert np.all(camera.dist[4:] == 0.0)
    assert result.rejected == ()
    assert result.rms_px < 0.3


def test_too_few_views():
    good = list(views(CHESSBOARD, 12, 3))[:2]
    blank = np.zeros((HEIGHT, WIDTH), dtype=np.uint8)
    message = (
        "images: 2 usable views of the board, need at least 3 "
        "(rejected: image[1]: no chessboard with 9x6 inner corners found)"
    )
    with pytest.raises(InputError, match=f"^{re.escape(message)}$"):
        calibrate_intrinsics([good[0], blank, good[1]], CHESSBOARD)
    with pytest.raises(
        InputError, match=re.escape("images: 0 usable views of the board, need at least 3")
    ):
        calibrate_intrinsics([], CHESSBOARD)


def test_input_errors():
    image = np.zeros((HEIGHT, WIDTH), dtype=np.uint8)
    with pytest.raises(
        InputError, match=re.escape("n_dist: expected 4, 5 or 8 distortion coefficients, got 6")
    ):
        calibrate_intrinsics([image], CHESSBOARD, n_dist=6)  # type: ignore[arg-type]
    with pytest.raises(
        InputError,
        match=re.escape("board: expected a Chessboard or a CharucoBoard, got ArucoGridBoard"),
    ):
        board = ArucoGridBoard("DICT_4X4_50", 2, 2, 0.05, 0.01)
        calibrate_intrinsics([image], board)  # type: ignore[arg-type]
    with pytest.raises(
        InputError, match=re.escape("max_rms_px: expected a positive number of pixels, got 0")
    ):
        calibrate_intrinsics([image], CHESSBOARD, max_rms_px=0)
    with pytest.raises(
        InputError, match=re.escape("sources: expected 2 names (one per image), got 1")
    ):
        calibrate_intrinsics([image, image], CHESSBOARD, sources=["a"])
    with pytest.raises(
        InputError,
        match=re.escape("b.png: image is 40x30 px, expected 800x600 px like the first image"),
    ):
        calibrate_intrinsics(
            [image, np.zeros((30, 40), dtype=np.uint8)], CHESSBOARD, sources=["a.png", "b.png"]
        )


def _corner_views(n_views, noise_px, seed):
    """Chessboard corners of `n_views` poses (as `views`), projected and noised."""
    pose_rng = np.random.default_rng(1234)  # the same poses for every seed
    rng = np.random.default_rng(seed)
    world = CHESSBOARD.corners_world()
    out = []
    for k in range(n_views):
        R, t = _pose(CHESSBOARD, k, n_views, pose_rng)
        pixels, _ = CAMERA.project(world @ R.T + t)
        out.append((world, pixels + rng.normal(0.0, noise_px, pixels.shape)))
    return out


def test_calibration_covariance_matches_opencv_and_the_spread_over_noise_draws():
    noise = 0.3
    estimates = []
    for seed in range(40):
        K, dist, _, cov = _calibrate(_corner_views(12, noise, seed), (WIDTH, HEIGHT), 5)
        estimates.append(np.r_[K[0, 0], K[1, 1], K[0, 2], K[1, 2], dist])
        if seed == 0:
            first = cov
            views0 = _corner_views(12, noise, seed)
            *_, std_opencv, _, _ = cv2.calibrateCameraExtended(
                [w.astype(np.float32) for w, _ in views0],
                [p.astype(np.float32).reshape(-1, 1, 2) for _, p in views0],
                (WIDTH, HEIGHT),
                None,
                None,
            )
            # The diagonal is OpenCV's (which divides by a slightly different dof).
            np.testing.assert_allclose(
                np.sqrt(np.diag(cov)), np.asarray(std_opencv).ravel()[:9], rtol=0.05
            )
            assert cov.shape == (9, 9)
            assert np.linalg.eigvalsh(cov).min() > 0.0
    spread = np.std(np.array(estimates), axis=0, ddof=1)
    predicted = np.sqrt(np.diag(first))
    # 40 draws: the sample standard deviation is good to about 11 %.
    np.testing.assert_allclose(spread[:4], predicted[:4], rtol=0.3)
    np.testing.assert_allclose(spread[4:], predicted[4:], rtol=0.3)


def test_calibrated_camera_carries_its_covariance():
    result = calibrate_intrinsics(views(CHESSBOARD, 6, 0)[:6], CHESSBOARD)
    cov = result.camera.intrinsics_covariance
    assert cov is not None and cov.shape == (9, 9)
    sigma = np.sqrt(np.diag(cov))
    # Sub-pixel corners on 6 views: fx to a fraction of a pixel, and the truth within 5 sigma.
    assert 0.0 < sigma[0] < 2.0
    assert abs(result.camera.fx - CAMERA.fx) < 5 * sigma[0] + 1e-3
