"""Figures for reports: residual maps with a colour bar, convergence plots, side by side.

Drawn with OpenCV (no plotting library); every function returns an RGB uint8 image,
`write_png` stores one atomically.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path

import cv2
import numpy as np

from lightcal.colormap import diverging_rgb, grey_rgb, robust_vmax
from lightcal.io.atomic import atomic_write_bytes

_FONT = cv2.FONT_HERSHEY_SIMPLEX
_INK = (20, 20, 20)


def write_png(path: str | Path, rgb: np.ndarray) -> None:
    """Write an RGB uint8 image as PNG, atomically."""
    ok, buf = cv2.imencode(".png", cv2.cvtColor(rgb, cv2.COLOR_RGB2BGR))
    if not ok:
        raise OSError(f"{path}: PNG encoding failed")
    atomic_write_bytes(Path(path), buf.tobytes())


def _fit_width(rgb: np.ndarray, max_width: int) -> np.ndarray:
    h, w = rgb.shape[:2]
    if w <= max_width:
        return rgb
    s = max_width / w
    return cv2.resize(rgb, (max_width, max(1, round(h * s))), interpolation=cv2.INTER_AREA)


def _text(img: np.ndarray, text: str, org: tuple[int, int], scale: float = 0.5) -> None:
    cv2.putText(img, text, org, _FONT, scale, _INK, 1, cv2.LINE_AA)


def _canvas(h: int, w: int) -> np.ndarray:
    return np.full((h, w, 3), 255, dtype=np.uint8)


def residual_figure(
    residual: np.ndarray, *, title: str, vmax: float | None = None, max_width: int = 900
) -> np.ndarray:
    """A residual map (real minus rendered) with a diverging colour bar and its scale.

    Args:
        residual: (H, W) residuals (masked/NaN where invalid).
        title: printed above the map.
        vmax: colour scale magnitude; default the 99th percentile of |residual|.
    """
    vmax = robust_vmax(residual) if vmax is None else vmax
    body = _fit_width(diverging_rgb(residual, vmax), max_width)
    h, w = body.shape[:2]
    bar_w, pad, top = 22, 12, 34
    fig = _canvas(h + top + pad, w + bar_w + 90 + 2 * pad)
    fig[top : top + h, pad : pad + w] = body
    _text(fig, title, (pad, 22))
    ramp = np.linspace(vmax, -vmax, h)[:, None].repeat(bar_w, axis=1)
    x0 = pad * 2 + w
    fig[top : top + h, x0 : x0 + bar_w] = diverging_rgb(ramp, vmax)
    for frac in (0.0, 0.25, 0.5, 0.75, 1.0):
        y = top + round(frac * (h - 1))
        value = vmax * (1 - 2 * frac)
        cv2.line(fig, (x0 + bar_w, y), (x0 + bar_w + 4, y), _INK, 1)
        _text(fig, f"{value:+.3g}", (x0 + bar_w + 7, y + 4), 0.4)
    return fig


def image_pair_figure(
    real: np.ndarray, rendered: np.ndarray, *, title: str, max_width: int = 1200
) -> np.ndarray:
    """Real and rendered images side by side on one grey scale."""
    finite = np.ma.filled(np.ma.asarray(real, dtype=np.float64), np.nan)
    vmax = float(np.nanpercentile(finite, 99.5)) if np.isfinite(finite).any() else 1.0
    pair = np.concatenate(
        [
            grey_rgb(real, vmax),
            np.full((real.shape[0], 8, 3), 255, np.uint8),
            grey_rgb(rendered, vmax),
        ],
        axis=1,
    )
    body = _fit_width(pair, max_width)
    fig = _canvas(body.shape[0] + 34, body.shape[1])
    fig[34:] = body
    _text(fig, f"{title}   (left: real, right: rendered)", (6, 22))
    return fig


def convergence_figure(
    costs: Sequence[float], *, title: str = "cost per iteration (log scale)", size=(640, 360)
) -> np.ndarray:
    """A log-scale plot of the cost per iteration."""
    w, h = size
    fig = _canvas(h, w)
    left, right, top, bottom = 70, 20, 34, 40
    _text(fig, title, (left, 22))
    c = np.asarray([v for v in costs if v > 0 and math.isfinite(v)], dtype=np.float64)
    cv2.rectangle(fig, (left, top), (w - right, h - bottom), _INK, 1)
    if c.size == 0:
        return fig
    lo = math.floor(math.log10(c.min()))
    hi = math.ceil(math.log10(c.max()))
    hi = hi if hi > lo else lo + 1
    n = max(len(c) - 1, 1)

    def xy(i: int, v: float) -> tuple[int, int]:
        x = left + (w - left - right) * i / n
        y = h - bottom - (h - top - bottom) * (math.log10(v) - lo) / (hi - lo)
        return round(x), round(y)

    step = max(1, (hi - lo) // 8)
    for e in range(lo, hi + 1, step):
        _, y = xy(0, 10.0**e)
        cv2.line(fig, (left - 4, y), (w - right, y), (225, 225, 225), 1)
        _text(fig, f"1e{e}", (8, y + 4), 0.4)
    pts = np.array([xy(i, v) for i, v in enumerate(c)], dtype=np.int32)
    cv2.polylines(fig, [pts], False, (33, 102, 172), 2, cv2.LINE_AA)
    for p in pts:
        cv2.circle(fig, tuple(int(t) for t in p), 3, (178, 24, 43), -1, cv2.LINE_AA)
    _text(fig, "iteration", (w // 2 - 30, h - 12), 0.45)
    for i in sorted({0, n // 2, n}):
        x, _ = xy(i, c[0])
        _text(fig, str(i), (x - 4, h - bottom + 16), 0.4)
    return fig


def angle_residual_figure(fit: dict, *, size: tuple[int, int] = (900, 340)) -> np.ndarray:
    """Mean relative residual (%) against the mirror and the incidence angle.

    Two panels from a result's ``fit`` (`lightcal.core.misfit.FitDiagnosis.to_dict`): the
    bins' mean (m_obs - m_render) / m_render, with the F-test's verdict in each title. A
    glossy wall shows a peak at small mirror angles; a wall fitted with the right model
    stays flat at 0.
    """
    w, h = size
    fig = _canvas(h, w)
    panels = [fit.get("mirror"), fit.get("incidence")]
    labels = ["angle to the mirror direction (deg)", "angle of incidence (deg)"]
    values = [
        100.0 * np.asarray(p["mean_relative_residual"], dtype=np.float64)
        for p in panels
        if p is not None
    ]
    vmax = _nice_ceiling(max([float(np.max(np.abs(v))) for v in values if v.size] + [0.1]))
    pw = w // 2
    top, bottom = 40, 44
    for k, (panel, label) in enumerate(zip(panels, labels, strict=True)):
        x0 = k * pw
        left, right = x0 + 62, x0 + pw - 16
        cv2.rectangle(fig, (left, top), (right, h - bottom), _INK, 1)
        if panel is None:
            _text(fig, "too few pixels to test", (left + 10, h // 2), 0.45)
            continue
        verdict = "structure" if panel["significant"] else "no structure"
        p_value = panel["p_value"]
        p_text = "p < 1e-300" if p_value is None or p_value == 0 else f"p = {p_value:.2g}"
        _text(fig, f"{verdict} ({p_text})", (left, 24), 0.5)
        edges = np.asarray(panel["bin_edges_deg"], dtype=np.float64)
        centers = 0.5 * (edges[:-1] + edges[1:])
        rel = 100.0 * np.asarray(panel["mean_relative_residual"], dtype=np.float64)
        a_lo, a_hi = float(edges[0]), float(max(edges[-1], edges[0] + 1e-9))

        def xy(a: float, v: float, lo=a_lo, hi=a_hi, left=left, right=right) -> tuple[int, int]:
            x = left + (right - left) * (a - lo) / (hi - lo)
            y = top + (h - bottom - top) * (0.5 - 0.5 * v / vmax)
            return round(x), round(y)

        _, y0 = xy(a_lo, 0.0)
        cv2.line(fig, (left, y0), (right, y0), (200, 200, 200), 1)
        for v in (-vmax, vmax):
            _, y = xy(a_lo, v)
            _text(fig, f"{v:+.2g}%", (x0 + 6, y + 4), 0.4)
        pts = np.array([xy(a, v) for a, v in zip(centers, rel, strict=True)], dtype=np.int32)
        cv2.polylines(fig, [pts], False, (33, 102, 172), 2, cv2.LINE_AA)
        for p in pts:
            cv2.circle(fig, (int(p[0]), int(p[1])), 4, (178, 24, 43), -1, cv2.LINE_AA)
        for a in (a_lo, a_hi):
            x, _ = xy(a, 0.0)
            _text(fig, f"{a:.0f}", (x - 6, h - bottom + 16), 0.4)
        _text(fig, label, (left + 10, h - 10), 0.45)
    return fig


def _nice_ceiling(v: float) -> float:
    """The smallest of 1, 2, 5 x 10^k that is >= v > 0."""
    e = math.floor(math.log10(v))
    for m in (1.0, 2.0, 5.0, 10.0):
        if m * 10.0**e >= v:
            return m * 10.0**e
    return 10.0 ** (e + 1)
