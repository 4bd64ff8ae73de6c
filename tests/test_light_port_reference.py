"""The render of a light behind its flat port against a brute-force reference.

The reference is written here, independently of lightcal's port code: each pixel is cut
into S x S sub-pixels whose corners are traced (pinhole, no distortion) to the wall
z = 0; each wall point's air direction from the emitter is found by bisection on the
scalar path equation rho = d tan(theta_a) + t tan(theta_g) + H tan(theta_w) (Snell's
law n sin(theta) = const, written with angles); each sub-quad receives I(theta_a)
T_F(theta_a) Omega_a, Omega_a the (small) solid angle spanned by its corners' air
directions (half the cross product of the diagonals), T_F the plate's Fresnel
transmittance written out here (s and p, both faces, inner reflections), in water times
exp(-c (H / cos(theta_w) + |P - C|)) at the sub-quad. lightcal's `radiance` value is the
footprint's flux over its area: the two agree to 1e-4.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from lightcal.core.camera import Camera
from lightcal.core.flat_port import FlatPort
from lightcal.core.medium import AIR, Medium
from lightcal.core.render import render_image
from lightcal.core.rid import CosPowerRID
from lightcal.core.scene import Light, Rig, View

N_GLASS, N_WATER = 1.49, 1.333
D, T = 0.02, 0.01
FX, CX, CY, W, H = 36.0, 19.5, 14.5, 40, 30
M_RID = 2.5
SUB = 16


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
    port = FlatPort(D, T, N_GLASS, N_WATER)
    return camera, view, Light(CosPowerRID(M_RID), np.array([0.15, 0.04, 0.05]), R, port=port)


def _wall_points(u: np.ndarray, v: np.ndarray, view: View) -> np.ndarray:
    """(..., 3) where the pinhole rays of pixel coordinates u, v meet the wall z = 0."""
    rays = np.stack([(u - CX) / FX, (v - CY) / FX, np.ones_like(u)], axis=-1)
    d = rays @ view.R_camera_world  # R^T r, row by row
    c = view.center_world
    lam = -c[2] / d[..., 2]
    return c + lam[..., None] * d


def _theta_air(rho: np.ndarray, h: np.ndarray) -> np.ndarray:
    """theta_a solving rho = d tan(theta_a) + t tan(theta_g) + H tan(theta_w), bisection."""
    lo, hi = np.zeros_like(rho), np.full_like(rho, math.pi / 2)
    for _ in range(64):
        mid = 0.5 * (lo + hi)
        s = np.sin(mid)
        th_g, th_w = np.arcsin(s / N_GLASS), np.arcsin(s / N_WATER)
        reach = D * np.tan(mid) + T * np.tan(th_g) + (h - D - T) * np.tan(th_w)
        low = reach < rho
        lo, hi = np.where(low, mid, lo), np.where(low, hi, mid)
    return 0.5 * (lo + hi)


def _fresnel(theta_a: np.ndarray) -> np.ndarray:
    """Unpolarised transmittance of the plate air -> glass -> water (incoherent)."""
    th = [theta_a, np.arcsin(np.sin(theta_a) / N_GLASS), np.arcsin(np.sin(theta_a) / N_WATER)]
    n = [1.0, N_GLASS, N_WATER]
    total = 0.0
    for pol in ("s", "p"):
        r = []
        for k in range(2):
            ci, ct = np.cos(th[k]), np.cos(th[k + 1])
            if pol == "s":
                amp = (n[k] * ci - n[k + 1] * ct) / (n[k] * ci + n[k + 1] * ct)
            else:
                amp = (n[k + 1] * ci - n[k] * ct) / (n[k + 1] * ci + n[k] * ct)
            r.append(amp**2)
        total = total + (1 - r[0]) * (1 - r[1]) / (1 - r[0] * r[1])
    return 0.5 * total


def _air_directions(P: np.ndarray, light: Light, view: View) -> tuple[np.ndarray, np.ndarray]:
    """Unit air directions (..., 3) (light frame) towards wall points P (..., 3), and the
    water path lengths (...)."""
    Y = (P - light.position_world(view)) @ light.rotation_world(view)
    rho, h = np.hypot(Y[..., 0], Y[..., 1]), Y[..., 2]
    th = _theta_air(rho, h)
    phi = np.arctan2(Y[..., 1], Y[..., 0])
    u = np.stack([np.sin(th) * np.cos(phi), np.sin(th) * np.sin(phi), np.cos(th)], axis=-1)
    return u, (h - D - T) / np.cos(np.arcsin(np.sin(th) / N_WATER))


def _reference(view: View, light: Light, c: float, *, t_at_centre: bool = False) -> np.ndarray:
    """(H, W) the mean irradiance over each pixel's footprint through the light's port;
    the water's transmittance at each sub-quad, or (`t_at_centre`) at the footprint's
    centre, the mean of its corners, as lightcal evaluates it."""
    s = (np.arange(SUB + 1) / SUB) - 0.5
    out = np.empty((H, W))
    for row in range(H):
        uu = np.arange(W)[:, None, None] + s[None, None, :]
        vv = np.zeros_like(uu) + row + s[None, :, None]
        uu = np.broadcast_to(uu, vv.shape)
        P = _wall_points(uu, vv, view)  # (W, SUB + 1, SUB + 1, 3)
        u, _ = _air_directions(P, light, view)
        u1, u2, u3, u4 = u[:, :-1, :-1], u[:, :-1, 1:], u[:, 1:, 1:], u[:, 1:, :-1]
        mid = u1 + u2 + u3 + u4
        mid /= np.linalg.norm(mid, axis=-1, keepdims=True)
        omega = 0.5 * np.abs(np.einsum("...i,...i", np.cross(u3 - u1, u4 - u2), mid))
        theta = np.arccos(np.clip(mid[..., 2], -1.0, 1.0))
        flux = np.cos(theta) ** M_RID * _fresnel(theta) * omega
        if c > 0.0:
            centre = 0.25 * (P[:, :-1, :-1] + P[:, :-1, 1:] + P[:, 1:, 1:] + P[:, 1:, :-1])
            if t_at_centre:
                corners = P[:, 0, 0] + P[:, 0, -1] + P[:, -1, -1] + P[:, -1, 0]
                centre = np.broadcast_to((0.25 * corners)[:, None, None], centre.shape)
            _, water = _air_directions(centre, light, view)
            camera = np.linalg.norm(centre - view.center_world, axis=-1)
            flux = flux * np.exp(-c * (water + camera))
        p1, p2, p3, p4 = P[:, 0, 0], P[:, 0, -1], P[:, -1, -1], P[:, -1, 0]
        d13, d24 = p3 - p1, p4 - p2
        area = 0.5 * np.abs(d13[:, 0] * d24[:, 1] - d13[:, 1] * d24[:, 0])
        out[row] = flux.sum(axis=(1, 2)) / area
    return out


@pytest.mark.parametrize(("distance", "c"), [(1.2, 0.0), (1.8, 0.0), (1.2, 0.3)])
def test_the_render_matches_the_brute_force_reference(distance: float, c: float) -> None:
    """With 4 x 4 RID sub-samples within 1e-4 (the sub-quads' edges are great circles of
    the air directions, the true ones are not quite); with one sample a pixel within 6e-4:
    the midpoint rule's error on the RID and T_F across a pixel (1.8e-4 in air here). In
    water the transmittance is lightcal's at the footprint's centre: against the
    reference's at the centre within 1e-4, against its integral over the footprint within
    2.5e-4 (these pixels are 1.9 degrees wide: "Where T is evaluated" in docs/model.md)."""
    camera, view, light = _scene(distance)
    medium = AIR if c == 0.0 else Medium(c)
    refs = {"T at the centre": _reference(view, light, c, t_at_centre=True)}
    if c > 0.0:
        refs["T integrated"] = _reference(view, light, c)
    for n_sub, bound in ((4, 1e-4), (1, 6e-4)):
        ours = render_image(camera, view, Rig.single(light), medium=medium, rid_subsamples=n_sub)
        assert not ours.mask.any()
        for name, ref in refs.items():
            rel = np.abs(ours.filled(np.nan) / ref - 1.0)
            print(f"\n{distance} m, c {c}, n {n_sub}, {name}: largest difference {rel.max():.2e}")
            assert rel.max() < (2.5e-4 if name == "T integrated" and n_sub > 1 else bound)


def test_ignoring_the_port_costs() -> None:
    """The same view rendered without the port (the same emitter in the water): numbers
    for docs/model.md; the port concentrates the beam (by about n_w^2 on its axis,
    times T_F 0.958) and narrows it."""
    camera, view, light = _scene(1.5)
    through = render_image(camera, view, Rig.single(light))
    plain = render_image(camera, view, Rig.single(light.replace(port=None)))
    ratio = (plain / through).filled(np.nan)
    centre = ratio[H // 2, W // 2]
    corners = [ratio[0, 0], ratio[0, -1], ratio[-1, 0], ratio[-1, -1]]
    print(f"\nwithout the port / with: centre {centre:.3f}, corners {np.round(corners, 3)}")
    assert 0.5 < centre < 0.65  # ~1 / (1.333^2 x 0.958) = 0.59 near the axis
    assert min(corners) > centre  # the port narrows the beam: the edges lose more
