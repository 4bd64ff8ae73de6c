"""What truth.json records of a dataset's departures (`lightcal.synthetic.departures`).

`departures_truth` returns the "departures" entry: each departure the data has, by name,
with its parameters (distances in metres or as the option's unit in the key's name,
angles in degrees):

- `ambient`: fraction, reference_view, reference_peak_dn, reference_exposure,
  per_exposure_dn, levels_dn (one per view, DN);
- `undeclared_vignetting`: coeffs [k1, k2], center_px, norm_radius_px, formula,
  declared_sensor;
- `rid_rim`: amplitude, width_fraction, half_angle_deg (a number, or one per
  azimuths_deg of a 2-D table), formula, declared_rid;
- `gamma`: gamma, black_level_dn, white_level_dn, formula;
- `pose_error`: position_sigma_mm, angle_sigma_deg, declared_position_sigma_mm,
  declared_angle_sigma_deg;
- `bow`: depth_mm, center_world_m [x0, y0], radius_m, shape, formula;
- `albedo_texture`: amplitude, wavelengths_m, directions_deg, phases_rad, weights,
  formula;
- `attenuation`: coefficient_per_m, formula.
- `backscatter`: beta_per_m, phase_g, formula.
- `corner`: distance_m, depth_m, albedo, surroundings (the surfaces), rendered_as.
- `port`: distance_mm, thickness_mm, glass_index, water_index, rendered_as.

The true lights (the rimmed profile included) are in truth.json's "lights" as always.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from lightcal.core.rid import RID, Table2DRID
from lightcal.core.vignetting import RadialVignetting
from lightcal.synthetic.departures import RIM_WIDTH_FRACTION, Departures
from lightcal.synthetic.imaging import AmbientLevels, Imaging
from lightcal.synthetic.rid_rim import AZIMUTH_STEP_DEG, half_angles_rad
from lightcal.synthetic.sensor import SensorConfig, white_level

__all__ = ["departures_truth"]


def _rim(declared: RID, amplitude: float, declared_truth: dict[str, Any]) -> dict[str, Any]:
    out: dict[str, Any] = {"amplitude": amplitude, "width_fraction": RIM_WIDTH_FRACTION}
    if isinstance(declared, Table2DRID):
        phi = np.radians(np.arange(0.0, 360.0 - AZIMUTH_STEP_DEG / 2, AZIMUTH_STEP_DEG))
        out["azimuths_deg"] = np.degrees(phi).tolist()
        out["half_angle_deg"] = np.degrees(half_angles_rad(declared, phi)).tolist()
    else:
        out["half_angle_deg"] = math.degrees(declared.half_angle_rad)
    out["formula"] = (
        "declared(theta, phi) * (1 + amplitude * exp(-((theta - half_angle) / "
        "(width_fraction * half_angle))^2))"
    )
    out["declared_rid"] = declared_truth
    return out


def departures_truth(
    departures: Departures,
    imaging: Imaging,
    *,
    ambient: AmbientLevels | None,
    view_names: list[str],
    declared_rid: RID,
    declared_rid_truth: dict[str, Any],
    pose_noise_m: float,
    pose_noise_deg: float,
    sensor: SensorConfig,
) -> dict[str, dict[str, Any]]:
    """The "departures" entry of truth.json (module docstring); {} without departures.

    Args:
        departures: The configuration.
        imaging: The dataset's imaging (its bow, texture, fall-off).
        ambient: The ambient levels, when the data has room light.
        view_names: (n,) the views' names.
        declared_rid: The light profile the project declares.
        declared_rid_truth: Its truth.json description (`describe_rid`, with its file).
        pose_noise_m: The declared pose noise (centre), metres.
        pose_noise_deg: The declared pose noise (rotation), degrees.
        sensor: The sensor (its black and white levels).
    """
    out: dict[str, dict[str, Any]] = {}
    names = departures.names
    if "ambient" in names and ambient is not None:
        out["ambient"] = {
            "fraction": ambient.fraction,
            "reference_view": view_names[ambient.reference],
            "reference_peak_dn": ambient.reference_peak_dn,
            "reference_exposure": ambient.reference_exposure,
            "per_exposure_dn": ambient.per_exposure_dn,
            "levels_dn": list(ambient.levels_dn),
        }
    if "undeclared_vignetting" in names and departures.undeclared_vignetting is not None:
        camera = imaging.camera
        model = RadialVignetting.centered(
            np.array(departures.undeclared_vignetting), width=camera.width, height=camera.height
        )
        out["undeclared_vignetting"] = {
            "coeffs": model.coeffs.tolist(),
            "center_px": model.center_px.tolist(),
            "norm_radius_px": model.norm_radius_px,
            "formula": "1 + k1 r^2 + k2 r^4, r = |(u, v) - center_px| / norm_radius_px",
            "declared_sensor": "radiance",
        }
    if "rid_rim" in names:
        out["rid_rim"] = _rim(declared_rid, departures.rid_rim_amplitude, declared_rid_truth)
    if "gamma" in names:
        out["gamma"] = {
            "gamma": departures.gamma,
            "black_level_dn": sensor.black_level,
            "white_level_dn": white_level(sensor),
            "formula": "stored = black + (white - black) * (max(x, 0) / (white - black))^(1 / "
            "gamma), x the linear value above black; then rounded and clipped",
        }
    if "pose_error" in names:
        out["pose_error"] = {
            "position_sigma_mm": departures.pose_error_m * 1000.0,
            "angle_sigma_deg": departures.pose_error_deg,
            "declared_position_sigma_mm": pose_noise_m * 1000.0,
            "declared_angle_sigma_deg": pose_noise_deg,
        }
    if "bow" in names and imaging.wall_shape is not None:
        shape = imaging.wall_shape
        out["bow"] = {
            "depth_mm": shape.depth_m * 1000.0,
            "center_world_m": list(shape.center_xy_m),
            "radius_m": shape.radius_m,
            "shape": "bulge towards the cameras" if shape.depth_m > 0.0 else "bowl",
            "formula": "z = depth * max(0, 1 - ((x - x0)^2 + (y - y0)^2) / radius^2)",
        }
    if "albedo_texture" in names and imaging.texture is not None:
        out["albedo_texture"] = imaging.texture.describe()
    if "attenuation" in names:
        out["attenuation"] = {
            "coefficient_per_m": departures.attenuation_per_m,
            "formula": "each light's value * exp(-coefficient * (d_light + d_camera))",
        }
    if "backscatter" in names:
        out["backscatter"] = {
            "beta_per_m": departures.backscatter_per_m,
            "phase_g": departures.phase_g,
            "formula": "each light adds scale * exposure * beta * S, S the single-scattering "
            "integral along the pixel's ray (lightcal.core.medium.backscatter)",
        }
    if "corner" in names and imaging.corner is not None:
        distance, depth, albedo = departures.corner or (0.0, 0.0, 0.0)
        out["corner"] = {
            "distance_m": distance,
            "depth_m": depth,
            "albedo": albedo,
            "surroundings": imaging.corner.surroundings.describe(),
            "rendered_as": "brute-force radiosity, every bounce, attenuated by the medium "
            "(lightcal.synthetic.bounce_reference); pixels that see a surface or wall it "
            "shadows are black",
        }
    if "port" in names and departures.port is not None:
        d_mm, t_mm, n_g, n_w = departures.port
        out["port"] = {
            "distance_mm": d_mm,
            "thickness_mm": t_mm,
            "glass_index": n_g,
            "water_index": n_w,
            "rendered_as": "each pixel centre's ray refracted by Snell's law (scalar form) "
            "into the water, the irradiance point-sampled on the wall, the camera's "
            "attenuation from the ray's exit point (lightcal.synthetic.port_imaging)",
        }
    if "light_port" in names and departures.light_port is not None:
        d_mm, t_mm, n_g, n_w = departures.light_port
        out["light_port"] = {
            "distance_mm": d_mm,
            "thickness_mm": t_mm,
            "glass_index": n_g,
            "water_index": n_w,
            "rendered_as": "each pixel centre's wall point reached from each light through "
            "its port (the air angle by bisection on the scalar path equation), the "
            "irradiance f(theta_a) T_Fresnel dOmega_air/dA point-sampled, the light's "
            "attenuation from the port (lightcal.synthetic.light_port_imaging)",
        }
    return out
