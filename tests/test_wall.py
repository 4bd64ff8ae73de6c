"""Wall reflectance models: closed forms, invariants, gradients, the renderer's use of them."""

from __future__ import annotations

import math

import numpy as np
import pytest

from lightcal.core.footprint import pixel_footprints
from lightcal.core.render import render_image, render_pixels, shade
from lightcal.core.rid import CosPowerRID
from lightcal.core.scene import Light, Rig
from lightcal.core.wall import (
    LAMBERTIAN,
    LambertianWall,
    OrenNayarWall,
    PlasticWall,
    footprint_spread,
    internal_reflectance,
    make_wall,
    rough_transmittance,
    wall_from_description,
)
from tests.scenes import all_pixels, oblique_view, pinhole_camera, rotation_with_z, two_light_rig

WALLS = {
    "plastic": PlasticWall(0.25, 1.5, 1.7),
    "plastic_rough": PlasticWall(0.6, 1.4, 0.8),
    "oren_nayar": OrenNayarWall(math.radians(25.0)),
}


def _dirs(rng: np.random.Generator, n: int) -> np.ndarray:
    v = rng.normal(size=(n, 3))
    v[:, 2] = np.abs(v[:, 2]) + 0.05
    return v / np.linalg.norm(v, axis=1, keepdims=True)


def test_lambertian_is_one() -> None:
    rng = np.random.default_rng(0)
    b, _ = LAMBERTIAN.factor(_dirs(rng, 10), _dirs(rng, 10))
    np.testing.assert_array_equal(b, 1.0)


def test_oren_nayar_closed_form() -> None:
    """Hand values: A alone when the tangential directions oppose; A + B sin a tan b in plane."""
    s = math.radians(30.0)
    s2 = s * s
    a = 1 - 0.5 * s2 / (s2 + 0.33)
    bb = 0.45 * s2 / (s2 + 0.09)
    wall = OrenNayarWall(s)
    ti, to = math.radians(40.0), math.radians(20.0)
    l = np.array([[math.sin(ti), 0.0, math.cos(ti)]])
    v_same = np.array([[math.sin(to), 0.0, math.cos(to)]])
    v_opp = np.array([[-math.sin(to), 0.0, math.cos(to)]])
    np.testing.assert_allclose(
        wall.factor(l, v_same)[0], a + bb * math.sin(ti) * math.tan(to), rtol=1e-14
    )
    np.testing.assert_allclose(wall.factor(l, v_opp)[0], a, rtol=1e-14)
    np.testing.assert_allclose(OrenNayarWall(0.0).factor(l, v_same)[0], 1.0, rtol=1e-14)


def test_plastic_smooth_limit_specular_peak() -> None:
    """Normal incidence and view: D = 1 / (pi alpha^2), G1 = 1, F = ((eta - 1)/(eta + 1))^2."""
    wall = PlasticWall(0.1, 1.5, 2.0)
    z = np.array([[0.0, 0.0, 1.0]])
    f0 = (0.5 / 2.5) ** 2
    spec = math.pi * f0 * (1.0 / (math.pi * 0.01)) / 4.0
    np.testing.assert_allclose(wall.factor(z, z)[0], 1.0 + 2.0 * spec, rtol=1e-12)


@pytest.mark.parametrize("name", sorted(WALLS))
def test_reciprocity(name: str) -> None:
    rng = np.random.default_rng(1)
    l, v = _dirs(rng, 200), _dirs(rng, 200)
    wall = WALLS[name]
    np.testing.assert_allclose(wall.factor(l, v)[0], wall.factor(v, l)[0], rtol=1e-12)


@pytest.mark.parametrize("name", sorted(WALLS))
def test_parameter_gradient_matches_differences(name: str) -> None:
    rng = np.random.default_rng(2)
    l, v = _dirs(rng, 50), _dirs(rng, 50)
    wall = WALLS[name]
    _, dp = wall.factor(l, v, want_grad=True)
    assert dp is not None
    p = wall.parameters()
    for k in range(p.size):
        h = 1e-6 * max(1.0, abs(p[k]))
        hi, lo = p.copy(), p.copy()
        hi[k] += h
        lo[k] -= h
        fd = (
            wall.with_parameters(hi).factor(l, v)[0] - wall.with_parameters(lo).factor(l, v)[0]
        ) / (2 * h)
        np.testing.assert_allclose(dp[:, k], fd, rtol=2e-6, atol=1e-9)


def test_transmittance_is_an_energy_fraction_and_falls_at_grazing() -> None:
    t, _, _ = rough_transmittance(0.3, 1.5)
    assert np.all((t > 0) & (t < 1))
    assert t[-1] > t[1]
    # A smooth coat transmits 1 - F(0) = 1 - 0.04 at normal incidence.
    t_smooth, _, _ = rough_transmittance(0.02, 1.5)
    assert t_smooth[-1] == pytest.approx(0.96, abs=2e-3)
    assert 0.3 < internal_reflectance(0.3, 1.5) < 0.7


def test_make_wall_errors() -> None:
    with pytest.raises(ValueError, match="wall model: expected one of lambertian, plastic, "):
        make_wall("glossy")
    with pytest.raises(ValueError, match="plastic wall: unknown parameter"):
        make_wall("plastic", {"alpha": 0.2})
    with pytest.raises(
        ValueError, match=r"plastic wall: roughness: expected a value in \[0.02, 1\]"
    ):
        make_wall("plastic", {"roughness": 0.0})
    assert isinstance(make_wall("lambertian"), LambertianWall)


# -- the renderer ------------------------------------------------------------------------


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


@pytest.mark.parametrize("name", sorted(WALLS))
def test_render_is_lambertian_times_factor(name: str) -> None:
    """Pixel values = Lambertian values x B(l, v) at the footprint centre."""
    camera, view, rig = _scene()
    wall = WALLS[name]
    px = all_pixels(camera.width, camera.height)[::7]
    fp = pixel_footprints(camera, view, px)
    lam = shade(fp, view, rig).values
    glossy = shade(fp, view, rig, wall=wall).values
    P = fp.centers_world
    L = rig.lights[0].position_world(view)
    l = (L - P) / np.linalg.norm(L - P, axis=1, keepdims=True)
    v = (view.center_world - P) / np.linalg.norm(view.center_world - P, axis=1, keepdims=True)
    b, _ = wall.factor(l, v)
    np.testing.assert_allclose(glossy, lam * b, rtol=1e-13)


@pytest.mark.parametrize("sensor", ["radiance", "paper"])
@pytest.mark.parametrize("binning", [1, 2])
@pytest.mark.parametrize("name", sorted(WALLS))
def test_full_image_matches_pixels(name: str, binning: int, sensor: str) -> None:
    camera, view, _ = _scene()
    rig = two_light_rig(CosPowerRID(2.0))
    wall = WALLS[name]
    kw = {"wall": wall, "binning": binning, "offset": 3.0, "sensor": sensor}
    img = render_image(camera, view, rig, **kw)
    px = all_pixels(camera.width // binning, camera.height // binning)
    vals = render_pixels(camera, view, rig, px, **kw)
    np.testing.assert_allclose(img.filled(np.nan).ravel(), vals.filled(np.nan), rtol=1e-9)


def test_lambertian_wall_is_bit_identical() -> None:
    camera, view, rig = _scene()
    a = render_image(camera, view, rig)
    b = render_image(camera, view, rig, wall=LambertianWall())
    np.testing.assert_array_equal(a.filled(np.nan), b.filled(np.nan))


@pytest.mark.parametrize("name", sorted(WALLS))
def test_shade_gradients_match_differences(name: str) -> None:
    camera, view, rig = _scene()
    wall = WALLS[name]
    px = all_pixels(camera.width, camera.height)[::11]
    fp = pixel_footprints(camera, view, px)
    sh = shade(fp, view, rig, want_grad=True, wall=wall)
    assert sh.grad_position is not None and sh.grad_wall is not None
    light = rig.lights[0]
    for k in range(3):
        h = 1e-7
        t_hi, t_lo = light.t_camera_light.copy(), light.t_camera_light.copy()
        t_hi[k] += h
        t_lo[k] -= h
        hi = shade(fp, view, Rig.single(light.replace(t_camera_light=t_hi)), wall=wall).values
        lo = shade(fp, view, Rig.single(light.replace(t_camera_light=t_lo)), wall=wall).values
        fd = (hi - lo) / (2 * h)
        np.testing.assert_allclose(sh.grad_position[0, :, k], fd, rtol=1e-5, atol=1e-9)
    p = wall.parameters()
    for k in range(p.size):
        h = 1e-6 * max(1.0, abs(p[k]))
        hi_p, lo_p = p.copy(), p.copy()
        hi_p[k] += h
        lo_p[k] -= h
        hi = shade(fp, view, rig, wall=wall.with_parameters(hi_p)).values
        lo = shade(fp, view, rig, wall=wall.with_parameters(lo_p)).values
        np.testing.assert_allclose(sh.grad_wall[:, k], (hi - lo) / (2 * h), rtol=1e-5, atol=1e-9)


@pytest.mark.parametrize("roughness", [0.1, 0.3])
def test_footprint_spread_bounds_the_center_error(roughness: float) -> None:
    """B averaged over each footprint (20 x 20 points per quad) differs from B(centre) by
    what `footprint_spread` estimates."""
    camera, view, rig = _scene()
    wall = PlasticWall.from_albedo(roughness, 1.5, 0.8)
    px = all_pixels(camera.width // 2, camera.height // 2)[::13]
    fp = pixel_footprints(camera, view, px, binning=2)
    L = rig.lights[0].position_world(view)
    bound = footprint_spread(fp.corners_world, fp.centers_world, L, view.center_world, wall)
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
            l = L - pts
            v = view.center_world - pts
            l /= np.linalg.norm(l, axis=1, keepdims=True)
            v /= np.linalg.norm(v, axis=1, keepdims=True)
            means.append(wall.factor(l, v)[0].mean())
        c = fp.centers_world[i]
        lc = (L - c) / np.linalg.norm(L - c)
        vc = (view.center_world - c) / np.linalg.norm(view.center_world - c)
        center = wall.factor(lc[None], vc[None])[0][0]
        errors.append(abs(np.mean(means) - center) / center)
    np.testing.assert_allclose(np.array(errors), bound, rtol=0.05, atol=5e-6)
    np.testing.assert_array_equal(
        footprint_spread(fp.corners_world, fp.centers_world, L, view.center_world, LAMBERTIAN),
        0.0,
    )


@pytest.mark.parametrize("name", sorted(WALLS))
def test_description_round_trip(name: str) -> None:
    wall = WALLS[name]
    back = wall_from_description(wall.describe())
    assert type(back) is type(wall)
    np.testing.assert_allclose(back.parameters(), wall.parameters(), rtol=1e-15)
    assert wall_from_description({"model": "lambertian"}).is_lambertian
