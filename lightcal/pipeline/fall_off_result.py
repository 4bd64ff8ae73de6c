"""The estimated sensor terms of a calibration in the result: the fall-off
(`sensor.estimate_fall_off`), its coefficients with their 1-sigma, the fall-off at the
sensor's corners, whether the data determine it, and the lines of text of it and of the
room light (`sensor.estimate_ambient`) for `lightcal calibrate` and the report.

A fall-off the data do not determine (one that leaves the range of a lens's, or that
ends on its search box) makes the result not converged, with its reason in
`undetermined`: the light's pose found with it is not to be trusted. One the data only
loosely determine (its 1-sigma at the corners above `LOOSE_CORNER_SIGMA`) is a warning
that says what would determine it.
"""

from __future__ import annotations

import math

import numpy as np

from lightcal.core.fall_off import FALL_OFF_MAX_ORDER, FallOffUnknown
from lightcal.core.solver import CalibrationModel

LOOSE_CORNER_SIGMA = 0.02
"""A 1-sigma of V at the sensor's corners above this (2 % of the signal) is a warning:
measured 0.003-0.005 with 12 views at 0.8-2.5 m or 1.2-1.8 m, tilted 0-35 or 0-15 deg,
and 0.04-0.05 with 12 views all at 1.5 m, facing the wall."""


def fall_off_summary(model: CalibrationModel, x: np.ndarray, cov: np.ndarray) -> dict | None:
    """The estimated fall-off at x with the 1-sigma of the covariance `cov` (n, n) (NaN
    where undetermined), JSON-ready; None when the project does not estimate it.

    Keys: model ("radial"), order, coefficients and sigma (c_1..c_K, of r^2..r^(2K)),
    center_px and norm_radius_px (full-resolution pixels: r = |(u, v) - center| / R),
    corner_value and corner_sigma (V at r = 1 and its 1-sigma), formula.
    """
    lay = model.layout
    f = lay.fall_off_unknown
    if f is None:
        return None
    c = x[lay.fall_off]
    C = cov[lay.fall_off, lay.fall_off]
    ones = np.ones(f.order)  # d V(r = 1) / d c
    corner_variance = float(ones @ C @ ones)
    return {
        "model": "radial",
        "order": f.order,
        "coefficients": c.tolist(),
        "sigma": [math.sqrt(v) if v >= 0.0 else math.nan for v in np.diag(C)],
        "center_px": [0.5 * (f.width - 1), 0.5 * (f.height - 1)],
        "norm_radius_px": f.norm_radius_px,
        "corner_value": float(1.0 + c.sum()),
        "corner_sigma": math.sqrt(corner_variance) if corner_variance >= 0.0 else math.nan,
        "formula": "V = 1 + sum_k c_k r^(2k), r = |(u, v) - center_px| / norm_radius_px",
    }


def fall_off_problems(model: CalibrationModel, x: np.ndarray, summary: dict | None) -> list[str]:
    """Why the estimated fall-off is not determined (empty: it is), in words."""
    f = model.layout.fall_off_unknown
    if f is None or summary is None:
        return []
    why = f.implausible(x[model.layout.fall_off])
    if why is None and math.isfinite(summary["corner_sigma"]):
        return []
    why = why or "its sigma is undetermined"
    return [
        f"the data do not determine the camera's fall-off ({why}), so neither the light's "
        "pose found with it: add views at other distances and tilts, or give the fall-off "
        "(sensor.model: map with a flat field) instead of sensor.estimate_fall_off"
    ]


def fall_off_warnings(summary: dict | None) -> list[str]:
    """A warning when the data only loosely determine the fall-off."""
    if summary is None or not summary["corner_sigma"] > LOOSE_CORNER_SIGMA:
        return []
    return [
        f"the camera's fall-off is loosely determined (V at the corners "
        f"{summary['corner_value']:.3f} ± {summary['corner_sigma']:.2g}): the light's sigmas "
        "include it; views at more distances and tilts would narrow both"
    ]


def fall_off_text(summary: dict) -> str:
    """ "fall-off: radial, V = 1 - 0.2497 ± 0.0051 r^2 + ... (0.800 ± 0.002 at the
    corners)"."""
    terms = []
    for k, (c, s) in enumerate(zip(summary["coefficients"], summary["sigma"], strict=True)):
        sigma = f"{s:.2g}" if math.isfinite(s) else "undetermined"
        terms.append(f"{'-' if c < 0 else '+'} {abs(c):.4f} ± {sigma} r^{2 * (k + 1)}")
    corner = summary["corner_sigma"]
    corner_sigma = f"{corner:.2g}" if math.isfinite(corner) else "undetermined"
    return (
        f"fall-off: radial, V = 1 {' '.join(terms)} ({summary['corner_value']:.3f} ± "
        f"{corner_sigma} at the corners)"
    )


def ambient_text(ambient: float, sigma: float | None) -> str:
    """ "room light: 12.3 ± 0.41 (pixel units at exposure and gain 1)"."""
    s = f"{sigma:.2g}" if sigma is not None and math.isfinite(sigma) else "undetermined"
    return f"room light: {ambient:.4g} ± {s} (pixel units at exposure and gain 1)"


def fall_off_map(fall_off: dict | None, width: int, height: int) -> np.ndarray | None:
    """(H, W) V of a result's `fall_off` on a camera of `width` x `height` pixels, for
    rendering the result (`lightcal render`); None when the result has none.

    Raises:
        ValueError: `fall_off` has no finite "coefficients" list (what is wrong, to be
            reported with the result file's name).
    """
    if fall_off is None:
        return None
    coeffs = fall_off.get("coefficients")
    if not (
        isinstance(coeffs, list)
        and 0 < len(coeffs) <= FALL_OFF_MAX_ORDER
        and all(isinstance(c, int | float) and math.isfinite(c) for c in coeffs)
    ):
        raise ValueError(
            f"fall_off.coefficients: expected a list of 1 to {FALL_OFF_MAX_ORDER} numbers, "
            f"got {coeffs!r}"
        )
    return FallOffUnknown(len(coeffs), width, height).image(np.array(coeffs, dtype=np.float64))
