"""The solver's compiled [J r] assembly: against NumPy, parallel equal to serial."""

from __future__ import annotations

import numpy as np
import pytest

from lightcal.core import solver_kernels as sk


def _inputs(rows: int, seed: int = 0):
    rng = np.random.default_rng(seed)
    grad = rng.normal(size=(rows, 6))
    flux = rng.uniform(0.0, 2.0, rows)
    pose_map = rng.normal(size=(6, 5))
    valid = rng.uniform(size=rows) > 0.1
    observed = rng.uniform(10.0, 100.0, rows)
    sigma = rng.uniform(1.0, 3.0, rows)
    return grad, flux, pose_map, valid, observed, sigma


@pytest.mark.parametrize("rows", [50, sk.PARALLEL_MIN_ROWS + 7])
def test_assembly_matches_numpy(rows):
    grad, flux, pose_map, valid, observed, sigma = _inputs(rows)
    n = 9  # pose 0..4, log-scale 5, gain 6, offset 7, a column left alone 8
    A = np.zeros((rows, n + 1), order="F")
    A[:, 8] = 0.25
    total = np.full(rows, 3.0)
    sk.add_light_columns(A, total, grad, flux, pose_map, 0, 5, 2.0, 4.0)
    squares, finite = sk.finish_rows(A, total, valid, observed, sigma, 1.5, 0.5, 6, 7)
    m = np.where(valid, 0.5 + 1.5 * (3.0 + 4.0 * flux), np.nan)
    assert not finite  # the invalid rows' residuals are NaN
    assert np.isnan(squares)
    expected = np.zeros((rows, n))
    expected[:, :5] = grad @ pose_map
    expected[:, 5] = 2.0 * flux
    expected[:, 6] = m - 0.5
    expected[:, 7] = 1.0
    expected[:, 8] = 0.25
    np.testing.assert_allclose(A[:, :n], -expected / sigma[:, None], rtol=1e-13, atol=1e-15)
    np.testing.assert_allclose(A[:, n], (observed - m) / sigma, rtol=1e-13, atol=1e-15)
    np.testing.assert_allclose(total, 3.0 + 4.0 * flux, rtol=1e-15)


@pytest.mark.parametrize("rows", [50, sk.PARALLEL_MIN_ROWS + 7])
def test_finishing_returns_the_squared_residuals_in_value_units(rows):
    grad, flux, pose_map, _, observed, sigma = _inputs(rows, seed=2)
    A = np.zeros((rows, 8), order="F")
    total = np.zeros(rows)
    sk.add_light_columns(A, total, grad, flux, pose_map, 0, 5, 2.0, 4.0)
    valid = np.ones(rows, dtype=bool)
    squares, finite = sk.finish_rows(A, total, valid, observed, sigma, 1.5, 0.5, 6, -1)
    assert finite
    m = 0.5 + 1.5 * 4.0 * flux
    np.testing.assert_allclose(squares, np.sum((observed - m) ** 2), rtol=1e-12)
    np.testing.assert_allclose(squares, np.sum((A[:, -1] * sigma) ** 2), rtol=1e-13)
    observed[rows // 2] = np.inf
    assert not sk.finish_rows(A, total, valid, observed, sigma, 1.5, 0.5, 6, -1)[1]


def test_parallel_and_serial_kernels_agree_bitwise():
    rows = 1000
    grad, flux, pose_map, valid, observed, sigma = _inputs(rows, seed=1)
    out = []
    for add, finish in (
        (sk._add_light_columns_parallel, sk._finish_rows_parallel),
        (sk._add_light_columns_serial, sk._finish_rows_serial),
    ):
        A = np.zeros((rows, 8), order="F")
        total = np.zeros(rows)
        stats = np.zeros(2)
        add(A, total, grad, flux, pose_map, 1, 0, 2.0, 4.0)
        finish(A, total, valid, observed, sigma, 1.5, 0.5, -1, 6, stats)
        out.append(A)
        assert stats[1] == np.count_nonzero(~valid)
    np.testing.assert_array_equal(out[0], out[1])
