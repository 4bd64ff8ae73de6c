"""Synthetic photos of a marker wall lit by a known light, for "New project from photos".

`write_photos` renders what a user would upload: 16-bit PNG photos of a white wall that
carries a printed ArUco grid, lit only by one cos-power light mounted beside the camera
(`tests.app_fixtures.true_light`: 30 degrees half angle, at (100, -30, 10) mm in the
camera frame), plus one photo with no marker in it (which `lightcal init` must reject),
the camera file and the board file.

Each photo is the renderer's irradiance (`lightcal.core.render.render_image`, sensor model
`radiance`) times the wall's albedo averaged over each pixel (the print sampled on
3 x 3 sub-pixels, `lightcal.capture.plane_texture.render_plane_image`; white 1, black print
0.05), one scale for every photo (no EXIF: the project gives each exposure 1), a little
Gaussian noise, rounded to 16 bits. The project `lightcal init` makes of them masks the
print (plus 3 px), so the calibration sees only the white wall, which follows the model
exactly; what is left is the marker poses' error and the noise.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from lightcal.capture.boards import ArucoGridBoard
from lightcal.capture.plane_texture import render_plane_image
from lightcal.core.camera import Camera
from lightcal.core.render import render_image
from lightcal.core.scene import Light, Rig, View
from lightcal.io.board_file import write_board
from lightcal.io.camera_file import write_camera
from tests.app_fixtures import HALF_ANGLE_DEG, true_light

WIDTH, HEIGHT = 320, 240
CAMERA = Camera.from_params(
    fx=352.0,
    fy=352.0,
    cx=159.5,
    cy=119.5,
    width=WIDTH,
    height=HEIGHT,
    dist=(-0.05, 0.01, 0.0, 0.0, 0.0),
)
BOARD = ArucoGridBoard("DICT_4X4_50", 6, 4, 0.09, 0.06, origin_world_m=(-0.42, 0.27))
"""6 x 4 markers of 9 cm, 15 cm apart centre to centre, centred on the world origin."""

# (camera centre (m), target on the wall (m)): 0.75 - 1.5 m away, tilted up to ~25 degrees.
VIEWS = [
    ((0.05, -0.04, 0.80), (0.03, 0.00)),
    ((-0.30, 0.12, 0.95), (0.02, 0.03)),
    ((0.35, 0.20, 1.10), (0.05, -0.02)),
    ((-0.15, -0.35, 1.30), (-0.02, 0.04)),
    ((0.20, 0.05, 1.35), (0.00, 0.00)),
]
BLANK_NAME = "wall_9_blank.png"
BLANK_REASON = "found 0 markers, need at least 4"
PEAK_DN = 0.7 * 65535.0
NOISE_DN = 8.0
ALBEDO_BLACK = 0.05
HALF_ANGLE = HALF_ANGLE_DEG


@dataclass(frozen=True)
class Photos:
    """What `write_photos` wrote.

    Attributes:
        folder: the folder.
        photos: the wall photos (the blank one last).
        camera: the camera file.
        board: the board file.
        views: the true view of each photo but the blank one.
        light: the light they were rendered with (camera frame).
    """

    folder: Path
    photos: list[Path]
    camera: Path
    board: Path
    views: list[View]
    light: Light


def write_photos(folder: Path, *, seed: int = 7) -> Photos:
    """Render the photos, the camera file and the board file into `folder` (created)."""
    folder.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(seed)
    light = true_light()
    rig = Rig.single(light)
    rendering = BOARD.render(2000.0)
    texture = ALBEDO_BLACK + (1.0 - ALBEDO_BLACK) * rendering.image / 255.0
    views = [View.looking_at(np.array(c), np.array([*t, 0.0])) for c, t in VIEWS]
    signals = []
    for view in views:
        irradiance = render_image(CAMERA, view, rig)
        if np.ma.count_masked(irradiance):
            raise RuntimeError("a synthetic view sees past the wall: change VIEWS")
        albedo = render_plane_image(
            CAMERA,
            view.R_camera_world,
            view.t_camera_world,
            texture,
            rendering.px_per_m,
            rendering.top_left_world_m,
            background=1.0,
            supersample=3,
        )
        signals.append(np.ma.getdata(irradiance) * albedo)
    scale = PEAK_DN / max(float(s.max()) for s in signals)
    photos = []
    for k, signal in enumerate(signals):
        dn = scale * signal + rng.normal(0.0, NOISE_DN, signal.shape)
        path = folder / f"wall_{k}.png"
        cv2.imwrite(str(path), np.clip(np.rint(dn), 0, 65535).astype(np.uint16))
        photos.append(path)
    blank = np.clip(np.rint(20000.0 + rng.normal(0.0, NOISE_DN, (HEIGHT, WIDTH))), 0, 65535)
    cv2.imwrite(str(folder / BLANK_NAME), blank.astype(np.uint16))
    photos.append(folder / BLANK_NAME)
    write_camera(CAMERA, folder / "camera.yaml")
    write_board(BOARD, folder / "board.yaml")
    return Photos(folder, photos, folder / "camera.yaml", folder / "board.yaml", views, light)


def angle_deg(a: np.ndarray, b: np.ndarray) -> float:
    """The angle between two directions, degrees."""
    c = float(a @ b / (np.linalg.norm(a) * np.linalg.norm(b)))
    return math.degrees(math.acos(min(1.0, max(-1.0, c))))
