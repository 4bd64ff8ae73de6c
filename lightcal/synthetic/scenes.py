"""Synthetic calibration scenes with known ground truth: views, rigs and the sensor.

Everything here is numbers in memory (no files; `lightcal.synthetic.dataset` writes a
dataset). Frames and units follow docs/conventions.md: the wall is the world plane z = 0, cameras
sit at z > 0 looking at it (OpenCV camera frame), a light's +z is its axis; metres and
radians inside, degrees only in the `_deg` fields of the configurations.

- `sample_views`: camera poses in front of the wall, distances stratified over a range,
  varied tilts, azimuths and rolls; every optical axis hits the wall in front of the camera
  (the lit area, where lights mounted next to the camera point, is in view).
- `sample_rig`: one or more lights beside the camera (a few to 30 cm), axes within a few
  tens of degrees of the optical axis, with one of six angular profiles (`LightModel`).
- `initial_guess`, `perturb_view`: the deliberately wrong starting point of a calibration
  and the marker / SfM error of the camera poses.
- The sensor (`SensorConfig`, `apply_sensor`, `noise_model`): the expected signal in DN
  above the black level becomes photo-electrons (signal / gain), gets Poisson shot noise
  and Gaussian read noise, goes back to DN, gets the black level, is rounded and clipped
  at the white level 2^bits - 1 (saturation).

The light scale k of docs/model.md (`Light.scale`) is expressed in DN: rendering with the true
rig gives the expected pixel value above the black level, at the exposure of the first
image. `signal_scale` picks k so that the brightest expected pixel of a dataset sits at
`SensorConfig.exposure_target` of the usable range (white - black).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from lightcal.core.camera import Camera
from lightcal.core.footprint import SensorModel
from lightcal.core.pose import rotation_from_axis
from lightcal.core.render import render_image, render_pixels
from lightcal.core.rid import (
    RID,
    CosPowerRID,
    GaussianRID,
    IsotropicRID,
    SymmetricTableRID,
    Table2DRID,
)
from lightcal.core.rotations import matrix_from_rotvec
from lightcal.core.scene import Light, Rig, View
from lightcal.core.vignetting import RadialVignetting
from lightcal.errors import InputError
from lightcal.synthetic.light_models import LIGHT_MODELS, LightModel

__all__ = [
    "LIGHT_MODELS",
    "LightModel",
    "RigConfig",
    "SceneConfig",
    "SensorConfig",
    "apply_sensor",
    "conversion_gain",
    "describe_rid",
    "elliptical_beam_table",
    "initial_guess",
    "make_rid",
    "noise_model",
    "peak_signal",
    "perturb_view",
    "sample_exposure_times",
    "sample_rig",
    "sample_views",
    "signal_scale",
    "symmetric_profile_table",
    "vignetting_image",
    "white_level",
]

TABLE_STEP_DEG = 2.5
"""Angular step of the synthetic tables (vertical angles 0..90 degrees)."""

AZIMUTH_STEP_DEG = 10.0
"""Azimuth step of the 2-D table (36 planes over the full circle)."""

_PROFILE_SHOULDER = 0.5
"""b of the symmetric table profile cos(theta)^m (1 + b sin^2 theta)."""

_MAX_TILT_DEG = 80.0
"""Largest accepted camera tilt: beyond it the wall is seen too grazingly to be useful."""


# ------------------------------------------------------------------------------ helpers


def _check_range(name: str, value: tuple[float, float], *, low: float, high: float) -> None:
    """Raise InputError unless `low <= value[0] <= value[1] <= high`, both finite."""
    if len(value) != 2 or not all(math.isfinite(v) for v in value):
        raise InputError(name, f"expected two finite numbers (min, max), got {value!r}")
    lo, hi = value
    if not (low <= lo <= hi <= high):
        raise InputError(name, f"expected {low:g} <= min <= max <= {high:g}, got ({lo:g}, {hi:g})")


def _check_positive_int(name: str, value: int) -> None:
    if isinstance(value, bool) or not isinstance(value, int | np.integer) or value < 1:
        raise InputError(name, f"expected an integer >= 1, got {value!r}")


def _unit_perpendicular(axis: NDArray[np.float64], rng: np.random.Generator) -> NDArray[np.float64]:
    """A uniformly random unit vector perpendicular to the unit vector `axis` (3,)."""
    while True:
        v = rng.normal(size=3)
        v -= (v @ axis) * axis
        norm = float(np.linalg.norm(v))
        if norm > 1e-6:
            return v / norm


def _unit_vector(rng: np.random.Generator) -> NDArray[np.float64]:
    """A uniformly random unit vector (3,)."""
    while True:
        v = rng.normal(size=3)
        norm = float(np.linalg.norm(v))
        if norm > 1e-6:
            return v / norm


def _rotation_z(angle_rad: float) -> NDArray[np.float64]:
    c, s = math.cos(angle_rad), math.sin(angle_rad)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


# -------------------------------------------------------------------------------- views


@dataclass(frozen=True)
class SceneConfig:
    """Where the cameras stand in front of the wall.

    Attributes:
        n_views: Number of images.
        distance_range_m: (min, max) distance from the camera centre to the wall along the
            optical axis, metres; stratified so every part of the range is used.
        tilt_range_deg: (min, max) angle between the optical axis and the wall normal,
            degrees (stratified too); the direction of the tilt is uniform.
        roll_range_deg: (min, max) rotation of the camera about its optical axis, degrees.
        target_spread_m: The optical axes hit the wall within +-spread of the world origin
            in x and y, metres.
        exposure_times_s: The shutter times an image may get (chosen at random), seconds.
    """

    n_views: int = 12
    distance_range_m: tuple[float, float] = (0.8, 2.5)
    tilt_range_deg: tuple[float, float] = (0.0, 35.0)
    roll_range_deg: tuple[float, float] = (-30.0, 30.0)
    target_spread_m: float = 0.3
    exposure_times_s: tuple[float, ...] = (1 / 60, 1 / 50, 1 / 40, 1 / 30)

    def __post_init__(self) -> None:
        _check_positive_int("n_views", self.n_views)
        _check_range("distance_range_m", self.distance_range_m, low=1e-3, high=1e3)
        _check_range("tilt_range_deg", self.tilt_range_deg, low=0.0, high=_MAX_TILT_DEG)
        _check_range("roll_range_deg", self.roll_range_deg, low=-180.0, high=180.0)
        if not (math.isfinite(self.target_spread_m) and self.target_spread_m >= 0.0):
            raise InputError(
                "target_spread_m", f"expected a finite value >= 0, got {self.target_spread_m!r}"
            )
        times = self.exposure_times_s
        if len(times) == 0 or not all(math.isfinite(t) and t > 0.0 for t in times):
            raise InputError(
                "exposure_times_s", f"expected one or more times > 0 seconds, got {times!r}"
            )


def _stratified(n: int, low: float, high: float, rng: np.random.Generator) -> NDArray[np.float64]:
    """(n,) one uniform sample in each of n equal strata of [low, high], in random order."""
    strata = (np.arange(n) + rng.uniform(size=n)) / n
    return low + (high - low) * strata[rng.permutation(n)]


def sample_views(config: SceneConfig, rng: np.random.Generator) -> list[View]:
    """Camera poses looking at the wall, exposure 1.

    Each camera looks at a target point T on the wall (its optical axis hits the wall
    there, so the principal point sees the wall), from distance d along the axis at tilt
    alpha from the wall normal in a random direction, then rolls about the axis.
    Distances and tilts are stratified (a Latin hypercube): n views cover n strata of
    each range.

    Args:
        config: The ranges.
        rng: Randomness.

    Returns:
        n_views views; `View.center_world` z = d cos(alpha) > 0.
    """
    n = config.n_views
    d_lo, d_hi = config.distance_range_m
    distances = _stratified(n, d_lo, d_hi, rng)
    tilt_lo, tilt_hi = config.tilt_range_deg
    tilts = _stratified(n, math.radians(tilt_lo), math.radians(tilt_hi), rng)
    azimuths = rng.uniform(0.0, 2.0 * math.pi, size=n)
    roll_lo, roll_hi = config.roll_range_deg
    rolls = rng.uniform(math.radians(roll_lo), math.radians(roll_hi), size=n)
    spread = config.target_spread_m
    targets = rng.uniform(-spread, spread, size=(n, 2))
    views = []
    for i in range(n):
        a, b = float(tilts[i]), float(azimuths[i])
        toward_camera = np.array(
            [math.sin(a) * math.cos(b), math.sin(a) * math.sin(b), math.cos(a)]
        )
        target = np.array([targets[i, 0], targets[i, 1], 0.0])
        center = target + distances[i] * toward_camera
        # World +y is "down" in the image before the roll (any up not along the axis works:
        # tilt <= 80 degrees keeps -y away from the axis).
        base = View.looking_at(center, target, up_world=(0.0, -1.0, 0.0))
        R = _rotation_z(float(rolls[i])) @ base.R_camera_world
        views.append(View(R, -R @ center, 1.0))
    return views


def sample_exposure_times(config: SceneConfig, rng: np.random.Generator) -> NDArray[np.float64]:
    """(n_views,) shutter times, seconds, drawn from `config.exposure_times_s`."""
    choices = np.asarray(config.exposure_times_s, dtype=np.float64)
    return choices[rng.integers(0, choices.size, size=config.n_views)]


def perturb_view(
    view: View, rng: np.random.Generator, *, position_sigma_m: float, angle_sigma_rad: float
) -> View:
    """The pose a marker detector or SfM would report: the true one plus Gaussian error.

    The camera centre moves by N(0, position_sigma_m^2) along each world axis; the rotation
    is `exp(delta) @ R_camera_world` with delta ~ N(0, angle_sigma_rad^2) per camera axis.

    Args:
        view: The true view.
        rng: Randomness.
        position_sigma_m: Standard deviation of each centre coordinate, metres (>= 0).
        angle_sigma_rad: Standard deviation of each rotation-vector component, radians (>= 0).

    Returns:
        The perturbed view, same exposure.
    """
    delta = rng.normal(0.0, 1.0, size=3) * angle_sigma_rad
    shift = rng.normal(0.0, 1.0, size=3) * position_sigma_m
    R = matrix_from_rotvec(delta) @ view.R_camera_world
    center = view.center_world + shift
    return View(R, -R @ center, view.exposure)


# -------------------------------------------------------------------------------- lights


@dataclass(frozen=True)
class RigConfig:
    """The lights mounted on the camera.

    Attributes:
        n_lights: Number of lights; light j sits at azimuth psi_0 + 2 pi j / n around the
            optical axis (psi_0 within +-20 degrees of the camera's +x: beside the camera).
        model: Angular profile of every light (`LightModel`).
        half_angle_deg: Half-intensity angle of the profile, degrees (along the beam's
            long axis for `table2d`).
        radius_range_m: (min, max) distance of a light from the optical axis, metres.
        forward_range_m: (min, max) position of a light along the optical axis, metres.
        max_axis_tilt_deg: A light's axis points within this angle of the optical axis.
        beam_aspect: `table2d`: half angle across the beam / along it (0 < aspect <= 1).
        beam_skew: `table2d`: lopsidedness s of f = cos^m(phi)(theta) (1 + s sin(theta) cos(phi)).
    """

    n_lights: int = 1
    model: LightModel = "cos_power"
    half_angle_deg: float = 30.0
    radius_range_m: tuple[float, float] = (0.08, 0.12)
    forward_range_m: tuple[float, float] = (-0.02, 0.02)
    max_axis_tilt_deg: float = 20.0
    beam_aspect: float = 0.6
    beam_skew: float = 0.25

    def __post_init__(self) -> None:
        _check_positive_int("n_lights", self.n_lights)
        if self.model not in LIGHT_MODELS:
            raise InputError(
                "model", f"expected one of {', '.join(LIGHT_MODELS)}, got {self.model!r}"
            )
        if not (math.isfinite(self.half_angle_deg) and 0.0 < self.half_angle_deg < 85.0):
            raise InputError(
                "half_angle_deg",
                f"expected a value in (0, 85) degrees, got {self.half_angle_deg!r}",
            )
        _check_range("radius_range_m", self.radius_range_m, low=0.0, high=1.0)
        _check_range("forward_range_m", self.forward_range_m, low=-0.5, high=0.5)
        if not (0.0 <= self.max_axis_tilt_deg <= 60.0):
            raise InputError(
                "max_axis_tilt_deg",
                f"expected a value in [0, 60] degrees, got {self.max_axis_tilt_deg!r}",
            )
        if not (0.0 < self.beam_aspect <= 1.0):
            raise InputError("beam_aspect", f"expected a value in (0, 1], got {self.beam_aspect!r}")
        if not (0.0 <= self.beam_skew < 1.0):
            raise InputError("beam_skew", f"expected a value in [0, 1), got {self.beam_skew!r}")


def symmetric_profile_table(
    half_angle_deg: float,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """A smooth measured-like LED profile f = cos(theta)^m (1 + b sin^2 theta), b = 0.5.

    m is chosen so that f(half_angle) = 0.5 exactly. Sampled every `TABLE_STEP_DEG`
    from 0 to 90 degrees (f(90) = 0).

    Returns:
        theta_deg: (n,) angles from the axis, degrees.
        values: (n,) relative intensities, values[0] = 1.
    """
    h = math.radians(half_angle_deg)
    b = _PROFILE_SHOULDER
    m = math.log(0.5 / (1.0 + b * math.sin(h) ** 2)) / math.log(math.cos(h))
    theta_deg = np.arange(0.0, 90.0 + TABLE_STEP_DEG / 2, TABLE_STEP_DEG)
    theta = np.radians(theta_deg)
    values = np.cos(theta).clip(0.0, None) ** m * (1.0 + b * np.sin(theta) ** 2)
    values[-1] = 0.0  # cos(pi / 2) is 6e-17, not 0
    return theta_deg, values


def elliptical_beam_table(
    half_angle_deg: float, *, aspect: float, skew: float
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """A lopsided elliptical beam f(theta, phi) = cos(theta)^m(phi) (1 + s sin(theta) cos(phi)).

    The half-intensity angle of the cos^m factor runs over an ellipse: `half_angle_deg`
    along phi = 0 (the light's +x), `aspect * half_angle_deg` along phi = 90 degrees;
    the skew s tilts the beam's brightest part towards +x, so no rotation about the axis
    leaves the beam unchanged.

    Returns:
        theta_deg: (n_t,) 0..90 degrees every `TABLE_STEP_DEG`.
        phi_deg: (n_p,) 0..350 degrees every `AZIMUTH_STEP_DEG` (light-frame azimuths).
        values: (n_p, n_t) relative intensities, 1 on the axis.
    """
    theta_deg = np.arange(0.0, 90.0 + TABLE_STEP_DEG / 2, TABLE_STEP_DEG)
    phi_deg = np.arange(0.0, 360.0 - AZIMUTH_STEP_DEG / 2, AZIMUTH_STEP_DEG)
    h_long = math.radians(half_angle_deg)
    h_short = h_long * aspect
    phi = np.radians(phi_deg)[:, None]
    half = 1.0 / np.sqrt((np.cos(phi) / h_long) ** 2 + (np.sin(phi) / h_short) ** 2)
    m = -math.log(2.0) / np.log(np.cos(half))
    theta = np.radians(theta_deg)[None, :]
    values = np.cos(theta).clip(0.0, None) ** m * (1.0 + skew * np.sin(theta) * np.cos(phi))
    values[:, -1] = 0.0
    return theta_deg, phi_deg, values


def make_rid(config: RigConfig) -> RID:
    """The RID of the configured profile (tables built in memory)."""
    half = math.radians(config.half_angle_deg)
    if config.model == "isotropic":
        return IsotropicRID()
    if config.model == "cos_power":
        return CosPowerRID.from_half_angle(half)
    if config.model == "gaussian":
        return GaussianRID.from_half_angle(half)
    if config.model in ("table", "ies"):
        theta_deg, values = symmetric_profile_table(config.half_angle_deg)
        return SymmetricTableRID(np.radians(theta_deg), values)
    theta_deg, phi_deg, values2 = elliptical_beam_table(
        config.half_angle_deg, aspect=config.beam_aspect, skew=config.beam_skew
    )
    return Table2DRID(np.radians(theta_deg), np.radians(phi_deg), values2)


def light_names(n_lights: int) -> list[str]:
    """`["light"]` for one light, else `["light_1", ..., "light_n"]`."""
    return ["light"] if n_lights == 1 else [f"light_{j + 1}" for j in range(n_lights)]


def sample_rig(config: RigConfig, rng: np.random.Generator) -> Rig:
    """Lights beside the camera with relative scales (the first 1, others 0.6..1.4).

    Positions: radius r ~ U(radius_range_m) from the optical axis at azimuth
    psi_0 + 2 pi j / n (psi_0 ~ U(-20, 20) degrees from the camera's +x), forward offset
    ~ U(forward_range_m). Axes: tilted from the optical axis by U(0, max_axis_tilt_deg)
    in a uniform direction. Isotropic lights get R = I, symmetric ones the minimal
    rotation from +z (`rotation_from_axis`: their roll is unobservable), 2-D tables a
    random roll about their axis as well.

    Args:
        config: The rig.
        rng: Randomness.

    Returns:
        The rig; `Light.scale` is relative (multiply by `signal_scale` for DN).
    """
    n = config.n_lights
    rid = make_rid(config)
    psi0 = math.radians(rng.uniform(-20.0, 20.0))
    names = light_names(n)
    lights = []
    for j in range(n):
        radius = rng.uniform(*config.radius_range_m)
        forward = rng.uniform(*config.forward_range_m)
        psi = psi0 + 2.0 * math.pi * j / n
        position = np.array([radius * math.cos(psi), radius * math.sin(psi), forward])
        tilt = math.radians(rng.uniform(0.0, config.max_axis_tilt_deg))
        direction = rng.uniform(0.0, 2.0 * math.pi)
        roll = rng.uniform(0.0, 2.0 * math.pi)
        scale = 1.0 if j == 0 else float(rng.uniform(0.6, 1.4))
        axis = np.array(
            [
                math.sin(tilt) * math.cos(direction),
                math.sin(tilt) * math.sin(direction),
                math.cos(tilt),
            ]
        )
        if config.model == "isotropic":
            R = np.eye(3)
        elif rid.symmetric:
            R = rotation_from_axis(axis)
        else:
            R = rotation_from_axis(axis) @ _rotation_z(roll)
        lights.append(Light(rid, position, R, scale=scale, name=names[j]))
    return Rig(tuple(lights))


def initial_guess(
    light: Light, rng: np.random.Generator, *, offset_m: float, offset_rad: float
) -> Light:
    """A deliberately wrong starting point: the truth moved by exactly `offset_m` in a
    random direction and its axis turned by exactly `offset_rad` (about a random direction
    perpendicular to the axis). An isotropic light keeps its rotation.

    Args:
        light: The true light.
        rng: Randomness.
        offset_m: Distance between the true and the initial position, metres.
        offset_rad: Angle between the true and the initial axis, radians.

    Returns:
        The initial light (same RID, scale and name).
    """
    position = light.t_camera_light + offset_m * _unit_vector(rng)
    turn_axis = _unit_perpendicular(light.axis_camera, rng)
    R = light.R_camera_light
    if not isinstance(light.rid, IsotropicRID):
        R = matrix_from_rotvec(offset_rad * turn_axis) @ R
    return light.replace(t_camera_light=position, R_camera_light=R)


def describe_rid(rid: RID) -> dict[str, object]:
    """A JSON-ready description of a RID for truth files (tables in degrees)."""
    if isinstance(rid, IsotropicRID):
        return {"type": "isotropic"}
    if isinstance(rid, CosPowerRID):
        return {"type": "cos_power", "m": rid.m, "half_angle_deg": math.degrees(rid.half_angle_rad)}
    if isinstance(rid, GaussianRID):
        return {
            "type": "gaussian",
            "sigma_deg": math.degrees(rid.sigma_rad),
            "half_angle_deg": math.degrees(rid.half_angle_rad),
        }
    if isinstance(rid, SymmetricTableRID):
        return {
            "type": "table",
            "theta_deg": np.degrees(rid.theta_rad).tolist(),
            "values": rid.values.tolist(),
            "half_angle_deg": math.degrees(rid.half_angle_rad),
        }
    if isinstance(rid, Table2DRID):
        return {
            "type": "table2d",
            "theta_deg": np.degrees(rid.theta_rad).tolist(),
            "phi_deg": np.degrees(rid.phi_rad).tolist(),
            "values": rid.values.tolist(),
        }
    raise InputError("rid", f"expected one of the lightcal RID models, got {type(rid).__name__}")


# -------------------------------------------------------------------------------- sensor


@dataclass(frozen=True)
class SensorConfig:
    """The camera's sensor.

    Attributes:
        bit_depth: Bits per sample (10, 12, 14 or 16); white level 2^bits - 1.
        full_well_e: Electrons that fill the usable range (white - black).
        read_noise_e: Standard deviation of the read noise, electrons.
        black_level_dn: Black level, DN; None: 2^(bits - 5) (512 for 14 bits).
        exposure_target: The brightest expected pixel sits at this fraction of the usable
            range (values > 1 saturate on purpose).
        noise: False: no shot or read noise (values are only rounded).
        model: Fall-off model of docs/model.md the images follow ("radiance", "cos4", "paper",
            "map").
        vignetting_coeffs: c_1, c_2, ... of a centred `RadialVignetting`; required for
            (and only for) model "map".
    """

    bit_depth: int = 14
    full_well_e: float = 20000.0
    read_noise_e: float = 3.0
    black_level_dn: float | None = None
    exposure_target: float = 0.7
    noise: bool = True
    model: SensorModel = "radiance"
    vignetting_coeffs: tuple[float, ...] | None = None

    def __post_init__(self) -> None:
        if self.bit_depth not in (10, 12, 14, 16):
            raise InputError("bit_depth", f"expected 10, 12, 14 or 16, got {self.bit_depth!r}")
        if not (math.isfinite(self.full_well_e) and self.full_well_e > 0.0):
            raise InputError("full_well_e", f"expected a value > 0, got {self.full_well_e!r}")
        if not (math.isfinite(self.read_noise_e) and self.read_noise_e >= 0.0):
            raise InputError("read_noise_e", f"expected a value >= 0, got {self.read_noise_e!r}")
        white = 2**self.bit_depth - 1
        if self.black_level_dn is not None and not (0.0 <= self.black_level_dn < white):
            raise InputError(
                "black_level_dn",
                f"expected a value in [0, {white}) for {self.bit_depth} bits, "
                f"got {self.black_level_dn!r}",
            )
        if not (math.isfinite(self.exposure_target) and self.exposure_target > 0.0):
            raise InputError(
                "exposure_target", f"expected a value > 0, got {self.exposure_target!r}"
            )
        if self.model not in ("radiance", "cos4", "paper", "map"):
            raise InputError("model", f"expected radiance, cos4, paper or map, got {self.model!r}")
        if (self.model == "map") != (self.vignetting_coeffs is not None):
            raise InputError(
                "vignetting_coeffs",
                "expected radial vignetting coefficients with the 'map' sensor model and "
                f"none with the others, got model {self.model!r} and "
                f"coefficients {self.vignetting_coeffs!r}",
            )
        if self.vignetting_coeffs is not None and (
            len(self.vignetting_coeffs) == 0
            or not all(math.isfinite(c) for c in self.vignetting_coeffs)
        ):
            raise InputError(
                "vignetting_coeffs",
                f"expected one or more finite coefficients, got {self.vignetting_coeffs!r}",
            )

    @property
    def black_level(self) -> float:
        """The black level in DN (the default filled in)."""
        if self.black_level_dn is None:
            return float(2 ** (self.bit_depth - 5))
        return float(self.black_level_dn)


def white_level(config: SensorConfig) -> float:
    """2^bits - 1, DN."""
    return float(2**config.bit_depth - 1)


def conversion_gain(config: SensorConfig) -> float:
    """DN per photo-electron: the full well fills the range above the black level."""
    return (white_level(config) - config.black_level) / config.full_well_e


def noise_model(config: SensorConfig) -> tuple[float, float]:
    """The Poisson-Gaussian noise of black-subtracted values, variance = gain m + read_variance.

    Returns:
        gain: DN per electron (0 without noise).
        read_variance: (DN per electron x read noise)^2 + 1/12 (quantisation), DN^2;
            1/12 alone without noise.
    """
    if not config.noise:
        return 0.0, 1.0 / 12.0
    g = conversion_gain(config)
    return g, (g * config.read_noise_e) ** 2 + 1.0 / 12.0


def signal_scale(peak: float, config: SensorConfig) -> float:
    """The light scale k (DN per unit of the rendered signal) putting `peak` at the target.

    Args:
        peak: The brightest rendered value of the dataset with unit (relative) scales.
        config: The sensor.

    Returns:
        exposure_target x (white - black) / peak.
    """
    if not (math.isfinite(peak) and peak > 0.0):
        raise InputError(
            "lights",
            f"the lights illuminate nothing the camera sees (peak signal {peak!r}); "
            "expected lights in front of the wall pointing at it",
        )
    return config.exposure_target * (white_level(config) - config.black_level) / peak


def vignetting_image(config: SensorConfig, camera: Camera) -> NDArray[np.float64] | None:
    """(H, W) the radial fall-off of the "map" model (centred, 1 at the centre), else None."""
    if config.vignetting_coeffs is None:
        return None
    model = RadialVignetting.centred(
        np.array(config.vignetting_coeffs), width=camera.width, height=camera.height
    )
    values = model.image()
    if not np.all(values > 0.0):
        raise InputError(
            "vignetting_coeffs",
            f"the fall-off reaches {float(values.min()):.3g} inside the image; expected V > 0",
        )
    return values


def peak_signal(
    camera: Camera,
    views: list[View],
    rig: Rig,
    *,
    sensor: SensorModel = "radiance",
    vignetting: NDArray[np.float64] | None = None,
    max_pixels: int = 100_000,
) -> float:
    """The brightest rendered value over the views (exposures included).

    Images of at most `max_pixels` pixels are rendered whole (the exact maximum); larger
    ones on a regular grid of about `max_pixels` pixels: a smooth beam's maximum is then
    found to a fraction of a percent, at a fraction of the cost of a render.

    Returns:
        The maximum value (0 when nothing is lit).
    """
    n_pixels = camera.width * camera.height
    pixels = None
    if n_pixels > max_pixels:
        stride = math.ceil(math.sqrt(n_pixels / max_pixels))
        vv, uu = np.mgrid[0 : camera.height : stride, 0 : camera.width : stride]
        pixels = np.stack([uu.ravel(), vv.ravel()], axis=1)
    peak = 0.0
    for view in views:
        if pixels is None:
            values = render_image(camera, view, rig, sensor=sensor, vignetting=vignetting)
        else:
            values = render_pixels(camera, view, rig, pixels, sensor=sensor, vignetting=vignetting)
        if values.count() > 0:
            peak = max(peak, float(values.max()))
    return peak


def apply_sensor(
    signal_dn: np.ma.MaskedArray | NDArray[np.float64],
    config: SensorConfig,
    rng: np.random.Generator,
) -> tuple[NDArray[np.uint16], NDArray[np.bool_]]:
    """Turn the expected signal into raw sensor values.

    photo-electrons ~ Poisson(signal / gain), plus N(0, read_noise_e^2) electrons; back to
    DN (x gain), plus the black level, rounded to integers and clipped to
    [0, 2^bits - 1]. Masked (invalid) pixels have no signal: black level plus read noise.
    Without noise the value is round(signal + black).

    Args:
        signal_dn: (H, W) expected value above the black level, DN (masked where invalid).
        config: The sensor.
        rng: Randomness (unused without noise).

    Returns:
        dn: (H, W) uint16 raw values.
        saturated: (H, W) True where the value was clipped at the white level.
    """
    signal = np.ma.filled(np.ma.masked_invalid(signal_dn), 0.0).astype(np.float64)
    if signal.ndim != 2:
        raise InputError("signal_dn", f"expected an (H, W) image, got shape {signal.shape}")
    signal = np.clip(signal, 0.0, None)
    white = white_level(config)
    black = config.black_level
    if config.noise:
        g = conversion_gain(config)
        electrons = rng.poisson(signal / g).astype(np.float64)
        electrons += rng.normal(0.0, config.read_noise_e, size=signal.shape)
        raw = electrons * g + black
    else:
        raw = signal + black
    raw = np.rint(raw)
    saturated = raw >= white
    dn = np.clip(raw, 0.0, white).astype(np.uint16)
    return dn, saturated
