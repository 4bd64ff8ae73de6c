"""The light a ceiling and a side wall send back to the wall, by brute force (`lightcal
synth --corner`): synthetic data's inter-reflection, computed independently of the
model's radiosity (`lightcal.core.bounce`).

The corner: a ceiling (the plane y = y0 - D, from x = x0 - REACH_M to the side wall) and
a side wall (x = x0 + D, from the ceiling to y = y0 + REACH_M), both `depth_m` deep (z from
0), meeting the wall at right angles D from where the views look (x0, y0: their optical
axes' mean point on the wall), Lambertian of `albedo` on both sides, the wall Lambertian of
the same albedo.

Here every surface and the wall near them are cut into square cells of CELL_M (surfaces)
and WALL_CELL_M (wall), each a point source of its cell's area (cos cos / r^2 between
centres, no polygon formula); the cells' radiance is iterated BOUNCES times (light,
surfaces and wall in turn: the path tracer's first bounces, as Mitsuba's `max_depth`);
the bounce at a pixel's wall point sums the surface cells' point kernels, each cell cut
into SPLIT x SPLIT points where the pixel is within 2 cells of it. Shadows and
visibility between the surfaces are tested centre to centre. What is not exact here:
the point kernels (a few per cent within a cell of where a surface meets the wall).
"""

from __future__ import annotations

import math

import cv2
import numpy as np
from numpy.typing import NDArray

from lightcal.core.scene import Rig, View
from lightcal.core.surroundings import Surface, Surroundings, segments_blocked

__all__ = ["REACH_M", "CornerBounce", "corner_surroundings"]

#: How far the ceiling and the side wall reach beyond where the views look, m.
REACH_M = 3.0

#: Cell sides, m: the surfaces'; the wall's, FINE_M within FINE_REACH_M of where a
#: surface meets it and WALL_CELL_M elsewhere.
CELL_M = 0.05
WALL_CELL_M = 0.1
FINE_M = 0.025
FINE_REACH_M = 0.3

#: Iterations of the cells' radiance: bounces off the surfaces and the wall.
BOUNCES = 4

#: Near cells are cut into SPLIT x SPLIT points.
SPLIT = 5


#: Pixels farther than this from a surface's foot take the bounce of every STRIDE-th
#: pixel, interpolated bilinearly; the others their own, m.
EXACT_REACH_M = 0.15
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


def _cells(surface: Surface, side: float) -> tuple[NDArray, NDArray, float, NDArray]:
    """(n, 3) cell centres, (n, 3) the unit normal of one side, the cell area and (2, 3)
    the cell's two edges."""
    u, v = surface.edge_u_world, surface.edge_v_world
    nu = max(1, math.ceil(np.linalg.norm(u) / CELL_M))
    nv = max(1, math.ceil(np.linalg.norm(v) / CELL_M))
    s, t = np.meshgrid((np.arange(nu) + 0.5) / nu, (np.arange(nv) + 0.5) / nv, indexing="ij")
    centres = surface.corner_world + s.ravel()[:, None] * u + t.ravel()[:, None] * v
    normal = np.broadcast_to(side * surface.normal_world, centres.shape)
    return centres, normal, surface.area_m2 / (nu * nv), np.stack([u / nu, v / nv])


class CornerBounce:
    """The brute-force bounce of surroundings (world-fixed cells and kernels).

    Args:
        surroundings: the surfaces (`corner_surroundings`).
        region_xy: (x0, x1, y0, y1) the wall the beam may light near them, m.
    """

    def __init__(
        self, surroundings: Surroundings, region_xy: tuple[float, float, float, float]
    ) -> None:
        self.surroundings = surroundings
        self.region_xy = region_xy
        cells = [
            (*_cells(s, side), k)
            for k, s in enumerate(self.surroundings.surfaces)
            for side in (1.0, -1.0)
        ]
        q = np.concatenate([c[0] for c in cells])
        n = np.concatenate([c[1] for c in cells])
        area = np.concatenate([np.full(len(c[0]), c[2]) for c in cells])
        owner = np.concatenate([np.full(len(c[0]), c[4]) for c in cells])
        edges = np.concatenate([np.broadcast_to(c[3], (len(c[0]), 2, 3)) for c in cells])
        w, w_area = _wall_cells(self.surroundings, self.region_xy)
        surfaces = self.surroundings.surfaces
        free_ws = ~segments_blocked(surfaces, w, np.full(len(w), -1), q, owner)
        # kernel[i, j] = cos_i cos_j / (pi r^2): radiance at j -> irradiance at i, / area
        k_ws = _kernel(w, np.broadcast_to([0.0, 0.0, 1.0], w.shape), q, n)
        _refine_near(k_ws, w, np.sqrt(w_area), q, n, edges)
        k_ws *= free_ws
        free_ss = ~segments_blocked(surfaces, q, owner, q, owner)
        k_ss = _kernel(q, n, q, n) * free_ss * (owner[:, None] != owner[None, :])
        self.q, self.n, self.area, self.owner, self.edges = q, n, area, owner, edges
        self.w, self.w_area, self.k_ws, self.k_ss = w, w_area, k_ws, k_ss

    def _sources(
        self, points: NDArray, normals: NDArray, owner: NDArray, rig: Rig, view: View
    ) -> NDArray:
        """(n,) the lights' irradiance (scale and exposure included) at points."""
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
            out += np.where(lit, light.scale * view.exposure * f * cos / r**2, 0.0)
        return out

    def radiance(self, rig: Rig, view: View) -> NDArray:
        """(n,) the surface cells' radiance after BOUNCES iterations."""
        rho = np.array([self.surroundings.surfaces[k].albedo for k in self.owner]) / math.pi
        rho_w = self.surroundings.wall_albedo / math.pi
        e_s = self._sources(self.q, self.n, self.owner, rig, view)
        up = np.broadcast_to([0.0, 0.0, 1.0], self.w.shape)
        e_w = self._sources(self.w, up, np.full(len(self.w), -1), rig, view)
        wall_area = self.w_area
        radiance = np.zeros(len(self.q))
        wall = rho_w * e_w
        for _ in range(BOUNCES):
            radiance = rho * (
                e_s + self.k_ws.T @ (wall * wall_area) + self.k_ss @ (radiance * self.area)
            )
            wall = rho_w * (e_w + self.k_ws @ (radiance * self.area))
        return radiance

    def bounce(self, radiance: NDArray, points: NDArray) -> NDArray:
        """(N,) the irradiance at wall points (N, 3) from the cells' radiance."""
        out = np.zeros(len(points))
        up = np.array([0.0, 0.0, 1.0])
        f = (np.arange(SPLIT) + 0.5) / SPLIT - 0.5
        for a in range(0, len(points), 512):
            p = points[a : a + 512]
            k = _kernel(p, np.broadcast_to(up, p.shape), self.q, self.n)
            gap = np.linalg.norm(p[:, None, :] - self.q[None, :, :], axis=2)
            near_p, near_c = np.nonzero(gap < 2.0 * CELL_M)
            k[near_p, near_c] = 0.0
            out[a : a + 512] = k @ (radiance * self.area)
            if near_c.size == 0:
                continue
            c = near_c
            for s_ in f:  # the near cells again, SPLIT x SPLIT points each
                for t_ in f:
                    sub = self.q[c] + s_ * self.edges[c, 0] + t_ * self.edges[c, 1]
                    kk = _pair_kernel(p[near_p], sub, self.n[c])
                    np.add.at(out, a + near_p, kk * radiance[c] * self.area[c] / SPLIT**2)
        return out

    def image_bounce(self, rig: Rig, view: View, points: NDArray, valid: NDArray) -> NDArray:
        """(H, W) the bounce (the lights' scale and the view's exposure included) at the
        pixels' wall points (H, W, 3); 0 where not `valid`."""
        radiance = self.radiance(rig, view)
        h, w = valid.shape
        safe = np.where(valid[..., None], points, 0.0)
        coarse = safe[::STRIDE, ::STRIDE]
        values = self.bounce(radiance, coarse.reshape(-1, 3)).reshape(coarse.shape[:2])
        out = cv2.resize(values, (w, h), interpolation=cv2.INTER_LINEAR)
        # cv2's pixel centres: coarse pixel k sits at fine (k + 1/2) STRIDE - 1/2; redo the
        # rim and the pixels near a surface exactly.
        near = np.zeros((h, w), dtype=bool)
        near[:STRIDE, :] = near[-STRIDE:, :] = near[:, :STRIDE] = near[:, -STRIDE:] = True
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


def _refine_near(
    k: NDArray, w: NDArray, w_side: NDArray, q: NDArray, n: NDArray, edges: NDArray
) -> None:
    """The kernel of wall cells (centres w, sides w_side) and surface cells (centres q,
    normals n, edges) closer than 2 CELL_M, again as the mean over SPLIT x SPLIT points of
    each, in place."""
    gap = np.linalg.norm(w[:, None, :] - q[None, :, :], axis=2)
    iw, iq = np.nonzero(gap < 2.0 * CELL_M)
    if iw.size == 0:
        return
    f = (np.arange(SPLIT) + 0.5) / SPLIT - 0.5
    total = np.zeros(iw.size)
    for a in f:
        for b in f:
            pw = w[iw] + np.stack([a * w_side[iw], b * w_side[iw], np.zeros(iw.size)], axis=1)
            for s_ in f:
                for t_ in f:
                    pq = q[iq] + s_ * edges[iq, 0] + t_ * edges[iq, 1]
                    total += _pair_kernel(pw, pq, n[iq])
    k[iw, iq] = total / SPLIT**4


def _wall_cells(
    surroundings: Surroundings, region_xy: tuple[float, float, float, float]
) -> tuple[NDArray, NDArray]:
    """(n, 3) wall cell centres and (n,) areas: WALL_CELL_M squares, each cut into
    FINE_M squares within FINE_REACH_M of a surface's foot on the wall."""
    x0, x1, y0, y1 = region_xy
    xs = np.arange(x0 + WALL_CELL_M / 2, x1, WALL_CELL_M)
    ys = np.arange(y0 + WALL_CELL_M / 2, y1, WALL_CELL_M)
    gx, gy = np.meshgrid(xs, ys, indexing="ij")
    coarse = np.stack([gx.ravel(), gy.ravel(), np.zeros(gx.size)], axis=1)
    near = np.zeros(len(coarse), dtype=bool)
    for s in surroundings.surfaces:
        foot = s.corners_world[np.abs(s.corners_world[:, 2]) <= 1e-9]
        if len(foot) < 2:
            continue
        a, b = foot[0], foot[1]
        t = np.clip((coarse - a) @ (b - a) / ((b - a) @ (b - a)), 0.0, 1.0)
        dist = np.linalg.norm(coarse - (a + t[:, None] * (b - a)), axis=1)
        near |= dist < FINE_REACH_M
    k = round(WALL_CELL_M / FINE_M)
    f = ((np.arange(k) + 0.5) / k - 0.5) * WALL_CELL_M
    fx, fy = (g.ravel() for g in np.meshgrid(f, f, indexing="ij"))
    offsets = np.stack([fx, fy, np.zeros(fx.size)], axis=1)
    fine = (coarse[near][:, None, :] + offsets[None]).reshape(-1, 3)
    cells = np.concatenate([coarse[~near], fine])
    area = np.concatenate(
        [np.full(int((~near).sum()), WALL_CELL_M**2), np.full(len(fine), (WALL_CELL_M / k) ** 2)]
    )
    return cells, area


def _kernel(a: NDArray, na: NDArray, b: NDArray, nb: NDArray) -> NDArray:
    """(len(a), len(b)) max(0, cos_a) max(0, cos_b) / r^2 between points a (normals na)
    and b (normals nb), 0 at r = 0."""
    d = b[None, :, :] - a[:, None, :]
    r2 = np.einsum("abi,abi->ab", d, d)
    with np.errstate(divide="ignore", invalid="ignore"):
        ca = np.einsum("abi,ai->ab", d, na)
        cb = -np.einsum("abi,bi->ab", d, nb)
        k = np.maximum(ca, 0.0) * np.maximum(cb, 0.0) / (r2 * r2)
    return np.where(r2 > 0.0, k, 0.0)


def _pair_kernel(a: NDArray, b: NDArray, nb: NDArray) -> NDArray:
    """(n,) `_kernel` of wall points a (normal +z) and points b (normals nb), pairwise."""
    d = b - a
    r2 = np.einsum("ni,ni->n", d, d)
    cb = -np.einsum("ni,ni->n", d, nb)
    return np.maximum(d[:, 2], 0.0) * np.maximum(cb, 0.0) / (r2 * r2)
