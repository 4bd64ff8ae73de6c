"""The misfit tests: level (chi^2), structure (residuals against angles), image noise."""

from __future__ import annotations

import math

import numpy as np
import pytest

from lightcal.core.misfit import NOISE_SAMPLES, angle_trend, diagnose, image_noise, pixel_angles
from lightcal.core.misfit_kernels import binned_noise, noise_samples
from lightcal.core.misfit_verdict import CauseTest, percent, significant_digits


def _angles(rng: np.random.Generator, m: int) -> tuple[np.ndarray, np.ndarray]:
    mirror = rng.uniform(0.0, 40.0, m)
    return mirror, mirror + rng.uniform(0.0, 5.0, m)


def test_pixel_angles_hand_case() -> None:
    """Light and camera symmetric about the normal: mirror angle 0, incidence 45 deg."""
    p = np.array([[0.0, 0.0, 0.0]])
    mirror, incidence = pixel_angles(p, np.array([1.0, 0.0, 1.0]), np.array([-2.0, 0.0, 2.0]))
    assert mirror[0] == pytest.approx(0.0, abs=1e-6)
    assert incidence[0] == pytest.approx(45.0, abs=1e-12)
    mirror, _ = pixel_angles(p, np.array([0.0, 0.0, 1.0]), np.array([1.0, 0.0, 1.0]))
    assert mirror[0] == pytest.approx(22.5, abs=1e-12)


def test_noise_only_is_adequate_in_most_seeds() -> None:
    alarms = 0
    for seed in range(40):
        rng = np.random.default_rng(seed)
        m = 1200
        r = rng.normal(size=m)
        mirror, incidence = _angles(rng, m)
        d = diagnose(
            r,
            0.01 * r,
            mirror,
            incidence,
            n_params=7,
            noise_source="model",
            wall_model="lambertian",
        )
        alarms += not d.adequate
        if d.adequate:
            assert d.findings == []
    assert alarms <= 1


def _cause(name: str, *, p: float, relative: float, shift_sigma: float, bic: float = 50.0):
    return CauseTest(name, 2, 40.0, 20.0, p, relative, bic, shift_sigma, 0.012, 0.4)


def _judged(r: np.ndarray, causes, noise_source: str = "model", **kw):
    rng = np.random.default_rng(3)
    mirror, incidence = _angles(rng, r.size)
    return diagnose(
        r,
        0.01 * r,
        mirror,
        incidence,
        n_params=7,
        noise_source=noise_source,
        wall_model="lambertian",
        causes=causes,
        **kw,
    )


def test_a_material_cause_is_a_finding_named_first_by_its_bic() -> None:
    r = 3.0 * np.random.default_rng(0).normal(size=1200)  # the level fails
    d = _judged(
        r,
        [
            _cause("vignetting", p=1e-9, relative=0.02, shift_sigma=3.0, bic=40.0),
            _cause("gloss", p=1e-12, relative=0.05, shift_sigma=6.1, bic=90.0),
        ],
        excess_relative=0.03,
        jackknife_ratio=1.2,
    )
    assert not d.adequate
    assert [c.name for c in d.causes] == ["gloss", "vignetting"]
    assert d.findings[0] == (
        "the wall is brighter than the model toward the mirror direction: it looks glossy "
        "(a correction of 5.0 % of the signal that moves the light by 12 mm and 0.40 deg "
        "(6.1 sigma)); try `wall: {model: plastic}` (or `auto`), or "
        "`selection.exclude_mirror_deg`"
    )
    assert d.findings[1] == (
        "less likely causes that would also move the pose: vignetting (12 mm, 0.40 deg)"
    )
    assert d.to_dict()["adequate"] is False
    assert d.to_dict()["causes"][0]["material"] is True


@pytest.mark.parametrize(
    ("p", "relative", "shift_sigma"),
    [(0.01, 0.05, 6.0), (1e-9, 0.002, 6.0), (1e-9, 0.05, 0.6)],
    ids=["not significant", "below the relative floor", "below one sigma"],
)
def test_a_cause_below_any_floor_is_no_finding(p: float, relative: float, shift_sigma: float):
    r = 3.0 * np.random.default_rng(0).normal(size=1200)
    cause = _cause("ambient", p=p, relative=relative, shift_sigma=shift_sigma)
    d = _judged(r, [cause], excess_relative=0.03, jackknife_ratio=1.2)
    assert d.adequate and d.findings == []
    assert d.notes[-1].endswith("; the sigma includes the misfit")


def test_no_finding_when_the_level_is_explained() -> None:
    """A significant cause on residuals the noise explains (what the camera's declared
    errors leave) is a note, never a finding."""
    r = np.random.default_rng(0).normal(size=1200)
    d = _judged(r, [_cause("wall", p=1e-9, relative=0.05, shift_sigma=6.0)])
    assert d.explained and d.adequate and d.findings == []
    assert d.notes == [
        "wall: a correction of 5.0 % of the signal that moves the light by 12 mm and 0.40 deg "
        "(6.0 sigma): within what the noise and the camera's declared errors explain"
    ]


def test_level_without_a_cause() -> None:
    rng = np.random.default_rng(1)
    r = 2.0 * rng.normal(size=1200)
    d = _judged(r, [], noise_source="image", excess_relative=0.02, jackknife_ratio=2.5)
    assert not d.adequate
    assert d.chi2_per_dof == pytest.approx(4.0, rel=0.1)
    assert "what the noise from the images explains" in d.findings[-1]
    assert "no single cause explains them" in d.findings[-1]
    assert d.findings[-1].endswith("the RID and the sensor model")
    # The images agree (jackknife within 2x): a note, not a finding.
    d = _judged(r, [], noise_source="image", excess_relative=0.02, jackknife_ratio=1.4)
    assert d.adequate and d.notes[0].startswith("residuals are 2.00x what the noise")
    # Without a noise estimate the level is not tested.
    d = _judged(r, [], noise_source="none")
    assert d.adequate
    assert math.isnan(d.p_value)


@pytest.mark.parametrize(
    ("value", "text"),
    [(0.00013, "+0.013 %"), (-0.25, "-25 %"), (0.0, "0 %"), (1.5, "+150 %"), (-4e-7, "-4.0e-05 %")],
)
def test_percentages_keep_two_significant_digits(value: float, text: str) -> None:
    assert percent(value) == text


def test_significant_digits() -> None:
    assert [significant_digits(v) for v in (0.01234, 12.3, 1534.0, 0.0, 0.4, 2.0)] == [
        "0.012",
        "12",
        "1500",
        "0",
        "0.40",
        "2.0",
    ]
    assert significant_digits(1.9972, 3) == "2.00"
    assert significant_digits(153400.0) == "1.5e+05"


def _numpy_bins(
    angles: np.ndarray, r: np.ndarray, relative: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
    """(count, means, mean relative, within) by NumPy, as `angle_trend` computed them."""
    edges = np.unique(np.quantile(angles, np.linspace(0.0, 1.0, 9)))
    k = edges.size - 1
    idx = np.clip(np.searchsorted(edges, angles, side="right") - 1, 0, k - 1)
    count = np.bincount(idx, minlength=k).astype(np.float64)
    means = np.bincount(idx, weights=r, minlength=k) / np.maximum(count, 1.0)
    rel = np.bincount(idx, weights=relative, minlength=k) / np.maximum(count, 1.0)
    return count, means, rel, float(np.sum((r - means[idx]) ** 2))


def test_angle_trend_bins_as_numpy_bit_for_bit() -> None:
    rng = np.random.default_rng(8)
    m = 50_000
    angles = np.round(rng.uniform(0.0, 30.0, m), 1)  # ties, and values on the edges
    angles[:20] = np.nan
    r = rng.normal(size=m) + 0.01 * angles
    relative = 0.02 * rng.normal(size=m)
    t = angle_trend("incidence", angles[20:], r[20:], relative[20:])
    assert t is not None
    count, means, rel, within = _numpy_bins(angles[20:], r[20:], relative[20:])
    np.testing.assert_array_equal(t.count, count)
    np.testing.assert_array_equal(t.mean_residual, means)
    np.testing.assert_array_equal(t.mean_relative, rel)
    sd = math.sqrt(within / (m - 20 - count.size))
    grand = float(r[20:].mean())
    assert t.effect == float(np.sqrt(np.sum(count * (means - grand) ** 2) / (m - 20))) / sd
    # A NaN angle makes every quantile NaN: no bins, no test (as before).
    assert angle_trend("mirror", angles, r, relative) is None


def _numpy_noise_bins(
    values: np.ndarray, usable: np.ndarray, offset: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """image_noise's bins as first written in NumPy (full-size temporaries, np.median per
    bin): (median level, robust variance, count) of the bins of >= 100 pixels."""
    v = np.asarray(values, dtype=np.float64)
    h, w = v.shape
    step = -(-((h - 2) * (w - 2)) // NOISE_SAMPLES)
    rows = np.arange(1, h - 1, step)
    above, here, below = v[rows - 1] - offset, v[rows] - offset, v[rows + 1] - offset
    lap = here[:, 1:-1] - 0.25 * (above[:, 1:-1] + below[:, 1:-1] + here[:, :-2] + here[:, 2:])
    diag = 0.25 * (above[:, :-2] + below[:, 2:] + above[:, 2:] + below[:, :-2])
    ok = np.ones(lap.shape, dtype=bool)
    for dy in (-1, 0, 1):
        for dx in range(3):
            ok &= usable[rows + dy][:, dx : dx + w - 2]
    ok &= np.isfinite(lap) & np.isfinite(diag)
    level, n = diag[ok], lap[ok]
    edges = np.quantile(level, np.linspace(0, 1, 13))
    idx = np.clip(np.searchsorted(edges, level, side="right") - 1, 0, 11)
    xs, ys, ws = [], [], []
    for b in range(12):
        sel = idx == b
        if sel.sum() < 100:
            continue
        nb = n[sel]
        mad = float(np.median(np.abs(nb - np.median(nb))))
        xs.append(float(np.median(level[sel])))
        ys.append((1.4826 * mad) ** 2 / 1.25)
        ws.append(int(sel.sum()))
    return np.array(xs), np.array(ys), np.array(ws)


@pytest.mark.parametrize("h, w", [(120, 90), (700, 1001)])  # even and odd bin sizes
def test_image_noise_bins_equal_the_numpy_formulation(h: int, w: int) -> None:
    rng = np.random.default_rng(5)
    yy, xx = np.mgrid[0:h, 0:w]
    img = 100.0 + 5.0 * xx + 2.0 * yy + rng.normal(size=(h, w)) * 3.0
    img[10, 20] = np.nan  # skipped with its neighbours
    img[30, 40] = np.inf
    usable = rng.random((h, w)) > 0.02
    rows = np.arange(1, h - 1, -(-((h - 2) * (w - 2)) // NOISE_SAMPLES), dtype=np.int64)
    level, n = noise_samples(img, usable, rows, 4.0)
    edges = np.quantile(level, np.linspace(0, 1, 13))
    count, median_level, mad = binned_noise(level, n, edges, 100)
    kept = count >= 100
    xs, ys, ws = _numpy_noise_bins(img, usable, 4.0)
    np.testing.assert_array_equal(median_level[kept], xs)
    np.testing.assert_array_equal((1.4826 * mad[kept]) ** 2 / 1.25, ys)
    np.testing.assert_array_equal(count[kept], ws)
    assert np.all(np.isnan(median_level[~kept]))


def test_angle_trend_needs_pixels() -> None:
    assert angle_trend("mirror", np.arange(50.0), np.zeros(50), np.zeros(50)) is None


@pytest.mark.parametrize("h, w", [(300, 400), (900, 1200)])  # the second one subsampled
def test_image_noise_recovers_poisson_gaussian(h: int, w: int) -> None:
    rng = np.random.default_rng(2)
    assert (h - 2) * (w - 2) < NOISE_SAMPLES or (h - 2) * (w - 2) > 5 * NOISE_SAMPLES
    yy, xx = np.mgrid[0:h, 0:w]
    s = h / 300.0
    signal = 3000.0 * np.exp(
        -((xx - 200.0 * s) ** 2 + (yy - 150.0 * s) ** 2) / (2 * (150.0 * s) ** 2)
    )
    signal += 50.0
    gain, read_variance = 0.8, 25.0
    img = signal + rng.normal(size=signal.shape) * np.sqrt(gain * signal + read_variance)
    est = image_noise(img, np.ones((h, w), dtype=bool))
    assert est is not None
    assert est[0] == pytest.approx(gain, rel=0.1)
    # The variance where the pixels are (the intercept alone is poorly determined).
    for level in (300.0, 1500.0, 3000.0):
        assert est[0] * level + est[1] == pytest.approx(gain * level + read_variance, rel=0.1)
    assert image_noise(img[:20, :20], np.ones((20, 20), dtype=bool)) is None
    # An offset given is removed from the rows read, as if from the whole image.
    usable = np.ones((h, w), dtype=bool)
    shifted = image_noise(img + 7.0, usable, offset=7.0)
    assert shifted is not None
    np.testing.assert_allclose(shifted, est, rtol=1e-9)
