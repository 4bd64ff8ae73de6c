"""`lightcal synth --light-port`: the beam of lights behind a flat port, computed
independently of the renderer (`lightcal.core.light_port`, `light_port_flux`).

Each pixel is point-sampled at its centre's point P on the wall z = 0, as the bowed wall
is (`lightcal.synthetic.height_field`). For each light, in its frame (the port's normal
its axis), P lies at radial distance rho and axial distance h from the emitter; the air
angle theta_a of the ray that reaches P solves, by bisection,

    rho = d tan(theta_a) + t tan(theta_g) + (h - d - t) tan(theta_w),
    sin(theta_a) = n_g sin(theta_g) = n_w sin(theta_w).

The irradiance there is scale x f(theta_a, phi) x T_F(theta_a) x dOmega_a / dA: the
rays leaving into dOmega_a = sin(theta_a) dtheta_a dphi cross the plane z_light = h on
rho drho dphi, drho / dtheta_a = d / cos^2(theta_a) + t (dtheta_g / dtheta_a) /
cos^2(theta_g) + H (dtheta_w / dtheta_a) / cos^2(theta_w) (dtheta / dtheta_a =
cos(theta_a) / (n cos(theta))); that plane's element is the beam's cross-section over
cos(theta_w), and the wall's is the cross-section over |w . z_world|, w the water
direction. T_F is the plate's Fresnel transmittance (s and p, both faces, the inner
reflections summed incoherently), written out here. In water the light's path starts
at the port's outer face: its length is H / cos(theta_w), H = h - d - t.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from lightcal.core.camera import Camera
from lightcal.core.flat_port import FlatPort
from lightcal.core.footprint import SensorModel
from lightcal.core.scene import Rig, View
from lightcal.synthetic.height_field import BowedWall, point_sensor_weights, surface_points

__all__ = ["light_port_shading"]

#: Bisection steps on theta_a in [0, pi / 2]: 2^-60 of the interval, round-off.
BISECTIONS = 60


def _theta_air(
    rho: NDArray[np.float64], h: NDArray[np.float64], port: FlatPort
) -> NDArray[np.float64]:
    """The air angle reaching radial distance rho at axial distance h (bisection)."""
    d, t = port.distance_m, port.thickness_m
    n_g = port.glass_index / port.air_index
    n_w = port.water_index / port.air_index
    lo = np.zeros_like(rho)
    hi = np.full_like(rho, 0.5 * math.pi)
    for _ in range(BISECTIONS):
        mid = 0.5 * (lo + hi)
        s = np.sin(mid)
        reach = (
            d * np.tan(mid)
            + t * np.tan(np.arcsin(s / n_g))
            + (h - d - t) * np.tan(np.arcsin(s / n_w))
        )
        short = reach < rho
        lo = np.where(short, mid, lo)
        hi = np.where(short, hi, mid)
    return 0.5 * (lo + hi)


def _fresnel(theta_air: NDArray[np.float64], port: FlatPort) -> NDArray[np.float64]:
    """The plate's unpolarised transmittance at air angles theta_air."""
    n = (port.air_index, port.glass_index, port.water_index)
    invariant = n[0] * np.sin(theta_air)
    cosines = [np.cos(np.arcsin(invariant / k)) for k in n]
    total = np.zeros_like(theta_air)
    for s_wave in (True, False):
        reflect = []
        for a, b in ((0, 1), (1, 2)):
            ca, cb = cosines[a], cosines[b]
            if s_wave:
                amp = (n[a] * ca - n[b] * cb) / (n[a] * ca + n[b] * cb)
            else:
                amp = (n[b] * ca - n[a] * cb) / (n[b] * ca + n[a] * cb)
            reflect.append(amp * amp)
        r1, r2 = reflect
        total += (1.0 - r1) * (1.0 - r2) / (1.0 - r1 * r2)
    return 0.5 * total


def light_port_shading(
    camera: Camera,
    view: View,
    rig: Rig,
    port: FlatPort,
    *,
    sensor: SensorModel,
    vignetting: NDArray[np.float64] | None,
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.bool_], NDArray[np.float64]]:
    """Each light's point-sampled value through its port (module docstring); every
    light of `rig` sits behind a port like `port`.

    Returns:
        values: (L, H, W) each light's contribution, scale and exposure included, before
            the water (NaN where the pixel is not valid; 0 where P is not in front of the
            port or the light is behind the wall).
        points: (H, W, 3) the pixel centres' wall points, world frame, m.
        valid: (H, W) the centre's ray meets the wall.
        water_m: (L, H, W) each light's path in the water, from its port to P, m.
    """
    if sensor == "paper":
        raise ValueError("light port: not rendered for the 'paper' sensor model")
    points, valid = surface_points(camera, view, BowedWall(0.0))
    term, term_ok = point_sensor_weights(camera, sensor, vignetting)
    valid = valid & term_ok
    h_img, w_img = valid.shape
    values = np.zeros((len(rig.lights), h_img, w_img))
    water_m = np.zeros_like(values)
    n_g = port.glass_index / port.air_index
    n_w = port.water_index / port.air_index
    d, t = port.distance_m, port.thickness_m
    for k, light in enumerate(rig.lights):
        L = light.position_world(view)
        R = light.rotation_world(view)
        if L[2] <= 0.0:
            continue
        local = (points[valid] - L) @ R  # light frame
        rho = np.hypot(local[:, 0], local[:, 1])
        h = local[:, 2]
        front = h > d + t
        th_a = _theta_air(np.where(front, rho, 0.0), np.where(front, h, 1.0), port)
        s = np.sin(th_a)
        th_g = np.arcsin(s / n_g)
        th_w = np.arcsin(s / n_w)
        big_h = h - d - t
        drho = (
            d / np.cos(th_a) ** 2
            + t * (np.cos(th_a) / (n_g * np.cos(th_g))) / np.cos(th_g) ** 2
            + big_h * (np.cos(th_a) / (n_w * np.cos(th_w))) / np.cos(th_w) ** 2
        )
        phi = np.arctan2(local[:, 1], local[:, 0])
        # The water direction, light frame, then its z in the world (the wall's normal).
        with np.errstate(invalid="ignore", divide="ignore"):
            radial = np.where(rho > 0.0, 1.0, 0.0)
            w_light = np.stack(
                [
                    np.sin(th_w) * np.cos(phi) * radial,
                    np.sin(th_w) * np.sin(phi) * radial,
                    np.cos(th_w),
                ],
                axis=1,
            )
        cos_wall = np.abs(w_light @ R[2])
        # dOmega_a / dA_plane = sin(theta_a) / (rho drho/dtheta_a), sin/rho -> its limit
        # 1 / (drho/dtheta_a) on the axis.
        with np.errstate(invalid="ignore", divide="ignore"):
            sin_over_rho = np.where(rho > 0.0, s / np.where(rho > 0.0, rho, 1.0), 1.0 / drho)
        d_omega = sin_over_rho / drho * cos_wall / np.cos(th_w)
        f = np.asarray(light.rid(th_a, phi), dtype=np.float64)
        e = light.scale * view.exposure * f * _fresnel(th_a, port) * d_omega
        values[k][valid] = np.where(front, e, 0.0) * term[valid]
        water_m[k][valid] = np.where(front, big_h / np.cos(th_w), 0.0)
    values[:, ~valid] = np.nan
    return values, points, valid, water_m
