"""Single-threaded BLAS around the solver's linear algebra.

The solver's evaluations alternate between numba's parallel kernels (which use every
core) and BLAS/LAPACK calls on tall, thin matrices ((N, 6) x (6, k) products, the QR of
each image's (N, n + 1) system, trf's SVD), which are memory-bound. With OpenBLAS's own
threads competing with numba's OpenMP threads on the same cores, each such call took
several times longer (measured on 2 cores: the dense 12 x 375,000-pixel solve went from
5.5 s with one BLAS thread to 21.6 s with two). `single_threaded_blas` limits BLAS to one
thread for the duration of a block, process-wide (threadpoolctl; OpenMP untouched).
"""

from __future__ import annotations

import functools
from contextlib import AbstractContextManager

from threadpoolctl import ThreadpoolController


@functools.cache
def _controller() -> ThreadpoolController:
    """The loaded thread pools, inspected once (~7 ms)."""
    return ThreadpoolController()


def single_threaded_blas() -> AbstractContextManager[object]:
    """A context manager running its block with BLAS limited to one thread."""
    return _controller().limit(limits=1, user_api="blas")
