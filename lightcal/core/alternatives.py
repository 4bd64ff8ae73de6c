"""Alternative explanations of a misfit: what each candidate cause would change.

After a solve the weighted residuals r (m,) = (m_obs - m_render) / sigma are orthogonal
to the columns of the weighted Jacobian J = d r / d x (m, n). A candidate cause c of a
misfit (room light, an undeclared vignetting, gloss, ...) is a model extension with k_c
parameters gamma whose rendered change is, to first order, C_c gamma: C_c (m, k_c) in value
units, S_c = C_c / sigma in the solver's units. Refitting x and gamma together from the
solution (Gauss-Newton, r(x + dx) - S gamma ~ r + J dx - S gamma):

    N dx - J^T S gamma = -g,    -S^T J dx + S^T S gamma = S^T r,

N = J^T J and g = J^T r (0 at the solution of these very rows; not on a subsample). So

    M gamma = S^T (r - J N^-1 g),   M = S^T S - S^T J N^-1 J^T S,
    dx_c = N^-1 J^T S gamma        (the shift of the estimate the cause accounts for),
    dchi2_c = gamma^T M gamma      (the decrease of the cost it brings).

dx_c is the omitted-variable bias of the estimate under cause c. gamma is tested by a
heteroscedasticity-consistent (White) Wald test, which holds whatever the residuals'
variance does across pixels (`GramBlocks.StDS`; the F test of dchi2_c without them).
Its size is the rendered values' net change |C gamma - K dx_c| (K = J sigma: what the
refitted model parameters take back) relative to the signal's sqrt(sum (m_render -
offset)^2) (`AlternativeFit.relative_effect`). Where physics fixes a coefficient's sign
(`GramBlocks.signs`), gamma is the sign-constrained minimiser and dchi2_c its decrease.
Columns the model already spans (a constant ambient when the offset is estimated) drop
out of M: its eigenvalues below `RANK_TOL` of the largest are not inverted, and k_c
counts the rest.

Everything here is linear algebra on Gram matrices (`GramBlocks`); what the columns are
is `lightcal.core.misfit_causes`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy import special

#: Eigenvalues of M below this fraction of its largest are taken as 0: a direction of the
#: (unit-norm) columns that is 99.9999 % in J's span is no evidence of its own, and its
#: coefficient would only amplify the noise into a meaningless shift.
RANK_TOL = 1e-6


@dataclass(frozen=True)
class GramBlocks:
    """The Gram quantities of one candidate's columns with the model's rows.

    Attributes:
        StS: (k, k) S^T S (solver units).
        StJ: (k, n) S^T J.
        Str: (k,) S^T r.
        CtC: (k, k) C^T C, the columns in value units (C = S sigma).
        CtK: (k, n) C^T K, K = J sigma the Jacobian in value units.
        KtK: (n, n) K^T K.
        signs: (k,) the sign each coefficient must have (+1, -1; 0: free), or None
            (all free): a glossy highlight adds light, absorption takes it away.
        StDS, StDJ, JtDJ: (k, k), (k, n), (n, n) the same Grams weighted by the squared
            residuals D = diag(r^2), for the heteroscedasticity-consistent test; None:
            the F test (which assumes every residual has the same variance).
    """

    StS: np.ndarray
    StJ: np.ndarray
    Str: np.ndarray
    CtC: np.ndarray
    CtK: np.ndarray
    KtK: np.ndarray
    signs: np.ndarray | None = None
    StDS: np.ndarray | None = None
    StDJ: np.ndarray | None = None
    JtDJ: np.ndarray | None = None


@dataclass(frozen=True)
class RowSet:
    """The rows the candidates are tested on.

    Attributes:
        N: (n, n) J^T J over these rows.
        g: (n,) J^T r over these rows (0 at the solution when they are all the rows).
        rss: r^T r over these rows.
        m: the row count.
        signal2: sum over these rows of (m_render - offset)^2, value units.
    """

    N: np.ndarray
    g: np.ndarray
    rss: float
    m: int
    signal2: float

    @property
    def n(self) -> int:
        return int(self.N.shape[0])


@dataclass(frozen=True)
class AlternativeFit:
    """One candidate cause fitted beside the model (see the module docstring).

    Attributes:
        k: columns that are not in the model's span (the F test's numerator dof).
        delta_chi2: decrease of the cost (solver units).
        f_statistic, p_value: the test of the cause's coefficients: the
            heteroscedasticity-consistent Wald statistic over k (chi^2 with k degrees of
            freedom) when the blocks carry the residual-weighted Grams, else the F test of
            the cost decrease against the residual variance left by the extended fit
            (p = 1 when k = 0).
        relative_effect: |C gamma - K dx| / sqrt(sum (m_render - offset)^2): the RMS of
            the rendered values' change (the cause's correction net of what the refitted
            model parameters take back) relative to the signal's.
        shift: (n,) dx_c, the estimate's shift the cause accounts for.
        bic_gain: m ln(rss / (rss - delta_chi2)) - k ln m (> 0: the cause is worth its
            parameters by the Bayesian information criterion).
    """

    k: int
    delta_chi2: float
    f_statistic: float
    p_value: float
    relative_effect: float
    shift: np.ndarray
    bic_gain: float


def _solve_inverse(N: np.ndarray, B: np.ndarray) -> np.ndarray:
    """N^-1 B (pseudo-inverse where N is singular)."""
    try:
        return np.linalg.solve(N, B)
    except np.linalg.LinAlgError:
        return np.linalg.pinv(N) @ B


def fit_alternative(rows: RowSet, blocks: GramBlocks) -> AlternativeFit:
    """Fit one candidate's columns beside the model on `rows` (module docstring)."""
    n = rows.n
    k_all = blocks.StS.shape[0]
    empty = AlternativeFit(0, 0.0, 0.0, 1.0, 0.0, np.zeros(n), -math.inf)
    if k_all == 0 or rows.m <= n + 1:
        return empty
    # Columns scaled to unit norm: M's eigenvalues then compare like with like.
    norms = np.sqrt(np.maximum(np.diag(blocks.StS), 0.0))
    keep = norms > 0.0
    if not keep.any():
        return empty
    d = np.where(keep, 1.0 / np.where(keep, norms, 1.0), 0.0)
    StS = blocks.StS * np.outer(d, d)
    StJ = blocks.StJ * d[:, None]
    Ninv_JtS = _solve_inverse(rows.N, StJ.T)  # (n, k)
    M = StS - StJ @ Ninv_JtS
    M = 0.5 * (M + M.T)
    rhs = d * blocks.Str - StJ @ _solve_inverse(rows.N, rows.g)
    w, V = np.linalg.eigh(M)
    top = float(w.max()) if w.size else 0.0
    if not top > 0.0:
        return empty
    use = w > RANK_TOL * top
    k = int(np.count_nonzero(use))
    signs = np.zeros(k_all) if blocks.signs is None else np.asarray(blocks.signs, dtype=float)
    gamma_scaled = _signed_minimiser(w[use], V[:, use], rhs, signs)
    # The cost decrease: gamma^T M gamma - 2 gamma^T rhs, negated (= proj^T w^-1 proj when
    # no sign binds).
    delta = max(float(2.0 * gamma_scaled @ rhs - gamma_scaled @ M @ gamma_scaled), 0.0)
    rss0 = rows.rss - float(rows.g @ _solve_inverse(rows.N, rows.g))
    rss1 = max(rss0 - delta, 0.0)
    dof2 = rows.m - n - k
    if dof2 <= 0 or k == 0:
        return empty
    if delta <= 0.0:
        f_stat, p = 0.0, 1.0
    elif blocks.StDS is not None and blocks.StDJ is not None and blocks.JtDJ is not None:
        f_stat, p = _robust_wald(blocks, d, Ninv_JtS, M, V[:, use], gamma_scaled)
    elif rss1 > 0.0:
        f_stat = (delta / k) / (rss1 / dof2)
        p = float(special.fdtrc(k, dof2, f_stat))
    else:
        f_stat, p = math.inf, 0.0
    gamma = d * gamma_scaled
    shift = Ninv_JtS @ gamma_scaled
    energy = float(
        gamma @ blocks.CtC @ gamma - 2.0 * gamma @ blocks.CtK @ shift + shift @ blocks.KtK @ shift
    )
    relative = math.sqrt(max(energy, 0.0) / rows.signal2) if rows.signal2 > 0 else math.inf
    if rss0 > 0.0 and rss1 > 0.0:
        bic_gain = rows.m * math.log(rss0 / rss1) - k * math.log(rows.m)
    else:
        bic_gain = math.inf if delta > 0 else -math.inf
    return AlternativeFit(k, delta, f_stat, p, relative, shift, bic_gain)


def _robust_wald(
    blocks: GramBlocks,
    d: np.ndarray,
    A: np.ndarray,
    M: np.ndarray,
    Vu: np.ndarray,
    gamma: np.ndarray,
) -> tuple[float, float]:
    """(W / k, p) of the heteroscedasticity-consistent Wald test of gamma (White's
    sandwich): with the columns' part outside J's span S~ = S d - J A (A = N^-1 J^T S d),
    Cov(gamma) = M^+ (S~^T D S~) M^+, D = diag(r^2), and W = gamma^T Cov^+ gamma on the
    r used directions Vu (k, r) of M, chi^2 with r degrees of freedom under "no effect".
    Unlike the F test it holds when the residuals' variance varies with the signal (a
    sensor's shot noise under unit weights), which would otherwise make any column that
    weighs bright pixels look significant."""
    assert blocks.StDS is not None and blocks.StDJ is not None and blocks.JtDJ is not None
    StDS = blocks.StDS * np.outer(d, d)
    StDJ = blocks.StDJ * d[:, None]
    cross = StDJ @ A
    meat = StDS - cross - cross.T + A.T @ blocks.JtDJ @ A
    meat_u = Vu.T @ (0.5 * (meat + meat.T)) @ Vu
    b = Vu.T @ (M @ gamma)
    r = Vu.shape[1]
    try:
        wald = float(b @ np.linalg.solve(meat_u, b))
    except np.linalg.LinAlgError:
        wald = float(b @ np.linalg.pinv(meat_u) @ b)
    if not math.isfinite(wald) or wald < 0.0:
        return math.inf, 0.0
    return wald / r, float(special.chdtrc(r, wald))


def _signed_minimiser(
    w: np.ndarray, V: np.ndarray, rhs: np.ndarray, signs: np.ndarray
) -> np.ndarray:
    """argmin over gamma of gamma^T M gamma - 2 gamma^T rhs, M = V diag(w) V^T (w > 0,
    V (k, r)), with sign(gamma_j) = signs_j where signs_j != 0.

    As least squares |A gamma - t|^2, A = diag(sqrt w) V^T and t = diag(1 / sqrt w) V^T rhs
    (the same up to a constant), over gamma = E u, u >= 0, each free coefficient split
    into a positive and a negative part (`scipy.optimize.nnls`)."""
    if not np.any(signs):
        return V @ ((V.T @ rhs) / w)
    from scipy.optimize import nnls

    A = np.sqrt(w)[:, None] * V.T
    t = (V.T @ rhs) / np.sqrt(w)
    columns = []
    for j, sj in enumerate(signs):
        e = np.zeros(signs.size)
        if sj == 0:
            e[j] = 1.0
            columns.append(e.copy())
            e[j] = -1.0
            columns.append(e)
        else:
            e[j] = float(np.sign(sj))
            columns.append(e)
    E = np.array(columns).T
    u, _ = nnls(A @ E, t, maxiter=50 * E.shape[1])
    return E @ u


def gram_of_columns(
    S: np.ndarray,
    J: np.ndarray,
    r: np.ndarray,
    sigma: np.ndarray,
    signs: np.ndarray | None = None,
) -> GramBlocks:
    """The Gram blocks of columns S (N, k) in solver units with rows J (N, n), r (N,);
    sigma (N,) turns S and J back into value units; signs as `GramBlocks.signs`; the
    residual-weighted Grams for the heteroscedasticity-consistent test."""
    C = S * sigma[:, None]
    K = J * sigma[:, None]
    DS = S * (r * r)[:, None]
    DJ = J * (r * r)[:, None]
    return GramBlocks(
        S.T @ S, S.T @ J, S.T @ r, C.T @ C, C.T @ K, K.T @ K, signs, DS.T @ S, DS.T @ J, DJ.T @ J
    )


def mahalanobis(shift: np.ndarray, covariance: np.ndarray) -> float:
    """sqrt(shift^T covariance^-1 shift) (pseudo-inverse where it is singular); inf when
    the shift lies where the covariance has no variance."""
    c = 0.5 * (covariance + covariance.T)
    w, V = np.linalg.eigh(c)
    top = float(w.max()) if w.size else 0.0
    if not top > 0.0:
        return math.inf if np.any(shift != 0.0) else 0.0
    p = V.T @ shift
    small = w <= 1e-12 * top
    if np.any(np.abs(p[small]) > 1e-9 * max(float(np.abs(p).max()), 1e-300)):
        return math.inf
    big = ~small
    return float(math.sqrt(np.sum(p[big] ** 2 / w[big])))


def jackknife_covariance(
    N: np.ndarray, parts: list[tuple[np.ndarray, np.ndarray]]
) -> np.ndarray | None:
    """The leave-one-image-out jackknife covariance of the estimate, one Gauss-Newton step
    from the solution per image.

    Without image i (N_i = J_i^T J_i, g_i = J_i^T r_i), the solution moves by
    d_i = (N - N_i)^-1 g_i (at the solution sum_i g_i = 0). The jackknife covariance is
    (K - 1) / K sum_i (d_i - mean d)(d_i - mean d)^T.

    Args:
        N: (n, n) the normal matrix over every image.
        parts: per image (N_i (n, n), g_i (n,)).

    Returns:
        (n, n), or None with fewer than 3 images or when leaving one out makes the
        problem singular (that image alone determines some parameter).
    """
    K = len(parts)
    if K < 3:
        return None
    d = []
    for N_i, g_i in parts:
        A = N - N_i
        w = np.linalg.eigvalsh(0.5 * (A + A.T))
        if not (w.size and w.min() > 1e-12 * max(float(w.max()), 1e-300)):
            return None
        d.append(np.linalg.solve(A, g_i))
    D = np.array(d)
    D -= D.mean(axis=0)
    return (K - 1) / K * (D.T @ D)


def excess_covariance(observed: np.ndarray, expected: np.ndarray) -> np.ndarray:
    """The part of `observed` (n, n) beyond `expected` (n, n), both covariances: with the
    generalised eigenvectors V of (observed, expected) (V^T expected V = I), the
    directions where observed exceeds expected keep the excess,
    expected V max(L - 1, 0) V^T expected. Where `expected` is singular, the excess is
    taken in its range only (its null directions are unknown there, not small)."""
    e = 0.5 * (expected + expected.T)
    o = 0.5 * (observed + observed.T)
    w, U = np.linalg.eigh(e)
    top = float(w.max()) if w.size else 0.0
    if not top > 0.0:
        return np.zeros_like(e)
    keep = w > 1e-12 * top
    W = U[:, keep] / np.sqrt(w[keep])  # whitening: W^T e W = I
    lam, Q = np.linalg.eigh(W.T @ o @ W)
    B = e @ W @ Q  # expected V, V = W Q
    out = (B * np.maximum(lam - 1.0, 0.0)) @ B.T
    return 0.5 * (out + out.T)
