"""The compiled per-pixel passes of the fit checks against their NumPy formulation."""

from __future__ import annotations

import numpy as np
import pytest

from lightcal.core.misfit import pixel_angles
from lightcal.core.misfit_kernels import (
    add_weighted_gram,
    mirror_incidence,
    noise_residuals,
)
from lightcal.core.problem import poisson_gaussian_sigma


def _numpy_noise_residuals(residual, sigma, observed, offset, noise):
    """fit_check's former NumPy pass: (r_noise, relative float32, ratio)."""
    d = residual * sigma
    rendered = observed - d
    sigma_n = sigma if noise is None else poisson_gaussian_sigma(rendered - offset, noise)
    with np.errstate(divide="ignore", invalid="ignore"):
        relative = np.where(rendered - offset > 0, d / (rendered - offset), 0.0)
    return d / sigma_n, relative.astype(np.float32), sigma / sigma_n


@pytest.mark.parametrize("noise", [None, (0.8, 6.0)])
def test_noise_residuals_are_the_numpy_pass_bit_for_bit(noise) -> None:
    rng = np.random.default_rng(3)
    n = 50_000
    observed = rng.uniform(-20.0, 4000.0, n)  # some below the offset: relative 0, signal 0
    sigma = rng.uniform(0.5, 30.0, n)
    residual = rng.normal(size=n) * 3.0
    residual[7] = np.nan
    out = np.empty(n), np.empty(n, dtype=np.float32), np.empty(n)
    noise_arr = np.empty(0) if noise is None else np.array(noise)
    noise_residuals(residual, sigma, observed, 10.0, noise_arr, out[0], out[1], out[2])
    want = _numpy_noise_residuals(residual, sigma, observed, 10.0, noise)
    for got, expected in zip(out, want, strict=True):
        np.testing.assert_array_equal(got, expected)
    assert np.isnan(out[0][7]) and np.isnan(out[2][7]) == (noise is not None)


def test_weighted_gram_adds_j_transpose_w_j() -> None:
    rng = np.random.default_rng(4)
    A = np.asfortranarray(rng.normal(size=(30_001, 7)))
    ratio = rng.uniform(0.5, 2.0, A.shape[0])
    out = np.full((6, 6), 1.0)
    add_weighted_gram(A, 6, ratio, out)
    J = A[:, :6]
    want = 1.0 + (J / ratio[:, None] ** 2).T @ J
    np.testing.assert_allclose(out, want, rtol=1e-12, atol=1e-10)
    assert np.array_equal(out, out.T)


def _points(n: int, rng: np.random.Generator) -> np.ndarray:
    return np.column_stack([rng.uniform(-1.5, 1.5, (n, 2)), np.zeros(n)])


def test_mirror_and_incidence_angles_match_pixel_angles() -> None:
    rng = np.random.default_rng(5)
    points = _points(20_000, rng)
    points[[3, 11]] = [[0.1, 0.2, 0.0], [0.3, -0.4, 0.0]]
    light = np.array([0.1, 0.2, 1.5])
    camera = np.array([0.3, -0.4, 1.2])  # points 3 and 11: straight below light / camera
    mirror, incidence = np.empty(len(points)), np.empty(len(points))
    mirror_incidence(points, light[None], np.ones((1, len(points))), camera, mirror, incidence)
    want_mirror, want_incidence = pixel_angles(points, light, camera)
    np.testing.assert_allclose(mirror, want_mirror, rtol=0, atol=1e-9)
    np.testing.assert_allclose(incidence, want_incidence, rtol=0, atol=1e-9)
    assert incidence[3] == 0.0 and mirror.min() >= 0.0 and incidence.max() < 90.0


def test_each_point_takes_the_angles_of_its_brightest_light() -> None:
    rng = np.random.default_rng(6)
    points = _points(5_000, rng)
    points[0] = np.nan  # a pixel off the wall
    lights = np.array([[0.1, 0.0, 1.0], [-0.4, 0.3, 2.0], [0.5, 0.5, 0.8]])
    camera = np.array([0.0, 0.0, 1.4])
    lit = rng.uniform(size=(3, len(points)))
    lit[:, 1] = 0.5  # a tie: the first light, as np.argmax picks it
    mirror = np.empty(len(points), dtype=np.float32)
    incidence = np.empty(len(points), dtype=np.float32)
    mirror_incidence(points, lights, lit, camera, mirror, incidence)
    brightest = np.argmax(lit, axis=0)
    assert brightest[1] == 0
    for j, light in enumerate(lights):
        sel = brightest == j
        want_mirror, want_incidence = pixel_angles(points[sel], light, camera)
        np.testing.assert_allclose(mirror[sel], want_mirror, rtol=1e-6, atol=1e-5)
        np.testing.assert_allclose(incidence[sel], want_incidence, rtol=1e-6, atol=1e-5)
    assert np.isnan(mirror[0]) and np.isnan(incidence[0])
    assert np.isfinite(mirror[1:]).all() and np.isfinite(incidence[1:]).all()
