"""The bounce term: light the surroundings (`lightcal.core.surroundings`) send back to
the wall, by radiosity on a mesh (docs/model.md, "Inter-reflection").

- Each surface is cut into patches of side at most `patch_m`; each patch is two oriented
  copies (K in all), one a side, each of uniform radiance, lit and lighting only on the
  side its normal points to. The wall around the pixels is a grid of nodes `patch_m`
  apart, each the centre of a square cell (J in all).
- Sources, per view and light, per unit intensity: e_S (K,) the beam's irradiance at the
  copies' centres, e_W (J,) at the nodes, 0 where a surface shadows them.
- The copies' radiance solves L = (rho / pi) (e_S + G_SS L + (rho_w / pi) G_SW (e_W + G_WS
  L)): every bounce between the surfaces and the wall, not only the first.
- The wall's bounce irradiance is G_WS L at the nodes, interpolated bilinearly to each
  pixel's footprint centre; copies within NEAR patch sides of the centre are integrated
  exactly there instead (the field is not smooth where a surface meets the wall).

G_ab[i, l] is the irradiance at point i of a per unit radiance of polygon l of b,
Lambert's formula (`polygon_irradiance`), times whether the segment between their centres
is free of other surfaces. All of it but the sources is fixed in the world, so the map
from sources to bounce is linear and built once per calibration; the derivatives with
respect to the light's pose are that map applied to the sources' derivatives (central
differences of the sources, whose shadows are held: 12 evaluations of K + J points).

In a medium of attenuation c every segment is attenuated: the sources by exp(-c r) from
the light, each transfer by exp(-c r) over its pair's distance (`in_medium`,
`medium_distances`, `lightcal.core.bounce_transfers`), the near copies and the close
copy-node pairs over their irradiance-weighted distance (`weighted_distance`); the
world-fixed part then depends on c and is kept for the last c asked. The term per image
and light, with the camera's segment, is `lightcal.core.bounce_term`.
"""

from __future__ import annotations

import functools
import math
import threading
from dataclasses import dataclass

import numpy as np
from scipy import sparse

from lightcal.core.bounce_transfers import (
    Transfers,
    TransferSlopes,
    attenuated,
    pair_distances,
    slopes,
)
from lightcal.core.rid import RID
from lightcal.core.rotations import matrix_from_rotvec
from lightcal.core.surroundings import Surface, Surroundings, polygon_irradiance, segments_blocked

__all__ = ["NEAR", "BounceMap", "NearPairs", "PixelMap"]

#: Copies whose centre lies within NEAR patch sides of a pixel's centre are integrated
#: exactly at it.
NEAR = 3.0

#: In a medium, the attenuation of a copy's light at a wall point closer than CLOSE patch
#: sides is weighted over SPLIT x SPLIT parts of the copy (`weighted_distance`).
CLOSE = 3.0
SPLIT = 8

#: The most patches (one side) and wall nodes of a mesh: the maps hold J x 2K numbers.
MAX_PATCHES = 4000
MAX_NODES = 40_000

#: Central differences of the sources: step in m and rad.
_STEP = 1e-6

_UP = np.array([0.0, 0.0, 1.0])

#: The wall grid's spacing is GRID_FRACTION patch_m: measured on the Mitsuba corner
#: (docs/model.md), the wall's cells set the accuracy more than the surfaces' patches.
GRID_FRACTION = 0.5


def _patches(surface: Surface, patch_m: float) -> tuple[np.ndarray, np.ndarray]:
    """(n, 4, 3) the surface's patches (its vertex order) and (n, 3) their centres."""
    u, v = surface.edge_u_world, surface.edge_v_world
    nu = max(1, math.ceil(np.linalg.norm(u) / patch_m - 1e-9))
    nv = max(1, math.ceil(np.linalg.norm(v) / patch_m - 1e-9))
    s0, t0 = (a.ravel() for a in np.meshgrid(np.arange(nu) / nu, np.arange(nv) / nv, indexing="ij"))
    du, dv = u / nu, v / nv
    base = surface.corner_world + s0[:, None] * u + t0[:, None] * v
    quads = np.stack([base, base + du, base + du + dv, base + dv], axis=1)
    return quads, base + 0.5 * (du + dv)


def weighted_distance(points_world: np.ndarray, quads_world: np.ndarray) -> np.ndarray:
    """(P,) the mean distance from wall points (P, 3) over quads (P, 4, 3), weighted by the
    irradiance each part of the quad sends to the point (the quad cut into SPLIT x SPLIT
    parts, Lambert's formula for each), m: exp(-c distance) is the quad's attenuated
    irradiance at the point to first order in c (docs/model.md, "Inter-reflection"). The
    centres' distance where the quad sends nothing."""
    q = quads_world
    o, du, dv = q[:, 0], q[:, 1] - q[:, 0], q[:, 3] - q[:, 0]
    n = SPLIT
    weight = np.zeros(len(q))
    moment = np.zeros(len(q))
    for i in range(n):
        for j in range(n):
            a = o + (i / n) * du + (j / n) * dv
            part = np.stack([a, a + du / n, a + (du + dv) / n, a + dv / n], axis=1)
            e = np.abs(_pair_irradiance(points_world, part))
            weight += e
            moment += e * np.linalg.norm(points_world - (a + 0.5 * (du + dv) / n), axis=1)
    centre_m = np.linalg.norm(points_world - q.mean(axis=1), axis=1)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(weight > 0.0, moment / weight, centre_m)


@dataclass(frozen=True, eq=False)
class NearPairs:
    """The P (point, copy) pairs of a `PixelMap` whose copy is integrated exactly.

    Attributes:
        point, copy: (P,) their indices.
        exact: (P,) the copy's exact irradiance at the point per unit radiance (0 from
            its back), in air.
        points_world: (P, 3) the points; quads_world: (P, 4, 3) the copies, m.
        nodes: (P, 4) the point's interpolating nodes; weights: (P, 4) their weights.
    """

    point: np.ndarray
    copy: np.ndarray
    exact: np.ndarray
    points_world: np.ndarray
    quads_world: np.ndarray
    nodes: np.ndarray
    weights: np.ndarray

    @functools.cached_property
    def distance_m(self) -> np.ndarray:
        """(P,) the distance over which a medium attenuates each pair's light, m
        (`weighted_distance`; made on first use in a medium)."""
        return weighted_distance(self.points_world, self.quads_world)

    def near(self, G_WS: np.ndarray, shape: tuple[int, int], c: float = 0.0) -> sparse.csr_matrix:
        """(N, K) sparse: per unit radiance of the copies, their exact irradiance at the
        points (times exp(-c r), r `distance_m`) less what the interpolation of G_WS
        (J, K) gives of them."""
        exact = self.exact if c == 0.0 else self.exact * np.exp(-c * self.distance_m)
        return self._sparse(exact, G_WS, shape)

    def near_slope(self, D_WS: np.ndarray, shape: tuple[int, int], c: float) -> sparse.csr_matrix:
        """(N, K) sparse: the derivative of `near` with respect to c, D_WS = d G_WS / dc."""
        exact = -self.distance_m * self.exact * np.exp(-c * self.distance_m)
        return self._sparse(exact, D_WS, shape)

    def _sparse(
        self, exact: np.ndarray, G_WS: np.ndarray, shape: tuple[int, int]
    ) -> sparse.csr_matrix:
        interpolated = np.einsum("nc,nc->n", self.weights, G_WS[self.nodes, self.copy[:, None]])
        return sparse.csr_matrix((exact - interpolated, (self.point, self.copy)), shape=shape)


@dataclass(frozen=True, eq=False)
class PixelMap:
    """How the bounce at N wall points follows from the copies' radiance.

    Attributes:
        interpolate: (N, J) sparse, the bilinear weights of the grid's nodes.
        near: (N, K) sparse, per unit radiance of the copies near each point, their exact
            irradiance there less what the interpolation gives of them (in air).
        pairs: the near pairs (to make `near` in a medium).
    """

    interpolate: sparse.csr_matrix
    near: sparse.csr_matrix
    pairs: NearPairs


class BounceMap:
    """The world-fixed part of the bounce term over a region of the wall.

    Args:
        surroundings: the surfaces.
        region_xy: (x0, x1, y0, y1) the part of the wall whose bounce is wanted, m; the
            grid covers it with a spacing of margin.

    Raises:
        ValueError: more than MAX_PATCHES patches or MAX_NODES nodes.
    """

    def __init__(
        self, surroundings: Surroundings, region_xy: tuple[float, float, float, float]
    ) -> None:
        self.surroundings = surroundings
        surfaces = surroundings.surfaces
        h = surroundings.patch_m
        parts = [_patches(s, h) for s in surfaces]
        count = sum(len(c) for _, c in parts)
        if count > MAX_PATCHES:
            raise ValueError(
                f"surroundings: {count} patches of {h:g} m; expected at most {MAX_PATCHES} "
                "(a larger patch_m, or smaller surfaces)"
            )
        x0, x1, y0, y1 = region_xy
        h = GRID_FRACTION * surroundings.patch_m
        self.x = np.arange(x0 - h, x1 + 2.0 * h, h)
        self.y = np.arange(y0 - h, y1 + 2.0 * h, h)
        J = self.x.size * self.y.size
        if J > MAX_NODES:
            raise ValueError(
                f"surroundings: the wall's grid would have {J} nodes of {h:g} m; expected at "
                f"most {MAX_NODES} (a larger patch_m)"
            )
        geo_quads = np.concatenate([q for q, _ in parts])
        geo_centres = np.concatenate([c for _, c in parts])
        geo_normals = np.concatenate(
            [np.broadcast_to(surfaces[k].normal_world, c.shape) for k, (_, c) in enumerate(parts)]
        )
        geo_owner = np.concatenate([np.full(len(c), k) for k, (_, c) in enumerate(parts)])
        geo_albedo = np.array([surfaces[k].albedo for k in geo_owner])
        # Copies: every patch with its normal, then every patch turned over.
        self.geometric = np.concatenate([np.arange(count), np.arange(count)])
        self.sign = np.repeat([1.0, -1.0], count)
        self.quads = np.concatenate([geo_quads, geo_quads[:, ::-1]])
        self.centres = np.concatenate([geo_centres, geo_centres])
        self.normals = np.ascontiguousarray(np.concatenate([geo_normals, -geo_normals]))
        self.owner = np.concatenate([geo_owner, geo_owner])
        xx, yy = np.meshgrid(self.x, self.y, indexing="ij")  # node (i, j) -> i * ny + j
        self.nodes = np.stack([xx.ravel(), yy.ravel(), np.zeros(J)], axis=1)
        no_owner = np.full(J, -1)

        # Copy c from copy d: other surfaces, each on the other's side, the line free.
        geo_ss = np.zeros((count, count))
        for k in range(len(surfaces)):
            mine = geo_owner == k
            others = ~mine
            if others.any():
                geo_ss[np.ix_(mine, others)] = np.abs(
                    polygon_irradiance(geo_centres[mine], geo_normals[mine], geo_quads[others])
                )
        geo_ss *= ~segments_blocked(surfaces, geo_centres, geo_owner, geo_centres, geo_owner)
        rel = self.centres[None, :, :] - self.centres[:, None, :]  # [c, d] = centre_d - centre_c
        facing = (np.einsum("cdi,ci->cd", rel, self.normals) > 1e-9) & (
            np.einsum("cdi,di->cd", rel, self.normals) < -1e-9
        )
        self.G_SS = geo_ss[np.ix_(self.geometric, self.geometric)] * facing
        # Copy c from wall cell j, and node j from copy c: j on c's side, the line free.
        toward = (
            self.nodes @ geo_normals.T - np.einsum("ki,ki->k", geo_centres, geo_normals)
        ) > 0.0
        free = ~segments_blocked(surfaces, self.nodes, no_owner, geo_centres, geo_owner)
        seen = np.concatenate([toward & free, ~toward & free], axis=1)  # (J, 2 count)
        self.h = h
        cells = self.nodes[:, None, :] + 0.5 * h * np.array(
            [[-1.0, -1.0, 0.0], [1.0, -1.0, 0.0], [1.0, 1.0, 0.0], [-1.0, 1.0, 0.0]]
        )
        # A copy sees the part of each wall cell on its side of its surface's plane.
        geo_sw = np.zeros((2 * count, J))
        for k, surface in enumerate(surfaces):
            mine = np.nonzero(geo_owner == k)[0]
            for side, rows in ((1.0, mine), (-1.0, mine + count)):
                part = _clip(cells, side * surface.normal_world, surface.corner_world)
                geo_sw[rows] = np.abs(
                    polygon_irradiance(geo_centres[mine], geo_normals[mine], part)
                )
        free_sw = np.concatenate([free, free], axis=1).T  # (2 count, J)
        self.G_SW = geo_sw * free_sw
        up = np.broadcast_to(_UP, self.nodes.shape)
        geo_ws = np.abs(polygon_irradiance(self.nodes, up, geo_quads))  # (J, count)
        self.G_WS = geo_ws[:, self.geometric] * seen
        self.transfers = Transfers.build(
            self.G_SS,
            self.G_SW,
            self.G_WS,
            geo_albedo[self.geometric] / math.pi,
            surroundings.wall_albedo,
            surroundings.bounces,
        )
        # The transfers in a medium: (c, at c, their slopes or None), the last c asked.
        self._in_medium: tuple[float, Transfers, TransferSlopes | None] | None = None
        self._medium_lock = threading.Lock()
        owners = np.concatenate([self.owner, no_owner])
        self._points = np.concatenate([self.centres, self.nodes])
        self._point_normals = np.concatenate([self.normals, up])
        self._point_owner = owners

    # -- sources ------------------------------------------------------------------------

    def sources(
        self,
        light_world: np.ndarray,
        R_world_light: np.ndarray,
        rid: RID,
        visible: np.ndarray | None = None,
        attenuation_per_m: float = 0.0,
    ) -> tuple[np.ndarray, np.ndarray]:
        """(K + J,) the beam's irradiance per unit intensity at the copies' centres and at
        the wall's nodes, times exp(-c r) in a medium of attenuation c (1/m; r the
        distance from the light, m), and (K + J,) where the light reaches them (its side,
        no surface in between; `visible`, when given, is taken instead)."""
        d = light_world[None, :] - self._points
        r = np.sqrt(np.einsum("ni,ni->n", d, d))
        cos = np.einsum("ni,ni->n", d, self._point_normals) / r
        if visible is None:
            blocked = segments_blocked(
                self.surroundings.surfaces,
                light_world[None, :],
                np.array([-1]),
                self._points,
                self._point_owner,
            )[0]
            visible = (cos > 0.0) & ~blocked
        u = (-d / r[:, None]) @ R_world_light  # directions in the light frame
        theta = np.arccos(np.clip(u[:, 2], -1.0, 1.0))
        phi = np.arctan2(u[:, 1], u[:, 0])
        f = rid.value_and_derivatives(theta, phi)[0]
        if attenuation_per_m > 0.0:
            f = f * np.exp(-attenuation_per_m * r)
        return np.where(visible, f * np.maximum(cos, 0.0) / (r * r), 0.0), visible

    def source_distances(self, light_world: np.ndarray) -> np.ndarray:
        """(K + J,) the distances from the light (3,) to the copies' centres and the
        wall's nodes, m: d e / dc = -r e for the sources e in a medium."""
        return np.asarray(np.linalg.norm(self._points - light_world[None, :], axis=1))

    def source_columns(
        self,
        light_world: np.ndarray,
        R_world_light: np.ndarray,
        rid: RID,
        *,
        want_grad: bool,
        attenuation_per_m: float = 0.0,
    ) -> np.ndarray:
        """(K + J, 1 or 7) the sources (in a medium of attenuation c, 1/m) and, with
        want_grad, their derivatives with respect to (L_world (3), delta_world (3)),
        delta_world a left rotation perturbation of R_world_light (central differences,
        the shadows held)."""
        attenuation = attenuation_per_m
        e, visible = self.sources(light_world, R_world_light, rid, attenuation_per_m=attenuation)
        if not want_grad:
            return e[:, None]
        out = np.empty((e.size, 7))
        out[:, 0] = e
        for c in range(3):
            step = np.zeros(3)
            step[c] = _STEP
            plus = self.sources(light_world + step, R_world_light, rid, visible, attenuation)[0]
            minus = self.sources(light_world - step, R_world_light, rid, visible, attenuation)[0]
            out[:, 1 + c] = (plus - minus) / (2.0 * _STEP)
            turn = matrix_from_rotvec(step)
            plus = self.sources(light_world, turn @ R_world_light, rid, visible, attenuation)[0]
            minus = self.sources(light_world, turn.T @ R_world_light, rid, visible, attenuation)[0]
            out[:, 4 + c] = (plus - minus) / (2.0 * _STEP)
        return out

    def radiance(self, sources: np.ndarray) -> np.ndarray:
        """(K, c) the copies' radiance in air per unit intensity of sources (K + J, c)
        (`Transfers.radiance`)."""
        return self.transfers.radiance(sources)

    def in_medium(
        self, attenuation_per_m: float, *, want_slopes: bool
    ) -> tuple[Transfers, TransferSlopes | None]:
        """The transfers in a medium of attenuation c (1/m) and, with want_slopes, their
        derivatives with respect to c; kept for the last c asked (a new c costs the
        (K, J) x (J, K) product and the K x K factorisation of `Transfers.build`)."""
        c = float(attenuation_per_m)
        with self._medium_lock:
            kept = self._in_medium
            if kept is None or kept[0] != c or (want_slopes and kept[2] is None):
                R_SS, R_SW = self.medium_distances
                at_c = kept[1] if kept is not None and kept[0] == c else None
                if at_c is None:
                    at_c = self.transfers if c == 0.0 else attenuated(self.transfers, R_SS, R_SW, c)
                kept = (c, at_c, slopes(at_c, R_SS, R_SW) if want_slopes else None)
                self._in_medium = kept
            return kept[1], kept[2]

    @functools.cached_property
    def medium_distances(self) -> tuple[np.ndarray, np.ndarray]:
        """(K, K) and (K, J) the distances over which a medium attenuates the transfers
        G_SS and G_SW (G_WS: its transpose), m: between the points the kernels use (copy
        centres, wall nodes), or for a copy and a node closer than CLOSE patch sides the
        mean over the copy weighted by the irradiance it sends to the node
        (`weighted_distance`). Made on first use in a medium."""
        R_SS, R_SW = pair_distances(self.centres, self.nodes)
        count = len(self.centres) // 2  # the second half: the same patches turned over
        geo = R_SW[:count]
        ci, ji = np.nonzero(geo < CLOSE * self.surroundings.patch_m)
        geo[ci, ji] = weighted_distance(self.nodes[ji], self.quads[ci])
        return R_SS, np.ascontiguousarray(geo[self.geometric])

    # -- pixels -------------------------------------------------------------------------

    def pixel_map(self, points_world: np.ndarray) -> PixelMap:
        """The `PixelMap` of wall points (N, 3) (finite, inside the region)."""
        h = self.h
        n = len(points_world)
        fx = (points_world[:, 0] - self.x[0]) / h
        fy = (points_world[:, 1] - self.y[0]) / h
        i = np.clip(np.floor(fx).astype(np.int64), 0, self.x.size - 2)
        j = np.clip(np.floor(fy).astype(np.int64), 0, self.y.size - 2)
        a = np.clip(fx - i, 0.0, 1.0)
        b = np.clip(fy - j, 0.0, 1.0)
        ny = self.y.size
        idx = np.stack([i * ny + j, (i + 1) * ny + j, i * ny + j + 1, (i + 1) * ny + j + 1], 1)
        w = np.stack([(1 - a) * (1 - b), a * (1 - b), (1 - a) * b, a * b], axis=1)
        interpolate = sparse.csr_matrix(
            (w.ravel(), idx.ravel(), np.arange(0, 4 * n + 1, 4)), shape=(n, len(self.nodes))
        )
        parts: list[tuple[np.ndarray, ...]] = []
        reach = NEAR * h
        for k in range(len(self.surroundings.surfaces)):
            mine = np.nonzero(self.owner == k)[0]
            lo = self.centres[mine].min(axis=0) - reach
            hi = self.centres[mine].max(axis=0) + reach
            close = np.nonzero(np.all((points_world >= lo) & (points_world <= hi), axis=1))[0]
            for start in range(0, close.size, 256):
                pts = close[start : start + 256]
                gap = points_world[pts, None, :] - self.centres[None, mine, :]
                pi, ki = np.nonzero(np.einsum("pki,pki->pk", gap, gap) <= reach * reach)
                if pi.size == 0:
                    continue
                p_idx, c_idx = pts[pi], mine[ki]
                P = points_world[p_idx]
                exact = np.abs(_pair_irradiance(P, self.quads[c_idx]))
                side = np.einsum("ni,ni->n", P - self.centres[c_idx], self.normals[c_idx]) > 0.0
                quads = self.quads[c_idx]
                parts.append((p_idx, c_idx, exact * side, P, quads, idx[p_idx], w[p_idx]))
        if parts:
            pairs = NearPairs(*(np.concatenate(a) for a in zip(*parts, strict=True)))
        else:
            none = np.zeros(0, dtype=np.int64)
            empty = np.zeros((0, 3))
            pairs = NearPairs(none, none, np.zeros(0), empty, self.quads[:0], idx[:0], w[:0])
        near = pairs.near(self.G_WS, (n, len(self.centres)))
        return PixelMap(interpolate, near, pairs)

    def bounce(self, radiance: np.ndarray, pixels: PixelMap) -> np.ndarray:
        """(N, c) the bounce irradiance at a pixel map's points of radiance (K, c)."""
        return np.asarray(pixels.interpolate @ (self.G_WS @ radiance) + pixels.near @ radiance)


def _clip(cells: np.ndarray, normal: np.ndarray, point: np.ndarray) -> np.ndarray:
    """(J, 5, 3) the convex quads `cells` (J, 4, 3) cut to the half-space
    (x - point) . normal >= 0 (Sutherland-Hodgman), padded by repeating their last vertex
    (an edge of length 0 adds nothing to Lambert's formula); all at one vertex when
    nothing is left."""
    d = (cells - point) @ normal  # (J, 4)
    out = np.concatenate([cells, cells[:, 3:]], axis=1)
    out[d.max(axis=1) < 0.0] = cells[d.max(axis=1) < 0.0, :1]
    for j in np.nonzero((d.min(axis=1) < 0.0) & (d.max(axis=1) >= 0.0))[0]:
        kept: list[np.ndarray] = []
        for i in range(4):
            a, b = cells[j, i], cells[j, (i + 1) % 4]
            da, db = d[j, i], d[j, (i + 1) % 4]
            if da >= 0.0:
                kept.append(a)
            if (da >= 0.0) != (db >= 0.0):
                kept.append(a + da / (da - db) * (b - a))
        out[j] = np.array(kept + [kept[-1]] * (5 - len(kept)))
    return out


def _pair_irradiance(points: np.ndarray, polygons: np.ndarray) -> np.ndarray:
    """(n,) Lambert's formula (`polygon_irradiance`) for wall points (n, 3) (normal +z),
    each with its own polygon (n, V, 3)."""
    R = polygons - points[:, None, :]
    R1 = np.roll(R, -1, axis=1)
    c = np.cross(R, R1)
    cn = np.sqrt(np.einsum("nvi,nvi->nv", c, c))
    gamma = np.arctan2(cn, np.einsum("nvi,nvi->nv", R, R1))
    with np.errstate(invalid="ignore", divide="ignore"):
        proj = np.where(cn > 1e-300, c[..., 2] / cn, 0.0)
    return np.asarray(0.5 * np.einsum("nv,nv->n", gamma, proj))
