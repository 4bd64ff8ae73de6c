"""What the calibration boards share: argument checks, the board-to-world map, ArUco
dictionaries and drawing at an exact scale (`BoardRendering`, whole pixels).

Frames and pixels: see `lightcal.capture.boards` and docs/conventions.md.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import cv2
import numpy as np
from numpy.typing import ArrayLike, NDArray

from lightcal.errors import InputError

_WHOLE_PIXEL_TOL = 1e-6
"""Largest accepted distance, in pixels, of a rendered length from a whole number of pixels."""


def aruco_dictionary_names() -> list[str]:
    """Names of the predefined ArUco dictionaries, e.g. `"DICT_5X5_100"`, sorted."""
    return sorted(name for name in dir(cv2.aruco) if name.startswith("DICT_"))


def aruco_dictionary(name: str) -> Any:
    """The predefined `cv2.aruco.Dictionary` called `name`.

    Args:
        name: A `cv2.aruco` dictionary name such as `"DICT_5X5_100"`.

    Raises:
        InputError: `name` is not a predefined dictionary (the message lists a few).
    """
    if not isinstance(name, str) or not name.startswith("DICT_") or not hasattr(cv2.aruco, name):
        raise InputError(
            "dictionary",
            f"unknown ArUco dictionary {name!r}: expected a cv2.aruco name such as "
            "DICT_4X4_50, DICT_5X5_100, DICT_6X6_250, DICT_7X7_1000 or DICT_APRILTAG_36h11",
        )
    return cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, name))


def check_count(name: str, value: Any, minimum: int) -> int:
    if isinstance(value, bool) or not isinstance(value, int | np.integer) or value < minimum:
        raise InputError(name, f"expected an int >= {minimum}, got {value!r}")
    return int(value)


def check_real(name: str, value: Any, *, positive: bool, expected: str) -> float:
    """`value` as a float if it is a finite real > 0 (`positive`) or >= 0, else InputError."""
    is_real = not isinstance(value, bool) and isinstance(
        value, int | float | np.integer | np.floating
    )
    if not (is_real and math.isfinite(value) and (value > 0.0 if positive else value >= 0.0)):
        raise InputError(name, f"expected {expected}, got {value!r}")
    return float(value)


def check_length(name: str, value: Any) -> float:
    return check_real(name, value, positive=True, expected="a positive length in metres")


def check_origin(value: Any) -> tuple[float, float]:
    try:
        array = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        array = np.zeros(0)
    if array.shape != (2,) or not np.all(np.isfinite(array)):
        raise InputError(
            "origin_world_m", f"expected two finite coordinates (x, y) in metres, got {value!r}"
        )
    return float(array[0]), float(array[1])


def check_ids(ids: ArrayLike, valid: NDArray[np.int64], *, what: str) -> NDArray[np.int64]:
    """Return `ids` as an (n,) int64 array, every id one of `valid`."""
    array = np.asarray(ids)
    if array.size == 0:
        return np.zeros(0, dtype=np.int64)
    if array.dtype.kind not in "iu":
        raise InputError("ids", f"expected integer {what} ids, got {array.dtype}")
    flat = array.reshape(-1).astype(np.int64)
    unknown = flat[~np.isin(flat, valid)]
    if unknown.size:
        raise InputError(
            "ids",
            f"{what} id {int(unknown[0])} is not on the board: expected ids "
            f"{int(valid.min())}..{int(valid.max())}",
        )
    return flat


def board_to_world(points_board_xy: NDArray[np.float64], origin: tuple[float, float]) -> Any:
    """(..., 2) board (x, y) -> (..., 3) world points on z = 0."""
    out = np.zeros((*points_board_xy.shape[:-1], 3))
    out[..., 0] = origin[0] + points_board_xy[..., 0]
    out[..., 1] = origin[1] - points_board_xy[..., 1]
    return out


def square_xy(x0: NDArray[np.float64], y0: NDArray[np.float64], side: float) -> Any:
    """(n, 4, 2) board-frame squares with top-left corners (x0, y0), OpenCV corner order.

    The order is top-left, top-right, bottom-right, bottom-left as printed: clockwise on
    the page, the order of `cv2.aruco` marker corners.
    """
    dx = np.array([0.0, side, side, 0.0])
    dy = np.array([0.0, 0.0, side, side])
    return np.stack([x0[:, None] + dx, y0[:, None] + dy], axis=-1)


def whole_pixels(px_per_m: float, lengths_m: dict[str, float]) -> dict[str, int]:
    """Each length in whole pixels, or InputError if one is not a whole number."""
    pixels = {name: length * px_per_m for name, length in lengths_m.items()}
    bad = {name: n for name, n in pixels.items() if abs(n - round(n)) > _WHOLE_PIXEL_TOL}
    if bad:
        details = ", ".join(f"{name} -> {n:.6g} px" for name, n in bad.items())
        raise InputError(
            "px_per_m",
            f"expected the board's lengths to be whole numbers of pixels at "
            f"{px_per_m!r} px/m, got {details}",
        )
    return {name: round(n) for name, n in pixels.items()}


def check_px_per_m(px_per_m: Any) -> float:
    return check_real(
        "px_per_m", px_per_m, positive=True, expected="a positive number of pixels per metre"
    )


def check_margin(margin_m: Any) -> float:
    return check_real("margin_m", margin_m, positive=False, expected="a length >= 0 in metres")


@dataclass(frozen=True, eq=False)
class BoardRendering:
    """A board drawn at an exact scale.

    Attributes:
        image: (H, W) uint8, white 255 (paper and margin), black 0 (print).
        px_per_m: Pixels per metre on the wall.
        top_left_world_m: (2,) world (x, y) of the image's top-left corner, i.e. the
            outer corner of pixel (0, 0); rows run towards world -y.
    """

    image: NDArray[np.uint8]
    px_per_m: float
    top_left_world_m: NDArray[np.float64] = field(repr=False)

    @property
    def A_pixel_world(self) -> NDArray[np.float64]:
        """(2, 3) affine mapping world (x, y, 1) to image pixel (u, v) (centres at integers).

        u = px_per_m (x - x0) - 1/2 and v = px_per_m (y0 - y) - 1/2 with
        (x0, y0) = `top_left_world_m`.
        """
        s = self.px_per_m
        x0, y0 = float(self.top_left_world_m[0]), float(self.top_left_world_m[1])
        return np.array([[s, 0.0, -s * x0 - 0.5], [0.0, -s, s * y0 - 0.5]])


def paste_markers(
    image: NDArray[np.uint8],
    dictionary: Any,
    ids: NDArray[np.int64],
    top_left_px: NDArray[np.int64],
    side_px: int,
    *,
    turns: int = 0,
) -> None:
    """Draw markers `ids` with their top-left pixel at `top_left_px` (n, 2) (col, row), as
    OpenCV draws them turned by `turns` quarter turns (`np.rot90`)."""
    for marker_id, (col, row) in zip(ids, top_left_px, strict=True):
        marker = np.rot90(dictionary.generateImageMarker(int(marker_id), side_px), turns)
        image[row : row + side_px, col : col + side_px] = marker
