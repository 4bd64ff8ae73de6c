"""Markers found on several stretches of one photo, merged, checked and refined (issue 25).

A linear stretch between the 0.5th and 99.5th percentiles (`marker_detection`) suits an
evenly lit wall; a bright beam puts the 99.5th percentile in the beam, and the markers
outside it end up a few grey levels from black, below the detector's threshold contrast.
So `find_markers` detects on several stretches of the same photo (`STRETCHES`):

- `percentile`: the 8-bit image the detectors always had (8-bit photos as they are);
- `gamma`: 255 x^(1/2.2), x the image from its 0.5th percentile (0) to its maximum (1):
  markers in the dark beside a beam;
- `log`: 255 log(1 + x / 0.001) / log(1001): the darkest markers;
- `clahe`: the `log` image with its local contrast equalised (CLAHE, 8 x 8 tiles,
  clip 3): markers beside a steep gradient.

On each, OpenCV's ArUco detector (AprilTag dictionaries too) with sub-pixel corners; only
the wanted ids are kept. `percentile` and `gamma` are always searched, `log` and `clahe`
only while a wanted marker is still missing (`MIN_STRETCHES`). The detections are merged
by (dictionary, id):

- a marker found twice in one stretch, or by two stretches, at places further apart (the
  largest distance between corresponding corners) than the larger of `CONSISTENT_PX` and
  half a module of the marker (`CONSISTENT_MODULES`) is refused for that photo, with the
  reason (two prints of one marker, or a false detection: which one is right cannot be
  told from the photo);
- otherwise its corners are those of the first stretch that found it, refined once on
  the straight edges of the linear image (`lightcal.capture.edge_refinement`): an edge
  located on a stretched image would be pulled towards its dark side by the stretch's
  curve;
- a marker whose corners are not finite (from the detector or the refinement) is refused.

What is found and what is refused, and why, is a `MarkerSearch`: its `report` is one line
a caller prints.

Cost: the stretches are lookup tables on the image quantised to 16 bits, made only when
searched (`Stretches`); the edge refinement runs once per marker, not per stretch. Best of
3-5 runs for the 48-marker grid of `tests/test_marker_pose.py` (2 shared cores), before
(percentile only) and after:

| photo | evenly lit | under a beam |
|---|---|---|
| 1200 x 800 | 0.04 s -> 0.06 s (48 markers both) | 0.01 s (3 markers) -> 0.04 s (48) |
| 6000 x 4000 | 0.37 s -> 0.44 s (48 both) | 0.20 s (2 markers) -> 0.38 s (48) |
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping
from dataclasses import dataclass
from typing import Any

import cv2
import numpy as np
from numpy.typing import ArrayLike, NDArray

from lightcal.capture.board_layout import aruco_dictionary
from lightcal.capture.edge_refinement import marker_half_windows, refine_quads_on_edges
from lightcal.core.camera import Camera
from lightcal.errors import InputError

__all__ = [
    "CONSISTENT_MODULES",
    "CONSISTENT_PX",
    "MIN_STRETCHES",
    "STRETCHES",
    "FoundMarker",
    "MarkerRefusal",
    "MarkerSearch",
    "Stretches",
    "detection_stretches",
    "detector_parameters",
    "find_markers",
    "search_stretched",
]

STRETCHES = ("percentile", "gamma", "log", "clahe")
"""The stretches a photo is searched on, in this order (module docstring)."""

CONSISTENT_PX = 3.0
CONSISTENT_MODULES = 0.5
"""Two detections of one marker (two stretches, or twice in one stretch) are the same
marker when their corresponding corners are within the larger of CONSISTENT_PX pixels
and CONSISTENT_MODULES modules (bits) of the marker: on a blurred 24 MP photo the
detector's corners of one marker differ by 3 - 4 px between stretches."""

MIN_STRETCHES = 2
"""Stretches always searched (`percentile` and `gamma`); the others only while some
wanted marker is still missing."""

GAMMA = 2.2
"""The `gamma` stretch's exponent is 1 / GAMMA."""

LOG_KNEE = 1e-3
"""The `log` stretch is log(1 + x / LOG_KNEE): linear below LOG_KNEE of the maximum."""

CLAHE_CLIP = 3.0
CLAHE_TILES = (8, 8)
"""The `clahe` stretch's contrast limit and tile grid (columns, rows)."""

_LEVELS = 65536
"""The stretches are lookup tables on the image quantised to this many levels."""


def detector_parameters() -> Any:
    """OpenCV's ArUco detector parameters lightcal uses: sub-pixel corners, tight."""
    params = cv2.aruco.DetectorParameters()
    params.cornerRefinementMethod = cv2.aruco.CORNER_REFINE_SUBPIX
    params.cornerRefinementMaxIterations = 100
    params.cornerRefinementMinAccuracy = 0.001
    return params


@dataclass(frozen=True)
class MarkerRefusal:
    """A marker seen in a photo but not used, and why.

    Attributes:
        dictionary: Its OpenCV dictionary name, e.g. "DICT_APRILTAG_36h11".
        marker_id: Its id.
        reason: What was wrong, a sentence fragment.
    """

    dictionary: str
    marker_id: int
    reason: str

    def __str__(self) -> str:
        return f"marker {self.marker_id} ({self.dictionary}) refused: {self.reason}"


@dataclass(frozen=True, eq=False)
class FoundMarker:
    """A marker found in a photo.

    Attributes:
        dictionary: Its OpenCV dictionary name.
        marker_id: Its id.
        corners_px: (4, 2) its corners (u, v), pixels, in the detector's order (clockwise
            in the image), refined on the edges where `refined`.
        refined: (4,) True where the edge refinement placed the corner (else it is the
            first stretch's detection).
        stretches: The stretches it was found on (`STRETCHES` order).
    """

    dictionary: str
    marker_id: int
    corners_px: NDArray[np.float64]
    refined: NDArray[np.bool_]
    stretches: tuple[str, ...]


@dataclass(frozen=True, eq=False)
class MarkerSearch:
    """What `find_markers` found in one photo.

    Attributes:
        source: Name of the photo.
        found: The markers found, sorted by (dictionary, id).
        refused: The markers seen but refused, with why, sorted by (dictionary, id).
    """

    source: str
    found: tuple[FoundMarker, ...]
    refused: tuple[MarkerRefusal, ...]

    def ids(self, dictionary: str) -> NDArray[np.int64]:
        """(n,) ids of the markers of `dictionary` found, ascending."""
        return np.array(
            [m.marker_id for m in self.found if m.dictionary == dictionary], dtype=np.int64
        )

    def corners_px(self, dictionary: str) -> NDArray[np.float64]:
        """(n, 4, 2) their corners, in the order of `ids`."""
        quads = [m.corners_px for m in self.found if m.dictionary == dictionary]
        return np.array(quads, dtype=np.float64).reshape(-1, 4, 2)

    def report(self) -> str:
        """One line: `photo.png: 4 markers found (...); marker 7 (...) refused: ...`."""
        by_dictionary: dict[str, list[str]] = {}
        for m in self.found:
            by_dictionary.setdefault(m.dictionary, []).append(str(m.marker_id))
        names = "; ".join(f"{d} {', '.join(ids)}" for d, ids in by_dictionary.items())
        count = len(self.found)
        line = f"{self.source}: {count} marker{'' if count == 1 else 's'} found"
        line += f" ({names})" if names else ""
        return "; ".join([line, *(str(r) for r in self.refused)])


class Stretches(Mapping[str, NDArray[np.uint8]]):
    """The 8-bit images of `STRETCHES` for one photo, each made when first asked for.

    Args:
        image_u8: (H, W) the `percentile` image (what `marker_detection.detection_images`
            gives the detectors).
        image_f: (H, W) the photo, linear, its 0.5th percentile at 0 (the unclipped float
            of `detection_images`; an 8-bit photo as float).
    """

    def __init__(self, image_u8: NDArray[np.uint8], image_f: NDArray[np.float64]) -> None:
        self._images: dict[str, NDArray[np.uint8]] = {"percentile": image_u8}
        self._image_f = image_f
        self._levels: NDArray[np.uint16] | None = None

    def __iter__(self) -> Iterator[str]:
        return iter(STRETCHES)

    def __len__(self) -> int:
        return len(STRETCHES)

    def __getitem__(self, name: str) -> NDArray[np.uint8]:
        if name not in self._images:
            if name not in STRETCHES:
                raise KeyError(name)
            self._images[name] = self._make(name)
        return self._images[name]

    def _quantised(self) -> NDArray[np.uint16] | None:
        """(H, W) the photo from 0 to its maximum in `_LEVELS` steps, None when dark."""
        if self._levels is None:
            image_f = self._image_f
            if not np.all(np.isfinite(image_f)):
                finite = np.isfinite(image_f)
                top = float(image_f[finite].max(initial=0.0))
                image_f = np.nan_to_num(image_f, nan=0.0, posinf=top, neginf=0.0)
            top = float(image_f.max(initial=0.0))
            if not top > 0.0:
                return None
            scaled = np.multiply(image_f, (_LEVELS - 1) / top, dtype=np.float32)
            np.clip(scaled, 0.0, _LEVELS - 1, out=scaled)
            self._levels = scaled.astype(np.uint16)
        return self._levels

    def _make(self, name: str) -> NDArray[np.uint8]:
        levels = self._quantised()
        if levels is None:  # nothing above the 0.5th percentile: black
            return np.zeros(self._image_f.shape, dtype=np.uint8)
        if name == "clahe":
            clahe = cv2.createCLAHE(clipLimit=CLAHE_CLIP, tileGridSize=CLAHE_TILES)
            return np.asarray(clahe.apply(self["log"]), dtype=np.uint8)
        x = np.arange(_LEVELS, dtype=np.float64) / (_LEVELS - 1)
        if name == "gamma":
            lut = np.rint(255.0 * x ** (1.0 / GAMMA))
        else:
            lut = np.rint(255.0 * np.log1p(x / LOG_KNEE) / np.log1p(1.0 / LOG_KNEE))
        return lut.astype(np.uint8)[levels]


def detection_stretches(image_u8: NDArray[np.uint8], image_f: NDArray[np.float64]) -> Stretches:
    """The 8-bit images of `STRETCHES` for one photo (`Stretches`: made when first used).

    Args:
        image_u8: (H, W) the `percentile` image.
        image_f: (H, W) the photo, linear, its 0.5th percentile at 0.

    Returns:
        name -> (H, W) uint8, for every name of `STRETCHES`.
    """
    return Stretches(image_u8, image_f)


def _corner_distance(a: NDArray[np.float64], b: NDArray[np.float64]) -> float:
    """The largest distance between corresponding corners of two (4, 2) quads, pixels."""
    return float(np.max(np.linalg.norm(a - b, axis=-1)))


def _fmt(quad: NDArray[np.float64]) -> str:
    u, v = quad.mean(axis=0)
    return f"({u:.1f}, {v:.1f})"


def _merge(
    dictionary: str, marker_id: int, seen: list[tuple[str, NDArray[np.float64]]], modules: int
) -> NDArray[np.float64] | MarkerRefusal:
    """The corners (4, 2) of one marker's detections [(stretch, (4, 2))] in `STRETCHES`
    order, or why not: the first stretch's, when every detection is within the tolerance
    (`CONSISTENT_PX`, or half a module of a marker of `modules` modules a side) of
    every other."""
    for stretch, quad in seen:
        if not np.all(np.isfinite(quad)):
            return MarkerRefusal(
                dictionary, marker_id, f"the {stretch} stretch's detection has non-finite corners"
            )
    first = seen[0][1]
    side_px = float(np.mean(np.linalg.norm(np.roll(first, -1, axis=0) - first, axis=-1)))
    tolerance = max(CONSISTENT_PX, CONSISTENT_MODULES * side_px / modules)
    worst, pair = 0.0, (0, 0)
    for i in range(len(seen)):
        for j in range(i + 1, len(seen)):
            d = _corner_distance(seen[i][1], seen[j][1])
            if d > worst:
                worst, pair = d, (i, j)
    if worst > tolerance:
        (sa, qa), (sb, qb) = seen[pair[0]], seen[pair[1]]
        where = f"twice by the {sa} stretch" if sa == sb else f"by the {sa} and {sb} stretches"
        return MarkerRefusal(
            dictionary,
            marker_id,
            f"found {where} at places {worst:.1f} px apart (centres {_fmt(qa)} and "
            f"{_fmt(qb)}); expected the same corners within {tolerance:.1f} px",
        )
    return first


def _detect(
    images: Mapping[str, NDArray[np.uint8]], dictionary: str, wanted: NDArray[np.int64]
) -> dict[int, list[tuple[str, NDArray[np.float64]]]]:
    """id -> [(stretch, corners (4, 2))] of the wanted markers, stretch by stretch in
    `STRETCHES` order; after the first `MIN_STRETCHES`, only while some are missing."""
    detector = cv2.aruco.ArucoDetector(aruco_dictionary(dictionary), detector_parameters())
    seen: dict[int, list[tuple[str, NDArray[np.float64]]]] = {}
    wanted_ids = set(wanted.tolist())
    for k, stretch in enumerate(STRETCHES):
        if k >= MIN_STRETCHES and wanted_ids <= seen.keys():
            break
        corners, ids, _ = detector.detectMarkers(images[stretch])
        if ids is None or len(corners) == 0:
            continue
        ids_flat = np.asarray(ids).reshape(-1).astype(np.int64)
        quads = np.asarray(corners, dtype=np.float64).reshape(-1, 4, 2)
        for marker_id, quad in zip(ids_flat.tolist(), quads, strict=True):
            if marker_id in wanted_ids:
                seen.setdefault(int(marker_id), []).append((stretch, quad))
    return seen


def find_markers(
    image_u8: NDArray[np.uint8],
    image_f: NDArray[np.float64],
    camera: Camera,
    wanted: Mapping[str, ArrayLike],
    *,
    source: str = "image",
) -> MarkerSearch:
    """The wanted markers in one photo, from several stretches (module docstring).

    Args:
        image_u8: (H, W) the photo stretched to 8 bits between its percentiles
            (`marker_detection.detection_images`).
        image_f: (H, W) the photo, linear, with that stretch's offset and scale but not
            clipped (the float of `detection_images`); the edges are refined on it.
        camera: The camera of the photo (its size must be the photo's).
        wanted: Dictionary name -> the ids to look for; other markers are ignored.
        source: Name of the photo for the result.

    Returns:
        The markers found (corners in the detector's order) and those refused, with why.

    Raises:
        InputError: The two images differ in shape from each other or from the camera.
    """
    height, width = image_f.shape
    if image_u8.shape != image_f.shape or (width, height) != (camera.width, camera.height):
        raise InputError(
            source,
            f"expected images of the camera's size {camera.width}x{camera.height} px, got "
            f"{image_u8.shape[1]}x{image_u8.shape[0]} and {width}x{height} px",
        )
    return search_stretched(
        detection_stretches(image_u8, image_f), image_f, camera, wanted, source=source
    )


def search_stretched(
    images: Mapping[str, NDArray[np.uint8]],
    image_f: NDArray[np.float64],
    camera: Camera,
    wanted: Mapping[str, ArrayLike],
    *,
    source: str = "image",
) -> MarkerSearch:
    """`find_markers` on stretches already made (`detection_stretches`; sizes unchecked)."""
    found: list[FoundMarker] = []
    refused: list[MarkerRefusal] = []
    for dictionary in sorted(wanted):
        ids = np.unique(np.asarray(wanted[dictionary], dtype=np.int64).reshape(-1))
        seen = _detect(images, dictionary, ids)
        keys = sorted(seen)
        modules = int(aruco_dictionary(dictionary).markerSize) + 2  # with the black border
        merged = [_merge(dictionary, k, seen[k], modules) for k in keys]
        good = [
            (k, quad)
            for k, quad in zip(keys, merged, strict=True)
            if not isinstance(quad, MarkerRefusal)
        ]
        refused.extend(m for m in merged if isinstance(m, MarkerRefusal))
        if not good:
            continue
        starts = np.array([quad for _, quad in good], dtype=np.float64)
        refined, ok = refine_quads_on_edges(
            image_f, starts, camera, marker_half_windows(starts, aruco_dictionary(dictionary))
        )
        for (marker_id, _), quad, quad_ok in zip(good, refined, ok, strict=True):
            if not np.all(np.isfinite(quad)):
                reason = "the edge refinement gave non-finite corners"
                refused.append(MarkerRefusal(dictionary, marker_id, reason))
                continue
            stretches = tuple(s for s in STRETCHES if any(s == t for t, _ in seen[marker_id]))
            found.append(FoundMarker(dictionary, marker_id, quad, quad_ok, stretches))
    refused.sort(key=lambda r: (r.dictionary, r.marker_id))
    return MarkerSearch(source, tuple(found), tuple(refused))
