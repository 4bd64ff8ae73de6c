"""`lattice_on_wall`: corners of the camera's port lattice moved to a view and met with
the wall z = 0, in one compiled pass (`lightcal.core.port_footprints.port_footprints`
reading a selection's corners from `camera_port_rays`).

Per corner (row, col) of the lattice: X_p = R^T X_c + C and w = R^T w_c, world frame;
the corner meets the wall at X_p + lambda w, lambda = -X_p,z / w_z, when it went through
the port, w_z < 0 and 0 < lambda < inf (`port_footprints.wall_hits`, whose numbers these
are to round-off: the same formulas, summed in another order than NumPy's einsum).
"""

from __future__ import annotations

import math

import numba
import numpy as np


@numba.njit(cache=True, inline="always", error_model="numpy")
def _corner(
    exits_camera: np.ndarray,
    dirs_camera: np.ndarray,
    corner_ok: np.ndarray,
    R: np.ndarray,
    C: np.ndarray,
    j: int,
    u: int,
    exit_out: np.ndarray,
    point_out: np.ndarray,
) -> bool:
    """Corner (j, u): its exit point (3,) and wall point (3,; NaN on a miss) written,
    world frame, m; returns whether it meets the wall."""
    for k in range(3):
        exit_out[k] = (
            exits_camera[j, u, 0] * R[0, k] + exits_camera[j, u, 1] * R[1, k]
            + exits_camera[j, u, 2] * R[2, k] + C[k]
        )  # fmt: skip
    dx = (
        dirs_camera[j, u, 0] * R[0, 0]
        + dirs_camera[j, u, 1] * R[1, 0]
        + dirs_camera[j, u, 2] * R[2, 0]
    )
    dy = (
        dirs_camera[j, u, 0] * R[0, 1]
        + dirs_camera[j, u, 1] * R[1, 1]
        + dirs_camera[j, u, 2] * R[2, 1]
    )
    dz = (
        dirs_camera[j, u, 0] * R[0, 2]
        + dirs_camera[j, u, 1] * R[1, 2]
        + dirs_camera[j, u, 2] * R[2, 2]
    )
    lam = -exit_out[2] / dz
    hit = corner_ok[j, u] and dz < 0.0 and lam > 0.0 and lam < math.inf
    if hit:
        point_out[0] = exit_out[0] + lam * dx
        point_out[1] = exit_out[1] + lam * dy
        point_out[2] = 0.0
    else:
        point_out[:] = np.nan
    return hit


@numba.njit(cache=True, parallel=True, error_model="numpy")
def _corners(
    exits_camera: np.ndarray,
    dirs_camera: np.ndarray,
    corner_ok: np.ndarray,
    R: np.ndarray,
    C: np.ndarray,
    grid_xy: np.ndarray,
    rows: np.ndarray,
    cols: np.ndarray,
    exits: np.ndarray,
    points: np.ndarray,
    xy: np.ndarray,
    hit: np.ndarray,
) -> None:
    for i in numba.prange(rows.shape[0]):
        j, u = rows[i], cols[i]
        hit[i] = _corner(exits_camera, dirs_camera, corner_ok, R, C, j, u, exits[i], points[i])
        xy[i, 0] = grid_xy[j, u, 0]
        xy[i, 1] = grid_xy[j, u, 1]


def lattice_on_wall(
    exits_camera: np.ndarray,
    dirs_camera: np.ndarray,
    corner_ok: np.ndarray,
    grid_xy: np.ndarray,
    R_camera_world: np.ndarray,
    center_world: np.ndarray,
    rows: np.ndarray,
    cols: np.ndarray,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Corners (rows, cols) (integers, broadcast to a shape S) of the port lattice (exits and water
    directions (H+1, W+1, 3), camera frame, NaN where not ok; corner_ok and undistorted
    coordinates grid_xy (H+1, W+1, 2): `camera_port_rays`') in the view (R_camera_world
    (3, 3), center_world (3,)): their exit points (*S, 3) and wall points (*S, 3; NaN on
    a miss), world frame, m, their coordinates (*S, 2) and whether they hit (*S)."""
    rows, cols = np.broadcast_arrays(rows, cols)
    shape = rows.shape
    r = np.ascontiguousarray(rows, dtype=np.int64).ravel()
    c = np.ascontiguousarray(cols, dtype=np.int64).ravel()
    exits = np.empty((r.size, 3))
    points = np.empty((r.size, 3))
    xy = np.empty((r.size, 2))
    hit = np.empty(r.size, dtype=np.bool_)
    _corners(
        exits_camera, dirs_camera, corner_ok,
        np.ascontiguousarray(R_camera_world, dtype=np.float64),
        np.ascontiguousarray(center_world, dtype=np.float64),
        grid_xy, r, c, exits, points, xy, hit,
    )  # fmt: skip
    out = (exits.reshape(*shape, 3), points.reshape(*shape, 3), xy.reshape(*shape, 2))
    return *out, hit.reshape(shape)
