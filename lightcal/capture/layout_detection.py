"""Finding the markers of a `MarkerLayout` in one image, corners in the printed order.

For each dictionary of the layout: `cv2.aruco.ArucoDetector` (as for an ArUco grid,
`lightcal.capture.marker_detection`), the markers of the layout kept (an id seen twice is
dropped: ambiguous), their corners put in the printed order whatever the installed
OpenCV reports (`lightcal.capture.apriltag.printed_corners`: AprilTags are their official
images), then refined on the markers' straight edges as an ArUco grid's are.
"""

from __future__ import annotations

import cv2
import numpy as np
from numpy.typing import NDArray

from lightcal.capture.apriltag import printed_corners
from lightcal.capture.board_layout import aruco_dictionary
from lightcal.capture.marker_detection import (
    _detector_parameters,
    _marker_half_windows,
    _refine_quads_on_edges,
)
from lightcal.capture.marker_layout import MarkerLayout
from lightcal.core.camera import Camera

__all__ = ["detect_layout"]


def detect_layout(
    image: NDArray[np.uint8], image_f: NDArray[np.float64], layout: MarkerLayout, camera: Camera
) -> tuple[NDArray[np.int64], NDArray[np.float64], NDArray[np.float64]]:
    """The layout's markers found in an image.

    Args:
        image: (H, W) the 8-bit image for the detector.
        image_f: (H, W) its float version, for the edge refinement.
        layout: The markers on the wall.
        camera: The camera of the image.

    Returns:
        indices: (n,) positions in `layout.markers` of the markers found, ascending.
        points_world: (4n, 3) their corners on the wall, printed order, metres.
        points_image: (4n, 2) the same corners in the image, pixels (u, v).
    """
    found_indices: list[NDArray[np.int64]] = []
    found_corners: list[NDArray[np.float64]] = []
    for dictionary_name in layout.dictionaries:
        dictionary = aruco_dictionary(dictionary_name)
        detector = cv2.aruco.ArucoDetector(dictionary, _detector_parameters())
        corners, ids, _ = detector.detectMarkers(image)
        if ids is None or len(corners) == 0:
            continue
        ids_flat = np.asarray(ids).reshape(-1).astype(np.int64)
        on_layout = np.isin(ids_flat, layout.ids_of(dictionary_name))
        unique_ids, counts = np.unique(ids_flat[on_layout], return_counts=True)
        keep = on_layout & np.isin(ids_flat, unique_ids[counts == 1])
        if not np.any(keep):
            continue
        corners_px = printed_corners(
            dictionary_name, np.asarray(corners, dtype=np.float64).reshape(-1, 4, 2)[keep]
        )
        refined, _ = _refine_quads_on_edges(
            image_f, corners_px, camera, _marker_half_windows(corners_px, dictionary)
        )
        found_indices.append(layout.indices_of(dictionary_name, ids_flat[keep]))
        found_corners.append(refined)
    if not found_indices:
        return np.zeros(0, np.int64), np.zeros((0, 3)), np.zeros((0, 2))
    indices = np.concatenate(found_indices)
    order = np.argsort(indices)
    indices = indices[order]
    corners_image = np.concatenate(found_corners)[order]
    points_world = layout.marker_corners_world(indices).reshape(-1, 3)
    return indices, points_world, corners_image.reshape(-1, 2)
