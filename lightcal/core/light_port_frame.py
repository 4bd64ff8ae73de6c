"""Whole frames of a rig with lights behind their flat ports, at the cost of air's.

Shading every pixel's footprint through a light's port (`render.render_image`'s exact
path for such a rig) solves five refracted paths a pixel: 45x the fused in-air kernel
on a 1200 x 800 frame. What a frame is for (the report's and the page's rendered-versus-
real overlays) needs the model's image, not its last bits. Here each ported light's
image is its *straight twin's* (the same light without its port, in the medium without
its scattering), rendered by the fused kernels (`kernels.image`, or `kernels.port_image`
through the camera's port), times the ratio

    r = (the pixel's exact shading through the light's port) / (the twin's),

plus the light's veil v (the exact shading in the medium minus the same without its
scattering). r and v are smooth across the image: r holds the port's bending of the
beam (the solid angles' ratio, the RID at the air direction against the straight one,
the Fresnel transmittance, the water path from the port's exit against the one from the
emitter), not the RID's own shape. Both are exact (`render.shade` of the node pixels'
footprints) on the nodes of `medium.scatter_grid` (every s-th row and column, s = min(H,
W) // 96) and bilinear between them (`kernels.node_image.add_on_nodes`). Where a node
cannot say (outside the frame's footprints, the twin below 1e-9 of its brightest node,
a node unlit through the port while its twin is lit) the pixels beside it are shaded
exactly. Measured against the exact frame in tests/test_light_port_frame.py.

The lights without a port are rendered together by the fused kernels, as in air.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numba
import numpy as np

from lightcal.core.camera import Camera
from lightcal.core.flat_port import FlatPort
from lightcal.core.footprint import Footprints, pixel_footprints
from lightcal.core.kernels.node_image import add_on_nodes, cubic_weights
from lightcal.core.medium import AIR, Medium
from lightcal.core.port_footprints import port_footprints
from lightcal.core.render import shade
from lightcal.core.scene import Light, Rig, View
from lightcal.core.wall import LAMBERTIAN

#: Nodes along the image's shorter side (every 16th pixel of an 800-pixel side).
NODES_PER_SIDE = 48

#: The error, relative to the ported light's own value, the cubics between the nodes
#: may make before the pixels beside a node are shaded exactly (`_rough`).
INTERPOLATION_TOLERANCE = 1e-6

#: A node whose twin is below this fraction of the twin's brightest node is shaded
#: exactly around (the ratio of two near-zero numbers says nothing).
TWIN_FLOOR = 1e-9


def render_frame_with_ported_lights(
    camera: Camera,
    view: View,
    rig: Rig,
    frame: Callable[[Rig, Medium, float], np.ma.MaskedArray],
    *,
    port: FlatPort | None = None,
    **options: Any,
) -> np.ma.MaskedArray:
    """The whole (binned) image of a rig of which some lights have a port (module
    docstring); `frame(rig, medium, offset)` renders a rig without ports by the fused
    kernels (through the camera's `port`, when given); `options` are
    `render.render_image`'s (sensor, vignetting, binning, offset, rid_subsamples, wall,
    medium). Returns (H // b, W // b), masked where invalid."""
    b = int(options.get("binning", 1))
    offset = float(options.get("offset", 0.0))
    medium: Medium = options.get("medium", AIR)
    shading = {
        "rid_subsamples": options.get("rid_subsamples", 1),
        "wall": options.get("wall", LAMBERTIAN),
    }
    sensor = {k: options[k] for k in ("sensor", "vignetting") if k in options}
    shape = (camera.height // b, camera.width // b)
    ported = [light for light in rig.lights if light.port is not None]
    plain = [light for light in rig.lights if light.port is None]
    if plain:
        total = np.ma.filled(frame(Rig(tuple(plain)), medium, offset), np.nan)
    else:
        total = np.full(shape, offset)
    clear = Medium(medium.attenuation_per_m, 0.0, medium.phase_g)
    rows, cols = node_grid(shape)
    row_stencil, col_stencil = cubic_weights(rows, shape[0]), cubic_weights(cols, shape[1])
    node_v, node_u = np.meshgrid(rows, cols, indexing="ij")
    nodes = np.stack([node_u.ravel(), node_v.ravel()], axis=1)

    def footprints(pixels: np.ndarray) -> Footprints:
        if port is None:
            return pixel_footprints(
                camera, view, pixels, binning=b, max_quads_per_side=None, **sensor
            )
        return port_footprints(
            camera, view, pixels, port, binning=b, max_quads_per_side=None, **sensor
        )

    def exact(fp: Footprints, light: Light, at: Medium) -> np.ndarray:
        values = shade(fp, view, Rig.single(light), medium=at, **shading).values
        return np.ma.filled(values, np.nan)

    base = total.copy()
    redo = np.zeros(shape, dtype=np.bool_)
    node_fp = footprints(nodes)
    for light in ported:
        twin = light.replace(port=None)
        straight = np.ma.filled(frame(Rig.single(twin), clear, 0.0), np.nan)
        v_port = exact(node_fp, light, clear)
        ratio = _node_ratio(v_port, exact(node_fp, twin, clear)).reshape(len(rows), len(cols))
        v_port = v_port.reshape(ratio.shape)
        ratio[_rough(ratio, rows, cols, np.abs(ratio))] = np.nan
        veil = np.zeros((0, 0))
        if medium.scatters:
            v_all = exact(node_fp, light, medium).reshape(ratio.shape)
            veil = v_all - v_port
            veil[_rough(veil, rows, cols, np.abs(v_all))] = np.nan
        with numba.parallel_chunksize(1):
            add_on_nodes(
                straight, ratio, veil, *row_stencil,
                *col_stencil, total, redo,
            )  # fmt: skip
    if redo.any():
        # The pixels the nodes cannot say: every ported light's exact shading.
        where = np.flatnonzero(redo.ravel())
        pixels = np.stack([where % shape[1], where // shape[1]], axis=1)
        again = base.ravel()[where]
        fp = footprints(pixels)
        for light in ported:
            again += exact(fp, light, medium)
        total.ravel()[where] = again
    return np.ma.masked_invalid(total, copy=False)


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


def _rough(grid: np.ndarray, rows: np.ndarray, cols: np.ndarray, scale: np.ndarray) -> np.ndarray:
    """(m, n) the nodes where the cubics between them may be off by more than
    INTERPOLATION_TOLERANCE x scale (m, n). A cubic through four nodes is off by
    |omega(x)| max|f^(4)| / 24 <= 0.5625 h^4 |f[x_k, ..., x_k+4]| (the fourth divided
    difference, h the nodes' spacing); this bound along the rows and along the columns,
    given to each of the difference's five nodes. Near a port's critical angle the ratio
    falls to 0 as a square root: there the pixels are shaded exactly."""
    rough = np.zeros(grid.shape, dtype=np.bool_)
    for axis, nodes in ((0, rows), (1, cols)):
        if len(nodes) < 5:
            continue
        x = nodes.astype(np.float64)
        along = np.moveaxis(grid, axis, 0)
        diff = along
        for order in range(1, 5):
            diff = (diff[1:] - diff[:-1]) / (x[order:] - x[:-order])[:, None]
        bound = 0.5625 * (((x[4:] - x[:-4]) / 4.0) ** 4)[:, None] * np.abs(diff)
        est = np.zeros(along.shape)
        for k in range(5):
            est[k : k + len(bound)] = np.fmax(est[k : k + len(bound)], bound)
        rough |= np.moveaxis(est, 0, axis) > INTERPOLATION_TOLERANCE * scale
    return rough


def _node_ratio(v_port: np.ndarray, v_twin: np.ndarray) -> np.ndarray:
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
