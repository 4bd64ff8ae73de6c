"""Resampling a table RID on the uniform grids of `lightcal.core.rid_grid`, once per RID.

The nodes hold the exact table interpolation (`rid_eval.rid_value_grad` of kinds 3, 4)
and its exact derivatives (1-D) or central differences of it (2-D), so the grids'
cubic Hermite interpolation differs from the table only between nodes, the most where
the table's interpolant itself is not smooth (its knots, the pole of a 2-D table):

- `GRID_CELLS_1D` cells in s per hemisphere;
- `GRID_NODES_2D` x `GRID_NODES_2D` nodes in p = s (cos phi, sin phi) per hemisphere.

Beyond the last angle the nodes continue the table linearly in theta (C1 across it), so
the cells that straddle it interpolate the table; the evaluators set f = 0 there.

Accuracy against the exact interpolation: `tests/test_rid_grid.py` measures it on the
test tables (and `benchmarks/rid_grid.py` prints it); the sizes keep the value within
about 1e-6 of f(0) = 1 and move the solver's estimates by well under 1 % of their
standard deviations.
"""

from __future__ import annotations

import math

import numpy as np

from lightcal.core import rid_eval
from lightcal.core.rid_eval import RIDData

#: Cells of the 1-D grid in s = sin(theta / 2): 16 KB of nodes.
GRID_CELLS_1D = 512
#: Nodes per side of the 2-D grid in p: GRID_NODES_2D^2 x 4 values (2 MB at 257).
GRID_NODES_2D = 257

#: Steps of the central differences of the 2-D nodes' slopes and cross derivatives.
_FD_STEP = 1e-6
_FD_STEP_CROSS = 1e-4


_HALF = math.sqrt(0.5)


def _s_front(theta_rad: float) -> float:
    """sin(theta / 2), written as the evaluators compute s from uz = cos(theta)."""
    return math.sqrt(max(0.5 - 0.5 * math.cos(theta_rad), 0.0))


def _s_back(theta_rad: float) -> float:
    """cos(theta / 2) as the evaluators compute it at the back; 2 (nothing at the back)
    for theta <= pi / 2."""
    if theta_rad <= 0.5 * math.pi:
        return 2.0
    return math.sqrt(max(0.5 + 0.5 * math.cos(theta_rad), 0.0))


def _grid_params(table: RIDData, inv_h: float) -> np.ndarray:
    """The table's params with the grid's (1 / h, s_max, s_back) in entries 2, 3, 4."""
    theta_last = float(table.theta_knots[-1])
    params = np.zeros(5)
    params[:2] = table.params[:2]
    params[2:] = (inv_h, _s_front(theta_last), _s_back(theta_last))
    return params


_KIND_NAMES = {
    rid_eval.KIND_TABLE_1D: "a symmetric table RID",
    rid_eval.KIND_TABLE_2D: "a 2-D table RID",
}


def _check(
    table: RIDData, kind: int, n: int, n_min: int, n_name: str, unit: str
) -> tuple[float, float]:
    """(theta_last, R) of `table` after checking its kind and the grid size `n`."""
    if table.kind != kind:
        raise ValueError(
            f"table: expected {_KIND_NAMES[kind]} (kind {kind}), got kind {table.kind}"
        )
    if n < n_min:
        raise ValueError(f"{n_name}: expected at least {n_min} {unit}, got {n}")
    theta_last = float(table.theta_knots[-1])
    return theta_last, min(_s_front(theta_last), _HALF)


def _extended(
    theta_rad: np.ndarray, phi_rad: np.ndarray, table: RIDData
) -> tuple[np.ndarray, np.ndarray]:
    """The table's f and df/dtheta at (N,) directions, continued linearly in theta beyond
    its last angle."""
    theta_last = float(table.theta_knots[-1])
    f, f_t, _ = rid_eval.rid_eval_many(np.minimum(theta_rad, theta_last), phi_rad, table)
    return np.where(theta_rad > theta_last, f + f_t * (theta_rad - theta_last), f), f_t


def tabulate_1d(table: RIDData, n_cells: int = GRID_CELLS_1D) -> RIDData:
    """The `rid_eval.KIND_GRID_1D` record of a symmetric table (`KIND_TABLE_1D`).

    Nodes s_k = k R / n_cells in each hemisphere; f and df/ds = +-f_theta 2 / cos(theta
    / 2) (front) or / sin(theta / 2) (back), both >= sqrt(1 / 2): exact.
    """
    theta_last, radius = _check(table, rid_eval.KIND_TABLE_1D, n_cells, 2, "n_cells", "cells")
    s = radius * np.arange(n_cells + 1) / n_cells
    grid = np.zeros((2, n_cells + 1, 2))
    f, f_t = _extended(2.0 * np.arcsin(s), np.zeros_like(s), table)
    grid[0, :, 0] = f
    grid[0, :, 1] = 2.0 * f_t / np.sqrt(1.0 - s * s)
    grid[0, 0, 1] = 0.0
    if theta_last > 0.5 * math.pi:
        back = 2.0 * np.arccos(s)
        f, f_t = _extended(back, np.zeros_like(s), table)
        grid[1, :, 0] = f
        grid[1, :, 1] = -2.0 * f_t / np.sqrt(1.0 - s * s)
    params = _grid_params(table, n_cells / radius)
    return table._replace(kind=rid_eval.KIND_GRID_1D, params=params, grid=grid)


def _value_2d(px: np.ndarray, py: np.ndarray, table: RIDData, *, back: bool) -> np.ndarray:
    """The table (continued beyond its last angle) at (N,) points p of a hemisphere's map."""
    s = np.minimum(np.hypot(px, py), 1.0)
    theta = 2.0 * (np.arccos(s) if back else np.arcsin(s))
    return _extended(theta, np.arctan2(py, px), table)[0]


def tabulate_2d(table: RIDData, n_nodes: int = GRID_NODES_2D) -> RIDData:
    """The `rid_eval.KIND_GRID_2D` record of a 2-D table (`KIND_TABLE_2D`).

    Nodes p = -R + (i, j) h, h = 2 R / (n_nodes - 1), per hemisphere: f of the table,
    df/dpx and df/dpy by central differences (step 1e-6), d2f/dpx dpy (step 1e-4).
    """
    theta_last, radius = _check(
        table, rid_eval.KIND_TABLE_2D, n_nodes, 3, "n_nodes", "nodes per side"
    )
    h = 2.0 * radius / (n_nodes - 1)
    xs = -radius + h * np.arange(n_nodes)
    py, px = (a.ravel() for a in np.meshgrid(xs, xs, indexing="ij"))
    e = _FD_STEP
    c = min(_FD_STEP_CROSS, 0.1 * h)
    grid = np.zeros((2, n_nodes * n_nodes, 4))
    for hemi in (0, 1) if theta_last > 0.5 * math.pi else (0,):

        def value(dx: float, dy: float, back: bool = hemi == 1) -> np.ndarray:
            return _value_2d(px + dx, py + dy, table, back=back)

        out = grid[hemi]
        out[:, 0] = value(0.0, 0.0)
        out[:, 1] = (value(e, 0.0) - value(-e, 0.0)) / (2 * e)
        out[:, 2] = (value(0.0, e) - value(0.0, -e)) / (2 * e)
        out[:, 3] = (value(c, c) - value(-c, c) - value(c, -c) + value(-c, -c)) / (4 * c * c)
    # The axis: flat (every row's slope is 0 there), exactly.
    grid[0, (n_nodes * n_nodes) // 2, 1:3] = 0.0
    return table._replace(
        kind=rid_eval.KIND_GRID_2D,
        params=_grid_params(table, 1.0 / h),
        grid=grid.reshape(2 * n_nodes, n_nodes, 4),
    )
