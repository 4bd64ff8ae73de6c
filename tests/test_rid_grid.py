"""The table RIDs' uniform grids (lightcal.core.rid_grid, rid_tabulate) against the exact
table interpolation (`RID.exact_data`, `rid_eval.rid_value_grad` of kinds 3 and 4).

Stated accuracy (f(0) = 1; derivatives in 1 / radian), for the tables of `tests.scenes`
and an IES-like full-sphere table:

- symmetric tables (512 cells in s per hemisphere): |f - f_exact| <= 5e-6,
  |df/dtheta - exact| <= 5e-3 (measured: 1.8e-6 and 2.6e-3; 99 % of directions within
  1e-7);
- 2-D tables (257 x 257 nodes per hemisphere in the equal-area maps): |f - f_exact| <=
  3e-4, |df/dtheta|, |df/dphi| within 0.1 of the exact ones (measured: 1.5e-4 and 0.063,
  both in the last 2.5 degrees of a table whose profile falls as cos(theta)^0.2 there;
  99 % of directions within 4e-6).

The largest differences sit where the exact interpolant is itself not smooth (its knots,
where PCHIP is C1 only; the pole of a 2-D table) or steep; elsewhere they are far smaller.
"""

from __future__ import annotations

import math
import re

import numpy as np
import pytest

from lightcal.core import rid_eval
from lightcal.core.rid import RID, SymmetricTableRID, Table2DRID
from lightcal.core.rid_eval import RIDData, rid_value_grad_direction
from lightcal.core.rid_tabulate import GRID_CELLS_1D, GRID_NODES_2D, tabulate_1d, tabulate_2d
from lightcal.core.scene import Rig
from lightcal.core.solver import run_least_squares
from lightcal.pipeline.diagnose import covariance
from tests import calib_scenes as cs
from tests.scenes import symmetric_table_rid, table_2d_rid, table_2d_values

VALUE_TOL = {"1d": 5e-6, "2d": 3e-4}
DERIV_TOL = {"1d": 5e-3, "2d": 0.1}


def full_sphere_table() -> SymmetricTableRID:
    """An IES-like type C profile at 5 degree steps to 180 degrees, with a back lobe."""
    theta = np.radians(np.arange(0.0, 180.1, 5.0))
    values = np.clip(np.cos(theta), 0.0, None) ** 1.5 + 0.05 * np.exp(-(((theta - 2.6) / 0.3) ** 2))
    return SymmetricTableRID(theta, values)


def table_2d_to_90() -> Table2DRID:
    """A 2-D table on 0..90 degrees, 24 azimuths (EULUMDAT-like), lopsided."""
    theta = np.radians(np.arange(0.0, 90.1, 2.5))
    phi = np.radians(np.arange(0.0, 360.0, 15.0))
    return Table2DRID(theta, phi, table_2d_values(theta, phi) + 0.02)


TABLES = {
    "symmetric": (symmetric_table_rid, "1d"),
    "full_sphere": (full_sphere_table, "1d"),
    "2d": (table_2d_rid, "2d"),
    "2d_to_90": (table_2d_to_90, "2d"),
}


def _both(rid, theta: np.ndarray, phi: np.ndarray):
    return (
        rid_eval.rid_eval_many(theta, phi, rid.data()),
        rid_eval.rid_eval_many(theta, phi, rid.exact_data()),
    )


def _random_directions(rid, n: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """(n,) theta uniform in solid angle up to the last knot; phi over three turns."""
    rng = np.random.default_rng(seed)
    theta_last = float(rid.exact_data().theta_knots[-1])
    theta = np.arccos(rng.uniform(math.cos(theta_last), 1.0, n))
    return theta, rng.uniform(-2 * math.pi, 4 * math.pi, n)


@pytest.mark.parametrize("name", list(TABLES))
def test_grid_matches_the_exact_table_at_random_directions(name: str) -> None:
    make, dim = TABLES[name]
    rid = make()
    theta, phi = _random_directions(rid, 200_000, seed=5)
    (f, ft, fp), (e, et, ep) = _both(rid, theta, phi)
    assert np.abs(f - e).max() <= VALUE_TOL[dim]
    assert np.abs(ft - et).max() <= DERIV_TOL[dim]
    assert np.abs(fp - ep).max() <= DERIV_TOL[dim]
    # Not a tolerance met by accident: the grid differs from the table, but little.
    assert np.abs(f - e).max() > 0.0
    assert np.median(np.abs(f - e)) <= 0.05 * VALUE_TOL[dim]


@pytest.mark.parametrize("name", list(TABLES))
def test_grid_on_the_axis_is_one_and_flat(name: str) -> None:
    rid = TABLES[name][0]()
    phi = np.linspace(-3.0, 9.0, 7)
    (f, ft, fp), _ = _both(rid, np.zeros(7), phi)
    np.testing.assert_array_equal(f, np.ones(7))
    np.testing.assert_array_equal(ft, np.zeros(7))
    np.testing.assert_array_equal(fp, np.zeros(7))
    # Near the axis (1e-4 .. 1e-2 rad): the exact values and slopes, within the tolerance.
    theta = np.geomspace(1e-4, 1e-2, 9)
    (f, ft, _), (e, et, _) = _both(rid, theta, np.full(9, 0.7))
    dim = TABLES[name][1]
    np.testing.assert_allclose(f, e, rtol=0, atol=VALUE_TOL[dim])
    np.testing.assert_allclose(ft, et, rtol=0, atol=DERIV_TOL[dim])


@pytest.mark.parametrize("name", list(TABLES))
def test_grid_at_and_beyond_the_last_angle(name: str) -> None:
    make, dim = TABLES[name]
    rid = make()
    theta_last = float(rid.exact_data().theta_knots[-1])
    phi = np.linspace(0.0, 2 * math.pi, 12, endpoint=False)
    at = np.full(12, theta_last)
    (f, _, _), (e, _, _) = _both(rid, at, phi)
    np.testing.assert_allclose(f, e, rtol=0, atol=VALUE_TOL[dim])
    if dim == "1d":  # the last node is the last knot: the table's value
        np.testing.assert_allclose(f, e, rtol=0, atol=1e-15)
    if theta_last < math.pi:
        beyond = np.minimum(theta_last + np.array([1e-6, 0.01, 0.3]), math.pi)
        (f, ft, fp), (e, _, _) = _both(rid, beyond, np.full(3, 1.3))
        np.testing.assert_array_equal(f, np.zeros(3))
        np.testing.assert_array_equal(e, np.zeros(3))
        np.testing.assert_array_equal(ft, np.zeros(3))
        np.testing.assert_array_equal(fp, np.zeros(3))
    # Just inside the last angle: the exact value (the rim's cells are not smeared).
    inside = np.full(12, theta_last - 1e-3)
    (f, _, _), (e, _, _) = _both(rid, inside, phi)
    np.testing.assert_allclose(f, e, rtol=0, atol=VALUE_TOL[dim])
    assert np.abs(e).max() > 1e-3  # a rim that is not dark


@pytest.mark.parametrize("name", ["2d", "2d_to_90"])
def test_2d_grid_wraps_around_in_phi(name: str) -> None:
    rid = TABLES[name][0]()
    theta = np.radians(np.linspace(1.0, 84.0, 25))
    phi0 = np.full(25, 0.37)
    (f, ft, fp), _ = _both(rid, theta, phi0)
    for turns in (-2, 1, 3):
        (g, gt, gp), _ = _both(rid, theta, phi0 + turns * 2 * math.pi)
        np.testing.assert_allclose(g, f, rtol=0, atol=1e-12)
        np.testing.assert_allclose(gt, ft, rtol=0, atol=1e-9)
        np.testing.assert_allclose(gp, fp, rtol=0, atol=1e-9)
    # Across phi = 0 (= 2 pi) and across the table's last-to-first row: continuous, and
    # the exact values there.
    knots = rid.exact_data().phi_knots
    for seam in (0.0, 0.5 * (knots[-1] + knots[0] + 2 * math.pi)):
        (lo, _, _), (e, _, _) = _both(rid, theta, np.full(25, seam - 1e-9))
        (hi, _, _), _ = _both(rid, theta, np.full(25, seam + 1e-9))
        np.testing.assert_allclose(lo, hi, rtol=0, atol=1e-7)
        np.testing.assert_allclose(lo, e, rtol=0, atol=VALUE_TOL["2d"])


def test_grid_nodes_hold_the_exact_table() -> None:
    rid = symmetric_table_rid()
    d = rid.data()
    s_max = d.params[3]
    s = s_max * np.arange(0, GRID_CELLS_1D + 1, 37) / GRID_CELLS_1D
    theta = 2.0 * np.arcsin(s)
    exact = rid_eval.rid_eval_many(theta, 0 * theta, rid.exact_data())[0]
    np.testing.assert_allclose(rid(theta), exact, rtol=0, atol=1e-14)
    rid2 = table_2d_rid()
    d2 = rid2.data()
    h = 1.0 / d2.params[2]
    nodes = -d2.params[3] + h * np.array([[128, 128], [100, 140], [60, 200], [131, 17]])
    s2 = np.hypot(nodes[:, 0], nodes[:, 1])
    assert np.all(s2 <= d2.params[3])
    th2 = 2.0 * np.arcsin(s2)
    ph2 = np.arctan2(nodes[:, 1], nodes[:, 0])
    exact2 = rid_eval.rid_eval_many(th2, ph2, rid2.exact_data())[0]
    np.testing.assert_allclose(rid2(th2, ph2), exact2, rtol=0, atol=1e-13)
    assert d2.grid.shape == (2 * GRID_NODES_2D, GRID_NODES_2D, 4)


@pytest.mark.parametrize("name", list(TABLES))
def test_grid_direction_gradient_is_the_derivative_of_its_values(name: str) -> None:
    """The tangential gradient of `rid_value_grad_direction` against central differences
    of the grid's own values on the sphere (the solver's Jacobian is consistent)."""
    rid = TABLES[name][0]()
    d = rid.data()
    rng = np.random.default_rng(11)
    theta, phi = _random_directions(rid, 300, seed=12)
    theta = np.minimum(theta, d.theta_knots[-1] - 2e-3)  # central differences inside
    u = np.stack([np.sin(theta) * np.cos(phi), np.sin(theta) * np.sin(phi), np.cos(theta)], 1)
    eps = 1e-7
    for k in range(u.shape[0]):
        t = np.cross(u[k], rng.normal(size=3))
        t /= np.linalg.norm(t)
        plus = u[k] + eps * t
        minus = u[k] - eps * t
        plus /= np.linalg.norm(plus)
        minus /= np.linalg.norm(minus)
        f_plus = rid_value_grad_direction(*plus, d)[0]
        fd = (f_plus - rid_value_grad_direction(*minus, d)[0]) / (2 * eps)
        _, gx, gy, gz = rid_value_grad_direction(*u[k], d)
        g = np.array([gx, gy, gz])
        assert abs(g @ u[k]) <= 1e-12  # tangential
        assert g @ t == pytest.approx(fd, abs=1e-5 * max(1.0, abs(fd)))


@pytest.mark.parametrize("name", ["symmetric", "2d"])
def test_grid_is_nan_at_nan(name: str) -> None:
    rid = TABLES[name][0]()
    f, ft, fp = rid.value_and_derivatives(np.array([math.nan, 0.3]), np.array([0.2, 0.2]))
    assert math.isnan(f[0]) and math.isnan(ft[0])
    assert math.isnan(fp[0]) if name == "2d" else fp[0] == 0.0  # as the exact table
    assert np.isfinite(f[1])
    out = rid_value_grad_direction(math.nan, 0.0, math.nan, rid.data())
    assert all(math.isnan(v) for v in out)


def test_exact_data_is_the_knot_interpolation() -> None:
    rid = symmetric_table_rid()
    exact = rid.exact_data()
    assert rid.data().kind == rid_eval.KIND_GRID_1D and exact.kind == rid_eval.KIND_TABLE_1D
    np.testing.assert_array_equal(exact.values, rid.data().values)
    assert table_2d_rid().exact_data().kind == rid_eval.KIND_TABLE_2D
    # At the knots the exact interpolation returns the table itself.
    np.testing.assert_allclose(
        rid_eval.rid_eval_many(rid.theta_rad, 0 * rid.theta_rad, exact)[0], rid.values, atol=1e-15
    )


def _exact(message: str) -> str:
    return "^" + re.escape(message) + "$"


def test_tabulate_rejects_other_kinds_and_too_few_nodes() -> None:
    one = symmetric_table_rid().exact_data()
    two = table_2d_rid().exact_data()
    with pytest.raises(
        ValueError, match=_exact("table: expected a symmetric table RID (kind 3), got kind 4")
    ):
        tabulate_1d(two)
    with pytest.raises(
        ValueError, match=_exact("table: expected a 2-D table RID (kind 4), got kind 3")
    ):
        tabulate_2d(one)
    with pytest.raises(ValueError, match=_exact("n_cells: expected at least 2 cells, got 1")):
        tabulate_1d(one, 1)
    with pytest.raises(
        ValueError, match=_exact("n_nodes: expected at least 3 nodes per side, got 2")
    ):
        tabulate_2d(two, 2)


def test_finer_grids_converge_to_the_table() -> None:
    """The error falls at least 2.5x per doubling of the 1-D grid (at least O(h^2): cubic
    Hermite of a C1 table): the grid converges to the exact interpolation."""
    exact = symmetric_table_rid().exact_data()
    theta, phi = _random_directions(symmetric_table_rid(), 50_000, seed=2)
    e = rid_eval.rid_eval_many(theta, phi, exact)[0]
    errs = []
    for n in (64, 128, 256):
        g: RIDData = tabulate_1d(exact, n)
        errs.append(np.abs(rid_eval.rid_eval_many(theta, phi, g)[0] - e).max())
    assert errs[1] < errs[0] / 2.5 and errs[2] < errs[1] / 2.5


class _ExactTable(RID):
    """A table RID rendered by its exact knot interpolation (the path before the grids)."""

    def __init__(self, table: RID) -> None:
        self.table = table
        self.symmetric = table.symmetric

    def data(self) -> RIDData:
        return self.table.exact_data()


@pytest.mark.parametrize("kind", ["symmetric", "general"])
def test_solver_estimates_move_far_less_than_their_sigma(kind: str) -> None:
    """The same noisy synthetic data (12 views, 400 pixels each, the 14-bit sensor's
    noise) solved with the table's grid and with its exact interpolation: every
    parameter moves by less than 2 % of its standard deviation."""
    truth = cs.general_light() if kind == "general" else cs.symmetric_light()
    if kind == "symmetric":
        theta = np.radians(np.arange(0.0, 90.1, 2.5))
        truth = truth.replace(rid=SymmetricTableRID(theta, np.cos(theta) ** 4.5 + 0.01))
    images = cs.observe(
        cs.small_camera(),
        cs.views(12),
        Rig.single(truth),
        n_per_image=400,
        rng=np.random.default_rng(4),
        noise=(0.79355, 5.7508),
    )
    start = cs.start_near(truth)
    grid_model = cs.model_of(images, [start])
    exact_model = cs.model_of(images, [start.replace(rid=_ExactTable(truth.rid))])
    on_grid = run_least_squares(grid_model)
    exact = run_least_squares(exact_model)
    assert on_grid.success and exact.success
    sigma = np.sqrt(np.diag(covariance(exact_model, exact.x)))
    shift = np.abs(on_grid.x - exact.x) / sigma
    assert shift.max() < 0.02, dict(zip(exact_model.layout.names, shift.round(4), strict=True))


@pytest.mark.parametrize("make", [table_2d_rid, table_2d_to_90])
def test_2d_grid_row_values_equal_the_per_pixel_interpolation(make) -> None:
    """`grid2d_values_row` (runs of pixels in one cell, power-basis Horner) against
    `grid2d_interp`'s value pixel by pixel: a smooth row of directions as an image row
    gives (long runs in a cell), random coordinates (runs of one), the clamped last node,
    beyond the last angle and NaN."""
    from lightcal.core.rid_grid import grid2d_cell, grid2d_coords, grid2d_interp, grid2d_values_row

    data = make().data()
    grid, inv_h, s_max, s_back = data.grid, data.params[2], data.params[3], data.params[4]
    n = grid.shape[1]
    rng = np.random.default_rng(7)
    # An image row: directions sweeping across the front hemisphere.
    a = np.linspace(-1.2, 1.2, 3000)
    dirs = np.stack([np.sin(a), 0.3 + 0.0 * a, np.cos(a)], axis=1)
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    coords = [grid2d_coords(*d, n, inv_h, s_max, s_back) for d in dirs]
    xs = np.array([c[0] for c in coords])
    ys = np.array([c[1] for c in coords])
    xs = np.concatenate([xs, rng.uniform(0, n - 1, 500), [n - 1.0, -1.0, np.nan, 0.0]])
    ys = np.concatenate([ys, rng.uniform(0, 2 * n - 1, 500), [n - 1.0, 3.0, 3.0, 2 * n - 1.0]])
    expected = np.array([grid2d_interp(x, y, grid, inv_h)[0] for x, y in zip(xs, ys, strict=True)])
    cells = np.array([grid2d_cell(x, y, n) for x, y in zip(xs, ys, strict=True)])
    got = xs.copy()
    grid2d_values_row(got, ys, cells, grid, inv_h)
    assert np.array_equal(np.isnan(got), np.isnan(expected))
    ok = ~np.isnan(expected)
    np.testing.assert_allclose(got[ok], expected[ok], rtol=1e-12, atol=1e-14)
    assert got[-3] == 0.0  # beyond the last angle
    runs = np.count_nonzero(np.diff(np.floor(xs[:3000])) != 0)
    assert runs < 300  # the image row does come in long runs
    # One number per cell: equal for coordinates in one cell (the clamped last node in
    # the last cell), different across cells and hemispheres; x itself beyond / at NaN.
    assert grid2d_cell(2.25, 3.5, n) == grid2d_cell(2.75, 3.0, n) == 2 + n * 3
    assert grid2d_cell(n - 1.0, n - 1.0, n) == grid2d_cell(n - 1.5, n - 1.5, n)
    assert grid2d_cell(2.25, n + 3.5, n) == 2 + n * (n + 3)
    assert len({grid2d_cell(x, y, n) for x in (0.5, 1.5) for y in (0.5, 1.5, n + 0.5)}) == 6
    assert grid2d_cell(-1.0, 3.0, n) == -1.0 and np.isnan(grid2d_cell(np.nan, 3.0, n))


def test_table_grids_are_filled_on_first_use() -> None:
    """A table RID keeps its knots from construction and fills its grid at the first
    `data()` (a compiled kernel: reading a project starts no numba), once."""
    theta = np.radians(np.arange(0.0, 90.0, 5.0))
    for rid, grid_kind, knot_kind in (
        (
            SymmetricTableRID(theta, np.cos(theta) ** 3),
            rid_eval.KIND_GRID_1D,
            rid_eval.KIND_TABLE_1D,
        ),
        (
            Table2DRID(theta, np.radians(np.arange(0.0, 360.0, 45.0)), np.ones((8, theta.size))),
            rid_eval.KIND_GRID_2D,
            rid_eval.KIND_TABLE_2D,
        ),
    ):
        assert rid._data is None
        assert rid.exact_data().kind == knot_kind and rid._data is None
        first = rid.data()
        assert first.kind == grid_kind and rid.data() is first
