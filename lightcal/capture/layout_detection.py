"""Finding the markers of a `MarkerLayout` in one image, corners in the printed order.

The layout's markers of every dictionary are searched as an ArUco grid's are
(`lightcal.capture.marker_search.find_markers`: several stretches of the photo, the
detections merged and checked, the corners refined on the markers' straight edges), then
their corners are put in the printed order whatever the installed OpenCV reports
(`lightcal.capture.apriltag.printed_corners`: AprilTags are their official images).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from lightcal.capture.apriltag import printed_corners
from lightcal.capture.marker_layout import MarkerLayout
from lightcal.capture.marker_search import MarkerSearch, find_markers
from lightcal.core.camera import Camera

__all__ = ["detect_layout", "search_layout"]


def search_layout(
    image: NDArray[np.uint8],
    image_f: NDArray[np.float64],
    layout: MarkerLayout,
    camera: Camera,
    *,
    source: str = "image",
) -> tuple[NDArray[np.int64], NDArray[np.float64], NDArray[np.float64], MarkerSearch]:
    """The layout's markers found in an image, with what was refused and why.

    Args:
        image: (H, W) the 8-bit image of `marker_detection.detection_images`.
        image_f: (H, W) its float image, for the edge refinement.
        layout: The markers on the wall.
        camera: The camera of the image.
        source: Name of the image for the search's report.

    Returns:
        indices: (n,) positions in `layout.markers` of the markers found, ascending;
        points_world: (4n, 3) their corners on the wall, printed order, metres;
        points_image: (4n, 2) the same corners in the image, pixels (u, v); and the
        `MarkerSearch` (its corners in the detector's order).
    """
    wanted = {d: layout.ids_of(d) for d in layout.dictionaries}
    search = find_markers(image, image_f, camera, wanted, source=source)
    indices: list[NDArray[np.int64]] = []
    corners: list[NDArray[np.float64]] = []
    for dictionary in layout.dictionaries:
        ids = search.ids(dictionary)
        if ids.size:
            indices.append(layout.indices_of(dictionary, ids))
            corners.append(printed_corners(dictionary, search.corners_px(dictionary)))
    if not indices:
        return np.zeros(0, np.int64), np.zeros((0, 3)), np.zeros((0, 2)), search
    found = np.concatenate(indices)
    order = np.argsort(found)
    found = found[order]
    corners_image = np.concatenate(corners)[order]
    points_world = layout.marker_corners_world(found).reshape(-1, 3)
    return found, points_world, corners_image.reshape(-1, 2), search


def detect_layout(
    image: NDArray[np.uint8], image_f: NDArray[np.float64], layout: MarkerLayout, camera: Camera
) -> tuple[NDArray[np.int64], NDArray[np.float64], NDArray[np.float64]]:
    """`search_layout` without the search: indices (n,), world points (4n, 3), image
    points (4n, 2)."""
    indices, points_world, points_image, _ = search_layout(image, image_f, layout, camera)
    return indices, points_world, points_image
