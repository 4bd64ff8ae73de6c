"""Camera intrinsics from views of a chessboard or a ChArUco board (`cv2.calibrateCamera`).

`calibrate_intrinsics` finds the board's corners in every view (`cv2.findChessboardCornersSB`
with its exhaustive search, or `cv2.aruco.CharucoDetector`), calibrates, then rejects the
views whose own reprojection RMS exceeds max(3 x the median over the views, `max_rms_px`)
and calibrates again, until no view is rejected. Views without a detection are rejected
with the reason, and so are copies of an earlier view (`view_variety.same_views`). At least
3 usable views are required, showing the board at 3 different angles
(`view_variety.angle_groups`: otherwise the focal length is undetermined and is refused,
however small the residuals); a board tilted less than 10 degrees in every view is a
warning (`IntrinsicsResult.warnings`). 10 - 20 views with the board tilted
(20 - 45 degrees) in several directions and covering the image corners determine the
focal length to better than 0.1 % (12 synthetic 800 x 600 views: 0.013 %, principal point
within 0.2 px; tests/test_intrinsics.py). (`CALIB_CB_ACCURACY` was left out: on such views
it was four times slower and no more accurate.)

Object points are the board's world coordinates (`lightcal.capture.boards`), so the per-view
extrinsics are `T_camera_world`; only the intrinsics are returned, with their covariance
(`calibration_covariance`): the full s^2 (J^T J)^-1 of the calibration's least squares,
J the Jacobian of every corner's (u, v) over the intrinsics and every view's pose, s^2 =
sum r^2 / (2 N - p - 6 V), restricted to the intrinsics (fx, fy, cx, cy, distortion).
Its diagonal agrees with `cv2.calibrateCameraExtended`'s `stdDeviationsIntrinsics`;
unlike that it keeps the correlations (e.g. fx with fy, cx with the poses' tilt).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, Literal

import cv2
import numpy as np
from numpy.typing import ArrayLike, NDArray

from lightcal.capture.boards import CharucoBoard, Chessboard
from lightcal.capture.marker_pose import stretch_to_uint8
from lightcal.capture.view_variety import (
    DISTINCT_ANGLE_DEG,
    EXPECTED_VIEWS,
    MIN_ANGLES,
    MIN_TILT_DEG,
    angle_groups,
    board_normals,
    listing,
    same_views,
    tilts_deg,
)
from lightcal.core.camera import Camera
from lightcal.errors import InputError

MIN_VIEWS = 3
"""Fewest usable views `calibrate_intrinsics` accepts."""

MIN_CHARUCO_CORNERS = 6
"""Fewest ChArUco corners (not all on one line) for a view to be used."""

_DIST_FLAGS = {
    4: cv2.CALIB_FIX_K3,
    5: 0,
    8: cv2.CALIB_RATIONAL_MODEL,
}
"""`cv2.calibrateCamera` flags for 4, 5 and 8 distortion coefficients."""

_CRITERIA = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 200, 1e-12)


@dataclass(frozen=True, eq=False)
class IntrinsicsResult:
    """The outcome of `calibrate_intrinsics`.

    Attributes:
        camera: The calibrated camera (skew 0, `n_dist` distortion coefficients), with
            its `intrinsics_covariance` (`calibration_covariance`).
        rms_px: Reprojection RMS over all corners of the used views, pixels.
        per_image_rms_px: (n_used,) reprojection RMS of each used view, in `used` order.
        used: Names of the views used in the final calibration.
        rejected: (name, reason) of every view left out, in input order.
        warnings: What the user should know about the views (e.g. a board seen nearly
            square-on in every view).
    """

    camera: Camera
    rms_px: float
    per_image_rms_px: tuple[float, ...]
    used: tuple[str, ...]
    rejected: tuple[tuple[str, str], ...]
    warnings: tuple[str, ...] = ()


def _detect_chessboard(
    image: NDArray[np.uint8], board: Chessboard
) -> tuple[NDArray[np.float64], NDArray[np.float64]] | str:
    """(world points (N, 3), image points (N, 2)) or the reason for no detection."""
    flags = cv2.CALIB_CB_EXHAUSTIVE
    found, corners = cv2.findChessboardCornersSB(image, board.pattern_size, flags=flags)
    if not found or corners is None:
        return f"no chessboard with {board.inner_x}x{board.inner_y} inner corners found"
    return board.corners_world(), np.asarray(corners, dtype=np.float64).reshape(-1, 2)


def _detect_charuco(
    image: NDArray[np.uint8], detector: Any, board: CharucoBoard
) -> tuple[NDArray[np.float64], NDArray[np.float64]] | str:
    """(world points (N, 3), image points (N, 2)) or the reason for no detection."""
    corners, ids, _, _ = detector.detectBoard(image)
    n = 0 if ids is None else len(ids)
    points_world = np.zeros((0, 3))
    if n:
        flat_ids = np.asarray(ids).reshape(-1).astype(np.int64)
        points_world = board.corners_world(flat_ids)
    if n < MIN_CHARUCO_CORNERS or not _spans_area(points_world):
        return f"found {n} ChArUco corners, need at least {MIN_CHARUCO_CORNERS} not all on one line"
    return points_world, np.asarray(corners, dtype=np.float64).reshape(-1, 2)


def _spans_area(points_world: NDArray[np.float64]) -> bool:
    if points_world.shape[0] < 3:
        return False
    centered = points_world[:, :2] - points_world[:, :2].mean(axis=0)
    singular = np.linalg.svd(centered, compute_uv=False)
    return bool(singular[1] > 1e-6 * singular[0])


def calibration_covariance(
    views: Sequence[tuple[NDArray[np.float64], NDArray[np.float64]]],
    K: NDArray[np.float64],
    dist: NDArray[np.float64],
    rvecs: Sequence[ArrayLike],
    tvecs: Sequence[ArrayLike],
) -> NDArray[np.float64]:
    """Covariance (p, p) of (fx, fy, cx, cy, dist) of a calibration, p = 4 + len(dist).

    s^2 (J^T J)^-1 over the intrinsics and the V views' poses (rvec, tvec), restricted
    to the intrinsics; J stacks `cv2.projectPoints`' Jacobians of every corner,
    s^2 = sum of squared residuals / (2 N - p - 6 V) (the module docstring).

    Args:
        views: (world points (N_v, 3), detected pixels (N_v, 2)) per view.
        K: (3, 3) the calibrated intrinsics (skew 0).
        dist: (n,) the calibrated distortion, n in (0, 4, 5, 8).
        rvecs, tvecs: (3,) each view's fitted pose.
    """
    dist = np.asarray(dist, dtype=np.float64).reshape(-1)
    p = 4 + dist.size
    V = len(views)
    blocks = []
    residuals = []
    for v, ((points_world, points_image), rvec, tvec) in enumerate(
        zip(views, rvecs, tvecs, strict=True)
    ):
        projected, jac = cv2.projectPoints(
            np.asarray(points_world, dtype=np.float64).reshape(-1, 1, 3),
            np.asarray(rvec, dtype=np.float64).reshape(3),
            np.asarray(tvec, dtype=np.float64).reshape(3),
            K,
            dist,
        )
        jac = np.asarray(jac, dtype=np.float64)  # columns rvec, tvec, (fx, fy), (cx, cy), dist
        rows = np.zeros((jac.shape[0], p + 6 * V))
        rows[:, :p] = jac[:, 6 : 6 + p]
        rows[:, p + 6 * v : p + 6 * v + 6] = jac[:, :6]
        blocks.append(rows)
        residuals.append(projected.reshape(-1) - np.asarray(points_image).reshape(-1))
    J = np.vstack(blocks)
    r = np.concatenate(residuals)
    dof = J.shape[0] - J.shape[1]
    if dof <= 0:
        raise InputError("views", f"{J.shape[0]} corner coordinates for {J.shape[1]} unknowns")
    s2 = float(r @ r) / dof
    # Columns scaled to unit norm before inverting (pixels per px, per rad and per m).
    scale = np.linalg.norm(J, axis=0)
    scale[scale == 0.0] = 1.0
    Js = J / scale
    inverse = np.linalg.pinv(Js.T @ Js) / np.outer(scale, scale)
    cov = s2 * inverse[:p, :p]
    return np.asarray(0.5 * (cov + cov.T), dtype=np.float64)


def _calibrate(
    views: list[tuple[NDArray[np.float64], NDArray[np.float64]]],
    image_size: tuple[int, int],
    n_dist: int,
) -> tuple[NDArray[np.float64], NDArray[np.float64], list[float], NDArray[np.float64]]:
    """K (3, 3), dist (n_dist,), the per-view reprojection RMS (pixels) and the
    intrinsics' covariance (`calibration_covariance`)."""
    K, dist, per_view, covariance, _ = _calibrate_views(views, image_size, n_dist)
    return K, dist, per_view, covariance


def _calibrate_views(
    views: list[tuple[NDArray[np.float64], NDArray[np.float64]]],
    image_size: tuple[int, int],
    n_dist: int,
) -> tuple[NDArray[np.float64], NDArray[np.float64], list[float], NDArray[np.float64], list[Any]]:
    """`_calibrate`'s results and each view's fitted rotation vector (3,)."""
    object_points = [w.astype(np.float32) for w, _ in views]
    image_points = [p.astype(np.float32).reshape(-1, 1, 2) for _, p in views]
    _, K, dist, rvecs, tvecs = cv2.calibrateCamera(
        object_points,
        image_points,
        image_size,
        None,
        None,
        flags=_DIST_FLAGS[n_dist],
        criteria=_CRITERIA,
    )
    dist = np.asarray(dist, dtype=np.float64).reshape(-1)[:n_dist]
    per_view = []
    for (points_world, points_image), rvec, tvec in zip(views, rvecs, tvecs, strict=True):
        projected, _ = cv2.projectPoints(points_world, rvec, tvec, K, dist)
        residual = projected.reshape(-1, 2) - points_image
        per_view.append(float(np.sqrt(np.mean(np.sum(residual**2, axis=1)))))
    K_out: NDArray[np.float64] = np.asarray(K, dtype=np.float64)
    covariance = calibration_covariance(views, K_out, dist, rvecs, tvecs)
    return K_out, dist, per_view, covariance, list(rvecs)


def calibrate_intrinsics(
    images: Sequence[ArrayLike],
    board: Chessboard | CharucoBoard,
    *,
    n_dist: Literal[4, 5, 8] = 5,
    max_rms_px: float = 1.0,
    sources: Sequence[str] | None = None,
) -> IntrinsicsResult:
    """Calibrate K and the distortion from views of a board.

    Args:
        images: (H, W) grey views, all of one size; uint8, or linear float / uint16
            (stretched to 8 bits for detection, see `marker_pose.stretch_to_uint8`).
        board: The board in the views.
        n_dist: Number of OpenCV distortion coefficients to fit: 4 (k1, k2, p1, p2),
            5 (+ k3) or 8 (+ k4, k5, k6, the rational model).
        max_rms_px: A view is rejected when its reprojection RMS exceeds
            max(3 x the median over the views, `max_rms_px`), pixels.
        sources: Names of the views (default `image[i]`), for the report.

    Returns:
        The camera, its residuals and the views used and rejected.

    Raises:
        InputError: Bad arguments, a view that is not 2-D or not the size of the first,
            fewer than 3 usable views (copies of one view count once), or views that show
            the board at fewer than 3 different angles.
    """
    if not isinstance(board, Chessboard | CharucoBoard):
        raise InputError(
            "board", f"expected a Chessboard or a CharucoBoard, got {type(board).__name__}"
        )
    if n_dist not in _DIST_FLAGS:
        raise InputError("n_dist", f"expected 4, 5 or 8 distortion coefficients, got {n_dist!r}")
    if not (isinstance(max_rms_px, int | float) and math.isfinite(max_rms_px) and max_rms_px > 0):
        raise InputError("max_rms_px", f"expected a positive number of pixels, got {max_rms_px!r}")
    names = [f"image[{i}]" for i in range(len(images))] if sources is None else list(sources)
    if len(names) != len(images):
        raise InputError(
            "sources", f"expected {len(images)} names (one per image), got {len(names)}"
        )

    detector = None
    if isinstance(board, CharucoBoard):
        detector = cv2.aruco.CharucoDetector(board.cv_board())
    image_size: tuple[int, int] | None = None
    views: list[tuple[NDArray[np.float64], NDArray[np.float64]]] = []
    view_names: list[str] = []
    rejected: list[tuple[str, str]] = []
    for image, name in zip(images, names, strict=True):
        image_u8 = stretch_to_uint8(image, source=name)
        height, width = image_u8.shape
        if image_size is None:
            image_size = (width, height)
        elif (width, height) != image_size:
            raise InputError(
                name,
                f"image is {width}x{height} px, expected {image_size[0]}x{image_size[1]} px "
                "like the first image",
            )
        if isinstance(board, Chessboard):
            found = _detect_chessboard(image_u8, board)
        else:
            found = _detect_charuco(image_u8, detector, board)
        if isinstance(found, str):
            rejected.append((name, found))
        else:
            views.append(found)
            view_names.append(name)

    order = {name: i for i, name in enumerate(names)}

    def in_input_order(items: list[tuple[str, str]]) -> tuple[tuple[str, str], ...]:
        return tuple(sorted(items, key=lambda item: order[item[0]]))

    def too_few() -> InputError:
        reasons = "; ".join(f"{n}: {r}" for n, r in in_input_order(rejected))
        return InputError(
            "images",
            f"{len(views)} usable views of the board, need at least {MIN_VIEWS}"
            + (f" (rejected: {reasons})" if reasons else ""),
        )

    n_found = len(views)
    copies = same_views(views)
    for j, (i, offset) in copies.items():
        rejected.append(
            (
                view_names[j],
                f"the same view as {view_names[i]} (every corner within {offset:.2f} px): "
                "a copy adds no information; expected each photo from another angle",
            )
        )
    copied = [view_names[j] for j in sorted(copies)]
    views = [v for k, v in enumerate(views) if k not in copies]
    view_names = [n for k, n in enumerate(view_names) if k not in copies]
    if len(views) < MIN_VIEWS and copies:
        raise InputError(
            "images",
            f"{n_found} views of the board but only {len(views)} distinct "
            f"({listing(copied)} {'is' if len(copied) == 1 else 'are'} the same view as an "
            f"earlier one): expected {EXPECTED_VIEWS}",
        )
    if len(views) < MIN_VIEWS or image_size is None:
        raise too_few()
    while True:
        K, dist, per_view, covariance, rvecs = _calibrate_views(views, image_size, n_dist)
        limit = max(3.0 * float(np.median(per_view)), float(max_rms_px))
        bad = [i for i, rms in enumerate(per_view) if rms > limit]
        if not bad:
            break
        for i in bad:
            rejected.append(
                (
                    view_names[i],
                    f"reprojection RMS {per_view[i]:.3f} px above the limit {limit:.3f} px "
                    f"(max of 3 x the median and max_rms_px={max_rms_px:g})",
                )
            )
        views = [v for i, v in enumerate(views) if i not in bad]
        view_names = [n for i, n in enumerate(view_names) if i not in bad]
        if len(views) < MIN_VIEWS:
            raise too_few()

    normals = board_normals(rvecs)
    groups = angle_groups(normals)
    if len(groups) < MIN_ANGLES:
        angles = "1 angle" if len(groups) == 1 else f"{len(groups)} different angles"
        described = "; ".join(listing([view_names[k] for k in group]) for group in groups)
        raise InputError(
            "images",
            f"the {len(views)} views show the board at only {angles} (board normals within "
            f"{DISTINCT_ANGLE_DEG:g} degrees of each other: {described}): expected "
            f"{EXPECTED_VIEWS}",
        )
    warnings = []
    largest_tilt = float(np.max(tilts_deg(normals)))
    if largest_tilt < MIN_TILT_DEG:
        warnings.append(
            f"the board is tilted at most {largest_tilt:.1f} degrees from square-on in "
            f"every view: the focal length is poorly determined; take {EXPECTED_VIEWS}"
        )
    n_points = np.array([w.shape[0] for w, _ in views], dtype=np.float64)
    rms = float(np.sqrt(np.sum(n_points * np.asarray(per_view) ** 2) / n_points.sum()))
    camera = Camera.from_params(
        fx=float(K[0, 0]),
        fy=float(K[1, 1]),
        cx=float(K[0, 2]),
        cy=float(K[1, 2]),
        width=image_size[0],
        height=image_size[1],
        dist=dist,
        skew=float(K[0, 1]),
    )
    camera = dataclasses.replace(camera, intrinsics_covariance=covariance)
    return IntrinsicsResult(
        camera=camera,
        rms_px=rms,
        per_image_rms_px=tuple(per_view),
        used=tuple(view_names),
        rejected=in_input_order(rejected),
        warnings=tuple(warnings),
    )
