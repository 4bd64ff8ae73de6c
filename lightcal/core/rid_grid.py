"""Table RIDs resampled on uniform grids, evaluated from the direction without angles.

A table RID (`rid_eval.KIND_TABLE_1D`, `KIND_TABLE_2D`) is interpolated exactly by
`rid_eval.rid_value_grad` in (theta, phi): per direction two atan2 and a knot search.
The renderer's fast paths evaluate it instead from grids that `rid_tabulate` fills once
(the RID's first `data()` call), in coordinates that are a polynomial in the unit direction
u = (ux, uy, uz) of the light frame and a square root. Each hemisphere has its own grid,
centred on its pole so that the coordinate is smooth there (a map centred on the axis
stretches theta without bound near theta = pi):

- front (uz >= 0): s = sin(theta / 2) = sqrt((1 - uz) / 2);
- back (uz < 0): s = cos(theta / 2) = sqrt((1 + uz) / 2), from the backward pole;

both on [0, R], R = min(sin(theta_last / 2), sqrt(1 / 2)).

- symmetric (1-D) tables, `KIND_GRID_1D`: n equal cells in s; per node the value f and
  df/ds; cubic Hermite in s. grid: (2, n + 1, 2), [hemisphere, node, (f, df/ds)].
- 2-D tables, `KIND_GRID_2D`: p = (ux, uy) / sqrt(2 (1 -+ uz)) = s (cos phi, sin phi),
  Lambert's azimuthal equal-area map about the hemisphere's pole, on the square
  [-R, R]^2 with n x n nodes; per node f, df/dpx, df/dpy and d2f/dpx dpy; bicubic
  Hermite. grid: (2 n, n, 4): rows [0, n) the front, [n, 2 n) the back, each indexed
  [row (py), column (px)].

f is 0 beyond the table's last angle theta_last, as for the table: in front where
s > s_max = sin(theta_last / 2), at the back where s < s_back = cos(theta_last / 2) (2
when theta_last <= pi / 2: the whole back hemisphere). Both evaluators return f and its
tangential gradient with respect to u (perpendicular to u), the derivative of the
interpolant itself, so finite differences of f agree with it. `rid_eval` dispatches the
two kinds. The kernels split each evaluation in two, so that the square roots and
divisions vectorise: the grid coordinate of every pixel first (`grid1d_coord`,
`grid2d_coords`: no memory reads), then the interpolation, whose reads are gathers, in a
scalar pass (`grid1d_interp`, `grid2d_interp`), then for 2-D tables the gradient
(`grid2d_gradient`). A full image row of a 2-D table takes `grid2d_values_row`: runs of
pixels in one cell, each evaluated from the cell's power-basis coefficients in a loop
that vectorises. Grid sizes and the accuracy against the exact table: `rid_tabulate`.
"""

from __future__ import annotations

import math

import numba
import numpy as np


@numba.njit(cache=True, inline="always", error_model="numpy")
def grid1d_coord(uz: float, n: int, inv_h: float, s_max: float, s_back: float) -> float:
    """The symmetric grids' coordinate of a unit direction with z = uz.

    Args:
        uz: cos(theta), in [-1, 1].
        n: cells per hemisphere; inv_h: n / R; s_max, s_back: the last angle's s in front
            and at the back.

    Returns:
        x = s inv_h in [0, n] in front, n + 1 + s inv_h at the back; -1 beyond the last
        angle, NaN at NaN.
    """
    back = uz < 0.0
    s = math.sqrt(max(0.5 + 0.5 * uz if back else 0.5 - 0.5 * uz, 0.0))
    inside = (s >= s_back) if back else (s <= s_max)  # False for NaN
    x = min(s * inv_h, float(n))
    x = x + (n + 1) if back else x
    return x if inside else (uz if uz != uz else -1.0)


@numba.njit(cache=True, inline="always", error_model="numpy")
def grid1d_interp(x: float, grid: np.ndarray, inv_h: float) -> tuple[float, float]:
    """Value f and df/duz of a symmetric table's grids at coordinate x (`grid1d_coord`).

    df/duz = -+(df/ds) / (4 s) (front, back); in the front's first cell, where df/ds = 0
    at s = 0, it is written with s divided out, so it is finite on the axis.

    Args:
        grid: (2, n + 1, >= 2) nodes: [hemisphere, k, 0] = f(s_k), [hemisphere, k, 1] =
            df/ds(s_k), s_k = k / inv_h.

    Returns:
        (f, df/duz): (0, 0) at x = -1 (beyond the last angle), NaN at NaN.
    """
    n = grid.shape[1] - 1
    ok = x >= 0.0  # False for NaN
    back = x > n + 0.5
    xl = (x - (n + 1) if back else x) if ok else 0.0
    lo = min(int(xl), n - 1)
    hemi = 1 if back else 0
    t = xl - lo
    v0 = grid[hemi, lo, 0]
    m0 = grid[hemi, lo, 1] / inv_h
    v1 = grid[hemi, lo + 1, 0]
    m1 = grid[hemi, lo + 1, 1] / inv_h
    t2 = t * t
    t3 = t2 * t
    f = (
        (2 * t3 - 3 * t2 + 1) * v0
        + (t3 - 2 * t2 + t) * m0
        + (-2 * t3 + 3 * t2) * v1
        + (t3 - t2) * m1
    )
    if lo == 0 and not back:
        # m0 = 0: d f / d s = t ((6 t - 6) (v0 - v1) + (3 t - 2) m1) / h, and s = t h.
        g = -0.25 * ((6 * t - 6) * (v0 - v1) + (3 * t - 2) * m1) * (inv_h * inv_h)
    else:
        dfds = (
            (6 * t2 - 6 * t) * (v0 - v1) + (3 * t2 - 4 * t + 1) * m0 + (3 * t2 - 2 * t) * m1
        ) * inv_h
        s = max(xl / inv_h, 1e-300)
        g = 0.25 * dfds / s if back else -0.25 * dfds / s
    if not ok:
        f = x if x != x else 0.0
        g = f
    return f, g


@numba.njit(cache=True, inline="always", error_model="numpy")
def grid1d_value_grad(
    uz: float, grid: np.ndarray, inv_h: float, s_max: float, s_back: float
) -> tuple[float, float]:
    """Value f and df/duz of a symmetric table's grids at a unit direction with z = uz
    (`grid1d_coord`, then `grid1d_interp`). The tangential gradient with respect to u is
    df/duz (e_z - uz u).

    Args:
        uz: cos(theta), in [-1, 1].
        grid: (2, n + 1, >= 2) nodes (`grid1d_interp`).
        inv_h: n / R; s_max, s_back: the last angle's s in front and at the back.

    Returns:
        (f, df/duz): (0, 0) beyond the last angle, NaN at NaN.
    """
    x = grid1d_coord(uz, grid.shape[1] - 1, inv_h, s_max, s_back)
    return grid1d_interp(x, grid, inv_h)


@numba.njit(cache=True, inline="always", error_model="numpy")
def _map_scale(uz: float) -> float:
    """k with p = k (ux, uy): 1 / sqrt(2 (1 + uz)) in front, 1 / sqrt(2 (1 - uz)) at the back."""
    return 1.0 / math.sqrt(max(2.0 - 2.0 * uz if uz < 0.0 else 2.0 + 2.0 * uz, 1e-300))


@numba.njit(cache=True, inline="always", error_model="numpy")
def grid2d_coords(
    ux: float, uy: float, uz: float, n: int, inv_h: float, s_max: float, s_back: float
) -> tuple[float, float]:
    """The 2-D grids' coordinates (column x, row y) of a unit direction.

    Args:
        ux, uy, uz: unit direction from the light, light frame.
        n: nodes per side; inv_h: (n - 1) / (2 R); s_max, s_back: the last angle's s in
            front and at the back.

    Returns:
        (x, y): x in [0, n - 1]; y in [0, n - 1] in front, n + y at the back; x = -1
        beyond the last angle, NaN at NaN.
    """
    back = uz < 0.0
    s = math.sqrt(max(0.5 + 0.5 * uz if back else 0.5 - 0.5 * uz, 0.0))
    inside = (s >= s_back) if back else (s <= s_max)  # False for NaN
    k = _map_scale(uz)
    c = 0.5 * (n - 1)
    x = min(max(ux * k * inv_h + c, 0.0), n - 1.0)
    y = min(max(uy * k * inv_h + c, 0.0), n - 1.0)
    return (x if inside else (uz if uz != uz else -1.0)), (y + n if back else y)


@numba.njit(cache=True, inline="always", error_model="numpy")
def grid2d_interp(x: float, y: float, grid: np.ndarray, inv_h: float) -> tuple[float, float, float]:
    """f, df/dpx and df/dpy of a 2-D table's grids at coordinates (x, y) (`grid2d_coords`).

    Args:
        grid: (2 n, n, >= 4) nodes at p = (column, row mod n) / inv_h - R: f, df/dpx,
            df/dpy, d2f/dpx dpy.

    Returns:
        (f, df/dpx, df/dpy): zeros at x = -1 (beyond the last angle), NaN at NaN.
    """
    n = grid.shape[1]
    ok = x >= 0.0  # False for NaN
    back = y > n - 0.5
    xl = x if ok else 0.0
    yl = (y - n if back else y) if ok else 0.0
    ix = min(int(xl), n - 2)
    iy = min(int(yl), n - 2)
    t = xl - ix
    w = yl - iy
    iy += n if back else 0
    h = 1.0 / inv_h
    t2 = t * t
    t3 = t2 * t
    # Hermite basis in x (a0, a1 for the values, b0, b1 for the slopes times h) and its
    # derivative in t.
    a0 = 2 * t3 - 3 * t2 + 1
    a1 = -2 * t3 + 3 * t2
    b0 = (t3 - 2 * t2 + t) * h
    b1 = (t3 - t2) * h
    da0 = 6 * t2 - 6 * t
    db0 = (3 * t2 - 4 * t + 1) * h
    db1 = (3 * t2 - 2 * t) * h
    # Rows iy and iy + 1: r (value along x), q (its y-slope times h), and their t-derivatives.
    r0 = q0 = dr0 = dq0 = r1 = q1 = dr1 = dq1 = 0.0
    for j in range(2):  # scalars, no views: this runs once per pixel
        row = iy + j
        f0 = grid[row, ix, 0]
        fx0 = grid[row, ix, 1]
        fy0 = grid[row, ix, 2]
        fxy0 = grid[row, ix, 3]
        f1 = grid[row, ix + 1, 0]
        fx1 = grid[row, ix + 1, 1]
        fy1 = grid[row, ix + 1, 2]
        fxy1 = grid[row, ix + 1, 3]
        r = a0 * f0 + b0 * fx0 + a1 * f1 + b1 * fx1
        dr = da0 * (f0 - f1) + db0 * fx0 + db1 * fx1
        q = (a0 * fy0 + b0 * fxy0 + a1 * fy1 + b1 * fxy1) * h
        dq = (da0 * (fy0 - fy1) + db0 * fxy0 + db1 * fxy1) * h
        if j == 0:
            r0, q0, dr0, dq0 = r, q, dr, dq
        else:
            r1, q1, dr1, dq1 = r, q, dr, dq
    w2 = w * w
    w3 = w2 * w
    e0 = 2 * w3 - 3 * w2 + 1
    e1 = -2 * w3 + 3 * w2
    g0 = w3 - 2 * w2 + w
    g1 = w3 - w2
    f = e0 * r0 + g0 * q0 + e1 * r1 + g1 * q1
    fx = (e0 * dr0 + g0 * dq0 + e1 * dr1 + g1 * dq1) * inv_h
    fy = ((6 * w2 - 6 * w) * (r0 - r1) + (3 * w2 - 4 * w + 1) * q0 + (3 * w2 - 2 * w) * q1) * inv_h
    if not ok:
        f = x if x != x else 0.0
        fx = fy = f
    return f, fx, fy


@numba.njit(cache=True, inline="always", error_model="numpy")
def grid2d_gradient(
    fx: float, fy: float, ux: float, uy: float, uz: float
) -> tuple[float, float, float]:
    """The tangential gradient with respect to the unit direction u of f(p(u)), from
    df/dpx and df/dpy: dpx = k dux -+ ux k^3 duz, dpy = k duy -+ uy k^3 duz (front,
    back), then the part perpendicular to u."""
    k = _map_scale(uz)
    gx = fx * k
    gy = fy * k
    gz = (fx * ux + fy * uy) * (k * k * k)
    gz = gz if uz < 0.0 else -gz
    gu = gx * ux + gy * uy + gz * uz
    return gx - gu * ux, gy - gu * uy, gz - gu * uz


@numba.njit(cache=True, inline="always", error_model="numpy")
def grid2d_value_grad(
    ux: float, uy: float, uz: float, grid: np.ndarray, inv_h: float, s_max: float, s_back: float
) -> tuple[float, float, float, float]:
    """Value f and tangential gradient of a 2-D table's equal-area grids at a unit
    direction (`grid2d_coords`, `grid2d_interp`, `grid2d_gradient`).

    Args:
        ux, uy, uz: unit direction from the light, light frame.
        grid: (2 n, n, >= 4) nodes (`grid2d_interp`).
        inv_h: (n - 1) / (2 R); s_max, s_back: the last angle's s in front and at the back.

    Returns:
        (f, gx, gy, gz), the gradient perpendicular to u; zeros beyond the last angle,
        NaN at NaN.
    """
    x, y = grid2d_coords(ux, uy, uz, grid.shape[1], inv_h, s_max, s_back)
    f, fx, fy = grid2d_interp(x, y, grid, inv_h)
    gx, gy, gz = grid2d_gradient(fx, fy, ux, uy, uz)
    return f, gx, gy, gz


@numba.njit(cache=True, inline="always", error_model="numpy")
def _hermite_powers(
    p0: float, p1: float, m0: float, m1: float
) -> tuple[float, float, float, float]:
    """The cubic Hermite segment on [0, 1] with values p0, p1 and slopes m0, m1, as its
    coefficients of 1, t, t^2, t^3."""
    return p0, m0, 3.0 * (p1 - p0) - 2.0 * m0 - m1, 2.0 * (p0 - p1) + m0 + m1


@numba.njit(cache=True, inline="always", error_model="numpy")
def grid2d_cell(x: float, y: float, n: int) -> float:
    """The grid cell of coordinates (x, y) (`grid2d_coords`) as one number, ix + n row
    (row: the node row, the back hemisphere's from n on); x itself (-1 or NaN) beyond
    the last angle or at NaN. Branch-free, for the coordinate loops: `grid2d_values_row`
    then finds a run of pixels in one cell by comparing these numbers alone."""
    ok = x >= 0.0  # False for NaN
    back = y > n - 0.5
    y_off = float(n) if back else 0.0
    ix = min(int(x if ok else 0.0), n - 2)
    iy = min(int((y - y_off) if ok else 0.0), n - 2)
    return float(ix + n * (iy + (n if back else 0))) if ok else x


@numba.njit(cache=True, inline="always", error_model="numpy")
def grid2d_values_row(
    xs: np.ndarray, ys: np.ndarray, cells: np.ndarray, grid: np.ndarray, inv_h: float
) -> None:
    """f of a 2-D table's grids at coordinates (xs, ys) (`grid2d_coords`), written over xs:
    the value of `grid2d_interp`, without its derivatives, for a row of pixels.

    Neighbouring pixels of an image row fall in the same grid cell for runs of tens to
    hundreds: per run, the cell's bicubic Hermite patch is turned into its 16 power-basis
    coefficients once, and the run is evaluated by Horner's rule with those constants, a
    loop without gathers that LLVM vectorises (the per-pixel interpolation gathers 16
    node values and spends about 40 products on each pixel). A run ends where the cell
    number (`grid2d_cell`, computed with the coordinates) changes. Equal to
    `grid2d_interp`'s value to rounding.

    Args:
        xs, ys: (w,) grid coordinates; xs is overwritten with f (0 beyond the last angle,
            NaN at NaN).
        cells: (w,) `grid2d_cell` of each pixel.
        grid, inv_h: as `grid2d_interp`.
    """
    n = grid.shape[1]
    h = 1.0 / inv_h
    w = xs.shape[0]
    u = 0
    while u < w:
        cell = cells[u]
        if not cell >= 0.0:  # beyond the last angle, or NaN
            xs[u] = cell if cell != cell else 0.0
            u += 1
            continue
        end = u + 1
        while end < w and cells[end] == cell:
            end += 1
        back = ys[u] > n - 0.5
        y_off = float(n) if back else 0.0
        ix = min(int(xs[u]), n - 2)
        iy = min(int(ys[u] - y_off), n - 2)
        row = iy + (n if back else 0)
        # Rows of nodes 0 and 1: r_j(t) (values) and q_j(t) (y-slopes times h) in powers
        # of t, Hermite with the x-slopes (times h) and the cross slopes (times h^2).
        r00, r01, r02, r03 = _hermite_powers(
            grid[row, ix, 0], grid[row, ix + 1, 0], grid[row, ix, 1] * h, grid[row, ix + 1, 1] * h
        )
        q00, q01, q02, q03 = _hermite_powers(
            grid[row, ix, 2] * h,
            grid[row, ix + 1, 2] * h,
            grid[row, ix, 3] * (h * h),
            grid[row, ix + 1, 3] * (h * h),
        )
        r10, r11, r12, r13 = _hermite_powers(
            grid[row + 1, ix, 0],
            grid[row + 1, ix + 1, 0],
            grid[row + 1, ix, 1] * h,
            grid[row + 1, ix + 1, 1] * h,
        )
        q10, q11, q12, q13 = _hermite_powers(
            grid[row + 1, ix, 2] * h,
            grid[row + 1, ix + 1, 2] * h,
            grid[row + 1, ix, 3] * (h * h),
            grid[row + 1, ix + 1, 3] * (h * h),
        )
        # In w: Hermite between r0 and r1 with slopes q0 and q1; d_k: the t-polynomial
        # multiplying w^k.
        d00, d10, d20, d30 = _hermite_powers(r00, r10, q00, q10)
        d01, d11, d21, d31 = _hermite_powers(r01, r11, q01, q11)
        d02, d12, d22, d32 = _hermite_powers(r02, r12, q02, q12)
        d03, d13, d23, d33 = _hermite_powers(r03, r13, q03, q13)
        fx_ = float(ix)
        fy_ = float(iy) + y_off
        # Views of the run indexed from 0: indices LLVM knows are not negative, so no
        # wrap-around test per element, and the loop vectorises.
        x_run = xs[u:end]
        y_run = ys[u:end]
        for k in range(x_run.shape[0]):
            t = x_run[k] - fx_
            s = y_run[k] - fy_
            e0 = ((d03 * t + d02) * t + d01) * t + d00
            e1 = ((d13 * t + d12) * t + d11) * t + d10
            e2 = ((d23 * t + d22) * t + d21) * t + d20
            e3 = ((d33 * t + d32) * t + d31) * t + d30
            x_run[k] = ((e3 * s + e2) * s + e1) * s + e0
        u = end
