"""How the bounce at wall points follows from the surfaces' copies' radiance
(`lightcal.core.bounce.BounceMap`; docs/model.md, "Inter-reflection").

The far copies' light is computed at the wall grid's nodes and interpolated to the points;
the copies within NEAR grid spacings of a point are integrated exactly there.

**One side at a time.** A copy lights only the half-space its normal points to, and its
irradiance at a wall point carries its cosine there, d / r, d the point's distance from the
copy's plane: for a surface standing on the wall it falls to 0 at the surface's foot,
linearly in d. So the copies are interpolated by group (one surface, one side): G_group /
d at the group's nodes on the point's side of its plane (and not across any surface's
foot), their bilinear weights renormalised, times the point's own d, in the cells the
plane or a foot cuts and those with a node within NEAR_PLANE spacings of the plane;
elsewhere the plain bilinear weights (G / d everywhere left the bulk 1-2 % high).
Interpolating across a foot instead (a node behind the surface seeing none of the copies)
made the first bounce 0.5-2 cm from a foot up to 12 % off, high or low with the grid's
alignment.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from scipy import sparse

from lightcal.core.surroundings import Surface

if TYPE_CHECKING:
    from lightcal.core.bounce import BounceMap

__all__ = ["NEAR", "NearPairs", "PixelMap", "pair_irradiance", "pixel_map", "weighted_distance"]

#: Copies whose centre lies within NEAR grid spacings of a pixel's centre are integrated
#: exactly at it.
NEAR = 3.0

#: In a medium, the attenuation of a copy's light at a wall point is weighted over
#: SPLIT x SPLIT parts of the copy (`weighted_distance`).
SPLIT = 8

#: Cells with a node closer than NEAR_PLANE grid spacings to a group's plane interpolate
#: its light as G / d (module docstring); the others plainly.
NEAR_PLANE = 1.0

#: A node within SIDE_TOLERANCE grid spacings of a copy's plane does not interpolate it (its
#: light there is nearly 0 and its quotient by d ill-conditioned).
SIDE_TOLERANCE = 1e-3


def pair_irradiance(points: np.ndarray, polygons: np.ndarray) -> np.ndarray:
    """(n,) Lambert's formula (`surroundings.polygon_irradiance`) for wall points (n, 3)
    (normal +z), each with its own polygon (n, V, 3), per unit radiance."""
    R = polygons - points[:, None, :]
    R1 = np.roll(R, -1, axis=1)
    c = np.cross(R, R1)
    cn = np.sqrt(np.einsum("nvi,nvi->nv", c, c))
    gamma = np.arctan2(cn, np.einsum("nvi,nvi->nv", R, R1))
    with np.errstate(invalid="ignore", divide="ignore"):
        proj = np.where(cn > 1e-300, c[..., 2] / cn, 0.0)
    return np.asarray(0.5 * np.einsum("nv,nv->n", gamma, proj))


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
            e = np.abs(pair_irradiance(points_world, part))
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
        nodes: (P, 4) the point's interpolating nodes; weights: (P, 4) their weights for
            the copy's group (module docstring).
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
        interpolate: (N, G J) sparse: per group (module docstring) the weights of the
            grid's J nodes, the quotient by the nodes' distance from the group's plane and
            the product with the point's folded in.
        groups: the G groups' copy ranges (start, stop).
        near: (N, K) sparse, per unit radiance of the copies near each point, their exact
            irradiance there less what the interpolation gives of them (in air).
        pairs: the near pairs (to make `near` in a medium).
    """

    interpolate: sparse.csr_matrix
    groups: tuple[tuple[int, int], ...]
    near: sparse.csr_matrix
    pairs: NearPairs

    def gather(self, G_WS: np.ndarray, radiance: np.ndarray) -> np.ndarray:
        """(N, c) the interpolated light at the points of the copies' radiance (K, c)
        through node transfers G_WS (J, K) (or their slopes with respect to c)."""
        at_nodes = np.concatenate([G_WS[:, a:b] @ radiance[a:b] for a, b in self.groups])
        return np.asarray(self.interpolate @ at_nodes)


def _clear_of_feet(
    surfaces: tuple[Surface, ...], points: np.ndarray, nodes: np.ndarray
) -> np.ndarray:
    """(N, 4) whether the segment from each point (N, 3) to each of its nodes (N, 4, 3),
    on the wall, crosses no surface's foot (where the surface meets the wall)."""
    clear = np.ones(nodes.shape[:2], dtype=bool)
    for s in surfaces:
        foot = s.corners_world[np.abs(s.corners_world[:, 2]) <= 1e-9, :2]
        if len(foot) < 2:
            continue
        a, d = foot[0], foot[1] - foot[0]
        across = np.array([-d[1], d[0]])
        side_point = (points[:, :2] - a) @ across
        side_node = (nodes[..., :2] - a) @ across
        crossing = side_point[:, None] * side_node < 0.0
        t = side_point[:, None] / np.where(crossing, side_point[:, None] - side_node, 1.0)
        hit = points[:, None, :2] + t[..., None] * (nodes[..., :2] - points[:, None, :2])
        along = (hit - a) @ d / (d @ d)
        clear &= ~(crossing & (along >= 0.0) & (along <= 1.0))
    return clear


def pixel_map(bm: BounceMap, points_world: np.ndarray) -> PixelMap:
    """The `PixelMap` of wall points (N, 3) (finite, inside the map's region)."""
    h = bm.h
    n = len(points_world)
    fx = (points_world[:, 0] - bm.x[0]) / h
    fy = (points_world[:, 1] - bm.y[0]) / h
    i = np.clip(np.floor(fx).astype(np.int64), 0, bm.x.size - 2)
    j = np.clip(np.floor(fy).astype(np.int64), 0, bm.y.size - 2)
    a = np.clip(fx - i, 0.0, 1.0)
    b = np.clip(fy - j, 0.0, 1.0)
    ny = bm.y.size
    idx = np.stack([i * ny + j, (i + 1) * ny + j, i * ny + j + 1, (i + 1) * ny + j + 1], 1)
    w = np.stack([(1 - a) * (1 - b), a * (1 - b), (1 - a) * b, a * b], axis=1)
    surfaces = bm.surroundings.surfaces
    nodes = bm.nodes[idx]
    clear = _clear_of_feet(surfaces, points_world, nodes)
    J = len(bm.nodes)
    group_of = np.empty(len(bm.centres), dtype=np.int64)
    weights = np.zeros((len(bm.groups), n, 4))
    for g, (start, stop, k, sign) in enumerate(bm.groups):
        group_of[start:stop] = g
        normal = sign * surfaces[k].normal_world
        d_node = (nodes - surfaces[k].corner_world) @ normal
        d_point = (points_world - surfaces[k].corner_world) @ normal
        keep = clear & (d_node > SIDE_TOLERANCE * h)
        kept = w * keep
        total = kept.sum(axis=1)
        ok = (total > 0.0) & (d_point > 0.0)
        scale = np.where(ok, d_point / np.where(ok, total, 1.0), 0.0)
        one_sided = kept * scale[:, None] / np.where(keep, d_node, 1.0)
        near_plane = np.where(keep, d_node, np.inf).min(axis=1) < NEAR_PLANE * h
        plain = keep.all(axis=1) & ~near_plane
        weights[g] = np.where(plain[:, None], w, one_sided)
    columns = idx[None, :, :] + J * np.arange(len(bm.groups))[:, None, None]
    rows = np.broadcast_to(np.arange(n)[None, :, None], columns.shape)
    interpolate = sparse.csr_matrix(
        (weights.ravel(), (rows.ravel(), columns.ravel())), shape=(n, len(bm.groups) * J)
    )
    interpolate.eliminate_zeros()
    parts: list[tuple[np.ndarray, ...]] = []
    reach = NEAR * h
    for k in range(len(surfaces)):
        mine = np.nonzero(bm.owner == k)[0]
        lo = bm.centres[mine].min(axis=0) - reach
        hi = bm.centres[mine].max(axis=0) + reach
        close = np.nonzero(np.all((points_world >= lo) & (points_world <= hi), axis=1))[0]
        for start in range(0, close.size, 256):
            pts = close[start : start + 256]
            gap = points_world[pts, None, :] - bm.centres[None, mine, :]
            pi, ki = np.nonzero(np.einsum("pki,pki->pk", gap, gap) <= reach * reach)
            if pi.size == 0:
                continue
            p_idx, c_idx = pts[pi], mine[ki]
            P = points_world[p_idx]
            exact = np.abs(pair_irradiance(P, bm.quads[c_idx]))
            side = np.einsum("ni,ni->n", P - bm.centres[c_idx], bm.normals[c_idx]) > 0.0
            pair_weights = weights[group_of[c_idx], p_idx]
            parts.append((p_idx, c_idx, exact * side, P, bm.quads[c_idx], idx[p_idx], pair_weights))
    if parts:
        pairs = NearPairs(*(np.concatenate(a) for a in zip(*parts, strict=True)))
    else:
        none = np.zeros(0, dtype=np.int64)
        empty = np.zeros((0, 3))
        pairs = NearPairs(none, none, np.zeros(0), empty, bm.quads[:0], idx[:0], w[:0])
    near = pairs.near(bm.G_WS, (n, len(bm.centres)))
    groups = tuple((start, stop) for start, stop, _, _ in bm.groups)
    return PixelMap(interpolate, groups, near, pairs)
