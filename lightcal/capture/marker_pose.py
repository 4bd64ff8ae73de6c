"""Camera poses from calibration markers on the wall (ArUco grid or ChArUco board).

`estimate_pose` detects the board in one image and returns `T_camera_world` in the world
frame of `lightcal.capture.boards` (the wall is z = 0, the camera at z > 0; docs/conventions.md):

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
4. `cv2.solvePnP` (IPPE, for planar points) then `cv2.solvePnPRefineLM` on the camera's
   distortion model (`solve_pose`).
5. The pose's covariance from the reprojection fit (`pose_covariance`), in the
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
from typing import Any

import cv2
import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.ndimage import map_coordinates

from lightcal.capture.boards import ArucoGridBoard, CharucoBoard, aruco_dictionary
from lightcal.core.camera import Camera
from lightcal.core.rotations import rotvec_from_matrix
from lightcal.errors import InputError

MarkerBoard = ArucoGridBoard | CharucoBoard
"""Boards that carry ArUco markers, hence give a camera pose from one image."""

STRETCH_PERCENTILES = (0.5, 99.5)
"""Percentiles of a non-8-bit image mapped to 0 and 255 for detection."""

_STRETCH_SAMPLES = 1_000_000
"""About this many pixels are used to estimate the percentiles of a large image."""

_MIN_CHARUCO_CORNERS = 4
"""Fewest ChArUco corners (not all on one line) that determine a pose."""

_EDGE_SAMPLES = 16
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


def _detection_images(
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
    fractions = np.arange(_EDGE_SAMPLES) / _EDGE_SAMPLES
    starts = polygons[:, :, None, :]
    ends = np.roll(polygons, -1, axis=1)[:, :, None, :]
    dense = starts + fractions[None, None, :, None] * (ends - starts)
    dense = dense.reshape(polygons.shape[0], n_vertices * _EDGE_SAMPLES, 3)
    points_camera = dense.reshape(-1, 3) @ R_camera_world.T + t_camera_world
    pixels, valid = camera.project(points_camera)
    pixels = pixels.reshape(dense.shape[0], dense.shape[1], 2)
    polygon_valid = np.all(valid.reshape(dense.shape[0], dense.shape[1]), axis=1).tolist()
    return [pixels[i] for i in range(dense.shape[0]) if polygon_valid[i]]


def _residuals_px(
    camera: Camera,
    R_camera_world: NDArray[np.float64],
    t_camera_world: NDArray[np.float64],
    points_world: NDArray[np.float64],
    points_image: NDArray[np.float64],
) -> NDArray[np.float64]:
    """(N, 2) detected minus projected pixels of (N, 3) world points."""
    projected, _ = camera.project(points_world @ R_camera_world.T + t_camera_world)
    return points_image - projected


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

    @property
    def camera_centre_world(self) -> NDArray[np.float64]:
        """(3,) camera centre C = -R^T t in the world frame, metres (C_z > 0)."""
        return -self.R_camera_world.T @ self.t_camera_world

    @property
    def sigma(self) -> NDArray[np.float64]:
        """(6,) 1-sigma of (delta (rad), c (m)): the square roots of `covariance`'s diagonal."""
        return np.sqrt(np.diag(self.covariance))

    def residuals_px(self) -> NDArray[np.float64]:
        """(N, 2) detected minus projected pixel positions of `points_world`."""
        return _residuals_px(
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
    board by a tenth of a degree. Here each side of a quad is sampled at `_EDGE_SAMPLES`
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
    fractions = (np.arange(_EDGE_SAMPLES) + 0.5) / _EDGE_SAMPLES
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
    side_ok = big_enough & (count >= _EDGE_SAMPLES // 2)
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


def _detect_grid(
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


def _detect_charuco(
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
    if corner_flat.size >= _MIN_CHARUCO_CORNERS and _not_collinear(corners_world):
        R, t = solve_pose(corners_world, corners_px, camera, refine=True, source=source)
        corners_px = _refine_charuco_corners(image_f, board, camera, corner_flat, corners_px, R, t)
    return marker_flat, corner_flat, corners_world, corners_px


def _not_collinear(points_world: NDArray[np.float64]) -> bool:
    """True if the planar points span an area (are not all on one line)."""
    if points_world.shape[0] < 3:
        return False
    centred = points_world[:, :2] - points_world[:, :2].mean(axis=0)
    singular = np.linalg.svd(centred, compute_uv=False)
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
    residuals = _residuals_px(camera, R_camera_world, t_camera_world, points_world, points_image)
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


def estimate_pose(
    image: ArrayLike,
    camera: Camera,
    board: MarkerBoard,
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
        board: The board on the wall (its `origin_world_m` places it in the world).
        min_markers: Fewest detected board markers accepted.
        refine: Refine the IPPE pose with `cv2.solvePnPRefineLM`.
        source: Name of the image for the result and error messages.

    Returns:
        The pose, its covariance, its reprojection RMS and what was detected.

    Raises:
        InputError: The image has the wrong shape, fewer than `min_markers` markers were
            found (message `found {n} markers, need at least {min_markers}`), a ChArUco
            board gave fewer than 4 corners or only collinear ones, or the pose puts
            the camera behind the wall.
    """
    if isinstance(min_markers, bool) or not isinstance(min_markers, int) or min_markers < 1:
        raise InputError("min_markers", f"expected an int >= 1, got {min_markers!r}")
    if not isinstance(board, ArucoGridBoard | CharucoBoard):
        raise InputError(
            "board", f"expected an ArucoGridBoard or a CharucoBoard, got {type(board).__name__}"
        )
    image_u8, image_f = _detection_images(image, camera, source)

    if isinstance(board, ArucoGridBoard):
        ids, points_world, points_image = _detect_grid(image_u8, image_f, board, camera)
        if ids.size < min_markers:
            raise InputError(source, f"found {ids.size} markers, need at least {min_markers}")
        polygons = board.outline_world(ids)
    else:
        ids, corner_ids, points_world, points_image = _detect_charuco(
            image_u8, image_f, board, camera, source
        )
        if ids.size < min_markers:
            raise InputError(source, f"found {ids.size} markers, need at least {min_markers}")
        if corner_ids.size < _MIN_CHARUCO_CORNERS or not _not_collinear(
            board.corners_world(corner_ids)
        ):
            raise InputError(
                source,
                f"found {corner_ids.size} ChArUco corners, need at least "
                f"{_MIN_CHARUCO_CORNERS} not all on one line",
            )
        polygons = np.concatenate(
            [board.outline_world(corner_ids), board.marker_corners_world(ids)], axis=0
        )

    R, t = solve_pose(points_world, points_image, camera, refine=refine, source=source)
    centre = -R.T @ t
    if not centre[2] > 0.0:
        raise InputError(
            source,
            f"the pose puts the camera at world z = {centre[2]:.4g} m, expected z > 0 "
            "(in front of the wall)",
        )
    residuals = _residuals_px(camera, R, t, points_world, points_image)
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
    )


def estimate_poses(
    images: Sequence[ArrayLike],
    camera: Camera,
    board: MarkerBoard,
    *,
    sources: Sequence[str] | None = None,
    min_markers: int = 4,
    refine: bool = True,
) -> list[MarkerPose | InputError]:
    """`estimate_pose` for each image; a rejected image gives its `InputError` instead.

    Args:
        images: (H, W) grey images, as for `estimate_pose`.
        camera: The camera of every image.
        board: The board on the wall.
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
            x, y, z = result.camera_centre_world
            lines.append(
                f"{result.source}: {result.n_markers} markers, rms "
                f"{result.reprojection_rms_px:.3f} px, camera at ({x:.4f}, {y:.4f}, {z:.4f}) m"
            )
        else:
            lines.append(f"{result.source}: rejected: {result.detail}")
    return "\n".join(lines)
