"""Surfaces around the wall (a ceiling, a side wall, a shelf) that send light back to it.

The beam and the light the wall reflects reach such surfaces, and part of it returns to
the wall: inter-reflection, a bounce term added to every pixel (docs/model.md,
"Inter-reflection"; the radiosity itself is `lightcal.core.bounce`). A surface is a
planar rectangle in the world frame (metres; the wall is z = 0, the cameras at z > 0),
corner + s edge_u + t edge_v for s, t in [0, 1], Lambertian of albedo rho on both sides.
The wall is Lambertian of albedo rho_w for this term (its model B applies to the direct
light only).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

__all__ = [
    "MAX_SURFACES",
    "Surface",
    "Surroundings",
    "polygon_irradiance",
    "screened_footprints",
    "segments_blocked",
]

#: The most surfaces a project may declare.
MAX_SURFACES = 16

#: The shortest edge, m.
MIN_EDGE_M = 1e-3

#: The longest edge, m.
MAX_EDGE_M = 100.0

#: A point closer than this to the wall's plane is in it, m.
PLANE_EPS_M = 1e-9

#: The mesh's patch side, m: default and range.
DEFAULT_PATCH_M = 0.1
PATCH_RANGE_M = (0.01, 0.5)


@dataclass(frozen=True, eq=False)
class Surface:
    """A planar rectangle near the wall: corner + s edge_u + t edge_v, s, t in [0, 1].

    Args:
        corner_world: (3,) one corner, world frame, m.
        edge_u_world, edge_v_world: (3,) its two edges from that corner, m.
        albedo: its diffuse reflectance (both sides), in [0, 1).
        name: how messages name it.

    Raises:
        ValueError: a vector that is not 3 finite numbers, an edge shorter than 1 mm or
            longer than 100 m, parallel edges, a corner behind the wall (z < 0), a
            surface in the wall's plane, an albedo outside [0, 1).
    """

    corner_world: np.ndarray
    edge_u_world: np.ndarray
    edge_v_world: np.ndarray
    albedo: float
    name: str = "surface"

    def __post_init__(self) -> None:
        for label in ("corner_world", "edge_u_world", "edge_v_world"):
            v = np.asarray(getattr(self, label), dtype=np.float64)
            if v.shape != (3,) or not np.all(np.isfinite(v)):
                raise ValueError(
                    f"{self.name}: {label}: expected 3 finite numbers, got {v.tolist()}"
                )
            object.__setattr__(self, label, v)
        a = float(self.albedo)
        if not (math.isfinite(a) and 0.0 <= a < 1.0):
            raise ValueError(f"{self.name}: albedo: expected a value in [0, 1), got {a:g}")
        object.__setattr__(self, "albedo", a)
        lengths = [float(np.linalg.norm(e)) for e in (self.edge_u_world, self.edge_v_world)]
        if not all(MIN_EDGE_M <= n <= MAX_EDGE_M for n in lengths):
            raise ValueError(
                f"{self.name}: expected edges of {1e3 * MIN_EDGE_M:g} mm to {MAX_EDGE_M:g} m, "
                f"got {lengths[0]:g} and {lengths[1]:g} m"
            )
        if self.area_m2 < 1e-3 * lengths[0] * lengths[1]:
            raise ValueError(f"{self.name}: expected two edges that are not parallel")
        z = self.corners_world[:, 2]
        if z.min() < -PLANE_EPS_M:
            raise ValueError(
                f"{self.name}: reaches behind the wall (z = {z.min():.4g} m); expected "
                "z >= 0 everywhere (the wall is the plane z = 0, the cameras are at z > 0)"
            )
        if z.max() <= PLANE_EPS_M:
            raise ValueError(
                f"{self.name}: lies in the wall's plane z = 0 (it would overlap the wall); "
                "expected a surface in front of it"
            )

    @property
    def corners_world(self) -> np.ndarray:
        """(4, 3) corner, corner + u, corner + u + v, corner + v, m."""
        c, u, v = self.corner_world, self.edge_u_world, self.edge_v_world
        return np.stack([c, c + u, c + u + v, c + v])

    @property
    def normal_world(self) -> np.ndarray:
        """(3,) the unit normal u x v / |u x v|."""
        n = np.cross(self.edge_u_world, self.edge_v_world)
        return n / np.linalg.norm(n)

    @property
    def area_m2(self) -> float:
        """Its area, m^2."""
        return float(np.linalg.norm(np.cross(self.edge_u_world, self.edge_v_world)))

    def contains(self, offsets: np.ndarray) -> np.ndarray:
        """(n,) whether points of its plane, given as offsets (n, 3) from its corner, lie
        strictly inside it."""
        u, v = self.edge_u_world, self.edge_v_world
        G = np.array([[u @ u, u @ v], [u @ v, v @ v]])
        st = np.linalg.solve(G, np.stack([offsets @ u, offsets @ v]))
        return np.asarray(np.all((st > 0.0) & (st < 1.0), axis=0))

    def describe(self) -> dict:
        """Its fields for files (`corner_m`, `edge_u_m`, `edge_v_m`, `albedo`, `name`)."""
        return {
            "name": self.name,
            "corner_m": self.corner_world.tolist(),
            "edge_u_m": self.edge_u_world.tolist(),
            "edge_v_m": self.edge_v_world.tolist(),
            "albedo": self.albedo,
        }


@dataclass(frozen=True, eq=False)
class Surroundings:
    """The surfaces around the wall and what the bounce term needs of the wall.

    Args:
        surfaces: the surfaces (1 to MAX_SURFACES).
        wall_albedo: rho_w, the wall's diffuse reflectance, in (0, 1).
        patch_m: the mesh's largest patch side (the wall grid's spacing is half of it), m
            (`lightcal.core.bounce`).
        bounces: None for every bounce (a room); n to keep only the light of paths with at
            most n reflections between the light and the wall point a pixel sees (n = 1:
            off a surface; 3: what a path tracer of `max_depth` 5 renders).
        estimate_albedo: the surfaces (indices) whose albedo the calibration estimates,
            from their declared albedo.
    """

    surfaces: tuple[Surface, ...]
    wall_albedo: float = 0.8
    patch_m: float = DEFAULT_PATCH_M
    bounces: int | None = None
    estimate_albedo: tuple[int, ...] = ()

    def __post_init__(self) -> None:
        object.__setattr__(self, "surfaces", tuple(self.surfaces))
        n = self.bounces
        if n is not None and (isinstance(n, bool) or not isinstance(n, int) or not 1 <= n <= 50):
            raise ValueError(f"surroundings: bounces: expected 1 to 50 or None (all), got {n!r}")
        if not 1 <= len(self.surfaces) <= MAX_SURFACES:
            raise ValueError(
                f"surroundings: expected 1 to {MAX_SURFACES} surfaces, got {len(self.surfaces)}"
            )
        w = float(self.wall_albedo)
        if not (math.isfinite(w) and 0.0 < w < 1.0):
            raise ValueError(f"surroundings: wall_albedo: expected a value in (0, 1), got {w:g}")
        h = float(self.patch_m)
        lo, hi = PATCH_RANGE_M
        if not (math.isfinite(h) and lo <= h <= hi):
            raise ValueError(f"surroundings: patch_m: expected {lo:g} to {hi:g} m, got {h:g}")
        object.__setattr__(self, "wall_albedo", w)
        object.__setattr__(self, "patch_m", h)
        chosen = tuple(int(k) for k in self.estimate_albedo)
        if len(set(chosen)) != len(chosen) or any(not 0 <= k < len(self.surfaces) for k in chosen):
            raise ValueError(
                f"surroundings: estimate_albedo: expected distinct surfaces among "
                f"0-{len(self.surfaces) - 1}, got {list(chosen)}"
            )
        object.__setattr__(self, "estimate_albedo", chosen)

    def albedos(self) -> np.ndarray:
        """(S,) the surfaces' albedos."""
        return np.array([surface.albedo for surface in self.surfaces])

    def with_albedos(self, albedos: np.ndarray) -> Surroundings:
        """The same surroundings, the surfaces' albedos (S,) replaced."""
        surfaces = tuple(
            dataclasses.replace(surface, albedo=float(a))
            for surface, a in zip(self.surfaces, albedos, strict=True)
        )
        return dataclasses.replace(self, surfaces=surfaces)

    def describe(self) -> dict:
        """Its fields for files."""
        return {
            "surfaces": [s.describe() for s in self.surfaces],
            "wall_albedo": self.wall_albedo,
            "patch_m": self.patch_m,
            "bounces": self.bounces,
        }


def polygon_irradiance(
    points: np.ndarray, normals: np.ndarray, polygons: np.ndarray, *, chunk: int = 1 << 17
) -> np.ndarray:
    """(P, K) the irradiance at points (P, 3) with unit normals (P, 3) from polygons
    (K, V, 3) of unit radiance (Lambert's formula, exact for a uniform polygon):

        E = (1/2) sum_i gamma_i n . c_i,

    gamma_i the angle edge i subtends from the point, c_i the unit normal of the plane
    through the point and the edge, (R_i x R_(i+1)) / |R_i x R_(i+1)|, R_i = vertex i -
    point. Signed: positive where the polygon's right-hand normal (of its vertex order)
    points away from the point. An edge through the point adds 0.
    """
    P, K, V = points.shape[0], polygons.shape[0], polygons.shape[1]
    out = np.empty((P, K))
    rows = max(1, chunk // max(1, K * V))
    for a in range(0, P, rows):
        b = min(P, a + rows)
        R = polygons[None, :, :, :] - points[a:b, None, None, :]  # (p, K, V, 3)
        R1 = np.roll(R, -1, axis=2)
        c = np.cross(R, R1)
        cn = np.sqrt(np.einsum("pkvi,pkvi->pkv", c, c))
        gamma = np.arctan2(cn, np.einsum("pkvi,pkvi->pkv", R, R1))
        with np.errstate(invalid="ignore", divide="ignore"):
            proj = np.einsum("pkvi,pi->pkv", c, normals[a:b]) / cn
        proj[~(cn > 1e-300)] = 0.0
        out[a:b] = 0.5 * np.einsum("pkv,pkv->pk", gamma, proj)
    return out


def segments_blocked(
    surfaces: tuple[Surface, ...],
    a: np.ndarray,
    a_owner: np.ndarray,
    b: np.ndarray,
    b_owner: np.ndarray,
) -> np.ndarray:
    """(len(a), len(b)) whether the segment a_i -> b_j (points (n, 3), world frame)
    crosses a surface that owns neither end (owners: indices into `surfaces`, -1 for a
    point of none)."""
    out = np.zeros((len(a), len(b)), dtype=bool)
    for k, s in enumerate(surfaces):
        n = np.cross(s.edge_u_world, s.edge_v_world)
        da = (a - s.corner_world) @ n
        db = (b - s.corner_world) @ n
        cand = (da[:, None] * db[None, :] < 0.0) & (a_owner[:, None] != k) & (b_owner[None, :] != k)
        ia, ib = np.nonzero(cand)
        if ia.size == 0:
            continue
        t = da[ia] / (da[ia] - db[ib])
        hit = a[ia] + t[:, None] * (b[ib] - a[ia]) - s.corner_world
        out[ia, ib] |= s.contains(hit)
    return out


def screened_footprints(
    surroundings: Surroundings, eye_world: np.ndarray, corners_world: np.ndarray
) -> np.ndarray:
    """(N,) the pixels a surface hides in part from a point (3,): a corner of their footprint
    (corners (N, K, 4, 3), world frame, m; NaN off the wall) behind a surface as the point
    sees it. From the camera centre: the pixels that see a surface, or straddle its foot;
    from a light: the pixels in a surface's shadow, or on its edge. The model renders the
    wall lit by the beam, not the surfaces nor their shadows, so such a pixel is not
    modelled (docs/model.md, "Inter-reflection")."""
    n = corners_world.shape[0]
    points = corners_world.reshape(-1, 3)
    finite = np.all(np.isfinite(points), axis=1)
    hidden = np.zeros(len(points), dtype=bool)
    hidden[finite] = segments_blocked(
        surroundings.surfaces,
        np.asarray(eye_world, dtype=np.float64)[None, :],
        np.array([-1]),
        points[finite],
        np.full(int(finite.sum()), -1),
    )[0]
    return np.asarray(hidden.reshape(n, -1).any(axis=1))
