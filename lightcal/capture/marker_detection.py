"""Finding a board's markers or ChArUco corners in one image, to sub-pixel accuracy.

1. Detection runs on 8-bit copies of the image. Linear float (or 16-bit) images are
   stretched between their 0.5th and 99.5th percentiles (`stretch_to_uint8`); the corner
   refinement below samples the linear image with that offset and scale, unclipped.
2. ArUco grid: the markers of the board found on that stretch and on gamma, log and
   local-contrast stretches of the image, merged and checked for consistency
   (`lightcal.capture.marker_search.find_markers`: a bright beam no longer hides the
   markers outside it); the 2-D points are the four corners of each marker.
   ChArUco: `cv2.aruco.CharucoDetector` given the camera; the 2-D points are the ChArUco
   (chessboard) corners, the markers only identify them.
3. Every corner is then refined on straight edges (`lightcal.capture.edge_refinement`):
   lines fitted to the undistorted edge points of each marker (or of the black chessboard
   squares, placed by a first pose) are intersected. This removes the 0.1 - 0.2 px bias of
   `cornerSubPix`, which would tilt the pose of a board 2.5 m away by about 0.1 degree.

`lightcal.capture.marker_pose` turns what is found here into a pose.
"""

from __future__ import annotations

import math

import cv2
import numpy as np
from numpy.typing import ArrayLike, NDArray

from lightcal.capture.boards import ArucoGridBoard, CharucoBoard
from lightcal.capture.edge_refinement import (
    EDGE_SAMPLES,
    marker_half_windows,
    refine_quads_on_edges,
)
from lightcal.capture.marker_search import (
    STRETCHES,
    MarkerSearch,
    detection_stretches,
    detector_parameters,
    find_markers,
    search_stretched,
)
from lightcal.capture.pose_fit import not_collinear, solve_pose
from lightcal.core.camera import Camera
from lightcal.errors import InputError

__all__ = [
    "EDGE_SAMPLES",
    "MIN_CHARUCO_CORNERS",
    "STRETCH_PERCENTILES",
    "detect_charuco",
    "detect_grid",
    "detection_images",
    "find_board_markers",
    "search_grid",
    "stretch_to_uint8",
]

STRETCH_PERCENTILES = (0.5, 99.5)
"""Percentiles of a non-8-bit image mapped to 0 and 255 for detection."""

_STRETCH_SAMPLES = 1_000_000
"""About this many pixels are used to estimate the percentiles of a large image."""

MIN_CHARUCO_CORNERS = 4
"""Fewest ChArUco corners (not all on one line) that determine a pose."""


def _affine(image: ArrayLike, source: str) -> NDArray[np.float64] | NDArray[np.uint8]:
    """A uint8 image unchanged; any other real image mapped so that its 0.5th and 99.5th
    percentiles become 0 and 255, as float64, not clipped (non-finite pixels put at the
    percentiles)."""
    array = np.asarray(image)
    if array.ndim != 2:
        raise InputError(source, f"expected a 2-D (H, W) grey image, got shape {array.shape}")
    if array.dtype == np.uint8:
        return np.ascontiguousarray(array)
    if array.dtype.kind not in "uif":
        raise InputError(source, f"expected a numeric grey image, got dtype {array.dtype}")
    values = array.astype(np.float64, copy=False)
    step = max(1, int(math.sqrt(values.size / _STRETCH_SAMPLES)))
    sample = values[::step, ::step]
    sample = sample[np.isfinite(sample)]
    if sample.size == 0:
        return np.zeros(array.shape)
    lo, hi = np.percentile(sample, STRETCH_PERCENTILES)
    if not hi > lo:
        return np.zeros(array.shape)
    scaled = values - lo
    if not np.all(np.isfinite(scaled)):  # (one pass over a finite image, not three)
        np.nan_to_num(scaled, copy=False, nan=0.0, posinf=hi - lo, neginf=0.0)
    scaled *= 255.0 / (hi - lo)
    return scaled


def _to_uint8(affine: NDArray[np.float64] | NDArray[np.uint8]) -> NDArray[np.uint8]:
    """(H, W) uint8: `affine` clipped to [0, 255] and rounded (half to even)."""
    # OpenCV saturates and rounds in one pass; negative values are clipped first (it
    # would take their absolute value).
    positive = np.maximum(affine, 0.0, dtype=np.float32)
    return np.asarray(cv2.convertScaleAbs(positive), dtype=np.uint8)


def stretch_to_uint8(image: ArrayLike, *, source: str = "image") -> NDArray[np.uint8]:
    """An 8-bit copy of a grey image for marker and corner detection.

    uint8 images are returned unchanged (as a contiguous array). Other images (linear
    float, uint16) are mapped linearly so that their 0.5th and 99.5th percentiles over the
    finite pixels become 0 and 255, then clipped and rounded; NaN pixels become 0 and
    infinite ones 0 or 255. A constant image becomes all 0.

    Args:
        image: (H, W) grey image, any real dtype.
        source: Name of the image for error messages.

    Returns:
        image_u8: (H, W) uint8.

    Raises:
        InputError: The image is not 2-D or not numeric.
    """
    stretched = _affine(image, source)
    if stretched.dtype == np.uint8:
        return stretched.astype(np.uint8, copy=False)
    return _to_uint8(stretched)


def detection_images(
    image: ArrayLike, camera: Camera, source: str
) -> tuple[NDArray[np.uint8], NDArray[np.float64]]:
    """The 8-bit image for the detectors (`stretch_to_uint8`) and the float64 image the
    edges are refined on: the same offset and scale, neither clipped nor rounded (a uint8
    image as float).

    Raises:
        InputError: The image is not 2-D, not numeric, or not of the camera's size.
    """
    affine = _affine(image, source)
    height, width = affine.shape
    if (width, height) != (camera.width, camera.height):
        raise InputError(
            source,
            f"image is {width}x{height} px, expected {camera.width}x{camera.height} px "
            "(the camera's size)",
        )
    if affine.dtype == np.uint8:
        return affine.astype(np.uint8, copy=False), affine.astype(np.float64)
    image_u8 = _to_uint8(affine)
    return image_u8, affine.astype(np.float64, copy=False)


_detector_parameters = detector_parameters  # (the name other capture modules import)
_refine_quads_on_edges = refine_quads_on_edges
_marker_half_windows = marker_half_windows


def search_grid(
    image: NDArray[np.uint8],
    image_f: NDArray[np.float64],
    board: ArucoGridBoard,
    camera: Camera,
    *,
    source: str = "image",
) -> tuple[NDArray[np.int64], NDArray[np.float64], NDArray[np.float64], MarkerSearch]:
    """`detect_grid` with what was found and refused, and why (`MarkerSearch`).

    Args:
        image: (H, W) the 8-bit image of `detection_images`.
        image_f: (H, W) its float image.
        board: The ArUco grid on the wall.
        camera: The camera of the image.
        source: Name of the image for the search's report.

    Returns:
        ids: (n,) the board markers found, ascending; points_world: (4n, 3) their corners
        on the wall, metres; points_image: (4n, 2) the same corners in the image, pixels;
        and the `MarkerSearch`.
    """
    search = find_markers(image, image_f, camera, {board.dictionary: board.ids}, source=source)
    ids = search.ids(board.dictionary)
    corners = search.corners_px(board.dictionary)
    return ids, board.corners_world(ids).reshape(-1, 3), corners.reshape(-1, 2), search


def detect_grid(
    image: NDArray[np.uint8], image_f: NDArray[np.float64], board: ArucoGridBoard, camera: Camera
) -> tuple[NDArray[np.int64], NDArray[np.float64], NDArray[np.float64]]:
    """Detected board markers: ids (n,), world points (4n, 3), image points (4n, 2).

    The markers are searched on several stretches of the image and merged; a marker found
    at inconsistent places is left out (`search_grid` says which, and why).
    """
    ids, points_world, points_image, _ = search_grid(image, image_f, board, camera)
    return ids, points_world, points_image


def find_board_markers(
    image: ArrayLike, camera: Camera, board: ArucoGridBoard, *, source: str = "image"
) -> MarkerSearch:
    """The board's markers in a photo as read (any real dtype), found and refused.

    Raises:
        InputError: The image is not 2-D, not numeric, or not of the camera's size.
    """
    image_u8, image_f = detection_images(image, camera, source)
    return search_grid(image_u8, image_f, board, camera, source=source)[3]


def _refine_charuco_corners(
    image_f: NDArray[np.float64],
    board: CharucoBoard,
    camera: Camera,
    corner_ids: NDArray[np.int64],
    corners_px: NDArray[np.float64],
    R_camera_world: NDArray[np.float64],
    t_camera_world: NDArray[np.float64],
) -> NDArray[np.float64]:
    """ChArUco corners refined on the edges of the black squares around them.

    The black squares are projected with an initial pose, refined by
    `refine_quads_on_edges` (window: 0.45 of the white gap between a square's edge and
    the marker in the next square), and each detected corner becomes the mean of the
    refined corners of the (one or two) black squares that touch it.

    Returns:
        corners_px: (m, 2) refined where possible, else the input.
    """
    sx, sy, s = board.squares_x, board.squares_y, board.square_length_m
    rows, cols = np.divmod(np.arange(sx * sy), sx)
    black = (rows + cols) % 2 == 0
    cols, rows = cols[black], rows[black]
    origin = board.origin_world_m
    dx = np.array([0.0, 1.0, 1.0, 0.0])
    dy = np.array([0.0, 0.0, 1.0, 1.0])
    grid_x = cols[:, None] + dx  # (B, 4) corner positions in squares
    grid_y = rows[:, None] + dy
    points_world = np.stack(
        [origin[0] + grid_x * s, origin[1] - grid_y * s, np.zeros_like(grid_x)], axis=-1
    )
    pixels, valid = camera.project(points_world.reshape(-1, 3) @ R_camera_world.T + t_camera_world)
    pixels = pixels.reshape(-1, 4, 2)
    height, width = image_f.shape
    visible = (
        valid.reshape(-1, 4).all(axis=1)
        & np.all(pixels[..., 0] >= 1.0, axis=1)
        & np.all(pixels[..., 0] <= width - 2.0, axis=1)
        & np.all(pixels[..., 1] >= 1.0, axis=1)
        & np.all(pixels[..., 1] <= height - 2.0, axis=1)
    )
    if not np.any(visible):
        return corners_px
    quads = pixels[visible]
    side_px = np.linalg.norm(np.roll(quads, -1, axis=1) - quads, axis=-1).mean(axis=1)
    gap = 0.5 * (board.square_length_m - board.marker_length_m) / board.square_length_m
    refined, ok = refine_quads_on_edges(image_f, quads, camera, 0.45 * gap * side_px)
    gx, gy = grid_x[visible][ok].astype(np.int64), grid_y[visible][ok].astype(np.int64)
    inner = (gx >= 1) & (gx <= sx - 1) & (gy >= 1) & (gy <= sy - 1)
    ids = (gy[inner] - 1) * (sx - 1) + (gx[inner] - 1)
    n_ids = (sx - 1) * (sy - 1)
    sums = np.zeros((n_ids, 2))
    counts = np.zeros(n_ids)
    np.add.at(sums, ids, refined[ok][inner])
    np.add.at(counts, ids, 1.0)
    found = counts[corner_ids] > 0
    out = corners_px.copy()
    out[found] = sums[corner_ids[found]] / counts[corner_ids[found], None]
    return out


def detect_charuco(
    image: NDArray[np.uint8],
    image_f: NDArray[np.float64],
    board: CharucoBoard,
    camera: Camera,
    source: str,
) -> tuple[NDArray[np.int64], NDArray[np.int64], NDArray[np.float64], NDArray[np.float64]]:
    """Marker ids (n,), ChArUco corner ids (m,), world points (m, 3), image points (m, 2).

    The markers are searched on several stretches of the image (`search_grid`'s
    `lightcal.capture.marker_search`: a beam does not hide them), and the chessboard
    corners between them interpolated and found to sub-pixel accuracy on the stretch that
    found the most. The points are these ChArUco corners, refined on the edges of the
    black squares around them (`_refine_charuco_corners`) from a first pose on the
    detector's corners.
    The markers only identify the board: their corners, 0.5 module from a white gap that is
    narrow at a distance, are less accurate than the chessboard corners on blurred images.
    """
    no_points = np.zeros((0, 3)), np.zeros((0, 2))
    images = detection_stretches(image, image_f)
    search = search_stretched(
        images, image_f, camera, {board.dictionary: board.marker_ids}, source=source
    )
    marker_flat = search.ids(board.dictionary)
    if marker_flat.size == 0:
        return np.zeros(0, np.int64), np.zeros(0, np.int64), *no_points
    # The chessboard corners between the markers found, sub-pixel on the stretch that found
    # the most markers (the first of STRETCHES among equals).
    best = max(STRETCHES, key=lambda s: sum(s in m.stretches for m in search.found))
    charuco_params = cv2.aruco.CharucoParameters()
    charuco_params.cameraMatrix = np.array(camera.K)
    charuco_params.distCoeffs = np.array(camera.dist)
    detector = cv2.aruco.CharucoDetector(board.cv_board(), charuco_params, detector_parameters())
    marker_corners = tuple(
        q.reshape(1, 4, 2).astype(np.float32) for q in search.corners_px(board.dictionary)
    )
    corners, corner_ids, _, _ = detector.detectBoard(
        images[best],
        markerCorners=marker_corners,
        markerIds=marker_flat.astype(np.int32).reshape(-1, 1),
    )
    if corner_ids is None or corners is None or len(corners) == 0:
        return marker_flat, np.zeros(0, np.int64), *no_points
    corner_flat = np.asarray(corner_ids).reshape(-1).astype(np.int64)
    corners_px = np.asarray(corners, dtype=np.float64).reshape(-1, 2)
    order = np.argsort(corner_flat)
    corner_flat, corners_px = corner_flat[order], corners_px[order]
    corners_world = board.corners_world(corner_flat)
    if corner_flat.size >= MIN_CHARUCO_CORNERS and not_collinear(corners_world):
        R, t = solve_pose(corners_world, corners_px, camera, refine=True, source=source)
        corners_px = _refine_charuco_corners(image_f, board, camera, corner_flat, corners_px, R, t)
    return marker_flat, corner_flat, corners_world, corners_px
