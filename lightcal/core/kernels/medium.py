"""The medium's transmittance (`lightcal.core.medium`): per pixel with the chain rule on a
light's flux and gradients, and on whole images.

Beer-Lambert along the two straight segments light -> wall point P -> camera,

    T(P) = exp(-c (|P - L| + |P - C|)),

c the attenuation coefficient (1/m), evaluated at each (super-)pixel's footprint centre.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from lightcal.core.kernels.fastmath import exp_real
from lightcal.core.kernels.sensor import view_scalars, wall_point

#: Below this many points the kernels run on the calling thread.
SERIAL_POINTS = 20_000


@numba.njit(cache=True, inline="always", error_model="numpy")
def _apply_range(
    i0: int,
    i1: int,
    points: np.ndarray,
    light: np.ndarray,
    camera: np.ndarray,
    c: float,
    flux: np.ndarray,
    grad: np.ndarray,
    want_grad: bool,
    out_t: np.ndarray,
    out_dc: np.ndarray,
) -> None:
    """flux *= T in place; with want_grad the chain rule on grad (N, 6) in place,
    d(flux T)/dL = T dflux/dL - c flux T (L - P) / |L - P|, d(flux T)/d delta =
    T dflux/d delta, and out_dc = d(flux T)/dc = -(|P - L| + |P - C|) flux T. out_t (N,)
    receives T (1 where the point is not finite: an invalid footprint, left as it is).
    out_dc of length 0: not wanted. camera: (1, 3) the camera centre C, or (N, 3) each
    point's own (behind the camera's flat port: where its ray leaves the port)."""
    lx, ly, lz = light[0], light[1], light[2]
    each = camera.shape[0] > 1
    want_dc = want_grad and out_dc.shape[0] > 0
    for i in range(i0, i1):
        px = points[i, 0]
        py = points[i, 1]
        pz = points[i, 2]
        ax = lx - px
        ay = ly - py
        az = lz - pz
        d_light = math.sqrt(ax * ax + ay * ay + az * az)
        j = i if each else 0
        bx = camera[j, 0] - px
        by = camera[j, 1] - py
        bz = camera[j, 2] - pz
        d_camera = math.sqrt(bx * bx + by * by + bz * bz)
        if not (math.isfinite(d_light) and math.isfinite(d_camera)):
            # An invalid footprint (NaN centre): its flux and gradients stay 0.
            out_t[i] = 1.0
            if want_dc:
                out_dc[i] = 0.0
            continue
        t = math.exp(-c * (d_light + d_camera))
        f = flux[i] * t
        flux[i] = f
        out_t[i] = t
        if want_grad:
            k = c * f / d_light if d_light > 0.0 else 0.0
            grad[i, 0] = t * grad[i, 0] - k * ax
            grad[i, 1] = t * grad[i, 1] - k * ay
            grad[i, 2] = t * grad[i, 2] - k * az
            grad[i, 3] *= t
            grad[i, 4] *= t
            grad[i, 5] *= t
            if want_dc:
                out_dc[i] = -(d_light + d_camera) * f


@numba.njit(cache=True, parallel=True, error_model="numpy")
def _apply_parallel(
    points: np.ndarray,
    light: np.ndarray,
    camera: np.ndarray,
    c: float,
    flux: np.ndarray,
    grad: np.ndarray,
    want_grad: bool,
    out_t: np.ndarray,
    out_dc: np.ndarray,
) -> None:
    n = points.shape[0]
    n_chunks = min(n, 64)
    for ch in numba.prange(n_chunks):
        _apply_range(
            ch * n // n_chunks,
            (ch + 1) * n // n_chunks,
            points,
            light,
            camera,
            c,
            flux,
            grad,
            want_grad,
            out_t,
            out_dc,
        )


@numba.njit(cache=True, error_model="numpy")
def _apply_serial(
    points: np.ndarray,
    light: np.ndarray,
    camera: np.ndarray,
    c: float,
    flux: np.ndarray,
    grad: np.ndarray,
    want_grad: bool,
    out_t: np.ndarray,
    out_dc: np.ndarray,
) -> None:
    _apply_range(0, points.shape[0], points, light, camera, c, flux, grad, want_grad, out_t, out_dc)


def apply_attenuation(
    points_world: np.ndarray,
    light_world: np.ndarray,
    camera_world: np.ndarray,
    attenuation_per_m: float,
    flux: np.ndarray,
    grad: np.ndarray,
    *,
    want_grad: bool,
    out_transmittance: np.ndarray,
    out_d_attenuation: np.ndarray,
) -> None:
    """Multiply one light's flux by T at the footprint centres, gradients chained, in place.

    Args:
        points_world: (N, 3) footprint centres; light_world: (3,), m.
        camera_world: (3,) the camera centre, or (N, 3) where each pixel's ray leaves
            the camera's flat port (T = exp(-c (|P - L| + |P - X_p|))), m.
        attenuation_per_m: c, 1/m.
        flux: (N,) the light's flux, multiplied in place.
        grad: (N, 6) d flux / d (L_world, delta_world), chained in place (want_grad).
        out_transmittance: (N,) receives T.
        out_d_attenuation: (N,) receives d(flux T)/dc (want_grad; length 0: not wanted).
    """
    kernel = _apply_serial if len(points_world) < SERIAL_POINTS else _apply_parallel
    kernel(
        points_world,
        light_world,
        np.ascontiguousarray(camera_world, dtype=np.float64).reshape(-1, 3),
        float(attenuation_per_m),
        flux,
        grad,
        bool(want_grad),
        out_transmittance,
        out_d_attenuation,
    )


@numba.njit(cache=True, inline="always", error_model="numpy")
def corner_row(
    grid_xy: np.ndarray,
    grid_ok: np.ndarray,
    j: int,
    view: tuple[float, ...],
    px: np.ndarray,
    py: np.ndarray,
) -> None:
    """Wall points (px, py) of corner row j (`wall_point`; (0, 0) where it misses)."""
    for u in range(px.shape[0]):
        px[u], py[u], _ = wall_point(grid_xy[j, u, 0], grid_xy[j, u, 1], grid_ok[j, u], view, False)


@numba.njit(cache=True, inline="always", error_model="numpy")
def centre_sums_row(
    grid_xy: np.ndarray,
    grid_ok: np.ndarray,
    view: tuple[float, ...],
    r: int,
    b: int,
    rows_x: np.ndarray,
    rows_y: np.ndarray,
    top: int,
    sx: np.ndarray,
    sy: np.ndarray,
) -> int:
    """Sums sx, sy (W // b,) of the wall points of the 4 corners of each pixel of the b x b
    super-pixels of row r (divide by 4 b^2 for the footprint centres), rows_x / rows_y
    (2, W + 1) holding the corner rows, row `top` the upper one (computed by the caller
    for the first row); returns the new `top`."""
    w = rows_x.shape[1] - 1
    wb = sx.shape[0]
    for jj in range(b):
        tx, ty = rows_x[top], rows_y[top]
        bx, by = rows_x[1 - top], rows_y[1 - top]
        corner_row(grid_xy, grid_ok, r * b + jj + 1, view, bx, by)
        top = 1 - top
        if b == 1:
            for u in range(w):
                sx[u] = (tx[u] + tx[u + 1]) + (bx[u] + bx[u + 1])
                sy[u] = (ty[u] + ty[u + 1]) + (by[u] + by[u + 1])
            continue
        if jj == 0:
            sx[:] = 0.0
            sy[:] = 0.0
        for col in range(wb):
            for ii in range(b):
                u = col * b + ii
                sx[col] += (tx[u] + tx[u + 1]) + (bx[u] + bx[u + 1])
                sy[col] += (ty[u] + ty[u + 1]) + (by[u] + by[u + 1])
    return top


@numba.njit(cache=True, parallel=True, error_model="numpy")
def attenuate_image(
    grid_xy: np.ndarray,
    grid_ok: np.ndarray,
    R_camera_world: np.ndarray,
    center_world: np.ndarray,
    binning: int,
    light_world: np.ndarray,
    attenuation_per_m: float,
    values: np.ndarray,
    total: np.ndarray,
    accumulate: bool,
    offset: float,
) -> None:
    """total = (total if accumulate else offset) + values x T, T one light's transmittance
    at every (super-)pixel's footprint centre, placed as `render_image_fused` places the
    wall's B: the mean of the 4 corners of each of its b x b pixels. `values` may be
    `total` itself (one light: in place).

    Args:
        grid_xy: (H+1, W+1, 2) undistorted normalised corner coordinates (`corner_grid`).
        grid_ok: (H+1, W+1) corners whose undistortion succeeded.
        R_camera_world: (3, 3); center_world: (3,) camera centre, world frame, m.
        binning: b, super-pixel side in pixels.
        light_world: (3,) the emitter, world frame, m.
        attenuation_per_m: c, 1/m.
        values: (H // b, W // b) the light's values (NaN where invalid: they stay NaN).
        total: (H // b, W // b) written.
        accumulate: add to total (else start from offset).
        offset: the offset total starts from when not accumulating.
    """
    hb = total.shape[0]
    wb = total.shape[1]
    b = binning
    w = wb * b
    view = view_scalars(R_camera_world, center_world)
    c0, c1, c2 = center_world[0], center_world[1], center_world[2]
    lx, ly = light_world[0], light_world[1]
    lz2 = light_world[2] * light_world[2]
    norm = 1.0 / (4.0 * b * b)
    n_chunks = min(hb, 64)
    for ch in numba.prange(n_chunks):
        rows_x = np.empty((2, w + 1))
        rows_y = np.empty((2, w + 1))
        sx = np.empty(wb)
        sy = np.empty(wb)
        exponent = np.empty(wb)  # -c path, then T
        r_begin = ch * hb // n_chunks
        top = 0  # the row of rows_x / rows_y holding the upper corner row
        corner_row(grid_xy, grid_ok, r_begin * b, view, rows_x[0], rows_y[0])
        for r in range(r_begin, (ch + 1) * hb // n_chunks):
            top = centre_sums_row(grid_xy, grid_ok, view, r, b, rows_x, rows_y, top, sx, sy)
            # Three loops, each vectorised (one loop with exp inline is not).
            for col in range(wb):
                mx = sx[col] * norm
                my = sy[col] * norm
                ex = mx - c0
                ey = my - c1
                ax = mx - lx
                ay = my - ly
                d_camera = math.sqrt(ex * ex + ey * ey + c2 * c2)
                exponent[col] = -attenuation_per_m * (d_camera + math.sqrt(ax * ax + ay * ay + lz2))
            for col in range(wb):
                exponent[col] = exp_real(exponent[col])
            out = total[r]
            vals = values[r]
            if accumulate:
                for col in range(wb):
                    out[col] += vals[col] * exponent[col]
            else:
                for col in range(wb):
                    out[col] = offset + vals[col] * exponent[col]
