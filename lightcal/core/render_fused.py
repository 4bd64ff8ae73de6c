"""The whole-image renderer's fused passes (`lightcal.core.render.render_image`).

`render_fused` runs the fused kernel (`kernels.image.render_image_fused`) over lights on
the plane z = 0; `render_in_medium` does so light by light, each times its transmittance
at the footprint centres, and adds each light's backscatter.
"""

from __future__ import annotations

import numba
import numpy as np

from lightcal.core.camera import Camera
from lightcal.core.corner_grid import GRID_CACHE
from lightcal.core.footprint import SENSOR_CODES, SensorModel
from lightcal.core.kernels.backscatter import add_scatter_image
from lightcal.core.kernels.image import render_image_fused
from lightcal.core.kernels.medium import attenuate_image
from lightcal.core.medium import Medium, scatter_grid, scatter_nodes
from lightcal.core.rid_stack import stack_rid_data
from lightcal.core.scene import Light, View
from lightcal.core.wall import WallReflectance


def render_in_medium(
    camera: Camera,
    view: View,
    lit: list[tuple[Light, np.ndarray, np.ndarray]],
    sensor: SensorModel,
    vmap: np.ndarray,
    b: int,
    n_sub: int,
    offset: float,
    wall: WallReflectance,
    medium: Medium,
) -> tuple[np.ndarray, np.ndarray]:
    """`render_fused` with each light's value times its transmittance T at the
    footprint centres (`attenuate_image`): one fused pass per light, whose T differs;
    then each light's backscatter along the rays to those centres (`add_scatter_image`,
    exact on the nodes of `scatter_grid`, interpolated between them)."""
    grid_xy, grid_ok = GRID_CACHE.get(camera)
    view_args = (
        grid_xy,
        grid_ok,
        np.ascontiguousarray(view.R_camera_world),
        np.ascontiguousarray(view.center_world),
        b,
    )
    total, invalid = render_fused(camera, view, lit[:1], sensor, vmap, b, n_sub, 0.0, wall)
    c = medium.attenuation_per_m
    with numba.parallel_chunksize(1):
        attenuate_image(*view_args, lit[0][1], c, total, total, False, float(offset))
        for k in range(1, len(lit)):
            out, _ = render_fused(camera, view, lit[k : k + 1], sensor, vmap, b, n_sub, 0.0, wall)
            attenuate_image(*view_args, lit[k][1], c, out, total, True, 0.0)
        if medium.scatters:
            nodes, weights = scatter_nodes()
            node_rows, node_cols = scatter_grid(total.shape)
            for light, L_world, R_world_light in lit:
                add_scatter_image(
                    *view_args,
                    L_world,
                    np.ascontiguousarray(R_world_light),
                    light.rid.data(),
                    c,
                    medium.phase_g,
                    nodes,
                    weights,
                    light.scale * view.exposure * medium.backscatter_per_m,
                    node_rows,
                    node_cols,
                    total,
                )
    return total, invalid


def render_fused(
    camera: Camera,
    view: View,
    lit: list[tuple[Light, np.ndarray, np.ndarray]],
    sensor: SensorModel,
    vmap: np.ndarray,
    b: int,
    n_sub: int,
    offset: float,
    wall: WallReflectance,
) -> tuple[np.ndarray, np.ndarray]:
    """The fused kernel over lights `lit` (light, L_world, R_world_light): values, invalid."""
    grid_xy, grid_ok = GRID_CACHE.get(camera)
    hb, wb = camera.height // b, camera.width // b
    lights_world = np.array([p for _, p, _ in lit], dtype=np.float64).reshape(len(lit), 3)
    R_world_lights = np.array([r for _, _, r in lit], dtype=np.float64).reshape(len(lit), 3, 3)
    scales = np.array([light.scale for light, _, _ in lit], dtype=np.float64)
    rids = stack_rid_data([light.rid.data() for light, _, _ in lit])
    wd = wall.data()
    out = np.empty((hb, wb))
    invalid = np.empty((hb, wb), dtype=np.bool_)
    # Dynamic scheduling of the row chunks: the machine's cores may be shared.
    with numba.parallel_chunksize(1):
        render_image_fused(
            grid_xy,
            grid_ok,
            np.ascontiguousarray(view.R_camera_world),
            np.ascontiguousarray(view.center_world),
            SENSOR_CODES[sensor],
            vmap,
            b,
            lights_world,
            R_world_lights,
            scales,
            rids,
            n_sub,
            float(view.exposure),
            float(offset),
            wd.kind,
            wd.params,
            wd.tables,
            out,
            invalid,
        )
    return out, invalid
