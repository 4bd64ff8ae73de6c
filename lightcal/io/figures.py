"""Figures for reports: residual maps with a colour bar, convergence plots, side by side.

Drawn with OpenCV (no plotting library); every function returns an RGB uint8 image,
`write_png` stores one atomically.

Figures are laid out in points and drawn at `scale` pixels per point (default 2): a
report figure is 1,300-1,800 pixels wide, so that printed across a page (about 17 cm)
its smallest text is about 2 mm tall (9 points at 2 pixels per point and 150-200 dpi).
The app passes `scale=1` for its smaller panels.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np
from numpy.typing import ArrayLike

from lightcal.colormap import diverging_rgb, grey_rgb, means_to_width, robust_vmax, stepped
from lightcal.core.quantiles import percentile
from lightcal.io.atomic import atomic_write_bytes

_FONT = cv2.FONT_HERSHEY_SIMPLEX
_INK = (20, 20, 20)
_GRID = (225, 225, 225)
_LINE = (33, 102, 172)
_DOT = (178, 24, 43)
PRINT_SCALE = 2
"""Pixels per layout point of the report's figures."""
_TICK_TEXT = 0.45
"""Text size of tick labels (OpenCV font scale at one pixel per point; 9-10 points)."""
_LABEL_TEXT = 0.5
"""Text size of titles and axis labels."""


def write_png(path: str | Path, rgb: np.ndarray) -> None:
    """Write an RGB uint8 image as PNG, atomically."""
    ok, buf = cv2.imencode(".png", cv2.cvtColor(rgb, cv2.COLOR_RGB2BGR))
    if not ok:
        raise OSError(f"{path}: PNG encoding failed")
    atomic_write_bytes(Path(path), buf.tobytes())


def nice_ticks(lo: float, hi: float, count: int = 5) -> list[float]:
    """About `count` round values (1, 2 or 5 x 10^k apart) covering [lo, hi], ends included.

    >>> nice_ticks(1.0, 66.0)
    [0.0, 20.0, 40.0, 60.0, 80.0]
    """
    if not (math.isfinite(lo) and math.isfinite(hi)) or hi <= lo:
        return [lo]
    step = _nice_ceiling((hi - lo) / max(count - 1, 1))
    first = math.floor(lo / step + 1e-9) * step
    last = math.ceil(hi / step - 1e-9) * step
    n = round((last - first) / step)
    return [round(first + k * step, 12) for k in range(n + 1)]


def _nice_ceiling(v: float) -> float:
    """The smallest of 1, 2, 5 x 10^k that is >= v > 0."""
    e = math.floor(math.log10(v))
    for m in (1.0, 2.0, 5.0, 10.0):
        if m * 10.0**e >= v:
            return m * 10.0**e
    return 10.0 ** (e + 1)


@dataclass(frozen=True)
class _Pen:
    """Drawing at `scale` pixels per layout point."""

    scale: float

    def px(self, points: float) -> int:
        return round(points * self.scale)

    def thickness(self, points: float = 1.0) -> int:
        return max(1, round(points * self.scale))

    def text_size(self, text: str, size: float) -> tuple[int, int]:
        (w, h), _ = cv2.getTextSize(text, _FONT, size * self.scale, self.thickness())
        return w, h

    def text(
        self, img: np.ndarray, text: str, org: tuple[int, int], size: float, align: str = "left"
    ) -> None:
        """Text with its baseline at org[1]; `align` left, center or right of org[0]."""
        w, _ = self.text_size(text, size)
        x = org[0] - {"left": 0, "center": w // 2, "right": w}[align]
        cv2.putText(
            img, text, (x, org[1]), _FONT, size * self.scale, _INK, self.thickness(), cv2.LINE_AA
        )

    def canvas(self, h: int, w: int) -> np.ndarray:
        return np.full((h, w, 3), 255, dtype=np.uint8)


def _fit_width(rgb: np.ndarray, max_width: int) -> np.ndarray:
    h, w = rgb.shape[:2]
    if w <= max_width:
        return rgb
    s = max_width / w
    return cv2.resize(rgb, (max_width, max(1, round(h * s))), interpolation=cv2.INTER_AREA)


def _fit_to(rgb: np.ndarray, width: int) -> np.ndarray:
    """`rgb` scaled to `width` pixels (down by area, up by nearest: pixels stay pixels)."""
    h, w = rgb.shape[:2]
    if w == width:
        return rgb
    interp = cv2.INTER_AREA if w > width else cv2.INTER_NEAREST
    return cv2.resize(rgb, (width, max(1, round(h * width / w))), interpolation=interp)


def residual_figure(
    residual: np.ndarray,
    *,
    title: str,
    vmax: float | None = None,
    unit: str = "DN",
    width_pt: int = 700,
    scale: float = PRINT_SCALE,
) -> np.ndarray:
    """A residual map (real minus rendered) with a diverging colour bar and its scale,
    each pixel a block mean in one of 2 RESIDUAL_STEPS + 1 bands (`lightcal.colormap`).

    Args:
        residual: (H, W) residuals (masked/NaN where invalid; masked pixels are grey).
        title: printed above the map.
        vmax: colour scale magnitude; default the 99th percentile of |residual|.
        unit: unit of the residuals, written on the colour bar.
        width_pt: width of the map in layout points.
    """
    pen = _Pen(scale)
    values = means_to_width(residual, pen.px(width_pt))
    vmax = robust_vmax(values) if vmax is None else vmax
    body = _fit_to(diverging_rgb(stepped(values, vmax), vmax), pen.px(width_pt))
    h, w = body.shape[:2]
    bar_w, pad, top = pen.px(16), pen.px(10), pen.px(30)
    labels = [f"{vmax * (1 - 2 * f):+.3g}" for f in (0.0, 0.25, 0.5, 0.75, 1.0)]
    label_w = max(pen.text_size(t, _TICK_TEXT)[0] for t in [*labels, unit])
    fig = pen.canvas(h + top + pad, w + bar_w + label_w + pen.px(8) + 3 * pad)
    fig[top : top + h, pad : pad + w] = body
    pen.text(fig, title, (pad, pen.px(20)), _LABEL_TEXT)
    ramp = np.linspace(vmax, -vmax, h)[:, None].repeat(bar_w, axis=1)
    x0 = pad * 2 + w
    fig[top : top + h, x0 : x0 + bar_w] = diverging_rgb(stepped(ramp, vmax), vmax)
    pen.text(fig, unit, (x0, top - pen.px(6)), _TICK_TEXT)
    for frac, label in zip((0.0, 0.25, 0.5, 0.75, 1.0), labels, strict=True):
        y = top + round(frac * (h - 1))
        cv2.line(fig, (x0 + bar_w, y), (x0 + bar_w + pen.px(4), y), _INK, pen.thickness())
        _, th = pen.text_size(label, _TICK_TEXT)
        y_text = min(max(y + th // 2, top + th), top + h)
        pen.text(fig, label, (x0 + bar_w + pen.px(7), y_text), _TICK_TEXT)
    return fig


def image_pair_figure(
    real: np.ndarray,
    rendered: np.ndarray,
    *,
    title: str,
    width_pt: int = 900,
    scale: float = PRINT_SCALE,
) -> np.ndarray:
    """Real and rendered images side by side on one grey scale (masked pixels dark)."""
    pen = _Pen(scale)
    filled = np.ma.filled(np.ma.asarray(real, dtype=np.float64), np.nan)
    shown = filled[~np.isnan(filled)]  # what np.nanpercentile reads
    vmax = percentile(shown, 99.5) if np.isfinite(filled).any() else 1.0
    gap = np.full((real.shape[0], max(8, real.shape[1] // 100), 3), 255, np.uint8)
    pair = np.concatenate([grey_rgb(real, vmax), gap, grey_rgb(rendered, vmax)], axis=1)
    body = _fit_width(pair, pen.px(width_pt))
    top = pen.px(30)
    fig = pen.canvas(body.shape[0] + top, body.shape[1])
    fig[top:] = body
    pen.text(fig, f"{title}   (left: real, right: rendered)", (pen.px(6), pen.px(20)), _LABEL_TEXT)
    return fig


@dataclass(frozen=True)
class _Axes:
    """A plot box in pixels and the data ranges it shows (y may be log10)."""

    left: int
    top: int
    right: int
    bottom: int
    x_range: tuple[float, float]
    y_range: tuple[float, float]

    def xy(self, x: float, y: float) -> tuple[int, int]:
        (x0, x1), (y0, y1) = self.x_range, self.y_range
        px = self.left + (self.right - self.left) * (x - x0) / (x1 - x0)
        py = self.bottom - (self.bottom - self.top) * (y - y0) / (y1 - y0)
        return round(px), round(py)


def _draw_axes(
    fig: np.ndarray,
    pen: _Pen,
    ax: _Axes,
    *,
    x_ticks: Sequence[float],
    x_format: str,
    y_ticks: Sequence[tuple[float, str]],
    x_label: str,
    y_label: str,
) -> None:
    """Grid lines, the frame, tick labels and axis titles of one plot."""
    for y, _ in y_ticks:
        _, py = ax.xy(ax.x_range[0], y)
        cv2.line(fig, (ax.left, py), (ax.right, py), _GRID, pen.thickness())
    cv2.rectangle(fig, (ax.left, ax.top), (ax.right, ax.bottom), _INK, pen.thickness())
    for y, text in y_ticks:
        _, py = ax.xy(ax.x_range[0], y)
        _, th = pen.text_size(text, _TICK_TEXT)
        pen.text(fig, text, (ax.left - pen.px(6), py + th // 2), _TICK_TEXT, "right")
    for x in x_ticks:
        px, _ = ax.xy(x, ax.y_range[0])
        cv2.line(fig, (px, ax.bottom), (px, ax.bottom + pen.px(4)), _INK, pen.thickness())
        pen.text(fig, format(x, x_format), (px, ax.bottom + pen.px(18)), _TICK_TEXT, "center")
    pen.text(
        fig, x_label, ((ax.left + ax.right) // 2, ax.bottom + pen.px(38)), _LABEL_TEXT, "center"
    )
    # The y title, written sideways beside the tick labels.
    tw, th = pen.text_size(y_label, _LABEL_TEXT)
    strip = pen.canvas(th + pen.px(8), tw + pen.px(4))
    pen.text(strip, y_label, (pen.px(2), th + pen.px(2)), _LABEL_TEXT)
    strip = np.ascontiguousarray(np.rot90(strip))
    sh, sw = strip.shape[:2]
    y0 = max(0, (ax.top + ax.bottom) // 2 - sh // 2)
    x0 = pen.px(4)
    region = fig[y0 : y0 + sh, x0 : x0 + sw]
    np.minimum(region, strip[: region.shape[0], : region.shape[1]], out=region)


def _draw_series(
    fig: np.ndarray,
    pen: _Pen,
    ax: _Axes,
    xs: ArrayLike,
    ys: ArrayLike,
    colours: tuple[tuple[int, int, int], tuple[int, int, int]] = (_LINE, _DOT),
) -> None:
    """A line with dots through (xs[i], ys[i]), both (N,); colours: (line, dots)."""
    x_values = np.asarray(xs, dtype=np.float64)
    y_values = np.asarray(ys, dtype=np.float64)
    pairs = zip(x_values.tolist(), y_values.tolist(), strict=True)
    pts = np.array([ax.xy(x, y) for x, y in pairs], dtype=np.int32)
    cv2.polylines(fig, [pts], False, colours[0], pen.thickness(2), cv2.LINE_AA)
    for p in pts:
        cv2.circle(fig, (int(p[0]), int(p[1])), pen.px(3.5), colours[1], -1, cv2.LINE_AA)


_EARLIER = ((160, 160, 175), (115, 115, 130))
"""Line and dot colours of `convergence_figure`'s earlier stage (a grey with a tint: not
the grey of anti-aliased text)."""


def convergence_figure(
    costs: Sequence[float],
    *,
    earlier: Sequence[float] = (),
    earlier_label: str = "",
    title: str = "cost per iteration",
    size: tuple[int, int] = (640, 360),
    scale: float = PRINT_SCALE,
) -> np.ndarray:
    """A log-scale plot of the cost per iteration (`size` in layout points).

    `earlier`: the costs of a stage that found the start (e.g. a solve on a subsample,
    scaled to the same pixels), drawn first in grey and named by `earlier_label`; its
    last iterate is the first of `costs`, which follow it on the iteration axis.
    """
    pen = _Pen(scale)
    w, h = pen.px(size[0]), pen.px(size[1])
    fig = pen.canvas(h, w)
    pen.text(fig, title, (pen.px(80), pen.px(20)), _LABEL_TEXT)
    c = np.asarray([v for v in costs if v > 0 and math.isfinite(v)], dtype=np.float64)
    early = np.asarray([v for v in earlier if v > 0 and math.isfinite(v)], dtype=np.float64)
    if c.size == 0:
        pen.text(fig, "no iterations", (w // 2, h // 2), _LABEL_TEXT, "center")
        return fig
    both = np.concatenate([early, c])
    lo = math.floor(math.log10(both.min()))
    hi = math.ceil(math.log10(both.max()))
    hi = hi if hi > lo else lo + 1
    n = max(both.size - 1, 1)
    ax = _Axes(pen.px(80), pen.px(32), w - pen.px(20), h - pen.px(50), (0.0, n), (lo, hi))
    step = max(1, math.ceil((hi - lo) / 8))
    _draw_axes(
        fig,
        pen,
        ax,
        x_ticks=[t for t in nice_ticks(0, n, min(n + 1, 6)) if float(t).is_integer() and t <= n],
        x_format=".0f",
        y_ticks=[(e, f"1e{e}") for e in range(lo, hi + 1, step)],
        x_label="iteration",
        y_label="cost (log)",
    )
    if early.size:
        _draw_series(fig, pen, ax, range(early.size), np.log10(early), _EARLIER)
        x_legend = ax.right - pen.px(4)
        for k, text in enumerate((f"grey: {earlier_label}", "colour: the full solve")):
            pen.text(fig, text, (x_legend, ax.top + pen.px(14 + 14 * k)), _TICK_TEXT, "right")
    _draw_series(fig, pen, ax, range(early.size, early.size + c.size), np.log10(c))
    return fig


def angle_residual_figure(
    fit: dict, *, size: tuple[int, int] = (900, 340), scale: float = PRINT_SCALE
) -> np.ndarray:
    """Mean relative residual (%) against the mirror and the incidence angle.

    Two panels from a result's ``fit`` (`lightcal.core.misfit.FitDiagnosis.to_dict`): each
    bin's sum (m_obs - m_render) / sum (m_render - offset), with the F-test's verdict in
    each title ("structure" only when it is also at least 0.3 % of the signal). A
    glossy wall shows a peak at small mirror angles; a wall fitted with the right model
    stays flat at 0. `size` is in layout points.
    """
    pen = _Pen(scale)
    w, h = pen.px(size[0]), pen.px(size[1])
    fig = pen.canvas(h, w)
    panels = [fit.get("mirror"), fit.get("incidence")]
    labels = ["angle to the mirror direction (deg)", "angle of incidence (deg)"]
    values = [
        100.0 * np.asarray(p["mean_relative_residual"], dtype=np.float64)
        for p in panels
        if p is not None
    ]
    vmax = _nice_ceiling(max([float(np.max(np.abs(v))) for v in values if v.size] + [0.1]))
    y_ticks = [(v, f"{v:+.2g}%" if v else "0") for v in (-vmax, -vmax / 2, 0.0, vmax / 2, vmax)]
    pw = w // 2
    for k, (panel, label) in enumerate(zip(panels, labels, strict=True)):
        x0 = k * pw
        left, right = x0 + pen.px(80), x0 + pw - pen.px(16)
        top, bottom = pen.px(34), h - pen.px(52)
        if panel is None:
            cv2.rectangle(fig, (left, top), (right, bottom), _INK, pen.thickness())
            pen.text(fig, "too few pixels to test", (left + pen.px(10), h // 2), _LABEL_TEXT)
            continue
        verdict = "structure" if panel["significant"] else "no structure"
        p_value = panel["p_value"]
        p_text = "p < 1e-300" if p_value is None or p_value == 0 else f"p = {p_value:.2g}"
        title = f"{verdict} ({p_text})"
        edges = np.asarray(panel["bin_edges_deg"], dtype=np.float64)
        centers = 0.5 * (edges[:-1] + edges[1:])
        rel = 100.0 * np.asarray(panel["mean_relative_residual"], dtype=np.float64)
        ticks = nice_ticks(float(edges[0]), float(edges[-1]), 5)
        x_range = (ticks[0], max(ticks[-1], ticks[0] + 1e-9))
        panel_fig = pen.canvas(h, pw)  # drawn apart: OpenCV draws on contiguous arrays
        ax = _Axes(left - x0, top, right - x0, bottom, x_range, (-vmax, vmax))
        _draw_axes(
            panel_fig,
            pen,
            ax,
            x_ticks=ticks,
            x_format="g",
            y_ticks=y_ticks,
            x_label=label,
            y_label="mean residual",
        )
        _draw_series(panel_fig, pen, ax, centers, rel)
        pen.text(panel_fig, title, (left - x0, pen.px(22)), _LABEL_TEXT)
        fig[:, x0 : x0 + pw] = panel_fig
    return fig


_CURVE_COLOURS = ((33, 102, 172), (230, 120, 0), (47, 158, 68), (174, 62, 201), (12, 133, 153))


def profile_figure(
    curves: Sequence[tuple[str, ArrayLike, ArrayLike]],
    *,
    title: str = "the light's relative intensity",
    size: tuple[int, int] = (480, 300),
    scale: float = PRINT_SCALE,
) -> np.ndarray:
    """Relative intensity against the angle from the light's axis, one line per curve.

    Args:
        curves: (label, angles (N,) in degrees, values (N,) relative to the axis).
        size: layout points; text stays 9-10 points whatever the size.
    """
    pen = _Pen(scale)
    w, h = pen.px(size[0]), pen.px(size[1])
    fig = pen.canvas(h, w)
    pen.text(fig, title, (pen.px(70), pen.px(20)), _LABEL_TEXT)
    angles = [np.asarray(a, dtype=np.float64) for _, a, _ in curves]
    top = max([float(a.max()) for a in angles if a.size] + [1.0])
    ticks = nice_ticks(0.0, top, 5)
    ax = _Axes(pen.px(70), pen.px(32), w - pen.px(16), h - pen.px(50), (0.0, ticks[-1]), (0.0, 1.0))
    y_ticks = [(v, f"{v:g}") for v in (0.0, 0.25, 0.5, 0.75, 1.0)]
    _draw_axes(
        fig,
        pen,
        ax,
        x_ticks=ticks,
        x_format="g",
        y_ticks=y_ticks,
        x_label="angle from the light's axis (deg)",
        y_label="relative intensity",
    )
    for k, (label, _, v) in enumerate(curves):
        colour = _CURVE_COLOURS[k % len(_CURVE_COLOURS)]
        values = np.clip(np.asarray(v, dtype=np.float64), 0.0, 1.0)
        pts = np.array(
            [ax.xy(x, y) for x, y in zip(angles[k].tolist(), values.tolist(), strict=True)],
            dtype=np.int32,
        )
        cv2.polylines(fig, [pts], False, colour, pen.thickness(2), cv2.LINE_AA)
        y = pen.px(50 + 16 * k)
        x = w - pen.px(20)
        tw, th = pen.text_size(label, _TICK_TEXT)
        cv2.line(
            fig,
            (x - tw - pen.px(26), y - th // 2),
            (x - tw - pen.px(6), y - th // 2),
            colour,
            pen.thickness(2),
        )
        pen.text(fig, label, (x, y), _TICK_TEXT, "right")
    return fig


def views_figure(
    distances_m: ArrayLike,
    tilts_deg: ArrayLike,
    names: Sequence[str],
    *,
    title: str = "the views: distance and tilt",
    size: tuple[int, int] = (300, 210),
    scale: float = PRINT_SCALE,
) -> np.ndarray:
    """One dot per image: its distance from the wall (m) against the tilt of its optical
    axis from the wall's normal (deg), named when there are at most 12.

    Args:
        distances_m, tilts_deg: (N,) per image.
        names: N image names.
        size: layout points (text 9-10 points whatever the size).
    """
    d = np.asarray(distances_m, dtype=np.float64)
    t = np.asarray(tilts_deg, dtype=np.float64)
    pen = _Pen(scale)
    w, h = pen.px(size[0]), pen.px(size[1])
    fig = pen.canvas(h, w)
    pen.text(fig, title, (pen.px(56), pen.px(16)), _LABEL_TEXT)
    x_ticks = nice_ticks(0.0, max(float(d.max(initial=0.0)) * 1.1, 0.5), 4)
    y_ticks = nice_ticks(0.0, max(float(t.max(initial=0.0)) * 1.15, 10.0), 4)
    ax = _Axes(
        pen.px(56),
        pen.px(26),
        w - pen.px(12),
        h - pen.px(48),
        (0.0, x_ticks[-1]),
        (0.0, y_ticks[-1]),
    )
    _draw_axes(
        fig,
        pen,
        ax,
        x_ticks=x_ticks,
        x_format="g",
        y_ticks=[(v, f"{v:g}") for v in y_ticks],
        x_label="distance from the wall (m)",
        y_label="tilt (deg)",
    )
    dots = [ax.xy(x, y) for x, y in zip(d.tolist(), t.tolist(), strict=True)]
    r = pen.px(3.5)
    taken = [(p[0] - r, p[1] - r, p[0] + r, p[1] + r) for p in dots]
    for p in dots:
        cv2.circle(fig, p, r, _DOT, -1, cv2.LINE_AA)
    if len(names) <= 12:
        # Each name where it overlaps no dot and no name placed before (else none).
        for p, name in zip(dots, names, strict=True):
            text = str(name)[:10]
            tw, th = pen.text_size(text, _NAME_TEXT)
            for dx, dy in ((1, -1), (1, 1), (-1, -1), (-1, 1)):
                x0 = p[0] + pen.px(5) if dx > 0 else p[0] - pen.px(5) - tw
                y1 = p[1] - pen.px(4) if dy < 0 else p[1] + pen.px(4) + th
                box = (x0, y1 - th, x0 + tw, y1)
                inside = box[0] >= ax.left and box[2] <= w and box[1] >= ax.top
                if inside and not any(_overlap(box, o) for o in taken):
                    pen.text(fig, text, (x0, y1), _NAME_TEXT)
                    taken.append(box)
                    break
    return fig


_NAME_TEXT = 0.38


def _overlap(a: tuple[int, int, int, int], b: tuple[int, int, int, int]) -> bool:
    return a[0] < b[2] and b[0] < a[2] and a[1] < b[3] and b[1] < a[3]
