"""A camera pose from planar world points and their pixels, and how certain it is.

- `solve_pose`: `cv2.solvePnP` (IPPE, for planar points) then `cv2.solvePnPRefineLM` on
  the camera's distortion model.
- `pose_covariance`: the pose's covariance from the reprojection fit, in the
  parameterisation of the project file's `T_camera_world.covariance`: (delta, c), delta
  (rad) a rotation perturbation R_camera_world -> exp(delta) R_camera_world (left, in the
  camera frame) and c the camera centre in the world frame (m). Sigma = s^2 (J^T J)^-1,
  J (2N, 6) the Jacobian of the N projected points' (u, v) with respect to (delta, c)
  (`pose_jacobian`) and s^2 = sum of squared residuals / (2N - 6) the residual variance
  per image coordinate. J comes from `cv2.projectPoints`' Jacobian by the chain rule:
  with the points in the camera frame, X_c = R (X_w - c), projected at rvec = tvec = 0,
  d/d rvec is exactly d/d delta (exp(delta) X_c: the camera's rotation about its own
  centre) and d/d c = (d/d tvec) (-R). It is the first-order covariance of a least-squares
  fit with independent, equal pixel noise; detection biases are not in it. Like
  `cv2.solvePnP`, it ignores the camera's skew.
- `pose_intrinsics_jacobian`: how the pose moves with the intrinsics (central differences).

Frames: docs/conventions.md (the wall is the world plane z = 0, the camera at z > 0).
"""

from __future__ import annotations

import cv2
import numpy as np
from numpy.typing import NDArray

from lightcal.core.camera import Camera
from lightcal.core.rotations import rotvec_from_matrix
from lightcal.errors import InputError


def residuals_px(
    camera: Camera,
    R_camera_world: NDArray[np.float64],
    t_camera_world: NDArray[np.float64],
    points_world: NDArray[np.float64],
    points_image: NDArray[np.float64],
) -> NDArray[np.float64]:
    """(N, 2) detected minus projected pixels of (N, 3) world points."""
    projected, _ = camera.project(points_world @ R_camera_world.T + t_camera_world)
    return points_image - projected


def not_collinear(points_world: NDArray[np.float64]) -> bool:
    """True if the planar points span an area (are not all on one line)."""
    if points_world.shape[0] < 3:
        return False
    centered = points_world[:, :2] - points_world[:, :2].mean(axis=0)
    singular = np.linalg.svd(centered, compute_uv=False)
    return bool(singular[1] > 1e-6 * max(singular[0], 1e-12))


def solve_pose(
    points_world: NDArray[np.float64],
    points_image: NDArray[np.float64],
    camera: Camera,
    *,
    refine: bool = True,
    source: str = "points",
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """`T_camera_world` from planar world points and their pixels (IPPE, then LM).

    Args:
        points_world: (N, 3) points on the wall (z = 0), metres, N >= 4, not all on a line.
        points_image: (N, 2) their detected pixels (u, v).
        camera: Intrinsics and distortion of the image.
        refine: Refine the IPPE pose with `cv2.solvePnPRefineLM`.
        source: Name of the image for error messages.

    Returns:
        R_camera_world: (3, 3).
        t_camera_world: (3,), metres.

    Raises:
        InputError: `cv2.solvePnP` found no pose.
    """
    K = np.array(camera.K)
    dist = np.array(camera.dist)
    ok, rvec, tvec = cv2.solvePnP(points_world, points_image, K, dist, flags=cv2.SOLVEPNP_IPPE)
    if not ok:
        raise InputError(source, "cv2.solvePnP found no pose for the detected markers")
    if refine:
        rvec, tvec = cv2.solvePnPRefineLM(
            points_world,
            points_image,
            K,
            dist,
            rvec,
            tvec,
            criteria=(cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT, 100, 1e-12),
        )
    R, _ = cv2.Rodrigues(rvec)
    return np.asarray(R, dtype=np.float64), np.asarray(tvec, dtype=np.float64).reshape(3)


def pose_jacobian(
    camera: Camera,
    R_camera_world: NDArray[np.float64],
    t_camera_world: NDArray[np.float64],
    points_world: NDArray[np.float64],
) -> NDArray[np.float64]:
    """d (u, v) / d (delta, c) of the projections of world points (see the module docstring).

    Args:
        camera: The camera (its skew is ignored, as by `cv2.projectPoints`).
        R_camera_world: (3, 3).
        t_camera_world: (3,), metres.
        points_world: (N, 3) world points, metres.

    Returns:
        J: (2N, 6): rows 2k and 2k + 1 are u and v of point k; columns delta (px/rad) and
        the camera centre c (px/m).
    """
    R = np.asarray(R_camera_world, dtype=np.float64)
    points_camera = np.asarray(points_world, dtype=np.float64) @ R.T + t_camera_world
    zero = np.zeros(3)
    K, dist = np.array(camera.K), np.array(camera.dist)
    _, jacobian = cv2.projectPoints(points_camera.reshape(-1, 1, 3), zero, zero, K, dist)
    jacobian = np.asarray(jacobian, dtype=np.float64)  # columns rvec, tvec, f, c, dist
    # X_c = exp(delta) R (X_w - c): rvec at 0 is delta, and d X_c / d c = -R.
    return np.hstack([jacobian[:, 0:3], -jacobian[:, 3:6] @ R])


def pose_covariance(
    camera: Camera,
    R_camera_world: NDArray[np.float64],
    t_camera_world: NDArray[np.float64],
    points_world: NDArray[np.float64],
    points_image: NDArray[np.float64],
) -> NDArray[np.float64]:
    """Covariance of a fitted pose from its reprojection residuals (see the module docstring).

    Sigma = s^2 (J^T J)^-1, J = `pose_jacobian` (2N, 6), s^2 = sum of squared residuals
    (detected minus projected, both coordinates) / (2N - 6).

    Args:
        camera: The camera of the image.
        R_camera_world: (3, 3) the fitted pose (a least-squares minimum of the residuals).
        t_camera_world: (3,), metres.
        points_world: (N, 3) the world points of the fit, metres, N >= 4.
        points_image: (N, 2) their detected pixels (u, v).

    Returns:
        covariance: (6, 6) of (delta (rad), c (m)), symmetric.

    Raises:
        InputError: Fewer than 4 points.
    """
    n_points = len(points_world)
    if n_points < 4:
        raise InputError("points_world", f"expected at least 4 points, got {n_points}")
    residuals = residuals_px(camera, R_camera_world, t_camera_world, points_world, points_image)
    s2 = float(np.sum(residuals**2)) / (2 * n_points - 6)
    jacobian = pose_jacobian(camera, R_camera_world, t_camera_world, points_world)
    # Columns scaled to unit norm before inverting (px/rad and px/m differ in size).
    scale = np.linalg.norm(jacobian, axis=0)
    scale[scale == 0.0] = 1.0
    scaled = jacobian / scale
    covariance = s2 * np.linalg.inv(scaled.T @ scaled) / np.outer(scale, scale)
    return np.asarray(0.5 * (covariance + covariance.T), dtype=np.float64)


def intrinsics_steps(camera: Camera) -> NDArray[np.float64]:
    """Finite-difference steps of `camera.intrinsic_params`: each one's sigma
    (`intrinsics_covariance`), else 0.1 px for fx, fy, cx, cy and 1e-4 for the distortion.

    The pose (and the rendering) is linear in the intrinsics well beyond a sigma (central
    differences of `solve_pose` agree to 1e-4 from 0.01 to 3 px in fx), while steps much
    below 0.01 px reach the pose solver's tolerance.
    """
    default = np.r_[np.full(4, 0.1), np.full(camera.n_dist, 1e-4)]
    cov = camera.intrinsics_covariance
    if cov is None:
        return default
    sigma = np.sqrt(np.maximum(np.diag(cov), 0.0))
    return np.where(sigma > 0.0, sigma, default)


def pose_intrinsics_jacobian(
    points_world: NDArray[np.float64],
    points_image: NDArray[np.float64],
    camera: Camera,
    *,
    binning: int = 1,
    source: str = "points",
) -> NDArray[np.float64]:
    """d (delta, c) / d K: how the marker pose moves per unit change of each intrinsic.

    Central differences of `solve_pose` with the camera's `intrinsic_params` (fx, fy, cx,
    cy, distortion) perturbed one at a time (`intrinsics_steps`): delta = log(R' R^T)
    (rad, camera frame) and c the camera centre (m), as `pose_covariance`.

    Args:
        points_world: (N, 3) the pose's world points, metres.
        points_image: (N, 2) their detected pixels (u, v), in the image as read.
        camera: The camera whose intrinsics (and covariance) are meant (e.g. the camera
            file's); `camera.binned(binning)` is the image's.
        binning: The image's binning relative to `camera`.
        source: Name of the image for error messages.

    Returns:
        (6, p), p = 4 + camera.n_dist.
    """

    def image_camera(params: NDArray[np.float64]) -> Camera:
        perturbed = camera.with_intrinsic_params(params)
        return perturbed if binning == 1 else perturbed.binned(binning)

    base = camera.intrinsic_params
    R0, _ = solve_pose(points_world, points_image, image_camera(base), source=source)
    steps = intrinsics_steps(camera)
    out = np.empty((6, base.size))
    for k, h in enumerate(steps):
        poses = []
        for sign in (1.0, -1.0):
            params = base.copy()
            params[k] += sign * h
            R, t = solve_pose(points_world, points_image, image_camera(params), source=source)
            poses.append(np.r_[rotvec_from_matrix(R @ R0.T), -R.T @ t])
        out[:, k] = (poses[0] - poses[1]) / (2.0 * h)
    return out
