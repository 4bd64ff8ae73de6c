"""A synthetic "real-world" dataset: what a user's camera gives (`lightcal synth --real-world`).

Issue 25's rig as photographed, with a known truth and no project: the user's path is
`lightcal response` on the bracket, `lightcal init` on the photos, `lightcal calibrate`.

| file | content |
|---|---|
| `images/view_00.jpg` ... | the wall, light and room light on: 8-bit grey JPEGs, EXIF time |
| `bracket/bracket_0.jpg` ... | view 0 at `BRACKET_STOPS` stops, for `lightcal response` |
| `camera.yaml` | the intrinsics (OpenCV FileStorage) |
| `markers.yaml` | the board file (`type: markers`) of the four tags |
| `truth.json` | the light's pose, the views, how the photos were made |

The wall carries four AprilTags tag36h11 (ids 0-3, official orientation, `TAG_SIZE_M`
black squares) centred on the corners of a 1.2 x 0.7 m rectangle (`tag_layout`), printed
as albedo: `PRINT_ALBEDO` relative to the white wall, drawn by `MarkerLayout.render` and
seen through the camera by `lightcal.capture.plane_texture.render_plane_image` (3 x 3
sub-pixels). The light, beside the camera (`LIGHT_POSITION_M`), is a cos^m beam of
`RealWorldConfig.half_angle_deg` (7 degrees: a 14-degree beam) aimed up and to the right
of the optical axis (`LIGHT_AIM_CAMERA_M`). Every other view is placed so that the beam's
centre falls on the top-right tag (id 1), which it overexposes; the others put it
between the tags.

A pixel's linear value relative to white (code 255) is

    x = g albedo (k E + A),

E the renderer's irradiance of the light (`lightcal.core.render.render_image`, sensor model
`radiance`), k chosen so that the brightest white-wall value of all views is
`peak_exposure` (values above 1 clip), A the room light (`room_light`, uniform
irradiance: albedo times a constant) and g the exposure (1 for the photos, 2^stop for the
bracket). The sensor counts x `full_well_e` photo-electrons (Poisson) plus Gaussian read
noise, clips at white, and the camera encodes with the sRGB tone curve (IEC 61966-2-1),
rounds to 8 bits and writes a JPEG of quality `jpeg_quality` (Pillow, 4:4:4 grey).

Randomness: `np.random.default_rng(seed)` spawns one stream for the views and one for
the sensor noise, so a seed gives the same dataset.
"""

from __future__ import annotations

import io
import json
import math
import shutil
from collections.abc import Callable
from dataclasses import asdict, dataclass
from fractions import Fraction
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from lightcal import __version__
from lightcal.capture.marker_layout import LayoutMarker, MarkerLayout
from lightcal.capture.plane_texture import look_at_pose, render_plane_image
from lightcal.core.camera import Camera
from lightcal.core.light_axis import rotation_from_axis
from lightcal.core.pose import describe_pose
from lightcal.core.render import render_image
from lightcal.core.rid import CosPowerRID
from lightcal.core.scene import Light, Rig, View
from lightcal.errors import InputError
from lightcal.io.atomic import atomic_write_bytes, atomic_write_text
from lightcal.io.board_file import write_board
from lightcal.io.camera_file import read_camera, write_camera
from lightcal.synthetic.dataset_files import (
    CAMERA_NAME,
    IMAGES_DIR,
    TRUTH_FORMAT,
    TRUTH_NAME,
    camera_dict,
    check_target,
    make_staging,
    publish,
    view_geometry,
)

__all__ = [
    "BOARD_NAME",
    "BRACKET_DIR",
    "BRACKET_STOPS",
    "RealWorldConfig",
    "RealWorldDataset",
    "srgb_encode",
    "tag_layout",
    "write_real_world",
]

BOARD_NAME = "markers.yaml"
BRACKET_DIR = "bracket"
TAG = "DICT_APRILTAG_36h11"
TAG_SIZE_M = 0.15
"""Side of each tag's black square, metres."""
RECTANGLE_M = (1.2, 0.7)
"""The rectangle whose corners carry the tags' centres, metres."""
PRINT_ALBEDO = 0.05
"""The printed black relative to the white wall (and paper)."""
LIGHT_POSITION_M = (0.11, -0.03, 0.02)
"""The light in the camera frame: 11 cm right of the lens, 3 cm up, 2 cm forward."""
LIGHT_AIM_CAMERA_M = (0.32, -0.20, 1.8)
"""A camera-frame point on the light's axis: up and to the right of the optical axis."""
EXPOSURE_TIME_S = 1.0 / 60.0
"""The photos' exposure time (EXIF); the bracket's are 2^stop times it."""
BRACKET_STOPS = (-4, -3, -2, -1, 0, 1, 2, 3, 4)
"""The bracket's exposures, stops from the photos' (a camera's 9-shot bracket). With 5
shots 2 stops apart the fitted curve's wiggles put the light 3 mm from the truth; with
these, 1 mm."""
_DISTANCE_RANGE_M = (1.5, 2.3)
_MAX_TILT_DEG = 20.0
_MAX_ROLL_DEG = 12.0
_EDGE_MARGIN_PX = 12.0
"""Every tag with its white border lies this far inside the image."""
_TEXTURE_PX_PER_M = 1500.0

Progress = Callable[[str], None]


@dataclass(frozen=True)
class RealWorldConfig:
    """What `write_real_world` makes (module docstring).

    Attributes:
        width, height: The image size, pixels (focal length 0.75 width, mild distortion).
        n_views: Photos of the wall.
        seed: The seed of every random choice.
        half_angle_deg: The beam's half-intensity angle, degrees.
        peak_exposure: The brightest white-wall value of all views, relative to white.
        room_light: The room light's irradiance relative to white (the white wall at A).
        full_well_e: Photo-electrons at white.
        read_noise_e: Read noise, electrons.
        jpeg_quality: JPEG quality, 1-100.
    """

    width: int = 800
    height: int = 600
    n_views: int = 8
    seed: int = 0
    half_angle_deg: float = 7.0
    peak_exposure: float = 2.0
    room_light: float = 0.03
    full_well_e: float = 10000.0
    read_noise_e: float = 5.0
    jpeg_quality: int = 90

    def __post_init__(self) -> None:
        for name in ("width", "height"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int) or not 320 <= value <= 8000:
                raise InputError(name, f"expected 320 to 8000 pixels, got {value!r}")
        if not 3 <= self.n_views <= 50:
            raise InputError("n_views", f"expected 3 to 50 views, got {self.n_views!r}")
        if isinstance(self.seed, bool) or not isinstance(self.seed, int) or self.seed < 0:
            raise InputError("seed", f"expected an integer >= 0, got {self.seed!r}")
        if not 1 <= self.jpeg_quality <= 100:
            raise InputError("jpeg_quality", f"expected 1 to 100, got {self.jpeg_quality!r}")

    def camera(self) -> Camera:
        """The camera: f = 0.75 width, principal point at the centre, mild barrel."""
        f = 0.75 * self.width
        return Camera.from_params(
            fx=f,
            fy=f,
            cx=(self.width - 1) / 2,
            cy=(self.height - 1) / 2,
            width=self.width,
            height=self.height,
            dist=(-0.05, 0.01, 0.0, 0.0, 0.0),
        )

    def light(self) -> Light:
        """The true light (camera frame), scale 1."""
        position = np.array(LIGHT_POSITION_M)
        axis = np.array(LIGHT_AIM_CAMERA_M) - position
        return Light(
            CosPowerRID.from_half_angle(math.radians(self.half_angle_deg)),
            position,
            rotation_from_axis(axis / np.linalg.norm(axis)),
        )


@dataclass(frozen=True, eq=False)
class RealWorldDataset:
    """What `write_real_world` wrote: the folder, its photos, bracket, camera and board
    files, truth.json, the true views and the true light (scale: `k` of the module)."""

    folder: Path
    image_paths: list[Path]
    bracket_paths: list[Path]
    camera_path: Path
    board_path: Path
    truth_path: Path
    views: list[View]
    light: Light


def tag_layout() -> MarkerLayout:
    """The four tag36h11 (ids 0-3 from the top left, clockwise) at the rectangle's corners."""
    half_x, half_y = RECTANGLE_M[0] / 2, RECTANGLE_M[1] / 2
    corners = [(-half_x, half_y), (half_x, half_y), (half_x, -half_y), (-half_x, -half_y)]
    return MarkerLayout(tuple(LayoutMarker(TAG, k, c, TAG_SIZE_M) for k, c in enumerate(corners)))


def srgb_encode(linear: NDArray[np.float64]) -> NDArray[np.uint8]:
    """8-bit codes of linear values relative to white (clipped to [0, 1]), sRGB curve."""
    x = np.clip(linear, 0.0, 1.0)
    encoded = np.where(x <= 0.0031308, 12.92 * x, 1.055 * x ** (1.0 / 2.4) - 0.055)
    return np.rint(255.0 * encoded).astype(np.uint8)


def _beam_hit_world(light: Light, view: View) -> NDArray[np.float64]:
    """(3,) where the light's axis meets the wall z = 0 in a view (world frame)."""
    R = view.R_camera_world
    origin = view.center_world + R.T @ light.t_camera_light
    axis = R.T @ light.R_camera_light[:, 2]
    return np.asarray(origin - origin[2] / axis[2] * axis)


def _sees_every_tag(camera: Camera, view: View, layout: MarkerLayout) -> bool:
    corners = np.concatenate([m.square_world(border_modules=1.0) for m in layout.markers])
    pixels, valid = camera.project(corners @ view.R_camera_world.T + view.t_camera_world)
    if not valid.all():
        return False
    u, v = pixels[:, 0], pixels[:, 1]
    m = _EDGE_MARGIN_PX
    return bool(
        np.all((u >= m) & (u <= camera.width - 1 - m) & (v >= m) & (v <= camera.height - 1 - m))
    )


def sample_views(
    camera: Camera, light: Light, layout: MarkerLayout, n: int, rng: np.random.Generator
) -> list[View]:
    """`n` views that see every tag; even ones put the beam's centre on tag 1.

    Raises:
        InputError: No such view found in 2000 tries (an image too small for the tags).
    """
    tag1 = np.array(layout.markers[1].center_world_m)
    views: list[View] = []
    for i in range(n):
        for _ in range(2000):
            if i % 2 == 0:
                aim = tag1 + rng.uniform(-0.04, 0.04, 2)
            else:
                aim = np.array([rng.uniform(-0.25, 0.35), rng.uniform(-0.15, 0.2)])
            distance = rng.uniform(*_DISTANCE_RANGE_M)
            tilt = math.radians(rng.uniform(0.0, _MAX_TILT_DEG))
            azimuth = rng.uniform(0.0, 2.0 * math.pi)
            roll = math.radians(rng.uniform(-_MAX_ROLL_DEG, _MAX_ROLL_DEG))
            sin_tilt = math.sin(tilt)
            back = np.array(
                [sin_tilt * math.cos(azimuth), sin_tilt * math.sin(azimuth), math.cos(tilt)]
            )
            target = aim - np.array([0.25, 0.15])
            for _ in range(5):  # move the target until the beam falls on the aim
                center = np.array([*target, 0.0]) + distance * back
                R, t = look_at_pose(center, np.array([*target, 0.0]), roll_rad=roll)
                view = View(R, t, 1.0)
                target = target + aim - _beam_hit_world(light, view)[:2]
            if np.linalg.norm(_beam_hit_world(light, view)[:2] - aim) > 0.005:
                continue
            if _sees_every_tag(camera, view, layout):
                views.append(view)
                break
        else:
            raise InputError(
                "--width/--height",
                f"found no view of all four tags for view {i} in 2000 tries: expected a "
                "larger image",
            )
    return views


def _jpeg(codes: NDArray[np.uint8], quality: int, exposure_time_s: float) -> bytes:
    """A grey JPEG of `codes` with its exposure time in the EXIF (Pillow)."""
    from PIL import Image
    from PIL.TiffImagePlugin import IFDRational

    exif = Image.Exif()
    # ExposureTime (0x829a) in the Exif IFD (0x8769), a rational (1/60 s as 1/60).
    time_s = Fraction(exposure_time_s).limit_denominator(100_000)
    exif.get_ifd(0x8769)[0x829A] = IFDRational(time_s.numerator, time_s.denominator)
    buffer = io.BytesIO()
    Image.fromarray(codes, mode="L").save(buffer, format="JPEG", quality=quality, exif=exif)
    return buffer.getvalue()


def _photo(
    linear: NDArray[np.float64], config: RealWorldConfig, rng: np.random.Generator
) -> NDArray[np.uint8]:
    """8-bit codes of linear values relative to white: shot and read noise, clip, sRGB."""
    electrons = rng.poisson(np.clip(linear, 0.0, None) * config.full_well_e).astype(np.float64)
    electrons += rng.normal(0.0, config.read_noise_e, linear.shape)
    return srgb_encode(electrons / config.full_well_e)


def write_real_world(
    out_dir: str | Path,
    config: RealWorldConfig,
    *,
    force: bool = False,
    progress: Progress | None = None,
) -> RealWorldDataset:
    """Render and write the dataset (layout in the module docstring).

    Args:
        out_dir: The dataset folder: new, empty, or (with `force`) one whose dataset files
            are replaced (an earlier dataset's project.json is removed: it would describe
            other photos).
        config: What to make.
        force: Allow a non-empty `out_dir`.
        progress: Called with one line of text per written photo.

    Raises:
        InputError: `out_dir` is not empty (without `force`) or not a folder; an image
            too small to show every tag.
    """
    out_dir = Path(out_dir)
    occupied = check_target(out_dir, force=force)
    staging = make_staging(out_dir)
    try:
        written = _write_into(staging, config, progress)
        publish(staging, out_dir, occupied=occupied)
    except BaseException:
        shutil.rmtree(staging, ignore_errors=True)
        raise
    return RealWorldDataset(
        folder=out_dir,
        image_paths=[out_dir / p.relative_to(staging) for p in written.image_paths],
        bracket_paths=[out_dir / p.relative_to(staging) for p in written.bracket_paths],
        camera_path=out_dir / CAMERA_NAME,
        board_path=out_dir / BOARD_NAME,
        truth_path=out_dir / TRUTH_NAME,
        views=written.views,
        light=written.light,
    )


def _write_into(
    folder: Path, config: RealWorldConfig, progress: Progress | None
) -> RealWorldDataset:
    rng_views, rng_noise = np.random.default_rng(config.seed).spawn(2)
    write_camera(config.camera(), folder / CAMERA_NAME)
    camera = read_camera(folder / CAMERA_NAME)  # as init and calibrate will read it
    layout = tag_layout()
    write_board(layout, folder / BOARD_NAME)
    light = config.light()
    views = sample_views(camera, light, layout, config.n_views, rng_views)

    rendering = layout.render(_TEXTURE_PX_PER_M)
    texture = PRINT_ALBEDO + (1.0 - PRINT_ALBEDO) * rendering.image / 255.0
    beams, albedos = [], []
    for view in views:
        rendered = render_image(camera, view, Rig.single(light))
        if np.ma.count_masked(rendered):  # pragma: no cover - the views look at the wall
            raise InputError("views", "a view sees past the wall")
        beams.append(np.asarray(np.ma.getdata(rendered), dtype=np.float64))
        albedos.append(
            render_plane_image(
                camera,
                view.R_camera_world,
                view.t_camera_world,
                texture,
                rendering.px_per_m,
                rendering.top_left_world_m,
                background=1.0,
                supersample=3,
            )
        )
    k = config.peak_exposure / max(float(b.max()) for b in beams)
    light = light.replace(scale=k)
    digits = max(2, len(str(len(views) - 1)))
    image_paths, view_truth = [], []
    for i, (view, beam, albedo) in enumerate(zip(views, beams, albedos, strict=True)):
        name = f"view_{i:0{digits}d}"
        linear = albedo * (k * beam + config.room_light)
        codes = _photo(linear, config, rng_noise)
        path = folder / IMAGES_DIR / f"{name}.jpg"
        atomic_write_bytes(path, _jpeg(codes, config.jpeg_quality, EXPOSURE_TIME_S))
        image_paths.append(path)
        view_truth.append(_view_truth(name, view, light, layout, codes, camera))
        if progress is not None:
            done = view_truth[-1]
            progress(
                f"{name}.jpg {i + 1}/{len(views)}: distance {done['distance_m']:.2f} m, "
                f"beam centre {done['beam_center_tag_distance_m'] * 100:.0f} cm from tag "
                f"{done['nearest_tag']}, {done['clipped_pixels']} pixels at code 255"
            )
    bracket_paths, bracket_times = [], []
    (folder / BRACKET_DIR).mkdir()
    linear = albedos[0] * (k * beams[0] + config.room_light)
    for j, stop in enumerate(BRACKET_STOPS):
        time_s = EXPOSURE_TIME_S * 2.0**stop
        codes = _photo(2.0**stop * linear, config, rng_noise)
        path = folder / BRACKET_DIR / f"bracket_{j}.jpg"
        atomic_write_bytes(path, _jpeg(codes, config.jpeg_quality, time_s))
        bracket_paths.append(path)
        bracket_times.append(time_s)
    truth = _truth(config, camera, light, view_truth, bracket_paths, bracket_times, folder)
    atomic_write_text(folder / TRUTH_NAME, json.dumps(truth, indent=2) + "\n")
    return RealWorldDataset(
        folder=folder,
        image_paths=image_paths,
        bracket_paths=bracket_paths,
        camera_path=folder / CAMERA_NAME,
        board_path=folder / BOARD_NAME,
        truth_path=folder / TRUTH_NAME,
        views=views,
        light=light,
    )


def _view_truth(
    name: str,
    view: View,
    light: Light,
    layout: MarkerLayout,
    codes: NDArray[np.uint8],
    camera: Camera,
) -> dict[str, Any]:
    hit = _beam_hit_world(light, view)
    centres = np.array([m.center_world_m for m in layout.markers])
    distances = np.linalg.norm(centres - hit[:2], axis=1)
    nearest = int(np.argmin(distances))
    pixel, _ = camera.project((view.R_camera_world @ hit + view.t_camera_world)[None, :])
    return {
        "name": name,
        "path": f"{IMAGES_DIR}/{name}.jpg",
        "T_camera_world": {"R": view.R_camera_world.tolist(), "t": view.t_camera_world.tolist()},
        "center_world_m": view.center_world.tolist(),
        **view_geometry(view),
        "exposure_time_s": EXPOSURE_TIME_S,
        "beam_center_world_m": hit[:2].tolist(),
        "beam_center_pixel": pixel[0].tolist(),
        "nearest_tag": layout.markers[nearest].id,
        "beam_center_tag_distance_m": float(distances[nearest]),
        "clipped_pixels": int(np.count_nonzero(codes == 255)),
    }


def _truth(
    config: RealWorldConfig,
    camera: Camera,
    light: Light,
    view_truth: list[dict[str, Any]],
    bracket_paths: list[Path],
    bracket_times: list[float],
    folder: Path,
) -> dict[str, Any]:
    rid = light.rid
    assert isinstance(rid, CosPowerRID)
    return {
        "format": TRUTH_FORMAT,
        "version": 1,
        "preset": "real_world",
        "lightcal_version": __version__,
        "seed": config.seed,
        "camera": camera_dict(camera),
        "board": BOARD_NAME,
        "views": view_truth,
        "lights": [
            {
                "name": light.name,
                "scale": light.scale,
                "rid": {"type": "cos_power", "m": rid.m, "half_angle_deg": config.half_angle_deg},
                **describe_pose(light.R_camera_light, light.t_camera_light),
            }
        ],
        "bracket": {
            "paths": [p.relative_to(folder).as_posix() for p in bracket_paths],
            "exposure_times_s": bracket_times,
            "view": view_truth[0]["name"],
        },
        "imaging": {
            "tone_curve": "sRGB (IEC 61966-2-1) of the linear value relative to white, 8 bits",
            "jpeg_quality": config.jpeg_quality,
            "print_albedo": PRINT_ALBEDO,
            "room_light": config.room_light,
            "peak_exposure": config.peak_exposure,
            "full_well_e": config.full_well_e,
            "read_noise_e": config.read_noise_e,
            "light_scale": "x = albedo (scale E + room_light), E the radiance-model render",
        },
        "config": asdict(config),
    }
