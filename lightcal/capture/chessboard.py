"""A plain chessboard for intrinsic calibration (`Chessboard`), in the world frame of
`lightcal.capture.boards` (its origin at the top-left inner corner; metres).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from lightcal.capture.board_layout import (
    BoardRendering,
    board_to_world,
    check_count,
    check_ids,
    check_length,
    check_margin,
    check_px_per_m,
    whole_pixels,
)


@dataclass(frozen=True)
class Chessboard:
    """A plain chessboard for intrinsic calibration (`cv2.findChessboardCornersSB`).

    `inner_x` x `inner_y` inner corners, i.e. (inner_x + 1) x (inner_y + 1) squares, the
    top-left square black. The world origin is the top-left inner corner; corner
    `k` (OpenCV's row-major order) is in column `k % inner_x` and row `k // inner_x`, at
    world (col, -row, 0) * square_length_m.

    Attributes:
        inner_x: Inner corners per row (>= 2).
        inner_y: Rows of inner corners (>= 2).
        square_length_m: Side of a square, metres.
    """

    inner_x: int
    inner_y: int
    square_length_m: float

    def __post_init__(self) -> None:
        object.__setattr__(self, "inner_x", check_count("inner_x", self.inner_x, 2))
        object.__setattr__(self, "inner_y", check_count("inner_y", self.inner_y, 2))
        object.__setattr__(
            self, "square_length_m", check_length("square_length_m", self.square_length_m)
        )

    @property
    def pattern_size(self) -> tuple[int, int]:
        """(inner_x, inner_y), the `patternSize` of `cv2.findChessboardCorners*`."""
        return self.inner_x, self.inner_y

    @property
    def n_corners(self) -> int:
        """Number of inner corners."""
        return self.inner_x * self.inner_y

    def corners_world(self, ids: ArrayLike | None = None) -> NDArray[np.float64]:
        """World positions of inner corners.

        Args:
            ids: (n,) corner indices in OpenCV's row-major order, or None for all.

        Returns:
            corners_world: (n, 3) metres, z = 0.
        """
        valid = np.arange(self.n_corners, dtype=np.int64)
        checked = valid if ids is None else check_ids(ids, valid, what="chessboard corner")
        row, col = np.divmod(checked, self.inner_x)
        xy = np.stack([col, row], axis=-1).astype(np.float64) * self.square_length_m
        return board_to_world(xy, (0.0, 0.0))

    def outline_world(self) -> NDArray[np.float64]:
        """(1, 4, 3) the board's outer rectangle on the wall, metres, z = 0."""
        s = self.square_length_m
        rectangle = np.array(
            [
                [
                    [-s, -s],
                    [self.inner_x * s, -s],
                    [self.inner_x * s, self.inner_y * s],
                    [-s, self.inner_y * s],
                ]
            ]
        )
        return board_to_world(rectangle, (0.0, 0.0))

    def render(self, px_per_m: float, *, margin_m: float | None = None) -> BoardRendering:
        """Draw the chessboard at `px_per_m` pixels per metre.

        Args:
            px_per_m: Scale; `square_length_m` and `margin_m` must each be a whole number
                of pixels at this scale.
            margin_m: White border around the squares, metres; None: one square length.

        Returns:
            The image and its placement on the wall.
        """
        scale = check_px_per_m(px_per_m)
        margin = self.square_length_m if margin_m is None else check_margin(margin_m)
        px = whole_pixels(scale, {"square_length_m": self.square_length_m, "margin_m": margin})
        square, border = px["square_length_m"], px["margin_m"]
        n_x, n_y = self.inner_x + 1, self.inner_y + 1
        rows, cols = np.divmod(np.arange(n_y * square * n_x * square), n_x * square)
        squares = ((rows // square) + (cols // square)) % 2 == 0
        image = np.full((n_y * square + 2 * border, n_x * square + 2 * border), 255, np.uint8)
        image[border : border + n_y * square, border : border + n_x * square] = np.where(
            squares.reshape(n_y * square, n_x * square), 0, 255
        )
        s = self.square_length_m
        top_left = np.array([-s - border / scale, s + border / scale])
        return BoardRendering(image=image, px_per_m=scale, top_left_world_m=top_left)
