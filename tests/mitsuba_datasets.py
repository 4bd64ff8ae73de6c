"""lightcal projects rendered by Mitsuba 3: ground truth lightcal's own model did not make.

`write_mitsuba_dataset(out_dir, scenario)` writes a folder that looks exactly like a
`lightcal synth --light table` dataset (the same views, exposures, rig, pose noise,
pose covariances, sensor, initial guess and file layout, drawn from the same seeded
streams as `lightcal.synthetic.dataset`), except that the images come from Mitsuba 3
and the scene departs from lightcal's model in one named way (issue 24: a reported
sigma must cover the real error, a fit test must name the real cause). The scenarios,
with the key of truth.json's `departures` (`lightcal synth`'s names and fields where it
has the departure: `lightcal.synthetic.departure_truth`):

- `clean`: a Lambertian wall (albedo 0.8), direct light only (`{}`).
- `painted`: a `roughplastic` wall (GGX alpha 0.25, ior 1.5, diffuse 0.8); the project
  says `wall: {model: auto}` (`painted`).
- `ambient`: plus room light, a `constant` environment giving the wall a uniform
  radiance of 5 % of the beam's peak in the image whose peak is the lower median
  (`ambient`, as `lightcal synth --ambient 0.05`).
- `vignetting`: the radiance times V = 1 - 0.25 r^2 + 0.05 r^4 before the sensor, r as
  in `RadialVignetting` (1 at the corners); the project still says `radiance`
  (`undeclared_vignetting`).
- `interreflection`: a ceiling and a side wall (diffuse, albedo 0.8, 0.5 m deep, meeting
  the wall at right angles 0.7 m from the median beam centre), the `path` integrator
  (max_depth 5: up to 3 bounces); masks exclude the pixels that see them, or wall the
  light cannot reach (`interreflection`).
- `bowed`: the wall bulges: z = 5 mm max(0, 1 - r^2 / (1 m)^2), r from where the views
  look, rendered as the cap of a sphere of radius 100 m (within 1.3e-7 m of that
  paraboloid; `_dome`) (`bow`, as `--bow-mm 5`).
- `albedo`: the albedo 0.8 (1 + 0.1 t(x, y)), t the smooth seeded field of
  `lightcal.synthetic.texture` (6 waves of 20-60 cm), a 4 mm bitmap texture
  (`albedo_texture`).
- `medium`: clear water between rig and wall, absorption only, 0.2 /m: each value times
  exp(-0.2 (d_light + d_camera)) (`attenuation`, as `--attenuation 0.2`).
- `murky_albedo`: `albedo`'s texture in water that also scatters (sigma_t 0.2 /m,
  sigma_s 0.16 /m, Henyey-Greenstein g 0.6): `medium`'s wall plus the veil, Mitsuba's
  `volpath` of the water in front of a black wall (`murky_veil`) (`albedo_texture`,
  `attenuation`, `backscatter` with beta = sigma_s pi / 0.8, as `--backscatter 0.63
  --phase-g 0.6`).
- `rgb_water`: `medium`'s water absorbing per colour channel, c = (0.40, 0.12, 0.06) /m
  for (R, G, B) (red absorbs most, as in ocean water), a Lambertian wall of albedo
  (0.8, 0.75, 0.6): a colour dataset, 3-channel 16-bit PNG (R, G, B as OpenCV's B, G, R
  planes), channel k's value times exp(-c_k (d_light + d_camera)) (`attenuation` with
  `coefficient_per_m` a list in the order of its `channels`). Its light has a scale per
  channel: truth.json's `lights[0].scale` is the list (R, G, B) and `lights[0].channels`
  their names. With `declare=True` the project says `sensor.channels: [R, G, B]` and
  `medium: {attenuation_per_m: [0.2, 0.2, 0.2], estimate: [attenuation_per_m]}` (the
  joint per-channel solve); without, it reads one `sensor.channel` (`auto`: the
  luminance, a mix of three waters that is not lightcal's model). 12 views
  of 480 x 320 render in 0.4 s (1.2-1.7 s written) with `llvm_ad_rgb`.

Frames follow docs/conventions.md; Mitsuba's camera is OpenCV's turned half a turn about
z (`tests/mitsuba_peer.py`): T_world_mitsuba = T_world_camera diag(-1, -1, 1, 1). The
camera has no distortion (Mitsuba's `perspective` has none), f = 0.9 x width, the
principal point at the image centre; a box pixel filter, so a Mitsuba pixel is the mean
radiance over its square, as lightcal's footprint is.

**The light** is Mitsuba's `spot` with a smooth profile: a bitmap `texture` (1024^2,
bilinear) of f(theta) = cos(theta)^m (m: f(30 deg) = 1/2) times a C2 taper from 1 at 45
deg to 0 at 55 deg, cutoff 60 deg (the spot's own linear fall-off between its beam width,
59.99 deg, and the cutoff lies where f is already 0). lightcal gets the profile read back
from Mitsuba (`spot_profile`: the emitter's intensity 1 m away, direction by direction,
the mean of 8 azimuths) as `rid.csv`, a table every 0.5 deg from 0 to 60 deg, as
`lightcal synth --light table` writes it. The read-back agrees with f to 1.4e-5.

**The scale.** The spot's intensity is 1 (W/sr), so Mitsuba's radiance is
L = k_d B E_rel, E_rel lightcal's irradiance per unit intensity (`radiance` model) and
k_d the wall's diffuse level (albedo / pi for a Lambertian wall, docs/model.md for
`roughplastic`). The value written, above the black level and before noise, is
k_m g_i L, g_i the image's relative exposure and k_m (`mitsuba.dn_per_radiance` in
truth.json) the factor that puts the brightest pixel of the dataset at 70 % of the
sensor's range (`SensorConfig.exposure_target`). The truth's light `scale` is therefore
k_m k_d (k_d of the base albedo for `albedo`; without the water's transmittance for
`medium`; per channel, k_m k_d,k with k_d,k = albedo_k / pi, for `rgb_water`, whose
brightest pixel is that of all channels): lightcal's `render_image` of the truth equals
the image minus the black level for `clean`.

**The sensor**: "realistic" is `lightcal synth`'s default (14 bits, 20000 e- full well,
3 e- read noise, shot noise; the project declares that noise model); "clean" has no
shot or read noise and 16 bits (values only rounded). A colour image's channels go
through the sensor one after the other (R, G, B: independent noise from the same stream).

**Monte Carlo noise.** The `direct` integrator with a point (delta) light is exact up to
the pixel's area integration: with 16 stratified (`multijitter`) samples per pixel its
relative noise is 3e-5, far below the realistic sensor's shot noise (0.85 % at the peak).
`interreflection`'s bounce light (the `path` render minus the `direct` render of the
same scene) has 1.0-1.2 % relative noise per pixel at 192 samples; it is smooth, so it is
blurred (`_smooth`: a Gaussian of `INDIRECT_SMOOTHING_PX` over the unmasked pixels),
which leaves 0.15-0.18 % (two seeds of 480 x 320 views compared) and a bias under 0.1 %
beside the masks (against 4096 samples). The bounce light is 10-12 % of the signal
(median over the lit pixels), up to 23-42 % (99th percentile) near the corner.
The environment of `ambient` is rendered on its own with BSDF
sampling only (each cosine-sampled direction sees the constant sky: exact) and added:
light is additive, and one render with both emitters would choose between them per
sample. `medium`: Mitsuba's `volpath` estimates the camera segment's transmittance by
free-flight sampling (a path dies or survives), 5 % relative noise per pixel at 64
samples; the images are the `direct` render times the exact transmittance of a
homogeneous absorbing medium, which `tests/test_mitsuba_datasets.py` checks against
`volpath` (`volpath_images`: 0.9998 +- 0.0003 at 1024 samples); `rgb_water`'s per
channel, a Mitsuba medium whose sigma_t is an RGB value (`volpath_channels`,
`tests/test_rgb_water_mitsuba.py`: within 5e-4 per channel, +- 2e-4, at 4096 samples).
`murky_albedo`'s veil (a third of the value in most views, three quarters beside the
light) is `volpath`'s on cells of 16 x 16 pixels at 480 x 320 (`murky_veil`: 0.07 % noise
in most cells, up to 1 % beside the light), 4-12 s a view; `volpath` of the whole scene,
the textured wall in the scattering water, agrees with wall + veil (0.99969 +- 0.00011 on
80 x 60).

**Variant**: `llvm_ad_rgb` where it runs (needs libLLVM >= 16: Debian's libLLVM 15
aborts in Dr.Jit's code generation; `apt-get install libllvm19` fixes that), else
`scalar_rgb`; checked once per process in a subprocess (an LLVM failure aborts the
process), or set by `LIGHTCAL_MITSUBA_VARIANT`. On 2 cores, quiet, a 12-view 480 x 320
dataset renders in 0.4-0.7 s with `llvm_ad_rgb` (`clean`: 5.2 s with `scalar_rgb`), an
`interreflection` view in 2.3 s (9.4 s): the eight scenarios before `murky_albedo` in
31 s (the first time, when Dr.Jit compiles its kernels, and under load: 70-100 s);
`murky_albedo` in 80-100 s under load, its veil's `volpath`.

Caching: `cached_dataset(root, scenario, ...)` reuses a folder written with the same
options (the options are kept in truth.json's `mitsuba.key`); `session_dataset` keeps one
dataset per option set per test session under pytest's `tmp_path_factory`.
"""

from __future__ import annotations

import functools
import json
import math
import os
import shutil
import subprocess
import sys
import time
from dataclasses import asdict, dataclass, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal, get_args

import cv2
import numpy as np
from numpy.typing import NDArray

from lightcal import __version__
from lightcal.core.camera import Camera
from lightcal.core.footprint import pixel_footprints
from lightcal.core.medium import AIR, Medium
from lightcal.core.pose import describe_pose
from lightcal.core.scene import Light, View
from lightcal.core.vignetting import RadialVignetting
from lightcal.core.wall import (
    LAMBERTIAN,
    PlasticWall,
    WallReflectance,
    internal_reflectance,
    rough_transmittance,
)
from lightcal.io.atomic import atomic_write_bytes, atomic_write_text
from lightcal.io.camera_file import read_camera, write_camera
from lightcal.io.photometric_table import write_rid_csv
from lightcal.io.project import (
    CameraSpec,
    ExposureSpec,
    ImageSpec,
    LightSpec,
    NoiseSpec,
    ProjectFile,
    RIDSpec,
    SelectionSpec,
    SensorSpec,
    SolverSpec,
    WallSpec,
    build_rid,
    load_project,
    save_project,
)
from lightcal.synthetic.dataset import TRUTH_FORMAT
from lightcal.synthetic.dataset_files import (
    CAMERA_NAME,
    IMAGES_DIR,
    PROJECT_NAME,
    TRUTH_NAME,
    camera_dict,
    check_target,
    encode_image,
    initial_spec,
    make_staging,
    pose_kind,
    pose_spec,
    publish,
    view_geometry,
)
from lightcal.synthetic.scenes import (
    RigConfig,
    SceneConfig,
    SensorConfig,
    apply_sensor,
    conversion_gain,
    describe_rid,
    initial_guess,
    noise_model,
    perturb_view,
    sample_exposure_times,
    sample_rig,
    sample_views,
    white_level,
)
from lightcal.synthetic.texture import AlbedoTexture, sample_albedo_texture

if TYPE_CHECKING:
    import pytest

Scenario = Literal[
    "clean",
    "painted",
    "ambient",
    "vignetting",
    "interreflection",
    "bowed",
    "albedo",
    "medium",
    "murky_albedo",
    "rgb_water",
]
SensorKind = Literal["realistic", "clean"]

SCENARIOS: tuple[str, ...] = get_args(Scenario)
"""Every scenario, in the order of the module docstring's list."""

ALBEDO = 0.8
"""Albedo of the white (Lambertian) surfaces."""

RID_NAME = "rid.csv"
MASKS_DIR = "masks"

SPOT_CUTOFF_DEG = 60.0
PROFILE_HALF_ANGLE_DEG = 30.0
PROFILE_TAPER_DEG = (45.0, 55.0)
PROFILE_STEP_DEG = 0.5
_TEXTURE_SIZE = 1024

PLASTIC = {"roughness": 0.25, "ior": 1.5, "albedo": 0.8}
AMBIENT_FRACTION = 0.05
VIGNETTING_COEFFS = (-0.25, 0.05)
INTERREFLECTION = {"distance_m": 0.7, "depth_m": 0.5, "albedo": ALBEDO, "max_depth": 5}
BOW = {"depth_mm": 5.0, "radius_m": 1.0}
ALBEDO_AMPLITUDE = 0.1
ATTENUATION_PER_M = 0.2
MURKY = {"scattering_albedo": 0.8, "phase_g": 0.6}
"""`murky_albedo`'s water: sigma_s = 0.8 sigma_t (sigma_t = `ATTENUATION_PER_M`), HG g."""
RGB_CHANNELS = ("R", "G", "B")
"""`rgb_water`'s channels, in the order of its per-channel lists."""
RGB_ATTENUATION_PER_M = (0.40, 0.12, 0.06)
"""`rgb_water`'s c per channel (R, G, B), 1/m: red absorbs most, as in ocean water."""
RGB_ALBEDO = (0.8, 0.75, 0.6)
"""`rgb_water`'s wall albedo per channel (R, G, B): the light's scale differs per channel."""
RGB_DECLARED_START_PER_M = 0.2
"""The c every channel starts from when `rgb_water` declares its medium (`declare`)."""
VEIL_CELLS = 20
"""`murky_albedo`'s veil is rendered on square cells, VEIL_CELLS across the image's shorter
side (16 pixels a cell at 480 x 320)."""
VEIL_SPP_PER_PIXEL = 256
"""Samples of the veil per pixel of the image (65536 a cell of 16 x 16 pixels)."""

DEFAULT_SPP: dict[str, int] = {name: 16 for name in SCENARIOS} | {"interreflection": 192}
"""Samples per pixel when `spp` is not given."""

INDIRECT_SMOOTHING_PX = 2.0
"""sigma of the Gaussian that smooths `interreflection`'s bounce light (pixels)."""

_SPP_PER_PASS = 64
"""Samples per pixel of one Mitsuba render call (several are averaged: memory of llvm)."""

_DEPARTURES: dict[str, dict[str, dict[str, Any]]] = {
    "clean": {},
    "painted": {
        "painted": {
            "model": "roughplastic (GGX)",
            **PLASTIC,
            "declared_wall": "auto",
            "formula": "Mitsuba's roughplastic: diffuse base under a rough dielectric coat",
        }
    },
    "ambient": {"ambient": {"fraction": AMBIENT_FRACTION}},
    "vignetting": {
        "undeclared_vignetting": {
            "coeffs": list(VIGNETTING_COEFFS),
            "formula": "1 + k1 r^2 + k2 r^4, r = |(u, v) - center_px| / norm_radius_px",
            "declared_sensor": "radiance",
        }
    },
    "interreflection": {"interreflection": dict(INTERREFLECTION)},
    "bowed": {
        "bow": {
            "depth_mm": BOW["depth_mm"],
            "radius_m": BOW["radius_m"],
            "shape": "bulge towards the cameras",
            "formula": "z = depth * max(0, 1 - ((x - x0)^2 + (y - y0)^2) / radius^2)",
        }
    },
    "albedo": {"albedo_texture": {"amplitude": ALBEDO_AMPLITUDE}},
    "medium": {
        "attenuation": {
            "coefficient_per_m": ATTENUATION_PER_M,
            "formula": "each light's value * exp(-coefficient * (d_light + d_camera))",
        }
    },
}
_DEPARTURES["murky_albedo"] = {
    **_DEPARTURES["albedo"],
    **_DEPARTURES["medium"],
    "backscatter": {
        "beta_per_m": MURKY["scattering_albedo"] * ATTENUATION_PER_M * math.pi / ALBEDO,
        "phase_g": MURKY["phase_g"],
        "scattering_per_m": MURKY["scattering_albedo"] * ATTENUATION_PER_M,
        "formula": "beta = sigma_s pi / base albedo; Mitsuba's volpath, single scattering",
    },
}
_DEPARTURES["rgb_water"] = {
    "attenuation": {
        "coefficient_per_m": list(RGB_ATTENUATION_PER_M),
        "channels": list(RGB_CHANNELS),
        "formula": "channel k's value * exp(-coefficient_per_m[k] * (d_light + d_camera))",
    }
}
"""truth.json's `departures` of each scenario, in `lightcal synth`'s names and fields
(`lightcal.synthetic.departure_truth`) where it has the departure; `painted` and
`interreflection` are Mitsuba's only."""


def departures(scenario: str) -> dict[str, dict[str, Any]]:
    """The truth's `departures` of a scenario (before the per-dataset details)."""
    _check_scenario(scenario)
    return json.loads(json.dumps(_DEPARTURES[scenario]))


def _check_scenario(scenario: str) -> None:
    if scenario not in SCENARIOS:
        raise ValueError(f"scenario: expected one of {', '.join(SCENARIOS)}, got {scenario!r}")


# ------------------------------------------------------------------------------ Mitsuba

_VARIANT: str | None = None

_PROBE = """
import mitsuba as mi
mi.set_variant("llvm_ad_rgb")
for integrator in ({"type": "direct"}, {"type": "path", "max_depth": 4}):
    scene = mi.load_dict({
        "type": "scene",
        "integrator": integrator,
        "sensor": {"type": "perspective", "to_world": mi.ScalarTransform4f().translate([0, 0, 2]),
                   "film": {"type": "hdrfilm", "width": 8, "height": 8},
                   "sampler": {"type": "multijitter", "sample_count": 4}},
        "wall": {"type": "rectangle", "bsdf": {"type": "roughplastic"}},
        "box": {"type": "cube",
                "to_world": mi.ScalarTransform4f().translate([0, 0.5, 1]).scale(0.2),
                "bsdf": {"type": "twosided", "bsdf": {"type": "diffuse"}}},
        "light": {"type": "spot", "to_world": mi.ScalarTransform4f().translate([0.1, 0, 1.5])},
        "sky": {"type": "constant", "radiance": 0.1},
    })
    mi.render(scene)
"""


def mitsuba_variant() -> str:
    """The Mitsuba variant the datasets are rendered with (see the module docstring)."""
    global _VARIANT
    if _VARIANT is None:
        chosen = os.environ.get("LIGHTCAL_MITSUBA_VARIANT")
        if chosen is None:
            probe = subprocess.run(
                [sys.executable, "-c", _PROBE], capture_output=True, timeout=300, check=False
            )
            chosen = "llvm_ad_rgb" if probe.returncode == 0 else "scalar_rgb"
        _VARIANT = chosen
    return _VARIANT


def _mitsuba(variant: str) -> Any:
    import mitsuba as mi

    mi.set_variant(variant)
    return mi


def _transform(R: NDArray[np.float64], t: NDArray[np.float64]) -> list[list[float]]:
    M = np.eye(4)
    M[:3, :3] = R
    M[:3, 3] = t
    return M.tolist()


def profile(theta_rad: NDArray[np.float64]) -> NDArray[np.float64]:
    """The spot's intended relative intensity f(theta) (the module docstring)."""
    m = math.log(0.5) / math.log(math.cos(math.radians(PROFILE_HALF_ANGLE_DEG)))
    f = np.cos(np.clip(theta_rad, 0.0, math.pi / 2)) ** m
    lo, hi = PROFILE_TAPER_DEG
    s = np.clip((np.degrees(theta_rad) - lo) / (hi - lo), 0.0, 1.0)
    return np.asarray(f * (1.0 - s**3 * (10.0 - 15.0 * s + 6.0 * s * s)), dtype=np.float64)


@functools.cache
def _profile_texture() -> NDArray[np.float32]:
    """(n, n, 1) f at the texels of the spot's texture: Mitsuba maps the light-frame
    direction d to uv = (1 + (d_x, d_y) / (d_z tan(cutoff))) / 2."""
    c = (np.arange(_TEXTURE_SIZE) + 0.5) / _TEXTURE_SIZE
    u, v = np.meshgrid(c, c)
    tan_cut = math.tan(math.radians(SPOT_CUTOFF_DEG))
    theta = np.arctan(np.hypot((2.0 * u - 1.0) * tan_cut, (2.0 * v - 1.0) * tan_cut))
    return profile(theta).astype(np.float32)[:, :, None]


def _spot(mi: Any, to_world: list[list[float]] | None = None) -> dict[str, Any]:
    """The spot emitter's dictionary (intensity 1, the smooth profile as its texture)."""
    texture = _profile_texture()
    out: dict[str, Any] = {
        "type": "spot",
        "cutoff_angle": SPOT_CUTOFF_DEG,
        "beam_width": SPOT_CUTOFF_DEG - 0.01,
        "intensity": {"type": "rgb", "value": [1.0, 1.0, 1.0]},
        "texture": {
            "type": "bitmap",
            "bitmap": mi.Bitmap(texture),
            "raw": True,
            "filter_type": "bilinear",
        },
    }
    if to_world is not None:
        out["to_world"] = mi.ScalarTransform4f(to_world)
    return out


def spot_profile(theta_deg: NDArray[np.float64], variant: str | None = None) -> NDArray[np.float64]:
    """Mitsuba's spot intensity at angles theta from its axis, relative to the axis.

    The emitter's `sample_direction` weight at points 1 m away (intensity / d^2), the mean
    over 8 azimuths.
    """
    mi = _mitsuba(variant or mitsuba_variant())
    emitter = mi.load_dict(_spot(mi))
    theta = np.radians(np.asarray(theta_deg, dtype=np.float64))
    phi = np.radians(np.arange(8) * 45.0 + 10.0)
    tt, pp = (a.ravel() for a in np.meshgrid(theta, phi))
    x, y, z = np.sin(tt) * np.cos(pp), np.sin(tt) * np.sin(pp), np.cos(tt)
    it = mi.Interaction3f()
    if mi.variant().startswith("scalar"):
        values = []
        for k in range(tt.size):
            it.p = mi.Point3f(float(x[k]), float(y[k]), float(z[k]))
            _, weight = emitter.sample_direction(it, mi.Point2f(0.5, 0.5))
            values.append(float(weight[0]))
        flat = np.array(values)
    else:
        it.p = mi.Point3f(mi.Float(x), mi.Float(y), mi.Float(z))
        n = tt.size
        _, weight = emitter.sample_direction(it, mi.Point2f(mi.Float(np.full(n, 0.5)), 0.5))
        flat = np.array(weight.x, dtype=np.float64)
    values = np.maximum(flat.reshape(phi.size, theta.size).mean(axis=0), 0.0)
    return np.asarray(values / values[0], dtype=np.float64)


def _render(
    mi: Any,
    scene_dict: dict[str, Any],
    spp: int,
    seed: int,
    *,
    per_pass: int = _SPP_PER_PASS,
    rgb: bool = False,
) -> NDArray[np.float64]:
    """Mitsuba's radiance image (H, W) (its first channel; with `rgb`, (H, W, 3) R, G, B),
    the mean of passes of at most `per_pass` samples per pixel."""
    scene = mi.load_dict(scene_dict)
    passes = max(1, math.ceil(spp / per_pass))
    total = None
    done = 0
    for k in range(passes):
        n = min(per_pass, spp - done)
        film = np.array(mi.render(scene, seed=seed * 1009 + k, spp=n), dtype=np.float64)
        image = film[:, :, :3] if rgb else film[:, :, 0]
        total = image * n if total is None else total + image * n
        done += n
    assert total is not None
    return total / spp


# ------------------------------------------------------------------------ the geometry


def _pixel_rays_world(camera: Camera, view: View, u: NDArray, v: NDArray) -> NDArray[np.float64]:
    """(..., 3) world directions of pixel positions (u, v) (no distortion)."""
    d = np.stack(
        [(u - camera.cx) / camera.fx, (v - camera.cy) / camera.fy, np.ones_like(u)], axis=-1
    )
    return np.asarray(d @ view.R_camera_world, dtype=np.float64)


def _wall_points(camera: Camera, view: View, u: NDArray, v: NDArray) -> NDArray[np.float64]:
    """(..., 3) where the rays of pixel positions (u, v) hit the plane z = 0."""
    d = _pixel_rays_world(camera, view, u, v)
    c = view.center_world
    lam = -c[2] / d[..., 2]
    if not np.all(lam > 0.0):
        raise ValueError("a pixel does not see the wall plane in front of the camera")
    return np.asarray(c + lam[..., None] * d, dtype=np.float64)


def _corner_grid(camera: Camera) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """(H + 1, W + 1) pixel-corner coordinates u, v (centres at integers)."""
    vv, uu = np.mgrid[0 : camera.height + 1, 0 : camera.width + 1].astype(np.float64)
    return uu - 0.5, vv - 0.5


def _wall_half_size(camera: Camera, views: list[View]) -> float:
    """Half the side of a square around the origin holding every image's wall, + 0.25 m."""
    corners_u = np.array([-0.5, camera.width - 0.5, camera.width - 0.5, -0.5])
    corners_v = np.array([-0.5, -0.5, camera.height - 0.5, camera.height - 0.5])
    extent = max(
        float(np.abs(_wall_points(camera, view, corners_u, corners_v)[:, :2]).max())
        for view in views
    )
    return extent + 0.25


def _sensor_dict(mi: Any, camera: Camera, view: View, spp: int) -> dict[str, Any]:
    T = np.array(_transform(view.R_camera_world.T, view.center_world)) @ np.diag(
        [-1.0, -1.0, 1.0, 1.0]
    )
    return {
        "type": "perspective",
        "fov": math.degrees(2.0 * math.atan(camera.width / 2.0 / camera.fx)),
        "fov_axis": "x",
        "to_world": mi.ScalarTransform4f(T.tolist()),
        "film": {
            "type": "hdrfilm",
            "width": camera.width,
            "height": camera.height,
            "rfilter": {"type": "box"},
            "pixel_format": "rgb",
        },
        "sampler": {"type": "multijitter", "sample_count": min(spp, _SPP_PER_PASS)},
    }


def _diffuse(albedo: float | dict[str, Any]) -> dict[str, Any]:
    value = albedo if isinstance(albedo, dict) else {"type": "rgb", "value": [albedo] * 3}
    return {"type": "diffuse", "reflectance": value}


def _plane_rectangle(
    mi: Any, center: NDArray, axis_u: NDArray, axis_v: NDArray, bsdf: dict[str, Any]
) -> dict[str, Any]:
    """A rectangle centre + s axis_u + t axis_v, s, t in [-1, 1] (axes: half sides)."""
    normal = np.cross(axis_u, axis_v)
    M = np.column_stack([axis_u, axis_v, normal / np.linalg.norm(normal)])
    return {
        "type": "rectangle",
        "to_world": mi.ScalarTransform4f(_transform(M, np.asarray(center, dtype=np.float64))),
        "bsdf": bsdf,
    }


# ---------------------------------------------------------------------- departures' parts


@dataclass(frozen=True)
class _Blocker:
    """An axis-aligned rectangle in the plane `coord[axis] = value` (a ceiling, a wall)."""

    axis: int
    value: float
    ranges: tuple[tuple[float, float], tuple[float, float]]  # the other two axes, in order

    def describe(self) -> dict[str, Any]:
        names = "xyz"
        others = [a for a in range(3) if a != self.axis]
        return {
            "plane": f"{names[self.axis]} = {self.value:.6g} m",
            **{f"{names[a]}_range_m": list(r) for a, r in zip(others, self.ranges, strict=True)},
        }

    def hits(self, start: NDArray[np.float64], end: NDArray[np.float64]) -> NDArray[np.bool_]:
        """(...) whether the open segments start -> end (..., 3) cross the rectangle."""
        a, b = start[..., self.axis], end[..., self.axis]
        with np.errstate(divide="ignore", invalid="ignore"):
            s = (self.value - a) / (b - a)
        inside = (s > 1e-9) & (s < 1 - 1e-9)
        p = start + np.nan_to_num(s)[..., None] * (end - start)
        others = [k for k in range(3) if k != self.axis]
        for k, (lo, hi) in zip(others, self.ranges, strict=True):
            inside &= (p[..., k] >= lo) & (p[..., k] <= hi)
        return np.asarray(inside)

    def scene_dict(self, mi: Any, bsdf: dict[str, Any]) -> dict[str, Any]:
        others = [k for k in range(3) if k != self.axis]
        center = np.zeros(3)
        center[self.axis] = self.value
        half = []
        for k, (lo, hi) in zip(others, self.ranges, strict=True):
            center[k] = (lo + hi) / 2.0
            axis = np.zeros(3)
            axis[k] = (hi - lo) / 2.0
            half.append(axis)
        return _plane_rectangle(mi, center, half[0], half[1], bsdf)


def _beam_centers(views: list[View], light: Light) -> NDArray[np.float64]:
    """(n, 2) where the light's axis meets the wall in each view."""
    out = []
    for view in views:
        p = light.position_world(view)
        a = light.rotation_world(view)[:, 2]
        out.append((p - p[2] / a[2] * a)[:2])
    return np.array(out)


def _interreflection_blockers(
    views: list[View], light: Light, half_size: float
) -> tuple[list[_Blocker], NDArray[np.float64]]:
    """A ceiling (above the beam: world -y is up before the roll) and a side wall (+x)."""
    center = np.median(_beam_centers(views, light), axis=0)
    d = INTERREFLECTION["distance_m"]
    depth = INTERREFLECTION["depth_m"]
    y_ceiling = float(center[1] - d)
    x_side = float(center[0] + d)
    ceiling = _Blocker(1, y_ceiling, ((-half_size, x_side), (0.0, depth)))
    side = _Blocker(0, x_side, ((y_ceiling, half_size), (0.0, depth)))
    return [ceiling, side], center


def _occlusion_mask(
    camera: Camera, view: View, light_world: NDArray[np.float64], blockers: list[_Blocker]
) -> NDArray[np.bool_]:
    """(H, W) True where a pixel sees a blocker instead of the wall, or wall the light
    cannot reach: tested at its corners and centre, then grown by one pixel."""
    u, v = _corner_grid(camera)
    cu = np.arange(camera.width, dtype=np.float64)[None, :].repeat(camera.height, 0)
    cv_ = np.arange(camera.height, dtype=np.float64)[:, None].repeat(camera.width, 1)
    masks = []
    for uu, vv in ((u, v), (cu, cv_)):
        p = _wall_points(camera, view, uu, vv)
        blocked = np.zeros(p.shape[:-1], dtype=bool)
        c = np.broadcast_to(view.center_world, p.shape)
        lw = np.broadcast_to(light_world, p.shape)
        for b in blockers:
            blocked |= b.hits(c, p) | b.hits(lw, p)
        masks.append(blocked)
    corners, centres = masks
    mask = centres | corners[:-1, :-1] | corners[1:, :-1] | corners[:-1, 1:] | corners[1:, 1:]
    grown = cv2.dilate(mask.astype(np.uint8), np.ones((3, 3), np.uint8)) > 0
    return np.asarray(grown)


def _dome(center_xy: tuple[float, float], bsdf: dict[str, Any]) -> dict[str, Any]:
    """The bulge of `bowed`: the cap of a sphere of radius rho = R^2 / (2 depth) (100 m)
    whose top is `depth` in front of the wall at (x0, y0). It meets the wall at
    r = sqrt(R^2 - depth^2) = R - 1.25e-5 m and differs from depth (1 - r^2 / R^2) by
    r^4 / (8 rho^3) <= 1.3e-7 m; the rest of the sphere lies behind the wall. (A 1 cm
    triangle mesh of the paraboloid with smooth normals agreed as well, but lost about one
    camera or shadow ray in 3e5 to the cracks between its float32 triangles: pixels
    1 / spp too dark.)"""
    depth = BOW["depth_mm"] / 1000.0
    rho = BOW["radius_m"] ** 2 / (2.0 * depth)
    return {
        "type": "sphere",
        "center": [center_xy[0], center_xy[1], depth - rho],
        "radius": rho,
        "bsdf": bsdf,
    }


def albedo_bitmap(
    texture: AlbedoTexture, half_size: float, texel_m: float = 0.004
) -> NDArray[np.float32]:
    """(n, n) float32 the albedo ALBEDO x the texture's factor at the texel centres of the
    wall rectangle [-half_size, half_size]^2: Mitsuba's rectangle has
    uv = ((x, y) / half_size + 1) / 2 and the bitmap's row j holds v = (j + 1/2) / n."""
    n = min(4096, math.ceil(2.0 * half_size / texel_m))
    c = ((np.arange(n) + 0.5) / n * 2.0 - 1.0) * half_size
    xy = np.stack(np.meshgrid(c, c), axis=-1)  # [j, i] = (x_i, y_j)
    return (ALBEDO * texture.factor(xy)).astype(np.float32)


def medium_transmittance(
    camera: Camera, view: View, light_world: NDArray[np.float64], sigma_t: float
) -> NDArray[np.float64]:
    """(H, W) exp(-sigma_t (|P - C| + |P - L|)), P the wall point of each pixel centre."""
    v, u = np.mgrid[0 : camera.height, 0 : camera.width].astype(np.float64)
    p = _wall_points(camera, view, u, v)
    length = np.linalg.norm(p - view.center_world, axis=-1) + np.linalg.norm(
        p - light_world, axis=-1
    )
    return np.asarray(np.exp(-sigma_t * length), dtype=np.float64)


def rgb_transmittance(
    camera: Camera, view: View, light_world: NDArray[np.float64]
) -> NDArray[np.float64]:
    """(H, W, 3) `medium_transmittance` of `rgb_water`'s c per channel (R, G, B)."""
    return np.stack(
        [medium_transmittance(camera, view, light_world, c) for c in RGB_ATTENUATION_PER_M],
        axis=-1,
    )


# ------------------------------------------------------------------------------ scenes


@dataclass(frozen=True, eq=False)
class _World:
    """What every view of a dataset shares: the truth and the scenario's fixed parts.

    Attributes:
        scenario: Its name.
        camera: The intrinsics.
        views: The true views (relative exposures).
        light: The true light, relative scale 1.
        half_size: The wall is [-half_size, half_size]^2 (it holds every image), metres.
        wall_model: lightcal's model of the true wall.
        blockers: The ceiling and the side wall of `interreflection`, else empty.
        texture: The albedo of `albedo`, else None.
        bow_center: (x0, y0) of `bowed`, metres.
    """

    scenario: str
    camera: Camera
    views: list[View]
    light: Light
    half_size: float
    wall_model: WallReflectance
    blockers: list[_Blocker]
    texture: AlbedoTexture | None
    bow_center: tuple[float, float]


def _make_world(
    scenario: str,
    camera: Camera,
    views: list[View],
    light: Light,
    rng_texture: np.random.Generator,
) -> tuple[_World, dict[str, dict[str, Any]]]:
    """The scenario's scene and its truth.json `departures` (the per-dataset details in)."""
    half_size = _wall_half_size(camera, views)
    found = departures(scenario)
    blockers: list[_Blocker] = []
    texture = None
    bow_center = (0.0, 0.0)
    if scenario == "interreflection":
        blockers, beam_center = _interreflection_blockers(views, light, half_size)
        found["interreflection"].update(
            median_beam_center_m=beam_center.tolist(),
            ceiling=blockers[0].describe(),
            side_wall=blockers[1].describe(),
            masks="pixels that see the ceiling or the side wall, or wall the light cannot "
            "reach (tested at the corners and centre, grown by 1 pixel)",
        )
    if scenario in ("albedo", "murky_albedo"):
        texture = sample_albedo_texture(ALBEDO_AMPLITUDE, rng_texture)
        found["albedo_texture"] = {
            **texture.describe(),
            "base_albedo": ALBEDO,
            "bitmap": "bilinear, 4 mm texels over the wall rectangle",
        }
    if scenario == "bowed":
        bow_center = _view_target_center(views)
        found["bow"]["center_world_m"] = list(bow_center)
        depth = BOW["depth_mm"] / 1000.0
        found["bow"]["rendered_as"] = (
            f"the cap of a sphere of radius {BOW['radius_m'] ** 2 / (2.0 * depth):g} m in "
            "front of the plane (within 1.3e-7 m of the formula)"
        )
    elif scenario in ("medium", "murky_albedo"):
        found["attenuation"]["rendered_as"] = (
            "the direct render x exp(-coefficient (d_light + d_camera)) at each pixel centre, "
            "the exact transmittance of a homogeneous absorbing medium (Mitsuba's volpath "
            "agrees: tests/test_mitsuba_datasets.py)"
        )
    elif scenario == "rgb_water":
        found["attenuation"]["rendered_as"] = (
            "each channel of the direct render (Mitsuba's rgb variant, wall albedo "
            f"{list(RGB_ALBEDO)} for {list(RGB_CHANNELS)}) x exp(-coefficient_per_m[k] "
            "(d_light + d_camera)) at each pixel centre, the exact transmittance of a "
            "homogeneous absorbing medium per channel (Mitsuba's volpath of an RGB sigma_t "
            "agrees: tests/test_rgb_water_mitsuba.py)"
        )
    if scenario == "murky_albedo":
        found["backscatter"]["rendered_as"] = (
            f"Mitsuba's volpath (max_depth 2) of the water in front of a black wall, "
            f"{VEIL_SPP_PER_PIXEL} samples a pixel on cells of {_veil_cell_px(camera)} "
            "pixels square, "
            "bilinear between the cells' centres (`murky_veil`), added to the wall's light"
        )
    wall_model: WallReflectance = (
        PlasticWall.from_albedo(PLASTIC["roughness"], PLASTIC["ior"], PLASTIC["albedo"])
        if scenario == "painted"
        else LAMBERTIAN
    )
    world = _World(
        scenario, camera, views, light, half_size, wall_model, blockers, texture, bow_center
    )
    return world, found


def _view_target_center(views: list[View]) -> tuple[float, float]:
    """(x0, y0) the mean of the points where the views' optical axes meet z = 0, metres."""
    hits = [
        v.center_world[:2] - v.center_world[2] / v.R_camera_world[2, 2] * v.R_camera_world[2, :2]
        for v in views
    ]
    x0, y0 = np.mean(hits, axis=0)
    return float(x0), float(y0)


def _wall_shape(mi: Any, world: _World) -> dict[str, Any]:
    """The wall's Mitsuba shape (with its BSDF): the plane z = 0 within the square."""
    if world.scenario == "painted":
        bsdf: dict[str, Any] = {
            "type": "roughplastic",
            "distribution": "ggx",
            "alpha": PLASTIC["roughness"],
            "int_ior": PLASTIC["ior"],
            "ext_ior": 1.0,
            "diffuse_reflectance": {"type": "rgb", "value": [PLASTIC["albedo"]] * 3},
        }
    elif world.texture is not None:
        bitmap = albedo_bitmap(world.texture, world.half_size)
        bsdf = _diffuse(
            {
                "type": "bitmap",
                "bitmap": mi.Bitmap(bitmap[:, :, None]),
                "raw": True,
                "filter_type": "bilinear",
                "wrap_mode": "clamp",
            }
        )
    elif world.scenario == "rgb_water":
        bsdf = _diffuse({"type": "rgb", "value": list(RGB_ALBEDO)})
    else:
        bsdf = _diffuse(ALBEDO)
    return {
        "type": "rectangle",  # [-1, 1]^2 at z = 0, normal +z
        "to_world": mi.ScalarTransform4f().scale([world.half_size, world.half_size, 1.0]),
        "bsdf": bsdf,
    }


def _view_scene(
    mi: Any, world: _World, wall: dict[str, Any], view: View, spp: int
) -> dict[str, Any]:
    """The Mitsuba scene of one view: the wall, the spot, the scenario's extras."""
    light = world.light
    scene: dict[str, Any] = {
        "type": "scene",
        "integrator": {"type": "direct", "emitter_samples": 1, "bsdf_samples": 0},
        "sensor": _sensor_dict(mi, world.camera, view, spp),
        "wall": wall,
        "light": _spot(mi, _transform(light.rotation_world(view), light.position_world(view))),
    }
    if world.scenario == "bowed":
        scene["dome"] = _dome(world.bow_center, wall["bsdf"])
    if world.scenario == "interreflection":
        scene["integrator"] = {"type": "path", "max_depth": INTERREFLECTION["max_depth"]}
        bsdf = {"type": "twosided", "bsdf": _diffuse(INTERREFLECTION["albedo"])}
        for k, blocker in enumerate(world.blockers):
            scene[f"blocker_{k}"] = blocker.scene_dict(mi, bsdf)
    return scene


def _in_water(
    mi: Any,
    world: _World,
    scene: dict[str, Any],
    scattering_albedo: float,
    sigma_t: float | tuple[float, ...] = ATTENUATION_PER_M,
) -> dict[str, Any]:
    """A view's scene (changed in place and returned) inside water: Mitsuba's homogeneous
    medium (sigma_t, `ATTENUATION_PER_M` or an RGB triple, HG g of `MURKY`) filling a box
    from behind the wall to 1 m above the cameras, rendered by `volpath` with single
    scattering (max_depth 2: the camera ray's first interaction, on the wall or in the
    water)."""
    top = float(max(x.center_world[2] for x in world.views)) + 1.0
    reach = world.half_size + 1.0
    scene["integrator"] = {"type": "volpath", "max_depth": 2}
    scene["water"] = {
        "type": "homogeneous",
        "sigma_t": sigma_t
        if isinstance(sigma_t, float)
        else {"type": "rgb", "value": [float(c) for c in sigma_t]},
        "albedo": scattering_albedo,
        "phase": {"type": "hg", "g": MURKY["phase_g"]},
    }
    scene["sensor"]["medium"] = {"type": "ref", "id": "water"}
    scene["sensor"]["near_clip"] = 1e-5  # the camera ray's first 1 cm is in the water
    scene["box"] = {
        "type": "cube",  # [-1, 1]^3
        "to_world": mi.ScalarTransform4f()
        .translate([0.0, 0.0, (top - 0.5) / 2.0])
        .scale([reach, reach, (top + 0.5) / 2.0]),
        "bsdf": {"type": "null"},
        "interior": {"type": "ref", "id": "water"},
    }
    return scene


def _veil_cell_px(camera: Camera) -> int:
    """The side of `murky_veil`'s cells, pixels: `VEIL_CELLS` across the shorter side."""
    return max(1, min(camera.width, camera.height) // VEIL_CELLS)


def murky_veil(
    mi: Any,
    world: _World,
    view: View,
    *,
    seed: int = 0,
    spp_per_pixel: int = VEIL_SPP_PER_PIXEL,
) -> NDArray[np.float64]:
    """(H, W) the backscatter of `murky_albedo`'s water, Mitsuba's radiance.

    `volpath` (single scattering) of the water in front of a black wall, on a coarse
    film of square cells (`_veil_cell_px`) reaching one cell beyond the image on every
    side (centred on the principal point), `spp_per_pixel` samples a pixel;
    the cells' means interpolated bilinearly from their centres to the pixels' centres.
    The veil is smooth: lightcal's own veil interpolated so from its cell means is within
    1e-3 of the pixel's value (99th percentile; 2e-3 at most) at 480 x 320, and taking
    the means for the centres' values (off by s^2 / 24 times the Laplacian) moves the
    veil by 2e-4 of itself. Its noise is Monte Carlo's: at 256 samples a pixel, 0.07 % of
    the value in most cells (median), up to +-1 % in the cells beside the light where
    the veil is three quarters of the value (free-flight sampling of an integrand that
    peaks as 1 / r^2 near the light). At the image's own resolution it would need 256
    times the samples for the same noise.
    """
    from scipy.interpolate import RegularGridInterpolator

    camera = world.camera
    s = _veil_cell_px(camera)
    spp = spp_per_pixel * s * s
    width, height = math.ceil(camera.width / s) + 2, math.ceil(camera.height / s) + 2
    cells = Camera.from_params(
        fx=camera.fx / s,
        fy=camera.fy / s,
        cx=(width - 1) / 2,
        cy=(height - 1) / 2,
        width=width,
        height=height,
    )
    coarse = replace(world, camera=cells, texture=None)  # the wall black below
    scene = _view_scene(mi, coarse, _wall_shape(mi, coarse), view, spp)
    scene["wall"]["bsdf"] = _diffuse(0.0)
    scene["sensor"]["sampler"] = {"type": "independent"}
    _in_water(mi, coarse, scene, MURKY["scattering_albedo"])
    per_pass = max(_SPP_PER_PASS, _SPP_PER_PASS * 480 * 320 // (width * height))
    cell_means = _render(mi, scene, spp, seed, per_pass=per_pass)
    # cell k's centre in image pixels: c + (k - (n - 1) / 2) s, c the principal point
    u = camera.cx + (np.arange(width) - (width - 1) / 2) * s
    v = camera.cy + (np.arange(height) - (height - 1) / 2) * s
    pv, pu = np.mgrid[0 : camera.height, 0 : camera.width].astype(np.float64)
    interpolate = RegularGridInterpolator((v, u), cell_means)
    return np.asarray(interpolate(np.stack([pv, pu], axis=-1)), dtype=np.float64)


def _sky_scene(
    mi: Any, world: _World, wall: dict[str, Any], view: View, radiance: float
) -> dict[str, Any]:
    """The wall under a constant sky alone, BSDF sampling only: each cosine-sampled
    direction of an open plane sees the sky, so every sample is albedo x radiance."""
    return {
        "type": "scene",
        "integrator": {"type": "direct", "emitter_samples": 0, "bsdf_samples": 1},
        "sensor": _sensor_dict(mi, world.camera, view, 4),
        "wall": wall,
        "sky": {"type": "constant", "radiance": {"type": "rgb", "value": [radiance] * 3}},
    }


def _smooth(
    values: NDArray[np.float64], weights: NDArray[np.bool_], sigma_px: float
) -> NDArray[np.float64]:
    """A Gaussian blur of `values` over the pixels where `weights` is true (normalised
    convolution: the pixels outside neither contribute nor dilute)."""
    size = 2 * math.ceil(3.0 * sigma_px) + 1
    w = weights.astype(np.float64)
    num = cv2.GaussianBlur(values * w, (size, size), sigma_px, borderType=cv2.BORDER_REFLECT)
    den = cv2.GaussianBlur(w, (size, size), sigma_px, borderType=cv2.BORDER_REFLECT)
    return np.asarray(np.where(weights, num / np.maximum(den, 1e-12), 0.0), dtype=np.float64)


@dataclass(frozen=True)
class _Renders:
    """Each view's radiance with the departures applied, its mask, its render time."""

    radiance: list[NDArray[np.float64]]
    masks: list[NDArray[np.bool_] | None]
    seconds: list[float]


def _render_views(mi: Any, world: _World, spp: int, found: dict[str, dict[str, Any]]) -> _Renders:
    """Render every view and apply what comes after the wall (sky, water, lens)."""
    camera, light = world.camera, world.light
    radiance: list[NDArray[np.float64]] = []
    masks: list[NDArray[np.bool_] | None] = []
    seconds: list[float] = []
    wall = _wall_shape(mi, world)
    for i, view in enumerate(world.views):
        t0 = time.perf_counter()
        light_world = light.position_world(view)
        scene = _view_scene(mi, world, wall, view, spp)
        image = _render(mi, scene, spp, i, rgb=world.scenario == "rgb_water")
        mask = None
        if world.scenario == "interreflection":
            mask = _occlusion_mask(camera, view, light_world, world.blockers)
            scene["integrator"] = {"type": "direct", "emitter_samples": 1, "bsdf_samples": 0}
            direct = _render(mi, scene, DEFAULT_SPP["clean"], i)
            image = direct + _smooth(image - direct, ~mask, INDIRECT_SMOOTHING_PX)
        seconds.append(time.perf_counter() - t0)
        if world.scenario in ("medium", "murky_albedo"):
            image = image * medium_transmittance(camera, view, light_world, ATTENUATION_PER_M)
        if world.scenario == "rgb_water":
            image = image * rgb_transmittance(camera, view, light_world)
        if world.scenario == "murky_albedo":
            t0 = time.perf_counter()
            image = image + murky_veil(mi, world, view, seed=i)
            seconds[-1] += time.perf_counter() - t0
        radiance.append(image)
        masks.append(mask)
    if world.scenario == "ambient":
        # lightcal synth's definition: F times the beam's peak in the image whose peak
        # (exposure included) is the lower median, the same radiance in every view.
        peaks = [
            float(image.max()) * v.exposure for image, v in zip(radiance, world.views, strict=True)
        ]
        ref = int(np.argsort(peaks, kind="stable")[(len(peaks) - 1) // 2])
        level = AMBIENT_FRACTION * peaks[ref] / world.views[ref].exposure
        sky = level / ALBEDO  # a Lambertian plane under a uniform sky: L = albedo x sky
        for i, view in enumerate(world.views):
            t0 = time.perf_counter()
            radiance[i] = radiance[i] + _render(
                mi, _sky_scene(mi, world, wall, view, sky), 4, 100 + i
            )
            seconds[i] += time.perf_counter() - t0
        found["ambient"].update(reference=ref, wall_radiance=level, sky_radiance=sky)
    if world.scenario == "vignetting":
        model = RadialVignetting.centered(
            np.array(VIGNETTING_COEFFS), width=camera.width, height=camera.height
        )
        found["undeclared_vignetting"].update(
            center_px=model.center_px.tolist(), norm_radius_px=model.norm_radius_px
        )
        fall_off = model.image()
        radiance = [image * fall_off for image in radiance]
    return _Renders(radiance, masks, seconds)


# ------------------------------------------------------------------------------- write


def _sensor_config(sensor: SensorKind) -> SensorConfig:
    if sensor == "realistic":
        return SensorConfig()
    if sensor == "clean":
        return SensorConfig(bit_depth=16, noise=False)
    raise ValueError(f"sensor: expected 'realistic' or 'clean', got {sensor!r}")


def _diffuse_level(wall: WallReflectance) -> float:
    """k_d: Mitsuba's radiance per unit of lightcal's B x irradiance (docs/model.md)."""
    if isinstance(wall, PlasticWall):
        rho, eta, alpha = PLASTIC["albedo"], PLASTIC["ior"], PLASTIC["roughness"]
        t1 = rough_transmittance(alpha, eta)[0][-1]
        return float(rho * t1**2 / (math.pi * eta**2 * (1.0 - internal_reflectance(alpha, eta))))
    return ALBEDO / math.pi


def write_mitsuba_dataset(
    out_dir: Path,
    scenario: str,
    *,
    seed: int = 0,
    views: int = 12,
    width: int = 480,
    height: int = 320,
    spp: int | None = None,
    sensor: SensorKind = "realistic",
    variant: str | None = None,
    force: bool = False,
    declare: bool = False,
) -> Path:
    """Render a scenario with Mitsuba 3 and write a complete lightcal project folder.

    Args:
        out_dir: The dataset folder: new or empty (or, with `force`, one to replace).
        scenario: One of `SCENARIOS` (the module docstring).
        seed: The seed of every random choice (views, exposures, rig, pose noise,
            initial guess, sensor noise, the albedo texture), as `lightcal synth --seed`.
        views: Number of images.
        width, height: Image size, pixels.
        spp: Samples per pixel; None: `DEFAULT_SPP[scenario]`.
        sensor: "realistic" (`lightcal synth`'s noisy 14-bit sensor) or "clean" (16 bits,
            no noise).
        variant: Mitsuba variant; None: `mitsuba_variant()`.
        force: Replace the dataset in a non-empty `out_dir` (the whole folder: it must
            hold a truth.json).
        declare: `rgb_water` only: the project declares `sensor.channels: [R, G, B]` and
            the medium to estimate (the module docstring).

    Returns:
        The path of the project file, `out_dir / "project.json"`.

    Raises:
        ImportError: Mitsuba 3 is not installed.
        ValueError: An unknown scenario or sensor, or `declare` for another scenario than
            `rgb_water`.
    """
    _check_scenario(scenario)
    _check_declare(scenario, declare)
    sensor_config = _sensor_config(sensor)
    mi = _mitsuba(variant or mitsuba_variant())
    out_dir = Path(out_dir)
    occupied = check_target(out_dir, force=force)
    if occupied and not _is_dataset(out_dir):
        raise ValueError(f"{out_dir}: not a dataset folder (no truth.json); not replaced")
    staging = make_staging(out_dir)
    (staging / MASKS_DIR).mkdir()
    n_spp = DEFAULT_SPP[scenario] if spp is None else spp
    key = _key(scenario, seed, views, width, height, n_spp, sensor, declare)
    try:
        _write_into(staging, mi, key, sensor_config)
        if occupied:
            shutil.rmtree(out_dir)
        publish(staging, out_dir, occupied=False)
    except BaseException:
        shutil.rmtree(staging, ignore_errors=True)
        raise
    return out_dir / PROJECT_NAME


def _check_declare(scenario: str, declare: bool) -> None:
    if declare and scenario != "rgb_water":
        raise ValueError(f"declare: only the rgb_water scenario declares, not {scenario!r}")


def _is_dataset(folder: Path) -> bool:
    try:
        truth = json.loads((folder / TRUTH_NAME).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return False
    return isinstance(truth, dict) and truth.get("format") == TRUTH_FORMAT


_POSE_NOISE_M, _POSE_NOISE_DEG = 0.0005, 0.05
"""`lightcal synth`'s default pose noise (and the covariance the project declares)."""

_INIT_OFFSET_M, _INIT_OFFSET_DEG = 0.1, 10.0
"""`lightcal synth`'s default initial guess error."""


def _write_into(folder: Path, mi: Any, key: dict[str, Any], sensor: SensorConfig) -> None:
    started = time.perf_counter()
    scenario, seed, n_views = key["scenario"], key["seed"], key["views"]
    width, height, spp = key["width"], key["height"], key["spp"]
    # The streams of lightcal.synthetic.dataset, in its order, then the texture's.
    root = np.random.default_rng(seed)
    rng_views, rng_exposure, rng_rig, rng_pose, rng_init, rng_sensor, rng_texture = root.spawn(7)
    project_path = folder / PROJECT_NAME

    # Camera and light profile files, read back as a calibration reads them.
    fx = 0.9 * width
    write_camera(
        Camera.from_params(
            fx=fx, fy=fx, cx=(width - 1) / 2, cy=(height - 1) / 2, width=width, height=height
        ),
        folder / CAMERA_NAME,
    )
    camera = read_camera(folder / CAMERA_NAME)
    theta_deg = np.arange(0.0, SPOT_CUTOFF_DEG + PROFILE_STEP_DEG / 2, PROFILE_STEP_DEG)
    write_rid_csv(folder / RID_NAME, theta_deg, spot_profile(theta_deg, mi.variant()))
    rid_spec = RIDSpec(type="table", path=RID_NAME)
    rid = build_rid(rid_spec, folder, project_path, "lights[0].rid")

    # The scene, as lightcal synth draws it.
    scene_config = SceneConfig(n_views=n_views)
    rig_config = RigConfig(model="table")
    poses = sample_views(scene_config, rng_views)
    times_s = sample_exposure_times(scene_config, rng_exposure)
    exposure_specs = [ExposureSpec(exposure_time_s=float(t)) for t in times_s]
    reference = exposure_specs[0].factor()
    views = [
        View(v.R_camera_world, v.t_camera_world, e.factor() / reference)
        for v, e in zip(poses, exposure_specs, strict=True)
    ]
    relative_light = sample_rig(rig_config, rng_rig).lights[0].replace(rid=rid)
    measured = [
        perturb_view(
            v,
            rng_pose,
            position_sigma_m=_POSE_NOISE_M,
            angle_sigma_rad=math.radians(_POSE_NOISE_DEG),
        )
        for v in views
    ]
    initial = initial_guess(
        relative_light,
        rng_init,
        offset_m=_INIT_OFFSET_M,
        offset_rad=math.radians(_INIT_OFFSET_DEG),
    )

    world, found = _make_world(scenario, camera, views, relative_light, rng_texture)
    renders = _render_views(mi, world, spp, found)

    # DN: the brightest (unmasked) pixel of the dataset at the sensor's exposure target.
    peak = max(
        float(np.max(image if mask is None else np.where(mask, 0.0, image))) * view.exposure
        for image, mask, view in zip(renders.radiance, renders.masks, views, strict=True)
    )
    black = sensor.black_level
    dn_per_radiance = sensor.exposure_target * (white_level(sensor) - black) / peak
    k_d = _diffuse_level(world.wall_model)
    light = relative_light.replace(scale=dn_per_radiance * k_d)
    colour = scenario == "rgb_water"
    channel_k_d = [a / math.pi for a in RGB_ALBEDO] if colour else None
    if scenario == "ambient":
        ref = found["ambient"]["reference"]
        beam_peak = found["ambient"]["wall_radiance"] / AMBIENT_FRACTION * views[ref].exposure
        per_exposure = AMBIENT_FRACTION * dn_per_radiance * beam_peak / views[ref].exposure
        found["ambient"].update(
            reference_view=f"view_{ref:0{max(2, len(str(n_views - 1)))}d}",
            reference_peak_dn=dn_per_radiance * beam_peak,
            reference_exposure=views[ref].exposure,
            per_exposure_dn=per_exposure,
            levels_dn=[per_exposure * v.exposure for v in views],
        )
        del found["ambient"]["reference"]

    view_truth = _write_images(
        folder, renders, views, measured, times_s, dn_per_radiance, sensor, rng_sensor
    )

    # The project, as lightcal synth writes it (a painted wall: `auto`).
    pose_covariance = np.diag([math.radians(_POSE_NOISE_DEG) ** 2] * 3 + [_POSE_NOISE_M**2] * 3)
    gain, read_variance = noise_model(sensor)
    spec = ProjectFile(
        camera=CameraSpec(path=CAMERA_NAME),
        sensor=SensorSpec(
            model="radiance",
            black_level=black,
            white_level=white_level(sensor),
            noise=NoiseSpec(gain=gain, read_variance=read_variance),
        ),
        images=[
            ImageSpec(
                path=truth["path"],
                name=truth["name"],
                T_camera_world=pose_spec(measured[i], pose_covariance),
                exposure=exposure_specs[i],
                mask=truth["mask"],
            )
            for i, truth in enumerate(view_truth)
        ],
        lights=[
            LightSpec(
                name=light.name,
                rid=rid_spec,
                pose=pose_kind(light.rid),
                initial=initial_spec(initial),
            )
        ],
        selection=SelectionSpec(),
        solver=SolverSpec(),
        wall=WallSpec(model="auto") if scenario == "painted" else WallSpec(),
    )

    rid_truth = describe_rid(rid)
    rid_truth["path"] = RID_NAME
    scale: float | list[float] = light.scale
    channel_truth: dict[str, Any] = {}
    if channel_k_d is not None:
        scale = [dn_per_radiance * k for k in channel_k_d]
        channel_truth = {"channels": list(RGB_CHANNELS)}
    truth = {
        "format": TRUTH_FORMAT,
        "version": 1,
        "lightcal_version": __version__,
        "seed": seed,
        "camera": camera_dict(camera),
        "sensor": {
            "model": "radiance",
            "bit_depth": sensor.bit_depth,
            "black_level_dn": black,
            "white_level_dn": white_level(sensor),
            "full_well_e": sensor.full_well_e,
            "read_noise_e": sensor.read_noise_e,
            "conversion_gain_dn_per_e": conversion_gain(sensor),
            "noise": sensor.noise,
            "noise_model": {"gain": gain, "read_variance": read_variance},
            "exposure_target": sensor.exposure_target,
            "vignetting_coeffs": None,
            "vignetting_path": None,
        },
        "views": view_truth,
        "wall": world.wall_model.describe(),
        "lights": [
            {
                "name": light.name,
                "scale": scale,
                **channel_truth,
                "relative_scale": 1.0,
                "pose_kind": "symmetric",
                "rid": rid_truth,
                **describe_pose(light.R_camera_light, light.t_camera_light),
                "initial": describe_pose(initial.R_camera_light, initial.t_camera_light),
            }
        ],
        "departures": found,
        "options": {
            "pose_noise_mm": _POSE_NOISE_M * 1000.0,
            "pose_noise_deg": _POSE_NOISE_DEG,
            "init_offset_m": _INIT_OFFSET_M,
            "init_offset_deg": _INIT_OFFSET_DEG,
            "image_format": "png",
        },
        "config": {
            "scene": asdict(scene_config),
            "rig": asdict(rig_config),
            "sensor": asdict(sensor),
        },
        "mitsuba": {
            "key": key,
            "mitsuba_version": mi.__version__,
            "variant": mi.variant(),
            "spp": spp,
            "integrator": _INTEGRATORS.get(scenario, "direct"),
            "spot": {
                "cutoff_angle_deg": SPOT_CUTOFF_DEG,
                "profile": "cos^m, f(30 deg) = 1/2, C2 taper 45..55 deg (bitmap texture)",
                "intensity": 1.0,
            },
            "dn_per_radiance": dn_per_radiance,
            "diffuse_level": k_d if channel_k_d is None else channel_k_d,
            **({"albedo": list(RGB_ALBEDO), "channels": list(RGB_CHANNELS)} if colour else {}),
            "declared": bool(key.get("declare", False)),
            "wall_half_size_m": world.half_size,
            "render_s": float(sum(renders.seconds)),
            "total_s": time.perf_counter() - started,
        },
    }
    atomic_write_text(folder / TRUTH_NAME, json.dumps(truth, indent=2) + "\n")
    save_project(spec, project_path)
    if key.get("declare", False):
        _declare_channels(project_path)
    load_project(project_path)  # the dataset must load


def _declare_channels(project_path: Path) -> None:
    """`rgb_water` with `declare`: the project (written by `save_project`) gains
    `sensor.channels` and the medium to estimate (the writer then loads it, validated)."""
    doc = json.loads(project_path.read_text(encoding="utf-8"))
    doc["sensor"].pop("channel", None)
    doc["sensor"]["channels"] = list(RGB_CHANNELS)
    doc["medium"] = {
        "attenuation_per_m": [RGB_DECLARED_START_PER_M] * len(RGB_CHANNELS),
        "estimate": ["attenuation_per_m"],
    }
    atomic_write_text(project_path, json.dumps(doc, indent=2) + "\n")


_INTEGRATORS = {"interreflection": "path", "murky_albedo": "direct; the veil volpath"}


def _write_images(
    folder: Path,
    renders: _Renders,
    views: list[View],
    measured: list[View],
    times_s: NDArray[np.float64],
    dn_per_radiance: float,
    sensor: SensorConfig,
    rng_sensor: np.random.Generator,
) -> list[dict[str, Any]]:
    """The images (and masks) through the sensor; truth.json's `views`."""
    digits = max(2, len(str(len(views) - 1)))
    view_truth: list[dict[str, Any]] = []
    for i, view in enumerate(views):
        name = f"view_{i:0{digits}d}"
        signal = dn_per_radiance * view.exposure * renders.radiance[i]
        if signal.ndim == 3:  # R, G, B: each through the sensor, written B, G, R (OpenCV's)
            planes = [apply_sensor(signal[..., k], sensor, rng_sensor) for k in range(3)]
            dn = np.stack([p[0] for p in planes[::-1]], axis=-1)
            saturated = np.any([p[1] for p in planes], axis=0)
        else:
            dn, saturated = apply_sensor(signal, sensor, rng_sensor)
        atomic_write_bytes(folder / IMAGES_DIR / f"{name}.png", encode_image(dn, "png"))
        mask = renders.masks[i]
        if mask is not None:
            ok, encoded = cv2.imencode(".png", mask.astype(np.uint8) * 255)
            assert ok
            atomic_write_bytes(folder / MASKS_DIR / f"{name}.png", encoded.tobytes())
        view_truth.append(
            {
                "name": name,
                "path": f"{IMAGES_DIR}/{name}.png",
                "mask": None if mask is None else f"{MASKS_DIR}/{name}.png",
                "T_camera_world": pose_spec(view).model_dump(exclude_none=True),
                "T_camera_world_measured": pose_spec(measured[i]).model_dump(exclude_none=True),
                "center_world_m": view.center_world.tolist(),
                **view_geometry(view),
                "exposure_time_s": float(times_s[i]),
                "exposure": view.exposure,
                "peak_signal_dn": float(signal.max()),
                "valid_pixels": int(signal.size - (0 if mask is None else mask.sum())),
                "masked_pixels": 0 if mask is None else int(mask.sum()),
                "saturated_pixels": int(np.count_nonzero(saturated)),
                "render_s": renders.seconds[i],
            }
        )
    return view_truth


def _key(
    scenario: str,
    seed: int,
    views: int,
    width: int,
    height: int,
    spp: int,
    sensor: str,
    declare: bool = False,
) -> dict[str, Any]:
    declared: dict[str, Any] = {"declare": True} if declare else {}  # older keys unchanged
    return {
        "scenario": scenario,
        "seed": seed,
        "views": views,
        "width": width,
        "height": height,
        "spp": spp,
        "sensor": sensor,
        "generator": _GENERATOR_VERSION,
        **declared,
    }


_GENERATOR_VERSION = 3
"""Bumped when what a key renders changes (cached folders are then rendered again)."""


# ------------------------------------------------------------------------------ caching


def cached_dataset(
    root: Path,
    scenario: str,
    *,
    seed: int = 0,
    views: int = 12,
    width: int = 480,
    height: int = 320,
    spp: int | None = None,
    sensor: SensorKind = "realistic",
    declare: bool = False,
) -> Path:
    """`write_mitsuba_dataset` into `root / <name of the options>`, unless a dataset of
    the same options is already there. Returns the project file's path."""
    _check_scenario(scenario)
    _check_declare(scenario, declare)
    n_spp = DEFAULT_SPP[scenario] if spp is None else spp
    folder = Path(root) / (
        f"{scenario}-s{seed}-v{views}-{width}x{height}-spp{n_spp}-{sensor}"
        + ("-declared" if declare else "")
    )
    key = _key(scenario, seed, views, width, height, n_spp, sensor, declare)
    try:
        truth = json.loads((folder / TRUTH_NAME).read_text(encoding="utf-8"))
        if truth.get("mitsuba", {}).get("key") == key and (folder / PROJECT_NAME).is_file():
            return folder / PROJECT_NAME
    except (OSError, ValueError):
        pass
    return write_mitsuba_dataset(
        folder,
        scenario,
        seed=seed,
        views=views,
        width=width,
        height=height,
        spp=n_spp,
        sensor=sensor,
        force=folder.exists(),
        declare=declare,
    )


_SESSION: dict[tuple[Any, ...], Path] = {}


def session_dataset(
    tmp_path_factory: pytest.TempPathFactory, scenario: str, **options: Any
) -> Path:
    """One dataset per scenario and options per test session (pytest's temporary folders).

    Use from a session- or module-scoped fixture:
    `session_dataset(tmp_path_factory, "clean", views=4, sensor="clean")`.
    """
    key = (scenario, *sorted(options.items()))
    if key not in _SESSION:
        root = tmp_path_factory.getbasetemp() / "mitsuba-datasets"
        _SESSION[key] = cached_dataset(root, scenario, **options)
    return _SESSION[key]


def read_images(project_path: Path) -> list[NDArray[np.float64]]:
    """The dataset's images as written, black level subtracted (DN, float): (H, W), or
    (H, W, 3) R, G, B for a colour dataset (`rgb_water`; the files hold B, G, R)."""
    truth = _read_truth(project_path)
    black = float(truth["sensor"]["black_level_dn"])
    out = []
    for v in truth["views"]:
        path = project_path.parent / v["path"]
        dn = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
        if dn is None:
            raise FileNotFoundError(f"{path}: not a readable image")
        if dn.ndim == 3:
            dn = dn[..., ::-1]
        out.append(dn.astype(np.float64) - black)
    return out


def _read_truth(project_path: Path) -> dict[str, Any]:
    return dict(json.loads((project_path.parent / TRUTH_NAME).read_text(encoding="utf-8")))


@dataclass(frozen=True, eq=False)
class TruthScene:
    """A dataset's truth, ready to render with lightcal.

    Attributes:
        camera: The intrinsics (camera.yaml).
        views: The true views with their relative exposures.
        light: The true light (the table RID of rid.csv, scale in DN per unit of lightcal's
            `radiance` value: `render_image` gives the expected image above black).
        wall: lightcal's model of the true wall.
        texture: The wall's albedo factor (`albedo`, `murky_albedo`), else None.
        medium: The water (`medium`, `murky_albedo`; beta relative to the base albedo),
            else air.
        channel: The colour channel of a colour dataset's scene ("R", "G", "B": the
            light's scale and the medium are that channel's), else None.
    """

    camera: Camera
    views: list[View]
    light: Light
    wall: WallReflectance
    texture: AlbedoTexture | None = None
    medium: Medium = AIR
    channel: str | None = None

    def albedo_factor(self, view: View) -> NDArray[np.float64]:
        """(H, W) the texture's albedo factor at each pixel's footprint centre in `view`
        (1 without a texture)."""
        camera = self.camera
        if self.texture is None:
            return np.ones((camera.height, camera.width))
        pixels = np.stack(np.meshgrid(np.arange(camera.width), np.arange(camera.height)), -1)
        centres = pixel_footprints(camera, view, pixels.reshape(-1, 2)).centers_world
        return self.texture.factor(centres[:, :2]).reshape(camera.height, camera.width)


def truth_scene(project_path: Path, channel: str | None = None) -> TruthScene:
    """The truth of the dataset whose project file is `project_path`; of one of its
    channels ("R", "G" or "B") for a colour dataset (`rgb_water`), where it is required.

    Raises:
        ValueError: A channel for a grey dataset, or none (or an unknown one) for a
            colour dataset.
    """
    project_path = Path(project_path)
    truth = _read_truth(project_path)
    t = truth["lights"][0]
    channels = t.get("channels")
    if (channels is None) != (channel is None) or (
        channels is not None and channel not in channels
    ):
        raise ValueError(
            f"channel: expected one of {channels} for this colour dataset, got {channel!r}"
            if channels is not None
            else f"channel: a grey dataset has no channel {channel!r}"
        )
    camera, rid = _camera_and_rid(project_path, truth)
    views = [
        View(
            np.array(v["T_camera_world"]["R"]),
            np.array(v["T_camera_world"]["t"]),
            float(v["exposure"]),
        )
        for v in truth["views"]
    ]
    k = None if channels is None else channels.index(channel)
    light = Light(
        rid,
        np.array(t["position_m"]),
        np.array(t["R_camera_light"]),
        scale=float(t["scale"] if k is None else t["scale"][k]),
        name=t["name"],
    )
    wall: WallReflectance = LAMBERTIAN
    if truth["wall"]["model"] == "plastic":
        w = truth["wall"]
        wall = PlasticWall(w["roughness"], w["ior"], w["specular_weight"])
    found = truth["departures"]
    texture = None
    if "albedo_texture" in found:
        d = found["albedo_texture"]
        directions = np.radians(d["directions_deg"])
        wavevectors = (2.0 * math.pi / np.array(d["wavelengths_m"]))[:, None] * np.stack(
            [np.cos(directions), np.sin(directions)], axis=1
        )
        texture = AlbedoTexture(
            d["amplitude"], wavevectors, np.array(d["phases_rad"]), np.array(d["weights"])
        )
    medium = AIR
    if "attenuation" in found:
        scattering = found.get("backscatter", {"beta_per_m": 0.0, "phase_g": 0.9})
        c = found["attenuation"]["coefficient_per_m"]
        if k is not None:
            c = c[found["attenuation"]["channels"].index(channel)]
        medium = Medium(c, scattering["beta_per_m"], scattering["phase_g"])
    return TruthScene(camera, views, light, wall, texture, medium, channel)


def _camera_and_rid(project_path: Path, truth: dict[str, Any]) -> tuple[Camera, Any]:
    """The camera and the light's profile as a calibration loads them (the project)."""
    project = load_project(project_path)
    return project.camera, project.lights[0].initial.rid


@dataclass(frozen=True)
class VolpathImages:
    """Mitsuba's `volpath` render of a view of `medium` or `murky_albedo` and its parts
    as the dataset's images carry them (Mitsuba's radiance, (H, W) each).

    Attributes:
        through_water: The whole scene in the water, one `volpath` render.
        wall: The `direct` render times `medium_transmittance`.
        veil: `murky_veil` (zero for `medium`).
        lit: The pixels whose wall + veil is above 5 % of its peak.
    """

    through_water: NDArray[np.float64]
    wall: NDArray[np.float64]
    veil: NDArray[np.float64]
    lit: NDArray[np.bool_]

    def ratio(self) -> tuple[float, float, int]:
        """The mean of through_water / (wall + veil) over the lit pixels, its standard
        error (from the pixels' spread: volpath's noise), and the pixel count."""
        ratio = self.through_water[self.lit] / (self.wall + self.veil)[self.lit]
        n = int(self.lit.sum())
        return float(ratio.mean()), float(ratio.std() / math.sqrt(n)), n


def volpath_channels(
    project_path: Path, *, view: int = 0, spp: int = 1024
) -> dict[str, VolpathImages]:
    """`volpath_images` of `rgb_water`, per channel: one `volpath` render of the view in
    an absorbing Mitsuba medium of sigma_t = `RGB_ATTENUATION_PER_M` (an RGB value,
    albedo 0) beside each channel of the `direct` render times that channel's exact
    transmittance (`rgb_transmittance`)."""
    scene = truth_scene(project_path, RGB_CHANNELS[0])
    camera, v = scene.camera, scene.views[view]
    mi = _mitsuba(mitsuba_variant())
    world = _World(
        "rgb_water",
        camera,
        scene.views,
        scene.light,
        _wall_half_size(camera, scene.views),
        LAMBERTIAN,
        [],
        None,
        (0.0, 0.0),
    )
    wall = _wall_shape(mi, world)
    direct = _render(mi, _view_scene(mi, world, wall, v, 16), 16, 0, rgb=True)
    volume = _in_water(mi, world, _view_scene(mi, world, wall, v, spp), 0.0, RGB_ATTENUATION_PER_M)
    through_water = _render(mi, volume, spp, 1, rgb=True)
    attenuated = direct * rgb_transmittance(camera, v, scene.light.position_world(v))
    out = {}
    for k, name in enumerate(RGB_CHANNELS):
        wall_k = attenuated[..., k]
        out[name] = VolpathImages(
            through_water[..., k], wall_k, np.zeros_like(wall_k), wall_k > 0.05 * wall_k.max()
        )
    return out


def volpath_images(
    project_path: Path, *, view: int = 0, spp: int = 1024, veil_spp_per_pixel: int = 4096
) -> VolpathImages:
    """Mitsuba's `volpath` through the water of `medium` or `murky_albedo` against the
    images' model: a view of the dataset rendered with its wall (the texture of
    `murky_albedo`) and the water as a Mitsuba medium (`_in_water`: the camera inside
    it), beside the parts its images were made of (the veil with `veil_spp_per_pixel`)."""
    scene = truth_scene(project_path)
    camera, v = scene.camera, scene.views[view]
    mi = _mitsuba(mitsuba_variant())
    murky = scene.medium.scatters
    world = _World(
        "murky_albedo" if murky else "clean",
        camera,
        scene.views,
        scene.light,
        _wall_half_size(camera, scene.views),
        LAMBERTIAN,
        [],
        scene.texture,
        (0.0, 0.0),
    )
    wall = _wall_shape(mi, world)
    direct = _render(mi, _view_scene(mi, world, wall, v, 16), 16, 0)
    scattering = MURKY["scattering_albedo"] if murky else 0.0
    volume = _in_water(mi, world, _view_scene(mi, world, wall, v, spp), scattering)
    through_water = _render(mi, volume, spp, 1)
    attenuated = direct * medium_transmittance(
        camera, v, scene.light.position_world(v), ATTENUATION_PER_M
    )
    veil = np.zeros_like(attenuated)
    if murky:
        veil = murky_veil(mi, world, v, spp_per_pixel=veil_spp_per_pixel)
    expected = attenuated + veil
    return VolpathImages(through_water, attenuated, veil, expected > 0.05 * expected.max())
