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
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy import sparse
from scipy.linalg import lu_factor, lu_solve

from lightcal.core.footprint import Footprints
from lightcal.core.rid import RID
from lightcal.core.rotations import matrix_from_rotvec
from lightcal.core.scene import Light, Rig, View
from lightcal.core.surroundings import Surface, Surroundings, polygon_irradiance, segments_blocked

__all__ = ["NEAR", "BounceMap", "BounceTerm", "PixelMap"]

#: Copies whose centre lies within NEAR patch sides of a pixel's centre are integrated
#: exactly at it.
NEAR = 3.0

#: The most patches (one side) and wall nodes of a mesh: the maps hold J x 2K numbers.
MAX_PATCHES = 4000
MAX_NODES = 40_000

#: Central differences of the sources: step in m and rad.
_STEP = 1e-6

_UP = np.array([0.0, 0.0, 1.0])

#: The wall grid's spacing is GRID_FRACTION patch_m: measured on the Mitsuba corner
#: (docs/model.md), the wall's cells set the accuracy more than the surfaces' patches.
GRID_FRACTION = 0.5

#: The wall grid reaches MARGIN_M beyond the pixels: wall the beam lights outside the
#: images also lights the surfaces, m.
MARGIN_M = 0.5


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


@dataclass(frozen=True, eq=False)
class PixelMap:
    """How the bounce at N wall points follows from the copies' radiance.

    Attributes:
        interpolate: (N, J) sparse, the bilinear weights of the grid's nodes.
        near: (N, K) sparse, per unit radiance of the copies near each point, their exact
            irradiance there less what the interpolation gives of them.
    """

    interpolate: sparse.csr_matrix
    near: sparse.csr_matrix


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
        self._rho = geo_albedo[self.geometric] / math.pi
        # The surfaces light each other directly and through the wall (the wall's
        # radiance holds their light too: rho_w / pi (e_W + G_WS L)).
        if surroundings.bounces is None:
            through_wall = surroundings.wall_albedo / math.pi * (self.G_SW @ self.G_WS)
            self._lu = lu_factor(
                np.eye(2 * count) - self._rho[:, None] * (self.G_SS + through_wall)
            )
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
    ) -> tuple[np.ndarray, np.ndarray]:
        """(K + J,) the beam's irradiance per unit intensity at the copies' centres and at
        the wall's nodes, and (K + J,) where the light reaches them (its side, no surface
        in between; `visible`, when given, is taken instead)."""
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
        return np.where(visible, f * np.maximum(cos, 0.0) / (r * r), 0.0), visible

    def source_columns(
        self, light_world: np.ndarray, R_world_light: np.ndarray, rid: RID, *, want_grad: bool
    ) -> np.ndarray:
        """(K + J, 1 or 7) the sources and, with want_grad, their derivatives with respect
        to (L_world (3), delta_world (3)), delta_world a left rotation perturbation of
        R_world_light (central differences, the shadows held)."""
        e, visible = self.sources(light_world, R_world_light, rid)
        if not want_grad:
            return e[:, None]
        out = np.empty((e.size, 7))
        out[:, 0] = e
        for c in range(3):
            step = np.zeros(3)
            step[c] = _STEP
            plus = self.sources(light_world + step, R_world_light, rid, visible)[0]
            minus = self.sources(light_world - step, R_world_light, rid, visible)[0]
            out[:, 1 + c] = (plus - minus) / (2.0 * _STEP)
            turn = matrix_from_rotvec(step)
            plus = self.sources(light_world, turn @ R_world_light, rid, visible)[0]
            minus = self.sources(light_world, turn.T @ R_world_light, rid, visible)[0]
            out[:, 4 + c] = (plus - minus) / (2.0 * _STEP)
        return out

    def radiance(self, sources: np.ndarray) -> np.ndarray:
        """(K, c) the copies' radiance per unit intensity of sources (K + J, c): every
        bounce, or the light of paths with at most `surroundings.bounces` reflections
        between the light and the pixel's wall point."""
        K = len(self.centres)
        b = self.surroundings.wall_albedo / math.pi
        n = self.surroundings.bounces
        if n is None:
            rhs = sources[:K] + b * (self.G_SW @ sources[K:])
            return np.asarray(lu_solve(self._lu, self._rho[:, None] * rhs))
        rho = self._rho[:, None]
        surfaces = rho * sources[:K]  # s_1: paths light -> surface
        wall = b * sources[K:]  # w_1: light -> wall
        total = surfaces.copy()
        for _ in range(n - 1):  # s_(m+1) = rho (G_SS s_m + G_SW w_m), w_(m+1) = b G_WS s_m
            surfaces, wall = (
                rho * (self.G_SS @ surfaces + self.G_SW @ wall),
                b * (self.G_WS @ surfaces),
            )
            total += surfaces
        return np.asarray(total)

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
        rows, cols, vals = [], [], []
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
                interpolated = np.einsum(
                    "nc,nc->n", w[p_idx], self.G_WS[idx[p_idx], c_idx[:, None]]
                )
                rows.append(p_idx)
                cols.append(c_idx)
                vals.append(exact * side - interpolated)
        shape = (n, len(self.centres))
        if rows:
            near = sparse.csr_matrix(
                (np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=shape
            )
        else:
            near = sparse.csr_matrix(shape)
        return PixelMap(interpolate, near)

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


#: The last maps built: (surroundings, region, map); a calibration's stages (a first solve
#: on a subset of its pixels, the mirror exclusion, `wall: auto`) share one.
_MAPS: list[tuple[Surroundings, tuple[float, float, float, float], BounceMap]] = []


def _shared_map(
    surroundings: Surroundings, region_xy: tuple[float, float, float, float]
) -> BounceMap:
    """A recent `BounceMap` of the same surroundings whose region holds `region_xy`, or
    a new one (kept with the last three)."""
    x0, x1, y0, y1 = region_xy
    for s, (a0, a1, b0, b1), found in _MAPS:
        if s is surroundings and a0 <= x0 and x1 <= a1 and b0 <= y0 and y1 <= b1:
            return found
    made = BounceMap(surroundings, region_xy)
    _MAPS.append((surroundings, region_xy, made))
    del _MAPS[:-4]
    return made


def _coverage(footprints: Footprints) -> np.ndarray:
    """(N,) sum over each footprint's quads of sensor weight x area: the value of a
    uniform irradiance of 1 (1 for the `radiance` sensor model)."""
    q = footprints.corners_world
    d = np.cross(q[:, :, 2] - q[:, :, 0], q[:, :, 3] - q[:, :, 1])
    area = 0.5 * np.linalg.norm(d, axis=-1)
    return np.nan_to_num(np.einsum("nk,nk->n", footprints.weights, area))


class BounceTerm:
    """The bounce term of a calibration's images: each light's bounce flux per unit
    scale into their pixels, with its derivatives.

    Args:
        surroundings: the surfaces.
        footprints: each image's selected pixels.
    """

    def __init__(self, surroundings: Surroundings, footprints: list[Footprints]) -> None:
        centres = [fp.corners_world.mean(axis=(1, 2)) for fp in footprints]
        known = np.concatenate([c[np.all(np.isfinite(c), axis=1)] for c in centres])
        if known.size == 0:
            known = np.zeros((1, 3))
        lo, hi = known.min(axis=0), known.max(axis=0)
        m = MARGIN_M
        self.map = _shared_map(surroundings, (lo[0] - m, hi[0] + m, lo[1] - m, hi[1] + m))
        self.coverage = [_coverage(fp) for fp in footprints]
        self.pixels = [self.map.pixel_map(np.where(np.isfinite(c), c, lo)) for c in centres]

    @classmethod
    def of(
        cls, surroundings: Surroundings | None, footprints: list[Footprints]
    ) -> BounceTerm | None:
        """The bounce term of `surroundings` (None: none) for images' footprints."""
        return None if surroundings is None else cls(surroundings, footprints)

    def add(
        self, i: int, view: View, light: Light, flux: np.ndarray, grad: np.ndarray | None
    ) -> None:
        """Add image i's bounce to a light's flux (N_i,) and its gradients (N_i, 6) (as
        `render.light_flux` gives them, per unit scale), in place."""
        b = self.flux(i, view, light, want_grad=grad is not None)
        flux += b[:, 0]
        if grad is not None:
            grad += b[:, 1:]

    def values(self, i: int, view: View, rig: Rig) -> np.ndarray:
        """(N_i,) image i's bounce value: the sum over the rig's lights of scale x flux."""
        return np.asarray(
            sum(
                light.scale * self.flux(i, view, light, want_grad=False)[:, 0]
                for light in rig.lights
            )
        )

    def flux(self, i: int, view: View, light: Light, *, want_grad: bool) -> np.ndarray:
        """(N_i, 1 or 7) image i's bounce flux per unit scale (exposure included) and,
        with want_grad, d / d (L_world (3), delta_world (3)) as `render.light_flux`."""
        L_world = light.position_world(view)
        n = len(self.coverage[i])
        if L_world[2] <= 0.0:  # a light on or behind the wall lights nothing
            return np.zeros((n, 7 if want_grad else 1))
        src = self.map.source_columns(
            L_world, light.rotation_world(view), light.rid, want_grad=want_grad
        )
        b = self.map.bounce(self.map.radiance(src), self.pixels[i])
        return b * (view.exposure * self.coverage[i])[:, None]
