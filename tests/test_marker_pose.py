"""Tests of lightcal.capture.marker_pose on synthetic, distorted images of boards on the wall."""

from __future__ import annotations

import functools
import re

import cv2
import numpy as np
import pytest

from lightcal.capture.boards import ArucoGridBoard, CharucoBoard, Chessboard
from lightcal.capture.marker_pose import (
    MarkerPose,
    estimate_pose,
    estimate_poses,
    pose_covariance,
    pose_jacobian,
    pose_report,
    solve_pose,
    stretch_to_uint8,
)
from lightcal.capture.plane_texture import look_at_pose, render_plane_image
from lightcal.core.camera import Camera
from lightcal.core.rotations import matrix_from_rotvec, rotvec_from_matrix
from lightcal.errors import InputError

CAMERA = Camera.from_params(
    fx=1400.0,
    fy=1402.0,
    cx=805.3,
    cy=596.8,
    width=1600,
    height=1200,
    dist=(-0.12, 0.06, 4e-4, -3e-4, -0.01),
)
GRID = ArucoGridBoard("DICT_5X5_100", 8, 6, 0.08, 0.02, origin_world_m=(-0.39, 0.29))
CHARUCO = CharucoBoard("DICT_5X5_100", 11, 8, 0.07, 0.05, origin_world_m=(-0.385, 0.28))
TEXTURE_PX_PER_M = 2000.0
BLACK, WHITE, NOISE = 0.05, 0.9, 0.005

# name: (board, distance to the board centre (m), tilt (deg), tilt azimuth (deg), roll (deg))
SCENES: dict[str, tuple[ArucoGridBoard | CharucoBoard, float, float, float, float]] = {
    "grid_0.8m_frontal": (GRID, 0.8, 0.0, 0.0, 0.0),
    "grid_1.5m_tilt30": (GRID, 1.5, 30.0, 40.0, 10.0),
    "grid_2.5m_tilt15": (GRID, 2.5, 15.0, 200.0, -5.0),
    "charuco_0.9m_tilt25": (CHARUCO, 0.9, 25.0, 300.0, 30.0),
    "charuco_1.6m_tilt30": (CHARUCO, 1.6, 30.0, 120.0, 180.0),
    "charuco_2.5m_frontal": (CHARUCO, 2.5, 0.0, 0.0, 0.0),
}

# The (delta, c) error of a chi^2 test with 6 degrees of freedom is rejected above this
# (the 0.999 quantile).
CHI2_6_999 = 22.46

# Tolerances of the task: 1 mm and 0.05 degrees.
MAX_POSITION_ERROR_M = 1e-3
MAX_ANGLE_ERROR_DEG = 0.05


def _board_center_world(board):
    width, height = board.size_m
    x0, y0 = board.origin_world_m
    return np.array([x0 + width / 2, y0 - height / 2, 0.0])


@functools.cache
def scene(name):
    """(board, image (H, W) float, R_camera_world, t_camera_world) of a named scene."""
    board, distance_m, tilt_deg, azimuth_deg, roll_deg = SCENES[name]
    rng = np.random.default_rng(sorted(SCENES).index(name))
    tilt, azimuth = np.radians(tilt_deg), np.radians(azimuth_deg)
    direction = [np.sin(tilt) * np.cos(azimuth), np.sin(tilt) * np.sin(azimuth), np.cos(tilt)]
    target = _board_center_world(board) + np.r_[rng.uniform(-0.03, 0.03, 2), 0.0]
    center = target + distance_m * np.array(direction)
    R, t = look_at_pose(center, target, roll_rad=np.radians(roll_deg))
    rendering = board.render(TEXTURE_PX_PER_M)
    texture = BLACK + (WHITE - BLACK) * rendering.image / 255.0
    image = render_plane_image(
        CAMERA, R, t, texture, rendering.px_per_m, rendering.top_left_world_m
    )
    image += rng.normal(0.0, NOISE, image.shape)
    image.flags.writeable = False
    return board, image, R, t


def _angle_deg(R_a, R_b):
    cos = (np.trace(R_a @ R_b.T) - 1.0) / 2.0
    return float(np.degrees(np.arccos(np.clip(cos, -1.0, 1.0))))


def _pose_error(R_estimate, t_estimate, R, t):
    """(6,) the estimate's (delta, c) error: R_estimate = exp(delta) R, c_estimate - c."""
    delta = rotvec_from_matrix(R_estimate @ R.T)
    return np.r_[delta, -R_estimate.T @ t_estimate + R.T @ t]


def _errors(pose, R, t):
    """(rotation error deg, |t error| m, |camera centre error| m)."""
    center = -R.T @ t
    return (
        _angle_deg(pose.R_camera_world, R),
        float(np.linalg.norm(pose.t_camera_world - t)),
        float(np.linalg.norm(pose.camera_center_world - center)),
    )


@pytest.mark.parametrize("name", list(SCENES))
def test_pose_recovered_from_synthetic_image(name):
    board, image, R, t = scene(name)
    pose = estimate_pose(image, CAMERA, board, source=name)
    angle_deg, t_error_m, center_error_m = _errors(pose, R, t)
    print(
        f"{name}: {pose.n_markers} markers, rms {pose.reprojection_rms_px:.3f} px, "
        f"rotation {angle_deg:.5f} deg, t {t_error_m * 1e3:.4f} mm, "
        f"centre {center_error_m * 1e3:.4f} mm"
    )
    assert angle_deg < MAX_ANGLE_ERROR_DEG
    assert t_error_m < MAX_POSITION_ERROR_M
    assert center_error_m < MAX_POSITION_ERROR_M
    assert pose.camera_center_world[2] > 0.5
    assert pose.reprojection_rms_px < 0.2
    assert pose.n_markers >= 40
    assert pose.source == name
    assert np.all(np.isin(pose.ids, GRID.ids if board is GRID else CHARUCO.marker_ids))
    np.testing.assert_allclose(
        np.sqrt(np.mean(np.sum(pose.residuals_px() ** 2, axis=1))), pose.reprojection_rms_px
    )
    # The covariance of the fit: symmetric, positive definite, and the true error is
    # within it (chi^2 of 6 degrees of freedom).
    covariance = pose.covariance
    assert covariance.shape == (6, 6)
    np.testing.assert_array_equal(covariance, covariance.T)
    assert np.linalg.eigvalsh(covariance).min() > 0.0
    np.testing.assert_array_equal(pose.sigma, np.sqrt(np.diag(covariance)))
    error = _pose_error(pose.R_camera_world, pose.t_camera_world, R, t)
    chi2 = float(error @ np.linalg.solve(covariance, error))
    print(
        f"  sigma rotation {np.degrees(pose.sigma[:3]).round(5)} deg, "
        f"centre {(pose.sigma[3:] * 1e3).round(4)} mm, chi2 of the error {chi2:.2f}"
    )
    assert chi2 < CHI2_6_999


@pytest.mark.parametrize("name", ["grid_2.5m_tilt15", "charuco_2.5m_frontal"])
def test_pose_under_blur_and_uneven_light(name):
    board, image, R, t = scene(name)
    rows, cols = np.mgrid[0 : CAMERA.height, 0 : CAMERA.width]
    spot = 0.15 + np.exp(-((cols - 500.0) ** 2 + (rows - 400.0) ** 2) / (2 * 350.0**2))
    raw = 1000.0 * cv2.GaussianBlur(np.array(image), (0, 0), 1.0) * spot + 30.0
    pose = estimate_pose(raw, CAMERA, board)
    angle_deg, t_error_m, center_error_m = _errors(pose, R, t)
    print(
        f"{name} blurred, spot: rotation {angle_deg:.5f} deg, t {t_error_m * 1e3:.4f} mm, "
        f"centre {center_error_m * 1e3:.4f} mm"
    )
    assert angle_deg < MAX_ANGLE_ERROR_DEG
    assert t_error_m < MAX_POSITION_ERROR_M
    assert center_error_m < MAX_POSITION_ERROR_M


def test_refinement_lowers_the_residual():
    board, image, R, t = scene("grid_1.5m_tilt30")
    refined = estimate_pose(image, CAMERA, board)
    coarse = estimate_pose(image, CAMERA, board, refine=False)
    assert refined.reprojection_rms_px <= coarse.reprojection_rms_px + 1e-9
    angle_deg, t_error_m, _ = _errors(coarse, R, t)
    assert angle_deg < 0.5 and t_error_m < 5e-3


def test_linear_float_and_uint8_images_give_the_same_pose():
    board, image, R, t = scene("grid_2.5m_tilt15")
    reference = estimate_pose(image, CAMERA, board)
    # A raw-like linear image (gain and black level) is stretched to the same 8 bits
    # (up to the rounding of values on a half step), hence gives the same pose.
    raw = 4000.0 * image + 250.0
    from_raw = estimate_pose(raw, CAMERA, board)
    np.testing.assert_allclose(from_raw.R_camera_world, reference.R_camera_world, atol=1e-6)
    np.testing.assert_allclose(from_raw.t_camera_world, reference.t_camera_world, atol=1e-6)
    image_u8 = np.clip(np.rint(image * 255.0), 0, 255).astype(np.uint8)
    from_u8 = estimate_pose(image_u8, CAMERA, board)
    angle_deg, t_error_m, center_error_m = _errors(from_u8, R, t)
    assert angle_deg < MAX_ANGLE_ERROR_DEG
    assert t_error_m < MAX_POSITION_ERROR_M
    assert center_error_m < MAX_POSITION_ERROR_M


def _marker_coverage(board, R, t):
    """(H, W) fraction of each pixel that sees a marker square, by ray casting."""
    rendering = board.render(TEXTURE_PX_PER_M, margin_m=0.01)
    texture = np.zeros(rendering.image.shape)
    A = rendering.A_pixel_world
    for quad in board.outline_world():
        uv = quad[:, :2] @ A[:, :2].T + A[:, 2]  # pixel corners, half-integers
        (u0, v0), (u1, v1) = np.rint(uv.min(axis=0) + 0.5), np.rint(uv.max(axis=0) + 0.5)
        texture[int(v0) : int(v1), int(u0) : int(u1)] = 1.0
    return render_plane_image(
        CAMERA, R, t, texture, rendering.px_per_m, rendering.top_left_world_m, background=0.0
    )


def test_marker_mask_covers_the_markers_and_little_else():
    board, image, R, t = scene("grid_1.5m_tilt30")
    pose = estimate_pose(image, CAMERA, board)
    assert pose.n_markers == GRID.n_markers
    margin_px = 3.0
    mask = pose.marker_mask(CAMERA.height, CAMERA.width, margin_px=margin_px)
    assert mask.shape == (CAMERA.height, CAMERA.width) and mask.dtype == bool
    covered = _marker_coverage(board, R, t) > 1e-9
    assert covered.sum() > 100_000
    # Every pixel whose footprint overlaps a marker is masked ...
    assert not np.any(covered & ~mask)
    # ... and nothing further than the margin (plus the footprint and a pixel) from one.
    radius = int(margin_px) + 3
    kernel = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * radius + 1, 2 * radius + 1))
    near = cv2.dilate(covered.astype(np.uint8), kernel).astype(bool)
    assert not np.any(mask & ~near)
    # A wider margin only adds pixels.
    wider = pose.marker_mask(CAMERA.height, CAMERA.width, margin_px=8.0)
    assert np.all(wider[mask]) and wider.sum() > mask.sum()


def test_charuco_marker_mask_covers_the_board():
    board, image, R, t = scene("charuco_2.5m_frontal")
    pose = estimate_pose(image, CAMERA, board)
    mask = pose.marker_mask(CAMERA.height, CAMERA.width)
    # Points all over the board, seen with the true pose, fall in the mask.
    width, height = board.size_m
    xs = board.origin_world_m[0] + np.linspace(0.0, width, 78)
    ys = board.origin_world_m[1] - np.linspace(0.0, height, 57)
    points = np.stack(np.meshgrid(xs, ys), axis=-1).reshape(-1, 2)
    points_world = np.column_stack([points, np.zeros(len(points))])
    pixels, valid = CAMERA.project(points_world @ R.T + t)
    assert np.all(valid)
    cols, rows = np.rint(pixels).astype(int).T
    assert np.all(mask[rows, cols])
    # The mask is about the board's area (+ margins), not the whole image.
    assert mask.sum() < 2.0 * (width * height) * (CAMERA.fx / 2.5) ** 2


def test_too_few_markers_is_an_input_error():
    blank = np.full((CAMERA.height, CAMERA.width), 0.5)
    message = "view_07.png: found 0 markers, need at least 4"
    with pytest.raises(InputError, match=f"^{re.escape(message)}$") as info:
        estimate_pose(blank, CAMERA, GRID, source="view_07.png")
    assert info.value.source == "view_07.png"
    with pytest.raises(InputError, match=re.escape("image: found 0 markers, need at least 4")):
        estimate_pose(blank, CAMERA, CHARUCO)
    board, image, _, _ = scene("grid_0.8m_frontal")
    with pytest.raises(InputError, match=re.escape("image: found 48 markers, need at least 49")):
        estimate_pose(image, CAMERA, board, min_markers=49)


def test_estimate_poses_reports_rejected_images():
    board, image, _, _ = scene("grid_0.8m_frontal")
    blank = np.full((CAMERA.height, CAMERA.width), 7, dtype=np.uint8)
    results = estimate_poses([image, blank], CAMERA, board, sources=["a.png", "b.png"])
    assert isinstance(results[0], MarkerPose)
    assert isinstance(results[1], InputError)
    assert results[1].source == "b.png"
    lines = pose_report(results).splitlines()
    assert len(lines) == 2
    x, y, z = results[0].camera_center_world
    assert lines[0] == (
        f"a.png: 48 markers, rms {results[0].reprojection_rms_px:.3f} px, "
        f"camera at ({x:.4f}, {y:.4f}, {z:.4f}) m"
    )
    assert lines[1] == "b.png: rejected: found 0 markers, need at least 4"
    names = [r.source for r in estimate_poses([blank], CAMERA, board)]
    assert names == ["image[0]"]


def test_input_errors():
    with pytest.raises(
        InputError,
        match=re.escape("img: image is 10x20 px, expected 1600x1200 px (the camera's size)"),
    ):
        estimate_pose(np.zeros((20, 10)), CAMERA, GRID, source="img")
    with pytest.raises(
        InputError, match=re.escape("img: expected a 2-D (H, W) grey image, got shape (4, 4, 3)")
    ):
        estimate_pose(np.zeros((4, 4, 3)), CAMERA, GRID, source="img")
    with pytest.raises(
        InputError,
        match=re.escape(
            "board: expected an ArucoGridBoard, a CharucoBoard or a MarkerLayout, got Chessboard"
        ),
    ):
        estimate_pose(np.zeros((1200, 1600)), CAMERA, Chessboard(9, 6, 0.03))  # type: ignore[arg-type]
    with pytest.raises(InputError, match=re.escape("min_markers: expected an int >= 1, got 0")):
        estimate_pose(np.zeros((1200, 1600)), CAMERA, GRID, min_markers=0)
    with pytest.raises(InputError, match=re.escape("sources: expected 2 names (one per image)")):
        estimate_poses([np.zeros((2, 2))] * 2, CAMERA, GRID, sources=["a"])


def test_stretch_to_uint8():
    u8 = np.array([[0, 7], [200, 255]], dtype=np.uint8)
    np.testing.assert_array_equal(stretch_to_uint8(u8), u8)
    ramp = np.arange(201, dtype=np.float64).reshape(1, -1)  # percentiles 1.0 and 199.0
    stretched = stretch_to_uint8(ramp)
    assert stretched[0, 0] == 0 and stretched[0, 1] == 0 and stretched[0, -1] == 255
    assert stretched[0, 100] == 128  # (100 - 1) / 198 * 255 = 127.5 -> 128
    # Invariant to gain and offset; NaN becomes 0; a constant image is all 0.
    np.testing.assert_array_equal(stretch_to_uint8(3.0 * ramp + 11.0), stretched)
    with_nan = ramp.copy()
    with_nan[0, 50] = np.nan
    assert stretch_to_uint8(with_nan)[0, 50] == 0
    assert not np.any(stretch_to_uint8(np.full((3, 3), 2.5)))
    assert stretch_to_uint8(ramp.astype(np.uint16))[0, 100] == 128


# --------------------------------------------------------------------------- covariance


def _detections(name):
    """(board points (N, 3), their true pixels (N, 2), R, t) of a named scene, no image."""
    board, distance_m, tilt_deg, azimuth_deg, roll_deg = SCENES[name]
    tilt, azimuth = np.radians(tilt_deg), np.radians(azimuth_deg)
    direction = [np.sin(tilt) * np.cos(azimuth), np.sin(tilt) * np.sin(azimuth), np.cos(tilt)]
    target = _board_center_world(board)
    center = target + distance_m * np.array(direction)
    R, t = look_at_pose(center, target, roll_rad=np.radians(roll_deg))
    ids = board.ids if isinstance(board, ArucoGridBoard) else board.corner_ids
    points_world = board.corners_world(ids).reshape(-1, 3)
    pixels, valid = CAMERA.project(points_world @ R.T + t)
    assert np.all(valid)
    return points_world, pixels, R, t


@pytest.mark.parametrize("name", ["grid_1.5m_tilt30", "charuco_2.5m_frontal"])
def test_pose_jacobian_matches_central_differences(name):
    points_world, _, R, t = _detections(name)
    jacobian = pose_jacobian(CAMERA, R, t, points_world)
    assert jacobian.shape == (2 * len(points_world), 6)
    center = -R.T @ t
    numeric = np.empty_like(jacobian)
    for k, step in enumerate([1e-7] * 3 + [1e-7] * 3):
        projected = []
        for sign in (1.0, -1.0):
            dp = np.zeros(6)
            dp[k] = sign * step
            R_k = matrix_from_rotvec(dp[:3]) @ R
            pixels, _ = CAMERA.project(points_world @ R_k.T - R_k @ (center + dp[3:]))
            projected.append(pixels.reshape(-1))
        numeric[:, k] = (projected[0] - projected[1]) / (2.0 * step)
    np.testing.assert_allclose(jacobian, numeric, rtol=0, atol=1e-6 * np.abs(jacobian).max())


@pytest.mark.parametrize("name", ["grid_1.5m_tilt30", "charuco_2.5m_frontal"])
def test_predicted_covariance_matches_the_spread_of_estimates(name):
    """Many fits of noisy detections: their (delta, c) errors spread as predicted."""
    points_world, pixels, R, t = _detections(name)
    sigma_px = 0.2
    errors, predicted = [], []
    for seed in range(1000):
        noisy = pixels + np.random.default_rng(seed).normal(0.0, sigma_px, pixels.shape)
        R_fit, t_fit = solve_pose(points_world, noisy, CAMERA)
        errors.append(_pose_error(R_fit, t_fit, R, t))
        predicted.append(pose_covariance(CAMERA, R_fit, t_fit, points_world, noisy))
    empirical = np.cov(np.array(errors).T)
    mean_predicted = np.mean(predicted, axis=0)
    ratio = np.diag(empirical) / np.diag(mean_predicted)
    print(
        f"{name}: predicted sigma {np.sqrt(np.diag(mean_predicted))}, "
        f"empirical {np.sqrt(np.diag(empirical))}, variance ratio {ratio.round(3)}"
    )
    np.testing.assert_array_less(np.abs(ratio - 1.0), 0.2)
    # The correlations agree too (the frontal view's rotation and centre are tied).
    d_emp, d_pred = np.sqrt(np.diag(empirical)), np.sqrt(np.diag(mean_predicted))
    correlation_emp = empirical / np.outer(d_emp, d_emp)
    correlation_pred = mean_predicted / np.outer(d_pred, d_pred)
    np.testing.assert_allclose(correlation_emp, correlation_pred, rtol=0, atol=0.15)
    # The prediction at the truth with the known noise, sigma^2 (J^T J)^-1, agrees as well.
    jacobian = pose_jacobian(CAMERA, R, t, points_world)
    at_truth = sigma_px**2 * np.linalg.inv(jacobian.T @ jacobian)
    np.testing.assert_allclose(np.diag(mean_predicted), np.diag(at_truth), rtol=0.05)


def test_predicted_sigma_scales_with_the_pixel_noise():
    points_world, pixels, _, _ = _detections("grid_1.5m_tilt30")
    sigmas = {}
    for sigma_px in (0.1, 0.4):
        covariances = []
        for seed in range(50):
            noise = np.random.default_rng(seed).normal(0.0, 1.0, pixels.shape)
            noisy = pixels + sigma_px * noise
            R_fit, t_fit = solve_pose(points_world, noisy, CAMERA)
            covariances.append(pose_covariance(CAMERA, R_fit, t_fit, points_world, noisy))
        sigmas[sigma_px] = np.sqrt(np.diag(np.mean(covariances, axis=0)))
    np.testing.assert_allclose(sigmas[0.4] / sigmas[0.1], 4.0, rtol=0.02)
    # Without noise beyond the rounding of the fit, the covariance all but vanishes.
    R_fit, t_fit = solve_pose(points_world, pixels, CAMERA)
    exact = pose_covariance(CAMERA, R_fit, t_fit, points_world, pixels)
    assert np.all(np.sqrt(np.diag(exact)) < 1e-3 * sigmas[0.1])


def test_pose_covariance_needs_four_points():
    points_world, pixels, R, t = _detections("grid_1.5m_tilt30")
    with pytest.raises(InputError, match=re.escape("points_world: expected at least 4 points")):
        pose_covariance(CAMERA, R, t, points_world[:3], pixels[:3])
