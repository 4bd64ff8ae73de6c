"""The bounce term in a homogeneous absorbing medium (`lightcal.core.bounce_term`,
`lightcal.core.bounce_transfers`; docs/model.md, "Inter-reflection"): c = 0 is the air
code path, the term against a brute-force point quadrature of the attenuated kernels,
its derivatives with respect to c and the pose against central differences, a
calibration that recovers the light and c with surroundings in water, and a project that
declares both."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from lightcal.core.bounce_term import BounceTerm
from lightcal.core.footprint import pixel_footprints
from lightcal.core.medium import AIR, Medium
from lightcal.core.problem import LightUnknown, MediumUnknown
from lightcal.core.render import shade
from lightcal.core.scene import Rig
from lightcal.core.solver import CalibrationModel, SolverOptions, run_least_squares
from lightcal.core.surroundings import Surface, Surroundings, segments_blocked
from lightcal.io.project import parse_project, project_from_spec
from tests.calib_scenes import (
    assert_columns_match_differences,
    observe,
    pose_errors,
    small_camera,
    start_near,
    symmetric_light,
)
from tests.calib_scenes import views as calib_views
from tests.test_bounce import _camera, _ceiling, _light_and_view, pose_differences

WATER = Medium(0.5)

SAMPLE = Path(__file__).resolve().parents[1] / "sample_data"


def _side() -> Surface:
    return Surface(
        np.array([0.6, -0.4, 0.0]),
        np.array([0.0, 1.4, 0.0]),
        np.array([0.0, 0.0, 0.5]),
        0.7,
        "side",
    )


def _term(bounces: int | None = None) -> BounceTerm:
    """The two-surface corner of tests/test_bounce.py seen by a 180 x 120 camera."""
    _, view = _light_and_view()
    pixels = np.array([[u, v] for u in range(5, 180, 12) for v in range(4, 120, 9)], np.int32)
    fp = pixel_footprints(_camera(), view, pixels)
    return BounceTerm(Surroundings((_ceiling(), _side()), 0.8, 0.1, bounces), [fp])


@pytest.mark.parametrize("bounces", [None, 3])
def test_c_zero_in_a_medium_is_the_air_term(bounces: int | None) -> None:
    """c = 0 through the medium's path (its derivative asked, backscatter declared) gives
    the air path's values and pose derivatives to 1e-12; air itself is untouched."""
    light, view = _light_and_view()
    term = _term(bounces)
    air = term.flux(0, view, light, want_grad=True)
    assert np.array_equal(air, term.flux(0, view, light, want_grad=True, medium=AIR))
    water = term.flux(0, view, light, want_grad=True, medium=Medium(0.0, 2.0), want_dc=True)
    scale = np.abs(air[:, 0]).max()
    np.testing.assert_allclose(water[:, :7], air, rtol=0.0, atol=1e-12 * scale)
    assert np.all(water[:, 7] < 0.0)  # attenuation only dims it


def _small_corner() -> Surroundings:
    """A ceiling and a side wall 0.2 m deep meeting the wall at y = -0.4 and x = 0.45."""
    ceiling = Surface(
        np.array([-0.4, -0.4, 0.0]), np.array([0.85, 0, 0]), np.array([0, 0, 0.2]), 0.8
    )
    side = Surface(np.array([0.45, -0.4, 0.0]), np.array([0, 0.6, 0]), np.array([0, 0, 0.2]), 0.7)
    return Surroundings((ceiling, side), 0.8, 0.05, 2)


def _cells(surface: Surface, nu: int, nv: int) -> tuple[np.ndarray, float]:
    """(nu nv, 3) the centres of an nu x nv grid of cells of a surface (index i nv + j),
    and their area."""
    s, t = np.meshgrid((np.arange(nu) + 0.5) / nu, (np.arange(nv) + 0.5) / nv, indexing="ij")
    q = surface.corner_world + s.reshape(-1, 1) * surface.edge_u_world
    return q + t.reshape(-1, 1) * surface.edge_v_world, surface.area_m2 / (nu * nv)


def _kernel(a, na, b, nb, c: float) -> np.ndarray:
    """(A, B) cos_a cos_b exp(-c r) / r^2 between points a (A, 3) with normals na (3,)
    and b (B, 3) with normals nb (3,); 0 where a side faces away."""
    d = b[None, :, :] - a[:, None, :]
    r = np.sqrt(np.einsum("abi,abi->ab", d, d))
    cos_a = np.maximum(d @ na, 0.0) / r
    cos_b = np.maximum(-(d @ nb), 0.0) / r
    return cos_a * cos_b * np.exp(-c * r) / (r * r)


def _brute_force(term: BounceTerm, light, view, points: np.ndarray, c: float) -> np.ndarray:
    """(N,) the bounce irradiance at wall points of two reflections (`bounces: 2`) by
    point quadrature with attenuation on every segment (light -> surface or wall, wall
    -> surface, surface -> surface, surface -> point): 2 cm cells for the radiance, the
    gather at the points over 5 mm cells (each holding its 2 cm cell's radiance); the
    wall is the map's grid region (the model's truncation), shadows tested point to
    point."""
    surfaces = term.map.surroundings.surfaces
    rho_w = term.map.surroundings.wall_albedo / math.pi
    L, R = light.position_world(view), light.rotation_world(view)
    h = term.map.h
    x0, x1 = term.map.x[0] - h / 2, term.map.x[-1] + h / 2
    y0, y1 = term.map.y[0] - h / 2, term.map.y[-1] + h / 2
    nx, ny = math.ceil((x1 - x0) / 0.02), math.ceil((y1 - y0) / 0.02)
    gx = x0 + (np.arange(nx) + 0.5) * (x1 - x0) / nx
    gy = y0 + (np.arange(ny) + 0.5) * (y1 - y0) / ny
    xx, yy = np.meshgrid(gx, gy, indexing="ij")
    wall = np.stack([xx.ravel(), yy.ravel(), np.zeros(xx.size)], axis=1)
    wall_area = (x1 - x0) * (y1 - y0) / xx.size
    up = np.array([0.0, 0.0, 1.0])

    def free(a, a_owner, b, b_owner) -> np.ndarray:
        owners = np.full(len(a), a_owner), np.full(len(b), b_owner)
        return ~segments_blocked(surfaces, a, owners[0], b, owners[1])

    def beam(q: np.ndarray, normal: np.ndarray, owner: int) -> np.ndarray:
        d = L - q
        r = np.linalg.norm(d, axis=1)
        u = (-d / r[:, None]) @ R
        f = light.rid(np.arccos(np.clip(u[:, 2], -1, 1)), np.arctan2(u[:, 1], u[:, 0]))
        lit = free(L[None], -1, q, owner)[0]
        return lit * f * np.maximum(d @ normal / r, 0.0) * np.exp(-c * r) / r**2

    w1 = rho_w * beam(wall, up, -1)
    sides = []  # each side of each surface: (cells, area, normal, owner, rho, grid, s1)
    for k, s in enumerate(surfaces):
        grid = (
            round(np.linalg.norm(s.edge_u_world) / 0.02),
            round(np.linalg.norm(s.edge_v_world) / 0.02),
        )
        q, area = _cells(s, *grid)
        for sign in (1.0, -1.0):
            n = sign * s.normal_world
            rho = s.albedo / math.pi
            sides.append((q, area, n, k, rho, grid, rho * beam(q, n, k)))
    out = np.zeros(len(points))
    for q, _, n, k, rho, (nu, nv), s1 in sides:
        s2 = rho * (_kernel(q, n, wall, up, c) * free(q, k, wall, -1)) @ w1 * wall_area
        for q2, area2, n2, k2, _, _, s1b in sides:
            if k2 != k:
                s2 += rho * (_kernel(q, n, q2, n2, c) * free(q, k, q2, k2)) @ s1b * area2
        fine, fine_area = _cells(surfaces[k], 4 * nu, 4 * nv)
        i, j = np.divmod(np.arange(16 * nu * nv), 4 * nv)
        coarse = (i // 4) * nv + j // 4
        K = _kernel(points, up, fine, n, c) * free(points, -1, fine, k)
        out += K @ (s1 + s2)[coarse] * fine_area
    return out


def test_the_term_in_water_matches_a_brute_force_quadrature() -> None:
    """bounces: 2 (the transfers G_SS, G_SW, G_WS and the near copies in play), c = 0.5
    /m: the model's bounce at pixels 5-35 cm from a corner against the brute force, in
    water and in air (measured: within 2.5 %, the two discretisations), and the ratio
    water / air, the attenuation alone (measured: 8.7e-4; the bounce cut to 42 %)."""
    light, view = _light_and_view()
    pixels = np.array([[u, v] for u in range(102, 140, 6) for v in range(66, 104, 6)], np.int32)
    fp = pixel_footprints(_camera(), view, pixels)
    term = BounceTerm(_small_corner(), [fp])
    points = term.centers_world[0]
    to_camera = np.linalg.norm(points - view.center_world, axis=1)
    got, want = {}, {}
    for c in (0.0, WATER.attenuation_per_m):
        flux = term.flux(0, view, light, want_grad=False, medium=Medium(c))[:, 0]
        got[c] = flux / (view.exposure * term.coverage[0]) * np.exp(c * to_camera)
        want[c] = _brute_force(term, light, view, points, c)
    ratio = (got[0.5] / got[0.0]) / (want[0.5] / want[0.0])
    for c in got:
        np.testing.assert_allclose(got[c], want[c], rtol=0.03)
    np.testing.assert_allclose(ratio, 1.0, rtol=0.0, atol=2e-3)


@pytest.mark.parametrize("bounces", [None, 3])
@pytest.mark.parametrize("c", [0.0, 0.5])
def test_d_dc_matches_central_differences(bounces: int | None, c: float) -> None:
    light, view = _light_and_view()
    term = _term(bounces)
    got = term.flux(0, view, light, want_grad=False, medium=Medium(c), want_dc=True)
    h = 1e-5
    hi = term.flux(0, view, light, want_grad=False, medium=Medium(c + h))[:, 0]
    lo = term.flux(0, view, light, want_grad=False, medium=Medium(max(c - h, 0.0)))[:, 0]
    fd = (hi - lo) / (h + min(h, c))
    scale = np.abs(got[:, 1]).max()
    assert scale > 0.0
    tol = 1e-7 if c > 0.0 else 1e-4  # one-sided at c = 0: second order
    np.testing.assert_allclose(got[:, 1], fd, rtol=tol, atol=tol * scale)


@pytest.mark.parametrize("bounces", [None, 3])
def test_pose_derivatives_in_water_match_central_differences(bounces: int | None) -> None:
    light, view = _light_and_view()
    term = _term(bounces)
    got = term.flux(0, view, light, want_grad=True, medium=WATER)
    fd = pose_differences(
        lambda moved: term.flux(0, view, moved, want_grad=False, medium=WATER)[:, 0], light, view
    )
    np.testing.assert_allclose(got[:, 1:7], fd, rtol=1e-4, atol=1e-6 * np.abs(got[:, 0]).max())


def _calibration_data(c: float, surroundings: Surroundings):
    """Noise-free views rendered by the model itself: the direct light through water of
    attenuation c and the bounce of `surroundings` in it."""
    truth = symmetric_light()
    medium = Medium(c)
    vs = calib_views(6, seed=5)
    images = observe(
        small_camera(), vs, Rig.single(truth), rng=np.random.default_rng(5), medium=medium
    )
    term = BounceTerm(surroundings, [im.footprints for im in images])
    for i, im in enumerate(images):
        bounce = term.values(i, im.view, Rig.single(truth), medium)
        assert np.all(bounce > 0.0)
        im.observed[:] = im.observed + bounce
    return images, truth


def _room() -> Surroundings:
    """A ceiling 0.5 m above where the views look and a side wall, 0.4 m deep."""
    ceiling = Surface(
        np.array([-1.5, -0.5, 0.0]), np.array([2.3, 0, 0]), np.array([0, 0, 0.4]), 0.8
    )
    side = Surface(np.array([0.8, -0.5, 0.0]), np.array([0, 1.8, 0]), np.array([0, 0, 0.4]), 0.8)
    return Surroundings((ceiling, side), 0.8, 0.2)


def test_the_attenuation_column_with_the_bounce_matches_differences() -> None:
    """The Jacobian's c and pose columns of a model with surroundings in water against
    central differences of its residuals."""
    images, truth = _calibration_data(0.3, _room())
    model = CalibrationModel(
        images[:3],
        [LightUnknown(start_near(truth))],
        SolverOptions(),
        medium=MediumUnknown(Medium(0.25), ("attenuation_per_m",)),
        surroundings=_room(),
    )
    assert_columns_match_differences(model, model.layout.x0.copy())


def test_a_calibration_in_water_recovers_the_light_and_c_with_surroundings() -> None:
    """Noise-free, the model's own render with surroundings in water (c = 0.3 /m), c
    estimated from 0.1 /m: the light to 1e-6 m and 1e-4 deg, c to 1e-6 /m."""
    room = _room()
    images, truth = _calibration_data(0.3, room)
    model = CalibrationModel(
        images,
        [LightUnknown(start_near(truth))],
        SolverOptions(),
        medium=MediumUnknown(Medium(0.1), ("attenuation_per_m",)),
        surroundings=room,
    )
    out = run_least_squares(model)
    assert out.success, out.message
    dp, da = pose_errors(model.layout.rig(out.x).lights[0], truth)
    assert dp < 1e-6
    assert da < 1e-4
    assert model.layout.medium_of(out.x).attenuation_per_m == pytest.approx(0.3, abs=1e-6)


def test_a_project_may_declare_surroundings_in_a_medium() -> None:
    """`surroundings:` beside `medium:` (attenuation estimated, backscatter given) loads:
    the sample project with both sections added."""
    source = SAMPLE / "project.json"
    doc = json.loads(source.read_text())
    doc["medium"] = {
        "attenuation_per_m": 0.2,
        "backscatter_per_m": 0.5,
        "estimate": ["attenuation_per_m"],
    }
    ceiling = {"corner_m": [-1, -0.5, 0], "edge_u_m": [2, 0, 0], "edge_v_m": [0, 0, 0.5]}
    doc["surroundings"] = {"surfaces": [{**ceiling, "albedo": 0.8}]}
    project = project_from_spec(parse_project(doc, source), source)
    assert project.surroundings is not None
    assert project.medium.initial.attenuation_per_m == 0.2
    assert project.medium.estimate == ("attenuation_per_m",)


def test_the_weights_from_the_render_hold_the_bounce_in_water() -> None:
    """`set_weights_at` (a noise model given) takes sigma from the rendered values, the
    bounce in water among them: at the truth, sqrt(gain (direct + bounce) + read)."""
    room, truth, noise = _room(), symmetric_light(), (0.5, 4.0)
    medium = Medium(0.3)
    images = observe(
        small_camera(),
        calib_views(2, seed=5),
        Rig.single(truth),
        rng=np.random.default_rng(5),
        medium=medium,
        noise=noise,
        noise_model=True,
    )
    model = CalibrationModel(
        images,
        [LightUnknown(truth)],
        SolverOptions(),
        medium=MediumUnknown(medium),
        surroundings=room,
    )
    model.set_weights_at(model.layout.x0)
    term = BounceTerm(room, [im.footprints for im in images])
    for i, im in enumerate(images):
        direct = shade(im.footprints, im.view, Rig.single(truth), medium=medium).values
        signal = direct.filled(np.nan) + term.values(i, im.view, Rig.single(truth), medium)
        want = np.sqrt(noise[0] * signal + noise[1])
        np.testing.assert_allclose(model.sigmas[i], want, rtol=1e-12)
