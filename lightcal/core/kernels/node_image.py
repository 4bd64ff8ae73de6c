"""`add_on_nodes`: a whole image's smooth factors, known on a grid of nodes, applied to
a frame in one parallel pass (`lightcal.core.light_port_frame`).

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


@numba.njit(cache=True, inline="always", error_model="numpy")
def _dot4(weights: np.ndarray, values: np.ndarray, first: int) -> float:
    """sum_a weights[a] values[first + a], a = 0..3."""
    return (
        weights[0] * values[first] + weights[1] * values[first + 1]
        + weights[2] * values[first + 2] + weights[3] * values[first + 3]
    )  # fmt: skip


@numba.njit(cache=True, parallel=True, error_model="numpy")
def add_on_nodes(
    frame: np.ndarray,
    ratio: np.ndarray,
    extra: np.ndarray,
    row_first: np.ndarray,
    row_weights: np.ndarray,
    col_first: np.ndarray,
    col_weights: np.ndarray,
    total: np.ndarray,
    redo: np.ndarray,
) -> None:
    """total += frame x r + e per pixel, r and e the cubics through the nodes' `ratio`
    and `extra` (the module's docstring); redo set (and total left) where one of a pixel's
    nodes is not finite.

    Args:
        frame: (H, W) the image the ratio scales (NaN where invalid: total becomes NaN).
        ratio: (m, n) r at the nodes; extra: (m, n) e at the nodes, or (0, 0) for none.
        row_first, row_weights: `cubic_weights` of the node rows (H,), (H, 4);
        col_first, col_weights: of the node columns (W,), (W, 4).
        total: (H, W) added to in place; redo: (H, W) set where the nodes cannot say.
    """
    h, w = frame.shape
    n = ratio.shape[1]
    has_extra = extra.shape[0] > 0
    for y in numba.prange(h):
        k = row_first[y]
        wy0, wy1, wy2, wy3 = (
            row_weights[y, 0],
            row_weights[y, 1],
            row_weights[y, 2],
            row_weights[y, 3],
        )
        r_row = np.empty(n)
        e_row = np.zeros(n)
        for j in range(n):
            r_row[j] = (
                wy0 * ratio[k, j] + wy1 * ratio[k + 1, j]
                + wy2 * ratio[k + 2, j] + wy3 * ratio[k + 3, j]
            )  # fmt: skip
            if has_extra:
                e_row[j] = (
                    wy0 * extra[k, j] + wy1 * extra[k + 1, j]
                    + wy2 * extra[k + 2, j] + wy3 * extra[k + 3, j]
                )  # fmt: skip
        for x in range(w):
            c = col_first[x]
            wx = col_weights[x]
            r = (
                wx[0] * r_row[c]
                + wx[1] * r_row[c + 1]
                + wx[2] * r_row[c + 2]
                + wx[3] * r_row[c + 3]
            )
            e = (
                wx[0] * e_row[c]
                + wx[1] * e_row[c + 1]
                + wx[2] * e_row[c + 2]
                + wx[3] * e_row[c + 3]
            )
            if math.isfinite(r) and math.isfinite(e):
                total[y, x] += frame[y, x] * r + e
            else:
                redo[y, x] = True
