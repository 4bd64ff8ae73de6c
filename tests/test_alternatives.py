"""The candidate-cause algebra (`lightcal.core.alternatives`) against direct least squares.

On a linear problem r = y - J x the one-step formulas are exact: the cause's coefficient,
the shift of x and the cost decrease equal those of the augmented least-squares fit
[J S]; the one-step jackknife equals refitting without each block of rows.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from lightcal.core.alternatives import (
    RowSet,
    excess_covariance,
    fit_alternative,
    gram_of_columns,
    jackknife_covariance,
    mahalanobis,
)


def _problem(seed: int, m: int = 400, n: int = 4, k: int = 2, effect: float = 0.0):
    rng = np.random.default_rng(seed)
    J = rng.normal(size=(m, n))
    S = rng.normal(size=(m, k))
    y = J @ rng.normal(size=n) + effect * S @ np.ones(k) + rng.normal(size=m)
    x = np.linalg.lstsq(J, y, rcond=None)[0]
    r = y - J @ x  # the residuals at the solution: J^T r = 0
    return J, S, y, r


def _rows(J: np.ndarray, r: np.ndarray, signal2: float = 1.0) -> RowSet:
    return RowSet(J.T @ J, J.T @ r, float(r @ r), J.shape[0], signal2)


def test_the_one_step_fit_is_the_augmented_least_squares_fit() -> None:
    J, S, y, r = _problem(1, effect=0.5)
    # The solver's r = obs - model and J_solver = d r / d x = -J.
    fit = fit_alternative(_rows(-J, r), gram_of_columns(S, -J, r, np.ones(len(r))))
    full = np.linalg.lstsq(np.hstack([J, S]), y, rcond=None)[0]
    x0 = np.linalg.lstsq(J, y, rcond=None)[0]
    np.testing.assert_allclose(fit.shift, full[: J.shape[1]] - x0, rtol=1e-9, atol=1e-12)
    rss0 = float(r @ r)
    rss1 = float(np.sum((y - np.hstack([J, S]) @ full) ** 2))
    assert fit.delta_chi2 == pytest.approx(rss0 - rss1, rel=1e-9)
    assert fit.k == 2
    assert fit.p_value < 1e-6


def test_no_effect_is_not_significant_in_most_seeds() -> None:
    p = [
        fit_alternative(_rows(J, r), gram_of_columns(S, J, r, np.ones(len(r)))).p_value
        for J, S, _, r in (_problem(seed) for seed in range(200))
    ]
    # A test at 5 %: about 10 of 200 by chance.
    assert 2 <= sum(v < 0.05 for v in p) <= 22


def test_a_column_in_the_models_span_drops_out() -> None:
    J, S, _, r = _problem(2, effect=0.5)
    S = np.hstack([S, J[:, :1] * 3.0])  # the third column is the model's own
    fit = fit_alternative(_rows(J, r), gram_of_columns(S, J, r, np.ones(len(r))))
    assert fit.k == 2


def test_a_sign_constraint_that_binds_gives_no_effect() -> None:
    J, S, _, r = _problem(3, k=1, effect=-2.0)
    P = np.eye(len(r)) - J @ np.linalg.solve(J.T @ J, J.T)
    wanted = float(np.sign(S[:, 0] @ P @ r))  # the sign of the free coefficient (k = 1)
    free = fit_alternative(_rows(J, r), gram_of_columns(S, J, r, np.ones(len(r))))
    allowed = gram_of_columns(S, J, r, np.ones(len(r)), np.array([wanted]))
    bound = gram_of_columns(S, J, r, np.ones(len(r)), np.array([-wanted]))
    assert free.delta_chi2 > 100.0
    assert fit_alternative(_rows(J, r), allowed).delta_chi2 == pytest.approx(free.delta_chi2)
    fit = fit_alternative(_rows(J, r), bound)
    assert fit.delta_chi2 == 0.0 and fit.p_value == 1.0
    assert np.all(fit.shift == 0.0)


def test_the_wald_test_holds_when_the_noise_grows_with_the_signal() -> None:
    """Noise that grows with the signal (unit weights, as without a noise model) and a
    column on the brightest pixels: the sandwich test keeps its 5 % false-alarm rate, the
    F test (which assumes one variance) raises twice as many alarms."""
    alarms = {"wald": 0, "f": 0}
    for seed in range(200):
        rng = np.random.default_rng(100 + seed)
        m = 400
        level = rng.uniform(0.1, 10.0, size=m)
        J = np.stack([level, np.ones(m)], axis=1)
        S = np.where(level > 8.0, 1.0, 0.0)[:, None]
        y = J @ np.array([1.0, 0.5]) + rng.normal(size=m) * level**1.5
        x = np.linalg.lstsq(J, y, rcond=None)[0]
        r = y - J @ x
        blocks = gram_of_columns(S, J, r, np.ones(m))
        alarms["wald"] += fit_alternative(_rows(J, r), blocks).p_value < 0.05
        f_only = dataclasses.replace(blocks, StDS=None)
        alarms["f"] += fit_alternative(_rows(J, r), f_only).p_value < 0.05
    assert alarms["wald"] <= 16 < 22 <= alarms["f"], alarms


def test_the_relative_effect_is_the_net_change_over_the_signal() -> None:
    J, S, y, r = _problem(4, effect=1.0)
    signal2 = float(y @ y)
    fit = fit_alternative(_rows(J, r, signal2), gram_of_columns(S, J, r, np.ones(len(r))))
    full = np.linalg.lstsq(np.hstack([J, S]), y, rcond=None)[0]
    x0 = np.linalg.lstsq(J, y, rcond=None)[0]
    change = np.hstack([J, S]) @ full - J @ x0
    assert fit.relative_effect == pytest.approx(math.sqrt(change @ change / signal2), rel=1e-9)


def test_the_one_step_jackknife_is_exact_on_a_linear_problem() -> None:
    J, _, y, r = _problem(5, m=120, n=3)
    x0 = np.linalg.lstsq(J, y, rcond=None)[0]
    blocks = np.array_split(np.arange(len(y)), 12)
    parts = [(J[b].T @ J[b], J[b].T @ r[b]) for b in blocks]
    cov = jackknife_covariance(J.T @ J, parts)
    leave = []
    for b in blocks:
        keep = np.setdiff1d(np.arange(len(y)), b)
        leave.append(np.linalg.lstsq(J[keep], y[keep], rcond=None)[0] - x0)
    D = np.array(leave) - np.mean(leave, axis=0)
    np.testing.assert_allclose(cov, 11 / 12 * D.T @ D, rtol=1e-8)
    assert jackknife_covariance(J.T @ J, parts[:2]) is None


def test_the_excess_covariance_keeps_only_what_exceeds() -> None:
    expected = np.diag([4.0, 1.0])
    observed = np.diag([1.0, 9.0])
    np.testing.assert_allclose(excess_covariance(observed, expected), np.diag([0.0, 8.0]))
    assert mahalanobis(np.array([2.0, 3.0]), np.diag([4.0, 1.0])) == pytest.approx(math.sqrt(10.0))
    assert mahalanobis(np.array([0.0, 1.0]), np.diag([1.0, 0.0])) == math.inf
