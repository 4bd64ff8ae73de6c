"""Smooth factors known on a grid of nodes, between the nodes: `cubic_lines` and
`along_row` (the tensor-product cubic in two passes), `add_on_nodes` (a whole frame
scaled and added to: `lightcal.core.light_port_frame`; the dense selections' use is
`light_port_dense.apply_ratio`).

Between the nodes each factor is the cubic through the four nearest nodes in each
direction (Lagrange, tensor product: `cubic_weights` per row and per column, shifted
inside at the image's borders), exact at the nodes, with an error of the order of
h^4 f'''' for nodes h apart. A pixel whose sixteen nodes include one whose factor is not
finite (NaN: the caller could not trust it there) is flagged for the caller to compute
exactly.
"""

from __future__ import annotations

import math

import numba
import numpy as np


def cubic_weights(nodes: np.ndarray, size: int) -> tuple[np.ndarray, np.ndarray]:
    """For each of `size` pixels along an axis, the first of its four nodes (size,) and
    their Lagrange weights (size, 4): the stencil of the interval holding the pixel, one
    node before and two after, shifted inside at the ends; `nodes` (m >= 4,) increasing,
    the first 0 and the last size - 1."""
    m = len(nodes)
    x = np.arange(size, dtype=np.float64)
    k = np.clip(np.searchsorted(nodes, x, side="right") - 2, 0, m - 4)
    stencil = nodes[k[:, None] + np.arange(4)[None, :]].astype(np.float64)
    weights = np.ones((size, 4))
    for a in range(4):
        for b in range(4):
            if a != b:
                weights[:, a] *= (x - stencil[:, b]) / (stencil[:, a] - stencil[:, b])
    return k.astype(np.int64), weights


@numba.njit(cache=True, parallel=True, error_model="numpy")
def cubic_lines(at_nodes: np.ndarray, row_first: np.ndarray, row_weights: np.ndarray) -> np.ndarray:
    """(H, n, q) the cubics through the nodes' values at_nodes (m, n, q) along the node
    columns, at every image row: the first half of the tensor-product cubic
    (`cubic_weights` of the node rows: row_first (H,), row_weights (H, 4))."""
    h = row_first.shape[0]
    n, q = at_nodes.shape[1], at_nodes.shape[2]
    lines = np.empty((h, n, q))
    for v in numba.prange(h):
        r0 = row_first[v]
        for c in range(n):
            for j in range(q):
                lines[v, c, j] = (
                    row_weights[v, 0] * at_nodes[r0, c, j]
                    + row_weights[v, 1] * at_nodes[r0 + 1, c, j]
                    + row_weights[v, 2] * at_nodes[r0 + 2, c, j]
                    + row_weights[v, 3] * at_nodes[r0 + 3, c, j]
                )  # fmt: skip
    return lines


@numba.njit(cache=True, inline="always", error_model="numpy")
def along_row(lines: np.ndarray, v: int, first: int, weights: np.ndarray, j: int) -> float:
    """The second half: the cubic through lines[v, first..first + 3, j] with the
    column's `cubic_weights` (4,)."""
    return (
        weights[0] * lines[v, first, j] + weights[1] * lines[v, first + 1, j]
        + weights[2] * lines[v, first + 2, j] + weights[3] * lines[v, first + 3, j]
    )  # fmt: skip


@numba.njit(cache=True, parallel=True, error_model="numpy")
def add_on_nodes(
    frame: np.ndarray,
    lines: np.ndarray,
    col_first: np.ndarray,
    col_weights: np.ndarray,
    base: float,
    accumulate: bool,
    total: np.ndarray,
    redo: np.ndarray,
) -> None:
    """total = (total if accumulate else base) + frame x r + e per pixel, r and e the
    cubics through the nodes' ratio and extra term (the module's docstring; `lines`:
    their `cubic_lines`); redo set where one of a pixel's nodes is not finite (and
    total there set to base, or left when accumulating).

    Args:
        frame: (H, W) the image the ratio scales (NaN where invalid: total becomes NaN);
            it may be `total` itself when not accumulating.
        lines: (H, n, 2) `cubic_lines` of the nodes' r and e (m, n, 2), or (H, n, 1) of
            r alone.
        col_first, col_weights: `cubic_weights` of the node columns (W,), (W, 4).
        base: what total starts from when not accumulating.
        total: (H, W) written or added to in place; redo: (H, W) set where the nodes
            cannot say.
    """
    h, w = frame.shape
    extra = lines.shape[2] > 1
    for y in numba.prange(h):
        for x in range(w):
            c = col_first[x]
            w0, w1, w2, w3 = (
                col_weights[x, 0],
                col_weights[x, 1],
                col_weights[x, 2],
                col_weights[x, 3],
            )
            r = (
                w0 * lines[y, c, 0]
                + w1 * lines[y, c + 1, 0]
                + w2 * lines[y, c + 2, 0]
                + w3 * lines[y, c + 3, 0]
            )
            e = 0.0
            if extra:
                e = (
                    w0 * lines[y, c, 1]
                    + w1 * lines[y, c + 1, 1]
                    + w2 * lines[y, c + 2, 1]
                    + w3 * lines[y, c + 3, 1]
                )
            start = total[y, x] if accumulate else base
            if math.isfinite(r) and math.isfinite(e):
                total[y, x] = start + (frame[y, x] * r + e)
            else:
                total[y, x] = start
                redo[y, x] = True
