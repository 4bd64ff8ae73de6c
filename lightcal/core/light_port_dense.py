"""A dense selection lit through a light's flat port, at about the cost of air's.

Every pixel's flux through the port is five refracted path solves (`light_port_flux`):
6x the in-air kernel's cost a pixel. On a dense selection of a view (its footprints on
the camera's corner grid, at least DENSE_PIXELS of them: the dense calibrations) the flux
is instead, as for whole frames (`lightcal.core.light_port_frame`), the straight twin's
(the same light without its port: the in-air kernels, the same medium) times the ratio

    r = Phi_port / Phi_twin,

exact on a node grid over the image (every s-th row and column, `port_nodes.node_grid`)
and the cubic through the four nearest nodes a side between them. The
gradients are those of this model, exactly: d(Phi_twin R) = R dPhi_twin + Phi_twin dR,
dR the same cubics of the nodes' dr = (dPhi_port - r dPhi_twin) / Phi_twin, for the
light's position and rotation and the medium's c (the cubics' weights depend on the
pixel, not on the pose). A node that cannot say (invalid, the twin
too dark, unlit through the port, or the cubic's error bound above 1e-6 of the value)
sends the pixels whose stencil holds it to the exact path (`port_nodes.node_ratio`,
`rough_nodes`).

Not here (the exact path): a whole image (`render.render_image`, what `lightcal synth`
renders with, keeps every pixel exact; frames take `light_port_frame`), a medium that
scatters (the veil), a selection with more than one quad a pixel (binning: the ratio
would weigh the quads by the node's weights).
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numba
import numpy as np

from lightcal.core.footprint import Footprints
from lightcal.core.kernels.node_image import along_row, cubic_lines, cubic_weights
from lightcal.core.medium import Medium
from lightcal.core.port_nodes import node_grid, node_ratio, rough_nodes
from lightcal.core.scene import Light, View

#: `render.light_flux` of some footprints and a light, into the given gradient buffers
#: (None: no gradients / no d/dc): (flux, grad).
ExactFlux = Callable[
    [Footprints, Light, np.ndarray | None, np.ndarray | None], tuple[np.ndarray, np.ndarray | None]
]

#: A view's selection takes the ratio path from this many pixels on (and on a grid).
DENSE_PIXELS = 50_000


def dense_applies(
    footprints: Footprints, medium: Medium, medium_grad_out: np.ndarray | None
) -> bool:
    """Whether `dense_port_flux` takes these footprints (module docstring)."""
    grid = footprints.grid
    return (
        grid is not None
        and grid.binning == 1
        and len(footprints) >= DENSE_PIXELS
        and footprints.image_shape is None  # a whole image (`render_image`) stays exact
        and footprints.normals_world is None
        and footprints.port_exits_world is None
        and not medium.scatters
        and (medium_grad_out is None or medium_grad_out.shape[1] == 1)
    )


def dense_port_flux(
    footprints: Footprints,
    view: View,
    light: Light,
    exact: ExactFlux,
    *,
    want_grad: bool,
    grad_out: np.ndarray | None,
    medium: Medium,
    medium_grad_out: np.ndarray | None,
) -> tuple[np.ndarray, np.ndarray | None]:
    """`render.light_flux` of a light behind its port on a dense selection (module
    docstring); `exact(footprints, light, grad_out, medium_grad_out)` is the exact
    `light_flux` (through the port, or in air for the twin) of other footprints."""
    grid = footprints.grid
    assert grid is not None and light.port is not None
    assert light.position_world(view)[2] > 0.0  # the caller's (`render.light_flux`)
    shape = (grid.grid_xy.shape[0] - 1, grid.grid_xy.shape[1] - 1)
    rows, cols = node_grid(shape)
    nv, nu = np.meshgrid(rows, cols, indexing="ij")
    nodes = np.stack([nu.ravel(), nv.ravel()], axis=1).astype(footprints.pixels.dtype)
    quads = grid.quads(nodes)
    node_fp = Footprints(
        pixels=nodes,
        stored_corners=quads,
        weights=np.ones((len(nodes), 1)),
        valid=np.isfinite(quads).reshape(len(nodes), -1).all(axis=1),
        area_m2=np.zeros(len(nodes)),
    )
    twin = light.replace(port=None)
    k = 7 if medium_grad_out is not None else 6
    n_nodes = len(nodes)
    g_port, g_twin = np.zeros((n_nodes, 6)), np.zeros((n_nodes, 6))
    c_port = np.zeros((n_nodes, 1)) if k == 7 else None
    c_twin = np.zeros((n_nodes, 1)) if k == 7 else None
    f_port, _ = exact(node_fp, light, g_port if want_grad else None, c_port)
    f_twin, _ = exact(node_fp, twin, g_twin if want_grad else None, c_twin)
    ratio = node_ratio(f_port, f_twin)
    d_ratio = np.zeros((n_nodes, k if want_grad else 0))
    if want_grad:
        with np.errstate(divide="ignore", invalid="ignore"):
            d_ratio[:, :6] = (g_port - ratio[:, None] * g_twin) / f_twin[:, None]
            if c_port is not None and c_twin is not None:
                d_ratio[:, 6] = (c_port[:, 0] - ratio * c_twin[:, 0]) / f_twin
    ratio = ratio.reshape(len(rows), len(cols))
    ratio[rough_nodes(ratio, rows, cols, np.abs(ratio))] = np.nan
    flux, grad = exact(footprints, twin, grad_out if want_grad else None, medium_grad_out)
    redo = np.zeros(len(footprints), dtype=np.bool_)
    no_c = np.zeros((0, 1))
    at_nodes = np.concatenate([ratio.reshape(-1, 1), d_ratio], axis=1)
    lines = cubic_lines(at_nodes.reshape(len(rows), len(cols), -1), *cubic_weights(rows, shape[0]))
    apply_ratio(
        np.ascontiguousarray(footprints.pixels, dtype=np.int64), footprints.valid, lines,
        *cubic_weights(cols, shape[1]), flux,
        grad if grad is not None else np.zeros((0, 6)),
        medium_grad_out if (want_grad and medium_grad_out is not None) else no_c, redo,
    )  # fmt: skip
    where = np.flatnonzero(redo)
    if len(where):
        sub = Footprints(
            pixels=footprints.pixels[where],
            stored_corners=grid.quads(footprints.pixels[where]),
            weights=footprints.weights[where],
            valid=footprints.valid[where],
            area_m2=footprints.area_m2[where],
        )
        g_sub = np.zeros((len(where), 6)) if want_grad else None
        c_sub = np.zeros((len(where), 1)) if (want_grad and medium_grad_out is not None) else None
        f_sub, _ = exact(sub, light, g_sub, c_sub)
        flux[where] = f_sub
        if grad is not None and g_sub is not None:
            grad[where] = g_sub
        if medium_grad_out is not None and c_sub is not None:
            medium_grad_out[where] = c_sub
    return flux, grad


@numba.njit(cache=True, parallel=True, error_model="numpy")
def apply_ratio(
    pixels: np.ndarray,
    valid: np.ndarray,
    lines: np.ndarray,
    col_first: np.ndarray,
    col_weights: np.ndarray,
    flux: np.ndarray,
    grad: np.ndarray,
    d_c: np.ndarray,
    redo: np.ndarray,
) -> None:
    """Per valid pixel (u, v): R and dR the cubics through the nodes' ratio, then its
    derivatives (`lines` (H, n, 1 + k): their `cubic_lines`; k = 0 without gradients, 6,
    or 7 with d/dc); grad <- R grad + flux dR[:6], d_c <- R d_c + flux dR[6], flux <- R
    flux, in place; redo set where a node of the pixel's stencil is not finite (outputs
    left)."""
    q = lines.shape[2]
    n = pixels.shape[0]
    n_chunks = min(n, 64)
    for ch in numba.prange(n_chunks):
        acc = np.empty(q)
        for i in range(ch * n // n_chunks, (ch + 1) * n // n_chunks):
            if not valid[i]:
                continue
            u, v = pixels[i, 0], pixels[i, 1]
            c0, wx = col_first[u], col_weights[u]
            finite = True
            for j in range(q):
                acc[j] = along_row(lines, v, c0, wx, j)
                finite = finite and math.isfinite(acc[j])
            if not finite:
                redo[i] = True
                continue
            r, f = acc[0], flux[i]
            for j in range(1, min(q, 7)):
                grad[i, j - 1] = r * grad[i, j - 1] + f * acc[j]
            if q == 8:
                d_c[i, 0] = r * d_c[i, 0] + f * acc[7]
            flux[i] = r * f
