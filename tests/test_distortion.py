"""Tests of lightcal.core.distortion: OpenCV distortion and its Newton inverse."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from lightcal.core.distortion import (
    distort_normalized,
    distort_points,
    distortion_jacobian,
    pad_distortion,
    undistort_normalized,
    undistort_points,
)

# (k1, k2, p1, p2[, k3[, k4, k5, k6]]) as OpenCV takes them.
DIST_SETS = {
    "4 coefficients": [-0.28, 0.09, 0.0012, -0.0021],
    "5 strong barrel": [-0.45, 0.2, 0.0005, 0.001, -0.03],
    "5 pincushion": [0.35, 0.1, -0.001, 0.002, 0.05],
    "8 rational": [0.8, -0.2, 0.001, -0.0015, 0.02, 0.6, -0.05, 0.01],
}


def _random_normalized(seed: int, n: int = 1000, half_width: float = 0.6) -> np.ndarray:
    return np.random.default_rng(seed).uniform(-half_width, half_width, (n, 2))


def test_pad_distortion_accepts_0_4_5_8_and_pads_with_zeros() -> None:
    assert np.array_equal(pad_distortion([]), np.zeros(8))
    assert np.array_equal(pad_distortion([1, 2, 3, 4]), [1, 2, 3, 4, 0, 0, 0, 0])
    assert np.array_equal(pad_distortion(np.array([[1, 2, 3, 4, 5]])), [1, 2, 3, 4, 5, 0, 0, 0])
    assert np.array_equal(pad_distortion(np.arange(8.0).reshape(8, 1)), np.arange(8.0))
    assert pad_distortion([1, 2, 3, 4]).dtype == np.float64


def test_pad_distortion_rejects_other_lengths() -> None:
    with pytest.raises(
        ValueError, match=r"^distortion coefficients: expected 0, 4, 5 or 8 values, got 3$"
    ):
        pad_distortion([1.0, 2.0, 3.0])
    with pytest.raises(ValueError, match=r"expected 0, 4, 5 or 8 values, got 12$"):
        pad_distortion(np.zeros(12))


def test_distort_hand_computed_k1_only() -> None:
    # r2 = 0.3^2 + 0.4^2 = 0.25; factor = 1 + 0.1 * 0.25 = 1.025.
    dist = pad_distortion([0.1, 0.0, 0.0, 0.0])
    xd, yd = distort_normalized(0.3, 0.4, dist)
    assert xd == pytest.approx(0.3075, abs=1e-15)
    assert yd == pytest.approx(0.41, abs=1e-15)


def test_distort_hand_computed_tangential_only() -> None:
    # x = 0.5, y = -0.2, r2 = 0.29, p1 = 0.01, p2 = 0.02:
    # xd = x + 2 p1 x y + p2 (r2 + 2 x^2) = 0.5 - 0.002 + 0.0158
    # yd = y + p1 (r2 + 2 y^2) + 2 p2 x y = -0.2 + 0.0037 - 0.004
    dist = pad_distortion([0.0, 0.0, 0.01, 0.02])
    xd, yd = distort_normalized(0.5, -0.2, dist)
    assert xd == pytest.approx(0.5138, abs=1e-15)
    assert yd == pytest.approx(-0.2003, abs=1e-15)


def test_zero_distortion_is_identity_both_ways() -> None:
    xy = _random_normalized(0, n=50, half_width=2.0)
    dist = np.zeros(8)
    assert np.array_equal(distort_points(xy, dist), xy)
    back, ok = undistort_points(xy, dist)
    assert ok.all()
    assert np.array_equal(back, xy)


@pytest.mark.parametrize("name", list(DIST_SETS))
def test_distort_points_matches_cv2_project_points(name: str) -> None:
    coeffs = np.array(DIST_SETS[name])
    xy = _random_normalized(1)
    points = np.column_stack([xy, np.ones(len(xy))])
    expected, _ = cv2.projectPoints(points, np.zeros(3), np.zeros(3), np.eye(3), coeffs)
    got = distort_points(xy, pad_distortion(coeffs))
    np.testing.assert_allclose(got, expected[:, 0, :], rtol=0, atol=1e-14)


@pytest.mark.parametrize("name", list(DIST_SETS))
def test_jacobian_matches_finite_differences(name: str) -> None:
    dist = pad_distortion(DIST_SETS[name])
    h = 1e-6
    for x, y in _random_normalized(2, n=20):
        a, b, c, d = distortion_jacobian(x, y, dist)
        xp, yp = distort_normalized(x + h, y, dist)
        xm, ym = distort_normalized(x - h, y, dist)
        np.testing.assert_allclose([a, c], [(xp - xm) / (2 * h), (yp - ym) / (2 * h)], atol=1e-8)
        xp, yp = distort_normalized(x, y + h, dist)
        xm, ym = distort_normalized(x, y - h, dist)
        np.testing.assert_allclose([b, d], [(xp - xm) / (2 * h), (yp - ym) / (2 * h)], atol=1e-8)


@pytest.mark.parametrize("name", list(DIST_SETS))
def test_undistort_inverts_distort_to_round_off(name: str) -> None:
    dist = pad_distortion(DIST_SETS[name])
    xy = _random_normalized(3)
    back, ok = undistort_points(distort_points(xy, dist), dist)
    assert ok.all()
    np.testing.assert_allclose(back, xy, rtol=0, atol=2e-15)


def test_undistort_scalar_matches_vectorised() -> None:
    dist = pad_distortion(DIST_SETS["8 rational"])
    x, y, ok = undistort_normalized(0.31, -0.27, dist)
    xy, ok_all = undistort_points(np.array([[0.31, -0.27]]), dist)
    assert ok and ok_all[0]
    assert (x, y) == (xy[0, 0], xy[0, 1])
    assert distort_normalized(x, y, dist) == pytest.approx((0.31, -0.27), abs=1e-15)


def test_undistort_beyond_the_fold_is_not_ok() -> None:
    # k1 = -0.4: r_d = r (1 - 0.4 r^2) grows up to r = 1/sqrt(1.2), r_d = 0.6086, then
    # folds back. A distorted radius 0.7 has no preimage in the valid region; its only
    # real preimage, x = -1.8556, is mirrored through the axis (radial factor < 0).
    dist = pad_distortion([-0.4, 0.0, 0.0, 0.0])
    x_mirrored = -1.8555620381898053
    assert distort_normalized(x_mirrored, 0.0, dist)[0] == pytest.approx(0.7, abs=1e-12)
    x, y, ok = undistort_normalized(0.7, 0.0, dist)
    assert not ok
    assert np.isnan(x) and np.isnan(y)
    xy, ok_all = undistort_points(np.array([[0.7, 0.0], [0.5, 0.4], [0.3, 0.0]]), dist)
    assert ok_all.tolist() == [False, False, True]
    assert np.isnan(xy[:2]).all() and np.isfinite(xy[2]).all()


def test_undistort_returns_the_preimage_inside_the_fold() -> None:
    # x = 1.2 lies beyond the fold (Jacobian determinant < 0 there); its image 0.5088
    # also has a preimage inside the valid region, which is the one returned.
    dist = pad_distortion([-0.4, 0.0, 0.0, 0.0])
    a, b, c, d = distortion_jacobian(1.2, 0.0, dist)
    assert a * d - b * c < 0
    xd, yd = distort_normalized(1.2, 0.0, dist)
    x, y, ok = undistort_normalized(xd, yd, dist)
    assert ok
    assert x < 1.0 / np.sqrt(1.2)
    assert distort_normalized(x, y, dist) == pytest.approx((xd, yd), abs=1e-15)


def test_undistort_rejects_a_solution_where_the_map_folds() -> None:
    # With these coefficients Newton from (0.7, -1.05) converges to (0.906, -1.349): it
    # reproduces the input and its radial factor is positive, but the Jacobian
    # determinant there is about -2.16: the map has folded over, so it is not ok.
    dist = pad_distortion([0.25, 0.32, 0.046, -0.033, -0.014, -0.31, -0.006, 0.18])
    x_fold, y_fold = 0.90615848489576, -1.3486008811563326
    assert distort_normalized(x_fold, y_fold, dist) == pytest.approx((0.7, -1.05), abs=1e-12)
    a, b, c, d = distortion_jacobian(x_fold, y_fold, dist)
    assert a * d - b * c < -2.0
    x, y, ok = undistort_normalized(0.7, -1.05, dist)
    assert not ok
    assert np.isnan(x) and np.isnan(y)


@pytest.mark.parametrize("bad", [(np.nan, 0.1), (0.1, np.nan), (np.inf, 0.0)])
def test_undistort_non_finite_input_is_not_ok(bad: tuple[float, float]) -> None:
    x, y, ok = undistort_normalized(bad[0], bad[1], pad_distortion(DIST_SETS["5 pincushion"]))
    assert not ok
    assert np.isnan(x) and np.isnan(y)


def test_distort_points_empty_input() -> None:
    dist = pad_distortion(DIST_SETS["4 coefficients"])
    assert distort_points(np.zeros((0, 2)), dist).shape == (0, 2)
    xy, ok = undistort_points(np.zeros((0, 2)), dist)
    assert xy.shape == (0, 2) and ok.shape == (0,)
