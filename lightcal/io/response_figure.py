"""The fitted camera response as a picture: each channel's log exposure against the code.

One curve per channel of a `ResponseCurve` (B, G, R in OpenCV's order: drawn blue,
green and red), log10 of the linear value (the curve's arbitrary scale: 1 at code 128)
against the 8-bit code; a dashed grey line is the sRGB standard's for comparison. A
straight line would be a pure gamma; the ends bend where the camera's tone curve does.
Drawn like the other report figures (`lightcal.io.figures`).
"""

from __future__ import annotations

import math

import cv2
import numpy as np

from lightcal.io.figures import _LABEL_TEXT, _Axes, _draw_axes, _draw_series, _Pen
from lightcal.io.response import ResponseCurve

_CHANNELS = (  # (line, dots) per channel, B G R
    ((33, 102, 172), (33, 102, 172)),
    ((27, 120, 55), (27, 120, 55)),
    ((178, 24, 43), (178, 24, 43)),
)
_GREY = ((150, 150, 150), (150, 150, 150))


def srgb_to_linear(codes: np.ndarray) -> np.ndarray:
    """The sRGB standard's decoding of 8-bit codes (IEC 61966-2-1), 0..1."""
    c = np.asarray(codes, dtype=np.float64) / 255.0
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)


def response_figure(
    curve: ResponseCurve, *, title: str = "camera response", scale: float = 2.0
) -> np.ndarray:
    """RGB uint8 plot of `curve` (see the module docstring)."""
    pen = _Pen(scale)
    w, h = pen.px(640), pen.px(400)
    fig = pen.canvas(h, w)
    pen.text(fig, title, (pen.px(80), pen.px(20)), _LABEL_TEXT)
    codes = np.arange(1, 256)
    values = curve.values[1:] / curve.values[128]
    srgb = srgb_to_linear(codes) / srgb_to_linear(np.array([128]))[0]
    logs = np.log10(np.concatenate([values.ravel(), srgb]))
    lo, hi = math.floor(float(logs.min())), math.ceil(float(logs.max()))
    hi = hi if hi > lo else lo + 1
    ax = _Axes(pen.px(80), pen.px(32), w - pen.px(20), h - pen.px(50), (0.0, 255.0), (lo, hi))
    _draw_axes(
        fig,
        pen,
        ax,
        x_ticks=[0.0, 50.0, 100.0, 150.0, 200.0, 255.0],
        x_format=".0f",
        y_ticks=[(e, f"1e{e}") for e in range(lo, hi + 1)],
        x_label="8-bit code",
        y_label="linear value (log)",
    )
    dashed = [(int(x), float(y)) for x, y in zip(codes[::6], np.log10(srgb[::6]), strict=True)]
    for (x0, y0), (x1, y1) in zip(dashed[::2], dashed[1::2], strict=False):
        cv2.line(fig, ax.xy(x0, y0), ax.xy(x1, y1), _GREY[0], pen.thickness(), cv2.LINE_AA)
    for c in range(curve.n_channels):
        colours = _CHANNELS[c] if curve.n_channels == 3 else _CHANNELS[1]
        _draw_series(fig, pen, ax, codes[::5], np.log10(values[::5, c]), colours)
    legend = "blue, green, red: the fitted channels; dashed: sRGB"
    pen.text(fig, legend, (ax.right - pen.px(4), ax.bottom - pen.px(8)), _LABEL_TEXT, "right")
    return fig
