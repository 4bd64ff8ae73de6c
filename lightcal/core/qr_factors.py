"""QR factors of stacked least-squares systems: each image's [J r] reduced to its R factor.

`CalibrationModel` hands trf the QR-compressed problem (the R factor of every image's
(N_i, n + 1) system [J_i r_i], stacked and reduced again), `pipeline.model.fit_scales`
reduces its (m, L) system the same way: no (m, k) matrix is kept.
"""

from __future__ import annotations

import numpy as np
import scipy.linalg


def economic_r(A: np.ndarray) -> np.ndarray:
    """R (min(N, k), k) of the thin QR of A (N, k); A (Fortran order) is overwritten."""
    qr, _, _, info = scipy.linalg.lapack.dgeqrf(A, overwrite_a=True)
    if info != 0:
        raise np.linalg.LinAlgError(f"QR of the image system failed (LAPACK info {info})")
    return np.triu(qr[: min(A.shape)])


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
