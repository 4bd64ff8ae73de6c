"""From a camera file's parsed mapping (YAML, JSON, OpenCV FileStorage) to a `Camera`.

The keys accepted for each value (`KEYS_*`; the first is what `write_camera` writes),
matrices as OpenCV matrices, nested or flat lists, and every check with its message
naming the file and the key. The file formats themselves are `lightcal.io.camera_file`.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from lightcal.core.camera import Camera
from lightcal.errors import InputError

KEYS_CAMERA_MATRIX = ("camera_matrix", "K", "cameraMatrix")
KEYS_DISTORTION = ("distortion_coefficients", "dist_coeffs", "D", "distCoeffs")
KEYS_WIDTH = ("image_width", "width")
KEYS_HEIGHT = ("image_height", "height")
KEY_IMAGE_SIZE = "image_size"
KEY_COVARIANCE = "intrinsics_covariance"


# --------------------------------------------------------------------------- interpreting


def _find_key(path: Path, content: dict[str, Any], keys: tuple[str, ...]) -> str | None:
    present = [key for key in keys if key in content]
    if len(present) > 1:
        raise InputError(
            path,
            f"{present[0]}: found the keys {', '.join(present)} for the same value: "
            "expected only one",
        )
    return present[0] if present else None


def _require_key(path: Path, content: dict[str, Any], keys: tuple[str, ...]) -> str:
    key = _find_key(path, content, keys)
    if key is None:
        raise InputError(path, f"{keys[0]}: missing key: expected one of {', '.join(keys)}")
    return key


def _as_float(path: Path, key: str, value: Any) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise InputError(path, f"{key}: expected numbers, got {value!r}")
    return float(value)


def _matrix(path: Path, key: str, value: Any) -> NDArray[np.float64]:
    """A matrix given as OpenCV rows/cols/data, a nested list or a flat list."""
    if isinstance(value, dict) and "sizes" in value and "rows" not in value:
        # An OpenCV n-dimensional matrix (what cv2 writes for a 1-D numpy array).
        sizes = value["sizes"]
        if not isinstance(sizes, list):
            sizes = [sizes]
        if len(sizes) == 1:
            sizes = [1, *sizes]
        if len(sizes) != 2:
            raise InputError(path, f"{key}: expected a 1- or 2-D matrix, got sizes {sizes!r}")
        value = {"rows": sizes[0], "cols": sizes[1], "data": value.get("data")}
    if isinstance(value, dict):
        missing = [name for name in ("rows", "cols", "data") if name not in value]
        if missing:
            raise InputError(
                path, f"{key}: expected a matrix with rows, cols and data, missing {missing[0]}"
            )
        rows, cols, data = value["rows"], value["cols"], value["data"]
        if (
            isinstance(rows, bool)
            or isinstance(cols, bool)
            or not isinstance(rows, int)
            or not isinstance(cols, int)
            or rows < 0
            or cols < 0
        ):
            raise InputError(
                path, f"{key}: expected non-negative integer rows and cols, got {rows!r}, {cols!r}"
            )
        if data is None:
            data = []
        if not isinstance(data, list):
            data = [data]
        if len(data) != rows * cols:
            raise InputError(
                path,
                f"{key}: expected rows x cols = {rows * cols} values in data, got {len(data)}",
            )
        flat = [_as_float(path, key, v) for v in data]
        return np.array(flat, dtype=np.float64).reshape(rows, cols)
    if isinstance(value, list):
        if all(isinstance(row, list) for row in value) and value:
            lengths = {len(row) for row in value}
            if len(lengths) != 1:
                raise InputError(path, f"{key}: expected rows of equal length, got {value!r}")
            rows_list = [[_as_float(path, key, v) for v in row] for row in value]
            return np.array(rows_list, dtype=np.float64).reshape(len(value), lengths.pop())
        flat = [_as_float(path, key, v) for v in value]
        return np.array(flat, dtype=np.float64).reshape(1, len(flat))
    raise InputError(path, f"{key}: expected a matrix, got {value!r}")


def _check_finite(path: Path, key: str, array: NDArray[np.float64]) -> None:
    if not np.all(np.isfinite(array)):
        raise InputError(path, f"{key}: expected finite values, got {array.ravel().tolist()}")


def _camera_matrix(path: Path, content: dict[str, Any]) -> NDArray[np.float64]:
    key = _require_key(path, content, KEYS_CAMERA_MATRIX)
    K = _matrix(path, key, content[key])
    if K.shape == (1, 9):
        K = K.reshape(3, 3)
    if K.shape != (3, 3):
        raise InputError(path, f"{key}: expected a 3x3 matrix, got {K.shape[0]}x{K.shape[1]}")
    _check_finite(path, key, K)
    return K


def _distortion(path: Path, content: dict[str, Any]) -> NDArray[np.float64]:
    key = _require_key(path, content, KEYS_DISTORTION)
    value = content[key]
    coeffs = np.zeros((1, 0)) if value is None else _matrix(path, key, value)
    if coeffs.size and min(coeffs.shape) != 1:
        raise InputError(
            path,
            f"{key}: expected a 1xn or nx1 vector, got {coeffs.shape[0]}x{coeffs.shape[1]}",
        )
    flat = coeffs.reshape(-1)
    _check_finite(path, key, flat)
    if flat.size in (12, 14):
        if np.any(flat[8:] != 0.0):
            raise InputError(
                path,
                f"{key}: thin-prism and tilt coefficients (s1..s4, tau_x, tau_y) are not "
                f"supported: expected them zero, got {flat[8:].tolist()}",
            )
        flat = flat[:8]
    if flat.size not in (0, 4, 5, 8):
        raise InputError(path, f"{key}: expected 0, 4, 5 or 8 coefficients, got {flat.size}")
    return flat


def _positive_int(path: Path, key: str, value: Any) -> int:
    if (
        isinstance(value, bool)
        or not isinstance(value, int | float)
        or not math.isfinite(value)
        or value != int(value)
        or value <= 0
    ):
        raise InputError(path, f"{key}: expected a positive integer, got {value!r}")
    return int(value)


def _image_size(path: Path, content: dict[str, Any]) -> tuple[int, int]:
    key_w = _find_key(path, content, KEYS_WIDTH)
    key_h = _find_key(path, content, KEYS_HEIGHT)
    if key_w is not None and key_h is not None:
        return (
            _positive_int(path, key_w, content[key_w]),
            _positive_int(path, key_h, content[key_h]),
        )
    if KEY_IMAGE_SIZE in content:
        size = content[KEY_IMAGE_SIZE]
        if isinstance(size, dict):  # cv2.FileStorage writes a tuple as a 2x1 matrix
            size = _matrix(path, KEY_IMAGE_SIZE, size).ravel().tolist()
        if not isinstance(size, list) or len(size) != 2:
            raise InputError(path, f"{KEY_IMAGE_SIZE}: expected [width, height], got {size!r}")
        return (
            _positive_int(path, KEY_IMAGE_SIZE, size[0]),
            _positive_int(path, KEY_IMAGE_SIZE, size[1]),
        )
    keys = KEYS_WIDTH if key_w is None else KEYS_HEIGHT
    raise InputError(
        path,
        f"{keys[0]}: missing key: expected one of {', '.join(keys)} (or {KEY_IMAGE_SIZE})",
    )


_CAMERA_FIELD_KEYS = {
    "K": KEYS_CAMERA_MATRIX[0],
    "dist": KEYS_DISTORTION[0],
    "width": KEYS_WIDTH[0],
    "height": KEYS_HEIGHT[0],
    "intrinsics_covariance": KEY_COVARIANCE,
}


def build_camera(
    path: Path, make: Callable[[], Camera], *, line: int | None = None, name: str | None = None
) -> Camera:
    """Build a Camera, reporting its validation errors against the file.

    The error names the file's key for the Camera field, or `name` when given.
    """
    try:
        return make()
    except InputError as error:
        field = name or _CAMERA_FIELD_KEYS.get(error.source, error.source)
        raise InputError(path, f"{field}: {error.detail}", line=line) from error


def camera_from_mapping(path: Path, content: dict[str, Any]) -> Camera:
    K = _camera_matrix(path, content)
    dist = _distortion(path, content)
    width, height = _image_size(path, content)
    covariance = None
    if content.get(KEY_COVARIANCE) is not None:
        covariance = _matrix(path, KEY_COVARIANCE, content[KEY_COVARIANCE])
        _check_finite(path, KEY_COVARIANCE, covariance)
        p = 4 + dist.size
        if covariance.shape != (p, p):
            raise InputError(
                path,
                f"{KEY_COVARIANCE}: expected a {p}x{p} matrix over (fx, fy, cx, cy and the "
                f"{dist.size} distortion coefficients), got "
                f"{covariance.shape[0]}x{covariance.shape[1]}",
            )
    return build_camera(
        path,
        lambda: Camera(
            K=K, dist=dist, width=width, height=height, intrinsics_covariance=covariance
        ),
    )
