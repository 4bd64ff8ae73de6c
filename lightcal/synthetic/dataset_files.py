"""The files of a synthetic dataset: the folder's layout, how it is put in place, and
what goes into its project (RID file, poses, initial guesses, camera, encoded images).

`lightcal.synthetic.dataset` writes a dataset with these; its docstring has the layout.
"""

from __future__ import annotations

import contextlib
import io
import json
import math
import re
import secrets
import shutil
from dataclasses import asdict
from pathlib import Path
from typing import Any, Literal

import cv2
import numpy as np
from numpy.typing import NDArray

from lightcal import __version__
from lightcal.core.camera import Camera
from lightcal.core.pose import describe_pose
from lightcal.core.rid import RID, CosPowerRID, GaussianRID, IsotropicRID
from lightcal.core.scene import Light, Rig, View
from lightcal.core.vignetting import RadialVignetting
from lightcal.errors import InputError
from lightcal.io.albedo_map_spec import AlbedoMapSpec
from lightcal.io.ies import write_ies
from lightcal.io.photometric_table import PhotometricTable, write_rid_csv
from lightcal.io.port_spec import PortSpec
from lightcal.io.project import InitialSpec, PoseSpec, RIDSpec, SelectionSpec, WallSpec
from lightcal.io.vignetting_file import load_vignetting, save_radial_vignetting
from lightcal.synthetic.scenes import (
    AZIMUTH_STEP_DEG,
    RigConfig,
    SensorConfig,
    conversion_gain,
    elliptical_beam_table,
    noise_model,
    symmetric_profile_table,
    white_level,
)

ImageFormat = Literal["png", "tiff"]

PROJECT_NAME = "project.json"
TRUTH_NAME = "truth.json"
CAMERA_NAME = "camera.yaml"
VIGNETTING_NAME = "vignetting.json"
IMAGES_DIR = "images"

_CANDELA_ON_AXIS = 1000.0
"""Intensity on the axis of the IES files written (the RID is relative: any value works)."""

IMAGE_SUFFIX = {"png": ".png", "tiff": ".tif"}
"""File suffix of each image format."""

DARK_SUFFIX = "_dark"
"""A view's light-off photo is `images/view_NN_dark.png` (`SynthConfig.dark_frames`)."""

_STALE_IMAGE = re.compile(r"view_\d+(_dark)?\.(png|tif|jpg)")

TRUTH_FORMAT = "lightcal.synth_truth"
"""The `format` tag of truth.json."""


# ------------------------------------------------------------------------- the folder


def check_target(out_dir: Path, *, force: bool) -> bool:
    """Whether `out_dir` already holds files (allowed only with `force`)."""
    if out_dir.exists() and not out_dir.is_dir():
        raise InputError(out_dir, "exists and is not a folder: expected a new or empty folder")
    for parent in out_dir.parents:  # the nearest existing one must be a folder
        if parent.exists():
            if not parent.is_dir():
                raise InputError(
                    out_dir,
                    f"{parent} is a file, not a folder: expected a new or empty folder",
                )
            break
    occupied = out_dir.is_dir() and any(out_dir.iterdir())
    if occupied and not force:
        raise InputError(
            out_dir,
            "the folder is not empty: expected a new or empty folder "
            "(--force replaces the dataset in it)",
        )
    return occupied


def make_staging(out_dir: Path) -> Path:
    parent = out_dir.parent
    try:
        parent.mkdir(parents=True, exist_ok=True)
        staging = parent / f".{out_dir.name}.{secrets.token_hex(6)}.partial"
        staging.mkdir()
        (staging / IMAGES_DIR).mkdir()
    except OSError as exc:
        # (the OS error names the staging folder, which the user never asked for)
        raise InputError(
            out_dir, f"cannot create the dataset folder in {parent}: {exc.strerror or exc}"
        ) from exc
    return staging


def publish(staging: Path, out_dir: Path, *, occupied: bool) -> None:
    """Move the finished dataset into `out_dir` (see lightcal.synthetic.dataset)."""
    if not occupied:
        if out_dir.is_dir():
            out_dir.rmdir()  # empty
        staging.rename(out_dir)
        return
    # Replace file by file; the old project goes first and the new one comes last, so a
    # loadable project.json always describes a complete dataset.
    with contextlib.suppress(FileNotFoundError):
        (out_dir / PROJECT_NAME).unlink()
    new_files = sorted(p.relative_to(staging) for p in staging.rglob("*") if p.is_file())
    (out_dir / IMAGES_DIR).mkdir(exist_ok=True)
    old_images = out_dir / IMAGES_DIR
    for p in old_images.iterdir():
        if _STALE_IMAGE.fullmatch(p.name) and Path(IMAGES_DIR, p.name) not in new_files:
            p.unlink()
    for rel in [*(r for r in new_files if r != Path(PROJECT_NAME)), Path(PROJECT_NAME)]:
        if not (staging / rel).exists():  # a dataset without a project (--real-world)
            continue
        (out_dir / rel).parent.mkdir(parents=True, exist_ok=True)
        (staging / rel).replace(out_dir / rel)
    shutil.rmtree(staging)


# --------------------------------------------------------------------------- contents


def rid_file(config: RigConfig, folder: Path) -> RIDSpec:
    """Write the lights' profile file when the model is a table; the project's RID entry."""
    if config.model == "isotropic":
        return RIDSpec(type="isotropic")
    if config.model == "cos_power":
        rid = CosPowerRID.from_half_angle(math.radians(config.half_angle_deg))
        return RIDSpec(type="cos_power", m=rid.m)
    if config.model == "gaussian":
        g = GaussianRID.from_half_angle(math.radians(config.half_angle_deg))
        return RIDSpec(type="gaussian", sigma_deg=math.degrees(g.sigma_rad))
    if config.model == "table":
        theta_deg, values = symmetric_profile_table(config.half_angle_deg)
        write_rid_csv(folder / "rid.csv", theta_deg, values)
        return RIDSpec(type="table", path="rid.csv")
    path = folder / "light.ies"
    if config.model == "ies":
        theta_deg, values = symmetric_profile_table(config.half_angle_deg)
        table = PhotometricTable(
            vertical_deg=theta_deg,
            horizontal_deg=np.zeros(1),
            candela=_CANDELA_ON_AXIS * values[None, :],
            source=str(path),
            symmetry="axial",
            luminaire="lightcal synth: rotationally symmetric LED profile",
        )
    else:
        theta_deg, phi_deg, values2 = elliptical_beam_table(
            config.half_angle_deg, aspect=config.beam_aspect, skew=config.beam_skew
        )
        # Type C: the C-plane at angle C is the light-frame azimuth phi = -C (mod 360).
        n = phi_deg.size
        rows = [(-k) % n for k in range(n)]
        table = PhotometricTable(
            vertical_deg=theta_deg,
            horizontal_deg=np.arange(n, dtype=np.float64) * AZIMUTH_STEP_DEG,
            candela=_CANDELA_ON_AXIS * values2[rows],
            source=str(path),
            symmetry="none",
            luminaire="lightcal synth: lopsided elliptical beam",
        )
    write_ies(path, table)
    return RIDSpec(type="ies", path="light.ies")


def pose_spec(view: View, covariance: np.ndarray | None = None) -> PoseSpec:
    return PoseSpec(
        R=view.R_camera_world.tolist(),
        t=view.t_camera_world.tolist(),
        covariance=None if covariance is None else covariance.tolist(),
    )


def initial_spec(light: Light) -> InitialSpec:
    position = light.t_camera_light.tolist()
    if isinstance(light.rid, IsotropicRID):
        return InitialSpec(position_m=position)
    if light.rid.symmetric:
        return InitialSpec(position_m=position, axis_camera=light.axis_camera.tolist())
    return InitialSpec(position_m=position, R_camera_light=light.R_camera_light.tolist())


def pose_kind(rid: RID) -> Literal["auto", "isotropic"]:
    return "isotropic" if isinstance(rid, IsotropicRID) else "auto"


def encode_image(dn: NDArray[np.uint16], image_format: ImageFormat) -> bytes:
    """The file's bytes of (H, W) grey or (H, W, 3) colour values in OpenCV's B, G, R order
    (a PNG stores them so; a TIFF as R, G, B samples, photometric RGB)."""
    if image_format == "png":
        ok, encoded = cv2.imencode(".png", dn)
        if not ok:  # pragma: no cover - OpenCV always encodes uint16 PNG
            raise InputError("image", "OpenCV could not encode a 16-bit PNG")
        return encoded.tobytes()
    import tifffile

    buffer = io.BytesIO()
    if dn.ndim == 3:
        tifffile.imwrite(buffer, np.ascontiguousarray(dn[..., ::-1]), photometric="rgb")
    else:
        tifffile.imwrite(buffer, dn, photometric="minisblack")
    return buffer.getvalue()


def view_geometry(view: View) -> dict[str, float]:
    """Distance along the optical axis to the wall and tilt from its normal."""
    axis = view.R_camera_world[2]  # optical axis in the world frame
    center = view.center_world
    return {
        "distance_m": float(-center[2] / axis[2]),
        "tilt_deg": math.degrees(math.acos(min(1.0, max(-1.0, float(-axis[2]))))),
    }


def camera_dict(camera: Camera) -> dict[str, Any]:
    return {
        "path": CAMERA_NAME,
        "fx": camera.fx,
        "fy": camera.fy,
        "cx": camera.cx,
        "cy": camera.cy,
        "skew": camera.skew,
        "width": camera.width,
        "height": camera.height,
        "dist": camera.dist_opencv.tolist(),
    }


def vignetting_file(
    sensor: SensorConfig, camera: Camera, folder: Path
) -> tuple[str | None, NDArray[np.float64] | None]:
    """Write the "map" model's fall-off file and read it back.

    Returns:
        Its path relative to `folder` and its (H, W) map; (None, None) for other models.
    """
    if sensor.vignetting_coeffs is None:
        return None, None
    model = RadialVignetting.centered(
        np.array(sensor.vignetting_coeffs), width=camera.width, height=camera.height
    )
    save_radial_vignetting(folder / VIGNETTING_NAME, model)
    vignetting = load_vignetting(folder / VIGNETTING_NAME, width=camera.width, height=camera.height)
    if not np.all(vignetting > 0.0):
        raise InputError(
            "vignetting_coeffs",
            f"the fall-off reaches {float(vignetting.min()):.3g} inside the image; "
            "expected V > 0 everywhere",
        )
    return VIGNETTING_NAME, vignetting


def sensor_truth(sensor: SensorConfig, vignetting_rel: str | None) -> dict[str, Any]:
    """The "sensor" entry of truth.json."""
    gain, read_variance = noise_model(sensor)
    return {
        "model": sensor.model,
        "bit_depth": sensor.bit_depth,
        "black_level_dn": sensor.black_level,
        "white_level_dn": white_level(sensor),
        "full_well_e": sensor.full_well_e,
        "read_noise_e": sensor.read_noise_e,
        "conversion_gain_dn_per_e": conversion_gain(sensor),
        "noise": sensor.noise,
        "noise_model": {"gain": gain, "read_variance": read_variance},
        "exposure_target": sensor.exposure_target,
        "vignetting_coeffs": (
            None if sensor.vignetting_coeffs is None else list(sensor.vignetting_coeffs)
        ),
        "vignetting_path": vignetting_rel,
    }


def read_truth(path: str | Path) -> dict[str, Any]:
    """The content of a truth.json (a plain dictionary, format checked)."""
    p = Path(path)
    try:
        data = json.loads(p.read_text(encoding="utf-8"))
    except FileNotFoundError as exc:
        raise InputError(p, "file not found: expected a lightcal synth truth.json") from exc
    except json.JSONDecodeError as exc:
        raise InputError(p, f"not valid JSON: {exc.msg}", line=exc.lineno) from exc
    if not isinstance(data, dict) or data.get("format") != TRUTH_FORMAT:
        raise InputError(p, f"expected a truth file with format {TRUTH_FORMAT!r}")
    return data


def truth_document(
    config: Any,
    *,
    camera: Camera,
    vignetting_rel: str | None,
    view_truth: list[dict[str, Any]],
    departure_truth: dict[str, Any],
    rig: Rig,
    relative_rig: Rig,
    initial: list[Light],
    rid_truth: dict[str, Any],
) -> dict[str, Any]:
    """The content of truth.json (`lightcal.synthetic.dataset`).

    Args:
        config: The dataset's `SynthConfig`.
        camera: The camera as read back.
        vignetting_rel: The fall-off map's path in the dataset, or None.
        view_truth: One entry per view.
        departure_truth: The departures' parameters (empty: none).
        rig: The true lights, scales in DN.
        relative_rig: The same at relative scale.
        initial: The project's initial guesses.
        rid_truth: The true profile's description.
    """
    return {
        "format": TRUTH_FORMAT,
        "version": 1,
        "lightcal_version": __version__,
        "seed": config.seed,
        "camera": camera_dict(camera),
        "sensor": sensor_truth(config.sensor, vignetting_rel),
        "views": view_truth,
        "wall": config.wall.describe(),
        **({"departures": departure_truth} if departure_truth else {}),
        "lights": [
            {
                "name": light.name,
                "scale": light.scale,
                "relative_scale": relative.scale,
                "pose_kind": "isotropic"
                if isinstance(light.rid, IsotropicRID)
                else ("symmetric" if light.rid.symmetric else "general"),
                "rid": rid_truth,
                **describe_pose(light.R_camera_light, light.t_camera_light),
                "initial": describe_pose(initial[j].R_camera_light, initial[j].t_camera_light),
            }
            for j, (light, relative) in enumerate(zip(rig.lights, relative_rig.lights, strict=True))
        ],
        "options": {
            "pose_noise_mm": config.pose_noise_m * 1000.0,
            "pose_noise_deg": config.pose_noise_deg,
            "init_offset_m": config.init_offset_m,
            "init_offset_deg": config.init_offset_deg,
            "image_format": config.image_format,
        },
        "config": {
            "scene": asdict(config.scene),
            "rig": asdict(config.rig),
            "sensor": asdict(config.sensor),
        },
    }


def declared_pose_covariance(noise_m: float, noise_deg: float) -> NDArray[np.float64] | None:
    """(6, 6) the covariance the project declares for each measured pose (rotation
    perturbation in rad^2, then the centre in m^2), or None without pose noise."""
    if noise_m == 0.0 and noise_deg == 0.0:
        return None
    return np.diag([math.radians(noise_deg) ** 2] * 3 + [noise_m**2] * 3)


ALBEDO_MAP_PIXELS = 9600
"""About this many super-pixels an image in a project that declares an albedo map."""


def declared_wall(cam: Camera, *, albedo_map: bool) -> dict[str, Any]:
    """The project's `wall` and `selection` for camera `cam` (ProjectFile fields; {}: the
    defaults): with `albedo_map`, the map declared and a dense selection binned to about
    `ALBEDO_MAP_PIXELS` super-pixels an image."""
    if not albedo_map:
        return {}
    binning = max(1, math.floor(math.sqrt(cam.width * cam.height / ALBEDO_MAP_PIXELS)))
    return {
        "wall": WallSpec(albedo_map=AlbedoMapSpec()),
        "selection": SelectionSpec(strategy="all", binning=binning),
    }


def declared_port(config: Any, *, light: bool = False) -> PortSpec | None:
    """The project's `camera.port` of a `SynthConfig`: its `port` departure when
    `declare_port`, else None (the data seen through a port nobody declared); with
    `light`, each `lights[i].port`: its `light_port` departure when `declare_light_port`."""
    port = config.departures.light_port if light else config.departures.port
    if not (config.declare_light_port if light else config.declare_port) or port is None:
        return None
    d_mm, t_mm, n_g, n_w = (float(v) for v in port)
    return PortSpec(distance_mm=d_mm, thickness_mm=t_mm, glass_index=n_g, water_index=n_w)
