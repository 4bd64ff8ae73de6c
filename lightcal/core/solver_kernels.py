"""Compiled (numba) assembly of each image's [J r] system for the solver.

NumPy built each image's system in several passes over its (N, n + 1) rows (a product,
column assignments, a row scaling, the residual), each a trip through memory; these
kernels do it in one pass per light plus one final pass: rows in parallel for large
images, on the calling thread for small ones (`PARALLEL_MIN_ROWS`), where waking the
thread pool would cost more than the work (with OMP_WAIT_POLICY=passive the paper-sized
solve took 3x longer). The row loops are inlined into a parallel and a serial entry point
(separate functions: numba's cache does not tell apart two compilations of one function
with different options).
"""

from __future__ import annotations

import numba
import numpy as np

#: Images with at least this many rows use the parallel kernels.
PARALLEL_MIN_ROWS = 20_000
_CHUNKS = 64


@numba.njit(cache=True, inline="always")
def _light_rows(
    i0: int,
    i1: int,
    A: np.ndarray,
    total: np.ndarray,
    grad_world: np.ndarray,
    flux: np.ndarray,
    pose_map: np.ndarray,
    pose_start: int,
    scale_column: int,
    d_value_d_log_scale_per_flux: float,
    scale: float,
) -> None:
    k = pose_map.shape[1]
    for i in range(i0, i1):
        for c in range(k):
            acc = 0.0
            for d in range(6):
                acc += grad_world[i, d] * pose_map[d, c]
            A[i, pose_start + c] = acc
        A[i, scale_column] = d_value_d_log_scale_per_flux * flux[i]
        total[i] += scale * flux[i]


@numba.njit(cache=True, parallel=True)
def _add_light_columns_parallel(
    A: np.ndarray,
    total: np.ndarray,
    grad_world: np.ndarray,
    flux: np.ndarray,
    pose_map: np.ndarray,
    pose_start: int,
    scale_column: int,
    d_value_d_log_scale_per_flux: float,
    scale: float,
) -> None:
    n = A.shape[0]
    for ch in numba.prange(_CHUNKS):
        _light_rows(
            ch * n // _CHUNKS,
            (ch + 1) * n // _CHUNKS,
            A,
            total,
            grad_world,
            flux,
            pose_map,
            pose_start,
            scale_column,
            d_value_d_log_scale_per_flux,
            scale,
        )


@numba.njit(cache=True)
def _add_light_columns_serial(
    A: np.ndarray,
    total: np.ndarray,
    grad_world: np.ndarray,
    flux: np.ndarray,
    pose_map: np.ndarray,
    pose_start: int,
    scale_column: int,
    d_value_d_log_scale_per_flux: float,
    scale: float,
) -> None:
    _light_rows(
        0,
        A.shape[0],
        A,
        total,
        grad_world,
        flux,
        pose_map,
        pose_start,
        scale_column,
        d_value_d_log_scale_per_flux,
        scale,
    )


def add_light_columns(
    A: np.ndarray,
    total: np.ndarray,
    grad_world: np.ndarray,
    flux: np.ndarray,
    pose_map: np.ndarray,
    pose_start: int,
    scale_column: int,
    d_value_d_log_scale_per_flux: float,
    scale: float,
) -> None:
    """Write one light's pose and log-scale columns of d m_render / d x and add its values.

    Args:
        A: (N, n + 1) the image's system (pose columns written, not added).
        total: (N,) sum over lights of scale * flux, added to.
        grad_world: (N, 6) d flux / d (L_world, delta_world).
        flux: (N,) the light's flux per unit scale.
        pose_map: (6, k) world gradient -> the light's k pose columns, gain and scale included.
        pose_start: the first pose column.
        scale_column: the log-scale column.
        d_value_d_log_scale_per_flux: gain * s (d m / d log s = gain * s * flux), or 0
            where log s is clipped.
        scale: s.
    """
    kernel = (
        _add_light_columns_parallel
        if A.shape[0] >= PARALLEL_MIN_ROWS
        else _add_light_columns_serial
    )
    kernel(
        A,
        total,
        grad_world,
        flux,
        pose_map,
        pose_start,
        scale_column,
        d_value_d_log_scale_per_flux,
        scale,
    )


@numba.njit(cache=True, inline="always")
def _finish(
    i0: int,
    i1: int,
    A: np.ndarray,
    total: np.ndarray,
    valid: np.ndarray,
    observed: np.ndarray,
    sigma: np.ndarray,
    gain: float,
    offset: float,
    gain_column: int,
    offset_column: int,
    stats: np.ndarray,
) -> None:
    """Rows i0 .. i1 - 1 (see `finish_rows`); stats (2,) receives the sum of (r sigma)^2
    and the number of rows whose r is not finite."""
    n = A.shape[1] - 1
    ssq = 0.0
    bad = 0
    for i in range(i0, i1):
        m = offset + gain * total[i] if valid[i] else np.nan
        if gain_column >= 0:
            A[i, gain_column] = m - offset
        if offset_column >= 0:
            A[i, offset_column] = 1.0
        inv = 1.0 / sigma[i]
        for c in range(n):
            A[i, c] = -A[i, c] * inv
        r = (observed[i] - m) * inv
        A[i, n] = r
        d = r * sigma[i]
        finite = abs(r) < np.inf  # False for NaN and infinities
        ssq += d * d
        bad += not finite
    stats[0] = ssq
    stats[1] = bad


@numba.njit(cache=True, parallel=True)
def _finish_rows_parallel(
    A: np.ndarray,
    total: np.ndarray,
    valid: np.ndarray,
    observed: np.ndarray,
    sigma: np.ndarray,
    gain: float,
    offset: float,
    gain_column: int,
    offset_column: int,
    stats: np.ndarray,
) -> None:
    n = A.shape[0]
    partial = np.zeros((_CHUNKS, 2))
    for ch in numba.prange(_CHUNKS):
        _finish(
            ch * n // _CHUNKS,
            (ch + 1) * n // _CHUNKS,
            A,
            total,
            valid,
            observed,
            sigma,
            gain,
            offset,
            gain_column,
            offset_column,
            partial[ch],
        )
    stats[0] = 0.0
    stats[1] = 0.0
    for ch in range(_CHUNKS):
        stats[0] += partial[ch, 0]
        stats[1] += partial[ch, 1]


@numba.njit(cache=True)
def _finish_rows_serial(
    A: np.ndarray,
    total: np.ndarray,
    valid: np.ndarray,
    observed: np.ndarray,
    sigma: np.ndarray,
    gain: float,
    offset: float,
    gain_column: int,
    offset_column: int,
    stats: np.ndarray,
) -> None:
    _finish(
        0,
        A.shape[0],
        A,
        total,
        valid,
        observed,
        sigma,
        gain,
        offset,
        gain_column,
        offset_column,
        stats,
    )


def finish_rows(
    A: np.ndarray,
    total: np.ndarray,
    valid: np.ndarray,
    observed: np.ndarray,
    sigma: np.ndarray,
    gain: float,
    offset: float,
    gain_column: int,
    offset_column: int,
) -> tuple[float, bool]:
    """Values, the gain and offset columns, d r / d x = -(d m / d x) / sigma and r.

    m = offset + gain * total (NaN where the footprint is invalid); column -1 of A
    receives r = (observed - m) / sigma. `gain_column` / `offset_column` < 0: none.

    Args:
        A: (N, n + 1) the image's system, columns 0..n-1 holding d m / d x.
        total: (N,) sum over lights of scale * flux.
        valid: (N,) footprints that are valid.
        observed, sigma: (N,) the measured values and their noise.
        gain, offset: the image's gain and the offset.
        gain_column, offset_column: their columns, or -1.

    Returns:
        (sum of (r sigma)^2, whether every r is finite), in the same pass: the RMS of
        the image's residuals in value units, and whether its system can be reduced.
    """
    kernel = _finish_rows_parallel if A.shape[0] >= PARALLEL_MIN_ROWS else _finish_rows_serial
    stats = np.zeros(2)
    kernel(A, total, valid, observed, sigma, gain, offset, gain_column, offset_column, stats)
    return float(stats[0]), stats[1] == 0
