"""The flat port's Fresnel transmittance against closed forms."""

import numpy as np
import pytest

from lightcal.core.fresnel import port_transmittance


def test_normal_incidence_is_the_plates_closed_form() -> None:
    r1 = ((1.0 - 1.49) / (1.0 + 1.49)) ** 2
    r2 = ((1.49 - 1.333) / (1.49 + 1.333)) ** 2
    expected = (1 - r1) * (1 - r2) / (1 - r1 * r2)
    T, _ = port_transmittance(np.array([1.0]), 1.0, 1.49, 1.333)
    assert T[0] == pytest.approx(expected, rel=1e-14)
    assert T[0] == pytest.approx(0.95842, abs=1e-5)


def test_at_brewsters_angle_p_light_passes_one_interface() -> None:
    # n_g = n_w: one interface; at tan(theta) = n the p reflectance is 0.
    n = 1.5
    theta = np.arctan(n)
    sin_t = np.sin(theta) / n
    cos_t = np.sqrt(1 - sin_t**2)
    rs = ((np.cos(theta) - n * cos_t) / (np.cos(theta) + n * cos_t)) ** 2
    T, _ = port_transmittance(np.array([np.cos(theta)]), 1.0, n, n)
    assert T[0] == pytest.approx(0.5 * ((1 - rs) + 1.0), rel=1e-13)


def test_derivative_matches_central_differences() -> None:
    c = np.cos(np.radians(np.linspace(0.5, 85.0, 40)))
    _, dT = port_transmittance(c, 1.0, 1.52, 1.34)
    h = 1e-7
    up, _ = port_transmittance(c + h, 1.0, 1.52, 1.34)
    down, _ = port_transmittance(c - h, 1.0, 1.52, 1.34)
    np.testing.assert_allclose(dT, (up - down) / (2 * h), rtol=1e-6, atol=1e-8)


def test_falls_with_the_angle() -> None:
    c = np.cos(np.radians(np.arange(0.0, 89.0, 1.0)))
    T, _ = port_transmittance(c, 1.0, 1.49, 1.333)
    assert np.all(np.diff(T) <= 1e-12)
    assert 0.0 < T[-1] < T[0] <= 1.0
