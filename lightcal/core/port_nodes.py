"""The node grid on which whole frames and dense selections lit through a light's port
are exact (`lightcal.core.light_port_frame`, `lightcal.core.light_port_dense`): where the
nodes are, the ratio of the port's flux to its straight twin's there, and which nodes
the cubics between them cannot be trusted from.
"""

from __future__ import annotations

import numpy as np

#: Nodes along the image's shorter side (every 16th pixel of an 800-pixel side).
NODES_PER_SIDE = 48

#: The error, relative to the ported light's own value, the cubics between the nodes
#: may make before the pixels beside a node are shaded exactly (`rough_nodes`).
INTERPOLATION_TOLERANCE = 1e-6

#: A node whose twin is below this fraction of the twin's brightest node is shaded
#: exactly around (the ratio of two near-zero numbers says nothing).
TWIN_FLOOR = 1e-9


def node_grid(shape: tuple[int, int]) -> tuple[np.ndarray, np.ndarray]:
    """The rows (m,) and columns (n,) of an (H, W) image where the ported lights' ratio
    and veil are exact: every s-th, s = max(1, min(H, W) // NODES_PER_SIDE), and the
    last; at least four of each (every pixel of an image smaller than 4 a side)."""
    h, w = shape
    step = max(1, min(h, w) // NODES_PER_SIDE)
    rows = np.unique(np.append(np.arange(0, h, step), h - 1)).astype(np.int64)
    cols = np.unique(np.append(np.arange(0, w, step), w - 1)).astype(np.int64)
    if len(rows) < 4 or len(cols) < 4:
        return np.arange(h, dtype=np.int64), np.arange(w, dtype=np.int64)
    return rows, cols


def rough_nodes(
    grid: np.ndarray, rows: np.ndarray, cols: np.ndarray, scale: np.ndarray
) -> np.ndarray:
    """(m, n) the nodes where the cubics between them may be off by more than
    INTERPOLATION_TOLERANCE x scale (m, n). A cubic through four nodes is off by
    |omega(x)| max|f^(4)| / 24, omega the product of x's distances to the four nodes: at
    most 0.5625 h^4 in a middle interval, 1.0 h^4 in the first or last (the stencil
    shifted inside); so by at most h^4 |f[x_k, ..., x_k+4]| (the fourth divided difference
    estimating f^(4) / 24, h the nodes' spacing), this bound taken along the rows and
    along the columns and given to each of the difference's five nodes. Near a port's
    critical angle the ratio falls to 0 as a square root: there the pixels are shaded
    exactly."""
    rough = np.zeros(grid.shape, dtype=np.bool_)
    for axis, nodes in ((0, rows), (1, cols)):
        if len(nodes) < 5:
            continue
        x = nodes.astype(np.float64)
        along = np.moveaxis(grid, axis, 0)
        diff = along
        for order in range(1, 5):
            diff = (diff[1:] - diff[:-1]) / (x[order:] - x[:-order])[:, None]
        bound = (((x[4:] - x[:-4]) / 4.0) ** 4)[:, None] * np.abs(diff)
        est = np.zeros(along.shape)
        for k in range(5):
            est[k : k + len(bound)] = np.fmax(est[k : k + len(bound)], bound)
        rough |= np.moveaxis(est, 0, axis) > INTERPOLATION_TOLERANCE * scale
    return rough


def node_ratio(v_port: np.ndarray, v_twin: np.ndarray) -> np.ndarray:
    """(N,) the nodes' ratio r = v_port / v_twin, NaN where it cannot be trusted: an
    invalid node, the twin below TWIN_FLOOR of its brightest node, or a node unlit
    through the port where the twin is lit (the port's shadow edge). 0 where both are 0
    (a light behind the wall, or beyond both beams)."""
    peak = np.nanmax(np.abs(v_twin)) if np.isfinite(v_twin).any() else 0.0
    ratio = np.full(v_twin.shape, np.nan)
    trusted = np.isfinite(v_port) & (v_twin > TWIN_FLOOR * peak) & (v_port > 0.0)
    ratio[trusted] = v_port[trusted] / v_twin[trusted]
    ratio[(v_port == 0.0) & (v_twin == 0.0)] = 0.0
    return ratio
