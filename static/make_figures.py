"""Draw the pictures of the app's explanation panel (run: python static/make_figures.py).

Every figure is drawn with NumPy and OpenCV from the model's own definitions (docs/model.md):
the frames, a pixel's footprint on the wall, the solid angle the footprint subtends at
the light, a RID curve with its half-intensity and cut-off angles, and a small rendered
example of real / rendered / residual images. The PNGs land beside this script.
"""

from __future__ import annotations

import math
import sys
from pathlib import Path

import cv2
import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent))

from lightcal.colormap import diverging_rgb, grey_rgb  # noqa: E402
from lightcal.core.camera import Camera  # noqa: E402
from lightcal.core.pose import axis_from_angles, rotation_from_axis  # noqa: E402
from lightcal.core.render import render_image  # noqa: E402
from lightcal.core.rid import CosPowerRID  # noqa: E402
from lightcal.core.scene import Light, Rig, View  # noqa: E402

W, H = 300, 210
"""The figures' logical size: shown about 360 pixels wide in the panel."""
S = 2
"""Drawn at S times the logical size (600 x 420 pixels): crisp when the page scales it."""
TEXT = 0.45
"""Text size (logical): about 12 pixels tall on the page."""
FONT = cv2.FONT_HERSHEY_SIMPLEX
INK = (30, 30, 30)
RED = (214, 40, 40)
GREEN = (30, 150, 60)
BLUE = (30, 90, 200)
ORANGE = (235, 130, 0)
GREY = (150, 150, 150)


def canvas() -> np.ndarray:
    return np.full((H * S, W * S, 3), 255, np.uint8)


def _px(xy) -> tuple[int, int]:
    return round(S * float(xy[0])), round(S * float(xy[1]))


def text(img: np.ndarray, s: str, xy, colour=INK, scale: float = TEXT) -> None:
    """`s` with its baseline's left end at logical `xy`."""
    cv2.putText(img, s, _px(xy), FONT, S * scale, colour, S, cv2.LINE_AA)


def text_width(s: str, scale: float = TEXT) -> float:
    """Logical width of `s`."""
    return cv2.getTextSize(s, FONT, S * scale, S)[0][0] / S


def dot(img: np.ndarray, xy, radius: float, colour) -> None:
    cv2.circle(img, _px(xy), round(S * radius), colour, -1, cv2.LINE_AA)


class Projector:
    """A perspective sketch camera: world points (N, 3) -> logical canvas points (N, 2)."""

    def __init__(self, eye: np.ndarray, target: np.ndarray, focal: float = 280.0) -> None:
        z = target - eye
        z /= np.linalg.norm(z)
        x = np.cross(z, np.array([0.0, 0.0, 1.0]))
        x /= np.linalg.norm(x)
        y = np.cross(z, x)
        self.R = np.stack([x, y, z])
        self.eye = eye
        self.f = focal

    def __call__(self, p: np.ndarray) -> np.ndarray:
        q = (np.atleast_2d(p) - self.eye) @ self.R.T
        return np.stack([W / 2 + self.f * q[:, 0] / q[:, 2], H / 2 + self.f * q[:, 1] / q[:, 2]], 1)


def line(img, P, a, b, colour=INK, width=1.5, arrow=False) -> None:
    pa, pb = _px(P(np.array(a))[0]), _px(P(np.array(b))[0])
    w = max(1, round(S * width))
    if arrow:
        cv2.arrowedLine(img, pa, pb, colour, w, cv2.LINE_AA, tipLength=0.14)
    else:
        cv2.line(img, pa, pb, colour, w, cv2.LINE_AA)


def poly(img, P, pts, colour, alpha=0.35, edge=INK) -> None:
    q = np.round(S * P(np.array(pts))).astype(np.int32)
    layer = img.copy()
    cv2.fillPoly(layer, [q], colour, cv2.LINE_AA)
    img[:] = cv2.addWeighted(layer, alpha, img, 1 - alpha, 0)
    cv2.polylines(img, [q], True, edge, S, cv2.LINE_AA)


def wall(img, P, size=1.0) -> None:
    s = size
    poly(img, P, [[-s, -s, 0], [s, -s, 0], [s, s, 0], [-s, s, 0]], (225, 222, 212), 0.9, GREY)


def frames_figure() -> np.ndarray:
    img = canvas()
    P = Projector(np.array([-1.2, -2.9, 1.7]), np.array([0.0, 0.0, 0.45]))
    wall(img, P, 0.9)
    line(img, P, [0.6, 0.6, 0], [0.6, 0.6, 0.35], GREEN, 1.5, arrow=True)
    text(img, "wall z = 0", (180, 196), GREY)
    c = np.array([0.0, 0.0, 1.0])
    R_wc = View.looking_at(c, np.array([0.1, 0.05, 0.0])).R_camera_world.T
    axes = {"x": (R_wc[:, 0], RED), "y": (R_wc[:, 1], GREEN), "z": (R_wc[:, 2], BLUE)}
    for name, (v, col) in axes.items():
        line(img, P, c, c + 0.35 * v, col, 1.5, arrow=True)
        text(img, name, P(c + 0.42 * v)[0], col)
    text(img, "camera (OpenCV frame)", (8, 18))
    t = np.array([0.18, -0.06, 0.02])
    light = c + R_wc @ t
    axis_c = axis_from_angles(0.25, -0.1)
    line(img, P, c, light, GREY, 1)
    dot(img, P(light)[0], 4, ORANGE)
    line(img, P, light, light + 0.5 * (R_wc @ axis_c), ORANGE, 1.5, arrow=True)
    text(img, "light: +z is its axis", (160, 80), ORANGE)
    return img


def footprint_figure() -> np.ndarray:
    img = canvas()
    P = Projector(np.array([2.4, -2.2, 1.6]), np.array([0.0, 0.0, 0.35]))
    wall(img, P, 0.9)
    c = np.array([-0.1, 0.0, 1.05])
    quad = np.array([[0.05, -0.1, 0], [0.32, -0.06, 0], [0.36, 0.2, 0], [0.02, 0.16, 0]])
    for q in quad:
        line(img, P, c, q, BLUE, 0.75)
    poly(img, P, quad, BLUE, 0.45)
    sensor = c + np.array(
        [[0.03, -0.02, -0.12], [0.07, -0.015, -0.12], [0.075, 0.02, -0.12], [0.025, 0.015, -0.12]]
    )
    poly(img, P, sensor, (120, 160, 230), 0.8)
    dot(img, P(c)[0], 3, INK)
    text(img, "camera centre", P(c)[0] + [8, -4])
    text(img, "one pixel: 4 corner rays", (8, 18))
    text(img, "footprint on the wall", P(quad[2])[0] + [-40, 22], BLUE)
    return img


def solid_angle_figure() -> np.ndarray:
    img = canvas()
    P = Projector(np.array([2.5, -2.0, 1.5]), np.array([0.0, 0.0, 0.4]))
    wall(img, P, 0.9)
    L = np.array([-0.25, -0.15, 1.0])
    quad = np.array([[0.1, 0.0, 0], [0.4, 0.05, 0], [0.42, 0.32, 0], [0.08, 0.28, 0]])
    for q in quad:
        line(img, P, L, q, ORANGE, 0.75)
    poly(img, P, quad, ORANGE, 0.45)
    r = 0.3
    patch = np.array([L + r * (q - L) / np.linalg.norm(q - L) for q in quad])
    poly(img, P, patch, (250, 200, 120), 0.9)
    dot(img, P(L)[0], 4, ORANGE)
    text(img, "light", P(L)[0] + [8, -6], ORANGE)
    text(img, "solid angle", P(patch.mean(0))[0] + [10, 0], INK)
    text(img, "the footprint seen from the light", (8, 18))
    return img


def rid_figure() -> np.ndarray:
    img = canvas()
    rid = CosPowerRID.from_half_angle(math.radians(30.0))
    x0, y0, x1, y1 = 30, 28, W - 12, H - 40
    cv2.rectangle(img, _px((x0, y0)), _px((x1, y1)), GREY, S)
    theta = np.linspace(0.0, math.radians(90.0), 400)
    f = np.asarray(rid(theta))
    px = x0 + (x1 - x0) * theta / theta[-1]
    py = y1 - (y1 - y0) * f
    curve = np.round(S * np.stack([px, py], 1)).astype(np.int32)
    cv2.polylines(img, [curve], False, ORANGE, 2 * S, cv2.LINE_AA)
    for level, name, col in ((0.5, "half", BLUE), (0.01, "1 %", RED)):
        a = rid.angle_at_level_rad(level)
        x = x0 + (x1 - x0) * a / theta[-1]
        cv2.line(img, _px((x, y0)), _px((x, y1)), col, S, cv2.LINE_AA)
        label = f"{name}: {math.degrees(a):.0f} deg"
        tx = x + 4 if x + 4 + text_width(label) < W else x - 4 - text_width(label)
        text(img, label, (tx, y0 + (16 if level == 0.5 else 34)), col)
    for deg in range(0, 91, 30):
        x = x0 + (x1 - x0) * deg / 90
        text(img, str(deg), (x - text_width(str(deg)) / 2, y1 + 15))
    text(img, "1", (x0 - 12, y0 + 6))
    text(img, "0", (x0 - 12, y1 + 4))
    text(img, "f = cos^m(theta)", (x0, 20))
    text(img, "theta from the axis (deg)", (x0 + 40, H - 6))
    return img


def residual_figure() -> np.ndarray:
    cam = Camera.from_params(fx=150, fy=150, cx=79.5, cy=59.5, width=160, height=120)
    view = View.looking_at(np.array([0.2, 0.1, 1.0]), np.array([0.1, 0.0, 0.0]))
    true = Light(
        CosPowerRID.from_half_angle(math.radians(30)),
        np.array([0.1, -0.03, 0.0]),
        rotation_from_axis(axis_from_angles(0.08, -0.05)),
    )
    guess = true.replace(t_camera_light=np.array([0.02, 0.03, 0.0]))
    real = render_image(cam, view, Rig.single(true)).filled(np.nan)
    rendered = render_image(cam, view, Rig.single(guess)).filled(np.nan)
    white = float(np.nanpercentile(real, 99.5))
    res = real - rendered
    vmax = float(np.nanpercentile(np.abs(res), 99))
    tiles = [grey_rgb(real, white), grey_rgb(rendered, white), diverging_rgb(res, vmax)]
    img = canvas()
    labels = ("real", "rendered", "residual")
    tile_w, tile_h, gap = 92, 69, 8  # logical
    for k, (tile, label) in enumerate(zip(tiles, labels, strict=True)):
        big = cv2.resize(tile, (S * tile_w, S * tile_h), interpolation=cv2.INTER_NEAREST)
        x = 8 + k * (tile_w + gap)
        img[S * 50 : S * (50 + tile_h), S * x : S * (x + tile_w)] = big
        text(img, label, (x, 42))
    text(img, "guess off: the residual is not flat", (8, 18))
    text(img, "red: real brighter", (8, 150), RED)
    text(img, "blue: real darker", (8, 172), BLUE)
    return img


FIGURES = {
    "frames.png": frames_figure,
    "footprint.png": footprint_figure,
    "solid_angle.png": solid_angle_figure,
    "rid.png": rid_figure,
    "residual.png": residual_figure,
}


def main() -> None:
    for name, fn in FIGURES.items():
        rgb = fn()
        ok = cv2.imwrite(str(HERE / name), cv2.cvtColor(rgb, cv2.COLOR_RGB2BGR))
        if not ok:
            raise OSError(f"{name}: could not write")
        print(f"wrote {HERE / name}")


if __name__ == "__main__":
    main()
