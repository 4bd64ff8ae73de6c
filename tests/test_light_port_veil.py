"""The veil of a light behind its flat port (lightcal.core.light_port_veil,
kernels/port_veil.py; docs/model.md, "The light's flat port"): the refracted bundle's
Jacobian, the integral against a brute-force reference written here, the gradients
against central differences."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import quad
from scipy.optimize import brentq

from lightcal.core.camera import Camera
from lightcal.core.flat_port import FlatPort
from lightcal.core.footprint import Footprints, pixel_footprints
from lightcal.core.kernels.port_veil import bundle_jacobian
from lightcal.core.light_port_veil import port_backscatter, port_scatter
from lightcal.core.medium import Medium, backscatter, scatter_grid
from lightcal.core.port_footprints import port_footprints
from lightcal.core.port_render import render_image_through_port
from lightcal.core.render import light_flux, render_image, shade
from lightcal.core.scene import Light, Rig, View
from lightcal.synthetic.light_port_imaging import _fresnel
from tests.test_light_port import PORT, TILTED, _camera, _light, _moved, _pixels, _view

WATER = Medium(0.3, 0.8, 0.6)


def _refract(v: np.ndarray, eta: float) -> np.ndarray:
    """Snell's law in vector form across a face of normal +z (v . z > 0), eta = n1 / n2."""
    cos_i = v[2]
    cos_t = math.sqrt(1.0 - eta * eta * (1.0 - cos_i * cos_i))
    out = eta * v
    out[2] += cos_t - eta * cos_i
    return out


def _trace(u: np.ndarray, port: FlatPort, h: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The air ray u (3,) (port frame, normal +z) traced forward to the plane z = h:
    the point there, its water direction and the exit point on the outer face."""
    d, t = port.distance_m, port.thickness_m
    g = _refract(u, port.air_index / port.glass_index)
    exit_ = u * (d / u[2]) + g * (t / g[2])
    w = _refract(g, port.glass_index / port.water_index)
    return exit_ + w * ((h - d - t) / w[2]), w, exit_


def _air_angle(rho: float, h: float, port: FlatPort) -> float:
    """theta_a reaching radial distance rho at depth h (the scalar equation, brentq)."""
    d, t = port.distance_m, port.thickness_m
    n_g, n_w = port.glass_index / port.air_index, port.water_index / port.air_index

    def reach(th: float) -> float:
        s = math.sin(th)
        tan_g, tan_w = s / math.sqrt(n_g**2 - s * s), s / math.sqrt(n_w**2 - s * s)
        return d * math.tan(th) + t * tan_g + (h - d - t) * tan_w - rho

    return 0.0 if rho == 0.0 else brentq(reach, 0.0, 0.5 * math.pi - 1e-12, xtol=1e-15)


def _bundle(
    y: np.ndarray, port: FlatPort, delta: float = 1e-7
) -> tuple[float, np.ndarray, np.ndarray, float]:
    """At the point y (3,) of the port frame (normal +z): J = dOmega_air / dA_perp from a
    forward-traced bundle (a tiny square cone of air rays about the solved direction,
    side 2 delta, traced to the plane z = h; the quad it lands on times cos(theta_w)),
    the air direction, the water direction and the water's length."""
    rho, h = float(np.hypot(y[0], y[1])), float(y[2])
    th = _air_angle(rho, h, port)
    phi = math.atan2(y[1], y[0])
    u = np.array([math.sin(th) * math.cos(phi), math.sin(th) * math.sin(phi), math.cos(th)])
    e1 = np.cross(u, [0.0, 1.0, 0.0] if abs(u[1]) < 0.9 else [1.0, 0.0, 0.0])
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(u, e1)
    corners = []
    for a, b in ((-1, -1), (1, -1), (1, 1), (-1, 1)):
        v = u + delta * (a * e1 + b * e2)
        corners.append(_trace(v / np.linalg.norm(v), port, h)[0])
    q = np.array(corners)
    area = 0.5 * abs(np.cross(q[2] - q[0], q[3] - q[1])[2])
    x, w, exit_ = _trace(u, port, h)
    omega = 4.0 * math.asin(delta * delta / (1.0 + delta * delta))
    return omega / (area * w[2]), u, w, float(np.linalg.norm(x - exit_))


@pytest.mark.parametrize("port", [PORT, FlatPort(0.015, 0.008, 1.49, 1.333), FlatPort(0.02, 0.0)])
def test_the_bundle_jacobian_is_the_forward_traced_bundles(port: FlatPort) -> None:
    """sin(theta_a) / (rho drho/dtheta_a cos(theta_w)) (the kernel's closed form in s and
    H) against the solid angle of a tiny square cone of air rays over the area its
    forward-traced rays cover, normal to the beam: within 1e-8 (measured 2e-9), from the axis (the
    analytic limit) to 70 degrees in the water's plane, 0.05-3 m."""
    d, t = port.distance_m, port.thickness_m
    n_g, n_w = port.glass_index / port.air_index, port.water_index / port.air_index
    worst = 0.0
    for h in (d + t + 0.002, 0.05, 0.4, 1.3, 3.0):
        for deg in (0.0, 1e-4, 5.0, 30.0, 55.0, 70.0):
            y = np.array([h * math.tan(math.radians(deg)), 0.0, h])
            ref, u, _, _ = _bundle(y, port)
            jac = bundle_jacobian(float(math.hypot(u[0], u[1])), h - d - t, d, t, n_g, n_w)[0]
            worst = max(worst, abs(jac / ref - 1.0))
    # Indices 1: 1 / r^2.
    assert bundle_jacobian(0.6, 1.0, d, t, 1.0, 1.0)[0] == pytest.approx(
        (0.8 / (1.0 + d + t)) ** 2, rel=1e-14
    )
    print(f"\nJ against the traced bundle: {worst:.1e}")
    assert worst < 1e-8


def test_the_bundle_jacobians_derivatives_match_central_differences() -> None:
    d, t, n_g, n_w = 0.02, 0.01, 1.49, 1.333
    for s, big_h in ((0.0, 0.5), (0.3, 0.01), (0.8, 1.2)):
        _, dln_s, dln_h, c_w = bundle_jacobian(s, big_h, d, t, n_g, n_w)
        assert c_w == pytest.approx(math.sqrt(n_w**2 - s * s), rel=1e-15)
        e = 1e-6
        num_s = (
            math.log(bundle_jacobian(s + e, big_h, d, t, n_g, n_w)[0])
            - math.log(bundle_jacobian(s - e, big_h, d, t, n_g, n_w)[0])
        ) / (2 * e)
        num_h = (
            math.log(bundle_jacobian(s, big_h + e, d, t, n_g, n_w)[0])
            - math.log(bundle_jacobian(s, big_h - e, d, t, n_g, n_w)[0])
        ) / (2 * e)
        assert dln_s == pytest.approx(num_s, abs=1e-7)
        assert dln_h == pytest.approx(num_h, rel=1e-7)


def test_unit_indices_in_front_of_the_port_give_the_in_air_veil() -> None:
    """A port of indices 1 bends nothing: with the camera's rays in front of its outer
    face and no attenuation (the water would start at the face) the veil is the in-air
    kernel's to round-off (the same nodes: the virtual source is the emitter)."""
    camera, view = _camera(), _view()
    fp = pixel_footprints(camera, view, _pixels(camera))
    points = fp.centers_world[fp.valid]
    light = _light(port=FlatPort(0.02, 0.01, 1.0, 1.0))
    start = view.center_world + 0.2 * light.rotation_world(view)[:, 2]
    medium = Medium(0.0, 1.0, 0.6)
    ours = port_backscatter(points, start, light, view, medium)
    air = backscatter(points, start, light, view, medium)
    np.testing.assert_allclose(ours, air, rtol=1e-12)


def _footprints(view: View, step: int, camera_port: bool) -> Footprints:
    """Every step-th pixel's footprints of `_camera`, through the camera's own flat port
    (its rays' exit points the starts) or from its centre."""
    camera = _camera()
    pixels = _pixels(camera)[::step]
    if camera_port:
        return port_footprints(camera, view, pixels, FlatPort(0.02, 0.01, 1.49, 1.333))
    return pixel_footprints(camera, view, pixels)


def _veil_reference(start: np.ndarray, end: np.ndarray, light: Light, view: View) -> float:
    """S along start -> end by adaptive quadrature (QUADPACK), the integrand written
    here: each point's air angle by brentq on the scalar equation, J from the
    forward-traced bundle, the water's direction and length traced, synth's Fresnel,
    p(mu) f T_F J exp(-c (s_w + t)) over the part in front of the outer face."""
    port = light.port
    assert port is not None
    L, R = light.position_world(view), light.rotation_world(view)
    c, g = WATER.attenuation_per_m, WATER.phase_g
    length = float(np.linalg.norm(end - start))
    o = (end - start) / length

    def integrand(t: float) -> float:
        y = R.T @ (start + t * o - L)
        if y[2] <= port.distance_m + port.thickness_m:
            return 0.0
        jac, u, w, water = _bundle(y, port)
        mu = -float((R @ w) @ o)
        p = (1 - g * g) / (4 * math.pi * (1 + g * g - 2 * g * mu) ** 1.5)
        th = math.acos(min(u[2], 1.0))
        f = float(light.rid(th, math.atan2(u[1], u[0])))
        tf = float(_fresnel(np.array([th]), port)[0])
        return p * f * tf * jac * math.exp(-c * (water + t))

    n_world = R[:, 2]
    face = port.distance_m + port.thickness_m
    lo, hi = 0.0, length
    cross = (face - n_world @ (start - L)) / (n_world @ o)
    if 0.0 < cross < length:
        lo, hi = (cross, length) if n_world @ o > 0 else (0.0, cross)
    near = float(np.clip((L - start) @ o, lo, hi))
    value, _ = quad(integrand, lo, hi, points=[near], epsabs=0.0, epsrel=1e-9, limit=400)
    return value


@pytest.mark.parametrize("camera_port", [False, True], ids=["camera-centre", "camera-port"])
def test_the_veil_matches_a_brute_force_reference(camera_port: bool) -> None:
    """Against `_veil_reference` on pixels across the image (the camera's rays crossing
    the light's outer face, or behind the camera's own port from its exit points):
    within 1e-4 (the 24 equiangular nodes about the virtual source)."""
    view = _view()
    fp = _footprints(view, 53, camera_port)
    light = _light()
    start = fp.camera_side(view.center_world)
    ok = fp.valid
    points = fp.centers_world[ok]
    starts = start[ok] if np.ndim(start) == 2 else np.broadcast_to(start, points.shape)
    ours = port_backscatter(points, start[ok] if np.ndim(start) == 2 else start, light, view, WATER)
    ref = np.array(
        [_veil_reference(s, e, light, view) for s, e in zip(starts, points, strict=True)]
    )
    worst = float(np.max(np.abs(ours / ref - 1.0)))
    print(f"\nport veil against the brute-force reference: {worst:.2e} ({len(ref)} rays)")
    assert np.all(ref > 0.0) and worst < 1e-4


@pytest.mark.parametrize("port", [PORT, TILTED], ids=["axial", "tilted"])
def test_the_veils_own_gradients_match_central_differences(port: FlatPort) -> None:
    """S alone (`port_scatter`), the camera's rays crossing the outer face's plane (the
    boundary term): every column within 1e-7 of its largest central difference
    (measured 1e-8)."""
    camera, view = _camera(), _view()
    fp = pixel_footprints(camera, view, _pixels(camera)[::5])
    points = fp.centers_world[fp.valid]
    light = _light(port=port)

    def veil(light_: Light, medium: Medium = WATER, want: bool = False):
        return port_scatter(
            points, view.center_world, light_.position_world(view),
            light_.rotation_world(view), light_.rid.data(), port, medium, want,
        )  # fmt: skip

    s, grad = veil(light, want=True)
    assert grad is not None and np.all(s > 0.0)
    h = 1e-6
    for j in range(6):
        e = np.zeros(6)
        e[j] = h
        numeric = (
            veil(_moved(light, view, e[:3], e[3:]))[0]
            - veil(_moved(light, view, -e[:3], -e[3:]))[0]
        ) / (2 * h)
        atol = 1e-7 * np.abs(numeric).max()
        np.testing.assert_allclose(grad[:, j], numeric, rtol=0, atol=atol, err_msg=str(j))
    for col, k in ((6, 0), (7, 2)):
        e = np.zeros(3)
        e[k] = h
        values = WATER.parameters()
        numeric = (
            veil(light, WATER.with_parameters(values + e))[0]
            - veil(light, WATER.with_parameters(values - e))[0]
        ) / (2 * h)
        atol = 1e-7 * np.abs(numeric).max()
        np.testing.assert_allclose(grad[:, col], numeric, rtol=0, atol=atol, err_msg=str(k))


@pytest.mark.parametrize(
    ("port", "camera_port", "medium"),
    [
        (PORT, False, WATER),
        (TILTED, False, Medium(0.2, 1.5, -0.3)),
        (PORT, True, WATER),
    ],
    ids=["axial", "tilted", "camera-port"],
)
def test_every_gradient_column_matches_central_differences(
    port: FlatPort, camera_port: bool, medium: Medium
) -> None:
    """The flux with the veil: position, rotation, c, beta and g columns within 1e-5
    of each column's largest central difference."""
    view = _view()
    fp = _footprints(view, 5, camera_port)
    light = _light(port=port)
    d_m = np.zeros((len(fp), 3))
    _, grad = light_flux(fp, view, light, want_grad=True, medium=medium, medium_grad_out=d_m)
    assert grad is not None
    h, worst = 1e-6, 0.0
    for j in range(6):
        e = np.zeros(6)
        e[j] = h
        plus, _ = light_flux(fp, view, _moved(light, view, e[:3], e[3:]), medium=medium)
        minus, _ = light_flux(fp, view, _moved(light, view, -e[:3], -e[3:]), medium=medium)
        numeric = (plus - minus) / (2 * h)
        scale = np.abs(numeric).max()
        worst = max(worst, float(np.abs(grad[:, j] - numeric).max() / scale))
        np.testing.assert_allclose(grad[:, j], numeric, rtol=0, atol=1e-5 * scale, err_msg=str(j))
    values = medium.parameters()
    for k in range(3):
        e = np.zeros(3)
        e[k] = h
        plus, _ = light_flux(fp, view, light, medium=medium.with_parameters(values + e))
        minus, _ = light_flux(fp, view, light, medium=medium.with_parameters(values - e))
        numeric = (plus - minus) / (2 * h)
        scale = np.abs(numeric).max()
        worst = max(worst, float(np.abs(d_m[:, k] - numeric).max() / scale))
        np.testing.assert_allclose(d_m[:, k], numeric, rtol=0, atol=1e-5 * scale, err_msg=str(k))
    print(f"\nthe worst column's difference: {worst:.1e} of its largest")


def test_the_whole_image_interpolates_the_veil_between_exact_nodes() -> None:
    """`render_image` with a ported light computes the veil on `scatter_grid`'s nodes
    (every 3rd pixel here) and interpolates bilinearly: exact at the nodes, elsewhere
    within 3e-4 of the pixel's value (measured 1.3e-4; the in-air veil's grid 4.8e-5 on
    this image: behind the port the veil spans 2e-5 to 0.2, the housing's shadow near the
    camera; a 400 x 300 image, 0.17 degrees a pixel)."""
    camera = Camera.from_params(fx=300.0, fy=300.0, cx=199.5, cy=149.5, width=400, height=300)
    view = _view()
    light = _light()
    rig = Rig.single(light)
    image = render_image(camera, view, rig, medium=WATER).filled(np.nan)
    clear = render_image(camera, view, rig, medium=Medium(WATER.attenuation_per_m))
    k = light.scale * view.exposure * WATER.backscatter_per_m
    veil = (image - clear.filled(np.nan)).ravel()
    fp = pixel_footprints(camera, view, _pixels(camera))
    exact = k * port_backscatter(fp.centers_world, view.center_world, light, view, WATER)
    rel = (np.abs(veil - exact) / image.ravel()).reshape(image.shape)
    rows, cols = scatter_grid(image.shape)
    print(f"\nthe interpolated veil against every pixel's: {np.nanmax(rel):.1e} of the values")
    assert np.nanmax(rel[np.ix_(rows, cols)]) < 1e-14
    assert np.nanmax(rel) < 3e-4


def test_the_whole_image_through_the_cameras_port_keeps_its_exit_points() -> None:
    """Both ports: `render_image_through_port`'s interpolated veil (each node's ray from
    its exit point, times the camera port's Fresnel transmittance) within 1e-4 of the
    values of every pixel shaded exactly (measured 1.7e-5 on 400 x 300)."""
    camera = Camera.from_params(fx=300.0, fy=300.0, cx=199.5, cy=149.5, width=400, height=300)
    view, rig, port = _view(), Rig.single(_light()), FlatPort(0.02, 0.01, 1.49, 1.333)
    image = render_image_through_port(camera, view, rig, port, medium=WATER).filled(np.nan)
    # A selection of pixels (here all, in another order): every ray integrated.
    fp = port_footprints(camera, view, _pixels(camera)[::-1], port)
    exact = shade(fp, view, rig, medium=WATER).values.filled(np.nan)[::-1]
    rel = np.abs(image.ravel() / exact - 1.0)
    print(f"\nthrough both ports, the interpolated veil: {np.nanmax(rel):.1e} of the values")
    assert np.all(np.isfinite(rel)) and np.nanmax(rel) < 1e-4
