"""The light's flat port: the refracted path's solve, the flux through the port and its
gradients (lightcal.core.light_port, light_port_flux; docs/model.md, "The light's flat
port")."""

from __future__ import annotations

import math

import numpy as np
import pytest

from lightcal.core.camera import Camera
from lightcal.core.flat_port import FlatPort
from lightcal.core.footprint import pixel_footprints
from lightcal.core.fresnel import port_transmittance
from lightcal.core.light_port import air_sines, port_paths
from lightcal.core.medium import Medium
from lightcal.core.port_footprints import port_footprints
from lightcal.core.render import light_flux, render_image, render_pixels
from lightcal.core.rid import CosPowerRID, Table2DRID
from lightcal.core.rotations import matrix_from_rotvec
from lightcal.core.scene import Light, Rig, View
from lightcal.core.wall import PlasticWall

PORT = FlatPort(0.02, 0.01, 1.49, 1.333)
TILTED = FlatPort(0.03, 0.008, 1.52, 1.34, normal_camera=np.array([0.06, -0.04, 1.0]))


def _camera() -> Camera:
    return Camera.from_params(
        fx=36.0, fy=36.0, cx=19.5, cy=14.5, width=40, height=30, dist=(-0.08, 0.02, 0.0, 0.0)
    )


def _view() -> View:
    return View.looking_at(np.array([0.25, -0.15, 1.3]), np.array([0.05, 0.1, 0.0]))


def _light(rid=None, port: FlatPort | None = PORT) -> Light:
    axis = np.array([0.1, -0.05, 1.0])
    z = axis / np.linalg.norm(axis)
    x = np.cross([0.0, 1.0, 0.0], z)
    x /= np.linalg.norm(x)
    R = np.stack([x, np.cross(z, x), z], axis=1)
    rid = CosPowerRID(3.0) if rid is None else rid
    return Light(rid, np.array([0.12, -0.05, 0.03]), R, scale=2.0, port=port)


def _pixels(camera: Camera) -> np.ndarray:
    v, u = np.mgrid[0 : camera.height, 0 : camera.width]
    return np.stack([u.ravel(), v.ravel()], axis=1)


def _table_rid() -> Table2DRID:
    theta = np.radians(np.linspace(0.0, 90.0, 19))
    phi = np.radians(np.arange(0.0, 360.0, 30.0))
    values = np.cos(theta)[None, :] ** (2.0 + 0.8 * np.cos(phi)[:, None] ** 2)
    return Table2DRID(theta, phi, values)


def test_a_point_on_the_axis_is_reached_along_the_axis() -> None:
    paths = port_paths(np.array([[0.0, 0.0, 0.5], [0.0, 0.0, 2.0]]), PORT)
    np.testing.assert_array_equal(paths.directions_light, [[0.0, 0.0, 1.0]] * 2)
    np.testing.assert_allclose(paths.water_m, [0.47, 1.97], rtol=1e-15)
    np.testing.assert_allclose(paths.exits_light, [[0.0, 0.0, 0.03]] * 2, atol=1e-18)


@pytest.mark.parametrize("port", [PORT, TILTED], ids=["axial", "tilted"])
def test_the_solved_air_ray_traced_forward_lands_on_the_point(port: FlatPort) -> None:
    """500 points up to ~60 degrees in the water: FlatPort.trace of the solved air
    direction (Snell's law in vector form, an independent computation) passes through
    the point to 1e-12 m, and n_a sin(theta_a) = n_w sin(theta_w) to 1e-13."""
    rng = np.random.default_rng(3)
    n = port.normal_camera
    h = rng.uniform(0.1, 3.0, 500)
    rho = h * np.tan(rng.uniform(0.0, math.radians(60.0), 500))
    phi = rng.uniform(0.0, 2 * math.pi, 500)
    e1 = np.cross(n, [0.0, 1.0, 0.0])
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(n, e1)
    Y = h[:, None] * n + rho[:, None] * (np.cos(phi)[:, None] * e1 + np.sin(phi)[:, None] * e2)
    paths = port_paths(Y, port)
    assert paths.ok.all()
    origins, water, ok = port.trace(paths.directions_light)
    assert ok.all()
    along = np.einsum("ij,ij->i", Y - origins, water)
    miss = np.linalg.norm(Y - origins - along[:, None] * water, axis=1)
    assert miss.max() < 1e-12, miss.max()
    np.testing.assert_allclose(origins, paths.exits_light, atol=1e-15)
    np.testing.assert_allclose(along, paths.water_m, rtol=1e-13)
    sin_air = np.linalg.norm(np.cross(paths.directions_light, n), axis=1)
    sin_water = np.linalg.norm(np.cross(water, n), axis=1)
    np.testing.assert_allclose(sin_air, port.water_index * sin_water, rtol=1e-13, atol=1e-16)


def test_points_not_in_front_of_the_port_are_not_reached() -> None:
    s, ok = air_sines(np.array([0.1, 0.1, 0.0, 0.2]), np.array([0.03, 0.02, -1.0, 0.031]), PORT)
    np.testing.assert_array_equal(ok, [False, False, False, True])
    assert np.isnan(s[:3]).all() and 0.0 < s[3] < 1.0


def test_unit_indices_give_the_in_air_flux() -> None:
    """A port whose indices are all 1 bends nothing and transmits everything: the flux
    and its gradients are the in-air kernel's to round-off (n = 1 and 3, a 2-D table);
    with d -> 0 the water path starts at the emitter, so in water too."""
    camera, view = _camera(), _view()
    fp = pixel_footprints(camera, view, _pixels(camera))
    for rid in (CosPowerRID(3.0), _table_rid()):
        for n_sub, port, c in (
            (1, FlatPort(0.02, 0.005, 1.0, 1.0), 0.0),
            (3, FlatPort(0.05, 0.0, 1.0, 1.0), 0.0),
            (2, FlatPort(1e-13, 0.0, 1.0, 1.0), 0.4),
        ):
            g_air = np.zeros((len(fp), 1))
            g_port = np.zeros((len(fp), 1))
            kw = {"rid_subsamples": n_sub, "want_grad": True, "medium": Medium(c)}
            f0, d0 = light_flux(fp, view, _light(rid, None), medium_grad_out=g_air, **kw)
            f1, d1 = light_flux(fp, view, _light(rid, port), medium_grad_out=g_port, **kw)
            assert d0 is not None and d1 is not None
            lit = f0 > 0
            assert lit.sum() > 1000
            np.testing.assert_allclose(f1, f0, rtol=1e-12, atol=0)
            np.testing.assert_allclose(d1, d0, rtol=0, atol=1e-12 * np.abs(d0).max())
            if port.distance_m < 1e-9:  # else the water path starts d + t further on
                atol = 1e-12 * np.abs(g_air).max()
                np.testing.assert_allclose(g_port, g_air, rtol=0, atol=atol)


def test_the_port_concentrates_the_beam_as_its_paraxial_optics_say() -> None:
    """On the axis the irradiance through the port is the air's times
    (h / (d + t n_a / n_g + H n_a / n_w))^2 (paraxial: rho = theta_a times that sum)
    and the Fresnel transmittance at normal incidence; a footprint of 0.2 mm at 1 m."""
    h, half = 1.0, 1e-4
    corners = np.array([[-half, -half], [half, -half], [half, half], [-half, half]])
    quad = np.concatenate([corners, np.zeros((4, 1))], axis=1)[None, None]
    from lightcal.core.footprint import Footprints

    fp = Footprints(np.zeros((1, 2), np.int32), quad, np.ones((1, 1)), np.array([True]), 4e-8)
    view = View.looking_at(np.array([0.0, 0.0, 2.0]), np.zeros(3))
    # The light at (0, 0, h) looking at the wall: R_world_light's z is -z_world.
    R_world_light = np.diag([1.0, -1.0, -1.0])
    t = view.R_camera_world @ (np.array([0.0, 0.0, h]) - view.center_world)
    light = Light(CosPowerRID(1.0), t, view.R_camera_world @ R_world_light, port=PORT)
    f_port, _ = light_flux(fp, view, light)
    f_air, _ = light_flux(fp, view, light.replace(port=None))
    d, th = PORT.distance_m, PORT.thickness_m
    paraxial = (h / (d + th / PORT.glass_index + (h - d - th) / PORT.water_index)) ** 2
    t_f = port_transmittance(np.array([1.0]), 1.0, PORT.glass_index, PORT.water_index)[0][0]
    assert f_port[0] / f_air[0] == pytest.approx(paraxial * t_f, rel=1e-7)


def _moved(light: Light, view: View, dL: np.ndarray, delta: np.ndarray) -> Light:
    """The light with its world position moved by dL (3,) and its world orientation
    turned by exp(delta) R_world_light."""
    R = view.R_camera_world
    L = light.position_world(view) + dL
    R_wl = matrix_from_rotvec(delta) @ light.rotation_world(view)
    return light.replace(t_camera_light=R @ (L - view.center_world), R_camera_light=R @ R_wl)


@pytest.mark.parametrize(
    ("port", "n_sub", "c", "table"),
    [(PORT, 1, 0.0, False), (PORT, 2, 0.3, True), (TILTED, 1, 0.5, False)],
    ids=["axial-air", "axial-water-n2-table", "tilted-water"],
)
def test_every_gradient_column_matches_central_differences(
    port: FlatPort, n_sub: int, c: float, table: bool
) -> None:
    camera, view = _camera(), _view()
    fp = pixel_footprints(camera, view, _pixels(camera))
    light = _light(_table_rid() if table else None, port)
    d_c = np.zeros((len(fp), 1))
    kw = {"rid_subsamples": n_sub}
    flux, grad = light_flux(
        fp, view, light, want_grad=True, medium=Medium(c), medium_grad_out=d_c, **kw
    )
    assert grad is not None and (flux > 0).sum() > 1000
    h = 1e-6
    for j in range(6):
        e = np.zeros(6)
        e[j] = h
        plus, _ = light_flux(fp, view, _moved(light, view, e[:3], e[3:]), medium=Medium(c), **kw)
        minus, _ = light_flux(fp, view, _moved(light, view, -e[:3], -e[3:]), medium=Medium(c), **kw)
        numeric = (plus - minus) / (2 * h)
        scale = np.abs(grad[:, j]).max()
        np.testing.assert_allclose(grad[:, j], numeric, rtol=0, atol=2e-6 * scale, err_msg=str(j))
    hc = 1e-6
    plus, _ = light_flux(fp, view, light, medium=Medium(c + hc), **kw)
    minus, _ = light_flux(fp, view, light, medium=Medium(max(c - hc, 0.0)), **kw)
    numeric = (plus - minus) / (c + hc - max(c - hc, 0.0))
    np.testing.assert_allclose(d_c[:, 0], numeric, rtol=0, atol=2e-6 * np.abs(d_c).max())


def test_pixels_behind_the_port_get_nothing() -> None:
    """A light whose port's outer face lies beyond some footprints' points (a long
    housing, d = 0.9 m, the light 1 m from the wall): those pixels get flux 0 and zero
    gradients; the others are lit."""
    camera = _camera()
    view = View.looking_at(np.array([0.0, 0.0, 1.0]), np.zeros(3))
    R_world_light = np.diag([1.0, -1.0, -1.0]) @ matrix_from_rotvec([0.0, 0.6, 0.0])
    t = view.R_camera_world @ (np.array([0.0, 0.0, 1.0]) - view.center_world)
    light = Light(CosPowerRID(1.0), t, view.R_camera_world @ R_world_light, port=FlatPort(0.9, 0.0))
    fp = pixel_footprints(camera, view, _pixels(camera))
    flux, grad = light_flux(fp, view, light, want_grad=True)
    assert grad is not None
    dark = flux == 0.0
    assert 100 < dark.sum() < len(fp) - 100
    assert np.all(grad[dark] == 0.0)


def test_the_renderer_and_the_camera_port_use_it() -> None:
    """render_image with a light behind its port is every pixel's footprint through
    light_flux (render_pixels' numbers), also through the camera's own port."""
    camera, view = _camera(), _view()
    rig = Rig.single(_light())
    image = render_image(camera, view, rig, medium=Medium(0.2))
    pixels = render_pixels(camera, view, rig, _pixels(camera), medium=Medium(0.2))
    np.testing.assert_allclose(image.ravel(), pixels, rtol=1e-14)
    plain = render_image(camera, view, Rig.single(_light(port=None)), medium=Medium(0.2))
    assert np.ma.median(image / plain) > 1.2  # the port narrows the beam
    fp = port_footprints(camera, view, _pixels(camera), PORT)
    flux, _ = light_flux(fp, view, _light())
    assert (flux > 0).sum() > 1000


def test_what_is_not_modelled_is_refused() -> None:
    camera, view = _camera(), _view()
    fp = pixel_footprints(camera, view, _pixels(camera))
    with pytest.raises(ValueError, match="light port: only a Lambertian wall"):
        light_flux(fp, view, _light(), wall=PlasticWall())
    # The veil is modelled behind the port (tests/test_light_port_veil.py).
    flux, _ = light_flux(fp, view, _light(), medium=Medium(0.2, 1.0))
    clear, _ = light_flux(fp, view, _light(), medium=Medium(0.2))
    assert np.all(flux[fp.valid] > clear[fp.valid])
