"""Plain compiled kernels of the renderer: the straightforward versions of the fast ones.

`geometry_image` + `flux_image` render a whole image quad by quad with `quad_flux` (the
plain quad loop), what `kernels.image.render_image_fused` computes with shared corners,
one arctangent per quad and branch-free cos^m; `flux_pixels_plain` is `flux_pixels`
without its fast paths. `tests/test_render_kernels_speedpath.py` holds the fast kernels
to these numbers.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from lightcal.core.kernels.flux import flux_range
from lightcal.core.kernels.quad_flux import quad_flux
from lightcal.core.kernels.sensor import (
    SENSOR_COS4,
    SENSOR_MAP,
    SENSOR_PAPER,
    cos4,
    paper_weight,
    quad_area,
    view_scalars,
    wall_point,
)
from lightcal.core.rid_eval import RIDData, RIDTuple


@numba.njit(cache=True)
def _pixel_quad(
    grid_xy: np.ndarray, grid_ok: np.ndarray, v: int, u: int, view: tuple[float, ...], q: np.ndarray
) -> bool:
    """Wall quad q (4, 3) of pixel (u, v), corners in the cyclic order; False on a miss."""
    ok = True
    for k in range(4):
        j = v + (k >> 1)
        i = u + (1 if k == 1 or k == 2 else 0)
        x = grid_xy[j, i, 0]
        y = grid_xy[j, i, 1]
        px, py, hit = wall_point(x, y, grid_ok[j, i], view, False)  # as `kernels.image`
        q[k, 0] = px
        q[k, 1] = py
        q[k, 2] = 0.0
        ok &= hit
    return ok


@numba.njit(cache=True, parallel=True)
def geometry_image(
    grid_xy: np.ndarray,
    grid_ok: np.ndarray,
    R_camera_world: np.ndarray,
    center_world: np.ndarray,
    sensor: int,
    vignetting: np.ndarray,
    binning: int,
    out_weight: np.ndarray,
    out_valid: np.ndarray,
) -> None:
    """Per-pixel sensor weights of a (binned) full image; see `flux_image`.

    Args:
        grid_xy: (H+1, W+1, 2) undistorted normalised coordinates of the pixel corners.
        grid_ok: (H+1, W+1) corners whose undistortion succeeded.
        R_camera_world: (3, 3); center_world: (3,) camera centre, world frame, m.
        sensor: one of the SENSOR_* codes.
        vignetting: (H, W) fall-off map for SENSOR_MAP, else any (1, 1) array.
        binning: b, super-pixel side in pixels.
        out_weight: (H // b, W // b, b * b) weight of each member pixel's flux.
        out_valid: (H // b, W // b) pixels whose every corner lands on the wall.
    """
    hb = out_valid.shape[0]
    wb = out_valid.shape[1]
    b = binning
    view = view_scalars(R_camera_world, center_world)
    g = grid_xy
    for r in numba.prange(hb):
        q = np.empty((4, 3))
        for c in range(wb):
            ok = True
            area = 0.0
            vsum = 0.0
            for jj in range(b):
                for ii in range(b):
                    v = r * b + jj
                    u = c * b + ii
                    ok &= _pixel_quad(grid_xy, grid_ok, v, u, view, q)
                    x1, y1, x2, y2 = q[0, 0], q[0, 1], q[1, 0], q[1, 1]
                    x3, y3, x4, y4 = q[2, 0], q[2, 1], q[3, 0], q[3, 1]
                    area += quad_area(x1, y1, x2, y2, x3, y3, x4, y4)
                    if sensor == SENSOR_PAPER:
                        wgt = paper_weight(x1, y1, x2, y2, x3, y3, x4, y4, view)
                        out_weight[r, c, jj * b + ii] = wgt / (b * b)
                    elif sensor == SENSOR_COS4:
                        vsum += cos4(
                            g[v, u, 0], g[v, u, 1], g[v, u + 1, 0], g[v, u + 1, 1],
                            g[v + 1, u + 1, 0], g[v + 1, u + 1, 1], g[v + 1, u, 0], g[v + 1, u, 1],
                        )  # fmt: skip
                    elif sensor == SENSOR_MAP:
                        vsum += vignetting[v, u]
                    else:
                        vsum += 1.0
            out_valid[r, c] = ok
            if ok and sensor != SENSOR_PAPER:
                for k in range(b * b):
                    out_weight[r, c, k] = (vsum / (b * b)) / area


@numba.njit(cache=True, parallel=True)
def flux_image(
    grid_xy: np.ndarray,
    grid_ok: np.ndarray,
    R_camera_world: np.ndarray,
    center_world: np.ndarray,
    weight: np.ndarray,
    valid: np.ndarray,
    light_world: np.ndarray,
    R_world_light: np.ndarray,
    rid: RIDData,
    n_sub: int,
    scale: float,
    out: np.ndarray,
) -> None:
    """Add scale * sum_k weight_k Phi_k / I0 of one light to every valid (super-)pixel.

    Args:
        grid_xy, grid_ok, R_camera_world, center_world: as `geometry_image`.
        weight, valid: from `geometry_image`.
        light_world (3,), R_world_light (3, 3), rid: the light.
        n_sub: RID sub-sampling per side.
        scale: the light's scale.
        out: (H // b, W // b) accumulator.
    """
    hb = valid.shape[0]
    wb = valid.shape[1]
    b = round(math.sqrt(weight.shape[2]))
    view = view_scalars(R_camera_world, center_world)
    lx = light_world[0]
    ly = light_world[1]
    lz = light_world[2]
    for r in numba.prange(hb):
        q = np.empty((4, 3))
        dummy = np.zeros(6)
        for c in range(wb):
            if not valid[r, c]:
                continue
            acc = 0.0
            for jj in range(b):
                for ii in range(b):
                    _pixel_quad(grid_xy, grid_ok, r * b + jj, c * b + ii, view, q)
                    phi = quad_flux(q, lx, ly, lz, R_world_light, rid, n_sub, False, dummy)
                    acc += weight[r, c, jj * b + ii] * phi
            out[r, c] += scale * acc


@numba.njit(cache=True)
def flux_pixels_plain(
    corners_world: np.ndarray,
    weights: np.ndarray,
    valid: np.ndarray,
    light_world: np.ndarray,
    R_world_light: np.ndarray,
    rid: RIDTuple,
    n_sub: int,
    want_grad: bool,
    out_flux: np.ndarray,
    out_grad: np.ndarray,
) -> None:
    """`flux_pixels` without the fast paths: `quad_flux` for every quad (rid: `rid_tuple`)."""
    flux_range(
        int(0),  # noqa: UP018, RUF046 (not a literal type)
        corners_world.shape[0],
        corners_world,
        weights,
        valid,
        light_world,
        R_world_light,
        RIDData(*rid),
        n_sub,
        want_grad,
        bool(False),  # noqa: UP018 (not a literal type)
        out_flux,
        out_grad,
    )
