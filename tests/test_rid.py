"""Tests of the RID models (lightcal.core.rid) and their compiled evaluator."""

from __future__ import annotations

import math
import re

import numpy as np
import pytest

from lightcal.core.rid import (
    RID,
    CosPowerRID,
    GaussianRID,
    IsotropicRID,
    SymmetricTableRID,
    Table2DRID,
)
from tests.scenes import rid_model, symmetric_table_rid, table_2d_rid, table_2d_values


def _exact(message: str) -> str:
    return "^" + re.escape(message) + "$"


# ---------------------------------------------------------------- analytic models


def test_isotropic_is_one_everywhere_with_zero_derivatives() -> None:
    rid = IsotropicRID()
    theta = np.array([0.0, 0.3, 1.5, 2.5, math.pi])
    f, ft, fp = rid.value_and_derivatives(theta, np.array([0.0, 1.0, 2.0, 4.0, 6.0]))
    np.testing.assert_array_equal(f, np.ones(5))
    np.testing.assert_array_equal(ft, np.zeros(5))
    np.testing.assert_array_equal(fp, np.zeros(5))
    assert rid.symmetric
    assert rid.angle_at_level_rad(0.5) == math.pi


def test_cos_power_by_hand_and_zero_behind_the_light() -> None:
    rid = CosPowerRID(2.0)
    theta = np.array([0.0, math.pi / 3, math.pi / 4, math.pi / 2 + 1e-9, 2.0, math.pi])
    np.testing.assert_allclose(rid(theta), [1.0, 0.25, 0.5, 0.0, 0.0, 0.0], rtol=1e-14, atol=0)
    # m = 0: a hemispherical emitter.
    np.testing.assert_array_equal(CosPowerRID(0.0)(np.array([0.0, 1.5, 1.6])), [1.0, 1.0, 0.0])


@pytest.mark.parametrize("half_angle_deg", [10.0, 30.0, 60.0, 75.0])
def test_cos_power_half_angle(half_angle_deg: float) -> None:
    t = math.radians(half_angle_deg)
    rid = CosPowerRID.from_half_angle(t)
    assert rid.m == pytest.approx(-math.log(2.0) / math.log(math.cos(t)), rel=1e-15)
    assert float(rid(np.array(t))) == pytest.approx(0.5, rel=1e-13)
    assert rid.half_angle_rad == pytest.approx(t, abs=1e-10)


def test_cos_power_half_angle_of_60_degrees_is_lambertian() -> None:
    assert CosPowerRID.from_half_angle(math.pi / 3).m == pytest.approx(1.0, rel=1e-14)


@pytest.mark.parametrize("half_angle_deg", [5.0, 25.0, 60.0, 85.0])
def test_gaussian_half_angle(half_angle_deg: float) -> None:
    t = math.radians(half_angle_deg)
    rid = GaussianRID.from_half_angle(t)
    assert rid.sigma_rad == pytest.approx(t / math.sqrt(2 * math.log(2)), rel=1e-15)
    assert float(rid(np.array(t))) == pytest.approx(0.5, rel=1e-13)
    assert float(rid(np.array(rid.sigma_rad))) == pytest.approx(math.exp(-0.5), rel=1e-14)
    assert rid.half_angle_rad == pytest.approx(t, abs=1e-10)


@pytest.mark.parametrize("name", ["isotropic", "cos_power", "gaussian", "table_1d", "table_2d"])
def test_every_model_is_one_on_the_axis(name: str) -> None:
    rid = rid_model(name)
    phi = np.linspace(0.0, 2 * math.pi, 13)
    np.testing.assert_allclose(rid(np.zeros(13), phi), np.ones(13), rtol=1e-15)


def test_call_broadcasts_theta_and_phi() -> None:
    rid = table_2d_rid()
    theta = np.array([[0.1], [0.4], [0.9]])
    phi = np.array([[0.0, 1.0, 2.0, 3.0]])
    f = rid(theta, phi)
    assert f.shape == (3, 4)
    assert f[1, 2] == rid(np.array([0.4]), np.array([2.0]))[0]
    # phi omitted means phi = 0.
    np.testing.assert_array_equal(rid(theta[:, 0]), rid(theta[:, 0], np.zeros(3)))


# ---------------------------------------------------------------- symmetric table


def test_symmetric_table_reproduces_its_knots_normalised_to_the_axis() -> None:
    theta = np.radians([0.0, 10.0, 20.0, 30.0, 45.0, 60.0, 80.0])
    raw = 4.0 * np.array([1.0, 0.97, 0.88, 0.72, 0.45, 0.2, 0.03])
    rid = SymmetricTableRID(theta, raw)
    exact = rid.value_and_derivatives(theta, exact=True)[0]
    np.testing.assert_allclose(exact, raw / 4.0, rtol=1e-15, atol=1e-16)
    # The renderer's grid (`rid_tabulate`): within its stated accuracy (test_rid_grid.py).
    np.testing.assert_allclose(rid(theta), raw / 4.0, rtol=0, atol=5e-6)
    assert float(rid(np.array(0.0))) == 1.0
    assert rid.symmetric


def test_symmetric_table_is_zero_beyond_its_last_knot() -> None:
    rid = symmetric_table_rid()
    last = float(rid.theta_rad[-1])
    assert float(rid(np.array(last))) == pytest.approx(0.03, rel=1e-14)
    f, ft, fp = rid.value_and_derivatives(np.array([last + 1e-9, 1.5, math.pi]))
    np.testing.assert_array_equal(f, np.zeros(3))
    np.testing.assert_array_equal(ft, np.zeros(3))
    np.testing.assert_array_equal(fp, np.zeros(3))


def test_symmetric_table_is_flat_on_the_axis_and_does_not_overshoot() -> None:
    rid = symmetric_table_rid()
    f, ft, _ = rid.value_and_derivatives(np.array([0.0, 1e-7]))
    assert ft[0] == 0.0
    assert abs(ft[1]) < 1e-6
    assert f[1] == pytest.approx(1.0, abs=1e-12)
    # PCHIP keeps monotone data monotone (no ringing above 1 or below 0).
    theta = np.linspace(0.0, float(rid.theta_rad[-1]), 2001)
    values = rid(theta)
    assert np.all(np.diff(values) <= 1e-15)
    assert values.max() <= 1.0
    assert values.min() >= 0.0


def test_symmetric_table_half_angle_lies_between_the_bracketing_knots() -> None:
    rid = symmetric_table_rid()  # 0.72 at 30 deg, 0.45 at 45 deg
    t = rid.half_angle_rad
    assert math.radians(30.0) < t < math.radians(45.0)
    assert float(rid(np.array(t))) == pytest.approx(0.5, abs=1e-10)


# ---------------------------------------------------------------- 2-D table


def test_2d_table_reproduces_its_knots() -> None:
    rid = table_2d_rid()
    tt, pp = np.meshgrid(rid.theta_rad, rid.phi_rad)
    exact = rid.value_and_derivatives(tt, pp, exact=True)[0]
    np.testing.assert_allclose(exact, rid.values, rtol=1e-14, atol=1e-16)
    np.testing.assert_allclose(rid(tt, pp), rid.values, rtol=0, atol=3e-4)  # the grid
    assert not rid.symmetric


def test_2d_table_normalises_by_the_mean_of_its_axis_column() -> None:
    theta = np.array([0.0, 0.5, 1.0])
    phi = np.array([0.0, 2.0, 4.0])
    values = np.array([[2.0, 1.5, 0.3], [4.0, 2.4, 0.6], [3.0, 3.0, 0.9]])  # axis mean 3
    rid = Table2DRID(theta, phi, values)
    exact = rid.value_and_derivatives(np.full(3, 0.5), phi, exact=True)[0]
    np.testing.assert_allclose(exact, [0.5, 0.8, 1.0], rtol=1e-15)
    np.testing.assert_allclose(rid(np.full(3, 0.5), phi), [0.5, 0.8, 1.0], rtol=0, atol=3e-4)
    np.testing.assert_array_equal(rid(np.zeros(3), phi), np.ones(3))
    np.testing.assert_array_equal(values[:, 0], [2.0, 4.0, 3.0])  # the input is not modified


def test_2d_table_without_azimuth_dependence_equals_the_symmetric_table() -> None:
    sym = symmetric_table_rid()
    phi = np.array([0.0, 1.0, 2.5, 4.0, 5.5])
    flat = Table2DRID(sym.theta_rad, phi, np.tile(sym.values, (phi.size, 1)))
    rng = np.random.default_rng(10)
    theta = rng.uniform(0.0, 1.5, 200)
    azimuth = rng.uniform(-7.0, 7.0, 200)
    f2, ft2, fp2 = flat.value_and_derivatives(theta, azimuth, exact=True)
    f1, ft1, _ = sym.value_and_derivatives(theta, exact=True)
    np.testing.assert_allclose(f2, f1, rtol=1e-13, atol=1e-15)
    np.testing.assert_allclose(ft2, ft1, rtol=1e-12, atol=1e-14)
    np.testing.assert_allclose(fp2, 0.0, atol=1e-13)
    # Their grids (different maps) agree to their stated accuracies.
    f2, ft2, fp2 = flat.value_and_derivatives(theta, azimuth)
    np.testing.assert_allclose(f2, f1, rtol=0, atol=3e-4)
    np.testing.assert_allclose(fp2, 0.0, atol=0.1)


def test_2d_table_is_periodic_in_phi() -> None:
    rid = table_2d_rid()
    rng = np.random.default_rng(11)
    theta = rng.uniform(0.0, 1.4, 300)
    phi = rng.uniform(-math.pi, math.pi, 300)
    f0, ft0, fp0 = rid.value_and_derivatives(theta, phi)
    for shift in (2 * math.pi, -2 * math.pi, 4 * math.pi):
        f, ft, fp = rid.value_and_derivatives(theta, phi + shift)
        np.testing.assert_allclose(f, f0, rtol=1e-12, atol=1e-14)
        np.testing.assert_allclose(ft, ft0, rtol=1e-11, atol=1e-13)
        np.testing.assert_allclose(fp, fp0, rtol=1e-11, atol=1e-13)


@pytest.mark.parametrize("phi_first", [0.0, 0.2])
def test_2d_table_is_continuous_across_the_last_to_first_row(phi_first: float) -> None:
    theta_knots = np.radians([0.0, 8.0, 17.0, 30.0, 45.0, 60.0, 72.0, 85.0])
    phi_knots = np.array([phi_first, 0.9, 1.6, 2.5, 3.3, 4.1, 5.0, 5.8])
    rid = Table2DRID(theta_knots, phi_knots, table_2d_values(theta_knots, phi_knots))
    theta = np.linspace(0.05, 1.4, 9)
    eps = 1e-9
    for seam in (phi_first, 5.8, 2 * math.pi):
        below = rid.value_and_derivatives(theta, np.full(9, seam - eps))
        above = rid.value_and_derivatives(theta, np.full(9, seam + eps))
        np.testing.assert_allclose(above[0], below[0], rtol=0, atol=1e-8)  # C0
        np.testing.assert_allclose(above[2], below[2], rtol=0, atol=1e-6)  # C1 in phi
    # The wrapped interval between the last row and the first one is interpolated
    # (not clamped): the midpoint differs from both rows.
    mid = 0.5 * (5.8 + phi_first + 2 * math.pi)
    f_mid = rid(theta, np.full(9, mid))
    f_last = rid(theta, np.full(9, 5.8))
    f_first = rid(theta, np.full(9, phi_first))
    assert np.all(np.minimum(f_last, f_first)[1:] - 1e-3 < f_mid[1:])
    assert np.all(f_mid[1:] < np.maximum(f_last, f_first)[1:] + 1e-3)
    assert np.all(np.abs(f_mid - f_last)[1:] > 1e-4)


def test_2d_table_interpolates_the_underlying_smooth_profile() -> None:
    # Rows every 15 degrees of a smooth profile: the interpolant is close to it off the knots.
    theta_knots = np.radians(np.arange(0.0, 86.0, 5.0))
    phi_knots = np.radians(np.arange(0.0, 360.0, 15.0))
    rid = Table2DRID(theta_knots, phi_knots, table_2d_values(theta_knots, phi_knots))
    rng = np.random.default_rng(12)
    theta = rng.uniform(0.0, math.radians(80.0), 400)
    phi = rng.uniform(0.0, 2 * math.pi, 400)
    exponent = 2.5 + 1.5 * np.cos(phi) + 0.8 * np.sin(2 * phi)
    error = np.abs(rid(theta, phi) - np.cos(theta) ** exponent)
    assert error.max() < 1e-2  # a row shifted by one knot errs by ~0.2
    assert error.mean() < 1e-3


# ---------------------------------------------------------------- derivatives


def _finite_differences(rid: RID, theta: np.ndarray, phi: np.ndarray, h: float = 1e-6):
    ft = (rid(theta + h, phi) - rid(theta - h, phi)) / (2 * h)
    fp = (rid(theta, phi + h) - rid(theta, phi - h)) / (2 * h)
    return ft, fp


@pytest.mark.parametrize("name", ["cos_power", "gaussian", "table_1d", "table_2d"])
def test_value_and_derivatives_match_finite_differences(name: str) -> None:
    rid = rid_model(name)
    rng = np.random.default_rng(13)
    theta = rng.uniform(0.02, 1.35, 300)
    phi = rng.uniform(-math.pi, math.pi, 300)
    f, ft, fp = rid.value_and_derivatives(theta, phi)
    np.testing.assert_array_equal(f, rid(theta, phi))
    ft_fd, fp_fd = _finite_differences(rid, theta, phi)
    np.testing.assert_allclose(ft, ft_fd, rtol=1e-6, atol=1e-7)
    np.testing.assert_allclose(fp, fp_fd, rtol=1e-6, atol=1e-7)
    if name == "table_2d":
        assert np.abs(fp).max() > 0.1  # the azimuth derivative is really exercised
    else:
        np.testing.assert_array_equal(fp, np.zeros(300))


def test_cos_power_derivative_by_hand() -> None:
    rid = CosPowerRID(3.0)
    t = 0.7
    _, ft, _ = rid.value_and_derivatives(np.array([t]))
    assert ft[0] == pytest.approx(-3.0 * math.cos(t) ** 2 * math.sin(t), rel=1e-14)


# ---------------------------------------------------------------- validation


@pytest.mark.parametrize(
    ("theta", "values", "message"),
    [
        (
            [5.0, 6.0, 7.0],
            [1.0, 0.5, 0.2],
            "RID table angles: expected the first angle to be 0 (the light axis), got 5",
        ),
        (
            [0.0],
            [1.0],
            "RID table angles: expected at least 2 angles in a 1-D array, got shape (1,)",
        ),
        (
            [[0.0, 1.0]],
            [[1.0, 0.5]],
            "RID table angles: expected at least 2 angles in a 1-D array, got shape (1, 2)",
        ),
        ([0.0, math.nan], [1.0, 0.5], "RID table angles: expected finite angles, got NaN or inf"),
        ([0.0, 0.5, 0.5], [1.0, 0.5, 0.2], "RID table angles: expected strictly increasing angles"),
        (
            [0.0, 1.0, 4.0],
            [1.0, 0.5, 0.2],
            "RID table angles: expected angles <= pi radians, got 4",
        ),
        (
            [0.0, 0.5, 1.0],
            [1.0, 0.5],
            "RID table values: expected 3 values (one per angle), got shape (2,)",
        ),
        ([0.0, 0.5, 1.0], [1.0, -0.5, 0.2], "RID table values: expected finite values >= 0"),
        ([0.0, 0.5, 1.0], [1.0, math.inf, 0.2], "RID table values: expected finite values >= 0"),
        (
            [0.0, 0.5, 1.0],
            [0.0, 0.5, 0.2],
            "RID table values: expected a positive value on the axis (theta = 0)",
        ),
    ],
)
def test_symmetric_table_validation_messages(theta: list, values: list, message: str) -> None:
    with pytest.raises(ValueError, match=_exact(message)):
        SymmetricTableRID(np.array(theta), np.array(values))


@pytest.mark.parametrize(
    ("phi", "values_shape", "message"),
    [
        ([0.0], (1, 3), "RID table azimuths: expected at least 2 azimuths, got shape (1,)"),
        (
            [0.0, 2 * math.pi],
            (2, 3),
            "RID table azimuths: expected strictly increasing values in [0, 2 pi)",
        ),
        (
            [-0.1, 1.0],
            (2, 3),
            "RID table azimuths: expected strictly increasing values in [0, 2 pi)",
        ),
        (
            [1.0, 1.0],
            (2, 3),
            "RID table azimuths: expected strictly increasing values in [0, 2 pi)",
        ),
        (
            [0.0, 1.0],
            (3, 2),
            "RID table values: expected shape (2, 3) (azimuths, angles), got (3, 2)",
        ),
    ],
)
def test_2d_table_validation_messages(phi: list, values_shape: tuple, message: str) -> None:
    with pytest.raises(ValueError, match=_exact(message)):
        Table2DRID(np.array([0.0, 0.5, 1.0]), np.array(phi), np.ones(values_shape))


def test_2d_table_value_checks() -> None:
    theta, phi = np.array([0.0, 0.5, 1.0]), np.array([0.0, 3.0])
    bad = np.ones((2, 3))
    bad[1, 2] = -1.0
    with pytest.raises(ValueError, match=_exact("RID table values: expected finite values >= 0")):
        Table2DRID(theta, phi, bad)
    zero_axis = np.ones((2, 3))
    zero_axis[:, 0] = 0.0
    with pytest.raises(
        ValueError,
        match=_exact("RID table values: expected a positive value on the axis (theta = 0)"),
    ):
        Table2DRID(theta, phi, zero_axis)
    with pytest.raises(
        ValueError,
        match=_exact(
            "RID table angles: expected the first angle to be 0 (the light axis), got 0.1"
        ),
    ):
        Table2DRID(np.array([0.1, 0.5, 1.0]), phi, np.ones((2, 3)))


@pytest.mark.parametrize(
    ("factory", "argument", "message"),
    [
        (CosPowerRID, -1.0, "cos-power exponent m: expected a finite value >= 0, got -1.0"),
        (CosPowerRID, math.nan, "cos-power exponent m: expected a finite value >= 0, got nan"),
        (GaussianRID, 0.0, "Gaussian sigma: expected a finite value > 0, got 0.0"),
        (GaussianRID, math.inf, "Gaussian sigma: expected a finite value > 0, got inf"),
        (
            CosPowerRID.from_half_angle,
            math.radians(95.0),
            "half-intensity angle: expected a value in (0, 90) degrees, got 95 degrees",
        ),
        (
            GaussianRID.from_half_angle,
            0.0,
            "half-intensity angle: expected a value in (0, 90) degrees, got 0 degrees",
        ),
        (
            CosPowerRID.from_half_angle,
            math.pi / 2,
            "half-intensity angle: expected a value in (0, 90) degrees, got 90 degrees",
        ),
    ],
)
def test_analytic_model_validation_messages(factory, argument: float, message: str) -> None:
    with pytest.raises(ValueError, match=_exact(message)):
        factory(argument)


@pytest.mark.parametrize("level", [0.0, 1.0, 1.5])
def test_angle_at_level_rejects_levels_outside_zero_one(level: float) -> None:
    with pytest.raises(ValueError, match=_exact(f"level: expected a value in (0, 1), got {level}")):
        CosPowerRID(2.0).angle_at_level_rad(level)


def test_angle_at_level_of_the_2d_table_takes_the_widest_azimuth() -> None:
    rid = table_2d_rid()
    t = rid.angle_at_level_rad(0.5)
    phi = np.linspace(0.0, 2 * math.pi, 721)
    peak = rid(np.full(721, t), phi).max()
    assert peak == pytest.approx(0.5, abs=2e-3)
    assert rid(np.full(721, t + 0.01), phi).max() < 0.5


def test_rid_data_arrays_are_c_contiguous() -> None:
    for name in ("cos_power", "table_1d", "table_2d"):
        d = rid_model(name).data()
        for array in (d.params, d.theta_knots, d.phi_knots, d.values, d.slopes):
            assert array.dtype == np.float64
            assert array.flags.c_contiguous


@pytest.mark.parametrize("n", [2, 3, 5, 19, 181])
def test_pchip_slopes_are_scipys(n: int) -> None:
    """Our PCHIP knot slopes (start-up avoids importing scipy.interpolate) equal SciPy's
    PchipInterpolator's on uneven knots, for smooth, noisy, flat and stepped profiles."""
    from scipy.interpolate import PchipInterpolator

    from lightcal.core.rid import pchip_slopes

    rng = np.random.default_rng(n)
    x = np.cumsum(rng.uniform(0.2, 1.0, n))
    tables = np.stack(
        [
            np.cos(x / x[-1]) ** 3,  # smooth and monotone
            rng.uniform(0.0, 1.0, n),  # noisy: secants change sign
            np.ones(n),  # flat: zero secants
            (x > x[n // 2]).astype(float),  # a step: zeros beside a jump
        ]
    )
    expected = PchipInterpolator(x, tables, axis=-1).derivative()(x)
    got = pchip_slopes(x, tables)
    assert got.shape == tables.shape
    np.testing.assert_allclose(got, expected, rtol=1e-12, atol=1e-14)
    np.testing.assert_allclose(pchip_slopes(x, tables[1]), expected[1], rtol=1e-12, atol=1e-14)
