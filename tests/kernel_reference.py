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
from lightcal.core.kernels.sensor import SENSOR_COS4, SENSOR_MAP, SENSOR_PAPER
from lightcal.core.rid_eval import RIDData


@numba.njit(cache=True, inline="always")
def _corner_world(
    x: float, y: float, R_camera_world: np.ndarray, center: np.ndarray, out: np.ndarray
) -> bool:
    """Intersect the ray of normalised camera coordinates (x, y) with z = 0; False on a miss."""
    dx = R_camera_world[0, 0] * x + R_camera_world[1, 0] * y + R_camera_world[2, 0]
    dy = R_camera_world[0, 1] * x + R_camera_world[1, 1] * y + R_camera_world[2, 1]
    dz = R_camera_world[0, 2] * x + R_camera_world[1, 2] * y + R_camera_world[2, 2]
    if not (dz < 0.0):
        return False
    lam = -center[2] / dz
    if not (lam > 0.0):
        return False
    out[0] = center[0] + lam * dx
    out[1] = center[1] + lam * dy
    out[2] = 0.0
    return True


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
    for r in numba.prange(hb):
        q = np.empty((4, 3))
        for cidx in range(wb):
            ok = True
            area = 0.0
            vsum = 0.0
            for jj in range(b):
                v = r * b + jj
                for ii in range(b):
                    u = cidx * b + ii
                    xs = (
                        grid_xy[v, u, 0],
                        grid_xy[v, u + 1, 0],
                        grid_xy[v + 1, u + 1, 0],
                        grid_xy[v + 1, u, 0],
                    )
                    ys = (
                        grid_xy[v, u, 1],
                        grid_xy[v, u + 1, 1],
                        grid_xy[v + 1, u + 1, 1],
                        grid_xy[v + 1, u, 1],
                    )
                    oks = (
                        grid_ok[v, u]
                        and grid_ok[v, u + 1]
                        and grid_ok[v + 1, u + 1]
                        and grid_ok[v + 1, u]
                    )
                    if not oks:
                        ok = False
                        break
                    for k in range(4):
                        if not _corner_world(xs[k], ys[k], R_camera_world, center_world, q[k]):
                            ok = False
                    if not ok:
                        break
                    a = 0.5 * abs(
                        (q[2, 0] - q[0, 0]) * (q[3, 1] - q[1, 1])
                        - (q[2, 1] - q[0, 1]) * (q[3, 0] - q[1, 0])
                    )
                    k_idx = jj * b + ii
                    if sensor == SENSOR_PAPER:
                        mx = 0.25 * (q[0, 0] + q[1, 0] + q[2, 0] + q[3, 0]) - center_world[0]
                        my = 0.25 * (q[0, 1] + q[1, 1] + q[2, 1] + q[3, 1]) - center_world[1]
                        mz = -center_world[2]
                        d2 = mx * mx + my * my + mz * mz
                        out_weight[r, cidx, k_idx] = (
                            (center_world[2] / math.sqrt(d2)) / d2 / (b * b)
                        )
                    else:
                        area += a
                        if sensor == SENSOR_COS4:
                            xm = 0.25 * (xs[0] + xs[1] + xs[2] + xs[3])
                            ym = 0.25 * (ys[0] + ys[1] + ys[2] + ys[3])
                            c2 = 1.0 / (1.0 + xm * xm + ym * ym)
                            vsum += c2 * c2
                        elif sensor == SENSOR_MAP:
                            vsum += vignetting[v, u]
                        else:
                            vsum += 1.0
                if not ok:
                    break
            out_valid[r, cidx] = ok
            if ok and sensor != SENSOR_PAPER:
                w = (vsum / (b * b)) / area
                for k_idx in range(b * b):
                    out_weight[r, cidx, k_idx] = w


@numba.njit(cache=True, parallel=True)
def flux_image(
    grid_xy: np.ndarray,
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
        grid_xy: (H+1, W+1, 2) undistorted normalised corner coordinates.
        R_camera_world, center_world: the view; light_world (3,), R_world_light (3, 3): the light.
        weight, valid: from `geometry_image`.
        rid: the light's RID; n_sub: RID sub-sampling per side.
        scale: the light's scale.
        out: (H // b, W // b) accumulator.
    """
    hb = valid.shape[0]
    wb = valid.shape[1]
    b = round(math.sqrt(weight.shape[2]))
    lx = light_world[0]
    ly = light_world[1]
    lz = light_world[2]
    for r in numba.prange(hb):
        q = np.empty((4, 3))
        dummy = np.zeros(6)
        for cidx in range(wb):
            if not valid[r, cidx]:
                continue
            acc = 0.0
            for jj in range(b):
                v = r * b + jj
                for ii in range(b):
                    u = cidx * b + ii
                    _corner_world(
                        grid_xy[v, u, 0], grid_xy[v, u, 1], R_camera_world, center_world, q[0]
                    )
                    _corner_world(
                        grid_xy[v, u + 1, 0],
                        grid_xy[v, u + 1, 1],
                        R_camera_world,
                        center_world,
                        q[1],
                    )
                    _corner_world(
                        grid_xy[v + 1, u + 1, 0],
                        grid_xy[v + 1, u + 1, 1],
                        R_camera_world,
                        center_world,
                        q[2],
                    )
                    _corner_world(
                        grid_xy[v + 1, u, 0],
                        grid_xy[v + 1, u, 1],
                        R_camera_world,
                        center_world,
                        q[3],
                    )
                    phi = quad_flux(q, lx, ly, lz, R_world_light, rid, n_sub, False, dummy)
                    acc += weight[r, cidx, jj * b + ii] * phi
            out[r, cidx] += scale * acc


@numba.njit(cache=True)
def flux_pixels_plain(
    corners_world: np.ndarray,
    weights: np.ndarray,
    valid: np.ndarray,
    light_world: np.ndarray,
    R_world_light: np.ndarray,
    rid: RIDData,
    n_sub: int,
    want_grad: bool,
    out_flux: np.ndarray,
    out_grad: np.ndarray,
) -> None:
    """`flux_pixels` without the fast paths: `quad_flux` for every quad."""
    flux_range(
        0,
        corners_world.shape[0],
        corners_world,
        weights,
        valid,
        light_world,
        R_world_light,
        rid,
        n_sub,
        want_grad,
        False,
        out_flux,
        out_grad,
    )
