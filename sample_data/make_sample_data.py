"""Regenerate lightcal's bundled sample calibration set (this folder), exactly.

    .venv/bin/python sample_data/make_sample_data.py            # the committed set (a minute)
    .venv/bin/python sample_data/make_sample_data.py --quick --out /tmp/s   # a small variant

What it builds (README.md in this folder says the same for users):

1. The rig: a 24 MP camera (6000 x 4000, 6 um pixels, 28 mm lens, k1 = -0.08, k2 = 0.02)
   read out binned 5 x 5 (averaged) to 1200 x 800, and one LED behind a reflector, 10 cm
   beside the lens, its axis 7 degrees off the optical axis. The LED's angular profile (a
   narrow core plus a wide skirt) is authored here and written as an axial IES file,
   `light.ies`; the truth is rendered with the profile read back from that file.
2. The wall: white paint (albedo 1) carrying a printed grid of 8 x 6 ArUco markers
   (DICT_4X4_50, 12 cm, 30 cm apart; black print albedo 0.05), `board.yaml`.
3. 12 views of the wall (`images/`) at 0.8 - 2.5 m, tilted up to 30 degrees, lit by the
   LED only: the irradiance is rendered with lightcal's energy-preserving renderer
   (`render_image`, sensor model `radiance`), multiplied by the albedo averaged over each
   pixel (the print sampled on 3 x 3 sub-pixels,
   `lightcal.capture.plane_texture.render_plane_image`),
   blurred by the lens (Gaussian PSF, sigma 0.5 px), exposed with a shutter time chosen
   per view (EXIF in the PNG), then through the sensor model (`apply_sensor`: shot and
   read noise, 14 bits, black level 512) and written as 16-bit PNG.
4. 16 views of a chessboard (9 x 6 inner corners, 6 cm squares) on the same wall under room
   light (`chessboard/`, 8-bit gamma-encoded PNG), for the intrinsics.
5. The real pipeline: `lightcal camera calibrate` on the chessboard views -> `camera.yaml`
   (estimated, not the truth); `lightcal init` on the wall views -> `project.json` and
   `masks/` (marker detection, poses, EXIF exposures), with an initial guess of the light
   measured "with a ruler" (a few cm and 7 degrees off); `truth.json` holds the truth.
6. Unless `--skip-calibration`: `lightcal calibrate`'s pipeline on the project, and the
   errors of every estimate against the truth are printed.

Every random choice comes from `numpy.random.default_rng(SEED)` (one spawned stream per
purpose) and OpenCV runs on one thread, so the same code writes the same bytes.
"""

from __future__ import annotations

import argparse
import io
import json
import math
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray
from PIL import Image

REPO = Path(__file__).resolve().parents[1]
if str(REPO) not in sys.path:
    sys.path.insert(0, str(REPO))

from lightcal import __version__  # noqa: E402
from lightcal.capture.boards import ArucoGridBoard, Chessboard  # noqa: E402
from lightcal.capture.plane_texture import look_at_pose, render_plane_image  # noqa: E402
from lightcal.cli.main import main as lightcal_main  # noqa: E402
from lightcal.core.camera import Camera  # noqa: E402
from lightcal.core.pose import describe_pose, rotation_from_axis  # noqa: E402
from lightcal.core.render import render_image  # noqa: E402
from lightcal.core.rid import RID  # noqa: E402
from lightcal.core.scene import Light, Rig, View  # noqa: E402
from lightcal.io.atomic import atomic_write_bytes, atomic_write_text  # noqa: E402
from lightcal.io.board_file import write_board  # noqa: E402
from lightcal.io.ies import read_ies, write_ies  # noqa: E402
from lightcal.io.photometric_table import PhotometricTable, table_to_rid  # noqa: E402
from lightcal.synthetic.scenes import (  # noqa: E402
    SceneConfig,
    SensorConfig,
    apply_sensor,
    conversion_gain,
    describe_rid,
    noise_model,
    sample_views,
    white_level,
)

SEED = 2020
"""Seed of every random choice (the year of Song et al.)."""

TRUTH_FORMAT = "lightcal.sample_truth"

GENERATED_FILES = (
    "board.yaml",
    "chessboard.yaml",
    "light.ies",
    "camera.yaml",
    "project.json",
    "truth.json",
)
"""Top-level files the script writes (README.md and the script itself are not generated)."""

# ---------------------------------------------------------------------------- the rig

FULL_SENSOR = Camera.from_params(
    fx=28e-3 / 6e-6,
    fy=28e-3 / 6e-6,
    cx=2999.5 + 14.3,
    cy=1999.5 - 9.1,
    width=6000,
    height=4000,
    dist=(-0.08, 0.02, 2.0e-4, -1.0e-4, 0.0),
)
"""The full 24 MP sensor: 6 um pixels behind a 28 mm lens, principal point a little off
centre, barrel distortion."""

LIGHT_POSITION_M = (0.102, -0.014, 0.018)
"""The LED in the camera frame: 10 cm right of the lens, a little above and in front."""

LIGHT_AXIS_CAMERA = (-math.tan(math.radians(6.0)), math.tan(math.radians(4.0)), 1.0)
"""The LED points 6 degrees left (towards the optical axis) and 4 degrees down."""

INITIAL_POSITION_M = (0.09, 0.0, 0.0)
"""The initial guess "measured with a ruler": 9 cm right of the lens."""

INITIAL_AXIS_CAMERA = (0.0, 0.0, 1.0)
"""The initial guess of the axis: along the optical axis."""

LED_CANDELA = 1800.0
"""Intensity on the axis written in the IES file (the RID is relative)."""

LED_CORE_HALF_ANGLE_DEG = 12.0
LED_SKIRT_HALF_ANGLE_DEG = 40.0
LED_CORE_WEIGHT = 0.75


def led_profile(theta_deg: NDArray[np.float64]) -> NDArray[np.float64]:
    """Relative intensity of the LED behind its reflector: a core plus a skirt.

    f = (w g(theta, 12 deg) + (1 - w) g(theta, 40 deg)) cos(theta)^0.3, w = 0.75, with
    g(theta, h) = 2^-(theta / h)^2 a Gaussian of half-intensity angle h; f(0) = 1 and
    f(90 deg) = 0.
    """
    theta = np.asarray(theta_deg, dtype=np.float64)

    def gaussian(half_deg: float) -> NDArray[np.float64]:
        return np.asarray(np.exp2(-((theta / half_deg) ** 2)))

    core = LED_CORE_WEIGHT * gaussian(LED_CORE_HALF_ANGLE_DEG)
    skirt = (1.0 - LED_CORE_WEIGHT) * gaussian(LED_SKIRT_HALF_ANGLE_DEG)
    values = (core + skirt) * np.cos(np.radians(theta)).clip(0.0, None) ** 0.3
    values[theta >= 90.0] = 0.0
    return np.asarray(values)


# --------------------------------------------------------------------------- the wall

MARKER_BOARD = ArucoGridBoard("DICT_4X4_50", 8, 6, 0.12, 0.18, origin_world_m=(-1.11, 0.81))
"""8 x 6 markers of 12 cm, 30 cm apart (centre to centre), centred on the world origin."""

CHESSBOARD = Chessboard(9, 6, 0.06)
"""9 x 6 inner corners, 6 cm squares (a 60 x 42 cm print)."""

ALBEDO_WHITE = 1.0
ALBEDO_BLACK = 0.05
TEXTURE_PX_PER_M = 2000.0
"""Resolution of the printed patterns' textures (0.5 mm texels)."""

PSF_SIGMA_PX = 0.5
"""Standard deviation of the lens blur (Gaussian point spread function), pixels."""

SHUTTER_TIMES_S = (
    1 / 250, 1 / 200, 1 / 160, 1 / 125, 1 / 100, 1 / 80, 1 / 60, 1 / 50, 1 / 40, 1 / 30,
    1 / 25, 1 / 20, 1 / 15, 1 / 13, 1 / 10, 1 / 8,
)  # fmt: skip
"""The camera's shutter times (1/3 stops)."""

F_NUMBER = 4.0
ISO = 100.0
BRIGHTEST_FRACTION = 0.75
"""A view gets the longest shutter time that keeps its brightest pixel below this fraction
of the usable range (exposing to the right, without clipping)."""

CLOSEST_VIEW_FRACTION = 0.7
"""The brightest view at 1/125 s would reach this fraction (sets the LED's brightness)."""

# Sensor after 5 x 5 averaging of a 15 000 e- full-well, 3 e- read-noise pixel: the mean of
# n = 25 pixels behaves like one pixel of n x 15 000 e- full well and sqrt(n) x 3 e- read noise.
SENSOR_BINNED_5 = SensorConfig(
    bit_depth=14,
    full_well_e=25 * 15000.0,
    read_noise_e=5 * 3.0,
    black_level_dn=512.0,
    model="radiance",
)


@dataclass(frozen=True)
class Variant:
    """Sizes of a generated set.

    Attributes:
        binning: Sensor pixels per image pixel along each axis.
        n_views: Views of the wall.
        distance_range_m: Camera-to-wall distances of the wall views.
        n_chessboard_views: Views of the chessboard.
        supersample: Sub-pixels per pixel side when sampling the print.
    """

    binning: int
    n_views: int
    distance_range_m: tuple[float, float]
    n_chessboard_views: int
    supersample: int


FULL = Variant(
    binning=5, n_views=12, distance_range_m=(0.8, 2.5), n_chessboard_views=16, supersample=3
)
QUICK = Variant(
    binning=12, n_views=2, distance_range_m=(0.8, 1.2), n_chessboard_views=5, supersample=2
)

SCENE_TILT_DEG = (0.0, 30.0)
SCENE_ROLL_DEG = (-15.0, 15.0)
SCENE_TARGET_SPREAD_M = 0.25


# ------------------------------------------------------------------------------ helpers


def log(message: str) -> None:
    print(f"make_sample_data: {message}", flush=True)


def _png_bytes(image: NDArray[Any], exif: dict[int, Any]) -> bytes:
    """A PNG (16-bit or 8-bit grey) with an eXIf chunk, maximal compression."""
    if image.dtype == np.uint16:
        pil = Image.fromarray(image.astype(np.uint16))
    else:
        pil = Image.fromarray(image.astype(np.uint8))
    tags = Image.Exif()
    tags[0x010F] = "lightcal"  # Make
    tags[0x0110] = "sample 24 MP camera, 5x5 binned"  # Model
    tags[0x8769] = exif  # the Exif IFD
    buffer = io.BytesIO()
    pil.save(buffer, format="PNG", exif=tags, compress_level=9)
    return buffer.getvalue()


def _exif(exposure_time_s: float, iso: float) -> dict[int, Any]:
    return {0x829A: exposure_time_s, 0x829D: F_NUMBER, 0x8827: int(iso)}


def _view_geometry(view: View) -> dict[str, float]:
    """Distance along the optical axis to the wall and tilt from its normal."""
    axis = view.R_camera_world[2]
    center = view.center_world
    return {
        "distance_m": float(-center[2] / axis[2]),
        "tilt_deg": math.degrees(math.acos(min(1.0, max(-1.0, float(-axis[2]))))),
    }


def _albedo_texture(board: ArucoGridBoard | Chessboard) -> tuple[NDArray[Any], Any]:
    rendering = board.render(TEXTURE_PX_PER_M)
    texture = ALBEDO_BLACK + (ALBEDO_WHITE - ALBEDO_BLACK) * rendering.image / 255.0
    return texture.astype(np.float32), rendering


def _albedo_image(
    camera: Camera, view: View, texture: NDArray[Any], rendering: Any, supersample: int
) -> NDArray[np.float64]:
    """(H, W) albedo averaged over each pixel; the plain wall around the print is white."""
    return render_plane_image(
        camera,
        view.R_camera_world,
        view.t_camera_world,
        texture,
        rendering.px_per_m,
        rendering.top_left_world_m,
        background=ALBEDO_WHITE,
        supersample=supersample,
    )


def _blur(image: NDArray[np.float64]) -> NDArray[np.float64]:
    return np.asarray(cv2.GaussianBlur(image, (0, 0), PSF_SIGMA_PX, borderType=cv2.BORDER_REFLECT))


def _angle_deg(a: NDArray[np.float64], b: NDArray[np.float64]) -> float:
    cos = float(a @ b / (np.linalg.norm(a) * np.linalg.norm(b)))
    return math.degrees(math.acos(min(1.0, max(-1.0, cos))))


def _rotation_angle_deg(R_a: NDArray[np.float64], R_b: NDArray[np.float64]) -> float:
    cos = (float(np.trace(R_a @ R_b.T)) - 1.0) / 2.0
    return math.degrees(math.acos(min(1.0, max(-1.0, cos))))


# ----------------------------------------------------------------------------- writing


def write_light(folder: Path) -> RID:
    """Write `light.ies` (1 degree steps) and return the RID read back from it."""
    theta_deg = np.arange(0.0, 91.0, 1.0)
    table = PhotometricTable(
        vertical_deg=theta_deg,
        horizontal_deg=np.zeros(1),
        candela=LED_CANDELA * led_profile(theta_deg)[None, :],
        source="light.ies",
        symmetry="axial",
        luminaire="lightcal sample LED behind a reflector (core 12 deg + skirt 40 deg)",
    )
    path = folder / "light.ies"
    write_ies(
        path,
        table,
        keywords={"TEST": "lightcal sample_data/make_sample_data.py", "MANUFAC": "lightcal"},
        digits=6,
    )
    return table_to_rid(read_ies(path))


def wall_views(variant: Variant, rng: np.random.Generator) -> list[View]:
    """Camera poses in front of the marker wall (exposure 1; set later)."""
    scene = SceneConfig(
        n_views=variant.n_views,
        distance_range_m=variant.distance_range_m,
        tilt_range_deg=SCENE_TILT_DEG,
        roll_range_deg=SCENE_ROLL_DEG,
        target_spread_m=SCENE_TARGET_SPREAD_M,
    )
    return sample_views(scene, rng)


def chessboard_views(camera: Camera, n: int, rng: np.random.Generator) -> list[View]:
    """Views of the chessboard tilted 20 - 45 degrees from all around, the board's centre
    placed on a 3 x 3 pattern over the frame so that the corners cover the whole image
    (the distortion is then interpolated, not extrapolated), the whole board in the image."""
    s = CHESSBOARD.square_length_m
    outline = CHESSBOARD.outline_world()[0]
    center = np.array([(CHESSBOARD.inner_x - 1) * s / 2, -(CHESSBOARD.inner_y - 1) * s / 2, 0.0])
    margin = camera.width / 60
    places = [(fu, fv) for fv in (0.3, 0.5, 0.7) for fu in (0.28, 0.5, 0.72)]
    views: list[View] = []
    attempts = 0
    while len(views) < n:
        attempts += 1
        if attempts > 100 * n:
            raise RuntimeError("no chessboard view fits in the image: change the layout")
        k = len(views)
        azimuth = 2 * math.pi * k / n + rng.uniform(-0.2, 0.2)
        tilt = math.radians(rng.uniform(20.0, 45.0))
        distance = rng.uniform(0.8, 1.05)
        direction = np.array(
            [math.sin(tilt) * math.cos(azimuth), math.sin(tilt) * math.sin(azimuth), math.cos(tilt)]
        )
        R, _ = look_at_pose(center + distance * direction, center, roll_rad=rng.uniform(-0.4, 0.4))
        # Turn the camera about its centre so that the board's centre appears at `place`.
        fu, fv = places[k % len(places)]
        target_px = [
            fu * camera.width + rng.uniform(-0.03, 0.03) * camera.width,
            fv * camera.height + rng.uniform(-0.03, 0.03) * camera.height,
        ]
        ray, _ = camera.rays_camera(np.array([target_px]))
        R = rotation_from_axis(ray[0] / np.linalg.norm(ray[0])) @ R
        view = View(R, -R @ (center + distance * direction))
        pixels, valid = camera.project(outline @ R.T + view.t_camera_world)
        inside = (
            valid.all()
            and np.all(pixels[:, 0] > margin)
            and np.all(pixels[:, 0] < camera.width - 1 - margin)
            and np.all(pixels[:, 1] > margin)
            and np.all(pixels[:, 1] < camera.height - 1 - margin)
        )
        if inside:
            views.append(view)
    return views


def write_chessboard_set(
    folder: Path, camera: Camera, variant: Variant, rng: np.random.Generator
) -> list[dict[str, Any]]:
    """8-bit views of the chessboard under room light; returns their truth entries."""
    rng_views, rng_noise = rng.spawn(2)
    views = chessboard_views(camera, variant.n_chessboard_views, rng_views)
    texture, rendering = _albedo_texture(CHESSBOARD)
    rows, cols = np.mgrid[0 : camera.height, 0 : camera.width].astype(np.float64)
    # Room light: brighter towards the top left, natural fall-off towards the corners.
    radius2 = ((cols - camera.cx) ** 2 + (rows - camera.cy) ** 2) / camera.fx**2
    gradient = 1.0 - 0.2 * cols / camera.width - 0.1 * rows / camera.height
    room = 0.85 * gradient / (1 + radius2) ** 2
    (folder / "chessboard").mkdir(exist_ok=True)
    truth = []
    for i, view in enumerate(views):
        albedo = _albedo_image(camera, view, texture, rendering, variant.supersample)
        linear = _blur(room * albedo)
        encoded = 255.0 * np.clip(linear, 0.0, 1.0) ** (1 / 2.2)
        encoded += rng_noise.normal(0.0, 1.0, encoded.shape)
        image = np.clip(np.rint(encoded), 0, 255).astype(np.uint8)
        name = f"chess_{i:02d}.png"
        atomic_write_bytes(folder / "chessboard" / name, _png_bytes(image, _exif(1 / 30, 400.0)))
        truth.append(
            {
                "name": name,
                "path": f"chessboard/{name}",
                "T_camera_world": {
                    "R": view.R_camera_world.tolist(),
                    "t": view.t_camera_world.tolist(),
                },
            }
        )
    log(f"wrote {len(views)} chessboard views")
    return truth


def write_wall_set(
    folder: Path,
    camera: Camera,
    light: Light,
    variant: Variant,
    rng: np.random.Generator,
) -> tuple[list[dict[str, Any]], float]:
    """16-bit views of the lit wall; returns their truth entries and the light's scale in DN
    at the exposure of the first view."""
    rng_views, rng_noise = rng.spawn(2)
    views = wall_views(variant, rng_views)
    sensor = SENSOR_BINNED_5
    usable = white_level(sensor) - sensor.black_level
    texture, rendering = _albedo_texture(MARKER_BOARD)
    rig = Rig((light.replace(scale=1.0),))

    radiance: list[NDArray[np.float64]] = []
    for view in views:
        started = time.perf_counter()
        irradiance = render_image(camera, view, rig, sensor=sensor.model)
        if np.ma.count_masked(irradiance):
            raise RuntimeError("a wall view sees past the wall: pick other poses")
        albedo = _albedo_image(camera, view, texture, rendering, variant.supersample)
        radiance.append(_blur(np.ma.getdata(irradiance) * albedo))
        seconds = time.perf_counter() - started
        log(f"rendered wall view {len(radiance)}/{len(views)} ({seconds:.1f} s)")

    # The LED's brightness (DN per unit of rendered signal per second) puts the brightest
    # view at CLOSEST_VIEW_FRACTION at 1/125 s; each view then gets the longest shutter time
    # that keeps its brightest pixel under BRIGHTEST_FRACTION.
    peaks = [float(r.max()) for r in radiance]
    dn_per_unit_s = CLOSEST_VIEW_FRACTION * usable / (max(peaks) / 125.0)
    times = []
    for peak in peaks:
        limit = BRIGHTEST_FRACTION * usable
        fitting = [t for t in SHUTTER_TIMES_S if dn_per_unit_s * t * peak <= limit]
        times.append(max(fitting) if fitting else SHUTTER_TIMES_S[0])

    (folder / "images").mkdir(exist_ok=True)
    truth = []
    for i, (view, signal, t) in enumerate(zip(views, radiance, times, strict=True)):
        dn, saturated = apply_sensor(dn_per_unit_s * t * signal, sensor, rng_noise)
        name = f"view_{i:02d}"
        atomic_write_bytes(folder / "images" / f"{name}.png", _png_bytes(dn, _exif(t, ISO)))
        truth.append(
            {
                "name": name,
                "path": f"images/{name}.png",
                "T_camera_world": {
                    "R": view.R_camera_world.tolist(),
                    "t": view.t_camera_world.tolist(),
                },
                "center_world_m": view.center_world.tolist(),
                **_view_geometry(view),
                "exposure_time_s": t,
                "exposure": t / times[0],
                "peak_signal_dn": float(dn_per_unit_s * t * signal.max()),
                "saturated_pixels": int(np.count_nonzero(saturated)),
            }
        )
        geometry = _view_geometry(view)
        log(
            f"wrote {name}.png: distance {geometry['distance_m']:.2f} m, tilt "
            f"{geometry['tilt_deg']:.1f} deg, 1/{1 / t:.0f} s, peak "
            f"{truth[-1]['peak_signal_dn']:.0f} DN above black"
        )
    return truth, dn_per_unit_s * times[0]


def run_pipeline(folder: Path) -> None:
    """`lightcal camera calibrate` then `lightcal init`, exactly as a user would run them."""
    steps = [
        [
            "camera",
            "calibrate",
            str(folder / "chessboard"),
            "--board",
            str(folder / "chessboard.yaml"),
            "--out",
            str(folder / "camera.yaml"),
        ],
        [
            "init",
            "--force",  # regenerating: replace the previous project and masks
            str(folder / "images"),
            "--camera",
            str(folder / "camera.yaml"),
            "--board",
            str(folder / "board.yaml"),
            "--light-ies",
            str(folder / "light.ies"),
            "--initial-position",
            *(str(v) for v in INITIAL_POSITION_M),
            "--initial-axis",
            *(str(v) for v in INITIAL_AXIS_CAMERA),
            "--black-level",
            f"{SENSOR_BINNED_5.black_level:g}",
            "--white-level",
            f"{white_level(SENSOR_BINNED_5):g}",
            "--out",
            str(folder / "project.json"),
        ],
    ]
    for argv in steps:
        log("lightcal " + " ".join(argv[:2]) + " ...")
        code = lightcal_main(argv)
        if code != 0:
            raise SystemExit(f"make_sample_data: lightcal {argv[0]} failed with exit code {code}")
    paper_selection(folder / "project.json")


def paper_selection(path: Path) -> None:
    """The sample solves the paper's way: 100 random pixels per image (`lightcal init`
    selects every pixel, binned to at most 300,000 super-pixels)."""
    from lightcal.io.project import SelectionSpec, load_project, save_project

    spec = load_project(path).spec
    save_project(spec.model_copy(update={"selection": SelectionSpec()}), path)


def check_calibration(folder: Path, truth: dict[str, Any]) -> None:
    """Run the calibration on the project and print every estimate's error against truth."""
    from lightcal.io.camera_file import read_camera
    from lightcal.io.project import load_project
    from lightcal.pipeline import calibrate_project

    camera = read_camera(folder / "camera.yaml")
    true = truth["camera"]
    log(
        f"intrinsics: fx {100 * (camera.fx / true['fx'] - 1):+.4f} %, "
        f"fy {100 * (camera.fy / true['fy'] - 1):+.4f} %, cx {camera.cx - true['cx']:+.3f} px, "
        f"cy {camera.cy - true['cy']:+.3f} px"
    )
    project = load_project(folder / "project.json")
    views = {v["name"]: v for v in truth["views"]}
    for name, view in zip(project.names, project.views, strict=True):
        R = np.array(views[name]["T_camera_world"]["R"])
        center = np.array(views[name]["center_world_m"])
        log(
            f"pose {name}: centre {1e3 * np.linalg.norm(view.center_world - center):.3f} mm, "
            f"rotation {_rotation_angle_deg(view.R_camera_world, R):.4f} deg"
        )
    started = time.perf_counter()
    _, _, result = calibrate_project(project)
    light = result.lights[0]
    true_light = truth["light"]
    position = np.array(light.pose.position_m)
    axis = np.array(light.pose.axis_camera)
    true_position = np.array(true_light["position_m"])
    true_axis = np.array(true_light["axis_camera"])
    log(
        f"calibration ({time.perf_counter() - started:.1f} s, converged {result.converged}): "
        f"position {1e3 * np.linalg.norm(position - true_position):.2f} mm off, "
        f"axis {_angle_deg(axis, true_axis):.3f} deg off (initial guess: "
        f"{1e3 * np.linalg.norm(np.subtract(INITIAL_POSITION_M, true_position)):.1f} mm, "
        f"{_angle_deg(np.array(INITIAL_AXIS_CAMERA), true_axis):.2f} deg)"
    )


def clean(folder: Path) -> None:
    """Remove what a previous run wrote (only the generated files)."""
    for sub in ("images", "chessboard", "masks"):
        for path in sorted((folder / sub).glob("*.png")):
            path.unlink()
    for name in GENERATED_FILES:
        (folder / name).unlink(missing_ok=True)


def generate(folder: Path, variant: Variant, *, calibrate: bool = True) -> None:
    """Write the whole set into `folder` (created if needed)."""
    folder.mkdir(parents=True, exist_ok=True)
    clean(folder)
    rng_wall, rng_chess = np.random.default_rng(SEED).spawn(2)
    camera = FULL_SENSOR.binned(variant.binning)
    write_board(MARKER_BOARD, folder / "board.yaml")
    write_board(CHESSBOARD, folder / "chessboard.yaml")
    rid = write_light(folder)
    light = Light(
        rid,
        np.array(LIGHT_POSITION_M),
        rotation_from_axis(np.array(LIGHT_AXIS_CAMERA) / np.linalg.norm(LIGHT_AXIS_CAMERA)),
        name="light",
    )
    chess_truth = write_chessboard_set(folder, camera, variant, rng_chess)
    view_truth, scale = write_wall_set(folder, camera, light, variant, rng_wall)
    gain, read_variance = noise_model(SENSOR_BINNED_5)
    truth = {
        "format": TRUTH_FORMAT,
        "version": 1,
        "lightcal_version": __version__,
        "seed": SEED,
        "variant": {
            "binning": variant.binning,
            "n_views": variant.n_views,
            "distance_range_m": list(variant.distance_range_m),
            "n_chessboard_views": variant.n_chessboard_views,
            "supersample": variant.supersample,
        },
        "camera_full_sensor": {
            "fx": FULL_SENSOR.fx,
            "fy": FULL_SENSOR.fy,
            "cx": FULL_SENSOR.cx,
            "cy": FULL_SENSOR.cy,
            "width": FULL_SENSOR.width,
            "height": FULL_SENSOR.height,
            "dist": FULL_SENSOR.dist_opencv.tolist(),
        },
        "camera": {
            "binning": variant.binning,
            "fx": camera.fx,
            "fy": camera.fy,
            "cx": camera.cx,
            "cy": camera.cy,
            "width": camera.width,
            "height": camera.height,
            "dist": camera.dist_opencv.tolist(),
        },
        "light": {
            "name": light.name,
            **describe_pose(light.R_camera_light, light.t_camera_light),
            "scale": scale,
            "scale_meaning": "DN above black per unit of rendered signal (sensor 'radiance') "
            "at the exposure of view_00",
            "rid": {
                "path": "light.ies",
                "profile": "(0.75 * 2^-(theta / 12 deg)^2 + 0.25 * 2^-(theta / 40 deg)^2) "
                "* cos(theta)^0.3",
                **describe_rid(rid),
            },
            "initial_guess": {
                "position_m": list(INITIAL_POSITION_M),
                "axis_camera": list(INITIAL_AXIS_CAMERA),
            },
        },
        "sensor": {
            "model": SENSOR_BINNED_5.model,
            "bit_depth": SENSOR_BINNED_5.bit_depth,
            "black_level_dn": SENSOR_BINNED_5.black_level,
            "white_level_dn": white_level(SENSOR_BINNED_5),
            "full_well_e": SENSOR_BINNED_5.full_well_e,
            "read_noise_e": SENSOR_BINNED_5.read_noise_e,
            "conversion_gain_dn_per_e": conversion_gain(SENSOR_BINNED_5),
            "noise_model": {"gain": gain, "read_variance": read_variance},
            "psf_sigma_px": PSF_SIGMA_PX,
            "f_number": F_NUMBER,
            "iso": ISO,
        },
        "wall": {
            "albedo_white": ALBEDO_WHITE,
            "albedo_black": ALBEDO_BLACK,
            "board": "board.yaml",
        },
        "views": view_truth,
        "chessboard_views": chess_truth,
    }
    atomic_write_text(folder / "truth.json", json.dumps(truth, indent=2) + "\n")
    run_pipeline(folder)
    if calibrate:
        check_calibration(folder, truth)
    size = sum(p.stat().st_size for p in folder.rglob("*") if p.is_file())
    log(f"done: {size / 1e6:.1f} MB in {folder}")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument(
        "--out", type=Path, default=Path(__file__).resolve().parent, help="folder (this one)"
    )
    parser.add_argument("--quick", action="store_true", help="a small, fast variant")
    parser.add_argument(
        "--skip-calibration", action="store_true", help="do not run the final calibration"
    )
    args = parser.parse_args(argv)
    # OpenCV's parallel loops (corner search, calibration) may sum in a different order
    # from run to run when the machine is busy: one thread makes every byte reproducible.
    threads = cv2.getNumThreads()
    cv2.setNumThreads(1)
    try:
        generate(args.out, QUICK if args.quick else FULL, calibrate=not args.skip_calibration)
    finally:
        cv2.setNumThreads(threads)
    return 0


if __name__ == "__main__":
    sys.exit(main())
