"""Quantiles of large arrays from order statistics found by a histogram, equal to
NumPy's.

np.quantile partitions the array at every rank it needs: for a dozen quantiles of
millions of values, a dozen passes of introselect. `order_statistics` finds the values at
given ranks in three passes (a histogram of the values, then only the bins holding the
ranks gathered and sorted); `quantiles` interpolates them as NumPy's "linear" method
does, so the results are NumPy's bit for bit (tested on float32 and float64 with ties).
"""

from __future__ import annotations

import numba
import numpy as np


@numba.njit(cache=True, nogil=True)
def order_statistics(values: np.ndarray, ranks: np.ndarray) -> np.ndarray:
    """The values at 0-based positions `ranks` (k,) of `values` (m,) sorted ascending
    (finite), without sorting them: a histogram of min(m, 65536) equal bins between the
    smallest and largest value finds each rank's bin, and only those bins' values are
    gathered and sorted (values in a lower bin are never larger: the bin index is a
    monotone function of the value). Three passes over `values` where np.partition at a
    dozen ranks takes several. Releases the GIL (image readers call it on their threads).

    Returns:
        (k,) in the dtype of `values`.
    """
    m = values.shape[0]
    k = ranks.shape[0]
    out = np.empty(k, dtype=values.dtype)
    lo = values[0]
    hi = values[0]
    for i in range(m):
        v = values[i]
        lo = min(lo, v)
        hi = max(hi, v)
    if not hi > lo:
        out[:] = lo
        return out
    n_bins = max(1, min(m, 65536))
    scale = n_bins / (float(hi) - float(lo))
    counts = np.zeros(n_bins, dtype=np.int64)
    for i in range(m):
        counts[min(int((float(values[i]) - float(lo)) * scale), n_bins - 1)] += 1
    start = np.zeros(n_bins + 1, dtype=np.int64)
    for b in range(n_bins):
        start[b + 1] = start[b] + counts[b]
    bin_of = np.empty(k, dtype=np.int64)
    offset = np.full(n_bins, -1, dtype=np.int64)
    gathered = 0
    for j in range(k):
        b = np.searchsorted(start, ranks[j], side="right") - 1
        bin_of[j] = b
        if offset[b] < 0:
            offset[b] = gathered
            gathered += counts[b]
    buffer = np.empty(gathered, dtype=values.dtype)
    fill = offset.copy()
    for i in range(m):
        b = min(int((float(values[i]) - float(lo)) * scale), n_bins - 1)
        if offset[b] >= 0:
            buffer[fill[b]] = values[i]
            fill[b] += 1
    for b in range(n_bins):
        if offset[b] >= 0:
            buffer[offset[b] : offset[b] + counts[b]].sort()
    for j in range(k):
        b = bin_of[j]
        out[j] = buffer[offset[b] + ranks[j] - start[b]]
    return out


def quantiles(values: np.ndarray, q: np.ndarray) -> np.ndarray:
    """np.quantile(values, q) (the "linear" method), equal to it; for finite values
    from the order statistics `order_statistics` finds, several times faster than
    NumPy's partition at every rank on large arrays (and without its per-call overhead
    on small ones).

    Args:
        values: any shape, flattened as np.quantile does.
        q: (k,) in [0, 1].

    Returns:
        (len(q),) float64.
    """
    m = values.size
    # NumPy itself for an empty array (its error), NaN (NaN everywhere) and infinities (the
    # histogram needs a finite range).
    if m == 0 or not np.isfinite(values).all():
        return np.quantile(values, q)
    # NumPy's linear method: virtual index (m - 1) q between its floor and the next rank,
    # interpolated as numpy.lib._function_base_impl._lerp does, in the same dtypes.
    virtual = (m - 1) * np.asarray(q, dtype=np.float64)
    below = np.floor(virtual)
    gamma = virtual - below
    below_i = np.minimum(below.astype(np.intp), m - 1)
    above_i = np.minimum(below_i + 1, m - 1)
    ranks = np.unique(np.concatenate([below_i, above_i])).astype(np.int64)
    stats = order_statistics(np.ravel(values), ranks)  # ravel: contiguous, 1-D
    a = stats[np.searchsorted(ranks, below_i)]
    b = stats[np.searchsorted(ranks, above_i)]
    diff = b - a
    out = a + diff * gamma
    np.subtract(b, diff * (1 - gamma), out=out, where=gamma >= 0.5)
    return out


def percentile(values: np.ndarray, p: float) -> float:
    """float(np.percentile(values, p)), equal to it, by `quantiles` (p in [0, 100])."""
    return float(quantiles(values, np.array([p / 100.0]))[0])
