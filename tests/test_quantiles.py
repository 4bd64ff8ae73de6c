"""Quantiles from order statistics against NumPy's."""

from __future__ import annotations

import numpy as np
import pytest

from lightcal.core.quantiles import order_statistics, quantiles


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_quantiles_equal_numpys(dtype) -> None:
    rng = np.random.default_rng(7)
    q = np.linspace(0.0, 1.0, 9)
    for m in (1, 2, 10, 999, 70_001, 300_000):
        values = (rng.gamma(2.0, 9.0, m)).astype(dtype)
        values[::5] = np.round(values[::5], 1)  # ties
        np.testing.assert_array_equal(quantiles(values, q), np.quantile(values, q))
    values[3] = np.nan  # NaN: every quantile NaN, as NumPy says
    assert np.isnan(quantiles(values, q)).all()
    same = np.full(100_000, 2.5, dtype=dtype)
    np.testing.assert_array_equal(quantiles(same, q), np.quantile(same, q))


def test_percentile_99_is_numpys() -> None:
    """The images' 99th percentile (from `quantiles`) is np.percentile's."""
    from lightcal.io.linear_image import LinearImage

    rng = np.random.default_rng(9)
    values = rng.gamma(2.0, 300.0, (700, 500))
    values[0, :10] = np.nan  # non-finite values are left out
    img = LinearImage(
        values,
        np.zeros(values.shape, bool),
        white_level=1e9,
        black_level=0.0,
        exposure=None,
        source="test",
        bit_depth=None,
    )
    finite = values[np.isfinite(values)]
    assert img.percentile_99 == float(np.percentile(finite, 99))


def test_infinities_and_percentiles_are_numpys() -> None:
    """Infinite values go to NumPy (the histogram needs a finite range); `percentile` is
    np.percentile, p in percent, at the display and residual scales' percentiles."""
    from lightcal.core.quantiles import percentile

    rng = np.random.default_rng(10)
    values = rng.normal(size=100_000) * 40.0
    q = np.linspace(0.0, 1.0, 5)
    for p in (0.0, 50.0, 99.0, 99.5, 100.0):
        assert percentile(values, p) == float(np.percentile(values, p))
    values[[3, 7]] = np.inf
    values[11] = -np.inf
    with np.errstate(invalid="ignore"):  # NumPy's inf - inf at the ends
        np.testing.assert_array_equal(quantiles(values, q), np.quantile(values, q))
        assert percentile(values, 99.5) == float(np.percentile(values, 99.5))


def test_order_statistics_are_the_sorted_values_at_the_ranks() -> None:
    rng = np.random.default_rng(8)
    values = np.concatenate([rng.normal(size=200_000), np.full(50_000, 0.25)])  # a spike
    ranks = np.array([0, 1, 99_999, 150_000, 160_000, 249_999], dtype=np.int64)
    np.testing.assert_array_equal(order_statistics(values, ranks), np.sort(values)[ranks])
