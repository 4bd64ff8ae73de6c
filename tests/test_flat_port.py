"""The camera's flat port: Snell's law at its two faces, footprints and the medium
through it (lightcal.core.flat_port, port_footprints; docs/model.md, "The camera's
flat port")."""

from __future__ import annotations

import math

import numpy as np
import pytest

from lightcal.core.camera import Camera
from lightcal.core.flat_port import FlatPort, refract
from lightcal.core.footprint import pixel_footprints
from lightcal.core.medium import Medium
from lightcal.core.port_footprints import port_footprints
from lightcal.core.port_render import render_image_through_port, render_pixels_through_port
from lightcal.core.render import render_pixels, shade
from lightcal.core.rid import CosPowerRID
from lightcal.core.scene import Light, Rig, View
from lightcal.core.wall import PlasticWall
from lightcal.core.wall_mesh import WallMesh, wall_footprints

PORT = FlatPort(0.02, 0.01, 1.49, 1.333)


def _camera() -> Camera:
    return Camera.from_params(
        fx=36.0, fy=36.0, cx=19.5, cy=14.5, width=40, height=30, dist=(-0.08, 0.02, 0.0, 0.0)
    )


def _view() -> View:
    return View.looking_at(np.array([0.25, -0.15, 1.5]), np.array([0.05, 0.1, 0.0]))


def _rig() -> Rig:
    axis = np.array([0.1, -0.05, 1.0])
    z = axis / np.linalg.norm(axis)
    x = np.cross([0.0, 1.0, 0.0], z)
    x /= np.linalg.norm(x)
    R = np.stack([x, np.cross(z, x), z], axis=1)
    return Rig.single(Light(CosPowerRID(3.0), np.array([0.12, -0.05, 0.03]), R, scale=2.0))


def _all_pixels(camera: Camera) -> np.ndarray:
    v, u = np.mgrid[0 : camera.height, 0 : camera.width]
    return np.stack([u.ravel(), v.ravel()], axis=1)


def _sin_to_axis(d: np.ndarray, n: np.ndarray) -> np.ndarray:
    d = d / np.linalg.norm(d, axis=1, keepdims=True)
    return np.linalg.norm(np.cross(d, n), axis=1)


def test_a_ray_along_the_axis_is_unbent() -> None:
    origins, dirs, ok = PORT.trace(np.array([[0.0, 0.0, 1.0], [0.0, 0.0, 3.0]]))
    assert ok.all()
    np.testing.assert_array_equal(dirs, [[0.0, 0.0, 1.0]] * 2)
    np.testing.assert_allclose(origins, [[0.0, 0.0, 0.03]] * 2, atol=1e-17)
    tilted = FlatPort(0.02, 0.01, normal_camera=np.array([0.05, -0.02, 1.0]))
    o, d, _ = tilted.trace(tilted.normal_camera[None, :])
    np.testing.assert_allclose(d[0], tilted.normal_camera, atol=1e-15)
    assert float(o[0] @ tilted.normal_camera) == pytest.approx(0.03, rel=1e-14)


@pytest.mark.parametrize("normal", [(0.0, 0.0, 1.0), (0.08, -0.05, 1.0)])
def test_snells_law_holds_across_the_port(normal: tuple[float, float, float]) -> None:
    """n_air sin(theta_air) = n_w sin(theta_w) whatever the glass; the exit point lies
    on the outer face, the ray's direction in the glass obeys Snell too; unit
    directions in the plane of incidence."""
    port = FlatPort(0.02, 0.01, 1.49, 1.333, normal_camera=np.array(normal))
    n = port.normal_camera
    rng = np.random.default_rng(1)
    rays = np.concatenate([rng.uniform(-1.2, 1.2, (500, 2)), np.ones((500, 1))], axis=1)
    origins, dirs, ok = port.trace(rays)
    assert ok.all()
    np.testing.assert_allclose(np.linalg.norm(dirs, axis=1), 1.0, rtol=1e-15)
    s_air, s_w = _sin_to_axis(rays, n), _sin_to_axis(dirs, n)
    np.testing.assert_allclose(port.air_index * s_air, port.water_index * s_w, rtol=1e-13)
    np.testing.assert_allclose(origins @ n, 0.03, rtol=1e-14)
    # Coplanar: the incident ray, the normal and the refracted ray.
    np.testing.assert_allclose(np.einsum("ij,ij->i", np.cross(rays, n), dirs), 0.0, atol=1e-14)
    # The glass only shifts: another glass index gives the same water direction.
    _, dirs2, _ = FlatPort(0.02, 0.01, 1.70, 1.333, normal_camera=np.array(normal)).trace(rays)
    np.testing.assert_allclose(dirs2, dirs, atol=1e-14)


def test_one_interface_when_the_glass_vanishes() -> None:
    """Thickness 0, or a glass of the water's index: one air -> water interface at d."""
    rng = np.random.default_rng(2)
    rays = np.concatenate([rng.uniform(-1.0, 1.0, (200, 2)), np.ones((200, 1))], axis=1)
    unit = rays / np.linalg.norm(rays, axis=1, keepdims=True)
    one, ok = refract(unit, np.array([0.0, 0.0, 1.0]), 1.0 / 1.333)
    assert ok.all()
    at = rays * 0.02  # the rays' points at z = d
    for port, exit_z in (
        (FlatPort(0.02, 0.0, 1.49, 1.333), 0.02),
        (FlatPort(0.02, 0.01, 1.333, 1.333), 0.03),
    ):
        origins, dirs, _ = port.trace(rays)
        np.testing.assert_allclose(dirs, one, atol=1e-15)
        expected = at + one * ((exit_z - 0.02) / one[:, 2])[:, None]
        np.testing.assert_allclose(origins, expected, atol=1e-15)


def test_no_total_internal_reflection_into_denser_media() -> None:
    """Even at grazing incidence (89.9 degrees) every ray passes; from glass into air
    (the reverse) Snell's law does reflect, which refract reports."""
    a = math.radians(89.9)
    rays = np.array([[math.sin(a), 0.0, math.cos(a)], [0.0, -math.sin(a), math.cos(a)]])
    _, dirs, ok = FlatPort(0.02, 0.01, 1.9, 1.34).trace(rays)
    assert ok.all() and np.all(np.isfinite(dirs))
    _, reflected = refract(rays, np.array([0.0, 0.0, 1.0]), 1.49)
    assert not reflected.any()


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"distance_m": 0.0, "thickness_m": 0.01}, "distance_m: expected a finite value > 0"),
        ({"distance_m": 0.02, "thickness_m": -0.01}, "thickness_m: expected a finite value >= 0"),
        ({"distance_m": 20.0, "thickness_m": 0.01}, "not millimetres"),
        ({"distance_m": 0.02, "thickness_m": 0.01, "water_index": 0.9}, "water_index"),
        ({"distance_m": 0.02, "thickness_m": 0.01, "glass_index": math.nan}, "glass_index"),
        ({"distance_m": 0.02, "thickness_m": 0.01, "normal_camera": (0.0, 1.0, 1.0)}, "20 deg"),
        ({"distance_m": "2", "thickness_m": 0.01}, "expected a number"),
    ],
)
def test_bad_ports_are_refused(kwargs: dict, match: str) -> None:
    with pytest.raises(ValueError, match=match):
        FlatPort(**kwargs)


def test_without_a_port_the_footprints_are_bit_for_bit_todays() -> None:
    camera, view = _camera(), _view()
    px = _all_pixels(camera)
    for b in (1, 2):
        pixels = px[(px[:, 0] < camera.width // b) & (px[:, 1] < camera.height // b)]
        a = pixel_footprints(camera, view, pixels, binning=b)
        w = wall_footprints(camera, view, pixels, mesh=None, binning=b, port=None)
        np.testing.assert_array_equal(w.corners_world, a.corners_world)
        np.testing.assert_array_equal(w.weights, a.weights)
        assert w.port_exits_world is None and w.normals_world is None
        rig = _rig()
        medium = Medium(0.3)
        np.testing.assert_array_equal(
            shade(w, view, rig, medium=medium).values, shade(a, view, rig, medium=medium).values
        )


def test_a_vanishing_port_gives_the_footprints_in_air() -> None:
    """A port of the air's index everywhere bends nothing: the footprints, weights and
    values are those without a port to round-off, in water too (an exit point lies on
    its ray, so |P - X_p| + |X_p - C| = |P - C|: T differs by exp(-c |X_p - C|); the
    mean of a pixel's exit points lies off the ray to its centre by a second-order
    amount: 1e-9 relative)."""
    camera, view, rig = _camera(), _view(), _rig()
    px = _all_pixels(camera)
    air_port = FlatPort(0.02, 0.01, 1.0, 1.0)
    for sensor in ("radiance", "cos4"):
        for b in (1, 2, 4):
            pixels = px[(px[:, 0] < camera.width // b) & (px[:, 1] < camera.height // b)]
            a = pixel_footprints(camera, view, pixels, binning=b, sensor=sensor)
            p = port_footprints(camera, view, pixels, air_port, binning=b, sensor=sensor)
            np.testing.assert_array_equal(p.valid, a.valid)
            np.testing.assert_allclose(p.corners_world, a.corners_world, atol=1e-14)
            np.testing.assert_allclose(p.weights, a.weights, rtol=1e-11)
            va = shade(a, view, rig, medium=Medium(0.5)).values
            vp = shade(p, view, rig, medium=Medium(0.5)).values
            dist_in = np.linalg.norm(p.port_exits_world - view.center_world, axis=1)
            np.testing.assert_allclose(vp, va * np.exp(0.5 * dist_in), rtol=3e-9)
            # A glossy wall: B through the +z normals and the exit points (the mesh's
            # path) is the planar kernel's from the camera centre (to 4e-7 b^2: the mean
            # of the exits lies a few um off the ray to the centre).
            wall = PlasticWall(0.2, 1.5, 1.0)
            np.testing.assert_allclose(
                shade(p, view, rig, wall=wall).values,
                shade(a, view, rig, wall=wall).values,
                rtol=1e-6 * b * b,
            )


def test_the_port_footprints_meet_the_refracted_rays_on_the_wall() -> None:
    camera, view = _camera(), _view()
    pixels = _all_pixels(camera)[::7]
    fp = wall_footprints(camera, view, pixels, mesh=None, port=PORT)
    assert fp.valid.all() and np.all(fp.corners_world[..., 2] == 0.0)
    # Corner (u - 1/2, v - 1/2) of each pixel, traced by hand.
    xy, _ = camera.pixels_to_normalized(pixels - 0.5)
    o, d, _ = PORT.trace(np.concatenate([xy, np.ones((len(xy), 1))], axis=1))
    R, C = view.R_camera_world, view.center_world
    o, d = o @ R + C, d @ R
    hit = o - (o[:, 2] / d[:, 2])[:, None] * d
    np.testing.assert_allclose(fp.corners_world[:, 0, 0, :2], hit[:, :2], atol=1e-15)
    # The port moves the footprints: by centimetres at 1.5 m.
    air = pixel_footprints(camera, view, pixels)
    shift = np.linalg.norm(fp.centers_world - air.centers_world, axis=1)
    assert shift.max() > 0.05


def test_port_refusals() -> None:
    camera, view = _camera(), _view()
    pixels = _all_pixels(camera)[:10]
    mesh = WallMesh(
        np.array([[-5.0, -5.0, 0.0], [5.0, -5.0, 0.0], [0.0, 5.0, 0.0]]), np.array([[0, 1, 2]])
    )
    with pytest.raises(ValueError, match="plane z = 0 only, not on a wall mesh"):
        wall_footprints(camera, view, pixels, mesh=mesh, port=PORT)
    with pytest.raises(ValueError, match="'paper' model"):
        wall_footprints(camera, view, pixels, mesh=None, port=PORT, sensor="paper")


def test_gradients_through_the_port_agree_with_central_differences() -> None:
    """Position and c, in water, with a glossy wall (its B from each pixel's exit point
    from the port)."""
    camera, view = _camera(), _view()
    pixels = _all_pixels(camera)[::11]
    fp = port_footprints(camera, view, pixels, PORT)
    medium, wall = Medium(0.4), PlasticWall(0.25, 1.5, 1.0)
    rig = _rig()
    s = shade(fp, view, rig, want_grad=True, medium=medium, wall=wall)
    assert s.grad_position is not None and s.grad_medium is not None
    light = rig.lights[0]
    h = 1e-6
    for k in range(3):
        e = np.zeros(3)
        e[k] = h
        up = shade(
            fp,
            view,
            Rig.single(light.replace(t_camera_light=light.t_camera_light + e)),
            medium=medium,
            wall=wall,
        )
        dn = shade(
            fp,
            view,
            Rig.single(light.replace(t_camera_light=light.t_camera_light - e)),
            medium=medium,
            wall=wall,
        )
        fd = (up.values - dn.values) / (2 * h)
        np.testing.assert_allclose(
            s.grad_position[0, :, k], fd, rtol=1e-5, atol=1e-6 * np.abs(fd).max()
        )
    up = shade(fp, view, rig, medium=Medium(0.4 + h), wall=wall).values
    dn = shade(fp, view, rig, medium=Medium(0.4 - h), wall=wall).values
    fd = (up - dn) / (2 * h)
    np.testing.assert_allclose(s.grad_medium[:, 0], fd, rtol=1e-6, atol=1e-9 * np.abs(fd).max())


def test_the_whole_image_through_the_port_is_every_pixels() -> None:
    """The whole image (the corner lattice traced once per camera and port, cached) is
    every pixel's footprint to round-off (the corner grid's undistortion), binned too."""
    camera, view, rig = _camera(), _view(), _rig()
    image = render_image_through_port(camera, view, rig, PORT, medium=Medium(0.2))
    px = _all_pixels(camera)
    values = render_pixels_through_port(camera, view, rig, px, PORT, medium=Medium(0.2))
    assert np.array_equal(np.ma.getmaskarray(image).ravel(), np.ma.getmaskarray(values))
    np.testing.assert_allclose(image.ravel(), values, rtol=1e-13, atol=0.0)
    again = render_image_through_port(camera, view, rig, PORT, medium=Medium(0.2))
    np.testing.assert_array_equal(again, image)  # from the cache: the same numbers
    binned = render_image_through_port(camera, view, rig, PORT, binning=2)
    assert binned.shape == (15, 20) and not np.ma.is_masked(binned)
    v, u = np.mgrid[0:15, 0:20]
    each = render_pixels_through_port(
        camera, view, rig, np.stack([u.ravel(), v.ravel()], axis=1), PORT, binning=2
    )
    np.testing.assert_allclose(binned.ravel(), each, rtol=1e-13, atol=0.0)
    # Without the port: the same view differs (the ratio is reported in model.md).
    air = render_pixels(camera, view, rig, px)
    assert np.max(np.abs(values / air - 1.0)) > 0.1


def test_the_room_light_through_the_port_carries_its_transmittance() -> None:
    """The whole image's room-light factor (report, page) is each pixel's footprint's
    (solver), radiance and cos4: the port's Fresnel transmittance of the pixel's rays."""
    from lightcal.core.port_render import room_light_view

    camera, view = _camera(), _view()
    assert room_light_view(camera, "radiance") is None
    px = _all_pixels(camera)
    for sensor in ("radiance", "cos4"):
        image = room_light_view(camera, sensor, None, PORT)
        assert image is not None and image.shape == (camera.height, camera.width)
        fp = port_footprints(camera, view, px, PORT, sensor=sensor)
        factor = fp.room_light_factor
        assert factor is not None
        ok = fp.valid
        np.testing.assert_allclose(image.ravel()[ok], factor[ok], rtol=1e-12)
    radiance = room_light_view(camera, "radiance", None, PORT)
    assert radiance is not None and 0.9 < np.nanmin(radiance) < np.nanmax(radiance) < 0.96


def test_a_lattice_too_large_to_keep_gives_the_same_image(monkeypatch) -> None:
    """Above `_RAYS_MAX_CORNERS` the lattice is traced each time, not kept: the same
    numbers."""
    from lightcal.core import port_footprints as pf

    camera, view, rig = _camera(), _view(), _rig()
    kept = render_image_through_port(camera, view, rig, PORT, medium=Medium(0.2))
    monkeypatch.setattr(pf, "_RAYS_MAX_CORNERS", 0)
    pf._RAYS.clear()
    traced = render_image_through_port(camera, view, rig, PORT, medium=Medium(0.2))
    np.testing.assert_array_equal(traced, kept)
    assert not pf._RAYS


@pytest.mark.parametrize("binning", [1, 2])
def test_a_selection_read_from_the_cached_lattice_is_the_traced_one(binning: int) -> None:
    """Once the camera's port lattice is cached (or for a dense selection) the corners
    are read from it, not traced: the same footprints to round-off (the corner grid's
    undistortion), the same valid pixels, on a grazing view where the top rows miss the
    wall."""
    from lightcal.core import port_footprints as pf

    camera = _camera()
    view = View.looking_at(np.array([0.1, -1.2, 0.35]), np.array([0.0, 0.6, 0.0]))
    pixels = _all_pixels(camera)
    pixels = pixels[(pixels[:, 0] < 40 // binning) & (pixels[:, 1] < 30 // binning)][::9]
    pf._RAYS.clear()
    traced = port_footprints(camera, view, pixels, PORT, sensor="cos4", binning=binning)
    assert not pf._RAYS  # a sparse selection traces its own corners
    pf.camera_port_rays(camera, PORT)
    read = port_footprints(camera, view, pixels, PORT, sensor="cos4", binning=binning)
    assert 0 < read.valid.sum() < len(pixels)
    np.testing.assert_array_equal(read.valid, traced.valid)
    ok = read.valid
    for a, b in (
        (read.corners_world, traced.corners_world),
        (read.port_exits_world, traced.port_exits_world),
        (read.weights, traced.weights),
        (read.port_transmittance, traced.port_transmittance),
    ):
        np.testing.assert_allclose(a[ok], b[ok], rtol=1e-12, atol=1e-15)
        assert np.all(np.isnan(a[~ok]) | (a[~ok] == 0.0))
    # A dense selection builds the lattice itself.
    pf._RAYS.clear()
    port_footprints(camera, view, _all_pixels(camera), PORT)
    assert len(pf._RAYS) == 1
