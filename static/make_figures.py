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

W, H = 560, 360
FONT = cv2.FONT_HERSHEY_SIMPLEX
INK = (30, 30, 30)
RED = (214, 40, 40)
GREEN = (30, 150, 60)
BLUE = (30, 90, 200)
ORANGE = (235, 130, 0)
GREY = (150, 150, 150)


def canvas() -> np.ndarray:
    return np.full((H, W, 3), 255, np.uint8)


def text(img: np.ndarray, s: str, xy: tuple[float, float], colour=INK, scale: float = 0.5) -> None:
    cv2.putText(img, s, (int(xy[0]), int(xy[1])), FONT, scale, colour, 1, cv2.LINE_AA)


class Projector:
    """A perspective sketch camera: world points (N, 3) -> canvas points (N, 2)."""

    def __init__(self, eye: np.ndarray, target: np.ndarray, focal: float = 520.0) -> None:
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


def line(img, P, a, b, colour=INK, width=2, arrow=False) -> None:
    pa, pb = P(np.array(a))[0], P(np.array(b))[0]
    pa_i = (int(pa[0]), int(pa[1]))
    pb_i = (int(pb[0]), int(pb[1]))
    if arrow:
        cv2.arrowedLine(img, pa_i, pb_i, colour, width, cv2.LINE_AA, tipLength=0.12)
    else:
        cv2.line(img, pa_i, pb_i, colour, width, cv2.LINE_AA)


def poly(img, P, pts, colour, alpha=0.35, edge=INK) -> None:
    q = np.round(P(np.array(pts))).astype(np.int32)
    layer = img.copy()
    cv2.fillPoly(layer, [q], colour, cv2.LINE_AA)
    img[:] = cv2.addWeighted(layer, alpha, img, 1 - alpha, 0)
    cv2.polylines(img, [q], True, edge, 1, cv2.LINE_AA)


def wall(img, P, size=1.0) -> None:
    s = size
    poly(img, P, [[-s, -s, 0], [s, -s, 0], [s, s, 0], [-s, s, 0]], (225, 222, 212), 0.9, GREY)


def frames_figure() -> np.ndarray:
    img = canvas()
    P = Projector(np.array([-1.2, -2.9, 1.7]), np.array([0.0, 0.0, 0.45]))
    wall(img, P, 0.9)
    line(img, P, [0.6, 0.6, 0], [0.6, 0.6, 0.35], GREEN, 2, arrow=True)
    text(img, "wall z = 0, normal +z", (300, 300), GREY)
    c = np.array([0.0, 0.0, 1.0])
    R_wc = View.looking_at(c, np.array([0.1, 0.05, 0.0])).R_camera_world.T
    axes = {"x": (R_wc[:, 0], RED), "y": (R_wc[:, 1], GREEN), "z": (R_wc[:, 2], BLUE)}
    for name, (v, col) in axes.items():
        line(img, P, c, c + 0.35 * v, col, 2, arrow=True)
        text(img, f"{name}c", P(c + 0.4 * v)[0], col)
    text(img, "camera C (OpenCV): x right, y down, z forward", (12, 24))
    t = np.array([0.18, -0.06, 0.02])
    light = c + R_wc @ t
    axis_c = axis_from_angles(0.25, -0.1)
    line(img, P, c, light, GREY, 1)
    cv2.circle(img, tuple(int(v) for v in P(light)[0]), 7, ORANGE, -1, cv2.LINE_AA)
    line(img, P, light, light + 0.5 * (R_wc @ axis_c), ORANGE, 2, arrow=True)
    text(img, "light L (orange): +z is its axis,", (330, 150), ORANGE)
    text(img, "mounted on the camera", (330, 172), ORANGE)
    text(img, "unknown: T_camera_light = (R_cl, p_cl), the same in every image", (12, H - 36))
    text(img, "views: T_camera_world = (R_i, t_i), X_c = R_i X_w + t_i", (12, H - 14))
    return img


def footprint_figure() -> np.ndarray:
    img = canvas()
    P = Projector(np.array([2.4, -2.2, 1.6]), np.array([0.0, 0.0, 0.35]))
    wall(img, P, 0.9)
    c = np.array([-0.1, 0.0, 1.05])
    quad = np.array([[0.05, -0.1, 0], [0.32, -0.06, 0], [0.36, 0.2, 0], [0.02, 0.16, 0]])
    for q in quad:
        line(img, P, c, q, BLUE, 1)
    poly(img, P, quad, BLUE, 0.45)
    sensor = c + np.array(
        [[0.03, -0.02, -0.12], [0.07, -0.015, -0.12], [0.075, 0.02, -0.12], [0.025, 0.015, -0.12]]
    )
    poly(img, P, sensor, (120, 160, 230), 0.8)
    cv2.circle(img, tuple(int(v) for v in P(c)[0]), 5, INK, -1, cv2.LINE_AA)
    text(img, "camera centre C_i", P(c)[0] + [10, -6])
    text(img, "pixel (u, v): corners at u +- 1/2, v +- 1/2", (12, 24))
    text(img, "footprint quad Q on the wall", P(quad[2])[0] + [8, 12], BLUE)
    text(img, "corner rays: undistort, d = R_i^T K^-1 (u, v, 1),", (12, H - 36))
    text(img, "P = C_i + lambda d with lambda = -C_iz / d_z (must be > 0)", (12, H - 14))
    return img


def solid_angle_figure() -> np.ndarray:
    img = canvas()
    P = Projector(np.array([2.5, -2.0, 1.5]), np.array([0.0, 0.0, 0.4]))
    wall(img, P, 0.9)
    L = np.array([-0.25, -0.15, 1.0])
    quad = np.array([[0.1, 0.0, 0], [0.4, 0.05, 0], [0.42, 0.32, 0], [0.08, 0.28, 0]])
    for q in quad:
        line(img, P, L, q, ORANGE, 1)
    poly(img, P, quad, ORANGE, 0.45)
    r = 0.3
    patch = np.array([L + r * (q - L) / np.linalg.norm(q - L) for q in quad])
    poly(img, P, patch, (250, 200, 120), 0.9)
    cv2.circle(img, tuple(int(v) for v in P(L)[0]), 7, ORANGE, -1, cv2.LINE_AA)
    text(img, "light L_w = C_i + R_i^T p_cl", P(L)[0] + [10, -8], ORANGE)
    text(img, "Omega_Q", P(patch.mean(0))[0] + [14, 0], INK)
    text(img, "solid angle of the footprint seen from the light:", (12, 24))
    text(img, "two spherical triangles (van Oosterom-Strackee), exact", (12, 46))
    text(img, "flux Phi_Q = I0 f(theta, phi) Omega_Q;  irradiance E = Phi_Q / A_Q", (12, H - 36))
    text(img, "pixel value m = k g_i V(u, v) rho E / pi + b", (12, H - 14))
    return img


def rid_figure() -> np.ndarray:
    img = canvas()
    rid = CosPowerRID.from_half_angle(math.radians(30.0))
    x0, y0, x1, y1 = 60, 40, W - 30, H - 60
    cv2.rectangle(img, (x0, y0), (x1, y1), GREY, 1)
    theta = np.linspace(0.0, math.radians(90.0), 400)
    f = np.asarray(rid(theta))
    px = x0 + (x1 - x0) * theta / theta[-1]
    py = y1 - (y1 - y0) * f
    cv2.polylines(img, [np.stack([px, py], 1).astype(np.int32)], False, ORANGE, 2, cv2.LINE_AA)
    for level, name, col in ((0.5, "half intensity", BLUE), (0.01, "cut-off (1 %)", RED)):
        a = rid.angle_at_level_rad(level)
        x = int(x0 + (x1 - x0) * a / theta[-1])
        cv2.line(img, (x, y0), (x, y1), col, 1, cv2.LINE_AA)
        label = f"{name}: {math.degrees(a):.1f} deg"
        size = cv2.getTextSize(label, FONT, 0.5, 1)[0][0]
        tx = x + 6 if x + 6 + size < W else x - 6 - size
        text(img, label, (tx, y0 + (20 if level == 0.5 else 40)), col)
    for deg in range(0, 91, 15):
        x = int(x0 + (x1 - x0) * deg / 90)
        text(img, str(deg), (x - 8, y1 + 18), INK, 0.42)
    text(img, "1", (x0 - 18, y0 + 5), INK, 0.42)
    text(img, "0", (x0 - 18, y1 + 5), INK, 0.42)
    text(img, "relative intensity f(theta) = cos^m(theta)", (x0, 26))
    text(
        img,
        "theta: angle from the light axis (deg); the 3D cones show both angles",
        (x0 - 40, H - 16),
    )
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
    labels = ("real image", "rendered (guess)", "real - rendered")
    for k, (tile, label) in enumerate(zip(tiles, labels, strict=True)):
        big = cv2.resize(tile, (160, 120), interpolation=cv2.INTER_NEAREST)
        x = 20 + k * 180
        img[70:190, x : x + 160] = big
        text(img, label, (x, 60))
    text(img, "the solver moves the light until the residual is flat (noise only)", (20, 230))
    text(img, "red: real brighter than rendered; blue: darker", (20, 256))
    text(img, "Step / Run in the Solve tab; watch the cost fall", (20, 282))
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
