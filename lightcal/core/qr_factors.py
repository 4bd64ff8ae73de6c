"""QR factors of stacked least-squares systems: each image's [J r] reduced to its R factor.

`CalibrationModel` hands trf the QR-compressed problem (the R factor of every image's
(N_i, n + 1) system [J_i r_i], stacked and reduced again), `pipeline.model.fit_scales`
reduces its (m, L) system the same way: no (m, k) matrix is kept.

A tall system is reduced in blocks of `QR_BLOCK_ROWS` rows (each block's copy stays in
the cache, where LAPACK's unblocked Householder sweeps over a narrow matrix run several
times faster than over the whole column), the blocks shared among a few threads (LAPACK
releases the GIL), and the stack of their R factors reduced once more: the R factor of
the whole, up to the signs of its rows. On two cores a 790,000 x 9 system (an image of
the dense sample) took 29 ms in one call and 11 ms so (blocks of 8192 rows: 15 ms).
"""

from __future__ import annotations

import functools
import os
from concurrent.futures import ThreadPoolExecutor

import numpy as np
import scipy.linalg

QR_BLOCK_ROWS = 32768
"""Rows per block of a tall system (32768 x 9 doubles: 2.4 MB)."""

_MAX_THREADS = 4


def economic_r(A: np.ndarray) -> np.ndarray:
    """R (min(N, k), k) of the thin QR of A (N, k) (Fortran order; may be overwritten).

    R is unique up to the signs of its rows, which no least-squares use of it sees.
    """
    n = A.shape[0]
    if n < 4 * QR_BLOCK_ROWS:
        return _r_factor(A)
    starts = range(0, n, QR_BLOCK_ROWS)
    tops = _pool().map(lambda s: _r_factor(np.asfortranarray(A[s : s + QR_BLOCK_ROWS])), starts)
    return _r_factor(np.asfortranarray(np.concatenate(list(tops))))


def _r_factor(A: np.ndarray) -> np.ndarray:
    """R of one LAPACK QR (dgeqrf) of A (N, k), overwritten when Fortran-ordered."""
    qr, _, _, info = scipy.linalg.lapack.dgeqrf(A, overwrite_a=True)
    if info != 0:
        raise np.linalg.LinAlgError(f"QR of the image system failed (LAPACK info {info})")
    return np.triu(qr[: min(A.shape)])


@functools.cache
def _pool() -> ThreadPoolExecutor:
    """The threads that reduce blocks: one per core this process may use, at most 4."""
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
    return ThreadPoolExecutor(
        max_workers=max(1, min(_MAX_THREADS, cores or 1)), thread_name_prefix="lightcal-qr"
    )


def stack_r_factors(tops: list[np.ndarray | None], width: int) -> np.ndarray:
    """R factor (width, width) of the row-stack of matrices whose R factors are `tops`.

    QR of the stacked (k, width) upper-triangular factors is that of the stack of the
    original blocks (Q is orthogonal). A None (a block with non-finite residuals) makes
    the whole result NaN, which trf treats as a failed step.
    """
    if any(t is None for t in tops):
        return np.full((width, width), np.nan)
    out = np.zeros((width, width))
    if tops:
        stack = np.concatenate([t for t in tops if t is not None])
        top = economic_r(np.asfortranarray(stack))
        out[: top.shape[0]] = top
    return out
