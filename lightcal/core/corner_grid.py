"""The undistorted corner grid of a camera, and a small cache of grids per camera.

Every pixel corner of an image, undistorted once: the renderer of whole images and the
footprints of dense pixel selections read their corners from it instead of undistorting
each corner four times (neighbouring pixels share corners). Corner (j, i) sits at pixel
coordinates (i - 1/2, j - 1/2) (docs/model.md: pixel centres at integers).
"""

from __future__ import annotations

from collections import OrderedDict
from threading import Lock

import numba
import numpy as np

from lightcal.core.camera import Camera
from lightcal.core.distortion import undistort_normalized

CornerGrid = tuple[np.ndarray, np.ndarray]
"""grid_xy (H+1, W+1, 2) undistorted normalised coordinates and grid_ok (H+1, W+1)."""


def corner_grid(camera: Camera) -> CornerGrid:
    """Undistorted normalised coordinates of every pixel corner.

    Computed by a parallel kernel with the arithmetic of `Camera.pixels_to_normalized`
    (bit for bit).

    Returns:
        grid_xy (H+1, W+1, 2) and grid_ok (H+1, W+1); corner (j, i) sits at pixel
        coordinates (i - 1/2, j - 1/2); grid_xy is (0, 0) where grid_ok is False.
    """
    grid_xy = np.empty((camera.height + 1, camera.width + 1, 2))
    grid_ok = np.empty((camera.height + 1, camera.width + 1), dtype=np.bool_)
    with numba.parallel_chunksize(8):  # dynamic scheduling: rows cost unequal Newton work
        undistorted_corner_grid(
            np.ascontiguousarray(camera.K), np.ascontiguousarray(camera.dist), grid_xy, grid_ok
        )
    return grid_xy, grid_ok


@numba.njit(cache=True, parallel=True)
def undistorted_corner_grid(
    K: np.ndarray, dist: np.ndarray, out_xy: np.ndarray, out_ok: np.ndarray
) -> None:
    """Undistorted normalised coordinates of every pixel corner, rows in parallel.

    The same arithmetic as `Camera.pixels_to_normalized` (bit for bit).

    Args:
        K: (3, 3) intrinsics; dist: (8,) OpenCV coefficients, zero padded.
        out_xy: (H+1, W+1, 2) written; corner (j, i) sits at pixel (i - 1/2, j - 1/2);
            (0, 0) where the undistortion fails.
        out_ok: (H+1, W+1) written: the undistortion succeeded.
    """
    n_rows = out_xy.shape[0]
    n_cols = out_xy.shape[1]
    fx = K[0, 0]
    s = K[0, 1]
    cx = K[0, 2]
    fy = K[1, 1]
    cy = K[1, 2]
    for j in numba.prange(n_rows):
        yd = (float(j) - 0.5 - cy) / fy
        for i in range(n_cols):
            xd = (float(i) - 0.5 - cx - s * yd) / fx
            x, y, ok = undistort_normalized(xd, yd, dist)
            out_ok[j, i] = ok
            out_xy[j, i, 0] = x if ok else 0.0
            out_xy[j, i, 1] = y if ok else 0.0


def _camera_key(camera: Camera) -> bytes:
    """Everything a corner grid depends on: K, the distortion and the image size."""
    return (
        camera.K.tobytes()
        + camera.dist.tobytes()
        + bytes(f"{camera.width}x{camera.height}", "ascii")
    )


class CornerGridCache:
    """Undistorted corner grids per camera (they cost far more than a render).

    Holds the `max_entries` most recently used grids; thread safe. A 24 MP camera's grid
    takes ~0.4 GB.
    """

    def __init__(self, max_entries: int = 2) -> None:
        self._entries: OrderedDict[bytes, CornerGrid] = OrderedDict()
        self._lock = Lock()
        self._max = max_entries

    def lookup(self, camera: Camera) -> CornerGrid | None:
        """The camera's grid if it is cached (marked as recently used), else None."""
        key = _camera_key(camera)
        with self._lock:
            grid = self._entries.get(key)
            if grid is not None:
                self._entries.move_to_end(key)
            return grid

    def get(self, camera: Camera) -> CornerGrid:
        """The camera's grid, computed and cached if it is not cached yet."""
        grid = self.lookup(camera)
        if grid is not None:
            return grid
        grid = corner_grid(camera)
        with self._lock:
            self._entries[_camera_key(camera)] = grid
            while len(self._entries) > self._max:
                self._entries.popitem(last=False)
        return grid

    def clear(self) -> None:
        """Forget every cached grid."""
        with self._lock:
            self._entries.clear()


GRID_CACHE = CornerGridCache()
"""The process-wide cache that `render_image` and `pixel_footprints` share."""
