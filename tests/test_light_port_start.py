"""The light port's path solve from its start in the water's slope u = tan(theta_w)
(`lightcal.core.kernels.port_paths`): few evaluations over the range of real ports and
scenes, the path's equation solved to round-off, and the edge cases (on the axis, near
the critical angle, just in front of the port, indices 1)."""

from __future__ import annotations

import numpy as np
import pytest

from lightcal.core.kernels.port_paths import air_sines_into

#: The realistic range: d 5-50 mm, t 3-20 mm, acrylic or glass into fresh or sea water.
GLASS = (1.49, 1.52)
WATER = (1.333, 1.34)


def _points(rng: np.random.Generator, n: int, deg: tuple[float, float], water_m=(0.3, 5.0)):
    """n ports and the points their rays at air angles in deg reach H = water_m beyond
    the outer face (the forward trace): (d, t, n_g, n_w, rho, h, s) each (n,)."""
    d = rng.uniform(0.005, 0.05, n)
    t = rng.uniform(0.003, 0.02, n)
    n_g = rng.choice(GLASS, n)
    n_w = rng.choice(WATER, n)
    s = np.sin(np.radians(rng.uniform(*deg, n)))
    big_h = rng.uniform(*water_m, n) if isinstance(water_m, tuple) else water_m
    tan = lambda n_i: s / np.sqrt(n_i * n_i - s * s)  # noqa: E731
    rho = d * tan(1.0) + t * tan(n_g) + big_h * tan(n_w)
    return d, t, n_g, n_w, rho, d + t + big_h, s


def _solve(d, t, n_g, n_w, rho, h) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """s, ok and the evaluations of each point (solved alone)."""
    s, ok, its = np.empty(len(rho)), np.empty(len(rho), dtype=bool), np.empty(len(rho), int)
    for i in range(len(rho)):
        out_s, out_ok = np.empty(1), np.empty(1, dtype=np.bool_)
        its[i] = air_sines_into(
            rho[i : i + 1], h[i : i + 1], d[i], t[i], n_g[i], n_w[i], out_s, out_ok
        )
        s[i], ok[i] = out_s[0], out_ok[0]
    return s, ok, its


def _residual(s, d, t, n_g, n_w, rho, h) -> np.ndarray:
    """|d tan(theta_a) + t tan(theta_g) + H tan(theta_w) - rho|, m."""
    tan = lambda n_i: s / np.sqrt(n_i * n_i - s * s)  # noqa: E731
    return np.abs(d * tan(1.0) + t * tan(n_g) + (h - d - t) * tan(n_w) - rho)


@pytest.mark.parametrize(
    ("deg", "mean_bound", "max_bound"),
    [((0.0, 30.0), 2.5, 3), ((30.0, 60.0), 3.0, 4), ((60.0, 80.0), 5.0, 12)],
)
def test_few_evaluations_reach_round_off_over_real_ports(deg, mean_bound, max_bound) -> None:
    d, t, n_g, n_w, rho, h, s_true = _points(np.random.default_rng(3), 4000, deg)
    s, ok, its = _solve(d, t, n_g, n_w, rho, h)
    assert ok.all()
    assert its.mean() <= mean_bound and its.max() <= max_bound, (its.mean(), its.max())
    np.testing.assert_allclose(s, s_true, rtol=5e-15, atol=0.0)
    # The path reaches its point within round-off of the lengths (2e-13 m: the
    # forward-trace closure of tests/test_light_port.py).
    assert _residual(s, d, t, n_g, n_w, rho, h).max() <= 2e-13


def test_the_edge_cases() -> None:
    rng = np.random.default_rng(4)
    # On the axis: s = 0 without a step.
    d, t, n_g, n_w, _, h, _ = _points(rng, 50, (0.0, 0.0))
    s, ok, its = _solve(d, t, n_g, n_w, np.zeros(50), h)
    assert ok.all() and np.all(s == 0.0) and its.max() == 0
    # Near the critical angle in the water (air angles 85-89.99 degrees).
    d, t, n_g, n_w, rho, h, s_true = _points(rng, 2000, (85.0, 89.99))
    s, ok, its = _solve(d, t, n_g, n_w, rho, h)
    assert ok.all() and its.max() <= 16, its.max()
    np.testing.assert_allclose(s, s_true, rtol=5e-15, atol=0.0)
    assert np.all(_residual(s, d, t, n_g, n_w, rho, h) <= 2e-13 * np.maximum(1.0, rho))
    # Just in front of the outer face (H 1 nm - 1 mm), every angle.
    for water_m in (1e-9, 1e-6, 1e-3):
        d, t, n_g, n_w, rho, h, s_true = _points(rng, 1000, (0.0, 89.0), water_m)
        s, ok, its = _solve(d, t, n_g, n_w, rho, h)
        assert ok.all() and its.max() <= 16, (water_m, its.max())
        np.testing.assert_allclose(s, s_true, rtol=5e-15, atol=0.0)
    # Not in front of the port (h <= d + t) or not finite: not ok, NaN.
    rho = np.array([0.1, 0.1, np.nan, 0.2])
    h = np.array([0.03, 0.02, 1.0, np.inf])
    out_s, out_ok = np.empty(4), np.empty(4, dtype=np.bool_)
    air_sines_into(rho, h, 0.02, 0.01, 1.49, 1.333, out_s, out_ok)
    assert not out_ok.any() and np.isnan(out_s).all()


def test_indices_one_give_the_straight_line_in_one_step() -> None:
    rng = np.random.default_rng(5)
    rho, h = rng.uniform(0.0, 3.0, 500), rng.uniform(0.05, 3.0, 500)
    d, t = np.full(500, 0.02), np.full(500, 0.01)
    s, ok, its = _solve(d, t, np.ones(500), np.ones(500), rho, h)
    # F is linear (one step, and the evaluation that finds it converged); past 80
    # degrees the path is solved in s.
    assert ok.all() and np.all(its[rho < 5.6 * h] <= 1) and its.max() <= 14
    np.testing.assert_allclose(s, rho / np.hypot(rho, h), rtol=5e-15)
