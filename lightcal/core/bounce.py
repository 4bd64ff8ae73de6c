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
  pixel's footprint centre one surface's side at a time; copies within NEAR grid spacings
  of the centre are integrated exactly there instead (the field is not smooth where a
  surface meets the wall; `lightcal.core.bounce_pixels`).

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

import numpy as np

from lightcal.core.bounce_pixels import PixelMap, pixel_map, weighted_distance
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

__all__ = ["BounceMap"]

#: In a medium, the attenuation of a copy's light at a wall point closer than CLOSE patch
#: sides is weighted over its parts (`bounce_pixels.weighted_distance`).
CLOSE = 3.0

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
        self.x = _axis(x0, x1, h, _foot_at(surfaces, 0))
        self.y = _axis(y0, y1, h, _foot_at(surfaces, 1))
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
        # The copies' groups, one surface's side each: (start, stop, surface, side).
        offsets = np.cumsum([0] + [len(c) for _, c in parts])
        self.groups = tuple(
            (int(half + offsets[k]), int(half + offsets[k + 1]), k, sign)
            for half, sign in ((0, 1.0), (count, -1.0))
            for k in range(len(surfaces))
        )
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
        # The transfers with other albedos: ((c, albedos), transfers), the last asked.
        self._with_albedos: tuple[tuple[float, tuple[float, ...]], Transfers] | None = None
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

    def transfers_at(
        self, attenuation_per_m: float, albedos: np.ndarray | None, *, want_slopes: bool
    ) -> tuple[Transfers, TransferSlopes | None]:
        """`in_medium`'s transfers with the surfaces' albedos (S,) instead of the declared
        (None: the declared); the slopes d/dc do not depend on them. Kept for the last
        (c, albedos) asked (a K x K factorisation, the (K, J) x (J, K) product)."""
        t, d = self.in_medium(attenuation_per_m, want_slopes=want_slopes)
        if albedos is None:
            return t, d
        key = (float(attenuation_per_m), tuple(float(a) for a in albedos))
        with self._medium_lock:
            kept = self._with_albedos
            if kept is None or kept[0] != key:
                rho = np.asarray(albedos, dtype=np.float64)[self.owner] / math.pi
                built = Transfers.build(t.G_SS, t.G_SW, t.G_WS, rho, t.wall_albedo, t.bounces)
                kept = (key, built)
                self._with_albedos = kept
            return kept[1], d

    def surface_masks(self, surfaces: tuple[int, ...]) -> np.ndarray:
        """(K, m) which copies belong to each of the surfaces (indices)."""
        return np.stack([self.owner == k for k in surfaces], axis=1)

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
        """The `PixelMap` of wall points (N, 3) (finite, inside the region;
        `lightcal.core.bounce_pixels`)."""
        return pixel_map(self, points_world)

    def bounce(self, radiance: np.ndarray, pixels: PixelMap) -> np.ndarray:
        """(N, c) the bounce irradiance at a pixel map's points of radiance (K, c)."""
        return np.asarray(pixels.gather(self.G_WS, radiance) + pixels.near @ radiance)


def _foot_at(surfaces: tuple[Surface, ...], axis: int) -> float | None:
    """The wall coordinate `axis` (0: x, 1: y) of the first surface's foot that runs along
    the other axis (a side wall's x, a ceiling's y), m; None if no foot does."""
    for s in surfaces:
        foot = s.corners_world[np.abs(s.corners_world[:, 2]) <= 1e-9]
        if len(foot) >= 2 and abs(foot[1, axis] - foot[0, axis]) <= 1e-9:
            return float(foot[0, axis])
    return None


def _axis(lo: float, hi: float, h: float, foot: float | None) -> np.ndarray:
    """The grid's node coordinates along one axis: every h from below lo - h to beyond
    hi + h, half a spacing off a foot (its cells' edges on it: no wall cell straddles the
    foot, so each side's light comes from nodes on that side)."""
    if foot is None:
        return np.arange(lo - h, hi + 2.0 * h, h)
    start = foot + 0.5 * h + h * math.floor((lo - h - foot - 0.5 * h) / h)
    return np.arange(start, hi + 2.0 * h, h)


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
