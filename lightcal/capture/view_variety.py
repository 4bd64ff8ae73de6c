"""Whether views of a calibration board can determine a camera's intrinsics.

A view of a plane gives two constraints on the intrinsics, and they depend only on the
plane's orientation relative to the camera, its normal (Zhang 2000: the images of the
plane's two circular points, which lie on its line at infinity). Moving the board in its
plane or towards the camera, turning it about its normal, or photographing it twice adds
nothing; a board seen square-on (normal along the optical axis) says nothing about the
focal length, which then trades with the distance. `cv2.calibrateCamera` returns numbers
all the same: ten copies of one photo gave fx 18 % off, with no warning. Hence:

- `same_views`: a view whose every corner lies within `SAME_VIEW_PX` of an earlier
  view's is a copy (the same photo, re-encoded, or a burst from a tripod): it adds no
  information, and counted as independent it would shrink the covariance;
- `angle_groups`: the views grouped by their board normals in the camera frame, within
  `DISTINCT_ANGLE_DEG` of each other; `lightcal.capture.intrinsics` refuses fewer than
  `MIN_ANGLES` groups (3: with zero skew two orientations in general position determine
  fx, fy, cx, cy; a third guards against the cases where two do not);
- `tilts_deg`: each board's tilt from square-on; below `MIN_TILT_DEG` in every view the
  focal length is poorly determined (a warning).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import cv2
import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = [
    "DISTINCT_ANGLE_DEG",
    "EXPECTED_VIEWS",
    "MIN_ANGLES",
    "MIN_TILT_DEG",
    "SAME_VIEW_PX",
    "angle_groups",
    "board_normals",
    "listing",
    "same_views",
    "tilts_deg",
]

SAME_VIEW_PX = 0.5
"""Two views whose corners all lie within this of each other (pixels) are one view."""

DISTINCT_ANGLE_DEG = 5.0
"""Board normals further apart than this (degrees) are different angles."""

MIN_ANGLES = 3
"""Fewest different board angles a calibration accepts."""

MIN_TILT_DEG = 10.0
"""Below this tilt from square-on in every view, the focal length is poorly determined."""

EXPECTED_VIEWS = (
    f"photos of the board from at least {MIN_ANGLES} different angles, tilted by 10-45 degrees"
)
"""What a calibration needs, in the words of the messages."""

View = tuple[NDArray[np.float64], NDArray[np.float64]]
"""(world points (N, 3), detected pixels (N, 2)) of one view."""


def listing(names: Sequence[str], *, limit: int = 3) -> str:
    """`a, b, c and 4 more`: the first `limit` names and how many are left out."""
    shown = ", ".join(names[:limit])
    return shown if len(names) <= limit else f"{shown} and {len(names) - limit} more"


def _corner_offset_px(a: View, b: View) -> float:
    """Largest distance (pixels) between two views' detections of the same corners; inf
    when they share fewer than 3/4 of their corners."""
    world_a, pixels_a = a
    world_b, pixels_b = b
    if world_a.shape == world_b.shape and np.array_equal(world_a, world_b):
        offsets = pixels_a - pixels_b
    else:  # ChArUco views see subsets: match the corners by their place on the board
        index = {tuple(np.round(p, 9)): i for i, p in enumerate(world_a)}
        pairs = [
            (index[k], j) for j, p in enumerate(world_b) if (k := tuple(np.round(p, 9))) in index
        ]
        if len(pairs) < 0.75 * max(len(world_a), len(world_b)):
            return math.inf
        rows_a, rows_b = np.array(pairs).T
        offsets = pixels_a[rows_a] - pixels_b[rows_b]
    return float(np.max(np.linalg.norm(offsets, axis=1)))


def same_views(views: Sequence[View]) -> dict[int, tuple[int, float]]:
    """The views that repeat an earlier one (see the module docstring).

    Args:
        views: (world points (N_v, 3), detected pixels (N_v, 2)) per view.

    Returns:
        copy index -> (index of the earlier view it repeats, the largest corner offset
        in pixels), for every copy; the earlier view is never itself a copy.
    """
    copies: dict[int, tuple[int, float]] = {}
    for j in range(len(views)):
        for i in range(j):
            if i in copies:
                continue
            offset = _corner_offset_px(views[i], views[j])
            if offset <= SAME_VIEW_PX:
                copies[j] = (i, offset)
                break
    return copies


def board_normals(rvecs: Sequence[ArrayLike]) -> NDArray[np.float64]:
    """(V, 3) unit normals of the board (its world z axis) in each view's camera frame.

    Args:
        rvecs: (3,) each view's `T_camera_world` rotation vector (`cv2.calibrateCamera`).
    """
    normals = [cv2.Rodrigues(np.asarray(r, dtype=np.float64).reshape(3))[0][:, 2] for r in rvecs]
    return np.array(normals, dtype=np.float64).reshape(-1, 3)


def angle_groups(normals: NDArray[np.float64]) -> list[list[int]]:
    """Views grouped by board angle: each view joins the first group whose first view's
    normal is within `DISTINCT_ANGLE_DEG` of its own, else starts a new group.

    Args:
        normals: (V, 3) unit board normals (`board_normals`).

    Returns:
        The groups, lists of view indices, in order of their first view.
    """
    limit = math.cos(math.radians(DISTINCT_ANGLE_DEG))
    groups: list[list[int]] = []
    for k, normal in enumerate(normals):
        for group in groups:
            if float(normals[group[0]] @ normal) >= limit:
                group.append(k)
                break
        else:
            groups.append([k])
    return groups


def tilts_deg(normals: NDArray[np.float64]) -> NDArray[np.float64]:
    """(V,) each board's tilt from square-on (its normal from the optical axis), degrees."""
    return np.degrees(np.arccos(np.clip(np.abs(normals[:, 2]), 0.0, 1.0)))
