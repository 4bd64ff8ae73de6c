"""Finding a board's markers or ChArUco corners in one image, to sub-pixel accuracy.

1. Detection runs on an 8-bit copy of the image. Linear float (or 16-bit) images are
   stretched between their 0.5th and 99.5th percentiles (`stretch_to_uint8`); the corner
   refinement below samples the stretched image before rounding.
2. ArUco grid: `cv2.aruco.ArucoDetector` (sub-pixel corner refinement), keeping the markers
   of the board; the 2-D points are the four corners of each marker.
   ChArUco: `cv2.aruco.CharucoDetector` given the camera; the 2-D points are the ChArUco
   (chessboard) corners, the markers only identify them.
3. Every corner is then refined on straight edges (`_refine_quads_on_edges`): lines fitted
   to the undistorted edge points of each marker (or of the black chessboard squares, placed
   by a first pose) are intersected. This removes the 0.1 - 0.2 px bias of `cornerSubPix`,
   which would tilt the pose of a board 2.5 m away by about 0.1 degree.

`lightcal.capture.marker_pose` turns what is found here into a pose.
"""

from __future__ import annotations

import math
from typing import Any

import cv2
import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.ndimage import map_coordinates

from lightcal.capture.boards import ArucoGridBoard, CharucoBoard, aruco_dictionary
from lightcal.capture.pose_fit import not_collinear, solve_pose
from lightcal.core.camera import Camera
from lightcal.errors import InputError

STRETCH_PERCENTILES = (0.5, 99.5)
"""Percentiles of a non-8-bit image mapped to 0 and 255 for detection."""

_STRETCH_SAMPLES = 1_000_000
"""About this many pixels are used to estimate the percentiles of a large image."""

MIN_CHARUCO_CORNERS = 4
"""Fewest ChArUco corners (not all on one line) that determine a pose."""

EDGE_SAMPLES = 16
"""Points per polygon edge when projecting polygons (lines bend under distortion), and
points per marker side when refining marker corners on the edges."""

_PROFILE_SAMPLES = 25
"""Samples across an edge when locating it on its profile."""

_MIN_HALF_WINDOW_PX = 1.5
"""Narrowest edge profile (half width, pixels) that still spans a blurred edge."""

_MAX_HALF_WINDOW_PX = 6.0
"""Widest edge profile (half width, pixels): enough for a blur of sigma 2 px, and narrow
enough that an illumination gradient across the profile barely moves the centroid."""

_EDGE_PASSES = 2
"""Passes of the edge refinement (each re-centres the profiles on the previous edges)."""

_MAX_CORNER_SHIFT_PX = 1.5
"""A corner refined on the edges further than this from the detector's keeps the latter."""


def _stretch(image: ArrayLike, source: str) -> NDArray[np.float64] | NDArray[np.uint8]:
    """A uint8 image unchanged, any other real image stretched to [0, 255] as float64."""
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
    scaled = (np.nan_to_num(values, nan=lo, posinf=hi, neginf=lo) - lo) * (255.0 / (hi - lo))
    return np.clip(scaled, 0.0, 255.0, out=scaled)


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
    stretched = _stretch(image, source)
    if stretched.dtype == np.uint8:
        return stretched.astype(np.uint8, copy=False)
    return np.rint(stretched).astype(np.uint8)


def detection_images(
    image: ArrayLike, camera: Camera, source: str
) -> tuple[NDArray[np.uint8], NDArray[np.float64]]:
    """The 8-bit image for the detectors and its float64 version (unrounded) for edges."""
    stretched = _stretch(image, source)
    height, width = stretched.shape
    if (width, height) != (camera.width, camera.height):
        raise InputError(
            source,
            f"image is {width}x{height} px, expected {camera.width}x{camera.height} px "
            "(the camera's size)",
        )
    if stretched.dtype == np.uint8:
        return stretched.astype(np.uint8, copy=False), stretched.astype(np.float64)
    return np.rint(stretched).astype(np.uint8), stretched.astype(np.float64, copy=False)


def _detector_parameters() -> Any:
    params = cv2.aruco.DetectorParameters()
    params.cornerRefinementMethod = cv2.aruco.CORNER_REFINE_SUBPIX
    params.cornerRefinementMaxIterations = 100
    params.cornerRefinementMinAccuracy = 0.001
    return params


def _refine_quads_on_edges(
    image: NDArray[np.float64],
    quads_px: NDArray[np.float64],
    camera: Camera,
    half_window_px: NDArray[np.float64],
) -> tuple[NDArray[np.float64], NDArray[np.bool_]]:
    """Corners of dark squares as intersections of lines fitted to their straight edges.

    `cornerSubPix` (what the detectors use) is biased on sharp images: it pulls the convex
    corners of a black square inwards by 0.1 - 0.2 px and moves chessboard saddle points
    by up to 0.1 px depending on their sub-pixel phase, which tilts the pose of a distant
    board by a tenth of a degree. Here each side of a quad is sampled at `EDGE_SAMPLES`
    points away from its corners; at each one the edge lies at the centroid of the
    intensity derivative along the side's outward normal, over +-`half_window_px` (at most
    `_MAX_HALF_WINDOW_PX`; exact for a box-filtered step edge). The edge points are
    undistorted (a straight edge on the wall is straight in a pinhole image), a line is
    fitted to each side, adjacent lines are intersected and the corner is distorted back to
    pixels. A second pass re-centres the profiles on the first pass's edges, so that windows
    truncating a blurred edge, or an illumination gradient across it, do not pull the edge
    towards the detector's estimate.

    Args:
        image: (H, W) float64 image, the quads darker than their surroundings.
        quads_px: (n, 4, 2) approximate corners (u, v), clockwise in the image (the order of
            `cv2.aruco` marker corners), within a fraction of the window of the truth.
        camera: Camera of the image.
        half_window_px: (n,) half width of the profile across each edge, pixels: it must
            stay inside the dark border and the light surround.

    Returns:
        corners_px: (n, 4, 2) refined corners (the input where not ok).
        ok: (n, 4) True where a corner was refined: both its sides had at least half their
            samples usable (inside the image, contrast at least half the quad's median),
            the window was at least `_MIN_HALF_WINDOW_PX`, and the corner moved less than
            `_MAX_CORNER_SHIFT_PX`.
    """
    current = quads_px
    ok = np.zeros(quads_px.shape[:2], dtype=bool)
    for _ in range(_EDGE_PASSES):
        corners, ok = _edge_line_corners(image, current, camera, half_window_px)
        current = np.where(ok[..., None], corners, current)
    ok &= np.linalg.norm(current - quads_px, axis=-1) < _MAX_CORNER_SHIFT_PX
    return np.where(ok[..., None], current, quads_px), ok


def _edge_line_corners(
    image: NDArray[np.float64],
    quads_px: NDArray[np.float64],
    camera: Camera,
    half_window_px: NDArray[np.float64],
) -> tuple[NDArray[np.float64], NDArray[np.bool_]]:
    """One pass of `_refine_quads_on_edges`: (corners (n, 4, 2), ok (n, 4)), unchecked shift."""
    n = quads_px.shape[0]
    if n == 0:
        return quads_px.copy(), np.zeros((0, 4), dtype=bool)
    height, width = image.shape
    starts = quads_px
    ends = np.roll(quads_px, -1, axis=1)
    lengths = np.linalg.norm(ends - starts, axis=2)  # (n, 4)
    direction = (ends - starts) / lengths[..., None]
    outward = np.stack([direction[..., 1], -direction[..., 0]], axis=-1)  # (n, 4, 2)
    half_window_px = np.minimum(half_window_px, _MAX_HALF_WINDOW_PX)
    margin_px = half_window_px[:, None] + 1.0  # keep the profiles clear of the corners
    big_enough = (half_window_px[:, None] >= _MIN_HALF_WINDOW_PX) & (lengths > 3.0 * margin_px)
    margin = np.minimum(margin_px / lengths, 0.4)  # (n, 4), fraction of the side
    fractions = (np.arange(EDGE_SAMPLES) + 0.5) / EDGE_SAMPLES
    t = margin[..., None] + (1.0 - 2.0 * margin[..., None]) * fractions  # (n, 4, M)
    offsets = np.linspace(-1.0, 1.0, _PROFILE_SAMPLES)[None, :] * half_window_px[:, None]
    base = starts[:, :, None, :] + t[..., None] * (ends - starts)[:, :, None, :]  # (n, 4, M, 2)
    samples = (
        base[:, :, :, None, :] + offsets[:, None, None, :, None] * outward[:, :, None, None, :]
    )  # (n, 4, M, K, 2)
    inside = (
        (samples[..., 0] >= 0.0)
        & (samples[..., 0] <= width - 1.0)
        & (samples[..., 1] >= 0.0)
        & (samples[..., 1] <= height - 1.0)
    ).all(axis=-1)  # (n, 4, M)
    flat = samples.reshape(-1, 2)
    values = map_coordinates(image, [flat[:, 1], flat[:, 0]], order=1, mode="nearest")
    steps = np.diff(values.reshape(samples.shape[:-1]), axis=-1)  # dark -> light: > 0
    midpoints = 0.5 * (offsets[:, 1:] + offsets[:, :-1])  # (n, K - 1)
    contrast = steps.sum(axis=-1)  # (n, 4, M)
    with np.errstate(divide="ignore", invalid="ignore"):
        edge_offset = (steps * midpoints[:, None, None, :]).sum(axis=-1) / contrast
    typical = np.median(np.where(inside, contrast, 0.0), axis=(1, 2), keepdims=True)
    usable = (
        inside
        & (contrast > 0.5 * typical)
        & (np.abs(edge_offset) < 0.8 * half_window_px[:, None, None])
    )
    points = base + np.where(usable, edge_offset, 0.0)[..., None] * outward[:, :, None, :]
    xy, valid = camera.pixels_to_normalized(points.reshape(-1, 2))
    xy = np.where(np.isfinite(xy), xy, 0.0).reshape(points.shape)
    usable &= valid.reshape(usable.shape)

    # Total least squares line per side, from the weighted 2x2 scatter matrix.
    weight = usable.astype(np.float64)
    count = weight.sum(axis=-1)  # (n, 4)
    side_ok = big_enough & (count >= EDGE_SAMPLES // 2)
    count = np.maximum(count, 1.0)
    mean = (weight[..., None] * xy).sum(axis=2) / count[..., None]  # (n, 4, 2)
    d = (xy - mean[:, :, None, :]) * weight[..., None]
    sxx = (d[..., 0] ** 2).sum(axis=-1)
    syy = (d[..., 1] ** 2).sum(axis=-1)
    sxy = (d[..., 0] * d[..., 1]).sum(axis=-1)
    angle = 0.5 * np.arctan2(2.0 * sxy, sxx - syy)  # direction of the side
    normal = np.stack([-np.sin(angle), np.cos(angle)], axis=-1)
    lines = np.concatenate([normal, -(normal * mean).sum(axis=-1, keepdims=True)], axis=-1)
    homogeneous = np.cross(np.roll(lines, 1, axis=1), lines)  # corner k: sides k - 1 and k
    with np.errstate(divide="ignore", invalid="ignore"):
        corners_xy = homogeneous[..., :2] / homogeneous[..., 2:3]
    corner_ok = side_ok & np.roll(side_ok, 1, axis=1) & np.all(np.isfinite(corners_xy), axis=-1)
    corners_xy = np.where(corner_ok[..., None], corners_xy, 0.0)
    pixels = camera.normalized_to_pixels(corners_xy.reshape(-1, 2)).reshape(n, 4, 2)
    return pixels, corner_ok & np.all(np.isfinite(pixels), axis=-1)


def _marker_half_windows(corners_px: NDArray[np.float64], dictionary: Any) -> NDArray[np.float64]:
    """(n,) edge profile half widths for markers: 0.45 of a module (a bit) in pixels."""
    modules_per_side = int(dictionary.markerSize) + 2  # one border bit on each side
    sides = np.linalg.norm(np.roll(corners_px, -1, axis=1) - corners_px, axis=-1)
    return 0.45 * sides.mean(axis=1) / modules_per_side


def detect_grid(
    image: NDArray[np.uint8], image_f: NDArray[np.float64], board: ArucoGridBoard, camera: Camera
) -> tuple[NDArray[np.int64], NDArray[np.float64], NDArray[np.float64]]:
    """Detected board markers: ids (n,), world points (4n, 3), image points (4n, 2)."""
    dictionary = aruco_dictionary(board.dictionary)
    detector = cv2.aruco.ArucoDetector(dictionary, _detector_parameters())
    corners, ids, _ = detector.detectMarkers(image)
    if ids is None or len(corners) == 0:
        return np.zeros(0, np.int64), np.zeros((0, 3)), np.zeros((0, 2))
    ids_flat = np.asarray(ids).reshape(-1).astype(np.int64)
    corners_px = np.asarray(corners, dtype=np.float64).reshape(-1, 4, 2)
    on_board = np.isin(ids_flat, board.ids)
    # A marker id seen twice is ambiguous: drop every copy.
    unique_ids, counts = np.unique(ids_flat[on_board], return_counts=True)
    keep = on_board & np.isin(ids_flat, unique_ids[counts == 1])
    order = np.argsort(ids_flat[keep])
    kept_ids = ids_flat[keep][order]
    kept_corners = corners_px[keep][order]
    refined, _ = _refine_quads_on_edges(
        image_f, kept_corners, camera, _marker_half_windows(kept_corners, dictionary)
    )
    return kept_ids, board.corners_world(kept_ids).reshape(-1, 3), refined.reshape(-1, 2)


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
    `_refine_quads_on_edges` (window: 0.45 of the white gap between a square's edge and
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
    refined, ok = _refine_quads_on_edges(image_f, quads, camera, 0.45 * gap * side_px)
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

    The points are the detected ChArUco corners, refined on the edges of the black squares
    around them (`_refine_charuco_corners`) from a first pose on the detector's corners.
    The markers only identify the board: their corners, 0.5 module from a white gap that is
    narrow at a distance, are less accurate than the chessboard corners on blurred images.
    """
    charuco_params = cv2.aruco.CharucoParameters()
    charuco_params.cameraMatrix = np.array(camera.K)
    charuco_params.distCoeffs = np.array(camera.dist)
    detector = cv2.aruco.CharucoDetector(board.cv_board(), charuco_params, _detector_parameters())
    corners, corner_ids, _, marker_ids = detector.detectBoard(image)
    no_points = np.zeros((0, 3)), np.zeros((0, 2))
    if marker_ids is None or len(marker_ids) == 0:
        return np.zeros(0, np.int64), np.zeros(0, np.int64), *no_points
    marker_flat = np.unique(np.asarray(marker_ids).reshape(-1).astype(np.int64))
    marker_flat = marker_flat[np.isin(marker_flat, board.marker_ids)]
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
