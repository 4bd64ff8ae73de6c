"""The fit test's candidate causes as a picture: how far each would move the pose.

One horizontal bar per cause of a result's ``fit.causes``
(`lightcal.core.misfit_verdict.CauseTest.to_dict`): its length is the pose shift the
cause accounts for, in statistical sigmas on a log scale (0.1 to the largest), with a
dashed line at the finding's floor (1 sigma); for `images` the jackknife's sigma over
the statistical one (its floor is 2). Red: a finding (significant, at least the
relative floor of the signal, at least 1 sigma); orange: significant but too small to
act on; grey: not significant. The label gives the cause and its correction in % of the
signal. Drawn like the other report figures (`lightcal.io.figures`).
"""

from __future__ import annotations

import math

import cv2
import numpy as np

from lightcal.io.figures import _LABEL_TEXT, _TICK_TEXT, _Pen

_FINDING = (178, 24, 43)
_SIGNIFICANT = (239, 138, 60)
_QUIET = (170, 170, 170)
_GRID = (225, 225, 225)
_INK = (20, 20, 20)


def _colour(cause: dict) -> tuple[int, int, int]:
    if cause.get("material"):
        return _FINDING
    if cause.get("significant"):
        return _SIGNIFICANT
    return _QUIET


def cause_figure(fit: dict, *, width: float = 720.0, scale: float = 2.0) -> np.ndarray | None:
    """RGB uint8 bar chart of the causes' pose shifts (module docstring); None when the
    result has no causes. `width` is in layout points."""
    causes = [c for c in fit.get("causes", []) if c.get("cause")]
    if not causes:
        return None
    pen = _Pen(scale)
    row = 22.0
    top, bottom = 40.0, 46.0
    w = pen.px(width)
    h = pen.px(top + row * len(causes) + bottom)
    fig = pen.canvas(h, w)
    left, right = pen.px(230), w - pen.px(20)
    shifts = [c.get("shift_sigma") for c in causes]
    known = [s for s in shifts if s is not None and math.isfinite(s) and s > 0]
    hi = max([10.0, *known])
    lo_log, hi_log = -1.0, math.ceil(math.log10(hi))

    def x_of(sigma: float) -> int:
        v = min(max(math.log10(max(sigma, 1e-12)), lo_log), hi_log)
        return round(left + (right - left) * (v - lo_log) / (hi_log - lo_log))

    y_top, y_bottom = pen.px(top), pen.px(top + row * len(causes))
    for k in range(int(lo_log), int(hi_log) + 1):
        x = x_of(10.0**k)
        cv2.line(fig, (x, y_top), (x, y_bottom), _GRID, pen.thickness())
        text = f"{10.0**k:g}"
        pen.text(fig, text, (x, y_bottom + pen.px(16)), _TICK_TEXT, "center")
    floor = x_of(fit.get("floors", {}).get("shift_sigma", 1.0))
    for y in range(y_top, y_bottom, pen.px(8)):
        cv2.line(fig, (floor, y), (floor, min(y + pen.px(4), y_bottom)), _INK, pen.thickness())
    pen.text(
        fig,
        "pose shift each cause accounts for (statistical sigmas)",
        ((left + right) // 2, y_bottom + pen.px(36)),
        _LABEL_TEXT,
        "center",
    )
    pen.text(
        fig,
        "red: a finding; orange: seen, too small; grey: not significant",
        (pen.px(8), pen.px(22)),
        _LABEL_TEXT,
    )
    for k, c in enumerate(causes):
        y0 = pen.px(top + row * k + 4)
        y1 = pen.px(top + row * (k + 1) - 4)
        s = c.get("shift_sigma")
        relative = c.get("relative_effect") or 0.0
        if c["cause"] != "images":
            label = f"{c['cause']} ({100.0 * relative:.2g} %)"
            pen.text(fig, label, (left - pen.px(8), y1 - pen.px(3)), _TICK_TEXT, "right")
        if c["cause"] == "images":
            # Its shift is the jackknife's: how many statistical sigmas its spread is.
            s = fit.get("jackknife_ratio")
            label = f"images, jackknife ({100.0 * relative:.2g} %)"
            pen.text(fig, label, (left - pen.px(8), y1 - pen.px(3)), _TICK_TEXT, "right")
        if s is None or not math.isfinite(s):
            pen.text(fig, "-", (left + pen.px(6), y1 - pen.px(3)), _TICK_TEXT)
            continue
        cv2.rectangle(fig, (left, y0), (max(x_of(s), left + 1), y1), _colour(c), -1)
    cv2.rectangle(fig, (left, y_top), (right, y_bottom), _INK, pen.thickness())
    return fig
