"""Camera poses from calibration markers on the wall (ArUco grid, ChArUco board or markers
placed one by one).

`estimate_pose` detects the board in one image and returns `T_camera_world` in the world
frame of `lightcal.capture.boards` (the wall is z = 0, the camera at z > 0; docs/conventions.md):

1. Detection on an 8-bit copy of the image (`stretch_to_uint8`), then
2. the markers (ArUco grid, marker layout) or ChArUco corners found by OpenCV's detectors,
   and
3. every corner refined on straight edges (steps 1-3: `lightcal.capture.marker_detection`;
   a `MarkerLayout`'s markers, AprilTags in their official corner order:
   `lightcal.capture.layout_detection`);
4. `cv2.solvePnP` (IPPE) then `cv2.solvePnPRefineLM` on the camera's distortion model
   (`solve_pose`), and
5. the pose's covariance from the reprojection fit (`pose_covariance`), as (delta, c):
   delta (rad) a rotation perturbation of R_camera_world in the camera frame, c the
   camera centre in the world frame (m) (steps 4-5: `lightcal.capture.pose_fit`).

This module exports the public names of both.

On synthetic 1600 x 1200 images (fx = 1400, distortion, 8 cm markers or 7 cm squares on
boards of 0.8 x 0.6 m) the poses are within 0.4 mm and 0.01 degrees of the truth from 0.8
to 2.5 m, and within 0.8 mm and 0.02 degrees under a Gaussian blur of 1 px and a light spot
that dims the image corners sevenfold (tests/test_marker_pose.py). On noisy detections the
predicted covariance matches the spread of the estimates (same file).

Too few markers raise `InputError`; `estimate_poses` collects those per image so that the
caller can reject the images and report why (`pose_report`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import cv2
import numpy as np
from numpy.typing import ArrayLike, NDArray

from lightcal.capture.apriltag import printed_corners
from lightcal.capture.boards import ArucoGridBoard, CharucoBoard, MarkerLayout
from lightcal.capture.layout_detection import search_layout
from lightcal.capture.marker_detection import (
    EDGE_SAMPLES,
    MIN_CHARUCO_CORNERS,
    STRETCH_PERCENTILES,
    detect_charuco,
    detection_images,
    search_grid,
    stretch_to_uint8,
)
from lightcal.capture.pose_fit import (
    intrinsics_steps,
    not_collinear,
    pose_covariance,
    pose_intrinsics_jacobian,
    pose_jacobian,
    residuals_px,
    solve_pose,
)
from lightcal.core.camera import Camera
from lightcal.errors import InputError

__all__ = [
    "STRETCH_PERCENTILES",
    "MarkerBoard",
    "MarkerPose",
    "estimate_pose",
    "estimate_poses",
    "intrinsics_steps",
    "pose_covariance",
    "pose_intrinsics_jacobian",
    "pose_jacobian",
    "pose_report",
    "project_polygons",
    "solve_pose",
    "stretch_to_uint8",
]

MarkerBoard = ArucoGridBoard | CharucoBoard | MarkerLayout
"""Boards that carry markers, hence give a camera pose from one image."""


def project_polygons(
    camera: Camera,
    R_camera_world: NDArray[np.float64],
    t_camera_world: NDArray[np.float64],
    polygons_world: NDArray[np.float64],
) -> list[NDArray[np.float64]]:
    """Project wall polygons into the image, edges densified so that distortion bends them.

    Args:
        camera: The camera.
        R_camera_world: (3, 3).
        t_camera_world: (3,).
        polygons_world: (P, V, 3) closed polygons, metres.

    Returns:
        A list of (V * 16, 2) pixel outlines, one per polygon whose every sampled point
        projects validly (in front of the camera); the others are left out.
    """
    polygons = np.asarray(polygons_world, dtype=np.float64)
    if polygons.size == 0:
        return []
    n_vertices = polygons.shape[1]
    fractions = np.arange(EDGE_SAMPLES) / EDGE_SAMPLES
    starts = polygons[:, :, None, :]
    ends = np.roll(polygons, -1, axis=1)[:, :, None, :]
    dense = starts + fractions[None, None, :, None] * (ends - starts)
    dense = dense.reshape(polygons.shape[0], n_vertices * EDGE_SAMPLES, 3)
    points_camera = dense.reshape(-1, 3) @ R_camera_world.T + t_camera_world
    pixels, valid = camera.project(points_camera)
    pixels = pixels.reshape(dense.shape[0], dense.shape[1], 2)
    polygon_valid = np.all(valid.reshape(dense.shape[0], dense.shape[1]), axis=1).tolist()
    return [pixels[i] for i in range(dense.shape[0]) if polygon_valid[i]]


@dataclass(frozen=True, eq=False)
class MarkerPose:
    """A camera pose found from the markers in one image.

    Attributes:
        source: Name of the image.
        R_camera_world: (3, 3) world -> camera rotation.
        t_camera_world: (3,) world -> camera translation, metres.
        reprojection_rms_px: RMS distance between the detected 2-D points and the
            projection of their world points, pixels.
        covariance: (6, 6) covariance of the pose as (delta, c): delta (rad, 3) a rotation
            perturbation R_camera_world -> exp(delta) R_camera_world in the camera frame,
            c (m, 3) the camera centre in the world frame; rows and columns in that order
            (`pose_covariance`; what the project file's `T_camera_world.covariance` holds).
        n_markers: Number of detected markers of the board.
        ids: (n_markers,) their ids.
        points_world: (N, 3) the world points used for the pose, metres.
        points_image: (N, 2) their detected pixels (u, v).
        camera: The camera the pose was computed with.
        mask_polygons_world: (P, 4, 3) wall areas covered by the detected print (marker
            squares for an ArUco grid, chessboard squares around the detected corners
            for a ChArUco board).
        refused: The markers seen but not used, each with why (`MarkerRefusal`'s words:
            "marker 7 (DICT_4X4_50) refused: found at places 5.1 px apart"); `pose_report`
            and a rejection for too few markers name them.
    """

    source: str
    R_camera_world: NDArray[np.float64]
    t_camera_world: NDArray[np.float64]
    reprojection_rms_px: float
    covariance: NDArray[np.float64] = field(repr=False)
    n_markers: int
    ids: NDArray[np.int64]
    points_world: NDArray[np.float64] = field(repr=False)
    points_image: NDArray[np.float64] = field(repr=False)
    camera: Camera = field(repr=False)
    mask_polygons_world: NDArray[np.float64] = field(repr=False)
    refused: tuple[str, ...] = ()

    @property
    def camera_center_world(self) -> NDArray[np.float64]:
        """(3,) camera centre C = -R^T t in the world frame, metres (C_z > 0)."""
        return -self.R_camera_world.T @ self.t_camera_world

    @property
    def sigma(self) -> NDArray[np.float64]:
        """(6,) 1-sigma of (delta (rad), c (m)): the square roots of `covariance`'s diagonal."""
        return np.sqrt(np.diag(self.covariance))

    def residuals_px(self) -> NDArray[np.float64]:
        """(N, 2) detected minus projected pixel positions of `points_world`."""
        return residuals_px(
            self.camera,
            self.R_camera_world,
            self.t_camera_world,
            self.points_world,
            self.points_image,
        )

    def marker_mask(self, height: int, width: int, *, margin_px: float = 3.0) -> NDArray[np.bool_]:
        """Pixels that see the detected print on the wall, padded by a margin.

        The polygons of `mask_polygons_world` are projected (edges densified so that lens
        distortion bends them) and filled; the result is dilated by `ceil(margin_px) + 1`
        pixels, so that every pixel whose footprint overlaps a polygon (its centre is
        within 1/sqrt(2) px of it) is covered, plus `margin_px`.

        Args:
            height: Rows of the mask (the image height).
            width: Columns of the mask (the image width).
            margin_px: Extra padding, pixels (>= 0).

        Returns:
            mask: (height, width) bool, True on and around the markers.
        """
        for name, value in (("height", height), ("width", width)):
            if isinstance(value, bool) or not isinstance(value, int | np.integer) or value < 1:
                raise InputError(name, f"expected a positive int, got {value!r}")
        if not (math.isfinite(margin_px) and margin_px >= 0.0):
            raise InputError("margin_px", f"expected a padding >= 0 pixels, got {margin_px!r}")
        mask = np.zeros((height, width), dtype=np.uint8)
        shift = 4
        outlines = project_polygons(
            self.camera, self.R_camera_world, self.t_camera_world, self.mask_polygons_world
        )
        for outline in outlines:
            # One polygon per call: fillPoly would cut holes where polygons overlap.
            fixed = np.rint(outline * (1 << shift)).astype(np.int32)
            cv2.fillPoly(mask, [fixed], 1, lineType=cv2.LINE_8, shift=shift)
        radius = math.ceil(margin_px) + 1
        kernel = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * radius + 1, 2 * radius + 1))
        return cv2.dilate(mask, kernel).astype(bool)


@dataclass(frozen=True, eq=False)
class _BoardFind:
    """What one board gave in one image: ids (n,), points (N, 3) and (N, 2), the print's
    polygons (P, 4, 3), and for a ChArUco board without enough corners, why (no points)."""

    ids: NDArray[np.int64]
    points_world: NDArray[np.float64]
    points_image: NDArray[np.float64]
    polygons: NDArray[np.float64]
    problem: str | None = None
    refused: tuple[str, ...] = ()


def _find_board(
    image_u8: NDArray[np.uint8],
    image_f: NDArray[np.float64],
    board: MarkerBoard,
    camera: Camera,
    source: str,
) -> _BoardFind:
    """One board's markers (ArUco grid, layout) or ChArUco corners in one image."""
    if isinstance(board, ArucoGridBoard):
        ids, points_world, points_image, search = search_grid(
            image_u8, image_f, board, camera, source=source
        )
        # The detector's corner order made the printed one (AprilTags: official images).
        quads = printed_corners(board.dictionary, points_image.reshape(-1, 4, 2))
        refused = tuple(str(r) for r in search.refused)
        return _BoardFind(
            ids, points_world, quads.reshape(-1, 2), board.outline_world(ids), refused=refused
        )
    if isinstance(board, MarkerLayout):
        indices, points_world, points_image, search = search_layout(
            image_u8, image_f, board, camera, source=source
        )
        ids = np.array([board.markers[i].id for i in indices], dtype=np.int64)
        refused = tuple(str(r) for r in search.refused)
        outline = board.outline_world(indices)
        return _BoardFind(ids, points_world, points_image, outline, refused=refused)
    ids, corner_ids, points_world, points_image = detect_charuco(
        image_u8, image_f, board, camera, source
    )
    if corner_ids.size < MIN_CHARUCO_CORNERS or not not_collinear(board.corners_world(corner_ids)):
        problem = (
            f"found {corner_ids.size} ChArUco corners, need at least "
            f"{MIN_CHARUCO_CORNERS} not all on one line"
        )
        return _BoardFind(ids, np.zeros((0, 3)), np.zeros((0, 2)), np.zeros((0, 4, 3)), problem)
    polygons = np.concatenate(
        [board.outline_world(corner_ids), board.marker_corners_world(ids)], axis=0
    )
    return _BoardFind(ids, points_world, points_image, polygons)


def _boards_of(board: MarkerBoard | Sequence[MarkerBoard]) -> list[MarkerBoard]:
    """The boards of `estimate_pose`'s `board` argument, each checked."""
    boards = list(board) if isinstance(board, Sequence) else [board]
    if not boards:
        raise InputError("board", "expected at least one board")
    for item in boards:
        if not isinstance(item, ArucoGridBoard | CharucoBoard | MarkerLayout):
            raise InputError(
                "board",
                "expected an ArucoGridBoard, a CharucoBoard or a MarkerLayout, got "
                f"{type(item).__name__}",
            )
    return boards


def estimate_pose(
    image: ArrayLike,
    camera: Camera,
    board: MarkerBoard | Sequence[MarkerBoard],
    *,
    min_markers: int = 4,
    refine: bool = True,
    source: str = "image",
) -> MarkerPose:
    """Camera pose `T_camera_world` from the board's markers seen in one image.

    Args:
        image: (H, W) grey image, uint8 or linear float / uint16 (stretched to 8 bits for
            detection only); its size must be the camera's.
        camera: Intrinsics and distortion of the image.
        board: The board on the wall (its `origin_world_m` places it in the world), or
            several boards on the one wall: the points of all of them make the pose (a
            ChArUco board with too few corners then gives none, and its markers do not
            count). No marker may be on two boards (`lightcal.capture.board_set`).
        min_markers: Fewest detected board markers accepted (of all boards together).
        refine: Refine the IPPE pose with `cv2.solvePnPRefineLM`.
        source: Name of the image for the result and error messages.

    Returns:
        The pose, its covariance, its reprojection RMS and what was detected (ids and
        points of the boards in the order given).

    Raises:
        InputError: The image has the wrong shape, fewer than `min_markers` markers were
            found (message `found {n} markers, need at least {min_markers}`), a single
            ChArUco board gave fewer than 4 corners or only collinear ones, or the pose
            puts the camera behind the wall.
    """
    if isinstance(min_markers, bool) or not isinstance(min_markers, int) or min_markers < 1:
        raise InputError("min_markers", f"expected an int >= 1, got {min_markers!r}")
    boards = _boards_of(board)
    image_u8, image_f = detection_images(image, camera, source)

    finds = [_find_board(image_u8, image_f, b, camera, source) for b in boards]
    refused = tuple(r for f in finds for r in f.refused)
    why = "".join(f"; {r}" for r in refused)  # what was seen but refused, and why
    if len(finds) == 1:
        found = finds[0]
        if found.ids.size < min_markers:
            raise InputError(
                source, f"found {found.ids.size} markers, need at least {min_markers}{why}"
            )
        if found.problem is not None:
            raise InputError(source, found.problem)
        ids, points_world, points_image = found.ids, found.points_world, found.points_image
        polygons = found.polygons
    else:
        used = [f for f in finds if f.problem is None]
        ids = np.concatenate([f.ids for f in used]) if used else np.zeros(0, np.int64)
        if ids.size < min_markers:
            raise InputError(source, f"found {ids.size} markers, need at least {min_markers}{why}")
        points_world = np.concatenate([f.points_world for f in used])
        points_image = np.concatenate([f.points_image for f in used])
        polygons = np.concatenate([f.polygons for f in used])

    R, t = solve_pose(points_world, points_image, camera, refine=refine, source=source)
    center = -R.T @ t
    if not center[2] > 0.0:
        raise InputError(
            source,
            f"the pose puts the camera at world z = {center[2]:.4g} m, expected z > 0 "
            "(in front of the wall)",
        )
    residuals = residuals_px(camera, R, t, points_world, points_image)
    return MarkerPose(
        source=source,
        R_camera_world=R,
        t_camera_world=t,
        reprojection_rms_px=float(np.sqrt(np.mean(np.sum(residuals**2, axis=1)))),
        covariance=pose_covariance(camera, R, t, points_world, points_image),
        n_markers=int(ids.size),
        ids=ids,
        points_world=points_world,
        points_image=points_image,
        camera=camera,
        mask_polygons_world=polygons,
        refused=refused,
    )


def estimate_poses(
    images: Sequence[ArrayLike],
    camera: Camera,
    board: MarkerBoard | Sequence[MarkerBoard],
    *,
    sources: Sequence[str] | None = None,
    min_markers: int = 4,
    refine: bool = True,
) -> list[MarkerPose | InputError]:
    """`estimate_pose` for each image; a rejected image gives its `InputError` instead.

    Args:
        images: (H, W) grey images, as for `estimate_pose`.
        camera: The camera of every image.
        board: The board on the wall, or several (as for `estimate_pose`).
        sources: Names of the images (default `image[i]`), same length as `images`.
        min_markers: Fewest detected markers accepted per image.
        refine: Refine each pose with Levenberg-Marquardt.

    Returns:
        One entry per image, in order: its `MarkerPose`, or the `InputError` saying why
        it was rejected (see `pose_report`).
    """
    names = [f"image[{i}]" for i in range(len(images))] if sources is None else list(sources)
    if len(names) != len(images):
        raise InputError(
            "sources", f"expected {len(images)} names (one per image), got {len(names)}"
        )
    results: list[MarkerPose | InputError] = []
    for image, name in zip(images, names, strict=True):
        try:
            results.append(
                estimate_pose(
                    image, camera, board, min_markers=min_markers, refine=refine, source=name
                )
            )
        except InputError as error:
            if error.source != name:
                raise
            results.append(error)
    return results


def pose_report(results: Sequence[MarkerPose | InputError]) -> str:
    """One line per image: its pose summary or why it was rejected.

    Args:
        results: What `estimate_poses` returned.

    Returns:
        Lines like `img_01.png: 24 markers, rms 0.08 px, camera at (0.102, -0.05, 1.203) m`
        and `img_02.png: rejected: found 2 markers, need at least 4`.
    """
    lines = []
    for result in results:
        if isinstance(result, MarkerPose):
            x, y, z = result.camera_center_world
            lines.append(
                f"{result.source}: {result.n_markers} markers, rms "
                f"{result.reprojection_rms_px:.3f} px, camera at ({x:.4f}, {y:.4f}, {z:.4f}) m"
                + "".join(f"; {r}" for r in result.refused)
            )
        else:
            lines.append(f"{result.source}: rejected: {result.detail}")
    return "\n".join(lines)
