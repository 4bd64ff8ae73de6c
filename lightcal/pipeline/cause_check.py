"""The candidate causes of a misfit tested at a solution, and the jackknife's ratio.

`cause_tests` fits each cause of `lightcal.core.misfit_causes` beside the model
(`lightcal.core.alternatives`) on the evidence's tested rows, and the `images` cause on
every pixel from each image's Gram blocks; each becomes a `CauseTest` with its pose shift
in statistical sigmas, millimetres and degrees (docs/model.md, "Is the fit explained by
the noise?").
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
from scipy import special

from lightcal.core.alternatives import (
    AlternativeFit,
    GramBlocks,
    RowSet,
    fit_alternative,
    gram_of_columns,
    mahalanobis,
)
from lightcal.core.misfit_causes import cause_columns
from lightcal.core.misfit_verdict import CauseTest
from lightcal.core.solver import CalibrationModel
from lightcal.pipeline.evidence import PixelEvidence


def pose_indices(model: CalibrationModel) -> np.ndarray:
    """The indices of every light's pose parameters in the model's x."""
    return np.concatenate(
        [np.arange(b.pose.start, b.pose.stop) for b in model.layout.blocks]
    ).astype(np.int64)


def pose_shift(model: CalibrationModel, x: np.ndarray, dx: np.ndarray) -> tuple[float, float]:
    """The largest light position (m) and axis (deg) change from x to x + dx."""
    lay = model.layout
    if not np.all(np.isfinite(dx)):
        return math.inf, math.inf
    position, axis = 0.0, 0.0
    x1 = x + dx
    for block in lay.blocks:
        R0, t0 = block.param.to_pose(x[block.pose])
        try:
            R1, t1 = block.param.to_pose(x1[block.pose])
        except (OverflowError, FloatingPointError, ValueError):
            return math.inf, math.inf
        position = max(position, float(np.linalg.norm(t1 - t0)))
        c = float(np.clip(R0[:, 2] @ R1[:, 2], -1.0, 1.0))
        axis = max(axis, math.degrees(math.acos(c)))
    return position, axis


def _image_cause(
    ev: PixelEvidence, N: np.ndarray, P: np.ndarray, rss: float, m: int
) -> AlternativeFit:
    """The `images` cause: every image its own deviation of the lights' pose parameters P
    (columns J_i[:, P] on image i's rows only), on every pixel."""
    grams = ev.image_grams
    k = P.size
    K = len(grams)
    n = N.shape[0]
    StS = np.zeros((K * k, K * k))
    CtC = np.zeros((K * k, K * k))
    StJ = np.zeros((K * k, n))
    CtK = np.zeros((K * k, n))
    KtK = np.zeros((n, n))
    Str = np.zeros(K * k)
    g = np.zeros(n)
    for i, (N_i, g_i, H_i) in enumerate(grams):
        block = slice(i * k, (i + 1) * k)
        StS[block, block] = N_i[np.ix_(P, P)]
        CtC[block, block] = H_i[np.ix_(P, P)]
        StJ[block] = N_i[P]
        CtK[block] = H_i[P]
        KtK += H_i
        Str[block] = g_i[P]
        g += g_i
    rows = RowSet(N, g, rss, m, ev.signal2)
    return fit_alternative(rows, GramBlocks(StS, StJ, Str, CtC, CtK, KtK))


def cause_tests(
    model: CalibrationModel,
    x: np.ndarray,
    ev: PixelEvidence,
    statistical_pose_cov: np.ndarray,
    expected_extra: float,
) -> tuple[list[CauseTest], dict[str, np.ndarray]]:
    """Every candidate cause of a misfit fitted beside the model
    (`lightcal.core.alternatives`), and each one's shift of x (n,).

    The causes of `misfit_causes.cause_columns` are tested on the seeded rows
    `ev.tested`; `images` on every pixel, its cost decrease less what the camera poses'
    declared errors leave (`expected_extra`: they make each image want its own pose)."""
    P = pose_indices(model)
    t = ev.tested
    out: list[CauseTest] = []
    shifts: dict[str, np.ndarray] = {}
    if t.r.size > model.layout.n + 1:
        rows = RowSet(
            t.J.T @ t.J,
            t.J.T @ t.r,
            float(t.r @ t.r),
            int(t.r.size),
            float(t.features.signal @ t.features.signal),
        )
        for name, (C, signs) in cause_columns(t.features).items():
            S = C / t.sigma[:, None]
            fit = fit_alternative(rows, gram_of_columns(S, t.J, t.r, t.sigma, signs))
            out.append(_cause_test(model, x, name, fit, statistical_pose_cov, P))
            shifts[name] = fit.shift
    N_full = model.normal_matrix(x)
    rss = ev.rss
    fit = _image_cause(ev, N_full, P, rss, model.m)
    if fit.k > 0:
        adjusted = max(fit.delta_chi2 - max(expected_extra, 0.0), 0.0)
        if adjusted != fit.delta_chi2:
            dof2 = model.m - model.layout.n - fit.k
            rss1 = max(rss - fit.delta_chi2, 1e-300)
            f_stat = (adjusted / fit.k) / (rss1 / dof2)
            fit = replace(
                fit,
                delta_chi2=adjusted,
                f_statistic=f_stat,
                p_value=float(special.fdtrc(fit.k, dof2, f_stat)),
            )
    # Its shift is the jackknife's (`diagnose`): none of its own.
    out.append(_as_test("images", fit, math.nan, (math.nan, math.nan)))
    return out, shifts


def _cause_test(
    model: CalibrationModel,
    x: np.ndarray,
    name: str,
    fit: AlternativeFit,
    statistical_pose_cov: np.ndarray,
    P: np.ndarray,
) -> CauseTest:
    shift_sigma = mahalanobis(fit.shift[P], statistical_pose_cov)
    return _as_test(name, fit, shift_sigma, pose_shift(model, x, fit.shift))


def _as_test(
    name: str, fit: AlternativeFit, shift_sigma: float, shift: tuple[float, float]
) -> CauseTest:
    """The `CauseTest` of a fitted cause, its shift in sigmas, m and deg given."""
    return CauseTest(
        name,
        fit.k,
        fit.delta_chi2,
        fit.f_statistic,
        fit.p_value,
        fit.relative_effect,
        fit.bic_gain,
        shift_sigma,
        shift[0],
        shift[1],
    )


def jackknife_ratio(jack: np.ndarray | None, statistical: np.ndarray, P: np.ndarray) -> float:
    """sqrt of the largest generalised eigenvalue of the jackknife's pose block over the
    statistical one: how many statistical sigmas the jackknife's sigma is in the pose's
    worst direction (NaN without a jackknife)."""
    if jack is None:
        return math.nan
    excess = jack[np.ix_(P, P)]
    c = statistical[np.ix_(P, P)]
    w, U = np.linalg.eigh(0.5 * (c + c.T))
    top = float(w.max()) if w.size else 0.0
    if not top > 0.0:
        return math.nan
    keep = w > 1e-12 * top
    W = U[:, keep] / np.sqrt(w[keep])
    lam = np.linalg.eigvalsh(W.T @ excess @ W)
    return float(math.sqrt(max(float(lam.max()), 0.0)))
