"""The medium (water): its transmittance, the renderer's use of it, its gradients."""

from __future__ import annotations

import math

import numpy as np
import pytest

from lightcal.core.footprint import pixel_footprints
from lightcal.core.medium import AIR, MAX_ATTENUATION_PER_M, Medium, footprint_spread
from lightcal.core.render import render_image, render_pixels, shade
from lightcal.core.rid import CosPowerRID
from lightcal.core.scene import Light, Rig
from lightcal.core.wall import PlasticWall
from tests.scenes import all_pixels, oblique_view, pinhole_camera, rotation_with_z, two_light_rig

WATER = Medium(0.3)


def _scene() -> tuple:
    camera = pinhole_camera()
    view = oblique_view()
    light = Light(
        CosPowerRID(3.0),
        np.array([0.06, -0.03, 0.02]),
        rotation_with_z((0.1, -0.05, 1.0)),
        scale=2.0,
    )
    return camera, view, Rig.single(light)


def test_transmittance_closed_form() -> None:
    """A point 3 m from the light and 4 m from the camera: exp(-c 7)."""
    light = np.array([0.0, 0.0, 3.0])
    camera = np.array([0.0, 4.0, 0.0])
    point = np.array([[0.0, 0.0, 0.0]])
    t = Medium(0.2).transmittance(point, light, camera)
    assert t[0] == pytest.approx(math.exp(-0.2 * 7.0), rel=1e-15)
    assert AIR.transmittance(point, light, camera)[0] == 1.0
    assert AIR.is_clear and not WATER.is_clear


def test_bad_medium_values_are_refused() -> None:
    for bad in (-0.1, math.nan, math.inf, MAX_ATTENUATION_PER_M * 1.01):
        with pytest.raises(ValueError, match="attenuation_per_m: expected a value in"):
            Medium(bad)


@pytest.mark.parametrize("medium", [WATER, Medium(1.7)])
def test_render_is_air_times_transmittance(medium: Medium) -> None:
    """Pixel values = the values in air x T at the footprint centre (one light)."""
    camera, view, rig = _scene()
    px = all_pixels(camera.width, camera.height)[::5]
    fp = pixel_footprints(camera, view, px)
    air = shade(fp, view, rig).values
    water = shade(fp, view, rig, medium=medium).values
    L = rig.lights[0].position_world(view)
    d = np.linalg.norm(fp.centers_world - L, axis=1)
    d += np.linalg.norm(fp.centers_world - view.center_world, axis=1)
    np.testing.assert_allclose(water, air * np.exp(-medium.attenuation_per_m * d), rtol=1e-13)


def test_air_is_bit_identical() -> None:
    camera, view, _ = _scene()
    rig = two_light_rig(CosPowerRID(2.0))
    a = render_image(camera, view, rig, offset=2.0)
    b = render_image(camera, view, rig, offset=2.0, medium=Medium(0.0))
    np.testing.assert_array_equal(a.filled(np.nan), b.filled(np.nan))


@pytest.mark.parametrize("wall", [None, PlasticWall(0.25, 1.5, 1.7)])
@pytest.mark.parametrize("sensor", ["radiance", "paper"])
@pytest.mark.parametrize("binning", [1, 2, 3])
def test_full_image_matches_pixels(binning: int, sensor: str, wall: PlasticWall | None) -> None:
    """The whole-image path (one fused pass per light, T per light) = the pixels' path,
    two lights, an offset, binned, with and without a glossy wall."""
    camera, view, _ = _scene()
    rig = two_light_rig(CosPowerRID(2.0))
    kw: dict = {"medium": WATER, "binning": binning, "offset": 3.0, "sensor": sensor}
    if wall is not None:
        kw["wall"] = wall
    img = render_image(camera, view, rig, **kw)
    px = all_pixels(camera.width // binning, camera.height // binning)
    vals = render_pixels(camera, view, rig, px, **kw)
    assert np.isfinite(vals.filled(np.nan)).sum() > 0.5 * len(px)
    np.testing.assert_allclose(img.filled(np.nan).ravel(), vals.filled(np.nan), rtol=1e-9)
    air = render_image(camera, view, rig, **{**kw, "medium": AIR})
    assert np.nanmax(img.filled(np.nan) - 3.0) < 0.9 * np.nanmax(air.filled(np.nan) - 3.0)


@pytest.mark.parametrize("wall", [None, PlasticWall(0.25, 1.5, 1.7)])
def test_shade_gradients_match_differences(wall: PlasticWall | None) -> None:
    """Position, rotation, wall and attenuation derivatives against central differences."""
    camera, view, _ = _scene()
    rig = two_light_rig(CosPowerRID(2.0))
    kw: dict = {} if wall is None else {"wall": wall}
    px = all_pixels(camera.width, camera.height)[::11]
    fp = pixel_footprints(camera, view, px)
    sh = shade(fp, view, rig, want_grad=True, medium=WATER, **kw)
    assert sh.grad_position is not None and sh.grad_rotation is not None
    assert sh.grad_medium is not None
    for j, light in enumerate(rig.lights):
        for k in range(3):
            h = 1e-7
            t_hi, t_lo = light.t_camera_light.copy(), light.t_camera_light.copy()
            t_hi[k] += h
            t_lo[k] -= h
            lights_hi, lights_lo = list(rig.lights), list(rig.lights)
            lights_hi[j] = light.replace(t_camera_light=t_hi)
            lights_lo[j] = light.replace(t_camera_light=t_lo)
            hi = shade(fp, view, Rig(tuple(lights_hi)), medium=WATER, **kw).values
            lo = shade(fp, view, Rig(tuple(lights_lo)), medium=WATER, **kw).values
            fd = (hi - lo) / (2 * h)
            np.testing.assert_allclose(sh.grad_position[j, :, k], fd, rtol=1e-5, atol=1e-9)
    c = WATER.attenuation_per_m
    h = 1e-6
    hi = shade(fp, view, rig, medium=Medium(c + h), **kw).values
    lo = shade(fp, view, rig, medium=Medium(c - h), **kw).values
    np.testing.assert_allclose(sh.grad_medium[:, 0], (hi - lo) / (2 * h), rtol=1e-6, atol=1e-10)
    if wall is not None:
        assert sh.grad_wall is not None
        p = wall.parameters()
        for k in range(p.size):
            h = 1e-6 * max(1.0, abs(p[k]))
            hi_p, lo_p = p.copy(), p.copy()
            hi_p[k] += h
            lo_p[k] -= h
            hi = shade(fp, view, rig, wall=wall.with_parameters(hi_p), medium=WATER).values
            lo = shade(fp, view, rig, wall=wall.with_parameters(lo_p), medium=WATER).values
            fd = (hi - lo) / (2 * h)
            np.testing.assert_allclose(sh.grad_wall[:, k], fd, rtol=1e-5, atol=1e-9)


def test_footprint_spread_bounds_the_center_error() -> None:
    """T averaged over each footprint (20 x 20 points per quad) differs from T(centre) by
    what `footprint_spread` estimates; 4 x 4 super-pixels in turbid water."""
    camera, view, rig = _scene()
    medium = Medium(2.0)
    px = all_pixels(camera.width // 4, camera.height // 4)[::5]
    fp = pixel_footprints(camera, view, px, binning=4)
    L = rig.lights[0].position_world(view)
    C = view.center_world
    bound = footprint_spread(fp.corners_world, fp.centers_world, L, C, medium)
    assert np.all(bound > 0)
    s = (np.arange(20) + 0.5) / 20
    ss, tt = (a.ravel() for a in np.meshgrid(s, s))
    errors = []
    for i in range(len(fp)):
        means = []
        for q in fp.corners_world[i]:  # bilinear points of each quad
            pts = (
                np.outer((1 - ss) * (1 - tt), q[0])
                + np.outer(ss * (1 - tt), q[1])
                + np.outer(ss * tt, q[2])
                + np.outer((1 - ss) * tt, q[3])
            )
            means.append(medium.transmittance(pts, L, C).mean())
        center = medium.transmittance(fp.centers_world[i], L, C)[0]
        errors.append(abs(np.mean(means) - center) / center)
    np.testing.assert_allclose(np.array(errors), bound, rtol=0.05, atol=1e-9)
    assert np.all(footprint_spread(fp.corners_world, fp.centers_world, L, C, AIR) == 0.0)


def test_invalid_pixels_stay_zero_with_their_gradients() -> None:
    """Footprints that miss the wall (NaN centres) keep flux and gradients 0 in water."""
    from tests.scenes import horizon_view, rid_model

    camera = pinhole_camera()
    view = horizon_view()
    fp = pixel_footprints(camera, view, all_pixels(64, 48)[::17])
    assert 0 < fp.valid.sum() < len(fp)
    rig = two_light_rig(rid_model("table_2d"))
    sh = shade(fp, view, rig, want_grad=True, medium=WATER)
    assert sh.grad_position is not None and sh.grad_medium is not None
    np.testing.assert_array_equal(sh.flux[:, ~fp.valid], 0.0)
    np.testing.assert_array_equal(sh.grad_position[:, ~fp.valid], 0.0)
    np.testing.assert_array_equal(sh.grad_medium[~fp.valid], 0.0)
    assert np.all(np.isfinite(sh.flux)) and np.any(sh.flux[:, fp.valid] > 0.0)


# -- backscatter -------------------------------------------------------------------------

MURKY = Medium(0.3, 2.0, 0.6)


def _scatter_reference(point: np.ndarray, camera: np.ndarray, light: Light, view, medium):
    """S of one pixel's ray by adaptive quadrature of the integrand (scipy's quad)."""
    from scipy.integrate import quad

    L = light.position_world(view)
    R = light.rotation_world(view)
    m = light.rid.m
    g, c = medium.phase_g, medium.attenuation_per_m
    d = point - camera
    t_w = float(np.linalg.norm(d))
    o = d / t_w

    def h(t: float) -> float:
        a = camera + t * o - L
        r = float(np.linalg.norm(a))
        w = a / r
        mu = -float(w @ o)
        p = (1 - g * g) / (4 * math.pi * (1 + g * g - 2 * g * mu) ** 1.5)
        f = max(float((R.T @ w)[2]), 0.0) ** m
        return p * f * math.exp(-c * (r + t)) / r**2

    return quad(h, 0.0, t_w, epsabs=0.0, epsrel=1e-10, limit=200)[0]


def test_backscatter_adds_beta_times_the_ray_integral() -> None:
    """Values in murky water = the values with attenuation alone + exposure beta S, S the
    integral along each pixel's ray to its footprint centre (24 Gauss-Legendre nodes
    against adaptive quadrature: 1e-5)."""
    camera, view, rig = _scene()
    light = rig.lights[0]
    px = all_pixels(camera.width, camera.height)[::97]
    fp = pixel_footprints(camera, view, px)
    clear = shade(fp, view, rig, medium=Medium(0.3)).values
    murky = shade(fp, view, rig, medium=MURKY).values
    s = np.array(
        [_scatter_reference(p, view.center_world, light, view, MURKY) for p in fp.centers_world]
    )
    expected = clear + light.scale * view.exposure * MURKY.backscatter_per_m * s
    assert np.all(s > 0.0)
    np.testing.assert_allclose(murky, expected, rtol=1e-5)


@pytest.mark.parametrize("binning", [1, 2])
def test_backscatter_full_image_matches_pixels(binning: int) -> None:
    camera, view, _ = _scene()
    rig = two_light_rig(CosPowerRID(2.0))
    kw: dict = {"medium": MURKY, "binning": binning, "offset": 3.0}
    img = render_image(camera, view, rig, **kw)
    vals = render_pixels(camera, view, rig, all_pixels(64 // binning, 48 // binning), **kw)
    np.testing.assert_allclose(img.filled(np.nan).ravel(), vals.filled(np.nan), rtol=1e-9)


def test_backscatter_needs_the_radiance_sensor_model() -> None:
    camera, view, rig = _scene()
    with pytest.raises(ValueError, match="backscatter is rendered for the radiance sensor"):
        render_image(camera, view, rig, medium=MURKY, sensor="cos4")


@pytest.mark.parametrize("medium", [MURKY, Medium(0.0, 5.0, -0.3)])
def test_backscatter_gradients_match_differences(medium: Medium) -> None:
    """Position, rotation (camera frame), c, beta and g derivatives of values with
    backscatter, two lights, against central differences."""
    from lightcal.core.rotations import matrix_from_rotvec

    camera, view, _ = _scene()
    rig = two_light_rig(CosPowerRID(2.0))
    fp = pixel_footprints(camera, view, all_pixels(camera.width, camera.height)[::13])
    sh = shade(fp, view, rig, want_grad=True, medium=medium)
    assert sh.grad_position is not None and sh.grad_rotation is not None
    assert sh.grad_medium is not None

    def values(lights: list[Light], m: Medium = medium) -> np.ndarray:
        return shade(fp, view, Rig(tuple(lights)), medium=m).values.filled(np.nan)

    h = 1e-6
    for j, light in enumerate(rig.lights):
        for k in range(3):
            e = np.zeros(3)
            e[k] = h
            hi, lo = list(rig.lights), list(rig.lights)
            hi[j] = light.replace(t_camera_light=light.t_camera_light + e)
            lo[j] = light.replace(t_camera_light=light.t_camera_light - e)
            fd = (values(hi) - values(lo)) / (2 * h)
            np.testing.assert_allclose(sh.grad_position[j, :, k], fd, rtol=1e-5, atol=1e-7)
            hi[j] = light.replace(R_camera_light=matrix_from_rotvec(e) @ light.R_camera_light)
            lo[j] = light.replace(R_camera_light=matrix_from_rotvec(-e) @ light.R_camera_light)
            fd = (values(hi) - values(lo)) / (2 * h)
            np.testing.assert_allclose(sh.grad_rotation[j, :, k], fd, rtol=1e-5, atol=1e-7)
    p = medium.parameters()
    assert sh.grad_medium.shape[1] == 3
    for k in range(3):
        hi_p, lo_p = p.copy(), p.copy()
        hi_p[k] += h
        lo_p[k] = p[k] - h if k == 2 else max(p[k] - h, 0.0)
        fd = (
            values(list(rig.lights), medium.with_parameters(hi_p))
            - values(list(rig.lights), medium.with_parameters(lo_p))
        ) / (hi_p[k] - lo_p[k])
        np.testing.assert_allclose(sh.grad_medium[:, k], fd, rtol=1e-5, atol=1e-8)


def test_backscatter_interpolated_across_a_large_image() -> None:
    """On a 960 x 720 image the whole-image renderer computes S on every 7th pixel and
    interpolates: within 1e-4 of the pixels' exact path, relative to the values."""
    from lightcal.core.medium import scatter_grid
    from tests.scenes import pinhole_camera as camera_of

    camera = camera_of(width=960, height=720, focal_px=900.0)
    _, view, rig = _scene()
    rows, cols = scatter_grid((720, 960))
    assert rows[1] - rows[0] == 7 and rows[-1] == 719 and cols[-1] == 959
    img = render_image(camera, view, rig, medium=MURKY).filled(np.nan)
    rng = np.random.default_rng(3)
    px = np.stack([rng.integers(0, 960, 3000), rng.integers(0, 720, 3000)], 1)
    exact = render_pixels(camera, view, rig, px, medium=MURKY).filled(np.nan)
    clear = render_pixels(camera, view, rig, px, medium=Medium(0.3)).filled(np.nan)
    ours = img[px[:, 1], px[:, 0]]
    ok = np.isfinite(exact)
    assert ok.sum() > 2500
    assert np.median((exact - clear)[ok] / exact[ok]) > 0.01  # backscatter matters
    np.testing.assert_allclose(ours[ok], exact[ok], rtol=1e-4)
