"""Tests of lightcal.core.solid_angle: closed forms, signs, precision, additivity, 2 pi."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import quad

from lightcal.core.solid_angle import (
    quad_area_in_plane,
    quad_solid_angle,
    subdivide_quads,
    triangle_solid_angle,
)


def _square_closed_form(a: float, d: float) -> float:
    """Solid angle of a square of side 2a seen from distance d on its axis."""
    return 4.0 * math.asin(a * a / (a * a + d * d))


def _rectangle_from_corner(a: float, b: float, h: float) -> float:
    """Solid angle of an a x b rectangle seen from height h above one of its corners."""
    return math.atan(a * b / (h * math.sqrt(a * a + b * b + h * h)))


def _square(a: float, d: float) -> tuple[np.ndarray, np.ndarray]:
    """Viewpoint (0, 0, d) and the (1, 4, 3) square of side 2a centred at the origin."""
    corners = np.array([[[-a, -a, 0.0], [a, -a, 0.0], [a, a, 0.0], [-a, a, 0.0]]])
    return np.array([0.0, 0.0, d]), corners


def _triangle_longdouble(
    viewpoint: np.ndarray, p1: np.ndarray, p2: np.ndarray, p3: np.ndarray
) -> np.ndarray:
    """Van Oosterom-Strackee in extended precision (np.longdouble, 64-bit mantissa)."""
    ld = np.longdouble
    v = viewpoint.astype(ld)
    a, b, c = p1.astype(ld) - v, p2.astype(ld) - v, p3.astype(ld) - v
    e1, e2 = p2.astype(ld) - p1.astype(ld), p3.astype(ld) - p1.astype(ld)
    numerator = np.sum(a * np.cross(e1, e2), axis=-1)
    la, lb, lc = (np.sqrt(np.sum(x * x, axis=-1)) for x in (a, b, c))
    denominator = (
        la * lb * lc
        + np.sum(a * b, axis=-1) * lc
        + np.sum(a * c, axis=-1) * lb
        + np.sum(b * c, axis=-1) * la
    )
    return ld(2) * np.arctan2(numerator, denominator)


# ---------------------------------------------------------------- closed forms


@pytest.mark.parametrize(("a", "d"), [(0.5, 1.0), (1.0, 1.0), (0.01, 3.0), (2.5, 0.2), (1e-3, 1e2)])
def test_square_on_axis_matches_closed_form(a: float, d: float) -> None:
    viewpoint, corners = _square(a, d)
    omega = quad_solid_angle(viewpoint, corners)
    assert omega.shape == (1,)
    assert omega[0] == pytest.approx(_square_closed_form(a, d), rel=1e-13)


def test_unit_square_at_unit_distance_is_two_thirds_pi() -> None:
    # 4 asin(1/2) = 2 pi / 3: a hand-checkable value.
    viewpoint, corners = _square(1.0, 1.0)
    assert quad_solid_angle(viewpoint, corners)[0] == pytest.approx(2 * math.pi / 3, rel=1e-14)


@pytest.mark.parametrize(("a", "d"), [(1.0, 1.0), (0.3, 2.0), (4.0, 0.5)])
def test_right_triangles_with_right_angle_on_the_axis_are_a_quarter_of_the_square(
    a: float, d: float
) -> None:
    # The diagonals cut the square into 4 right isosceles triangles whose right angle
    # sits on the axis; by symmetry each one subtends a quarter of the square.
    viewpoint = np.array([0.0, 0.0, d])
    o = np.zeros((4, 3))
    ring = np.array([[a, -a, 0.0], [a, a, 0.0], [-a, a, 0.0], [-a, -a, 0.0]])
    omega = triangle_solid_angle(viewpoint, o, ring, np.roll(ring, -1, axis=0))
    np.testing.assert_allclose(np.abs(omega), _square_closed_form(a, d) / 4, rtol=1e-13)
    # Half of such a triangle, (0, 0), (a, 0), (a, a): an eighth of the square.
    half = triangle_solid_angle(
        viewpoint, np.zeros((1, 3)), np.array([[a, 0.0, 0.0]]), np.array([[a, a, 0.0]])
    )
    assert abs(half[0]) == pytest.approx(_square_closed_form(a, d) / 8, rel=1e-13)


@pytest.mark.parametrize(("a", "b", "d"), [(1.0, 2.0, 0.7), (0.2, 0.05, 1.5), (3.0, 1.0, 0.1)])
def test_right_triangle_seen_from_above_its_right_angle_matches_quadrature(
    a: float, b: float, d: float
) -> None:
    # Legs a (along x) and b (along y), viewpoint at height d above the right angle.
    # In polar coordinates about the foot point the hypotenuse is rho(phi) =
    # p / cos(phi - phi_n); the solid angle is int (1 - d / sqrt(d^2 + rho^2)) dphi.
    p = a * b / math.hypot(a, b)
    phi_n = math.atan2(a, b)

    def integrand(phi: float) -> float:
        rho = p / math.cos(phi - phi_n)
        return 1.0 - d / math.sqrt(d * d + rho * rho)

    expected, _ = quad(integrand, 0.0, math.pi / 2, epsabs=0.0, epsrel=1e-13, limit=200)
    omega = triangle_solid_angle(
        np.array([0.0, 0.0, d]),
        np.zeros((1, 3)),
        np.array([[a, 0.0, 0.0]]),
        np.array([[0.0, b, 0.0]]),
    )
    assert abs(omega[0]) == pytest.approx(expected, rel=1e-12)


@pytest.mark.parametrize(("a", "b", "h"), [(1.0, 2.0, 0.5), (0.1, 0.3, 2.0), (5.0, 0.2, 1.0)])
def test_rectangle_seen_from_above_a_corner_matches_closed_form(
    a: float, b: float, h: float
) -> None:
    corners = np.array([[[0.0, 0.0, 0.0], [a, 0.0, 0.0], [a, b, 0.0], [0.0, b, 0.0]]])
    omega = quad_solid_angle(np.array([0.0, 0.0, h]), corners)
    assert omega[0] == pytest.approx(_rectangle_from_corner(a, b, h), rel=1e-13)


def test_huge_square_very_close_subtends_a_hemisphere() -> None:
    viewpoint, corners = _square(1e6, 1e-6)
    omega = quad_solid_angle(viewpoint, corners)[0]
    assert abs(omega - 2 * math.pi) < 1e-9


# ---------------------------------------------------------------- signs and shapes


def test_sign_flips_with_vertex_order_and_survives_cyclic_permutation() -> None:
    rng = np.random.default_rng(1)
    viewpoint = np.array([0.2, -0.1, 1.3])
    p1, p2, p3 = (np.column_stack([rng.uniform(-1, 1, (50, 2)), np.zeros(50)]) for _ in range(3))
    omega = triangle_solid_angle(viewpoint, p1, p2, p3)
    assert np.all(np.abs(omega) > 0.0)
    np.testing.assert_allclose(triangle_solid_angle(viewpoint, p1, p3, p2), -omega, rtol=1e-14)
    np.testing.assert_allclose(triangle_solid_angle(viewpoint, p2, p3, p1), omega, rtol=1e-12)
    np.testing.assert_allclose(triangle_solid_angle(viewpoint, p3, p1, p2), omega, rtol=1e-12)
    # Seen from the other side of the plane (mirror image of the viewpoint) the sign flips.
    mirror = viewpoint * np.array([1.0, 1.0, -1.0])
    np.testing.assert_allclose(triangle_solid_angle(mirror, p1, p2, p3), -omega, rtol=1e-12)


def test_sign_is_positive_when_the_normal_points_away_from_the_viewpoint() -> None:
    # (0,0,-1), (1,0,-1), (0,1,-1) seen from the origin: e1 x e2 = +z points towards the
    # viewpoint, a . (e1 x e2) = -1 < 0: the signed solid angle is negative.
    o = np.zeros(3)
    p1, p2, p3 = (
        np.array([[0.0, 0.0, -1.0]]),
        np.array([[1.0, 0.0, -1.0]]),
        np.array([[0, 1, -1.0]]),
    )
    assert triangle_solid_angle(o, p1, p2, p3)[0] < 0.0
    assert triangle_solid_angle(o, p1, p3, p2)[0] > 0.0


def test_sign_convention_documented_in_the_module_docstring() -> None:
    # The viewer at the origin looks down (-z) at z = -1 with +x to its right and +y up:
    # (0,0) -> (1,0) -> (0,1) runs counter-clockwise for it: negative, as documented.
    o = np.zeros(3)
    p1, p2, p3 = (
        np.array([[0.0, 0.0, -1.0]]),
        np.array([[1.0, 0.0, -1.0]]),
        np.array([[0, 1, -1.0]]),
    )
    assert triangle_solid_angle(o, p1, p2, p3)[0] < 0.0
    assert triangle_solid_angle(o, p1, p3, p2)[0] > 0.0


def test_quad_solid_angle_is_orientation_free_and_accepts_one_viewpoint_per_quad() -> None:
    rng = np.random.default_rng(2)
    centers = np.column_stack([rng.uniform(-2, 2, (20, 2)), np.zeros(20)])
    offsets = np.array(
        [[-0.1, -0.05, 0.0], [0.12, -0.04, 0.0], [0.1, 0.08, 0.0], [-0.07, 0.1, 0.0]]
    )
    corners = centers[:, None, :] + offsets[None]
    viewpoints = np.column_stack([rng.uniform(-1, 1, (20, 2)), rng.uniform(0.5, 2.0, 20)])
    omega = quad_solid_angle(viewpoints, corners)
    reversed_omega = quad_solid_angle(viewpoints, corners[:, ::-1])
    one_by_one = np.array(
        [quad_solid_angle(v, c[None])[0] for v, c in zip(viewpoints, corners, strict=True)]
    )
    assert omega.shape == (20,)
    assert np.all(omega > 0.0)
    np.testing.assert_allclose(reversed_omega, omega, rtol=1e-14)
    np.testing.assert_allclose(one_by_one, omega, rtol=0.0, atol=0.0)


# ---------------------------------------------------------------- tiny footprints


def _tiny_triangles(omega_target: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """A viewpoint and 40 wall triangles of about `omega_target` sr, 2.3 to 3.1 m away."""
    rng = np.random.default_rng(3)
    viewpoint = np.array([0.3127, -0.2719, 1.9313])
    center = np.array([1.3711, 2.1103, 0.0]) + np.column_stack(
        [rng.uniform(-0.3, 0.3, (40, 2)), np.zeros(40)]
    )
    r = np.linalg.norm(center - viewpoint, axis=1)
    cos_i = viewpoint[2] / r
    size = np.sqrt(2.0 * omega_target * r * r / cos_i)[:, None]
    shape = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]])[None] + rng.uniform(
        -0.2, 0.2, (40, 3, 2)
    )
    p1, p2, p3 = (center + size * np.column_stack([shape[:, k], np.zeros(40)]) for k in range(3))
    return viewpoint, p1, p2, p3


@pytest.mark.parametrize("omega_target", [1e-4, 1e-6, 1e-8, 1e-10, 1e-12])
def test_tiny_triangles_keep_relative_precision(omega_target: float) -> None:
    viewpoint, p1, p2, p3 = _tiny_triangles(omega_target)
    omega = triangle_solid_angle(viewpoint, p1, p2, p3)
    exact = _triangle_longdouble(viewpoint, p1, p2, p3)
    assert np.all(np.abs(omega) > 0.05 * omega_target)
    assert np.all(np.abs(omega) < 20 * omega_target)
    rel = np.abs((omega.astype(np.longdouble) - exact) / exact).astype(np.float64)
    assert rel.max() < 1e-9


@pytest.mark.parametrize("omega_target", [1e-10, 1e-12])
def test_tiny_triangles_match_the_point_formula(omega_target: float) -> None:
    # Omega = A cos(theta_i) / r^2 (r to the centroid) up to O((size / r)^2) ~ omega.
    viewpoint, p1, p2, p3 = _tiny_triangles(omega_target)
    omega = np.abs(triangle_solid_angle(viewpoint, p1, p2, p3))
    e1, e2 = p2 - p1, p3 - p1
    area = 0.5 * np.abs(e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0])
    r = np.linalg.norm((p1 + p2 + p3) / 3 - viewpoint, axis=1)
    point = area * (viewpoint[2] / r) / r**2
    np.testing.assert_allclose(omega, point, rtol=1e-9)


@pytest.mark.parametrize("omega_target", [1e-4, 1e-8, 1e-12])
def test_tiny_quads_keep_relative_precision(omega_target: float) -> None:
    viewpoint, p1, _, _ = _tiny_triangles(omega_target)
    rng = np.random.default_rng(5)
    shape = np.array([[0.0, 0.0], [1.0, 0.1], [0.9, 1.1], [-0.1, 0.8]])
    xy = shape[None] + rng.uniform(-0.1, 0.1, (p1.shape[0], 4, 2))
    size = math.sqrt(omega_target) * 2.7 / math.sqrt(0.7)
    corners = p1[:, None, :] + size * np.concatenate([xy, np.zeros((p1.shape[0], 4, 1))], axis=2)
    omega = quad_solid_angle(viewpoint, corners)
    exact = np.abs(
        _triangle_longdouble(viewpoint, corners[:, 0], corners[:, 1], corners[:, 2])
        + _triangle_longdouble(viewpoint, corners[:, 0], corners[:, 2], corners[:, 3])
    )
    assert np.all((exact > 0.1 * omega_target) & (exact < 10 * omega_target))
    rel = np.abs((omega.astype(np.longdouble) - exact) / exact).astype(np.float64)
    assert rel.max() < 1e-9


# ---------------------------------------------------------------- additivity


def _perspective_quads(rng: np.random.Generator, n: int) -> np.ndarray:
    """(n, 4, 3) convex, non-rectangular quads on z = 0 (cyclic order)."""
    centers = np.column_stack([rng.uniform(-1.5, 1.5, (n, 2)), np.zeros(n)])
    base = np.array([[-1.0, -1.0], [1.0, -1.0], [1.0, 1.0], [-1.0, 1.0]])
    jitter = rng.uniform(-0.3, 0.3, (n, 4, 2))
    size = rng.uniform(1e-3, 0.4, n)[:, None, None]
    xy = size * (base[None] + jitter)
    return centers[:, None, :] + np.concatenate([xy, np.zeros((n, 4, 1))], axis=2)


@pytest.mark.parametrize("n", [1, 2, 3, 7])
def test_quad_equals_the_sum_of_its_subdivisions(n: int) -> None:
    rng = np.random.default_rng(4)
    quads = _perspective_quads(rng, 30)
    viewpoint = np.array([0.25, -0.4, 0.9])
    pieces = subdivide_quads(quads, n)
    assert pieces.shape == (30, n * n, 4, 3)
    whole = quad_solid_angle(viewpoint, quads)
    parts = quad_solid_angle(viewpoint, pieces.reshape(-1, 4, 3)).reshape(30, n * n).sum(axis=1)
    np.testing.assert_allclose(parts, whole, rtol=1e-12)
    # The pieces tile the parent: their areas add up, and the corners are kept.
    areas = quad_area_in_plane(pieces.reshape(-1, 4, 3)).reshape(30, n * n).sum(axis=1)
    np.testing.assert_allclose(areas, quad_area_in_plane(quads), rtol=1e-12)
    np.testing.assert_array_equal(pieces[:, 0, 0], quads[:, 0])
    np.testing.assert_array_equal(pieces[:, n - 1, 1], quads[:, 1])
    np.testing.assert_array_equal(pieces[:, n * n - 1, 2], quads[:, 2])
    np.testing.assert_array_equal(pieces[:, n * (n - 1), 3], quads[:, 3])


def test_subdivide_quads_by_hand() -> None:
    quad_corners = np.array([[[0.0, 0.0, 0.0], [2.0, 0.0, 0.0], [2.0, 4.0, 0.0], [0.0, 4.0, 0.0]]])
    pieces = subdivide_quads(quad_corners, 2)
    expected_first_row = np.array(
        [
            [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 2.0, 0.0], [0.0, 2.0, 0.0]],
            [[1.0, 0.0, 0.0], [2.0, 0.0, 0.0], [2.0, 2.0, 0.0], [1.0, 2.0, 0.0]],
        ]
    )
    np.testing.assert_array_equal(pieces[0, :2], expected_first_row)
    np.testing.assert_array_equal(pieces[0, 3], [[1, 2, 0], [2, 2, 0], [2, 4, 0], [1, 4, 0]])


def test_quad_area_in_plane_by_hand() -> None:
    corners = np.array(
        [
            [[0.0, 0.0, 0.0], [2.0, 0.0, 0.0], [2.0, 3.0, 0.0], [0.0, 3.0, 0.0]],
            [[0.0, 0.0, 0.0], [4.0, 0.0, 0.0], [3.0, 2.0, 0.0], [1.0, 2.0, 0.0]],  # trapezoid
        ]
    )
    np.testing.assert_allclose(quad_area_in_plane(corners), [6.0, 6.0], rtol=1e-15)
    np.testing.assert_allclose(quad_area_in_plane(corners[:, ::-1, :2]), [6.0, 6.0], rtol=1e-15)


# ---------------------------------------------------------------- invariant: 2 pi


def _log_grid_quads(extent_m: float, n_per_side: int) -> np.ndarray:
    """(M, 4, 3) quads tiling [-extent, extent]^2 on z = 0 with log-spaced edges."""
    positive = np.logspace(-4, math.log10(extent_m), n_per_side)
    edges = np.concatenate([-positive[::-1], [0.0], positive])
    x0, y0 = np.meshgrid(edges[:-1], edges[:-1], indexing="xy")
    x1, y1 = np.meshgrid(edges[1:], edges[1:], indexing="xy")
    corners = np.stack(
        [
            np.stack([x0, y0], axis=-1),
            np.stack([x1, y0], axis=-1),
            np.stack([x1, y1], axis=-1),
            np.stack([x0, y1], axis=-1),
        ],
        axis=2,
    ).reshape(-1, 4, 2)
    return np.concatenate([corners, np.zeros((corners.shape[0], 4, 1))], axis=2)


def test_tiled_square_sums_to_its_closed_form() -> None:
    # Off-centre viewpoint: the square is the sum of four rectangles seen from a corner.
    extent = 1e6
    quads = _log_grid_quads(extent, 40)
    viewpoint = np.array([0.31, -0.17, 1.0])
    total = quad_solid_angle(viewpoint, quads).sum()
    x, y, h = viewpoint
    expected = sum(
        _rectangle_from_corner(a, b, h)
        for a in (extent - x, extent + x)
        for b in (extent - y, extent + y)
    )
    assert total == pytest.approx(expected, rel=1e-12)


@pytest.mark.parametrize("height_m", [1e-4, 3e-5])
def test_isotropic_light_over_a_large_plane_sees_two_pi(height_m: float) -> None:
    # A light height_m above a 2e6 m wide tiled plane: what lies beyond the tiles
    # subtends ~ 4 sqrt(2) h / extent < 1e-9 of 2 pi.
    quads = _log_grid_quads(1e6, 40)
    viewpoint = np.array([0.00031, -0.00017, height_m])
    total = quad_solid_angle(viewpoint, quads).sum()
    assert total == pytest.approx(2 * math.pi, rel=1e-9)
