"""`lightcal synth --port`: the beam seen through the camera's flat port, computed
independently of the renderer (`lightcal.core.port_footprints`).

Each pixel is point-sampled at its centre, as the bowed wall is
(`lightcal.synthetic.height_field`): its ray, undistorted, is refracted through the
port by Snell's law in its scalar form (the angle from the port's normal in each layer,
n sin(theta) the same in air, glass and water; the ray shifted sideways by d tan(theta_air)
+ t tan(theta_glass)), and meets the wall z = 0 at P. The value is the irradiance of
each light there, scale x exposure x f(theta, phi) cos(i) / r^2, times the sensor's
point term (`point_sensor_weights`) and by the port's Fresnel transmittance at the
ray's angle (`_fresnel_plate`: Fresnel's equations in their sine and tangent form,
r_s = -sin(i - t) / sin(i + t), r_p = tan(i - t) / tan(i + t), and the light reflected
back and forth between the faces summed as a series, per polarisation; the renderer
uses `lightcal.core.fresnel`, written otherwise): the footprint mean the renderer
computes, to second order in the footprint's size. The water's attenuation on the
camera's side runs from the ray's exit point X_p (`Imaging.beam`).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from lightcal.core.camera import Camera
from lightcal.core.flat_port import FlatPort
from lightcal.core.footprint import SensorModel
from lightcal.core.scene import Rig, View
from lightcal.synthetic.height_field import point_sensor_weights

__all__ = ["port_shading"]


def _interface_reflectances(
    n_1: float, n_2: float, theta_i: NDArray[np.float64], theta_t: NDArray[np.float64]
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """(R_s, R_p) of an interface n_1 -> n_2, angles of incidence and refraction (M,),
    radians: Fresnel's sine and tangent form, its limit ((n_1 - n_2) / (n_1 + n_2))^2 at
    normal incidence."""
    normal = ((n_1 - n_2) / (n_1 + n_2)) ** 2
    at_normal = theta_i == 0.0
    with np.errstate(invalid="ignore", divide="ignore"):
        r_s = np.sin(theta_i - theta_t) / np.sin(theta_i + theta_t)
        r_p = np.tan(theta_i - theta_t) / np.tan(theta_i + theta_t)
    return np.where(at_normal, normal, r_s * r_s), np.where(at_normal, normal, r_p * r_p)


def _fresnel_plate(
    port: FlatPort,
    theta_air: NDArray[np.float64],
    theta_glass: NDArray[np.float64],
    theta_water: NDArray[np.float64],
) -> NDArray[np.float64]:
    """(M,) the fraction of unpolarised light crossing both faces: per polarisation the
    series T_1 T_2 sum_k (R_1 R_2)^k of the light reflected 2k times inside the glass
    (R_1 R_2 < 0.012 up to 89 degrees in the air for acrylic into water: 8 terms are
    exact to round-off), then the mean. A port of thickness 0 is one interface."""
    n_a, n_g, n_w = port.air_index, port.glass_index, port.water_index
    if port.thickness_m == 0.0:  # one interface air -> water: no glass
        n_g, theta_glass = n_w, theta_water
    total = np.zeros_like(theta_air)
    inner = _interface_reflectances(n_a, n_g, theta_air, theta_glass)
    outer = _interface_reflectances(n_g, n_w, theta_glass, theta_water)
    for r_1, r_2 in zip(inner, outer, strict=True):
        series = sum((r_1 * r_2) ** k for k in range(8))
        total = total + 0.5 * (1.0 - r_1) * (1.0 - r_2) * series
    return total


def _scalar_snell(
    rays: NDArray[np.float64], port: FlatPort
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """Exit points and water directions (M, 3), camera frame, of rays (M, 3) (z > 0),
    and (M,) their Fresnel transmittance through the port."""
    n = port.normal_camera
    r = rays / np.linalg.norm(rays, axis=1, keepdims=True)
    along = r @ n
    perp = r - along[:, None] * n[None, :]
    s = np.linalg.norm(perp, axis=1)
    e = np.where(s[:, None] > 0.0, perp / np.where(s > 0.0, s, 1.0)[:, None], 0.0)
    theta_air = np.arctan2(s, along)
    invariant = port.air_index * np.sin(theta_air)
    theta_glass = np.arcsin(invariant / port.glass_index)
    theta_water = np.arcsin(invariant / port.water_index)
    shift = port.distance_m * np.tan(theta_air) + port.thickness_m * np.tan(theta_glass)
    exits = shift[:, None] * e + (port.distance_m + port.thickness_m) * n[None, :]
    water = np.sin(theta_water)[:, None] * e + np.cos(theta_water)[:, None] * n[None, :]
    return exits, water, _fresnel_plate(port, theta_air, theta_glass, theta_water)


def port_fresnel_image(camera: Camera, port: FlatPort) -> NDArray[np.float64]:
    """(H, W) the port's Fresnel transmittance of each pixel centre's ray (its own
    formula, `_fresnel_plate`): what the light of the water (the veil) and the room
    light seen through the port carry into the camera, as the wall's does."""
    h, w = camera.height, camera.width
    v, u = np.mgrid[0:h, 0:w]
    xy, ok = camera.pixels_to_normalized(np.stack([u.ravel(), v.ravel()], axis=1).astype(float))
    rays = np.concatenate([np.where(ok[:, None], xy, 0.0), np.ones((h * w, 1))], axis=1)
    _, _, fresnel = _scalar_snell(rays, port)
    return np.asarray(fresnel, dtype=np.float64).reshape(h, w)


def port_shading(
    camera: Camera,
    view: View,
    rig: Rig,
    port: FlatPort,
    *,
    sensor: SensorModel,
    vignetting: NDArray[np.float64] | None,
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.bool_], NDArray[np.float64]]:
    """Each light's point-sampled value through the port (module docstring).

    Returns:
        values: (L, H, W) each light's contribution, scale and exposure included (NaN
            where the pixel is not valid).
        points: (H, W, 3) the pixel centres' wall points, world frame, m.
        valid: (H, W) the centre's ray meets the wall in front of the port.
        exits: (H, W, 3) where the rays leave the port, world frame, m.
    """
    if sensor == "paper":
        raise ValueError("port: not rendered for the 'paper' sensor model")
    h, w = camera.height, camera.width
    v, u = np.mgrid[0:h, 0:w]
    xy, ok = camera.pixels_to_normalized(np.stack([u.ravel(), v.ravel()], axis=1).astype(float))
    rays = np.concatenate([np.where(ok[:, None], xy, 0.0), np.ones((h * w, 1))], axis=1)
    exits_c, water_c, fresnel = _scalar_snell(rays, port)
    R, C = view.R_camera_world, view.center_world
    exits = exits_c @ R + C
    water = water_c @ R
    with np.errstate(invalid="ignore", divide="ignore"):
        lam = -exits[:, 2] / water[:, 2]
    ok &= (water[:, 2] < 0.0) & (lam > 0.0)
    points = exits + np.where(ok, lam, 0.0)[:, None] * water
    points[:, 2] = 0.0
    term, term_ok = point_sensor_weights(camera, sensor, vignetting)
    ok &= term_ok.ravel()
    term = term.ravel() * fresnel
    values = np.full((len(rig.lights), h * w), np.nan)
    for k, light in enumerate(rig.lights):
        L = light.position_world(view)
        if L[2] <= 0.0:
            values[k, ok] = 0.0
            continue
        to = points - L
        r = np.linalg.norm(to, axis=1)
        local = (to / r[:, None]) @ light.rotation_world(view)  # light frame
        theta = np.arccos(np.clip(local[:, 2], -1.0, 1.0))
        phi = np.arctan2(local[:, 1], local[:, 0])
        f = np.asarray(light.rid(theta, phi), dtype=np.float64)
        e = light.scale * view.exposure * f * (L[2] / r) / (r * r) * term
        values[k] = np.where(ok, e, np.nan)
    return (
        values.reshape(len(rig.lights), h, w),
        points.reshape(h, w, 3),
        ok.reshape(h, w),
        exits.reshape(h, w, 3),
    )
