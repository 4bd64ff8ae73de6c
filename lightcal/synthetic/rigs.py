"""Synthetic light rigs: lights mounted beside the camera, their RIDs and a wrong start.

- `sample_rig`: one or more lights beside the camera (a few to 30 cm), axes within a few
  tens of degrees of the optical axis, with one of six angular profiles (`LightModel`).
- `make_rid` and the tables it builds (`symmetric_profile_table`, `elliptical_beam_table`);
  `describe_rid` for the ground truth.
- `initial_guess`: the deliberately wrong starting point of a calibration.

Frames and units: docs/conventions.md (a light's +z is its axis; metres, radians).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from lightcal.core.pose import rotation_from_axis
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
from lightcal.errors import InputError
from lightcal.synthetic.light_models import LIGHT_MODELS, LightModel
from lightcal.synthetic.sampling import (
    check_positive_int,
    check_range,
    random_unit_perpendicular,
    random_unit_vector,
    rotation_z,
)

TABLE_STEP_DEG = 2.5
"""Angular step of the synthetic tables (vertical angles 0..90 degrees)."""

AZIMUTH_STEP_DEG = 10.0
"""Azimuth step of the 2-D table (36 planes over the full circle)."""

_PROFILE_SHOULDER = 0.5
"""b of the symmetric table profile cos(theta)^m (1 + b sin^2 theta)."""


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
        check_positive_int("n_lights", self.n_lights)
        if self.model not in LIGHT_MODELS:
            raise InputError(
                "model", f"expected one of {', '.join(LIGHT_MODELS)}, got {self.model!r}"
            )
        if not (math.isfinite(self.half_angle_deg) and 0.0 < self.half_angle_deg < 85.0):
            raise InputError(
                "half_angle_deg",
                f"expected a value in (0, 85) degrees, got {self.half_angle_deg!r}",
            )
        check_range("radius_range_m", self.radius_range_m, low=0.0, high=1.0)
        check_range("forward_range_m", self.forward_range_m, low=-0.5, high=0.5)
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
            R = rotation_from_axis(axis) @ rotation_z(roll)
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
    position = light.t_camera_light + offset_m * random_unit_vector(rng)
    turn_axis = random_unit_perpendicular(light.axis_camera, rng)
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


def check_in_front(lights: list[Light], views: list[View]) -> None:
    """Every light is in front of the wall in every view (world z > 0), as a project
    demands of its initial guesses: checked before the images are rendered."""
    for light in lights:
        for i, view in enumerate(views):
            z = float(light.position_world(view)[2])
            if z <= 0.0:
                raise InputError(
                    "lights",
                    f"the initial guess of light {light.name!r} is on or behind the wall in "
                    f"view {i} (world z = {z:.3g} m); expected it in front (z > 0): a larger "
                    "--distance, or a smaller --light-radius-m or --init-offset-m",
                )
