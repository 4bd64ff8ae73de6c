"""The undistorted corner grid of a camera, and a small cache of grids per camera.

Every pixel corner of an image, undistorted once: the renderer of whole images and the
footprints of dense pixel selections read their corners from it instead of undistorting
each corner four times (neighbouring pixels share corners). Corner (j, i) sits at pixel
coordinates (i - 1/2, j - 1/2) (docs/model.md: pixel centres at integers).

Each corner is a root of the distortion map, found by Newton's method seeded from the
corners already solved around it (`_solve_rows`): one Newton step from a quadratic
extrapolation of the three corners above polishes it to round-off, in vectorised loops,
where `undistort_normalized` (what `Camera.pixels_to_normalized` runs per point) needs
~8-10 damped steps from the distorted point. The corners agree with
`Camera.pixels_to_normalized`'s to round-off (not bit for bit: ~1e-15 in normalised
coordinates, tests hold them to 1e-12). A neighbour-seeded corner is kept only at
`undistort_normalized`'s residual tolerance and within `PIXEL_TOL` (1e-9 px) of its
pixel (~1e-12 px in practice; tests hold every corner to 1e-9 px). `grid_ok` is exactly
`pixels_to_normalized`'s validity: a neighbour-seeded root is kept only inside the disc
where the map is one-to-one with margin (`_safe_radius2`), where it is the root
`undistort_normalized` finds; every other corner (past or near the fold of a strong
distortion, next to a failed corner, or slow to converge) is solved by
`undistort_normalized` itself, bit for bit as before, which decides whether it fails.
"""

from __future__ import annotations

from collections import OrderedDict
from threading import Lock

import numba
import numpy as np

from lightcal.core.camera import Camera
from lightcal.core.distortion import _ACCEPT_TOL, _RESIDUAL_TOL, _STEP_TOL, undistort_normalized

CornerGrid = tuple[np.ndarray, np.ndarray]
"""grid_xy (H+1, W+1, 2) undistorted normalised coordinates and grid_ok (H+1, W+1)."""

ROWS_PER_BLOCK = 32
"""Rows of corners one thread solves in turn (a work item of the parallel kernel): the
first from its left neighbours, the others from the rows above them."""

WARM_MAX_STEPS = 4
"""Newton steps a corner seeded from its left neighbours may take before it is solved
from scratch (`undistort_normalized`)."""

PIXEL_TOL = 1e-9
"""A neighbour-seeded corner is kept only if it maps back to its pixel within this, px."""

SAFE_SLOPE = 0.1
"""Lower bound of the distortion Jacobian's eigenvalues on the disc where
neighbour-seeded roots are kept (`_safe_radius2`)."""

SAFE_MARGIN = 0.9
"""That disc's radius as a fraction of where the bound `SAFE_SLOPE` first fails."""

SAFE_SCAN_STEPS = 20_000
"""Radii `_safe_radius2` samples."""


def corner_grid(camera: Camera) -> CornerGrid:
    """Undistorted normalised coordinates of every pixel corner.

    The roots `Camera.pixels_to_normalized` finds, to round-off (module docstring), and
    its validity flags exactly.

    Returns:
        grid_xy (H+1, W+1, 2) and grid_ok (H+1, W+1); corner (j, i) sits at pixel
        coordinates (i - 1/2, j - 1/2); grid_xy is (0, 0) where grid_ok is False.
    """
    grid_xy = np.empty((camera.height + 1, camera.width + 1, 2))
    grid_ok = np.empty((camera.height + 1, camera.width + 1), dtype=np.bool_)
    with numba.parallel_chunksize(1):  # dynamic scheduling: blocks cost unequal work
        undistorted_corner_grid(
            np.ascontiguousarray(camera.K), np.ascontiguousarray(camera.dist), grid_xy, grid_ok
        )
    return grid_xy, grid_ok


@numba.njit(cache=True, parallel=True)
def undistorted_corner_grid(
    K: np.ndarray, dist: np.ndarray, out_xy: np.ndarray, out_ok: np.ndarray
) -> None:
    """Undistorted normalised coordinates of every pixel corner, blocks of
    `ROWS_PER_BLOCK` rows in parallel (`_solve_rows`).

    Args:
        K: (3, 3) intrinsics; dist: (8,) OpenCV coefficients, zero padded.
        out_xy: (H+1, W+1, 2) written; corner (j, i) sits at pixel (i - 1/2, j - 1/2);
            (0, 0) where the undistortion fails.
        out_ok: (H+1, W+1) written: the undistortion succeeded.
    """
    n_rows = out_xy.shape[0]
    r2_safe = _safe_radius2(K, dist, n_rows, out_xy.shape[1])
    n_blocks = (n_rows + ROWS_PER_BLOCK - 1) // ROWS_PER_BLOCK
    for block in numba.prange(n_blocks):
        j0 = block * ROWS_PER_BLOCK
        _solve_rows(K, dist, r2_safe, j0, min(j0 + ROWS_PER_BLOCK, n_rows), out_xy, out_ok)


@numba.njit(cache=True, error_model="numpy")
def _safe_radius2(K: np.ndarray, dist: np.ndarray, n_rows: int, n_cols: int) -> float:
    """r^2 of the disc about the optical axis where neighbour-seeded roots are kept.

    The distortion's Jacobian is symmetric; its radial part has the eigenvalues c and
    rho' = c + 2 r^2 c' (rho(r) = r c(r^2), the radial map), and the tangential terms
    shift them by at most 8 (|p1| + |p2|) r. On the disc out to `SAFE_MARGIN` of the
    first sampled radius where min(c, rho') - 8 (|p1| + |p2|) r < `SAFE_SLOPE` (or the
    rational model's denominator is <= 0) the Jacobian is positive definite: the map is
    one-to-one there, so a root found in the disc is the only one, the one
    `undistort_normalized` converges to from a distorted point in the disc. (Near the
    fold of a strong distortion it may stop early or find a root on an outer sheet;
    the margins come from random cameras, tests/test_corner_grid.py.) Sampled up to 4
    times the largest distorted radius of the image's corners, plus 1.
    """
    fx = K[0, 0]
    s = K[0, 1]
    cx = K[0, 2]
    fy = K[1, 1]
    cy = K[1, 2]
    r2_image = 0.0
    for v in (-0.5, float(n_rows) - 1.5):
        for u in (-0.5, float(n_cols) - 1.5):
            yd = (v - cy) / fy
            xd = (u - cx - s * yd) / fx
            r2_image = max(r2_image, xd * xd + yd * yd)
    r_max = 4.0 * np.sqrt(r2_image) + 1.0
    k1, k2, k3 = dist[0], dist[1], dist[4]
    k4, k5, k6 = dist[5], dist[6], dist[7]
    tangential = 8.0 * (abs(dist[2]) + abs(dist[3]))
    r_safe = r_max
    for n in range(1, SAFE_SCAN_STEPS + 1):
        r = r_max * n / SAFE_SCAN_STEPS
        r2 = r * r
        num = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3))
        den = 1.0 + r2 * (k4 + r2 * (k5 + r2 * k6))
        dnum = k1 + r2 * (2.0 * k2 + 3.0 * r2 * k3)
        dden = k4 + r2 * (2.0 * k5 + 3.0 * r2 * k6)
        c = num / den
        dc = (dnum * den - num * dden) / (den * den)
        if not (den > 0.0 and min(c, c + 2.0 * r2 * dc) - tangential * r >= SAFE_SLOPE):
            r_safe = r_max * (n - 1) / SAFE_SCAN_STEPS
            break
    r_safe *= SAFE_MARGIN
    return r_safe * r_safe


@numba.njit(cache=True, error_model="numpy")
def _solve_rows(
    K: np.ndarray,
    dist: np.ndarray,
    r2_safe: float,
    j0: int,
    j1: int,
    out_xy: np.ndarray,
    out_ok: np.ndarray,
) -> None:
    """Rows j0..j1-1 of the corner grid (see `undistorted_corner_grid`).

    Row j0 is solved corner by corner, each seeded from its left neighbours
    (`_warm_newton`). A later row is seeded column by column from the rows above it
    (extrapolated from one, two, then three rows: constant, linear, quadratic; the
    quadratic seed is ~1e-11 off on a 24 MP sensor), takes 3, 2, then 1 Newton steps and
    keeps the corners whose residual is then at round-off (`_RESIDUAL_TOL` relative,
    where `undistort_normalized` stops too, and within `PIXEL_TOL`), in the valid region
    (Jacobian determinant and radial factor > 0, as `undistort_normalized` checks) and
    in the disc `r2_safe` (with their distorted point): independent corners, vectorised
    loops over contiguous row buffers. The others (next to a failed corner, near the
    fold, slow to converge) are solved as in row j0; one that is not kept from there
    either is solved from scratch by `undistort_normalized`, which decides whether it
    fails.
    """
    n_cols = out_xy.shape[1]
    fx = K[0, 0]
    s = K[0, 1]
    cx = K[0, 2]
    fy = K[1, 1]
    cy = K[1, 2]
    k1, k2, p1, p2, k3 = dist[0], dist[1], dist[2], dist[3], dist[4]
    k4, k5, k6 = dist[5], dist[6], dist[7]
    # The last three rows solved, row j in slot j % 3 ((0, 0) where not ok).
    row_x = np.empty((3, n_cols))
    row_y = np.empty((3, n_cols))
    row_ok = np.empty((3, n_cols), dtype=np.bool_)
    xs = np.empty(n_cols)
    ys = np.empty(n_cols)
    for j in range(j0, j1):
        yd = (float(j) - 0.5 - cy) / fy
        cur = j % 3
        if j > j0:
            # Seeds from the rows above (of this block): slots a, b, c = rows j-1, j-2, j-3.
            a = (j - 1) % 3
            b = (j - 2) % 3 if j - j0 >= 2 else a
            c = (j - 3) % 3 if j - j0 >= 3 else a
            two = j - j0 >= 2
            three = j - j0 >= 3
            for i in range(n_cols):
                linear = two & row_ok[a, i] & row_ok[b, i]
                quadratic = three & linear & row_ok[c, i]
                xa = row_x[a, i]
                xb = row_x[b, i]
                ya = row_y[a, i]
                yb = row_y[b, i]
                x_lin = 2.0 * xa - xb if linear else xa
                y_lin = 2.0 * ya - yb if linear else ya
                xs[i] = 3.0 * (xa - xb) + row_x[c, i] if quadratic else x_lin
                ys[i] = 3.0 * (ya - yb) + row_y[c, i] if quadratic else y_lin
            n_steps = 1 if three else (2 if two else 3)
            for _ in range(n_steps):
                for i in range(n_cols):
                    xd = (float(i) - 0.5 - cx - s * yd) / fx
                    x = xs[i]
                    y = ys[i]
                    gx, gy, jxx, jxy, jyy, _ = _distort_with_jacobian(
                        x, y, k1, k2, p1, p2, k3, k4, k5, k6
                    )
                    ex = gx - xd
                    ey = gy - yd
                    det = jxx * jyy - jxy * jxy
                    xs[i] = x - (jyy * ex - jxy * ey) / det
                    ys[i] = y - (jxx * ey - jxy * ex) / det
            for i in range(n_cols):
                xd = (float(i) - 0.5 - cx - s * yd) / fx
                x = xs[i]
                y = ys[i]
                gx, gy, jxx, jxy, jyy, radial = _distort_with_jacobian(
                    x, y, k1, k2, p1, p2, k3, k4, k5, k6
                )
                ex = gx - xd
                ey = gy - yd
                eu = fx * ex + s * ey
                ev = fy * ey
                tol = _RESIDUAL_TOL * (1.0 + abs(xd) + abs(yd))
                ok = (
                    row_ok[a, i]
                    & (ex * ex + ey * ey <= tol * tol)
                    & (eu * eu + ev * ev <= PIXEL_TOL * PIXEL_TOL)
                    & (jxx * jyy - jxy * jxy > 0.0)
                    & (radial > 0.0)
                    & (abs(x) + abs(y) < np.inf)
                    & (x * x + y * y <= r2_safe)
                    & (xd * xd + yd * yd <= r2_safe)
                )
                row_ok[cur, i] = ok
                row_x[cur, i] = x if ok else 0.0
                row_y[cur, i] = y if ok else 0.0
        else:
            row_ok[cur, :] = False
        # The corners not solved above, seeded from their left neighbours.
        n_left = 0  # solved corners just left of i (up to 3)
        xa = ya = xb = yb = xc = yc = 0.0
        for i in range(n_cols):
            if row_ok[cur, i]:
                x = row_x[cur, i]
                y = row_y[cur, i]
                ok = True
            else:
                xd = (float(i) - 0.5 - cx - s * yd) / fx
                ok = False
                if n_left > 0 and xd * xd + yd * yd <= r2_safe:
                    if n_left >= 3:
                        x = 3.0 * (xa - xb) + xc
                        y = 3.0 * (ya - yb) + yc
                    elif n_left == 2:
                        x = 2.0 * xa - xb
                        y = 2.0 * ya - yb
                    else:
                        x = xa
                        y = ya
                    x, y, ok = _warm_newton(x, y, xd, yd, fx, s, fy, k1, k2, p1, p2, k3, k4, k5, k6)
                    ok = ok and x * x + y * y <= r2_safe
                if not ok:
                    x, y, ok = undistort_normalized(xd, yd, dist)
                row_ok[cur, i] = ok
                row_x[cur, i] = x if ok else 0.0
                row_y[cur, i] = y if ok else 0.0
            if ok:
                xc, yc = xb, yb
                xb, yb = xa, ya
                xa, ya = x, y
                n_left = min(n_left + 1, 3)
            else:
                n_left = 0
        for i in range(n_cols):
            out_xy[j, i, 0] = row_x[cur, i]
            out_xy[j, i, 1] = row_y[cur, i]
            out_ok[j, i] = row_ok[cur, i]


@numba.njit(cache=True, error_model="numpy")
def _warm_newton(
    x: float,
    y: float,
    xd: float,
    yd: float,
    fx: float,
    s: float,
    fy: float,
    k1: float,
    k2: float,
    p1: float,
    p2: float,
    k3: float,
    k4: float,
    k5: float,
    k6: float,
) -> tuple[float, float, bool]:
    """Newton's iteration for one corner from a seed near its root.

    Stops as `undistort_normalized` does (residual below `_RESIDUAL_TOL`, or a step
    below `_STEP_TOL` and the residual below `_ACCEPT_TOL`, relative) within
    `WARM_MAX_STEPS` steps; the root must map back within `PIXEL_TOL` px and lie in the
    valid region (Jacobian determinant and radial factor > 0).

    Returns:
        (x, y, ok); ok False: not converged (the caller solves the corner from scratch).
    """
    scale = 1.0 + abs(xd) + abs(yd)
    res_tol = _RESIDUAL_TOL * scale
    acc_tol = _ACCEPT_TOL * scale
    small_step = False
    for it in range(WARM_MAX_STEPS + 1):
        gx, gy, a, b, d, radial = _distort_with_jacobian(x, y, k1, k2, p1, p2, k3, k4, k5, k6)
        ex = gx - xd
        ey = gy - yd
        err = ex * ex + ey * ey
        det = a * d - b * b
        if err <= res_tol * res_tol or (small_step and err <= acc_tol * acc_tol):
            eu = fx * ex + s * ey
            ev = fy * ey
            ok = (
                eu * eu + ev * ev <= PIXEL_TOL * PIXEL_TOL
                and det > 0.0
                and radial > 0.0
                and abs(x) + abs(y) < np.inf
            )
            return x, y, ok
        if it == WARM_MAX_STEPS or not (det > 0.0 and det < np.inf):
            break
        sx = (d * ex - b * ey) / det
        sy = (a * ey - b * ex) / det
        x -= sx
        y -= sy
        small_step = abs(sx) + abs(sy) <= _STEP_TOL * (1.0 + abs(x) + abs(y))
    return x, y, False


@numba.njit(cache=True, inline="always", error_model="numpy")
def _distort_with_jacobian(
    x: float,
    y: float,
    k1: float,
    k2: float,
    p1: float,
    p2: float,
    k3: float,
    k4: float,
    k5: float,
    k6: float,
) -> tuple[float, float, float, float, float, float]:
    """`distort_normalized` and `distortion_jacobian` at one point, with their arithmetic.

    Returns:
        (xd, yd, dxd_dx, dxd_dy, dyd_dy, c): dyd_dx = dxd_dy; c the radial factor.
    """
    x2 = x * x
    y2 = y * y
    xy = x * y
    r2 = x2 + y2
    num = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3))
    den = 1.0 + r2 * (k4 + r2 * (k5 + r2 * k6))
    c = num / den
    xd = x * c + 2.0 * p1 * xy + p2 * (r2 + 2.0 * x2)
    yd = y * c + p1 * (r2 + 2.0 * y2) + 2.0 * p2 * xy
    dnum = k1 + r2 * (2.0 * k2 + 3.0 * r2 * k3)
    dden = k4 + r2 * (2.0 * k5 + 3.0 * r2 * k6)
    dc = (dnum * den - num * dden) / (den * den)
    dxd_dx = c + 2.0 * x * x * dc + 2.0 * p1 * y + 6.0 * p2 * x
    dxd_dy = 2.0 * x * y * dc + 2.0 * p1 * x + 2.0 * p2 * y
    dyd_dy = c + 2.0 * y * y * dc + 6.0 * p1 * y + 2.0 * p2 * x
    return xd, yd, dxd_dx, dxd_dy, dyd_dy, c


def _camera_key(camera: Camera) -> bytes:
    """Everything a corner grid depends on: K, the distortion and the image size."""
    return (
        camera.K.tobytes()
        + camera.dist.tobytes()
        + bytes(f"{camera.width}x{camera.height}", "ascii")
    )


class CornerGridCache:
    """Undistorted corner grids per camera (a 24 MP camera's grid is built in ~0.13 s on
    2 cores with a realistic distortion, several seconds with `undistort_normalized` per
    corner before issue 12, and takes ~0.4 GB).

    Holds the `max_entries` most recently used grids; thread safe.
    """

    def __init__(self, max_entries: int = 2) -> None:
        self._entries: OrderedDict[bytes, CornerGrid] = OrderedDict()
        self._lock = Lock()
        self._max = max_entries

    @staticmethod
    def key(camera: Camera) -> bytes:
        """What a camera's grid depends on (K, the distortion, the image size): a key
        for caches of things made from the grid."""
        return _camera_key(camera)

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
