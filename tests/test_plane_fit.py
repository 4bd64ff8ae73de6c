"""Tests of lightcal.core.plane_fit: RANSAC + least squares plane fit."""

from __future__ import annotations

import numpy as np
import pytest

from lightcal.core.plane_fit import fit_plane_ransac
from lightcal.errors import InputError


def _noisy_plane(
    rng: np.random.Generator,
    *,
    normal: np.ndarray,
    offset: float,
    n_points: int,
    noise: float,
    outlier_fraction: float,
) -> tuple[np.ndarray, np.ndarray]:
    """Points on `normal . x + offset = 0` with Gaussian noise along the normal, and outliers."""
    normal = normal / np.linalg.norm(normal)
    a = np.cross(normal, [1.0, 0.0, 0.0])
    a /= np.linalg.norm(a)
    b = np.cross(normal, a)
    uv = rng.uniform(-1.0, 1.0, size=(n_points, 2))
    points = -offset * normal + uv[:, :1] * a + uv[:, 1:] * b
    points += noise * rng.standard_normal((n_points, 1)) * normal
    outliers = np.zeros(n_points, dtype=bool)
    outliers[rng.permutation(n_points)[: round(outlier_fraction * n_points)]] = True
    # Outliers 5 cm to 1 m off the plane, on both sides, shifted within the plane.
    n_out = int(outliers.sum())
    off = rng.uniform(0.05, 1.0, size=n_out) * rng.choice([-1.0, 1.0], n_out)
    shift = rng.uniform(-0.5, 0.5, (n_out, 2))
    points[outliers] += shift[:, :1] * a + shift[:, 1:] * b + off[:, None] * normal
    return points, outliers


def _angle_deg(n1: np.ndarray, n2: np.ndarray) -> float:
    """Angle between two lines (sign of the normals ignored)."""
    return float(np.degrees(np.arccos(min(1.0, abs(float(n1 @ n2))))))


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_recovers_noisy_plane_with_30_percent_outliers(seed: int) -> None:
    rng = np.random.default_rng(seed)
    normal = rng.standard_normal(3)
    normal /= np.linalg.norm(normal)
    offset = rng.uniform(-2.0, 2.0)
    points, outliers = _noisy_plane(
        rng, normal=normal, offset=offset, n_points=600, noise=0.001, outlier_fraction=0.3
    )

    fit = fit_plane_ransac(points, threshold=0.005, rng=np.random.default_rng(seed + 100))

    assert _angle_deg(fit.normal, normal) < 0.1
    sign = np.sign(fit.normal @ normal)
    assert fit.offset * sign == pytest.approx(offset, abs=5e-4)
    assert np.linalg.norm(fit.normal) == pytest.approx(1.0, abs=1e-12)
    # Every true inlier lies within 5 sigma: all are found; outliers are >= 5 cm off.
    np.testing.assert_array_equal(fit.inliers, ~outliers)
    assert fit.n_inliers == int((~outliers).sum())
    assert fit.rms == pytest.approx(0.001, rel=0.15)


def test_hand_computed_plane_excludes_the_outlier() -> None:
    # Plane z = 2 (normal -z given by orientation of the data does not matter).
    points = np.array(
        [[0.0, 0.0, 2.0], [1.0, 0.0, 2.0], [0.0, 1.0, 2.0], [1.0, 1.0, 2.0], [0.5, 0.5, 3.0]]
    )
    fit = fit_plane_ransac(points, threshold=0.1, rng=np.random.default_rng(0))
    np.testing.assert_allclose(fit.normal, [0.0, 0.0, 1.0], atol=1e-15)
    assert fit.offset == pytest.approx(-2.0, abs=1e-15)
    np.testing.assert_array_equal(fit.inliers, [True, True, True, True, False])
    assert fit.rms == pytest.approx(0.0, abs=1e-15)
    np.testing.assert_allclose(
        fit.signed_distances([[7.0, -3.0, 5.0], [0.0, 0.0, 0.0]]), [3.0, -2.0], atol=1e-15
    )


def test_normal_sign_is_canonical() -> None:
    # Largest-magnitude component positive, whichever way the data would orient it.
    rng = np.random.default_rng(5)
    points, _ = _noisy_plane(
        rng,
        normal=np.array([0.2, -0.9, 0.1]),
        offset=0.7,
        n_points=50,
        noise=0.0,
        outlier_fraction=0.0,
    )
    fit = fit_plane_ransac(points, threshold=1e-6, rng=rng)
    assert fit.normal[1] > 0.0
    expected = -np.array([0.2, -0.9, 0.1]) / np.linalg.norm([0.2, -0.9, 0.1])
    np.testing.assert_allclose(fit.normal, expected, atol=1e-12)
    assert fit.offset == pytest.approx(-0.7, abs=1e-12)


def test_same_seed_same_result() -> None:
    rng = np.random.default_rng(11)
    points, _ = _noisy_plane(
        rng,
        normal=np.array([0.0, 0.3, 1.0]),
        offset=-1.0,
        n_points=200,
        noise=0.002,
        outlier_fraction=0.4,
    )
    a = fit_plane_ransac(points, threshold=0.01, rng=np.random.default_rng(3))
    b = fit_plane_ransac(points, threshold=0.01, rng=np.random.default_rng(3))
    np.testing.assert_array_equal(a.normal, b.normal)
    np.testing.assert_array_equal(a.inliers, b.inliers)
    assert a.offset == b.offset


def test_fewer_than_three_points() -> None:
    with pytest.raises(
        InputError, match=r"^points: expected at least 3 points to fit a plane, got 2$"
    ):
        fit_plane_ransac(np.zeros((2, 3)), threshold=0.1, rng=np.random.default_rng(0))


def test_collinear_points_are_a_degenerate_plane() -> None:
    t = np.linspace(0.0, 1.0, 20)
    points = np.stack([t, 2.0 * t, 3.0 - t], axis=1)
    with pytest.raises(InputError, match=r"^points: degenerate plane: expected points spanning"):
        fit_plane_ransac(points, threshold=0.01, rng=np.random.default_rng(0))


def test_noisy_line_is_a_degenerate_plane() -> None:
    # Points along a line with 0.1 mm noise: every plane through the line fits within a
    # 1 cm threshold, so the orientation is not determined.
    rng = np.random.default_rng(4)
    t = rng.uniform(0.0, 2.0, 100)
    points = np.stack([t, 0.5 * t, 1.0 - t], axis=1) + 1e-4 * rng.standard_normal((100, 3))
    with pytest.raises(
        InputError, match=r"^points: degenerate plane: the 100 inliers lie along a line"
    ):
        fit_plane_ransac(points, threshold=0.01, rng=np.random.default_rng(0))


def test_line_with_one_point_beside_it_is_a_plane() -> None:
    t = np.linspace(0.0, 1.0, 20)
    points = np.concatenate([np.stack([t, 0 * t, 0 * t], axis=1), [[0.5, 3.0, 0.0]]])
    fit = fit_plane_ransac(points, threshold=0.01, rng=np.random.default_rng(0))
    np.testing.assert_allclose(fit.normal, [0.0, 0.0, 1.0], atol=1e-12)
    assert fit.n_inliers == 21


@pytest.mark.parametrize(
    ("points", "kwargs", "message"),
    [
        (np.zeros((4, 2)), {}, r"^points: expected an \(N, 3\) array, got shape \(4, 2\)$"),
        (
            np.array([[0, 0, 0], [1, 0, np.nan], [0, 1, 0.0]]),
            {},
            r"^points: expected finite coordinates, got 1 rows with NaN or inf$",
        ),
        (np.eye(3), {"threshold": 0.0}, r"^threshold: expected a finite distance > 0, got 0.0$"),
        (np.eye(3), {"max_iters": 0}, r"^max_iters: expected an int >= 1, got 0$"),
        (
            np.eye(3),
            {"confidence": 1.0},
            r"^confidence: expected a probability in \(0, 1\), got 1.0$",
        ),
    ],
)
def test_argument_errors(points: np.ndarray, kwargs: dict, message: str) -> None:
    options = {"threshold": 0.1, "rng": np.random.default_rng(0), **kwargs}
    with pytest.raises(InputError, match=message):
        fit_plane_ransac(points, **options)
