"""`flux_pixels`: the flux of any set of pixels for one light, with gradients.

What `render.shade` (and so the solver) calls: sum_k weight_k Phi_k / I0 of each pixel
(the model of docs/model.md; `kernels.quad_flux`) and its gradients with respect to the
light's world position and a left rotation perturbation of its orientation. With
n = 1, quads on the wall z = 0 take the fast paths: without gradients `wall_quad_flux`
(shared corner norms, one arctangent per quad, `cos_power`), with gradients
`kernels.wall_gradients` (blocks of pixels in vectorised loops). Other quads take the
plain quad loop (`quad_flux`).

Footprints whose quads are not kept (a dense selection: `footprint.GridCorners`) go
through `flux_pixels_grid`: each parallel block of pixels reads its quads from the
camera's corner grid into a small buffer (the numbers of kept quads, bit for bit) and
runs the same code on it.
"""

from __future__ import annotations

import numba
import numpy as np

from lightcal.core.footprint_grid_kernels import grid_corners_serial, grid_quads_range
from lightcal.core.kernels.quad_flux import pixel_flux_range, wall_flux_range
from lightcal.core.kernels.sensor import view_scalars
from lightcal.core.kernels.wall_gradients import wall_grad_range
from lightcal.core.rid_eval import RIDData, RIDTuple, rid_tuple

#: Below this many quad evaluations (pixels x quads x sub-quads, x 4 with gradients by
#: the quad loop: n > 1), `flux_pixels` runs on the calling thread: waking the thread pool
#: costs more. (With n = 1 a quad with gradients costs about one without.)
SERIAL_WORK = 20_000


@numba.njit(cache=True, inline="always")
def flux_range(
    i0: int,
    i1: int,
    corners_world: np.ndarray,
    weights: np.ndarray,
    valid: np.ndarray,
    light_world: np.ndarray,
    R_world_light: np.ndarray,
    rid: RIDData,
    n_sub: int,
    want_grad: bool,
    allow_fast: bool,
    out_flux: np.ndarray,
    out_grad: np.ndarray,
) -> None:
    """`flux_pixels` for pixels i0 .. i1 - 1; without `allow_fast` no fast path is taken.

    The parallel and serial entry points below (and the plain one of the tests) inline
    it (they are separate functions: numba's cache does not tell apart compilations of
    one function with different options); the work is in `wall_flux_range` (inlined
    too), `wall_grad_range` and `pixel_flux_range` (compiled once for all of them).
    Callers pass int(0), not the constant 0: numba types a constant argument as a
    literal (Literal[int](0)) and would compile the last two again for it; int(...) and
    bool(...) of a constant are typed int64 and bool.
    """
    if allow_fast and n_sub == 1 and not want_grad:
        wall_flux_range(
            i0,
            i1,
            corners_world,
            weights,
            valid,
            light_world,
            R_world_light,
            rid,
            out_flux,
            out_grad,
        )
    elif allow_fast and want_grad and n_sub == 1:
        wall_grad_range(
            i0,
            i1,
            corners_world,
            weights,
            valid,
            light_world,
            R_world_light,
            rid,
            out_flux,
            out_grad,
        )
    else:
        pixel_flux_range(
            i0,
            i1,
            corners_world,
            weights,
            valid,
            light_world,
            R_world_light,
            rid,
            n_sub,
            want_grad,
            bool(allow_fast),  # the entry points pass a literal
            out_flux,
            out_grad,
        )


@numba.njit(cache=True, parallel=True)
def flux_pixels_parallel(
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
    """`flux_pixels` on all threads, in chunks of pixels (scratch buffers per chunk).

    rid: `rid_tuple` of the RID (a plain tuple: faster to dispatch than the record).
    """
    n = corners_world.shape[0]
    n_chunks = min(n, 256)
    for ch in numba.prange(n_chunks):
        flux_range(
            ch * n // n_chunks,
            (ch + 1) * n // n_chunks,
            corners_world,
            weights,
            valid,
            light_world,
            R_world_light,
            RIDData(*rid),
            n_sub,
            want_grad,
            True,
            out_flux,
            out_grad,
        )


@numba.njit(cache=True)
def flux_pixels_serial(
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
    """`flux_pixels` on the calling thread (small sets: no thread launch); rid: as
    `flux_pixels_parallel`'s."""
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
        True,
        out_flux,
        out_grad,
    )


def flux_pixels(
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
    """Weighted footprint flux of pixels for one light; writes (not adds) the outputs.

    Args:
        corners_world: (N, K, 4, 3) the K footprint quads of each pixel, world frame, m.
        weights: (N, K) sensor weights of each quad.
        valid: (N,) pixels to compute; others get 0.
        light_world: (3,) emitter position, world frame, m. Must have z > 0.
        R_world_light: (3, 3) light orientation in the world frame.
        rid: the light's RID.
        n_sub: RID sub-sampling per side of each quad.
        want_grad: compute out_grad.
        out_flux: (N,) sum_k weight_k Phi_k / I0.
        out_grad: (N, 6) d out_flux / d (L_world (3), delta_world (3)); untouched if not want_grad.
    """
    per_quad = 4 if want_grad and n_sub > 1 else 1
    work = corners_world.shape[0] * corners_world.shape[1] * n_sub * n_sub * per_quad
    kernel = flux_pixels_serial if work < SERIAL_WORK else flux_pixels_parallel
    kernel(
        corners_world,
        weights,
        valid,
        light_world,
        R_world_light,
        rid_tuple(rid),
        int(n_sub),
        bool(want_grad),
        out_flux,
        out_grad,
    )


#: Pixels (of one quad each) per block of `flux_pixels_grid_parallel`: the block's quads
#: (96 bytes a quad) and outputs stay in the L2 cache.
GRID_BLOCK_QUADS = 2048


@numba.njit(cache=True, parallel=True)
def flux_pixels_grid_parallel(
    pixels: np.ndarray,
    binning: int,
    grid_xy: np.ndarray,
    grid_ok: np.ndarray,
    R_camera_world: np.ndarray,
    center_world: np.ndarray,
    weights: np.ndarray,
    valid: np.ndarray,
    light_world: np.ndarray,
    R_world_light: np.ndarray,
    rid: RIDTuple,
    n_sub: int,
    want_grad: bool,
    block_pixels: int,
    out_flux: np.ndarray,
    out_grad: np.ndarray,
) -> None:
    """`flux_pixels` of footprints whose quads come from the corner grid, on all threads.

    Per block of `block_pixels`: the quads by `grid_quads_range`, the weights and validity
    copied alongside, `flux_range` on the block, its outputs copied out.
    """
    n = pixels.shape[0]
    k = weights.shape[1]
    view = view_scalars(R_camera_world, center_world)
    n_blocks = (n + block_pixels - 1) // block_pixels
    for blk in numba.prange(n_blocks):
        i0 = blk * block_pixels
        nb = min(n, i0 + block_pixels) - i0
        quads = np.empty((nb, k, 4, 3))
        w = np.empty((nb, k))
        ok = np.empty(nb, dtype=np.bool_)
        flux = np.empty(nb)
        grad = np.empty((nb if want_grad else 1, 6))
        grid_quads_range(i0, i0 + nb, pixels, binning, grid_xy, grid_ok, view, quads)
        for i in range(nb):
            ok[i] = valid[i0 + i]
            for m in range(k):
                w[i, m] = weights[i0 + i, m]
        flux_range(
            int(0),  # noqa: UP018, RUF046 (not a literal type)
            nb,
            quads,
            w,
            ok,
            light_world,
            R_world_light,
            RIDData(*rid),
            n_sub,
            want_grad,
            True,
            flux,
            grad,
        )
        for i in range(nb):
            out_flux[i0 + i] = flux[i]
        if want_grad:
            for i in range(nb):
                for c in range(6):
                    out_grad[i0 + i, c] = grad[i, c]


def flux_pixels_grid(
    pixels: np.ndarray,
    binning: int,
    grid: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray],
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
    """`flux_pixels` of footprints whose quads are read from the camera's corner grid.

    Args:
        pixels: (N, 2) int32 (u, v) in the image binned by `binning`.
        binning: b, the super-pixel side.
        grid: (grid_xy (H+1, W+1, 2), grid_ok (H+1, W+1), R_camera_world (3, 3),
            center_world (3,)): the corner grid and the view (`footprint.GridCorners`).
        weights, valid, ...: as `flux_pixels`.
    """
    n, k = weights.shape
    per_quad = 4 if want_grad and n_sub > 1 else 1
    if n * k * n_sub * n_sub * per_quad < SERIAL_WORK:
        # A few pixels: their quads into one array, then the serial kernel.
        quads = np.empty((n, k, 4, 3))
        grid_corners_serial(pixels, binning, *grid, quads)
        flux_pixels(
            quads, weights, valid, light_world, R_world_light, rid, n_sub, want_grad,
            out_flux, out_grad,
        )  # fmt: skip
        return
    # Dynamic scheduling of the blocks: the machine's cores may be shared.
    with numba.parallel_chunksize(1):
        flux_pixels_grid_parallel(
            pixels,
            int(binning),
            *grid,
            weights,
            valid,
            light_world,
            R_world_light,
            rid_tuple(rid),
            int(n_sub),
            bool(want_grad),
            max(1, GRID_BLOCK_QUADS // k),
            out_flux,
            out_grad,
        )
