"""The render through the camera's flat port against a brute-force reference.

The reference is written here, independently of lightcal's geometry: Snell's law in
its scalar form (angles from the port's normal, a radial shift in each layer), each
pixel cut into S x S sub-pixels whose corner rays are traced through the port to the
wall z = 0, the point light's irradiance I0 f(theta) cos(i) / r^2 (times the water's
transmittance along the light's path and the refracted camera path, and the port's
Fresnel transmittance of the sub-pixel's ray) integrated over the sub-quads (midpoint
rule over their true areas). The Fresnel transmittance is written here from the
transmission amplitudes, t_s = 2 n_1 cos_i / (n_1 cos_i + n_2 cos_t), t_p = 2 n_1 cos_i /
(n_2 cos_i + n_1 cos_t), T = (n_2 cos_t) / (n_1 cos_i) t^2 per face, the plate's inner
reflections (R = 1 - T) summed per polarisation, then the mean of s and p (not
`lightcal.core.fresnel`'s reflectances). lightcal's `radiance` value is the footprint's
mean irradiance (flux / area, T at its centre) times the Fresnel factor of the pixel's
ray: the two agree to 1e-4.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from lightcal.core.camera import Camera
from lightcal.core.flat_port import FlatPort
from lightcal.core.medium import AIR, Medium
from lightcal.core.port_render import render_image_through_port
from lightcal.core.render import render_image
from lightcal.core.rid import CosPowerRID
from lightcal.core.scene import Light, Rig, View

N_AIR, N_GLASS, N_WATER = 1.0, 1.49, 1.333
D, T = 0.02, 0.01
FX, CX, CY, W, H = 36.0, 19.5, 14.5, 40, 30
M_RID = 2.5
SUB = 24


def _scene(distance: float) -> tuple[Camera, View, Light]:
    camera = Camera.from_params(fx=FX, fy=FX, cx=CX, cy=CY, width=W, height=H)
    view = View.looking_at(
        np.array([0.2, -0.1, distance]), np.array([0.05, 0.08, 0.0]), up_world=(0.1, -1.0, 0.0)
    )
    axis = np.array([-0.12, 0.06, 1.0])
    z = axis / np.linalg.norm(axis)
    x = np.cross([0.0, 1.0, 0.0], z)
    x /= np.linalg.norm(x)
    R = np.stack([x, np.cross(z, x), z], axis=1)
    return camera, view, Light(CosPowerRID(M_RID), np.array([0.15, 0.04, 0.05]), R)


def _face(n1: float, n2: float, th_i: np.ndarray, th_t: np.ndarray) -> list[np.ndarray]:
    """[T_s, T_p] of one face n1 -> n2 from the transmission amplitudes."""
    ci, ct = np.cos(th_i), np.cos(th_t)
    t_s = 2 * n1 * ci / (n1 * ci + n2 * ct)
    t_p = 2 * n1 * ci / (n2 * ci + n1 * ct)
    return [(n2 * ct) / (n1 * ci) * t_s**2, (n2 * ct) / (n1 * ci) * t_p**2]


def _fresnel(th_a: np.ndarray, th_g: np.ndarray, th_w: np.ndarray) -> np.ndarray:
    """The port's unpolarised transmittance, inner reflections summed (a geometric
    series: the flux reflected 2k times inside the glass, R = 1 - T at each face)."""
    out = np.zeros_like(th_a)
    inner, outer = _face(N_AIR, N_GLASS, th_a, th_g), _face(N_GLASS, N_WATER, th_g, th_w)
    for t1, t2 in zip(inner, outer, strict=True):
        out += 0.5 * t1 * t2 / (1.0 - (1.0 - t1) * (1.0 - t2))
    return out


def _trace(u: np.ndarray, v: np.ndarray, view: View) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Wall points (..., 3), port exit points (..., 3), world frame, and the port's
    Fresnel transmittance (...) of pixel coordinates u, v: pinhole ray, then Snell's law
    n sin(theta) = const at z = D and z = D + T (camera frame), written with angles."""
    x, y = (u - CX) / FX, (v - CY) / FX
    rho = np.hypot(x, y)  # tan(theta_air)
    with np.errstate(invalid="ignore", divide="ignore"):
        cphi, sphi = np.where(rho > 0, x / rho, 1.0), np.where(rho > 0, y / rho, 0.0)
    th_a = np.arctan(rho)
    th_g = np.arcsin(N_AIR * np.sin(th_a) / N_GLASS)
    th_w = np.arcsin(N_AIR * np.sin(th_a) / N_WATER)
    r_exit = D * np.tan(th_a) + T * np.tan(th_g)
    exit_c = np.stack([r_exit * cphi, r_exit * sphi, np.full_like(x, D + T)], axis=-1)
    dir_c = np.stack([np.sin(th_w) * cphi, np.sin(th_w) * sphi, np.cos(th_w)], axis=-1)
    Rt = view.R_camera_world.T
    exit_w = exit_c @ Rt.T + view.center_world
    dir_w = dir_c @ Rt.T
    lam = -exit_w[..., 2] / dir_w[..., 2]
    return exit_w + lam[..., None] * dir_w, exit_w, _fresnel(th_a, th_g, th_w)


def _reference(view: View, light: Light, c: float) -> np.ndarray:
    """(H, W) the mean irradiance over each pixel's footprint through the port."""
    L = light.position_world(view)
    a = light.rotation_world(view)[:, 2]
    s = (np.arange(SUB + 1) / SUB) - 0.5
    out = np.empty((H, W))
    for row in range(H):
        uu = np.arange(W)[:, None, None] + s[None, None, :]
        vv = np.full_like(uu, 0.0) + row + s[None, :, None]
        uu = np.broadcast_to(uu, vv.shape)
        P, X, _ = _trace(uu, vv, view)  # (W, SUB + 1, SUB + 1, 3)
        # each sub-pixel's ray through its centre
        half = 0.5 / SUB
        _, _, fresnel = _trace(uu[:, :-1, :-1] + half, vv[:, :-1, :-1] + half, view)
        p1, p2, p3, p4 = P[:, :-1, :-1], P[:, :-1, 1:], P[:, 1:, 1:], P[:, 1:, :-1]
        d13, d24 = p3 - p1, p4 - p2
        area = 0.5 * np.abs(d13[..., 0] * d24[..., 1] - d13[..., 1] * d24[..., 0])
        mid = (p1 + p2 + p3 + p4) / 4.0
        xm = (X[:, :-1, :-1] + X[:, :-1, 1:] + X[:, 1:, 1:] + X[:, 1:, :-1]) / 4.0
        to = mid - L
        r = np.linalg.norm(to, axis=-1)
        cos_axis = np.clip((to @ a) / r, 0.0, None)
        e = cos_axis**M_RID * (L[2] / r) / r**2
        e *= np.exp(-c * (r + np.linalg.norm(mid - xm, axis=-1))) * fresnel
        out[row] = (e * area).sum(axis=(1, 2)) / area.sum(axis=(1, 2))
    return out


@pytest.mark.parametrize(("distance", "c"), [(1.2, 0.0), (1.8, 0.3)])
def test_the_port_render_agrees_with_brute_force(distance: float, c: float) -> None:
    camera, view, light = _scene(distance)
    port = FlatPort(D, T, N_GLASS, N_WATER, air_index=N_AIR)
    medium = Medium(c) if c > 0 else AIR
    ours = render_image_through_port(
        camera, view, Rig.single(light), port, rid_subsamples=6, medium=medium
    )
    ref = _reference(view, light, c)
    assert not np.ma.is_masked(ours)
    rel = np.abs(ours.filled(np.nan) / ref - 1.0)
    print(
        f"\ndistance {distance} m, c {c}: max rel diff {rel.max():.2e}, median {np.median(rel):.2e}"
    )
    assert rel.max() < 1e-4


def test_what_ignoring_the_port_costs() -> None:
    """The same view rendered without the port (the housing's in-air intrinsics, and
    those with fx, fy times n_w: the port's first-order effect, which intrinsics
    calibrated in water absorb): the relative difference at the image's corners and
    centre (numbers in docs/model.md)."""
    camera, view, light = _scene(1.5)
    rig = Rig.single(light)
    port = FlatPort(D, T, N_GLASS, N_WATER, air_index=N_AIR)
    through = render_image_through_port(camera, view, rig, port).filled(np.nan)
    water_k = Camera.from_params(fx=FX * N_WATER, fy=FX * N_WATER, cx=CX, cy=CY, width=W, height=H)
    where = {"centre": (H // 2, W // 2), "top-left": (0, 0), "top-right": (0, W - 1),
             "bottom-left": (H - 1, 0), "bottom-right": (H - 1, W - 1)}  # fmt: skip
    ratios = {}
    for name, cam in (("in-air K", camera), ("K x n_w", water_k)):
        plain = render_image(cam, view, rig).filled(np.nan)
        rel = plain / through - 1.0
        ratios[name] = rel
        text = ", ".join(f"{k} {rel[i, j]:+.3f}" for k, (i, j) in where.items())
        print(f"\nignoring the port ({name}): {text}; max |rel| {np.nanmax(np.abs(rel)):.3f}")
    assert np.nanmax(np.abs(ratios["in-air K"])) > 0.2
    # The first-order part absorbed, what is left is smaller but not negligible.
    assert np.nanmax(np.abs(ratios["K x n_w"])) < np.nanmax(np.abs(ratios["in-air K"]))
    assert math.isfinite(float(np.nanmax(np.abs(ratios["K x n_w"]))))
