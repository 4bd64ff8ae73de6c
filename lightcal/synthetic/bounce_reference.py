"""The light a ceiling and a side wall send back to the wall, by brute force (`lightcal
synth --corner`): synthetic data's inter-reflection, computed independently of the
model's radiosity (`lightcal.core.bounce`: no polygon formula, no wall nodes).

The corner: a ceiling (the plane y = y0 - D, from x = x0 - REACH_M to the side wall) and
a side wall (x = x0 + D, from the ceiling to y = y0 + REACH_M), both `depth_m` deep (z from
0), meeting the wall at right angles D from where the views look (x0, y0: their optical
axes' mean point on the wall), Lambertian of `albedo` on both sides, the wall Lambertian of
the same albedo.

**How.** Each surface is cut into cells (two copies, one a side) of uniform radiance:
CELL_M squares, the rows within ROW_FINE_REACH_M of the wall ROW_FINE_M high. The wall is
cut into cells of uniform radiance: WALL_CELL_M squares over the region the beam may light
near the views, twice that beyond it up to WALL_MARGIN_M around the surfaces, WALL_LEVELS
squares near a surface's foot. The lights' irradiance of a cell is its mean over
SOURCE_SPLIT x SOURCE_SPLIT points (shadows tested at each). Every transfer (wall cell <->
surface cell, surface cell <-> surface cell, surface cell -> a pixel's wall point) is the
double integral of cos cos / r^2 (times exp(-c r) in water) by Gauss-Legendre quadrature
whose order grows as the two come close (`lightcal.synthetic.bounce_quadrature`), the
surface -> wall transfer from the wall -> surface one by reciprocity. The copies' radiance
is the Neumann series of light -> surfaces and wall -> surfaces -> ... (every bounce until
a term is below CONVERGED of the sum; `surroundings.bounces` cuts it as the model's
option does). The bounce is gathered at every STRIDE-th pixel's wall point and
interpolated bilinearly (sample k at pixel k STRIDE, the last row and column sampled
too), exactly at the pixels within EXACT_REACH_M of a surface's foot or beside an invalid
sample. In water (`attenuation_per_m` c) every segment light -> cell, cell -> cell and
cell -> wall point carries exp(-c r); the camera's segment is the caller's
(`lightcal.synthetic.imaging` multiplies the bounce by exp(-c d_camera) as the beam).

**Measured.** Against Mitsuba 3's bounce (`path`, `max_depth` 16, less its `direct`
render; 2048 samples a pixel, 12 views of 480 x 320, the wall a 12 m square), over the
blocks of 16 x 16 pixels that see lit wall and whose bounce is above 1 % of the signal:
the ratio's median 1.001 and 95th percentile of |ratio - 1| 1.2 % (Mitsuba's own noise
alone gives 0.8 %), each view's sum 0.999-1.003; by distance from a surface's foot 1.001
(2-5 cm), 0.998 (5-10 cm), 0.998 (10-20 cm), 1.002 (0.2-1 m), 1.001 beyond
(`tests/test_bounce_reference.py` checks two views of 240 x 160 against 1024 samples).
In water (c = 0.2 /m) against Mitsuba's `volpath` (2 views, 2048 samples, 32 x 32
blocks, its direct light replaced by the exact attenuated one): the views' sums 0.996 and
0.997 (its noise about 0.3 %). The single bounce of one shelf matches a 2 mm midpoint
integral within 0.5 %, in air and in water. The first version (point kernels between
cell centres, 4 iterations, the wall 0.5 m around the views, no visibility test between a
pixel's point and a cell, and the bounce interpolated 1.5 pixels off) was 1.2 % above per
block (median) and 22 % off at the 95th percentile (the wall behind the side wall saw the
ceiling through it); each view's sum 0.7-3.5 % above.

**Not exact.** The radiance is uniform over each cell (5 cm, 1.25 cm rows next to the
wall; the wall's 2.5-20 cm); the wall ends WALL_MARGIN_M beyond the surfaces; whether a
surface hides one cell from another is tested between their centres; a pixel's bounce is
the irradiance at its centre's wall point (not the mean over its footprint), and pixels
beyond EXACT_REACH_M of a foot interpolate it; the water absorbs only (no light scattered
into the bounce). Speed: 1.9 s to build (about 4700 surface copies, 11,500 wall cells,
0.22 GB of transfers), then about 2 s a view of 480 x 320 on 2 cores.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from lightcal.core.scene import Rig, View
from lightcal.core.surroundings import Surface, Surroundings, segments_blocked
from lightcal.synthetic.bounce_quadrature import (
    MAX_ORDER,
    ORDER_PER_RATIO,
    gather,
    gauss_tables,
    planes_of,
    transfer,
)

__all__ = ["REACH_M", "CornerBounce", "corner_surroundings"]

#: How far the ceiling and the side wall reach beyond where the views look, m.
REACH_M = 3.0

#: Cell sides, m: the surfaces'; the wall's, WALL_LEVELS (side, reach) within reach of
#: where a surface meets it and WALL_CELL_M elsewhere.
CELL_M = 0.05
WALL_CELL_M = 0.1
WALL_LEVELS = ((0.025, 0.3),)

#: The wall's cells cover the region the caller gives and WALL_MARGIN_M around every
#: surface, m.
WALL_MARGIN_M = 1.5

#: A surface standing on the wall has rows ROW_FINE_M high within ROW_FINE_REACH_M of it, m.
ROW_FINE_M = 0.0125
ROW_FINE_REACH_M = 0.1

#: The lights' irradiance of a cell is the mean over SOURCE_SPLIT x SOURCE_SPLIT points.
SOURCE_SPLIT = 4

#: The Neumann series of every bounce stops when a term falls below CONVERGED of the sum
#: (or after MAX_TERMS terms).
CONVERGED = 1e-6
MAX_TERMS = 500

#: Pixels farther than this from a surface's foot take the bounce of every STRIDE-th
#: pixel, interpolated bilinearly; the others their own, m.
EXACT_REACH_M = 0.05
STRIDE = 4


def corner_surroundings(
    target_xy: tuple[float, float], distance_m: float, depth_m: float, albedo: float
) -> Surroundings:
    """The ceiling and the side wall of `--corner` (module docstring) as surroundings."""
    x0, y0 = target_xy
    y_c, x_s = y0 - distance_m, x0 + distance_m
    ceiling = Surface(
        np.array([x0 - REACH_M, y_c, 0.0]),
        np.array([x_s - (x0 - REACH_M), 0.0, 0.0]),
        np.array([0.0, 0.0, depth_m]),
        albedo,
        "ceiling",
    )
    side = Surface(
        np.array([x_s, y_c, 0.0]),
        np.array([0.0, y0 + REACH_M - y_c, 0.0]),
        np.array([0.0, 0.0, depth_m]),
        albedo,
        "side wall",
    )
    return Surroundings((ceiling, side), wall_albedo=albedo)


def _cells(surface: Surface, side: float) -> tuple[NDArray, NDArray, NDArray, NDArray]:
    """A surface's cells: (n, 3) centres, (n, 3) the unit normal of one side, (n,) areas
    and (n, 2, 3) edges. CELL_M squares, the rows within ROW_FINE_REACH_M of the wall
    ROW_FINE_M high when the surface stands on the wall along its first edge."""
    u, v = surface.edge_u_world, surface.edge_v_world
    nu = max(1, math.ceil(np.linalg.norm(u) / CELL_M))
    t_edges = _row_edges(float(np.linalg.norm(v)), _stands_on_wall(surface))
    s_mid = (np.arange(nu) + 0.5) / nu
    t_mid = (t_edges[:-1] + t_edges[1:]) / 2.0
    t_len = np.diff(t_edges)
    s, t = np.meshgrid(s_mid, t_mid, indexing="ij")
    _, dt = np.meshgrid(s_mid, t_len, indexing="ij")
    centres = surface.corner_world + s.ravel()[:, None] * u + t.ravel()[:, None] * v
    normal = np.broadcast_to(side * surface.normal_world, centres.shape)
    edges = np.stack(
        [np.broadcast_to(u / nu, centres.shape), dt.ravel()[:, None] * v[None, :]], axis=1
    )
    area = surface.area_m2 / nu * dt.ravel()
    return centres, normal, area, edges


def _stands_on_wall(surface: Surface) -> bool:
    """Whether the surface's first edge lies on the wall (z = 0)."""
    c, u = surface.corner_world, surface.edge_u_world
    return abs(c[2]) <= 1e-9 and abs(c[2] + u[2]) <= 1e-9


def _row_edges(length_m: float, graded: bool) -> NDArray:
    """(m + 1,) the rows' edges as fractions of an edge of `length_m`: CELL_M rows, the
    first ROW_FINE_REACH_M in ROW_FINE_M rows when `graded`."""
    if not graded or length_m <= ROW_FINE_REACH_M:
        n = max(1, math.ceil(length_m / (ROW_FINE_M if graded else CELL_M)))
        return np.linspace(0.0, 1.0, n + 1)
    n_fine = math.ceil(ROW_FINE_REACH_M / ROW_FINE_M)
    n_rest = max(1, math.ceil((length_m - ROW_FINE_REACH_M) / CELL_M))
    fine = np.linspace(0.0, ROW_FINE_REACH_M, n_fine + 1)
    rest = np.linspace(ROW_FINE_REACH_M, length_m, n_rest + 1)[1:]
    return np.concatenate([fine, rest]) / length_m


class CornerBounce:
    """The brute-force bounce of surroundings (world-fixed cells and transfers).

    Args:
        surroundings: the surfaces (`corner_surroundings`); its `bounces` cuts the paths
            (None: every bounce, a room).
        region_xy: (x0, x1, y0, y1) the wall the beam may light near them, m.
        attenuation_per_m: c of the medium between the surfaces and the wall, 1/m (0:
            air): every segment (light -> cell, cell -> cell, cell -> wall point) is
            weighted by exp(-c r).
    """

    def __init__(
        self,
        surroundings: Surroundings,
        region_xy: tuple[float, float, float, float],
        *,
        attenuation_per_m: float = 0.0,
    ) -> None:
        self.surroundings = surroundings
        self.region_xy = region_xy
        self.attenuation_per_m = float(attenuation_per_m)
        cells = [
            (*_cells(s, side), k)
            for k, s in enumerate(surroundings.surfaces)
            for side in (1.0, -1.0)
        ]
        self.q = np.concatenate([c[0] for c in cells])
        self.n = np.ascontiguousarray(np.concatenate([c[1] for c in cells]))
        self.area = np.concatenate([c[2] for c in cells])
        self.owner = np.concatenate([np.full(len(c[0]), c[4]) for c in cells])
        self.edges = np.ascontiguousarray(np.concatenate([c[3] for c in cells]))
        self.w, self.w_area = _wall_cells(surroundings, region_xy)
        side = np.sqrt(self.w_area)
        self.w_edges = np.zeros((len(self.w), 2, 3))
        self.w_edges[:, 0, 0] = side
        self.w_edges[:, 1, 1] = side
        self.w_normals = np.ascontiguousarray(np.broadcast_to([0.0, 0.0, 1.0], self.w.shape))
        s_ = surroundings.surfaces
        self.planes = planes_of(
            np.array([x.corner_world for x in s_]),
            np.array([x.edge_u_world for x in s_]),
            np.array([x.edge_v_world for x in s_]),
        )
        self.nodes, self.weights = gauss_tables(MAX_ORDER)
        wall_owner = np.full(len(self.w), -1)
        # g_ws[i, j]: the mean irradiance of wall cell i per unit radiance of copy j
        # float32 (single precision, 1e-7, far below the quadrature's error): half the
        # memory and twice the speed of the Neumann series' products
        self.g_ws = self._transfer(self.w, self.w_normals, self.w_edges, wall_owner).astype(
            np.float32
        )
        self.g_ss = self._transfer(self.q, self.n, self.edges, self.owner).astype(np.float32)

    def _transfer(self, a: NDArray, na: NDArray, ea: NDArray, owner: NDArray) -> NDArray:
        """(len(a), K) the transfer to cells a (centres, normals (n, 3), edges (n, 2, 3),
        owners (n,)) from the copies (`bounce_quadrature.transfer`)."""
        return transfer(
            np.ascontiguousarray(a),
            np.ascontiguousarray(na),
            np.ascontiguousarray(ea),
            owner,
            self.q,
            self.n,
            self.edges,
            self.area,
            self.owner,
            self.planes,
            self.attenuation_per_m,
            ORDER_PER_RATIO,
            self.nodes,
            self.weights,
        )

    def _sources(
        self,
        centres: NDArray,
        normals: NDArray,
        edges: NDArray,
        owner: NDArray,
        rig: Rig,
        view: View,
    ) -> NDArray:
        """(n,) the lights' mean irradiance (scale and exposure included, attenuated) over
        cells (centres, normals (n, 3), edges (n, 2, 3), owners (n,)): SOURCE_SPLIT x
        SOURCE_SPLIT points each."""
        f = (np.arange(SOURCE_SPLIT) + 0.5) / SOURCE_SPLIT - 0.5
        a, b = (g.ravel() for g in np.meshgrid(f, f, indexing="ij"))
        points = (
            centres[:, None, :]
            + a[None, :, None] * edges[:, None, 0, :]
            + b[None, :, None] * edges[:, None, 1, :]
        ).reshape(-1, 3)
        per_point = np.repeat(np.arange(len(centres)), a.size)
        values = self._point_sources(points, normals[per_point], owner[per_point], rig, view)
        return values.reshape(len(centres), a.size).mean(axis=1)

    def _point_sources(
        self, points: NDArray, normals: NDArray, owner: NDArray, rig: Rig, view: View
    ) -> NDArray:
        """(n,) the lights' irradiance (scale and exposure included, attenuated) at
        points (n, 3) of normals (n, 3)."""
        out = np.zeros(len(points))
        for light in rig.lights:
            L = light.position_world(view)
            R = light.rotation_world(view)
            d = L - points
            r = np.linalg.norm(d, axis=1)
            cos = np.einsum("ni,ni->n", d, normals) / r
            lit = (cos > 0.0) & ~segments_blocked(
                self.surroundings.surfaces, L[None, :], np.array([-1]), points, owner
            )[0]
            u = (-d / r[:, None]) @ R
            f = light.rid(np.arccos(np.clip(u[:, 2], -1, 1)), np.arctan2(u[:, 1], u[:, 0]))
            e = light.scale * view.exposure * f * cos / r**2
            if self.attenuation_per_m > 0.0:
                e = e * np.exp(-self.attenuation_per_m * r)
            out += np.where(lit, e, 0.0)
        return out

    def radiance(self, rig: Rig, view: View) -> NDArray:
        """(K,) the copies' radiance: the Neumann series of paths of up to
        `surroundings.bounces` reflections (all: until a term is below CONVERGED)."""
        rho = np.array([self.surroundings.surfaces[k].albedo for k in self.owner]) / math.pi
        rho_w = self.surroundings.wall_albedo / math.pi
        wall_owner = np.full(len(self.w), -1)
        e_s = self._sources(self.q, self.n, self.edges, self.owner, rig, view)
        e_w = self._sources(self.w, self.w_normals, self.w_edges, wall_owner, rig, view)
        s, w = rho * e_s, rho_w * e_w
        total = s.copy()
        limit = self.surroundings.bounces or MAX_TERMS
        for _ in range(1, limit):
            # g_sw by reciprocity: A_j g_sw[j, i] = A_i g_ws[i, j] (the same quadrature)
            from_wall = (w * self.w_area).astype(np.float32) @ self.g_ws / self.area
            s32 = s.astype(np.float32)
            s, w = rho * (self.g_ss @ s32 + from_wall), rho_w * (self.g_ws @ s32)
            total += s
            if self.surroundings.bounces is None and s.max() <= CONVERGED * total.max():
                break
        return total

    def bounce(self, radiance: NDArray, points: NDArray) -> NDArray:
        """(N,) the irradiance at wall points (N, 3) from the copies' radiance (K,)."""
        return gather(
            np.ascontiguousarray(points, dtype=np.float64),
            self.q,
            self.n,
            self.edges,
            self.area,
            self.owner,
            np.ascontiguousarray(radiance),
            self.planes,
            self.attenuation_per_m,
            ORDER_PER_RATIO,
            self.nodes,
            self.weights,
        )

    def image_bounce(self, rig: Rig, view: View, points: NDArray, valid: NDArray) -> NDArray:
        """(H, W) the bounce (the lights' scale and the view's exposure included) at the
        pixels' wall points (H, W, 3); 0 where not `valid`."""
        radiance = self.radiance(rig, view)
        h, w = valid.shape
        safe = np.where(valid[..., None], points, 0.0)
        rows, cols = _samples(h), _samples(w)
        coarse_valid = valid[np.ix_(rows, cols)]
        values = np.zeros(coarse_valid.shape)
        values[coarse_valid] = self.bounce(radiance, safe[np.ix_(rows, cols)][coarse_valid])
        out, complete = _bilinear(values, coarse_valid, rows, cols)
        # exactly: the pixels near a surface's foot and those beside an invalid sample
        near = ~complete
        for s in self.surroundings.surfaces:
            foot = s.corners_world[np.abs(s.corners_world[:, 2]) <= 1e-9]
            if len(foot) < 2:
                continue
            a, b = foot[0], foot[1]
            t = np.clip((safe - a) @ (b - a) / ((b - a) @ (b - a)), 0.0, 1.0)
            near |= np.linalg.norm(safe - (a + t[..., None] * (b - a)), axis=-1) < EXACT_REACH_M
        near &= valid
        out[near] = self.bounce(radiance, safe[near])
        return np.where(valid, out, 0.0)

    def hidden(self, rig: Rig, view: View, points: NDArray) -> NDArray:
        """(H, W) pixels whose wall point a surface hides from the camera or from a light."""
        flat = points.reshape(-1, 3)
        finite = np.all(np.isfinite(flat), axis=1)
        safe = np.where(finite[:, None], flat, 0.0)
        owner = np.full(len(flat), -1)
        surfaces = self.surroundings.surfaces
        hidden = segments_blocked(
            surfaces, view.center_world[None, :], np.array([-1]), safe, owner
        )[0]
        for light in rig.lights:
            L = light.position_world(view)
            hidden |= segments_blocked(surfaces, L[None, :], np.array([-1]), safe, owner)[0]
        return (hidden & finite).reshape(points.shape[:2])


def _wall_cells(
    surroundings: Surroundings, region_xy: tuple[float, float, float, float]
) -> tuple[NDArray, NDArray]:
    """(n, 3) wall cell centres and (n,) areas: WALL_CELL_M squares over the region,
    2 WALL_CELL_M squares beyond it up to WALL_MARGIN_M around the surfaces, each cut into
    squares of side WALL_LEVELS[i][0] within WALL_LEVELS[i][1] of a surface's foot."""
    x0, x1, y0, y1 = _wall_region(surroundings, region_xy)
    outer = 2.0 * WALL_CELL_M
    xs = np.arange(x0 + outer / 2, x1, outer)
    ys = np.arange(y0 + outer / 2, y1, outer)
    gx, gy = np.meshgrid(xs, ys, indexing="ij")
    cells = np.stack([gx.ravel(), gy.ravel(), np.zeros(gx.size)], axis=1)
    side = np.full(len(cells), outer)
    rx0, rx1, ry0, ry1 = region_xy
    inside = (cells[:, 0] > rx0 - outer) & (cells[:, 0] < rx1 + outer)
    inside &= (cells[:, 1] > ry0 - outer) & (cells[:, 1] < ry1 + outer)
    pieces = [_split(c, outer, 2) for c in cells[inside]]
    cells = np.concatenate([cells[~inside], *[p[0] for p in pieces]])
    side = np.concatenate([side[~inside], *[p[1] for p in pieces]])
    for fine_m, reach_m in WALL_LEVELS:
        near = (_foot_distance(surroundings, cells) < reach_m + side / 2) & (side > fine_m * 1.5)
        k = np.rint(side[near] / fine_m).astype(int)
        pieces = [
            _split(c, s_, int(n)) for c, s_, n in zip(cells[near], side[near], k, strict=True)
        ]
        cells = np.concatenate([cells[~near], *[p[0] for p in pieces]])
        side = np.concatenate([side[~near], *[p[1] for p in pieces]])
    return cells, side**2


def _wall_region(
    surroundings: Surroundings, region_xy: tuple[float, float, float, float]
) -> tuple[float, float, float, float]:
    """(x0, x1, y0, y1) the region and WALL_MARGIN_M around every surface, m."""
    corners = np.concatenate([s.corners_world for s in surroundings.surfaces])
    lo = corners[:, :2].min(axis=0) - WALL_MARGIN_M
    hi = corners[:, :2].max(axis=0) + WALL_MARGIN_M
    x0, x1, y0, y1 = region_xy
    return min(x0, lo[0]), max(x1, hi[0]), min(y0, lo[1]), max(y1, hi[1])


def _foot_distance(surroundings: Surroundings, points: NDArray) -> NDArray:
    """(n,) the distance of wall points (n, 3) to the nearest surface's foot, m (inf
    without one)."""
    out = np.full(len(points), np.inf)
    for s in surroundings.surfaces:
        foot = s.corners_world[np.abs(s.corners_world[:, 2]) <= 1e-9]
        if len(foot) < 2:
            continue
        a, b = foot[0], foot[1]
        t = np.clip((points - a) @ (b - a) / ((b - a) @ (b - a)), 0.0, 1.0)
        out = np.minimum(out, np.linalg.norm(points - (a + t[:, None] * (b - a)), axis=1))
    return out


def _split(centre: NDArray, side_m: float, k: int) -> tuple[NDArray, NDArray]:
    """((k^2, 3), (k^2,)) a square wall cell cut into k x k squares: centres, sides."""
    f = ((np.arange(k) + 0.5) / k - 0.5) * side_m
    fx, fy = (g.ravel() for g in np.meshgrid(f, f, indexing="ij"))
    return centre + np.stack([fx, fy, np.zeros(fx.size)], axis=1), np.full(k * k, side_m / k)


def _samples(n: int) -> NDArray:
    """(m,) the indices 0, STRIDE, 2 STRIDE, ... and n - 1 of n pixels (m >= 2 for n >= 2)."""
    out = np.arange(0, n, STRIDE)
    return out if out[-1] == n - 1 else np.append(out, n - 1)


def _bilinear(
    values: NDArray, ok: NDArray, rows: NDArray, cols: NDArray
) -> tuple[NDArray, NDArray]:
    """((H, W), (H, W)) samples values (m, k) at pixel rows (m,) and columns (k,)
    interpolated bilinearly to every pixel (H = rows[-1] + 1, W = cols[-1] + 1), and whether
    a pixel's four samples are all `ok` (m, k)."""

    def axis(index: NDArray, n: int) -> tuple[NDArray, NDArray]:
        i = np.arange(n)
        k = np.clip(np.searchsorted(index, i, side="right") - 1, 0, max(len(index) - 2, 0))
        if len(index) < 2:
            return k, np.zeros(n)
        return k, (i - index[k]) / (index[k + 1] - index[k])

    ky, ty = axis(rows, int(rows[-1]) + 1)
    kx, tx = axis(cols, int(cols[-1]) + 1)
    ky1 = np.minimum(ky + 1, len(rows) - 1)
    kx1 = np.minimum(kx + 1, len(cols) - 1)
    ty, tx = ty[:, None], tx[None, :]
    out = (1 - ty) * ((1 - tx) * values[np.ix_(ky, kx)] + tx * values[np.ix_(ky, kx1)]) + ty * (
        (1 - tx) * values[np.ix_(ky1, kx)] + tx * values[np.ix_(ky1, kx1)]
    )
    complete = ok[np.ix_(ky, kx)] & ok[np.ix_(ky, kx1)] & ok[np.ix_(ky1, kx)] & ok[np.ix_(ky1, kx1)]
    return out, complete
