"""The light's flat port in the water, compiled: the paths' water lengths and exits, and
the medium's attenuation of the flux lit through the port.

- `paths_into`: `light_port.port_paths` (`kernels.port_paths.solve_paths`, then the
  water's length H / cos(theta_w) from the exit point, its gradient in Y and the exit);
- `attenuate_rows`: `light_port_flux.attenuate_through_port`, T = exp(-c (|P - E| +
  the camera's side)) on the lit pixels' flux with the chain rule on their gradients
  and d (flux T) / dc, on all threads in chunks past `ATTENUATE_SERIAL_ROWS`.

The same formulas in the same order as the NumPy code they replaced (kept in
tests/light_port_numpy.py, which tests/test_light_port_kernels.py holds them to).
"""

from __future__ import annotations

import math

import numba
import numpy as np

from lightcal.core.kernels.port_flux import to_light
from lightcal.core.kernels.port_paths import BLOCK, PATH_SIZE, WORK_SIZE, solve_paths

#: Below this many pixels `attenuate_rows` runs on the calling thread (as
#: `kernels.port_flux.PORT_SERIAL_POINTS`: a few ms of work).
ATTENUATE_SERIAL_ROWS = 25_000


@numba.njit(cache=True, inline="always", error_model="numpy")
def _water(p: np.ndarray, big_h: float, normal: np.ndarray, n_w: float, grad: np.ndarray) -> float:
    """The water's length H / cos(theta_w) of the path p (`solve_paths`' row) to a point
    H beyond the outer face; its gradient in Y into grad (3,)."""
    s = p[11]
    c_w = math.sqrt(1.0 - (s / n_w) ** 2)
    # d(H / c_w) = dH / c_w + H (s / n_w^2) / c_w^3 ds, dH = n . dY, ds = a . dY.
    w_s = big_h * s / (n_w * n_w * c_w**3)
    for j in range(3):
        grad[j] = normal[j] / c_w + w_s * p[6 + j]
    return big_h / c_w


@numba.njit(cache=True, error_model="numpy")
def paths_into(
    points: np.ndarray, normal: np.ndarray, d: float, t: float, n_g: float, n_w: float,
    out_path: np.ndarray, out_ok: np.ndarray, out_water: np.ndarray,
    out_water_grad: np.ndarray, out_exits: np.ndarray,
) -> None:  # fmt: skip
    """`light_port.port_paths` of points (M, 3): `solve_paths` into out_path
    (M, PATH_SIZE) (NaN where not ok), out_ok (M,), the water's length (M,) and its
    gradient in Y (M, 3) (NaN, 0 where not ok), the exit points (M, 3) (NaN where not
    ok); BLOCK points at a time."""
    work = np.empty((BLOCK, WORK_SIZE))
    active = np.empty(BLOCK, dtype=np.bool_)
    for lo in range(0, points.shape[0], BLOCK):
        m = min(BLOCK, points.shape[0] - lo)
        solve_paths(
            points[lo:], m, normal, d, t, n_g, n_w, work, active, out_ok[lo:], out_path[lo:]
        )
        for i in range(lo, lo + m):
            p = out_path[i]
            if not out_ok[i]:
                p[:] = np.nan
                out_water[i] = np.nan
                out_water_grad[i, :] = 0.0
                out_exits[i, :] = np.nan
                continue
            out_water[i] = _water(p, work[i - lo, 4], normal, n_w, out_water_grad[i])
            sj, c_a = p[11], p[12]
            radial = d * (sj / c_a) + t * (sj / math.sqrt(n_g * n_g - sj * sj))
            for j in range(3):
                out_exits[i, j] = radial * p[3 + j] + (d + t) * normal[j]


@numba.njit(cache=True, error_model="numpy")
def _attenuate_range(
    lo: int, hi: int, rows: np.ndarray, centers: np.ndarray, camera: np.ndarray,
    light: np.ndarray, R: np.ndarray, normal: np.ndarray, geometry: np.ndarray, c: float,
    flux: np.ndarray, grad: np.ndarray, want_grad: bool, out_dc: np.ndarray,
) -> None:  # fmt: skip
    """`attenuate_rows` of the lit pixels lo..hi-1 (rows[lo:hi] of flux and grad)."""
    d, t, n_g, n_w = geometry[0], geometry[1], geometry[2], geometry[3]
    ys = np.empty((BLOCK, 3))
    paths = np.empty((BLOCK, PATH_SIZE))
    work = np.empty((BLOCK, WORK_SIZE))
    active = np.empty(BLOCK, dtype=np.bool_)
    ok = np.empty(BLOCK, dtype=np.bool_)
    w_grad = np.empty(3)
    g_y = np.empty(3)
    one_camera = camera.shape[0] == 1
    for b in range(lo, hi, BLOCK):
        m = min(BLOCK, hi - b)
        for j in range(m):
            to_light(centers[b + j], light, R, ys[j])
        solve_paths(ys, m, normal, d, t, n_g, n_w, work, active, ok, paths)
        for j in range(m):
            i = b + j
            row = rows[i]
            cam = camera[0] if one_camera else camera[i]
            e0 = centers[i, 0] - cam[0]
            e1 = centers[i, 1] - cam[1]
            e2 = centers[i, 2] - cam[2]
            camera_m = math.sqrt(e0 * e0 + e1 * e1 + e2 * e2)
            # Not ok (not in front of the port: a lit pixel's centre always is): NaN,
            # as the NumPy code's water length.
            water = _water(paths[j], work[j, 4], normal, n_w, w_grad) if ok[j] else math.nan
            length = water + camera_m
            tr = math.exp(-c * length)
            f = flux[row]
            if want_grad:
                cf = -c * tr * f
                y = ys[j]
                for k in range(3):
                    g_y[k] = cf * w_grad[k]
                c0 = g_y[1] * y[2] - g_y[2] * y[1]
                c1 = g_y[2] * y[0] - g_y[0] * y[2]
                c2 = g_y[0] * y[1] - g_y[1] * y[0]
                for k in range(3):
                    grad[row, k] = grad[row, k] * tr - (
                        g_y[0] * R[k, 0] + g_y[1] * R[k, 1] + g_y[2] * R[k, 2]
                    )
                    grad[row, 3 + k] = grad[row, 3 + k] * tr + (
                        c0 * R[k, 0] + c1 * R[k, 1] + c2 * R[k, 2]
                    )
            flux[row] = f * tr
            out_dc[i] = -length * flux[row]


@numba.njit(cache=True, parallel=True, error_model="numpy")
def _attenuate_parallel(
    rows: np.ndarray, centers: np.ndarray, camera: np.ndarray, light: np.ndarray,
    R: np.ndarray, normal: np.ndarray, geometry: np.ndarray, c: float, flux: np.ndarray,
    grad: np.ndarray, want_grad: bool, out_dc: np.ndarray,
) -> None:  # fmt: skip
    """`_attenuate_range` on all threads, in chunks of pixels."""
    n = rows.shape[0]
    n_chunks = min(n, 256)
    for ch in numba.prange(n_chunks):
        _attenuate_range(
            ch * n // n_chunks, (ch + 1) * n // n_chunks, rows, centers, camera, light, R,
            normal, geometry, c, flux, grad, want_grad, out_dc,
        )  # fmt: skip


@numba.njit(cache=True, error_model="numpy")
def _attenuate_serial(
    rows: np.ndarray, centers: np.ndarray, camera: np.ndarray, light: np.ndarray,
    R: np.ndarray, normal: np.ndarray, geometry: np.ndarray, c: float, flux: np.ndarray,
    grad: np.ndarray, want_grad: bool, out_dc: np.ndarray,
) -> None:  # fmt: skip
    """`_attenuate_range` on the calling thread."""
    _attenuate_range(
        int(0),  # noqa: UP018, RUF046 (not a literal type)
        rows.shape[0], rows, centers, camera, light, R, normal, geometry, c, flux, grad,
        want_grad, out_dc,
    )  # fmt: skip


def attenuate_rows(
    rows: np.ndarray,
    centers_world: np.ndarray,
    camera_world: np.ndarray,
    light_world: np.ndarray,
    R_world_light: np.ndarray,
    normal: np.ndarray,
    geometry: np.ndarray,
    c_per_m: float,
    flux: np.ndarray,
    grad: np.ndarray | None,
) -> np.ndarray:
    """Multiply flux[rows] by T in place, with the chain rule on grad[rows] (M, 6) when
    given; returns d (flux T) / dc (L,) (`light_port_flux.attenuate_through_port`).

    Args:
        rows: (L,) the lit pixels' rows of flux and grad; centers_world: (L, 3) their
            footprints' centres; camera_world: (3,) or (L, 3) where the camera's side
            of the path starts, m.
        normal, geometry: as `kernels.port_flux.port_flux_pixels`'.
    """
    n = rows.shape[0]
    out_dc = np.empty(n)
    want_grad = grad is not None
    kernel = _attenuate_serial if n < ATTENUATE_SERIAL_ROWS else _attenuate_parallel
    kernel(
        np.ascontiguousarray(rows, dtype=np.int64),
        np.ascontiguousarray(centers_world, dtype=np.float64).reshape(-1, 3),
        np.ascontiguousarray(camera_world, dtype=np.float64).reshape(-1, 3),
        np.ascontiguousarray(light_world, dtype=np.float64),
        np.ascontiguousarray(R_world_light, dtype=np.float64),
        np.ascontiguousarray(normal, dtype=np.float64),
        np.ascontiguousarray(geometry, dtype=np.float64), float(c_per_m), flux,
        grad if grad is not None else np.zeros((0, 6)), want_grad, out_dc,
    )  # fmt: skip
    return out_dc
