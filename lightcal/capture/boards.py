"""Calibration boards: their geometry on the wall and their printable images.

Four boards are described by frozen dataclasses:

| class | used for | printed pattern |
|---|---|---|
| `ArucoGridBoard` | camera poses on the wall (`marker_pose`) | a grid of ArUco markers |
| `CharucoBoard` | camera poses, intrinsics | a chessboard with ArUco markers in its white squares |
| `Chessboard` | intrinsics (`intrinsics`) | a plain chessboard |
| `MarkerLayout` | camera poses on the wall | ArUco markers or AprilTags placed one by one |

World frame and board frame (the one convention of this module):

- OpenCV's board frame B has its origin at the board's top-left corner as printed, x to
  the right, y DOWN the printed page and z = x cross y pointing INTO the wall. A camera that
  sees the board therefore sits at negative board z.
- Our world frame W (docs/conventions.md, "Frames") has the wall as the plane z = 0 and
  the cameras at z > 0. W is B rotated by diag(1, -1, -1) and shifted by the board origin:
  x_w = x_b + origin_x, y_w = origin_y - y_b, z_w = -z_b = 0. On a board hung upright,
  world x points right, world y up and world z out of the wall towards the camera.
- `origin_world_m` = (origin_x, origin_y) is where the board's top-left corner lies on the
  wall: the outer corner of the top-left marker (ArUco grid) or of the top-left square
  (ChArUco). The board extends to +x (right) and -y (down) from there. A `Chessboard`,
  used only for intrinsics, has its origin at its top-left INNER corner.

All lengths are in metres. Every 3-D point a board returns is in the world frame, z = 0,
float64, computed from the layout (not from OpenCV's float32 object points), so that
`cv2.solvePnP(points_world, ...)` returns `T_camera_world` directly.

`render(px_per_m)` draws a board (white = 255, black = 0) at an exact scale, for printing
and for synthetic images. Pixels follow docs/conventions.md: pixel (u, v) = (column, row) covers
[u - 1/2, u + 1/2] x [v - 1/2, v + 1/2]; `BoardRendering.A_pixel_world` maps world (x, y)
to (u, v). Markers come from `cv2.aruco.Dictionary.generateImageMarker` (AprilTags
turned to their official images), placed at whole pixels; for ArUco dictionaries the
layout equals `cv2.aruco.Board.generateImage` wherever the latter is exact.

`Chessboard` lives in `lightcal.capture.chessboard`, `MarkerLayout` (whose AprilTags are
printed and read as their official images: `lightcal.capture.apriltag`) in
`lightcal.capture.marker_layout`, and what the boards share (checks, ArUco dictionaries,
`BoardRendering`) in `lightcal.capture.board_layout`; this module exports them.

AprilTags: an `ArucoGridBoard` and a `MarkerLayout` draw them as their official images,
and `marker_pose` puts their detected corners in that order, whatever the installed
OpenCV's own drawing and order (`lightcal.capture.apriltag`). A `CharucoBoard` draws its
markers as OpenCV does (OpenCV's ChArUco detector matches them so).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import cv2
import numpy as np
from numpy.typing import ArrayLike, NDArray

from lightcal.capture.apriltag import drawing_turns
from lightcal.capture.board_layout import (
    BoardRendering,
    aruco_dictionary,
    aruco_dictionary_names,
    board_to_world,
    check_count,
    check_ids,
    check_length,
    check_margin,
    check_origin,
    check_px_per_m,
    paste_markers,
    square_xy,
    whole_pixels,
)
from lightcal.capture.chessboard import Chessboard
from lightcal.capture.marker_layout import LayoutMarker, MarkerLayout
from lightcal.errors import InputError

__all__ = [
    "R_WORLD_BOARD",
    "ArucoGridBoard",
    "Board",
    "BoardRendering",
    "CharucoBoard",
    "Chessboard",
    "LayoutMarker",
    "MarkerLayout",
    "aruco_dictionary",
    "aruco_dictionary_names",
]

R_WORLD_BOARD = np.diag([1.0, -1.0, -1.0])
"""(3, 3) rotation from OpenCV's board frame to the world frame (see the module docstring)."""


@dataclass(frozen=True)
class ArucoGridBoard:
    """A grid of ArUco markers (OpenCV's `cv2.aruco.GridBoard`).

    Markers are numbered row by row from the top-left: marker `first_id + k` sits in
    column `k % markers_x` and row `k // markers_x`; its top-left corner is at board
    (x, y) = (col, row) * (marker_length_m + separation_m), i.e. at world
    (origin_x + x, origin_y - y, 0).

    Attributes:
        dictionary: Predefined `cv2.aruco` dictionary name, e.g. `"DICT_5X5_100"`.
        markers_x: Number of markers per row.
        markers_y: Number of rows.
        marker_length_m: Side of a marker's black square, metres.
        separation_m: White gap between neighbouring markers, metres.
        first_id: Id of the top-left marker; the board uses ids
            `first_id .. first_id + markers_x * markers_y - 1`.
        origin_world_m: World (x, y) of the outer top-left corner of the top-left marker.
    """

    dictionary: str
    markers_x: int
    markers_y: int
    marker_length_m: float
    separation_m: float
    first_id: int = 0
    origin_world_m: tuple[float, float] = (0.0, 0.0)

    def __post_init__(self) -> None:
        dictionary = aruco_dictionary(self.dictionary)
        object.__setattr__(self, "markers_x", check_count("markers_x", self.markers_x, 1))
        object.__setattr__(self, "markers_y", check_count("markers_y", self.markers_y, 1))
        for name in ("marker_length_m", "separation_m"):
            object.__setattr__(self, name, check_length(name, getattr(self, name)))
        object.__setattr__(self, "first_id", check_count("first_id", self.first_id, 0))
        object.__setattr__(self, "origin_world_m", check_origin(self.origin_world_m))
        n_dictionary = int(dictionary.bytesList.shape[0])
        last_id = self.first_id + self.n_markers - 1
        if last_id >= n_dictionary:
            raise InputError(
                "first_id",
                f"the board needs marker ids {self.first_id}..{last_id} but "
                f"{self.dictionary} has ids 0..{n_dictionary - 1}",
            )

    @property
    def n_markers(self) -> int:
        """Number of markers on the board."""
        return self.markers_x * self.markers_y

    @property
    def ids(self) -> NDArray[np.int64]:
        """(n_markers,) the marker ids, row by row from the top-left."""
        return np.arange(self.first_id, self.first_id + self.n_markers, dtype=np.int64)

    @property
    def size_m(self) -> tuple[float, float]:
        """(width, height) of the printed pattern (outer marker edges), metres."""
        pitch = self.marker_length_m + self.separation_m
        return (
            self.markers_x * pitch - self.separation_m,
            self.markers_y * pitch - self.separation_m,
        )

    def cv_board(self) -> Any:
        """The equivalent `cv2.aruco.GridBoard` (board frame, float32 object points)."""
        return cv2.aruco.GridBoard(
            (self.markers_x, self.markers_y),
            self.marker_length_m,
            self.separation_m,
            aruco_dictionary(self.dictionary),
            self.ids.astype(np.int32),
        )

    def _marker_top_left_xy(self, ids: NDArray[np.int64]) -> tuple[Any, Any]:
        k = ids - self.first_id
        pitch = self.marker_length_m + self.separation_m
        return (k % self.markers_x) * pitch, (k // self.markers_x) * pitch

    def corners_world(self, ids: ArrayLike) -> NDArray[np.float64]:
        """World corners of markers.

        Args:
            ids: (n,) marker ids on this board.

        Returns:
            corners_world: (n, 4, 3) metres, z = 0, in `cv2.aruco` corner order (top-left,
            top-right, bottom-right, bottom-left of the printed marker).

        Raises:
            InputError: An id is not on the board.
        """
        checked = check_ids(ids, self.ids, what="marker")
        x0, y0 = self._marker_top_left_xy(checked)
        return board_to_world(square_xy(x0, y0, self.marker_length_m), self.origin_world_m)

    def outline_world(self, ids: ArrayLike | None = None) -> NDArray[np.float64]:
        """Polygons covered by printed markers, to mask them in images of the wall.

        Args:
            ids: (n,) marker ids, or None for every marker of the board.

        Returns:
            polygons_world: (n, 4, 3) one square per marker, metres, z = 0.
        """
        return self.corners_world(self.ids if ids is None else ids)

    def render(self, px_per_m: float, *, margin_m: float | None = None) -> BoardRendering:
        """Draw the board at `px_per_m` pixels per metre.

        Args:
            px_per_m: Scale; `marker_length_m`, `separation_m` and `margin_m` must each be
                a whole number of pixels at this scale (for instance 5 cm markers and
                1 cm gaps at 10000 px/m = 254 dpi).
            margin_m: White border around the markers, metres; None: one marker length
                (the quiet zone marker detection needs).

        Returns:
            The image and its placement on the wall.

        Raises:
            InputError: A non-positive scale, a negative margin, or a length that is not
                a whole number of pixels.
        """
        scale = check_px_per_m(px_per_m)
        margin = self.marker_length_m if margin_m is None else check_margin(margin_m)
        px = whole_pixels(
            scale,
            {
                "marker_length_m": self.marker_length_m,
                "separation_m": self.separation_m,
                "margin_m": margin,
            },
        )
        side, gap, border = px["marker_length_m"], px["separation_m"], px["margin_m"]
        width = self.markers_x * (side + gap) - gap + 2 * border
        height = self.markers_y * (side + gap) - gap + 2 * border
        image = np.full((height, width), 255, dtype=np.uint8)
        k = self.ids - self.first_id
        top_left_px = np.stack(
            [
                border + (k % self.markers_x) * (side + gap),
                border + (k // self.markers_x) * (side + gap),
            ],
            axis=1,
        )
        paste_markers(
            image,
            aruco_dictionary(self.dictionary),
            self.ids,
            top_left_px,
            side,
            turns=drawing_turns(self.dictionary),
        )
        top_left = np.array(
            [self.origin_world_m[0] - border / scale, self.origin_world_m[1] + border / scale]
        )
        return BoardRendering(image=image, px_per_m=scale, top_left_world_m=top_left)


@dataclass(frozen=True)
class CharucoBoard:
    """A ChArUco board (OpenCV's `cv2.aruco.CharucoBoard`, pattern of OpenCV >= 4.6).

    `squares_x` x `squares_y` squares of side `square_length_m`; the top-left square is
    black and ArUco markers (ids 0, 1, ... row by row) are centred in the white squares.
    Chessboard corner `k` (the ChArUco corner id) is the inner corner in column
    `k % (squares_x - 1)` and row `k // (squares_x - 1)`, at board (x, y) =
    ((col + 1), (row + 1)) * square_length_m.

    Attributes:
        dictionary: Predefined `cv2.aruco` dictionary name.
        squares_x: Number of squares per row (>= 2).
        squares_y: Number of rows of squares (>= 2).
        square_length_m: Side of a chessboard square, metres.
        marker_length_m: Side of a marker, metres; smaller than the square.
        origin_world_m: World (x, y) of the board's outer top-left corner.
    """

    dictionary: str
    squares_x: int
    squares_y: int
    square_length_m: float
    marker_length_m: float
    origin_world_m: tuple[float, float] = (0.0, 0.0)

    def __post_init__(self) -> None:
        dictionary = aruco_dictionary(self.dictionary)
        object.__setattr__(self, "squares_x", check_count("squares_x", self.squares_x, 2))
        object.__setattr__(self, "squares_y", check_count("squares_y", self.squares_y, 2))
        for name in ("square_length_m", "marker_length_m"):
            object.__setattr__(self, name, check_length(name, getattr(self, name)))
        if self.marker_length_m >= self.square_length_m:
            raise InputError(
                "marker_length_m",
                f"expected a marker smaller than the square ({self.square_length_m!r} m), "
                f"got {self.marker_length_m!r} m",
            )
        object.__setattr__(self, "origin_world_m", check_origin(self.origin_world_m))
        n_dictionary = int(dictionary.bytesList.shape[0])
        if self.n_markers > n_dictionary:
            raise InputError(
                "dictionary",
                f"the board needs {self.n_markers} markers but {self.dictionary} has "
                f"{n_dictionary}",
            )

    @property
    def n_markers(self) -> int:
        """Number of markers (white squares)."""
        return (self.squares_x * self.squares_y) // 2

    @property
    def marker_ids(self) -> NDArray[np.int64]:
        """(n_markers,) the marker ids 0 .. n_markers - 1."""
        return np.arange(self.n_markers, dtype=np.int64)

    @property
    def corner_ids(self) -> NDArray[np.int64]:
        """(n_corners,) the ChArUco (inner chessboard) corner ids."""
        return np.arange((self.squares_x - 1) * (self.squares_y - 1), dtype=np.int64)

    @property
    def size_m(self) -> tuple[float, float]:
        """(width, height) of the board, metres."""
        return self.squares_x * self.square_length_m, self.squares_y * self.square_length_m

    def cv_board(self) -> Any:
        """The equivalent `cv2.aruco.CharucoBoard` (board frame, float32 object points)."""
        return cv2.aruco.CharucoBoard(
            (self.squares_x, self.squares_y),
            self.square_length_m,
            self.marker_length_m,
            aruco_dictionary(self.dictionary),
        )

    def _white_cells(self) -> NDArray[np.int64]:
        """(n_markers, 2) (col, row) of the white squares, in marker-id order."""
        rows, cols = np.divmod(np.arange(self.squares_x * self.squares_y), self.squares_x)
        white = (rows + cols) % 2 == 1
        return np.stack([cols[white], rows[white]], axis=1)

    def corners_world(self, ids: ArrayLike) -> NDArray[np.float64]:
        """World positions of ChArUco corners.

        Args:
            ids: (n,) ChArUco corner ids.

        Returns:
            corners_world: (n, 3) metres, z = 0.
        """
        checked = check_ids(ids, self.corner_ids, what="ChArUco corner")
        row, col = np.divmod(checked, self.squares_x - 1)
        xy = np.stack([(col + 1) * self.square_length_m, (row + 1) * self.square_length_m], -1)
        return board_to_world(xy.astype(np.float64), self.origin_world_m)

    def marker_corners_world(self, ids: ArrayLike) -> NDArray[np.float64]:
        """World corners of markers.

        Args:
            ids: (n,) marker ids.

        Returns:
            corners_world: (n, 4, 3) metres, z = 0, in `cv2.aruco` corner order.
        """
        checked = check_ids(ids, self.marker_ids, what="marker")
        cells = self._white_cells()[checked].astype(np.float64)
        offset = 0.5 * (self.square_length_m - self.marker_length_m)
        x0 = cells[:, 0] * self.square_length_m + offset
        y0 = cells[:, 1] * self.square_length_m + offset
        return board_to_world(square_xy(x0, y0, self.marker_length_m), self.origin_world_m)

    def outline_world(self, corner_ids: ArrayLike | None = None) -> NDArray[np.float64]:
        """Polygons covered by the printed board, to mask them in images of the wall.

        Args:
            corner_ids: (n,) ChArUco corner ids: the squares touching these corners; None:
                the whole board.

        Returns:
            polygons_world: (P, 4, 3) squares (or the board's rectangle), metres, z = 0.
        """
        s = self.square_length_m
        if corner_ids is None:
            width, height = self.size_m
            rectangle = np.array([[[0.0, 0.0], [width, 0.0], [width, height], [0.0, height]]])
            return board_to_world(rectangle, self.origin_world_m)
        checked = check_ids(corner_ids, self.corner_ids, what="ChArUco corner")
        row, col = np.divmod(checked, self.squares_x - 1)
        cells = {
            (int(c) + dc, int(r) + dr)
            for c, r in zip(col, row, strict=True)
            for dc in (0, 1)
            for dr in (0, 1)
        }
        ordered = np.array(sorted(cells, key=lambda cell: (cell[1], cell[0])), dtype=np.float64)
        if ordered.size == 0:
            return np.zeros((0, 4, 3))
        squares = square_xy(ordered[:, 0] * s, ordered[:, 1] * s, s)
        return board_to_world(squares, self.origin_world_m)

    def render(self, px_per_m: float, *, margin_m: float | None = None) -> BoardRendering:
        """Draw the board at `px_per_m` pixels per metre.

        Args:
            px_per_m: Scale; `square_length_m`, `margin_m` and the marker's inset
                `(square_length_m - marker_length_m) / 2` must each be a whole number of
                pixels at this scale.
            margin_m: White border around the board, metres; None: one square length.

        Returns:
            The image and its placement on the wall.

        Raises:
            InputError: A non-positive scale, a negative margin, or a length that is not
                a whole number of pixels.
        """
        scale = check_px_per_m(px_per_m)
        margin = self.square_length_m if margin_m is None else check_margin(margin_m)
        px = whole_pixels(
            scale,
            {
                "square_length_m": self.square_length_m,
                "(square_length_m - marker_length_m) / 2": 0.5
                * (self.square_length_m - self.marker_length_m),
                "margin_m": margin,
            },
        )
        square, inset, border = (
            px["square_length_m"],
            px["(square_length_m - marker_length_m) / 2"],
            px["margin_m"],
        )
        image = np.full(
            (self.squares_y * square + 2 * border, self.squares_x * square + 2 * border),
            255,
            dtype=np.uint8,
        )
        for row in range(self.squares_y):
            for col in range(self.squares_x):
                if (row + col) % 2 == 0:
                    r0, c0 = border + row * square, border + col * square
                    image[r0 : r0 + square, c0 : c0 + square] = 0
        top_left_px = border + self._white_cells() * square + inset
        paste_markers(
            image,
            aruco_dictionary(self.dictionary),
            self.marker_ids,
            top_left_px,
            square - 2 * inset,
        )
        top_left = np.array(
            [self.origin_world_m[0] - border / scale, self.origin_world_m[1] + border / scale]
        )
        return BoardRendering(image=image, px_per_m=scale, top_left_world_m=top_left)


Board = ArucoGridBoard | CharucoBoard | Chessboard | MarkerLayout
"""Any of the boards of this module."""
