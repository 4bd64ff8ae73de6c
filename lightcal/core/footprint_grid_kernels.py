"""Compiled (numba) kernels of footprints that keep no quads (`footprint.GridCorners`).

A dense selection's footprints hold the camera's corner grid and the view instead of
96 bytes a quad; these kernels recompute a pixel's quads from the grid when they are
needed (the flux kernel's blocks, `kernels.flux.flux_pixels_grid`; the footprint centres;
`Footprints.corners_world` on request), with the arithmetic of
`footprint_kernels.pixel_footprints_parallel` reading the same grid: the same numbers, bit
for bit.
"""

from __future__ import annotations

import numba
import numpy as np

from lightcal.core.kernels.sensor import view_scalars, wall_point


@numba.njit(cache=True, inline="always")
def write_quad(
    out: np.ndarray,
    p: int,
    m: int,
    x1: float,
    y1: float,
    x2: float,
    y2: float,
    x3: float,
    y3: float,
    x4: float,
    y4: float,
) -> None:
    """out[p, m] (4, 3) = the wall quad P1..P4 (z = 0)."""
    out[p, m, 0, 0] = x1
    out[p, m, 0, 1] = y1
    out[p, m, 0, 2] = 0.0
    out[p, m, 1, 0] = x2
    out[p, m, 1, 1] = y2
    out[p, m, 1, 2] = 0.0
    out[p, m, 2, 0] = x3
    out[p, m, 2, 1] = y3
    out[p, m, 2, 2] = 0.0
    out[p, m, 3, 0] = x4
    out[p, m, 3, 1] = y4
    out[p, m, 3, 2] = 0.0


@numba.njit(cache=True, inline="always", error_model="numpy")
def _grid_wall_point(
    grid_xy: np.ndarray, grid_ok: np.ndarray, row: int, col: int, view: tuple[float, ...]
) -> tuple[float, float, bool]:
    """Where corner (row, col) of the grid meets the wall (as `_pixel_footprint`)."""
    return wall_point(grid_xy[row, col, 0], grid_xy[row, col, 1], grid_ok[row, col], view, True)


@numba.njit(cache=True, inline="always", error_model="numpy")
def grid_quads(
    p: int,
    pixels: np.ndarray,
    binning: int,
    grid_xy: np.ndarray,
    grid_ok: np.ndarray,
    view: tuple[float, ...],
    out: np.ndarray,
    row: int,
) -> None:
    """Write the b^2 quads of (super-)pixel p into out[row] (b^2, 4, 3): the numbers
    `pixel_footprints_parallel` writes from the same grid, bit for bit (NaN if invalid).

    Args:
        p: the pixel's row in `pixels` (N, 2) (u, v) of the image binned by `binning`.
        grid_xy, grid_ok: the camera's corner grid (`corner_grid`).
        view: `view_scalars` of the view.
        out: (M, b^2, 4, 3) written at `row`.
    """
    b = binning
    u0 = pixels[p, 0] * b
    v0 = pixels[p, 1] * b
    valid = True
    for m in range(b * b):
        jj = m // b
        r = v0 + jj
        c = u0 + m - jj * b
        x1, y1, h1 = _grid_wall_point(grid_xy, grid_ok, r, c, view)
        x2, y2, h2 = _grid_wall_point(grid_xy, grid_ok, r, c + 1, view)
        x3, y3, h3 = _grid_wall_point(grid_xy, grid_ok, r + 1, c + 1, view)
        x4, y4, h4 = _grid_wall_point(grid_xy, grid_ok, r + 1, c, view)
        valid = valid & h1 & h2 & h3 & h4
        write_quad(out, row, m, x1, y1, x2, y2, x3, y3, x4, y4)
    if not valid:
        out[row] = np.nan


@numba.njit(cache=True, inline="always", error_model="numpy")
def grid_quads_range(
    i0: int,
    i1: int,
    pixels: np.ndarray,
    binning: int,
    grid_xy: np.ndarray,
    grid_ok: np.ndarray,
    view: tuple[float, ...],
    out: np.ndarray,
) -> None:
    """`grid_quads` of pixels i0 .. i1 - 1 into out[0 : i1 - i0] (M, b^2, 4, 3).

    With b = 1, a pixel right of the previous one (a dense selection's rows) takes its
    left corners from the previous pixel's right ones: half the wall intersections.
    """
    if binning != 1:
        for i in range(i0, i1):
            grid_quads(i, pixels, binning, grid_xy, grid_ok, view, out, i - i0)
        return
    u_prev = -2
    v_prev = -2
    x2 = y2 = x3 = y3 = 0.0
    h2 = h3 = False
    for i in range(i0, i1):
        u = pixels[i, 0]
        v = pixels[i, 1]
        if v == v_prev and u == u_prev + 1:
            x1, y1, h1 = x2, y2, h2
            x4, y4, h4 = x3, y3, h3
        else:
            x1, y1, h1 = _grid_wall_point(grid_xy, grid_ok, v, u, view)
            x4, y4, h4 = _grid_wall_point(grid_xy, grid_ok, v + 1, u, view)
        x2, y2, h2 = _grid_wall_point(grid_xy, grid_ok, v, u + 1, view)
        x3, y3, h3 = _grid_wall_point(grid_xy, grid_ok, v + 1, u + 1, view)
        u_prev = u
        v_prev = v
        r = i - i0
        if h1 & h2 & h3 & h4:
            write_quad(out, r, 0, x1, y1, x2, y2, x3, y3, x4, y4)
        else:
            out[r] = np.nan


@numba.njit(cache=True, parallel=True, error_model="numpy")
def grid_corners_parallel(
    pixels: np.ndarray,
    binning: int,
    grid_xy: np.ndarray,
    grid_ok: np.ndarray,
    R_camera_world: np.ndarray,
    center_world: np.ndarray,
    out: np.ndarray,
) -> None:
    """The quads (N, b^2, 4, 3) of `pixels` read from the corner grid (`grid_quads`)."""
    view = view_scalars(R_camera_world, center_world)
    for p in numba.prange(pixels.shape[0]):
        grid_quads(p, pixels, binning, grid_xy, grid_ok, view, out, p)


@numba.njit(cache=True, error_model="numpy")
def grid_corners_serial(
    pixels: np.ndarray,
    binning: int,
    grid_xy: np.ndarray,
    grid_ok: np.ndarray,
    R_camera_world: np.ndarray,
    center_world: np.ndarray,
    out: np.ndarray,
) -> None:
    """`grid_corners_parallel` on the calling thread (a few pixels)."""
    view = view_scalars(R_camera_world, center_world)
    for p in range(pixels.shape[0]):
        grid_quads(p, pixels, binning, grid_xy, grid_ok, view, out, p)


@numba.njit(cache=True, parallel=True, error_model="numpy")
def grid_centers_parallel(
    pixels: np.ndarray,
    binning: int,
    grid_xy: np.ndarray,
    grid_ok: np.ndarray,
    R_camera_world: np.ndarray,
    center_world: np.ndarray,
    chunk_pixels: int,
    out: np.ndarray,
) -> None:
    """(N, 3) means of the 4 b^2 corners of each pixel's quads, read from the grid.

    The numbers of `footprint.quad_corner_means` of the kept corners, bit for bit (a
    running sum in the same order, then one division); NaN for invalid pixels.
    """
    n = pixels.shape[0]
    k = binning * binning
    count = float(4 * k)
    view = view_scalars(R_camera_world, center_world)
    n_chunks = (n + chunk_pixels - 1) // chunk_pixels
    for chunk in numba.prange(n_chunks):
        quads = np.empty((1, k, 4, 3))
        for p in range(chunk * chunk_pixels, min(n, (chunk + 1) * chunk_pixels)):
            grid_quads(p, pixels, binning, grid_xy, grid_ok, view, quads, 0)
            for d in range(3):
                total = quads[0, 0, 0, d]
                for j in range(1, 4 * k):
                    total += quads[0, j // 4, j % 4, d]
                out[p, d] = total / count
