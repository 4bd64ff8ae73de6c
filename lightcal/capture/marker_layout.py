"""A board of markers placed one by one on the wall (`MarkerLayout`, board file `type: markers`).

Markers taped where they fit: four AprilTags at the corners of a rectangle, a few ArUco
markers of two dictionaries, each with its own size and rotation. Each `LayoutMarker` is
one printed marker:

- `dictionary`, `id`: an OpenCV dictionary name (`DICT_4X4_50`, ..., `DICT_APRILTAG_16h5`,
  `_25h9`, `_36h10`, `_36h11`) and the marker's id in it. AprilTags are printed as their
  official images, ArUco markers as OpenCV draws them (`lightcal.capture.apriltag`).
- `center_world_m`: where the centre of the marker lies on the wall, world (x, y) metres
  (docs/conventions.md: the wall is z = 0, x right, y up seen from the cameras).
- `size_m`: the side of the marker's black square (what AprilTag calls the tag size:
  without the white border of the official image).
- `rotation_deg`: the marker turned counterclockwise on the wall (seen from the cameras)
  from upright (its printed top edge along world +x).

Corners, as for every board (`lightcal.capture.boards`): top-left, top-right,
bottom-right, bottom-left of the printed marker, in the world frame, z = 0.

A layout is refused (`InputError` naming `markers[i]` and the field) when a marker is
invalid, an id is outside its dictionary, a (dictionary, id) pair appears twice, or two
markers overlap: each marker keeps a white border of one module (the official AprilTag's
white ring; an ArUco marker's quiet zone) clear of the others.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from lightcal.capture.apriltag import dictionary_size, marker_modules
from lightcal.capture.board_layout import (
    BoardRendering,
    aruco_dictionary,
    check_length,
    check_margin,
    check_px_per_m,
)
from lightcal.errors import InputError

__all__ = ["LayoutMarker", "MarkerLayout"]

_SUBPIXELS = 4
"""Samples per pixel side drawing a marker turned by other than a multiple of 90 degrees."""

_MAX_RENDER_PIXELS = 200_000_000
"""Largest image `MarkerLayout.render` draws (a mistyped scale would exhaust memory)."""


def _rotated(local: NDArray[np.float64], rotation_deg: float) -> NDArray[np.float64]:
    """(..., 2) marker-local (a right along the printed top edge, b up) -> world offsets."""
    theta = math.radians(rotation_deg)
    c, s = math.cos(theta), math.sin(theta)
    return np.stack(
        [c * local[..., 0] - s * local[..., 1], s * local[..., 0] + c * local[..., 1]], -1
    )


@dataclass(frozen=True)
class LayoutMarker:
    """One printed marker of a `MarkerLayout` (see the module docstring).

    Attributes:
        dictionary: OpenCV dictionary name, e.g. `"DICT_APRILTAG_36h11"`.
        id: The marker's id in the dictionary.
        center_world_m: World (x, y) of the marker's centre on the wall, metres.
        size_m: Side of the marker's black square, metres.
        rotation_deg: Counterclockwise turn on the wall from upright, degrees.
    """

    dictionary: str
    id: int
    center_world_m: tuple[float, float]
    size_m: float
    rotation_deg: float = 0.0

    def __post_init__(self) -> None:
        aruco_dictionary(self.dictionary)
        n = dictionary_size(self.dictionary)
        marker_id = self.id
        if isinstance(marker_id, bool) or not isinstance(marker_id, int | np.integer):
            raise InputError("id", f"expected an integer marker id, got {marker_id!r}")
        if not 0 <= marker_id < n:
            raise InputError("id", f"{self.dictionary} has ids 0..{n - 1}, got {marker_id}")
        object.__setattr__(self, "id", int(marker_id))
        try:
            center = np.asarray(self.center_world_m, dtype=np.float64)
        except (TypeError, ValueError):
            center = np.zeros(0)
        if center.shape != (2,) or not np.all(np.isfinite(center)):
            raise InputError(
                "center_world_m",
                f"expected two finite coordinates (x, y) in metres, got {self.center_world_m!r}",
            )
        object.__setattr__(self, "center_world_m", (float(center[0]), float(center[1])))
        object.__setattr__(self, "size_m", check_length("size_m", self.size_m))
        rotation = self.rotation_deg
        is_real = not isinstance(rotation, bool) and isinstance(
            rotation, int | float | np.integer | np.floating
        )
        if not (is_real and math.isfinite(rotation)):
            raise InputError(
                "rotation_deg", f"expected a finite angle in degrees, got {rotation!r}"
            )
        object.__setattr__(self, "rotation_deg", float(rotation))

    @property
    def modules(self) -> int:
        """Modules (bits) across the black square, its black border included."""
        return int(aruco_dictionary(self.dictionary).markerSize) + 2

    def square_world(self, *, border_modules: float = 0.0) -> NDArray[np.float64]:
        """(4, 3) the corners of the black square (grown by `border_modules` modules on
        each side), printed order, world frame, z = 0."""
        half = 0.5 * self.size_m * (1.0 + 2.0 * border_modules / self.modules)
        local = np.array([[-half, half], [half, half], [half, -half], [-half, -half]])
        out = np.zeros((4, 3))
        out[:, :2] = np.asarray(self.center_world_m) + _rotated(local, self.rotation_deg)
        return out

    def describe(self) -> str:
        """`DICT_APRILTAG_36h11 id 3`: how messages name the marker."""
        return f"{self.dictionary} id {self.id}"


def _overlap(a: NDArray[np.float64], b: NDArray[np.float64]) -> bool:
    """Whether two convex quads (4, 2) share interior points (separating axis test)."""
    for quad in (a, b):
        edges = np.roll(quad, -1, axis=0) - quad
        normals = np.stack([-edges[:, 1], edges[:, 0]], axis=1)
        for normal in normals:
            pa, pb = a @ normal, b @ normal
            scale = 1e-9 * float(np.abs(np.r_[pa, pb]).max() + 1e-300)
            if pa.max() <= pb.min() + scale or pb.max() <= pa.min() + scale:
                return False
    return True


@dataclass(frozen=True)
class MarkerLayout:
    """Markers placed one by one on the wall (see the module docstring).

    Attributes:
        markers: The markers, in the order of the board file (at least one).
    """

    markers: tuple[LayoutMarker, ...]

    def __post_init__(self) -> None:
        markers = tuple(self.markers)
        if not markers:
            raise InputError("markers", "expected at least one marker")
        for i, marker in enumerate(markers):
            if not isinstance(marker, LayoutMarker):
                raise InputError(
                    f"markers[{i}]", f"expected a LayoutMarker, got {type(marker).__name__}"
                )
        object.__setattr__(self, "markers", markers)
        seen: dict[tuple[str, int], int] = {}
        for i, marker in enumerate(markers):
            key = (marker.dictionary, marker.id)
            if key in seen:
                raise InputError(
                    f"markers[{i}]",
                    f"{marker.describe()} is also markers[{seen[key]}]: expected each "
                    "(dictionary, id) once",
                )
            seen[key] = i
        squares = np.stack([m.square_world(border_modules=1.0)[:, :2] for m in markers])
        lo, hi = squares.min(axis=1), squares.max(axis=1)  # (n, 2) bounding boxes
        boxes_meet = np.all(
            (lo[:, None, :] < hi[None, :, :]) & (lo[None, :, :] < hi[:, None, :]), -1
        )
        for i in range(len(markers)):
            for j in np.flatnonzero(boxes_meet[i, :i]).tolist():
                if _overlap(squares[i], squares[j]):
                    raise InputError(
                        f"markers[{i}]",
                        f"{markers[i].describe()} overlaps markers[{j}] "
                        f"({markers[j].describe()}): expected each marker and its white "
                        "border of one module clear of the others",
                    )

    @classmethod
    def from_markers(cls, markers: Sequence[LayoutMarker]) -> MarkerLayout:
        """A layout of these markers."""
        return cls(tuple(markers))

    @property
    def n_markers(self) -> int:
        """Number of markers."""
        return len(self.markers)

    @property
    def dictionaries(self) -> tuple[str, ...]:
        """The dictionaries of the markers, sorted, each once."""
        return tuple(sorted({m.dictionary for m in self.markers}))

    def ids_of(self, dictionary: str) -> NDArray[np.int64]:
        """(n,) the ids of the markers of one dictionary, in layout order."""
        return np.array([m.id for m in self.markers if m.dictionary == dictionary], np.int64)

    def indices_of(self, dictionary: str, ids: ArrayLike) -> NDArray[np.int64]:
        """(n,) the positions in `markers` of markers `ids` of `dictionary`.

        Raises:
            InputError: An id that is not on the layout with that dictionary.
        """
        where = {m.id: i for i, m in enumerate(self.markers) if m.dictionary == dictionary}
        out = []
        for marker_id in np.asarray(ids).reshape(-1).tolist():
            if marker_id not in where:
                raise InputError(
                    "ids",
                    f"{dictionary} id {marker_id} is not on the board: expected one of "
                    f"{sorted(where)}",
                )
            out.append(where[marker_id])
        return np.array(out, dtype=np.int64)

    def marker_corners_world(self, indices: ArrayLike) -> NDArray[np.float64]:
        """World corners of markers by position in `markers`.

        Args:
            indices: (n,) positions in `markers`.

        Returns:
            corners_world: (n, 4, 3) metres, z = 0, printed order (top-left, top-right,
            bottom-right, bottom-left).
        """
        index = np.asarray(indices, dtype=np.int64).reshape(-1)
        if index.size == 0:
            return np.zeros((0, 4, 3))
        return np.stack([self.markers[int(i)].square_world() for i in index])

    def corners_world(self, ids: ArrayLike, dictionary: str | None = None) -> NDArray[np.float64]:
        """World corners of markers by id.

        Args:
            ids: (n,) marker ids of `dictionary`.
            dictionary: Their dictionary; None for the only one of a single-dictionary layout.

        Returns:
            corners_world: (n, 4, 3) metres, z = 0, printed order.

        Raises:
            InputError: No dictionary given for a layout of several, or an id not on it.
        """
        if dictionary is None:
            if len(self.dictionaries) != 1:
                raise InputError(
                    "dictionary",
                    f"the board has markers of {', '.join(self.dictionaries)}: say which",
                )
            dictionary = self.dictionaries[0]
        return self.marker_corners_world(self.indices_of(dictionary, ids))

    def outline_world(self, indices: ArrayLike | None = None) -> NDArray[np.float64]:
        """Polygons covered by printed markers (their black squares), to mask them.

        Args:
            indices: (n,) positions in `markers`, or None for every marker.

        Returns:
            polygons_world: (n, 4, 3) metres, z = 0.
        """
        every = np.arange(self.n_markers) if indices is None else indices
        return self.marker_corners_world(every)

    def render(self, px_per_m: float, *, margin_m: float | None = None) -> BoardRendering:
        """Draw the layout at `px_per_m` pixels per metre (white paper, black print).

        A marker turned by a multiple of 90 degrees is drawn with each pixel the colour
        of the module under its centre (exact, 0 or 255, when its edges fall on whole
        pixels); other markers with each pixel the mean of `_SUBPIXELS` x `_SUBPIXELS`
        samples (grey along the edges, as a photo of the print would be).

        Args:
            px_per_m: Scale.
            margin_m: White border around the markers' white borders, metres; None: the
                largest marker's size.

        Returns:
            The image and its placement on the wall; its top-left corner lies on whole
            pixels of the world (a multiple of 1 / px_per_m).

        Raises:
            InputError: A non-positive scale, a negative margin, or an image of more than
                `_MAX_RENDER_PIXELS` pixels.
        """
        scale = check_px_per_m(px_per_m)
        size = max(m.size_m for m in self.markers)
        margin = size if margin_m is None else check_margin(margin_m)
        extent = np.concatenate([m.square_world(border_modules=1.0) for m in self.markers])
        x0 = math.floor((extent[:, 0].min() - margin) * scale) / scale
        y0 = math.ceil((extent[:, 1].max() + margin) * scale) / scale
        width = math.ceil((extent[:, 0].max() + margin - x0) * scale)
        height = math.ceil((y0 - extent[:, 1].min() + margin) * scale)
        if width * height > _MAX_RENDER_PIXELS:
            raise InputError(
                "px_per_m",
                f"expected an image of at most {_MAX_RENDER_PIXELS} pixels, got "
                f"{width} x {height} at {scale:g} px/m",
            )
        image = np.full((height, width), 255, dtype=np.uint8)
        for marker in self.markers:
            self._draw(image, marker, scale, x0, y0)
        return BoardRendering(image=image, px_per_m=scale, top_left_world_m=np.array([x0, y0]))

    @staticmethod
    def _draw(
        image: NDArray[np.uint8], marker: LayoutMarker, scale: float, x0: float, y0: float
    ) -> None:
        """Paint one marker's black square into `image` (sub-pixels sample the modules)."""
        square = marker.square_world()
        u = (square[:, 0] - x0) * scale - 0.5
        v = (y0 - square[:, 1]) * scale - 0.5
        height, width = image.shape
        u0, u1 = max(0, math.floor(u.min())), min(width - 1, math.ceil(u.max()))
        v0, v1 = max(0, math.floor(v.min())), min(height - 1, math.ceil(v.max()))
        upright = marker.rotation_deg % 90.0 == 0.0
        k = 1 if upright else _SUBPIXELS
        rows, cols = np.mgrid[v0 : v1 + 1, u0 : u1 + 1]
        offsets = (np.arange(k) + 0.5) / k
        theta = math.radians(marker.rotation_deg)
        modules = marker_modules(marker.dictionary, marker.id).astype(np.float64)
        n = modules.shape[0]
        pitch = marker.size_m / n
        total = np.zeros(rows.shape)
        touched = np.zeros(rows.shape, dtype=bool)
        for dv in offsets:
            for du in offsets:
                dx = x0 + (cols + du) / scale - marker.center_world_m[0]
                dy = y0 - (rows + dv) / scale - marker.center_world_m[1]
                a = math.cos(theta) * dx + math.sin(theta) * dy  # along the printed top edge
                b = -math.sin(theta) * dx + math.cos(theta) * dy  # up the printed marker
                col = np.floor((a + 0.5 * marker.size_m) / pitch).astype(np.int64)
                row = np.floor((0.5 * marker.size_m - b) / pitch).astype(np.int64)
                inside = (col >= 0) & (col < n) & (row >= 0) & (row < n)
                value = np.full(rows.shape, 255.0)
                value[inside] = modules[row[inside], col[inside]]
                total += value
                touched |= inside
        patch = image[v0 : v1 + 1, u0 : u1 + 1]
        patch[touched] = np.rint(total[touched] / (k * k)).astype(np.uint8)
