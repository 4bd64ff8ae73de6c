"""Is the fit explained by the noise? Residual tests after a solve.

Two questions, each with a test whose false-alarm rate is fixed (`P_ALARM`):

1. **Level**: chi^2 = sum r^2 of the weighted residuals r = (m_obs - m_render) / sigma
   against the chi^2 distribution with m - n degrees of freedom. Only meaningful when
   sigma is the real noise: from the sensor's noise model, or estimated from the images
   themselves (`image_noise`). A value far above 1 per degree of freedom means the model
   does not explain the data (wrong wall model, wrong poses, wrong RID, stray light).
2. **Structure**: do the residuals depend on an angle? A one-way analysis of variance of r
   over quantile bins of (a) the angle between the wall normal and the half vector of
   the light and view directions (0 in the mirror direction: the signature of gloss),
   (b) the angle of incidence (the signature of a non-Lambertian fall-off, e.g. a rough
   matte wall). The F statistic compares the spread of the bin means to the spread
   within the bins, so it holds whether or not sigma is known.

The test is conservative about what it claims: a significant structure must also be large
enough to matter (`MIN_EFFECT`, the RMS of the bin means in sigma units).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numba
import numpy as np
from scipy import special  # not scipy.stats: 0.6 s to import, for two tail functions

from lightcal.core.misfit_kernels import (
    binned_noise,
    noise_samples,
    quantile_bin,
)
from lightcal.core.misfit_verdict import (
    JACKKNIFE_FLOOR,
    P_ALARM,
    RELATIVE_FLOOR,
    SHIFT_FLOOR_SIGMA,
    CauseTest,
    is_material,
    verdict,
)
from lightcal.core.quantiles import quantiles

#: Quantile bins of each angle.
N_BINS = 8
#: A structure must move the bin means by at least this RMS (sigma units) to count.
MIN_EFFECT = 0.1
#: Above this chi^2 per degree of freedom the level test fails whatever its p-value (a
#: fit whose residuals are 1.5x the noise is not explained by it, however few pixels).
MAX_CHI2_PER_DOF = 1.5


def _finite(v: float) -> float | None:
    """v, or None where it is NaN or infinite (JSON has neither)."""
    return float(v) if math.isfinite(v) else None


@dataclass(frozen=True)
class AngleTrend:
    """Weighted residuals against one angle.

    Attributes:
        angle: "mirror" (half vector to the wall normal) or "incidence".
        bin_edges_deg: (k + 1,) quantile bin edges, degrees.
        mean_residual: (k,) mean weighted residual per bin (sigma units).
        mean_relative: (k,) relative residual per bin, sum (m_obs - m_render) / sum
            (m_render - offset): signal-weighted, so dark pixels cannot blow it up.
        count: (k,) pixels per bin.
        f_statistic, p_value: the one-way analysis of variance.
        effect: RMS of the bin means (sigma units).
    """

    angle: str
    bin_edges_deg: np.ndarray
    mean_residual: np.ndarray
    mean_relative: np.ndarray
    count: np.ndarray
    f_statistic: float
    p_value: float
    effect: float

    @property
    def relative_spread(self) -> float:
        """RMS of the bins' relative residuals (pixel-weighted)."""
        total = float(self.count.sum())
        if not total > 0:
            return 0.0
        return math.sqrt(float(np.sum(self.count * self.mean_relative**2)) / total)

    @property
    def significant(self) -> bool:
        """A structure against the angle that is significant and large enough to matter:
        p < `P_ALARM`, `MIN_EFFECT` sigmas and `RELATIVE_FLOOR` of the signal (for the
        report's plot; the verdict is the causes')."""
        return (
            self.p_value < P_ALARM
            and self.effect >= MIN_EFFECT
            and self.relative_spread >= RELATIVE_FLOOR
        )

    def to_dict(self) -> dict:
        return {
            "angle": self.angle,
            "bin_edges_deg": self.bin_edges_deg.tolist(),
            "mean_residual_sigma": self.mean_residual.tolist(),
            "mean_relative_residual": self.mean_relative.tolist(),
            "count": self.count.tolist(),
            "f_statistic": _finite(self.f_statistic),
            "p_value": _finite(self.p_value),
            "effect_sigma": _finite(self.effect),
            "relative_spread": _finite(self.relative_spread),
            "significant": self.significant,
        }


@dataclass(frozen=True)
class FitDiagnosis:
    """The verdict on a fit.

    Attributes:
        noise_source: "model" (the sensor's noise model), "image" (estimated from each
            image) or "none" (sigma = 1: the level test is skipped).
        chi2, dof, chi2_per_dof, p_value: the level test (NaN p-value without noise).
        expected_chi2: what chi^2 should be if the model is right: dof plus what the
            camera poses' errors leave (`lightcal.core.uncertainty`).
        mirror, incidence: the residuals against those angles (None with too few pixels),
            for the report's plot.
        adequate: no finding: nothing that would move the pose beyond its sigma.
        findings: what the tests saw that matters and what to try, one sentence each,
            the most likely cause first.
        causes: every candidate cause's test, most likely (largest BIC gain) first.
        excess_relative: the residuals' RMS beyond what the noise explains, relative to
            the signal's RMS (NaN without noise).
        jackknife_ratio: the leave-one-image-out jackknife's sigma over the statistical
            sigma in the pose's worst direction (NaN when not computed).
        notes: what the tests saw that is too small to act on.
    """

    noise_source: str
    chi2: float
    dof: int
    chi2_per_dof: float
    p_value: float
    expected_chi2: float
    mirror: AngleTrend | None
    incidence: AngleTrend | None
    adequate: bool
    findings: list[str] = field(default_factory=list)
    causes: list[CauseTest] = field(default_factory=list)
    excess_relative: float = math.nan
    jackknife_ratio: float = math.nan
    notes: list[str] = field(default_factory=list)

    @property
    def chi2_ratio(self) -> float:
        """chi^2 / its expected value (1 when the model explains the data)."""
        return self.chi2 / self.expected_chi2 if self.expected_chi2 > 0 else math.nan

    @property
    def level_fails(self) -> bool:
        """chi^2 is significantly above what the noise (and the camera's errors) explain."""
        if self.noise_source == "none" or self.dof <= 0:
            return False
        return self.chi2_ratio > MAX_CHI2_PER_DOF or (
            self.p_value < P_ALARM and self.chi2_ratio > 1.0 + MIN_EFFECT**2
        )

    @property
    def explained(self) -> bool:
        """The residuals are explained by the noise and the camera's declared errors: the
        level test passes (without a known noise, no cause is significant with a relative
        effect of at least `RELATIVE_FLOOR`). Then there is no finding and the uncertainty
        has no systematic term: a cause the level does not need is what the camera
        poses' and intrinsics' declared errors leave."""
        if self.noise_source != "none" and self.dof > 0:
            return not self.level_fails
        return not any(c.significant and c.relative_effect >= RELATIVE_FLOOR for c in self.causes)

    def to_dict(self) -> dict:
        return {
            "adequate": self.adequate,
            "explained_by_noise": self.explained,
            "noise_source": self.noise_source,
            "chi2": _finite(self.chi2),
            "dof": self.dof,
            "chi2_per_dof": _finite(self.chi2_per_dof),
            "expected_chi2": _finite(self.expected_chi2),
            "p_value": _finite(self.p_value),
            "excess_relative": _finite(self.excess_relative),
            "jackknife_ratio": _finite(self.jackknife_ratio),
            "floors": {
                "relative_effect": RELATIVE_FLOOR,
                "shift_sigma": SHIFT_FLOOR_SIGMA,
                "jackknife_ratio": JACKKNIFE_FLOOR,
                "p_alarm": P_ALARM,
            },
            "causes": [
                {
                    **c.to_dict(),
                    "material": not self.explained and is_material(c, self.jackknife_ratio),
                }
                for c in self.causes
            ],
            "mirror": None if self.mirror is None else self.mirror.to_dict(),
            "incidence": None if self.incidence is None else self.incidence.to_dict(),
            "findings": list(self.findings),
            "notes": list(self.notes),
        }


def angle_trend(
    angle: str,
    angles_deg: np.ndarray,
    r: np.ndarray,
    relative: np.ndarray,
    signal: np.ndarray | None = None,
) -> AngleTrend | None:
    """One-way ANOVA of residuals r (m,) over N_BINS quantile bins of angles_deg (m,).

    relative (m,) is (m_obs - m_render) / (m_render - offset) per pixel and signal (m,)
    its denominator (default 1: plain means); a bin's relative residual is their
    signal-weighted mean. None when there are fewer than 10 pixels per bin.
    """
    m = r.size
    if m < 10 * N_BINS:
        return None
    edges = np.unique(quantiles(angles_deg, np.linspace(0.0, 1.0, N_BINS + 1)))
    k = edges.size - 1
    if k < 2:
        return None
    # Per bin: pixel counts and sums of r and relative (as np.bincount adds them), then
    # sum (r - its bin's mean)^2; compiled passes instead of a dozen (m,) temporaries.
    count = np.zeros(k)
    sums = np.zeros(k)
    rel_sums = np.zeros(k)
    sig_sums = np.zeros(k)
    angles = np.ascontiguousarray(angles_deg)  # float64 or float32 (not copied)
    r = np.ascontiguousarray(r, dtype=np.float64)
    weight = np.ones(m, dtype=np.float32) if signal is None else np.ascontiguousarray(signal)
    _bin_sums(
        edges, angles, r, np.ascontiguousarray(relative), weight, count, sums, rel_sums, sig_sums
    )
    means = sums / np.maximum(count, 1.0)
    rel = np.where(sig_sums > 0.0, rel_sums / np.where(sig_sums > 0.0, sig_sums, 1.0), 0.0)
    grand = float(r.mean())
    between = float(np.sum(count * (means - grand) ** 2))
    squares = np.empty(m)
    _squared_deviations(edges, angles, r, means, squares)
    within = float(np.sum(squares))
    del squares
    df_b, df_w = k - 1, m - k
    if within <= 0.0:
        f_stat = math.inf if between > 0 else 0.0
    else:
        f_stat = (between / df_b) / (within / df_w)
    p = float(special.fdtrc(df_b, df_w, f_stat)) if math.isfinite(f_stat) else 0.0  # F sf
    sd = math.sqrt(within / df_w) if within > 0 else 1.0
    effect = float(np.sqrt(np.sum(count * (means - grand) ** 2) / m)) / sd
    return AngleTrend(angle, edges, means, rel, count.astype(np.int64), f_stat, p, effect)


@numba.njit(cache=True)
def _bin_sums(
    edges: np.ndarray,
    angles: np.ndarray,
    r: np.ndarray,
    relative: np.ndarray,
    signal: np.ndarray,
    count: np.ndarray,
    sums: np.ndarray,
    rel_sums: np.ndarray,
    sig_sums: np.ndarray,
) -> None:
    """Add each pixel's 1, r, relative * signal and signal (m,) to its bin's count, sums,
    rel_sums and sig_sums (k,), in pixel order (the sums of `np.bincount` with weights)."""
    for i in range(angles.size):
        b = quantile_bin(edges, angles[i])
        count[b] += 1.0
        sums[b] += r[i]
        w = float(signal[i])
        rel_sums[b] += relative[i] * w
        sig_sums[b] += w


@numba.njit(cache=True)
def _squared_deviations(
    edges: np.ndarray, angles: np.ndarray, r: np.ndarray, means: np.ndarray, out: np.ndarray
) -> None:
    """out (m,) = (r - the mean of each pixel's bin)^2."""
    for i in range(angles.size):
        d = r[i] - means[quantile_bin(edges, angles[i])]
        out[i] = d * d


def diagnose(
    r: np.ndarray,
    relative: np.ndarray,
    mirror_deg: np.ndarray,
    incidence_deg: np.ndarray,
    *,
    n_params: int,
    noise_source: str,
    wall_model: str,
    expected_extra: float = 0.0,
    signal: np.ndarray | None = None,
    causes: list[CauseTest] | None = None,
    excess_relative: float = math.nan,
    jackknife_ratio: float = math.nan,
) -> FitDiagnosis:
    """Judge whether the residuals matter: the level test, the candidate causes and the
    jackknife, each on its effect size as well as its significance (docs/model.md,
    "Is the fit explained by the noise?").

    Args:
        r: (m,) weighted residuals (m_obs - m_render) / sigma.
        relative: (m,) relative residuals (m_obs - m_render) / (m_render - offset).
        mirror_deg: (m,) angle between the wall normal and the half vector, degrees.
        incidence_deg: (m,) angle of incidence of the light, degrees.
        n_params: parameters fitted.
        noise_source: "model", "image" or "none" (see `FitDiagnosis`).
        wall_model: the wall model the fit used (for the advice).
        expected_extra: chi^2 the camera poses' errors leave on average (0: none known).
        signal: (m,) m_render - offset (the angle bins' weights; default 1).
        causes: the candidate causes' tests (`lightcal.pipeline.fit_check`).
        excess_relative, jackknife_ratio: see `FitDiagnosis`.
    """
    m = int(r.size)
    dof = m - n_params
    chi2 = float(r @ r)
    per_dof = chi2 / dof if dof > 0 else math.nan
    expected = dof + max(expected_extra, 0.0)
    p = math.nan
    if dof > 0 and noise_source != "none":
        # chi^2 scaled to dof degrees of freedom (exact without pose errors).
        p = float(special.chdtrc(dof, chi2 * dof / expected))  # chi^2 sf
    mirror = angle_trend("mirror", mirror_deg, r, relative, signal)
    incidence = angle_trend("incidence", incidence_deg, r, relative, signal)
    ranked = sorted(causes or [], key=lambda c: -c.bic_gain if math.isfinite(c.bic_gain) else 0.0)
    parts = (noise_source, chi2, dof, per_dof, p, expected, mirror, incidence)
    draft = FitDiagnosis(
        *parts,
        True,
        causes=ranked,
        excess_relative=excess_relative,
        jackknife_ratio=jackknife_ratio,
    )
    findings, notes = verdict(draft, wall_model)
    return replace(draft, adequate=not findings, findings=findings, notes=notes)


def pixel_angles(
    points_world: np.ndarray, light_world: np.ndarray, camera_world: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Mirror and incidence angles (degrees, (N,) each) at wall points (N, 3).

    mirror: angle between the wall normal +z and the half vector of the unit directions
    to the light and to the camera; incidence: angle between the normal and the light.
    """
    # Per coordinate (contiguous columns): the same arithmetic as norms of (N, 3) rows,
    # several times faster on millions of points.
    p = np.asarray(points_world, dtype=np.float64)
    lx, ly, lz = (light_world[k] - p[:, k] for k in range(3))
    vx, vy, vz = (camera_world[k] - p[:, k] for k in range(3))
    ln = np.sqrt(lx * lx + ly * ly + lz * lz)
    vn = np.sqrt(vx * vx + vy * vy + vz * vz)
    lx /= ln
    ly /= ln
    lz /= ln
    hx = lx + vx / vn
    hy = ly + vy / vn
    hz = lz + vz / vn
    hz /= np.sqrt(hx * hx + hy * hy + hz * hz)
    mirror = np.degrees(np.arccos(np.clip(hz, -1.0, 1.0)))
    incidence = np.degrees(np.arccos(np.clip(lz, -1.0, 1.0)))
    return mirror, incidence


NOISE_SAMPLES = 200_000
"""Most usable pixels `image_noise` reads from one image (a regular subsample beyond)."""

NOISE_BIN_MIN = 100
"""Fewest pixels a level bin of `image_noise` needs to enter the fit."""


def image_noise(
    values: np.ndarray, usable: np.ndarray, offset: float = 0.0
) -> tuple[float, float] | None:
    """A Poisson-Gaussian noise model (gain, read_variance) estimated from one image.

    The wall's shading is smooth, so the difference between a pixel and the mean of its
    four neighbours, n = v - (left + right + up + down) / 4, is noise with variance
    (1 + 4/16) sigma^2 = 1.25 sigma^2 (independent pixels). Its robust variance
    (1.4826 MAD)^2 in 12 quantile bins of the level is fitted by a line
    variance = gain * level + read_variance (weighted least squares, both >= 0). The
    level is the mean of the four diagonal neighbours, whose noise is independent of n
    (binning by the pixel's own value would select on its noise and bias the variance).

    Args:
        values: (H, W) linear values.
        usable: (H, W) pixels to use (lit, unsaturated, unmasked).
        offset: the values' offset, subtracted from the rows read (not the whole image).

    Returns:
        (gain, read_variance), or None with fewer than 2,000 usable interior pixels.
        Beyond NOISE_SAMPLES interior pixels, every k-th row is used.
        Demosaiced or compressed images have correlated noise: the estimate is then low.
    """
    v = np.ascontiguousarray(values, dtype=np.float64)
    if v.ndim != 2 or v.shape[0] < 3 or v.shape[1] < 3:
        return None
    # Every k-th interior row, at most NOISE_SAMPLES pixels: 200,000 samples pin each
    # bin's variance to about 2 %, and the medians cost ~4 ms.
    h, w = v.shape
    step = -(-((h - 2) * (w - 2)) // NOISE_SAMPLES)
    rows = np.arange(1, h - 1, step, dtype=np.int64)
    level, n = noise_samples(v, np.ascontiguousarray(usable, dtype=np.bool_), rows, offset)
    if level.size < 2000:
        return None
    edges = quantiles(level, np.linspace(0, 1, 13))
    count, median_level, mad = binned_noise(level, n, edges, NOISE_BIN_MIN)
    kept = count >= NOISE_BIN_MIN
    if np.count_nonzero(kept) < 2:
        return None
    x = median_level[kept]
    y = (1.4826 * mad[kept]) ** 2 / 1.25
    w = np.sqrt(count[kept].astype(np.float64))
    A = np.stack([x, np.ones_like(x)], axis=1) * w[:, None]
    from scipy.optimize import nnls

    (gain, read_variance), _ = nnls(A, y * w)
    if read_variance <= 0.0:
        read_variance = max(float(np.min(y)) * 1e-3, 1e-12)
    return float(gain), float(read_variance)
