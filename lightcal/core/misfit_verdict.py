"""The fit test's verdict: each candidate cause judged on its effect size, and the words.

A cause (`lightcal.core.misfit_causes`) fitted beside the model
(`lightcal.core.alternatives`) is a *finding* only when it is significant (`P_ALARM`),
large (`RELATIVE_FLOOR` of the signal) and moves the pose by at least
`SHIFT_FLOOR_SIGMA` statistical sigmas; what is significant but smaller is a note. The
floors are documented in docs/model.md, "Is the fit explained by the noise?".
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

from lightcal.core.misfit_causes import CAUSES

if TYPE_CHECKING:
    from lightcal.core.misfit import FitDiagnosis

__all__ = [
    "JACKKNIFE_FLOOR",
    "P_ALARM",
    "RELATIVE_FLOOR",
    "SHIFT_FLOOR_SIGMA",
    "CauseTest",
    "is_material",
    "percent",
    "significant_digits",
    "verdict",
]

#: False-alarm probability of each test on data the model explains.
P_ALARM = 1e-3
#: A cause's fitted correction must change the rendered values by at least this fraction
#: of the signal (RMS, `CauseTest.relative_effect`) to be a finding: below, no one would
#: act on it, however significant (a million pixels make 0.01 % significant).
RELATIVE_FLOOR = 0.003
#: ... and move the pose by at least this many of its statistical sigmas (Mahalanobis
#: distance over every light's pose parameters).
SHIFT_FLOOR_SIGMA = 1.0
#: A misfit no cause explains is a finding when the leave-one-image-out jackknife's
#: sigma exceeds the statistical one by this factor in some direction of the pose (the
#: jackknife of 12 images alone reaches ~1.5x by chance).
JACKKNIFE_FLOOR = 2.0


def _finite_or_none(v: float) -> float | None:
    return float(v) if math.isfinite(v) else None


def significant_digits(v: float, digits: int = 2) -> str:
    """v with `digits` significant digits, trailing zeros kept, no exponent for ordinary
    sizes ("0.012", "2.00", "150", "1500", "1.5e+05")."""
    if not math.isfinite(v):
        return str(v)
    if v == 0.0:
        return "0"
    text = f"{v:#.{digits}g}"
    if "e" in text:
        e = int(text.split("e")[1])
        if -4 <= e < digits + 2:
            return f"{round(v, digits - 1 - e):.{max(digits - 1 - e, 0)}f}"
        return text
    return text.rstrip(".")


def percent(v: float) -> str:
    """A fraction as a signed percentage with two significant digits ("+0.42 %")."""
    sign = "+" if v > 0 else "-" if v < 0 else ""
    return f"{sign}{significant_digits(abs(100.0 * v))} %"


@dataclass(frozen=True)
class CauseTest:
    """One candidate cause of a misfit fitted beside the model
    (`lightcal.core.alternatives`, `lightcal.core.misfit_causes`).

    Attributes:
        name: the cause (`misfit_causes.CAUSES`).
        k: its columns outside the model's span.
        delta_chi2: the cost decrease it brings (solver units).
        f_statistic, p_value: its F test.
        relative_effect: its fitted correction's RMS relative to the signal.
        bic_gain: > 0 when it is worth its parameters (Bayesian information criterion).
        shift_sigma: the pose shift it accounts for, in statistical sigmas (Mahalanobis
            over every light's pose parameters); NaN for `images` (its shift is the
            jackknife's).
        position_shift_m, axis_shift_deg: the largest light position and axis shift it
            accounts for.
    """

    name: str
    k: int
    delta_chi2: float
    f_statistic: float
    p_value: float
    relative_effect: float
    bic_gain: float
    shift_sigma: float
    position_shift_m: float
    axis_shift_deg: float

    @property
    def significant(self) -> bool:
        """Its F test rejects "no effect" at the false-alarm rate `P_ALARM`."""
        return self.k > 0 and self.p_value < P_ALARM

    @property
    def material(self) -> bool:
        """Significant, above `RELATIVE_FLOOR` and moving the pose by `SHIFT_FLOOR_SIGMA`
        or more (for `images`: judged with the jackknife by `diagnose`)."""
        large = not (self.shift_sigma < SHIFT_FLOOR_SIGMA)  # NaN: decided elsewhere
        return self.significant and self.relative_effect >= RELATIVE_FLOOR and large

    def describe(self) -> str:
        """Its size in words: "a correction of 0.8 % of the signal that moves the light by
        12 mm and 0.4 deg (6.1 sigma)"."""
        text = f"a correction of {percent(self.relative_effect).lstrip('+')} of the signal"
        if math.isfinite(self.shift_sigma):
            text += (
                f" that moves the light by {significant_digits(1e3 * self.position_shift_m)} mm"
                f" and {significant_digits(self.axis_shift_deg)} deg "
                f"({significant_digits(self.shift_sigma)} sigma)"
            )
        return text

    def to_dict(self) -> dict:
        return {
            "cause": self.name,
            "columns": self.k,
            "delta_chi2": _finite_or_none(self.delta_chi2),
            "f_statistic": _finite_or_none(self.f_statistic),
            "p_value": _finite_or_none(self.p_value),
            "relative_effect": _finite_or_none(self.relative_effect),
            "bic_gain": _finite_or_none(self.bic_gain),
            "shift_sigma": _finite_or_none(self.shift_sigma),
            "position_shift_m": _finite_or_none(self.position_shift_m),
            "axis_shift_deg": _finite_or_none(self.axis_shift_deg),
            "significant": self.significant,
            "material": self.material,
        }


def is_material(c: CauseTest, jackknife_ratio: float) -> bool:
    """`CauseTest.material`, for `images` judged by the jackknife ratio (its shift)."""
    if c.name == "images":
        return (
            c.significant
            and c.relative_effect >= RELATIVE_FLOOR
            and jackknife_ratio >= JACKKNIFE_FLOOR
        )
    return c.material


def _size(c: CauseTest, jackknife_ratio: float) -> str:
    """A cause's size in words (`CauseTest.describe`; `images`: with the jackknife)."""
    if c.name == "images":
        return (
            f"{percent(c.relative_effect).lstrip('+')} of the signal; the jackknife over "
            f"the images gives {significant_digits(jackknife_ratio)}x the statistical sigma"
        )
    return c.describe()


def _shift(c: CauseTest, jackknife_ratio: float) -> str:
    """A cause's pose shift in a few words: "12 mm, 0.40 deg"."""
    if c.name == "images":
        return f"jackknife {significant_digits(jackknife_ratio)}x"
    return (
        f"{significant_digits(1e3 * c.position_shift_m)} mm, "
        f"{significant_digits(c.axis_shift_deg)} deg"
    )


def verdict(d: FitDiagnosis, wall_model: str) -> tuple[list[str], list[str]]:
    """(findings, notes): one sentence per cause that matters, most likely first, and
    what was seen but is too small to act on."""
    findings: list[str] = []
    notes: list[str] = []
    material = [c for c in d.causes if not d.explained and is_material(c, d.jackknife_ratio)]
    if material:
        c = material[0]
        cause = CAUSES[c.name]
        advice = cause.advice
        if c.name == "gloss" and wall_model != "lambertian":
            advice = "exclude pixels near the mirror direction (`selection.exclude_mirror_deg`)"
        elif c.name == "rough_matte" and wall_model != "lambertian":
            advice = "check the RID and the sensor fall-off model"
        findings.append(f"{cause.meaning} ({_size(c, d.jackknife_ratio)}); {advice}")
    if len(material) > 1:
        others = ", ".join(f"{c.name} ({_shift(c, d.jackknife_ratio)})" for c in material[1:])
        findings.append(f"less likely causes that would also move the pose: {others}")
    small = [
        c
        for c in d.causes
        if c.significant and c.relative_effect >= RELATIVE_FLOOR and c not in material
    ]
    why = (
        "within what the noise and the camera's declared errors explain"
        if d.explained
        else "too small to move the pose beyond its sigma"
    )
    for c in small:
        notes.append(f"{c.name}: {c.describe()}: {why}")
    if d.level_fails:
        source = "the sensor's noise model" if d.noise_source == "model" else "the images"
        poses = " and the camera poses' errors" if d.expected_chi2 > d.dof else ""
        level = (
            f"residuals are {significant_digits(math.sqrt(d.chi2_ratio), 3)}x what the noise "
            f"from {source}{poses} explains (chi2 {significant_digits(d.chi2, 4)}, expected "
            f"{significant_digits(d.expected_chi2, 4)} over {d.dof} degrees of freedom; "
            f"{percent(d.excess_relative).lstrip('+')} of the signal beyond the noise)"
        )
        unexplained = (
            not material
            and d.excess_relative >= RELATIVE_FLOOR
            and d.jackknife_ratio >= JACKKNIFE_FLOOR
        )
        if unexplained:
            findings.append(
                f"{level}: no single cause explains them and the images disagree beyond the "
                f"noise (jackknife {significant_digits(d.jackknife_ratio)}x the statistical "
                "sigma); check the camera poses, masks (markers, stray light), the RID and "
                "the sensor model"
            )
        else:
            notes.append(f"{level}; the sigma includes the misfit")
    return findings, notes
