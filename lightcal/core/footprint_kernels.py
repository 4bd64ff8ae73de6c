"""Compiled (numba) kernel of `lightcal.core.footprint.pixel_footprints`.

One parallel pass over the (super-)pixels: for each, the (b+1) x (b+1) lattice of its
members' corners is undistorted (or read from the camera's corner grid), each corner's
ray is intersected with the wall z = 0 once, and the b^2 footprint quads, their validity
and sensor weights are written straight into the outputs: no temporaries per corner.

The arithmetic reproduces the NumPy formulation of `footprint.py` (which these kernels
replaced; `tests/test_footprint_kernels.py` keeps it as the reference) operation for
operation, so that the results are the same to the last bit (with NumPy 2.4 and its
OpenBLAS; the order of a sum or an FMA only ever moves the last bit):

- corner (u_c, v_c): yd = (v_c - cy) / fy, xd = (u_c - cx - s yd) / fx, undistorted by
  `undistort_normalized` (`Camera.pixels_to_normalized`), or read from the `corner_grid`
  (the same roots to round-off, not bit for bit: the reference is then fed the grid's);
- ray d = R^T (x, y, 1) rounded as `(N, 3) @ (3, 3)` does in OpenBLAS's FMA kernels:
  d_k = fl(fma(y, R[1, k], fl(x R[0, k])) + R[2, k]);
- wall point C + lambda d, lambda = -C_z / d_z, hit when undistorted, d_z < 0 and
  lambda > 0; its z is exactly 0 (this and the sensor weights: `kernels.sensor`, shared
  with the full-image renderer);
- sums over a super-pixel's b^2 quads in NumPy's pairwise order (`pairwise_sum`), sums
  over a quad's 4 corners left to right, the squared length of a 3-vector as
  `numpy.einsum` evaluates it, (o_x^2 + o_z^2) + o_y^2.

Footprints read from the grid keep no quads (`footprint.GridCorners`):
`footprint_grid_kernels` recomputes them from the grid when they are needed.
"""

from __future__ import annotations

import numba
import numpy as np

from lightcal.core.distortion import undistort_normalized
from lightcal.core.footprint_grid_kernels import write_quad
from lightcal.core.kernels.sensor import (
    SENSOR_COS4,
    SENSOR_MAP,
    SENSOR_PAPER,
    SENSOR_RADIANCE,
    cos4,
    paper_weight,
    quad_area,
    view_scalars,
    wall_point,
)

#: Corners per parallel work item (each item allocates its small scratch array once).
CHUNK_CORNERS = 1024


@numba.njit(cache=True, error_model="numpy")
def _pairwise_block(a: np.ndarray, start: int, n: int) -> float:
    """`pairwise_sum` of n <= 128 terms: below 8 left to right, else 8 interleaved sums."""
    if n < 8:
        res = 0.0
        for i in range(start, start + n):
            res += a[i]
        return res
    r0 = a[start]
    r1 = a[start + 1]
    r2 = a[start + 2]
    r3 = a[start + 3]
    r4 = a[start + 4]
    r5 = a[start + 5]
    r6 = a[start + 6]
    r7 = a[start + 7]
    i = 8
    stop = n - n % 8
    while i < stop:
        j = start + i
        r0 += a[j]
        r1 += a[j + 1]
        r2 += a[j + 2]
        r3 += a[j + 3]
        r4 += a[j + 4]
        r5 += a[j + 5]
        r6 += a[j + 6]
        r7 += a[j + 7]
        i += 8
    res = ((r0 + r1) + (r2 + r3)) + ((r4 + r5) + (r6 + r7))
    while i < n:
        res += a[start + i]
        i += 1
    return res


@numba.njit(cache=True, error_model="numpy")
def pairwise_sum(a: np.ndarray, start: int, n: int) -> float:
    """Sum of a[start : start + n] in NumPy's pairwise order (`np.add.reduce` of a row).

    Up to 128 terms `_pairwise_block`; beyond, the sum of the two halves (the first a
    multiple of 8 long), each summed the same way (an explicit stack: numba kernels
    cannot recurse here).
    """
    if n <= 128:
        return _pairwise_block(a, start, n)
    depth = 64  # halving n <= 2^63 at most 63 times
    frame_start = np.empty(depth, dtype=np.int64)
    frame_n = np.empty(depth, dtype=np.int64)
    frame_stage = np.empty(depth, dtype=np.int64)  # 0: left next, 1: right next, 2: add
    partial = np.empty(depth + 1)
    top = 0
    frame_start[0] = start
    frame_n[0] = n
    frame_stage[0] = 0
    n_partial = 0
    while top >= 0:
        s0 = frame_start[top]
        n0 = frame_n[top]
        if n0 <= 128:
            partial[n_partial] = _pairwise_block(a, s0, n0)
            n_partial += 1
            top -= 1
            continue
        half = n0 // 2
        half -= half % 8
        stage = frame_stage[top]
        frame_stage[top] = stage + 1
        if stage == 2:
            n_partial -= 1
            partial[n_partial - 1] = partial[n_partial - 1] + partial[n_partial]
            top -= 1
            continue
        top += 1
        frame_start[top] = s0 if stage == 0 else s0 + half
        frame_n[top] = half if stage == 0 else n0 - half
        frame_stage[top] = 0
    return partial[0]


@numba.njit(cache=True, inline="always", error_model="numpy")
def _pixel_footprint(
    p: int,
    pixels: np.ndarray,
    binning: int,
    step: int,
    use_grid: bool,
    grid_xy: np.ndarray,
    grid_ok: np.ndarray,
    K: np.ndarray,
    dist: np.ndarray,
    R: np.ndarray,
    center_world: np.ndarray,
    sensor: int,
    vignetting: np.ndarray,
    write_corners: bool,
    scratch: np.ndarray,
    out_corners: np.ndarray,
    out_weights: np.ndarray,
    out_valid: np.ndarray,
    out_area: np.ndarray,
) -> None:
    """Write the outputs of (super-)pixel p (arguments: `pixel_footprints_parallel`);
    out_corners only when `write_corners`.

    scratch: (6, (b+1)^2) work space: the lattice's wall x, y and undistorted x, y, then
    the members' quad areas and sensor terms.
    """
    b = binning
    k = b * b
    n_lat = b + 1
    wall_x = scratch[0]
    wall_y = scratch[1]
    norm_x = scratch[2]
    norm_y = scratch[3]
    areas = scratch[4]
    terms = scratch[5]
    view = view_scalars(R, center_world)
    u0 = pixels[p, 0] * b
    v0 = pixels[p, 1] * b
    valid = True
    for jj in range(n_lat):
        row = v0 + jj
        yd = (float(row) - 0.5 - K[1, 2]) / K[1, 1]
        for ii in range(n_lat):
            col = u0 + ii
            if use_grid:
                ok = grid_ok[row, col]
                x = grid_xy[row, col, 0]
                y = grid_xy[row, col, 1]
            else:
                xd = (float(col) - 0.5 - K[0, 2] - K[0, 1] * yd) / K[0, 0]
                x, y, ok = undistort_normalized(xd, yd, dist)
            px, py, hit = wall_point(x, y, ok, view, True)
            if not hit:
                valid = False
                break
            i = jj * n_lat + ii
            wall_x[i] = px
            wall_y[i] = py
            norm_x[i] = x
            norm_y[i] = y
        if not valid:
            break
    out_valid[p] = valid
    if not valid:
        for m in range(out_weights.shape[1]):
            out_weights[p, m] = 0.0
            if write_corners:
                for q in range(4):
                    for d in range(3):
                        out_corners[p, m, q, d] = np.nan
        out_area[p] = np.nan
        return
    for m in range(k):
        jj = m // b
        i1 = jj * n_lat + m - jj * b  # P1 = lattice (jj, ii); P2, P3, P4 cyclic
        i2 = i1 + 1
        i3 = i2 + n_lat
        i4 = i1 + n_lat
        x1 = wall_x[i1]
        y1 = wall_y[i1]
        x2 = wall_x[i2]
        y2 = wall_y[i2]
        x3 = wall_x[i3]
        y3 = wall_y[i3]
        x4 = wall_x[i4]
        y4 = wall_y[i4]
        if write_corners and step == 1:
            write_quad(out_corners, p, m, x1, y1, x2, y2, x3, y3, x4, y4)
        areas[m] = quad_area(x1, y1, x2, y2, x3, y3, x4, y4)
        if sensor == SENSOR_PAPER:
            terms[m] = paper_weight(x1, y1, x2, y2, x3, y3, x4, y4, view) / k
        elif sensor == SENSOR_COS4:
            terms[m] = cos4(
                norm_x[i1], norm_y[i1], norm_x[i2], norm_y[i2],
                norm_x[i3], norm_y[i3], norm_x[i4], norm_y[i4],
            )  # fmt: skip
        elif sensor == SENSOR_MAP:
            terms[m] = vignetting[v0 + jj, u0 + m - jj * b]
    area = pairwise_sum(areas, 0, k)
    out_area[p] = area
    weight = 0.0
    if sensor != SENSOR_PAPER:
        v_mean = 1.0
        if sensor != SENSOR_RADIANCE:  # cos4, map: the mean over the members
            v_mean = pairwise_sum(terms, 0, k) / k
        weight = v_mean / area
    if step == 1:
        for m in range(k):
            out_weights[p, m] = terms[m] if sensor == SENSOR_PAPER else weight
        return
    # Merged quads: group (gj, gi) of step x step members, its quad from the lattice at
    # the group's corners, its weight the mean of its members' (a weight multiplies flux,
    # and the group's flux is the sum of its members': sum_m w_m Phi_m ~ mean(w) Phi_group).
    s = b // step
    members = float(step * step)
    for g in range(s * s):
        gj = g // s
        gi = g - gj * s
        if write_corners:
            i1 = gj * step * n_lat + gi * step
            i2 = i1 + step
            i3 = i2 + step * n_lat
            i4 = i1 + step * n_lat
            write_quad(
                out_corners, p, g,
                wall_x[i1], wall_y[i1], wall_x[i2], wall_y[i2],
                wall_x[i3], wall_y[i3], wall_x[i4], wall_y[i4],
            )  # fmt: skip
        if sensor == SENSOR_PAPER:
            total = 0.0
            for mj in range(gj * step, (gj + 1) * step):
                for mi in range(gi * step, (gi + 1) * step):
                    total += terms[mj * b + mi]
            out_weights[p, g] = total / members
        else:
            out_weights[p, g] = weight


@numba.njit(cache=True, parallel=True, error_model="numpy")
def pixel_footprints_parallel(
    pixels: np.ndarray,
    binning: int,
    step: int,
    use_grid: bool,
    grid_xy: np.ndarray,
    grid_ok: np.ndarray,
    K: np.ndarray,
    dist: np.ndarray,
    R_camera_world: np.ndarray,
    center_world: np.ndarray,
    sensor: int,
    vignetting: np.ndarray,
    write_corners: bool,
    chunk_pixels: int,
    out_corners: np.ndarray,
    out_weights: np.ndarray,
    out_valid: np.ndarray,
    out_area: np.ndarray,
) -> None:
    """Footprint quads, validity, areas and sensor weights of N (super-)pixels.

    Args:
        pixels: (N, 2) int32 (u, v) indices in the image binned by `binning`, in range.
        binning: b >= 1; super-pixel (u, v) has the b^2 members (u b + i, v b + j),
            member index j b + i.
        step: g, a divisor of b: the members are merged into (b / g)^2 groups of g x g
            (`footprint.quads_per_side`), group (gi, gj) at index gj (b / g) + gi, its
            quad from the lattice at the group's corners and its weight the mean of
            its members' (validity, area and the members' sensor terms are the members'
            all the same). g = 1: each member its own quad (the exact footprints).
        use_grid: read corners from `grid_xy` / `grid_ok`, else undistort them here.
        grid_xy: (H+1, W+1, 2) the camera's corner grid (`corner_grid`); any shape when
            not `use_grid`.
        grid_ok: (H+1, W+1) its validity.
        K: (3, 3) intrinsics of the full-resolution image.
        dist: (8,) OpenCV distortion, zero padded.
        R_camera_world: (3, 3) the view's rotation.
        center_world: (3,) the camera centre, m (z > 0).
        sensor: SENSOR_* code of `kernels.sensor`.
        vignetting: (H, W) fall-off map for SENSOR_MAP; any shape otherwise.
        write_corners: write out_corners (else it is not touched: any shape). A dense
            selection's footprints read their corners from the grid when they need them
            (`grid_quads`) instead of keeping 96 bytes a quad.
        chunk_pixels: pixels per parallel work item (>= 1).
        out_corners: (N, (b/g)^2, 4, 3) written: quads P1..P4 of each member (group),
            world frame, m; NaN for invalid pixels.
        out_weights: (N, (b/g)^2) written: sensor weights, 0 for invalid pixels.
        out_valid: (N,) written: every corner ray of every member hits the wall.
        out_area: (N,) written: the sum of the members' quad areas, m^2; NaN if invalid.
    """
    n = pixels.shape[0]
    n_scratch = (binning + 1) * (binning + 1)
    n_chunks = (n + chunk_pixels - 1) // chunk_pixels
    for chunk in numba.prange(n_chunks):
        scratch = np.empty((6, n_scratch))
        for p in range(chunk * chunk_pixels, min(n, (chunk + 1) * chunk_pixels)):
            _pixel_footprint(
                p,
                pixels,
                binning,
                step,
                use_grid,
                grid_xy,
                grid_ok,
                K,
                dist,
                R_camera_world,
                center_world,
                sensor,
                vignetting,
                write_corners,
                scratch,
                out_corners,
                out_weights,
                out_valid,
                out_area,
            )


@numba.njit(cache=True, error_model="numpy")
def pixel_footprints_serial(
    pixels: np.ndarray,
    binning: int,
    step: int,
    use_grid: bool,
    grid_xy: np.ndarray,
    grid_ok: np.ndarray,
    K: np.ndarray,
    dist: np.ndarray,
    R_camera_world: np.ndarray,
    center_world: np.ndarray,
    sensor: int,
    vignetting: np.ndarray,
    write_corners: bool,
    out_corners: np.ndarray,
    out_weights: np.ndarray,
    out_valid: np.ndarray,
    out_area: np.ndarray,
) -> None:
    """`pixel_footprints_parallel` on the calling thread: for a few pixels, where waking
    the thread pool (milliseconds on a busy machine) would cost more than the work."""
    scratch = np.empty((6, (binning + 1) * (binning + 1)))
    for p in range(pixels.shape[0]):
        _pixel_footprint(
            p,
            pixels,
            binning,
            step,
            use_grid,
            grid_xy,
            grid_ok,
            K,
            dist,
            R_camera_world,
            center_world,
            sensor,
            vignetting,
            write_corners,
            scratch,
            out_corners,
            out_weights,
            out_valid,
            out_area,
        )
