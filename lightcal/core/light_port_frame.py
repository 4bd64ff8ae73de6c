"""Whole frames of a rig with lights behind their flat ports, at the cost of air's.

Shading every pixel's footprint through a light's port (`render.render_image`'s exact
path for such a rig) solves five refracted paths a pixel: 52x the fused in-air kernel
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
footprints through the light's port, over the twin frame's own value there, which is
`shade`'s to round-off) on the nodes of `port_nodes.node_grid` (every s-th row and column and the
last, s = min(H, W) // 48) and the tensor-product cubic between them
(`kernels.node_image`). Where a node cannot say (outside the frame's footprints, the
twin below 1e-9 of its brightest node, unlit through the port while its twin is lit, or
the cubic's error bound above 1e-6 of the value: `port_nodes.node_ratio`,
`rough_nodes`) the pixels whose stencil holds it are shaded exactly. Measured against
the exact frame in tests/test_light_port_frame.py.

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
from lightcal.core.kernels.node_image import add_on_nodes, cubic_lines, cubic_weights
from lightcal.core.medium import AIR, Medium
from lightcal.core.port_footprints import port_footprints
from lightcal.core.port_nodes import node_grid, node_ratio, rough_nodes
from lightcal.core.render import shade
from lightcal.core.scene import Light, Rig, View
from lightcal.core.wall import LAMBERTIAN


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
    # The lights without a port, by the fused kernels; the first ported light's twin
    # frame becomes the total when there are none.
    total = _nan_filled(frame(Rig(tuple(plain)), medium, offset)) if plain else None
    base = None if total is None else total.copy()  # what the redone pixels start from
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

    redo = np.zeros(shape, dtype=np.bool_)
    node_fp = footprints(nodes)
    for light in ported:
        twin = light.replace(port=None)
        straight = _nan_filled(frame(Rig.single(twin), clear, 0.0))
        v_port = exact(node_fp, light, clear).reshape(len(rows), len(cols))
        # The twin at the nodes is its frame's value there (the fused kernels' numbers
        # are `shade`'s to round-off): the product is the port's exact value there.
        ratio = node_ratio(v_port, straight[np.ix_(rows, cols)])
        ratio[rough_nodes(ratio, rows, cols, np.abs(ratio))] = np.nan
        at_nodes = ratio[:, :, None]  # no veil without scattering
        if medium.scatters:
            v_all = exact(node_fp, light, medium).reshape(ratio.shape)
            veil = v_all - v_port
            veil[rough_nodes(veil, rows, cols, np.abs(v_all))] = np.nan
            at_nodes = np.stack([ratio, veil], axis=2)
        first = total is None
        total = straight if total is None else total  # the twin's frame, scaled in place
        with numba.parallel_chunksize(1):
            lines = cubic_lines(at_nodes, *row_stencil)
            add_on_nodes(straight, lines, *col_stencil, offset, not first, total, redo)
    assert total is not None  # the rig has a ported light
    if redo.any():
        # The pixels the nodes cannot say: every ported light's exact shading.
        where = np.flatnonzero(redo.ravel())
        pixels = np.stack([where % shape[1], where // shape[1]], axis=1)
        again = np.full(len(where), offset) if base is None else base.ravel()[where]
        fp = footprints(pixels)
        for light in ported:
            again += exact(fp, light, medium)
        total.ravel()[where] = again
    return np.ma.masked_array(total, mask=~np.isfinite(total), copy=False)


def _nan_filled(image: np.ma.MaskedArray) -> np.ndarray:
    """The image's values with NaN where masked: its own data when they hold NaN there
    already (the fused kernels write NaN at invalid pixels), else a filled copy."""
    data = np.ma.getdata(image)
    mask = np.ma.getmask(image)
    if mask is np.ma.nomask or not mask.any() or np.isnan(data[mask]).all():
        return data
    return np.ma.filled(image, np.nan)
