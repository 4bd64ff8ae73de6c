"""Markers as printed, and the order of their detected corners, whatever OpenCV's version.

lightcal prints an ArUco marker as OpenCV draws it (`cv2.aruco.Dictionary.generateImageMarker`)
and an AprilTag (`DICT_APRILTAG_16h5`, `25h9`, `36h10`, `36h11`) as its official image:
the bitmap AprilRobotics' `apriltag_to_image` draws from the family's published code and
bit layout (`lightcal.capture.apriltag_families`), the images of AprilRobotics/apriltag-imgs.
A marker's corners are named on the printed marker: top-left, top-right, bottom-right,
bottom-left, clockwise on the page (`board_layout.square_xy`).

OpenCV's `DICT_APRILTAG_*` dictionaries have the same codes as the families, but some
versions read an official tag with its corners rotated (OpenCV 5.0 reports the official
bottom-right corner first: 180 degrees), and OpenCV has changed that order before.
`detected_corner_order` therefore finds the order at run time, once per dictionary: it
draws a few markers as printed, detects them with the installed OpenCV and sees which
detected corner lands on which printed corner. `printed_corners` applies it to what a
detector returns.
"""

from __future__ import annotations

import functools
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

from lightcal.capture.apriltag_families import FAMILIES, AprilTagFamily
from lightcal.capture.board_layout import aruco_dictionary
from lightcal.errors import InputError

__all__ = [
    "APRILTAG_DICTIONARIES",
    "detected_corner_order",
    "dictionary_size",
    "drawing_turns",
    "family_of",
    "marker_modules",
    "printed_corners",
]

APRILTAG_DICTIONARIES = {
    "DICT_APRILTAG_16h5": "tag16h5",
    "DICT_APRILTAG_25h9": "tag25h9",
    "DICT_APRILTAG_36h10": "tag36h10",
    "DICT_APRILTAG_36h11": "tag36h11",
}
"""OpenCV's AprilTag dictionaries and the AprilTag family each one holds."""

_PROBE_IDS = (0, 1, 2)
"""Markers drawn and detected to find a dictionary's corner order (they must agree)."""

_PROBE_PX_PER_MODULE = 12
_PROBE_MARGIN_MODULES = 3
_PROBE_TOLERANCE_PX = 2.0
"""Largest distance of a detected corner from the printed corner it is matched with."""


def family_of(dictionary: str) -> AprilTagFamily | None:
    """The AprilTag family of an OpenCV dictionary name, None for ArUco dictionaries."""
    name = APRILTAG_DICTIONARIES.get(dictionary)
    return None if name is None else FAMILIES[name]


def dictionary_size(dictionary: str) -> int:
    """Number of markers (ids 0 .. n - 1) of a dictionary.

    Raises:
        InputError: An unknown dictionary name.
    """
    return int(aruco_dictionary(dictionary).bytesList.shape[0])


def _official_modules(family: AprilTagFamily, marker_id: int) -> NDArray[np.uint8]:
    """The black square of an official tag image, one pixel per module (255 white)."""
    code = family.codes[marker_id]
    width = family.width_at_border
    modules = np.zeros((width, width), dtype=np.uint8)
    for k in range(family.n_bits):
        if code >> (family.n_bits - 1 - k) & 1:
            modules[family.bit_y[k], family.bit_x[k]] = 255
    return modules


def marker_modules(dictionary: str, marker_id: int) -> NDArray[np.uint8]:
    """A marker's black square as lightcal prints it, one pixel per module.

    Args:
        dictionary: An OpenCV dictionary name (`"DICT_4X4_50"`, `"DICT_APRILTAG_36h11"`).
        marker_id: The marker's id in it.

    Returns:
        modules: (w, w) uint8, 0 black, 255 white, row 0 at the top of the printed marker;
        w = the dictionary's marker size + 2 (the black border). AprilTags are the
        official image without its white border; ArUco markers are OpenCV's drawing.

    Raises:
        InputError: An unknown dictionary, or an id outside it.
    """
    n = dictionary_size(dictionary)
    if isinstance(marker_id, bool) or not isinstance(marker_id, int | np.integer):
        raise InputError("id", f"expected an integer marker id, got {marker_id!r}")
    if not 0 <= marker_id < n:
        raise InputError("id", f"{dictionary} has ids 0..{n - 1}, got {marker_id}")
    family = family_of(dictionary)
    if family is not None:
        return _official_modules(family, int(marker_id))
    cv_dictionary = aruco_dictionary(dictionary)
    width = int(cv_dictionary.markerSize) + 2
    return np.asarray(cv_dictionary.generateImageMarker(int(marker_id), width), dtype=np.uint8)


@functools.cache
def drawing_turns(dictionary: str) -> int:
    """Quarter turns (`np.rot90`) from OpenCV's drawing of a marker to the printed one.

    Found once per dictionary (cached) on markers `_PROBE_IDS` drawn one pixel a module:
    0 for ArUco markers; for AprilTags whatever turns OpenCV's drawing into the official
    image (2 in OpenCV 5.0). So `np.rot90(generateImageMarker(id, side_px), turns)` draws
    the printed marker at any size, resampled as OpenCV resamples.

    Raises:
        InputError: An unknown dictionary, or no single turn makes OpenCV's drawings the
            printed markers.
    """
    cv_dictionary = aruco_dictionary(dictionary)
    width = int(cv_dictionary.markerSize) + 2
    found = set()
    for marker_id in _PROBE_IDS:
        drawn = cv_dictionary.generateImageMarker(marker_id, width)
        printed = marker_modules(dictionary, marker_id)
        found.add(tuple(k for k in range(4) if np.array_equal(np.rot90(drawn, k), printed)))
    if len(found) != 1 or len(turns := found.pop()) != 1:
        raise InputError(
            dictionary,
            f"OpenCV {cv2.__version__} draws markers {_PROBE_IDS} other than their official "
            "images turned: lightcal cannot draw them",
        )
    return turns[0]


def _probe_image(modules: NDArray[np.uint8]) -> tuple[NDArray[np.uint8], NDArray[np.float64]]:
    """A printed marker with a white margin, and its corners (4, 2) in pixels, printed order."""
    scale, margin = _PROBE_PX_PER_MODULE, _PROBE_MARGIN_MODULES
    big = np.kron(modules, np.ones((scale, scale), dtype=np.uint8))
    side = big.shape[0]
    image = np.full((side + 2 * margin * scale,) * 2, 255, dtype=np.uint8)
    start = margin * scale
    image[start : start + side, start : start + side] = big
    lo, hi = start - 0.5, start + side - 0.5  # pixel centres at integers
    return image, np.array([[lo, lo], [hi, lo], [hi, hi], [lo, hi]])


def _order_of(dictionary: str, detector: Any, marker_id: int) -> tuple[int, ...]:
    image, printed = _probe_image(marker_modules(dictionary, marker_id))
    corners, ids, _ = detector.detectMarkers(image)
    found = [] if ids is None else np.asarray(ids).reshape(-1).tolist()
    if found != [marker_id]:
        raise InputError(
            dictionary,
            f"OpenCV {cv2.__version__} does not find marker {marker_id} in its printed image "
            f"(found ids {found}): lightcal cannot tell the order of its corners",
        )
    detected = np.asarray(corners[0], dtype=np.float64).reshape(4, 2)
    distances = np.linalg.norm(printed[:, None, :] - detected[None, :, :], axis=-1)
    order = tuple(int(k) for k in distances.argmin(axis=1))
    cyclic = {tuple((start + j) % 4 for j in range(4)) for start in range(4)}
    if order not in cyclic or distances.min(axis=1).max() > _PROBE_TOLERANCE_PX:
        raise InputError(
            dictionary,
            f"OpenCV {cv2.__version__} finds marker {marker_id}'s corners away from the "
            "printed ones: lightcal cannot tell the order of its corners",
        )
    return order


@functools.cache
def detected_corner_order(dictionary: str) -> tuple[int, int, int, int]:
    """Which corner the installed OpenCV reports for each printed corner of a marker.

    Found once per dictionary (cached): markers `_PROBE_IDS` are drawn as printed
    (`marker_modules`), detected with `cv2.aruco.ArucoDetector`, and each printed corner
    matched with the nearest detected one.

    Args:
        dictionary: An OpenCV dictionary name.

    Returns:
        order: (4,) with `printed = detected[order]` for the corners of one marker
        (top-left, top-right, bottom-right, bottom-left as printed). (0, 1, 2, 3) for
        ArUco markers; for AprilTags (2, 3, 0, 1) where OpenCV reads them rotated by 180
        degrees (OpenCV 5.0).

    Raises:
        InputError: An unknown dictionary, or the installed OpenCV does not detect the
            printed markers (or not at their corners, or not all in one order).
    """
    detector = cv2.aruco.ArucoDetector(aruco_dictionary(dictionary), cv2.aruco.DetectorParameters())
    orders = {_order_of(dictionary, detector, marker_id) for marker_id in _PROBE_IDS}
    if len(orders) != 1:
        raise InputError(
            dictionary,
            f"OpenCV {cv2.__version__} reports the corners of markers {_PROBE_IDS} in "
            "different orders: lightcal cannot tell the order of its corners",
        )
    a, b, c, d = orders.pop()
    return a, b, c, d


def printed_corners(dictionary: str, corners_px: NDArray[np.float64]) -> NDArray[np.float64]:
    """Detected marker corners put in the printed order.

    Args:
        dictionary: The dictionary the markers were detected with.
        corners_px: (n, 4, 2) corners as `cv2.aruco.ArucoDetector.detectMarkers` gives them.

    Returns:
        corners_px: (n, 4, 2) top-left, top-right, bottom-right, bottom-left of each printed
        marker (still clockwise in the image).
    """
    order = list(detected_corner_order(dictionary))
    return np.asarray(corners_px, dtype=np.float64)[:, order, :]
