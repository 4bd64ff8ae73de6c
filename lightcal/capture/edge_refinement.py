"""Corners of dark squares refined on their straight edges, to sub-pixel accuracy.

`cornerSubPix` (what OpenCV's marker and ChArUco detectors use) is biased on sharp images
by 0.1 - 0.2 px, which tilts the pose of a board 2.5 m away by about 0.1 degree. Here
lines fitted to the undistorted edge points of each square are intersected
(`refine_quads_on_edges`). `lightcal.capture.marker_detection` and
`lightcal.capture.marker_search` use it on the markers and the chessboard squares.
"""

from __future__ import annotations

import warnings
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray
from scipy.ndimage import map_coordinates

from lightcal.core.camera import Camera

__all__ = ["EDGE_SAMPLES", "marker_half_windows", "refine_quads_on_edges"]

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

_TAIL_FRACTION = 0.2
"""The outer fraction of an edge profile's samples on each side where the illumination's
gradient is measured (`_flatten_illumination`)."""

_PLATEAU_SIGMAS = 3.0
"""A profile's light-side tail is a plateau when it starts this many edge widths (the
spread of the derivative) beyond the edge."""

_EDGE_PASSES = 2
"""Passes of the edge refinement (each re-centres the profiles on the previous edges)."""

_MAX_CORNER_SHIFT_PX = 3.0
_MAX_CORNER_SHIFT_WINDOWS = 0.5
"""A corner refined on the edges further from the detector's than the larger of
_MAX_CORNER_SHIFT_PX and _MAX_CORNER_SHIFT_WINDOWS profile half widths keeps the
detector's (large markers: the detector's corners on a stretched, blurred 24 MP photo can
be 2 px off, well inside a 6 px profile). Small tags too: on `lightcal synth
--real-world`'s 8-bit JPEGs (tag36h11 of 37 px, modules of 3.7 px) OpenCV put one corner
of a tag 1.4-2.1 px off in 3 of 8 photos, which the edges found within 0.25 px; with a
limit of 1.5 px those corners stayed where the detector put them and moved the camera
centre by 7 mm. 3 px is `marker_search.CONSISTENT_PX`, how far apart two detections of one
marker may be."""


def refine_quads_on_edges(
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
            `_MAX_CORNER_SHIFT_PX` or half the window.
    """
    current = quads_px
    ok = np.zeros(quads_px.shape[:2], dtype=bool)
    clipped = _clipped_pixels(image)
    for _ in range(_EDGE_PASSES):
        corners, ok = _edge_line_corners(image, current, camera, half_window_px, clipped)
        current = np.where(ok[..., None], corners, current)
    max_shift_px = np.maximum(
        _MAX_CORNER_SHIFT_PX,
        _MAX_CORNER_SHIFT_WINDOWS * np.minimum(half_window_px, _MAX_HALF_WINDOW_PX),
    )
    ok &= np.linalg.norm(current - quads_px, axis=-1) < max_shift_px[:, None]
    return np.where(ok[..., None], current, quads_px), ok


def _edge_line_corners(
    image: NDArray[np.float64],
    quads_px: NDArray[np.float64],
    camera: Camera,
    half_window_px: NDArray[np.float64],
    clipped: NDArray[np.uint8] | None = None,
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
    profiles = values.reshape(samples.shape[:-1])
    midpoints = 0.5 * (offsets[:, 1:] + offsets[:, :-1])  # (n, K - 1)
    edge_offset, contrast, plateau = _edge_offsets(profiles, offsets, midpoints)
    if np.any(plateau):  # the illumination's gradient measured on plateaus: divided out
        flattened = _edge_offsets(_flatten_illumination(profiles, offsets), offsets, midpoints)
        edge_offset = np.where(plateau, flattened[0], edge_offset)
        contrast = np.where(plateau, flattened[1], contrast)
    typical = np.median(np.where(inside, contrast, 0.0), axis=(1, 2), keepdims=True)
    usable = (
        inside
        & (contrast > 0.5 * typical)
        & (np.abs(edge_offset) < 0.8 * half_window_px[:, None, None])
    )
    if clipped is not None:  # a profile that reaches the image's clipped top is flat there
        at_top = map_coordinates(clipped, [flat[:, 1], flat[:, 0]], order=0, mode="nearest")
        usable &= ~np.any(at_top.reshape(samples.shape[:-1]) > 0, axis=-1)
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


def marker_half_windows(corners_px: NDArray[np.float64], dictionary: Any) -> NDArray[np.float64]:
    """(n,) edge profile half widths for markers: 0.45 of a module (a bit) in pixels."""
    modules_per_side = int(dictionary.markerSize) + 2  # one border bit on each side
    sides = np.linalg.norm(np.roll(corners_px, -1, axis=1) - corners_px, axis=-1)
    return 0.45 * sides.mean(axis=1) / modules_per_side


def _clipped_pixels(image: NDArray[np.float64]) -> NDArray[np.uint8] | None:
    """(H, W) 1 on and next to the pixels at the image's maximum when more than one pixel
    reaches it (a clipped, saturated plateau), else None."""
    top = np.max(image)
    at_top = image >= top
    if np.count_nonzero(at_top) < 2:
        return None
    return np.asarray(cv2.dilate(at_top.astype(np.uint8), np.ones((3, 3), np.uint8)), np.uint8)


def _edge_offsets(
    profiles: NDArray[np.float64], offsets: NDArray[np.float64], midpoints: NDArray[np.float64]
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.bool_]]:
    """Each profile's edge: the centroid of its derivative.

    Args:
        profiles: (n, 4, M, K) intensities along each profile (dark to light).
        offsets: (n, K) signed distance of each sample from the profile's centre, px.
        midpoints: (n, K - 1) the offsets between samples.

    Returns:
        edge_offset: (n, 4, M) the edge's offset along the profile, px.
        contrast: (n, 4, M) the rise across the profile.
        flat: (n, 4) whether the side's light-side tail (`_TAIL_FRACTION` of the samples)
            starts `_PLATEAU_SIGMAS` edge widths (the derivative's median spread along the
            side) or more beyond the edge: a plateau where `_flatten_illumination` may
            measure the illumination.
    """
    steps = np.diff(profiles, axis=-1)  # dark -> light: > 0
    contrast = steps.sum(axis=-1)
    with np.errstate(divide="ignore", invalid="ignore"):
        edge_offset = (steps * midpoints[:, None, None, :]).sum(axis=-1) / contrast
        spread = (steps * (midpoints[:, None, None, :] - edge_offset[..., None]) ** 2).sum(
            axis=-1
        ) / contrast
    k = profiles.shape[-1]
    tail_start = offsets[:, k - max(3, round(_TAIL_FRACTION * k))]  # (n,)
    with warnings.catch_warnings():  # (a side without a usable profile: NaN, not flat)
        warnings.simplefilter("ignore", RuntimeWarning)
        width = np.sqrt(np.nanmedian(np.where(spread > 0.0, spread, np.nan), axis=-1))
        beyond = tail_start[:, None] - np.nanmedian(np.abs(edge_offset), axis=-1)
    flat = np.isfinite(width) & (beyond >= _PLATEAU_SIGMAS * width)
    return edge_offset, contrast, flat[..., None] & np.ones(edge_offset.shape, dtype=bool)


def _flatten_illumination(
    profiles: NDArray[np.float64], offsets: NDArray[np.float64]
) -> NDArray[np.float64]:
    """Edge profiles with a linear illumination gradient across them divided out.

    A profile across an edge is albedo x illumination, I(s) = A(s) L0 (1 + g s); the
    gradient g adds A L0 g to the derivative, whose centroid it pulls towards the light
    side (0.2 px for a beam whose light changes by 5 % across a 12 px profile). On the
    light side's plateau (the outer `_TAIL_FRACTION` of the samples, beyond the edge's
    blur: see `_edge_offsets`) dI/ds / I = g whatever the albedo, so g is the slope
    of a line fitted there over its level, and I / (1 + g s) is the profile under even
    light, to first order in g (an offset in the image, such as the stretch's, biases g
    by the offset over the level).

    Args:
        profiles: (n, 4, M, K) intensities along each profile (dark to light).
        offsets: (n, K) signed distance of each sample from the profile's centre, px.

    Returns:
        (n, 4, M, K) the flattened profiles.
    """
    k = profiles.shape[-1]
    tail = max(3, round(_TAIL_FRACTION * k))
    s = offsets[:, None, None, k - tail :]  # (n, 1, 1, T)
    y = profiles[..., k - tail :]
    ds = s - s.mean(axis=-1, keepdims=True)
    y_mean = y.mean(axis=-1, keepdims=True)
    with np.errstate(divide="ignore", invalid="ignore"):
        slope = (ds * (y - y_mean)).sum(axis=-1, keepdims=True) / (ds * ds).sum(
            axis=-1, keepdims=True
        )
        g = slope / (y_mean - slope * s.mean(axis=-1, keepdims=True))  # level at s = 0
    g = np.where(np.isfinite(g) & (y_mean > 0.0), g, 0.0)
    return profiles / np.maximum(1.0 + g * offsets[:, None, None, :], 0.2)
