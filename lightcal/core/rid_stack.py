"""The RIDs of several lights as one record for the fused image kernel.

`stack_rid_data` pads the `RIDData` of L lights into one `RIDStack`; `light_rid` takes
one light's `RIDData` back out of it inside a kernel (views, no copy).
"""

from __future__ import annotations

from typing import NamedTuple

import numba
import numpy as np

from lightcal.core.rid_eval import RIDData


class RIDStack(NamedTuple):
    """The `RIDData` of L lights padded into arrays (`stack_rid_data`), one record.

    Light l uses theta_knots[l, :n_theta[l]], phi_knots[l, :n_phi[l]] and
    values[l, :n_phi[l], :n_theta[l]], grid[l, :n_grid[l, 0], :n_grid[l, 1]] (`light_rid`).

    Attributes:
        kind: (L,) int64; params: (L, 4); theta_knots: (L, NT); n_theta: (L,) int64;
        phi_knots: (L, NP); n_phi: (L,) int64; values, slopes: (L, NP, NT);
        grid: (L, GA, GB, GC); n_grid: (L, 2) int64.
    """

    kind: np.ndarray
    params: np.ndarray
    theta_knots: np.ndarray
    n_theta: np.ndarray
    phi_knots: np.ndarray
    n_phi: np.ndarray
    values: np.ndarray
    slopes: np.ndarray
    grid: np.ndarray
    n_grid: np.ndarray


def stack_rid_data(rids: list[RIDData]) -> RIDStack:
    """Stack the `RIDData` of L lights into padded arrays (for `kernels.image`)."""
    n_l = len(rids)
    nt = max([1, *(d.theta_knots.shape[0] for d in rids)])
    n_p = max([1, *(d.phi_knots.shape[0] for d in rids)])
    kind = np.array([d.kind for d in rids], dtype=np.int64)
    params = np.zeros((n_l, max([1, *(d.params.shape[0] for d in rids)])))
    g_shape = np.max([d.grid.shape for d in rids], axis=0) if rids else np.ones(3, np.int64)
    grid = np.zeros((n_l, *(int(g) for g in g_shape)))
    n_grid = np.zeros((n_l, 2), dtype=np.int64)
    theta = np.zeros((n_l, nt))
    phi = np.zeros((n_l, n_p))
    values = np.zeros((n_l, n_p, nt))
    slopes = np.zeros((n_l, n_p, nt))
    n_theta = np.zeros(n_l, dtype=np.int64)
    n_phi = np.zeros(n_l, dtype=np.int64)
    for i, d in enumerate(rids):
        k_t = d.theta_knots.shape[0]
        k_p = d.phi_knots.shape[0]
        params[i, : d.params.shape[0]] = d.params
        theta[i, :k_t] = d.theta_knots
        phi[i, :k_p] = d.phi_knots
        values[i, :k_p, :k_t] = d.values
        slopes[i, :k_p, :k_t] = d.slopes
        n_theta[i] = k_t
        n_phi[i] = k_p
        a, b, c = d.grid.shape
        grid[i, :a, :b, :c] = d.grid
        n_grid[i] = (a, b)
    return RIDStack(kind, params, theta, n_theta, phi, n_phi, values, slopes, grid, n_grid)


@numba.njit(cache=True, inline="always")
def light_rid(stack: RIDStack, li: int) -> RIDData:
    """The `RIDData` of light li of a `RIDStack` (views of its arrays)."""
    nt = stack.n_theta[li]
    n_p = stack.n_phi[li]
    return RIDData(
        stack.kind[li],
        stack.params[li],
        stack.theta_knots[li, :nt],
        stack.phi_knots[li, :n_p],
        stack.values[li, :n_p, :nt],
        stack.slopes[li, :n_p, :nt],
        stack.grid[li, : stack.n_grid[li, 0], : stack.n_grid[li, 1]],
    )
