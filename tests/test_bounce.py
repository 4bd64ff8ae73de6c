"""The bounce term of surfaces around the wall (`lightcal.core.surroundings`,
`lightcal.core.bounce`; docs/model.md, "Inter-reflection"): Lambert's formula against
closed forms, the radiosity against a brute-force integral, the pose derivatives against
central differences, and the refusals of bad surfaces."""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
import pytest

from lightcal.core.bounce import BounceMap
from lightcal.core.bounce_term import BounceTerm
from lightcal.core.footprint import pixel_footprints
from lightcal.core.rid import CosPowerRID
from lightcal.core.rotations import matrix_from_rotvec
from lightcal.core.scene import Light, View
from lightcal.core.surroundings import (
    Surface,
    Surroundings,
    polygon_irradiance,
    screened_footprints,
)


def _parallel_corner(a: float, b: float, c: float) -> float:
    """pi x the form factor from a point to an a x b rectangle parallel to it at distance
    c, the point under one corner (Howell's catalogue, B-3)."""
    A, B = a / c, b / c
    return 0.5 * (
        A / math.sqrt(1 + A * A) * math.atan(B / math.sqrt(1 + A * A))
        + B / math.sqrt(1 + B * B) * math.atan(A / math.sqrt(1 + B * B))
    )


def test_polygon_irradiance_matches_the_parallel_rectangle_closed_form() -> None:
    a, b, c = 1.0, 2.0, 1.5
    quad = np.array([[[0, 0, c], [a, 0, c], [a, b, c], [0, b, c]]], dtype=np.float64)
    got = polygon_irradiance(np.zeros((1, 3)), np.array([[0.0, 0.0, 1.0]]), quad)
    assert got[0, 0] == pytest.approx(_parallel_corner(a, b, c), rel=1e-12)
    # Reversed vertices: the opposite sign (the formula is signed by the vertex order).
    back = polygon_irradiance(np.zeros((1, 3)), np.array([[0.0, 0.0, 1.0]]), quad[:, ::-1])
    assert back[0, 0] == pytest.approx(-got[0, 0], rel=1e-12)


def test_polygon_irradiance_of_a_huge_rectangle_is_pi() -> None:
    """A rectangle filling the hemisphere: the projected solid angle pi."""
    s = 1e5
    quad = np.array([[[-s, -s, 1.0], [s, -s, 1.0], [s, s, 1.0], [-s, s, 1.0]]])
    got = polygon_irradiance(np.zeros((1, 3)), np.array([[0.0, 0.0, 1.0]]), quad)
    assert got[0, 0] == pytest.approx(math.pi, rel=1e-4)


def test_polygon_irradiance_of_a_perpendicular_strip() -> None:
    """An infinite strip of depth D perpendicular to the receiving plane, its edge at
    distance d: pi F = (pi/2) (1 - d / sqrt(d^2 + D^2)) (the 2-D strip's form factor)."""
    d, D, s = 0.3, 0.5, 1e5
    quad = np.array([[[-s, 0.0, 0.0], [s, 0.0, 0.0], [s, 0.0, D], [-s, 0.0, D]]])
    point = np.array([[0.0, d, 0.0]])
    got = abs(polygon_irradiance(point, np.array([[0.0, 0.0, 1.0]]), quad)[0, 0])
    assert got == pytest.approx(math.pi / 2 * (1 - d / math.hypot(d, D)), rel=1e-6)


def _ceiling(albedo: float = 0.8) -> Surface:
    return Surface(
        np.array([-1.0, -0.4, 0.0]),
        np.array([2.0, 0.0, 0.0]),
        np.array([0.0, 0.0, 0.5]),
        albedo,
        "ceiling",
    )


def _light_and_view() -> tuple[Light, View]:
    view = View(np.diag([1.0, -1.0, -1.0]), np.array([0.0, 0.0, 1.2]))  # 1.2 m, facing
    R = np.array(
        [[1.0, 0.0, 0.0], [0.0, np.cos(0.2), -np.sin(0.2)], [0.0, np.sin(0.2), np.cos(0.2)]]
    )
    light = Light(CosPowerRID(3.0), np.array([0.05, 0.02, 0.0]), R, scale=1.0)
    return light, view


def _brute_force_first_bounce(
    surface: Surface, light_world: np.ndarray, R_world_light: np.ndarray, rid, points: np.ndarray
) -> np.ndarray:
    """(N,) the bounce irradiance at wall points of one surface lit by the beam alone
    (the wall's own light not sent back): a midpoint sum of (rho / pi) e(Q) cos cos / r^2
    over 2 mm cells of the side facing the points."""
    n_u, n_v = 1000, 250
    s = (np.arange(n_u) + 0.5) / n_u
    t = (np.arange(n_v) + 0.5) / n_v
    ss, tt = np.meshgrid(s, t, indexing="ij")
    q = surface.corner_world + ss.ravel()[:, None] * surface.edge_u_world
    q = q + tt.ravel()[:, None] * surface.edge_v_world
    area = surface.area_m2 / (n_u * n_v)
    normal = surface.normal_world
    if (points[0] - surface.corner_world) @ normal < 0:
        normal = -normal
    d = light_world - q
    r = np.linalg.norm(d, axis=1)
    u = (-d / r[:, None]) @ R_world_light
    f = rid(np.arccos(np.clip(u[:, 2], -1, 1)), np.arctan2(u[:, 1], u[:, 0]))
    e = f * np.maximum(d @ normal / r, 0.0) / r**2
    radiance = surface.albedo / math.pi * e
    out = np.empty(len(points))
    for k, p in enumerate(points):
        w = q - p
        rr = np.einsum("ij,ij->i", w, w)
        cos_p = w[:, 2] / np.sqrt(rr)
        cos_q = -(w @ normal) / np.sqrt(rr)
        out[k] = np.sum(radiance * np.maximum(cos_p, 0) * np.maximum(cos_q, 0) / rr) * area
    return out


def test_the_first_bounce_matches_a_brute_force_integral() -> None:
    """One surface, the wall nearly black (no light sent back to the surface): the map's
    bounce equals the integral over 2 mm cells, away from the corner and next to it."""
    ceiling = _ceiling()
    light, view = _light_and_view()
    L, R = light.position_world(view), light.rotation_world(view)
    points = np.array([[0.0, 0.3, 0.0], [0.2, -0.1, 0.0], [-0.3, -0.37, 0.0], [0.1, -0.395, 0.0]])
    surroundings = Surroundings((ceiling,), wall_albedo=1e-9, patch_m=0.05)
    bm = BounceMap(surroundings, (-0.5, 0.5, -0.5, 0.5))
    got = bm.bounce(
        bm.radiance(bm.source_columns(L, R, light.rid, want_grad=False)), bm.pixel_map(points)
    )
    want = _brute_force_first_bounce(ceiling, L, R, light.rid, points)
    np.testing.assert_allclose(got[:, 0], want, rtol=0.02)


@pytest.mark.parametrize("offset", [0.0, 0.3, 0.55, 0.8])
def test_next_to_a_foot_the_bounce_does_not_hang_on_the_grid(offset: float) -> None:
    """0.5-2 cm from where the ceiling meets the wall, the production mesh (`patch_m` 0.1,
    nodes 5 cm apart) against the 2 mm integral, the grid shifted by `offset` spacings:
    the nodes across the foot (behind the ceiling) do not interpolate its light, and its
    far copies' light falls to 0 at the foot with the point's distance from the ceiling's
    plane (`lightcal.core.bounce_pixels`). Interpolated across the foot, as before, it was
    up to 12 % off with the grid shifted (measured: within 3.4 % now, the copies' uniform
    radiance)."""
    ceiling = _ceiling()
    light, view = _light_and_view()
    L, R = light.position_world(view), light.rotation_world(view)
    x = np.array([-0.31, -0.12, 0.07, 0.26])
    points = np.stack([x, -0.4 + np.array([0.005, 0.01, 0.015, 0.02]), np.zeros(4)], axis=1)
    surroundings = Surroundings((ceiling,), wall_albedo=1e-9, patch_m=0.1)
    h = 0.05 * offset
    bm = BounceMap(surroundings, (-0.5 + h, 0.5, -0.5 + h, 0.5))
    got = bm.bounce(
        bm.radiance(bm.source_columns(L, R, light.rid, want_grad=False)), bm.pixel_map(points)
    )
    want = _brute_force_first_bounce(ceiling, L, R, light.rid, points)
    np.testing.assert_allclose(got[:, 0], want, rtol=0.04)


def test_pixels_a_surface_hides_in_part_are_screened() -> None:
    """A footprint with a corner behind the ceiling as the camera sees it (one straddling
    its foot, one beyond it) is screened; one beside the foot, all on the camera's side,
    is not, nor one off the wall (NaN corners)."""
    _, view = _light_and_view()  # the camera 1.2 m from the wall, above the ceiling's plane
    square = np.array([[0.0, 0.0, 0.0], [0.004, 0.0, 0.0], [0.004, 0.004, 0.0], [0.0, 0.004, 0.0]])
    lows_m = [-0.402, -0.45, -0.396, -0.2]  # the ceiling's foot at y = -0.4
    corners = np.stack([square + np.array([0.1, y, 0.0]) for y in lows_m])[:, None]
    corners = np.concatenate([corners, np.full((1, 1, 4, 3), np.nan)])
    surroundings = Surroundings((_ceiling(),), wall_albedo=0.8, patch_m=0.1)
    screened = screened_footprints(surroundings, view.center_world, corners)
    assert screened.tolist() == [True, True, False, False, False]


def test_the_wall_albedo_adds_the_light_the_wall_sends_back() -> None:
    """Wall -> surface -> wall grows with rho_w: the bounce is larger, by less than the
    first bounce's rho_w F (F < 1/2 for one surface)."""
    light, view = _light_and_view()
    L, R = light.position_world(view), light.rotation_world(view)
    points = np.array([[0.0, 0.0, 0.0], [0.3, -0.3, 0.0]])
    values = []
    for rho_w in (1e-9, 0.8):
        bm = BounceMap(Surroundings((_ceiling(),), rho_w, 0.05), (-0.5, 0.5, -0.5, 0.5))
        src = bm.source_columns(L, R, light.rid, want_grad=False)
        values.append(bm.bounce(bm.radiance(src), bm.pixel_map(points))[:, 0])
    ratio = values[1] / values[0]
    assert np.all(ratio > 1.05) and np.all(ratio < 1.0 + 0.8 * 0.5 * 4)


def test_the_pose_derivatives_match_central_differences() -> None:
    light, view = _light_and_view()
    camera = _camera()
    pixels = np.array([[u, v] for u in range(20, 160, 35) for v in range(10, 120, 30)], np.int32)
    fp = pixel_footprints(camera, view, pixels)
    side = Surface(
        np.array([0.6, -0.4, 0.0]),
        np.array([0.0, 1.4, 0.0]),
        np.array([0.0, 0.0, 0.5]),
        0.7,
        "side",
    )
    term = BounceTerm(Surroundings((_ceiling(), side), 0.8, 0.1), [fp])
    got = term.flux(0, view, light, want_grad=True)
    fd = pose_differences(
        lambda moved: term.flux(0, view, moved, want_grad=False)[:, 0], light, view
    )
    np.testing.assert_allclose(got[:, 1:7], fd, rtol=1e-4, atol=1e-6 * np.abs(got[:, 0]).max())


def pose_differences(
    flux: Callable[[Light], np.ndarray], light: Light, view: View, h: float = 1e-5
) -> np.ndarray:
    """(N, 6) central differences of flux(light) (N,) with respect to the light's world
    position and a left rotation of its world orientation (`render.light_flux`'s order)."""
    R_cw = view.R_camera_world
    columns = []
    for c in range(6):
        vals = []
        for sgn in (1.0, -1.0):
            step = np.zeros(3)
            step[c % 3] = sgn * h
            if c < 3:  # world position: t_camera_light moves by R step
                moved = light.replace(t_camera_light=light.t_camera_light + R_cw @ step)
            else:  # world rotation: R_camera_light -> R exp(delta_world) R^T ...
                turn = R_cw @ matrix_from_rotvec(step) @ R_cw.T
                moved = light.replace(R_camera_light=turn @ light.R_camera_light)
            vals.append(flux(moved))
        columns.append((vals[0] - vals[1]) / (2 * h))
    return np.stack(columns, axis=1)


def _camera():
    from lightcal.core.camera import Camera

    return Camera.from_params(fx=150.0, fy=150.0, cx=89.5, cy=59.5, width=180, height=120)


@pytest.mark.parametrize(
    ("corner", "u", "v", "albedo", "message"),
    [
        (
            [0, 0, -0.1],
            [1, 0, 0],
            [0, 0, 0.5],
            0.8,
            "s: reaches behind the wall (z = -0.1 m); expected z >= 0 everywhere (the wall is "
            "the plane z = 0, the cameras are at z > 0)",
        ),
        (
            [0, 0, 0],
            [1, 0, 0],
            [0, 1, 0],
            0.8,
            "s: lies in the wall's plane z = 0 (it would overlap the wall); expected a surface "
            "in front of it",
        ),
        (
            [0, 0, 0],
            [0, 0, 0],
            [0, 0, 0.5],
            0.8,
            "s: expected edges of 1 mm to 100 m, got 0 and 0.5 m",
        ),
        ([0, 0, 0], [1, 0, 0], [2, 0, 0], 0.8, "s: expected two edges that are not parallel"),
        (
            [0, float("nan"), 0],
            [1, 0, 0],
            [0, 0, 0.5],
            0.8,
            "s: corner_world: expected 3 finite numbers, got [0.0, nan, 0.0]",
        ),
        ([0, 0, 0], [1, 0, 0], [0, 0, 0.5], 1.0, "s: albedo: expected a value in [0, 1), got 1"),
    ],
)
def test_bad_surfaces_are_refused(corner, u, v, albedo, message) -> None:
    with pytest.raises(ValueError) as info:
        Surface(np.array(corner, float), np.array(u, float), np.array(v, float), albedo, "s")
    assert str(info.value) == message


def test_bad_surroundings_are_refused() -> None:
    with pytest.raises(ValueError, match=r"^surroundings: expected 1 to 16 surfaces, got 0$"):
        Surroundings(())
    with pytest.raises(
        ValueError, match=r"^surroundings: wall_albedo: expected a value in \(0, 1\), got 0$"
    ):
        Surroundings((_ceiling(),), wall_albedo=0.0)
    with pytest.raises(ValueError, match=r"^surroundings: patch_m: expected 0.01 to 0.5 m, got 0$"):
        Surroundings((_ceiling(),), patch_m=0.0)


def test_too_fine_a_mesh_is_refused() -> None:
    big = Surface(np.zeros(3), np.array([20.0, 0, 0]), np.array([0, 0, 5.0]), 0.5, "big")
    with pytest.raises(
        ValueError, match=r"^surroundings: 10000 patches of 0.1 m; expected at most 4000"
    ):
        BounceMap(Surroundings((big,), patch_m=0.1), (0.0, 1.0, 0.0, 1.0))


def test_bounces_truncate_the_paths_and_converge_to_every_bounce() -> None:
    """bounces = 1 keeps light -> surface -> wall alone (the wall's albedo plays no
    part); more bounces grow towards the solution with every bounce (the LU solve)."""
    light, view = _light_and_view()
    L, R = light.position_world(view), light.rotation_world(view)
    side = Surface(
        np.array([0.6, -0.4, 0.0]), np.array([0.0, 1.4, 0.0]), np.array([0.0, 0.0, 0.5]), 0.7
    )
    points = np.array([[0.0, 0.0, 0.0], [0.5, -0.3, 0.0]])

    def bounce(wall_albedo: float, bounces: int | None) -> np.ndarray:
        s = Surroundings((_ceiling(), side), wall_albedo, 0.1, bounces)
        bm = BounceMap(s, (-0.5, 0.5, -0.5, 0.5))
        src = bm.source_columns(L, R, light.rid, want_grad=False)
        return bm.bounce(bm.radiance(src), bm.pixel_map(points))[:, 0]

    np.testing.assert_allclose(bounce(0.2, 1), bounce(0.9, 1), rtol=1e-12)
    values = [bounce(0.8, n) for n in (1, 2, 3, 30)]
    assert np.all(np.diff(values, axis=0) > 0.0)
    np.testing.assert_allclose(values[-1], bounce(0.8, None), rtol=1e-9)
