"""The wall's albedo map, estimated with the light by variable projection.

A wall is rarely evenly white: paint thins, sheets of paper differ, a seafloor is
textured. Its albedo relative to its mean is a field a(x, y) on the wall (world x, y,
metres), the same in every view, and every pixel's value above the offset is multiplied
by a at its footprint's centre (the light's terms and the room light's, which the wall
reflects alike; not the offset). The field is bilinear on a regular grid of nodes
covering the selected pixels' footprints (`AlbedoGrid`), a = 1 + sum_k w_k delta_k
(`AlbedoGrid.basis`: a sparse (N, K) matrix B, four weights a row; 0 off the grid, where
a = 1).

Given the other parameters x the values are linear in delta, so delta is not a solver
parameter: at every evaluation it is the exact minimiser of

    sum_pixels (r0 - u B delta)^2 + |Gamma delta|^2,

r0 the weighted residuals at delta = 0, u = (value above the offset) / sigma, and Gamma
the prior (`AlbedoGrid.regulariser`): each node's delta / `variation` (the albedo's
spread about its mean) and the second differences along x and y / `smoothness` (how much
the albedo may bend from one node to the next). With M = sum B_u^T B_u + Gamma^T Gamma
(B_u = diag(u) B, sparse K x K) the solve is one sparse LU per evaluation
(`project_albedo`). The solver then sees the variable projection of the problem
(Golub and Pereyra 1973; Kaufman 1975's Jacobian): each image's residuals at delta*
and its Jacobian columns scaled by a (except the offset's), minus their projection on
the albedo, and a block of prior rows [Gamma M^-1 C | Gamma delta*], C = sum B_u^T J.
Its cost is the joint problem's minimum over delta, its Gauss-Newton matrix the Schur
complement of the joint one: the covariance of x has the albedo's uncertainty
marginalised, not fixed.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, replace
from typing import TypeVar, cast

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from lightcal.core.medium import Medium

__all__ = [
    "ALBEDO_MAX_NODES",
    "AlbedoGrid",
    "AlbedoMap",
    "AlbedoMapOptions",
    "AlbedoProjection",
    "with_albedo",
]

Values = TypeVar("Values", bound=np.ndarray)

ALBEDO_MAX_NODES = 250_000
"""At most this many grid nodes (a 5 x 5 m wall at 1 cm): the sparse LU's fill beyond."""


@dataclass(frozen=True)
class AlbedoMapOptions:
    """How the albedo map is estimated (the project's `wall.albedo_map`).

    Attributes:
        spacing_m: the grid's node spacing, metres.
        variation: the prior 1-sigma of the albedo about its mean (relative).
        smoothness: the prior 1-sigma of a second difference of the albedo between three
            neighbouring nodes (relative).
    """

    spacing_m: float = 0.025
    variation: float = 0.3
    smoothness: float = 0.05

    def __post_init__(self) -> None:
        for name, value, high in (
            ("spacing_m", self.spacing_m, 1.0),
            ("variation", self.variation, 10.0),
            ("smoothness", self.smoothness, 10.0),
        ):
            if isinstance(value, bool) or not (
                isinstance(value, int | float) and math.isfinite(value) and 0.0 < value <= high
            ):
                raise ValueError(
                    f"albedo map: {name}: expected a value in (0, {high:g}], got {value!r}"
                )


@dataclass(frozen=True, eq=False)
class AlbedoGrid:
    """A regular grid of nodes on the wall z = 0.

    Attributes:
        origin_xy_m: (2,) world (x, y) of node (0, 0), metres.
        spacing_m: the distance between neighbouring nodes, metres.
        shape: (ny, nx) the nodes along y and x; node (j, i) is number j nx + i.
    """

    origin_xy_m: np.ndarray
    spacing_m: float
    shape: tuple[int, int]

    @classmethod
    def covering(cls, points_xy_m: np.ndarray, spacing_m: float) -> AlbedoGrid:
        """The grid whose cells cover `points_xy_m` (N, 2) with one cell to spare."""
        pts = np.asarray(points_xy_m, dtype=np.float64)
        if pts.ndim != 2 or pts.shape[1] != 2 or len(pts) == 0:
            raise ValueError(f"albedo map: expected (N, 2) wall points, N > 0, got {pts.shape}")
        if not np.all(np.isfinite(pts)):
            raise ValueError("albedo map: expected finite wall points, got NaN or inf")
        low = pts.min(axis=0) - spacing_m
        high = pts.max(axis=0) + spacing_m
        nx, ny = (np.ceil((high - low) / spacing_m - 1e-9).astype(int) + 1).tolist()
        if nx * ny > ALBEDO_MAX_NODES:
            raise ValueError(
                f"albedo map: {nx} x {ny} nodes at {spacing_m * 1000:g} mm cover the "
                f"{high[0] - low[0]:.2f} x {high[1] - low[1]:.2f} m the pixels see; expected "
                f"at most {ALBEDO_MAX_NODES} (a larger spacing_mm)"
            )
        return cls(low, float(spacing_m), (int(ny), int(nx)))

    @property
    def size(self) -> int:
        """K, the number of nodes."""
        return self.shape[0] * self.shape[1]

    def node_xy(self) -> np.ndarray:
        """(K, 2) the nodes' world (x, y), metres, in node order."""
        ny, nx = self.shape
        j, i = np.mgrid[0:ny, 0:nx]
        return self.origin_xy_m + self.spacing_m * np.stack([i.ravel(), j.ravel()], axis=1)

    def basis(self, points_xy_m: np.ndarray) -> sp.csr_matrix:
        """B (N, K): the bilinear weights of each point (N, 2) on its cell's four nodes
        (a row of zeros for a point off the grid or not finite)."""
        pts = np.asarray(points_xy_m, dtype=np.float64).reshape(-1, 2)
        ny, nx = self.shape
        f = (pts - self.origin_xy_m) / self.spacing_m
        inside = np.all(np.isfinite(f), axis=1)
        inside &= (f[:, 0] >= 0) & (f[:, 0] <= nx - 1) & (f[:, 1] >= 0) & (f[:, 1] <= ny - 1)
        f = np.where(inside[:, None], f, 0.0)
        cell = np.minimum(np.floor(f).astype(np.int64), [nx - 2, ny - 2])
        t = f - cell
        ix = cell[:, :1] + np.array([0, 1, 0, 1])
        iy = cell[:, 1:] + np.array([0, 0, 1, 1])
        tx, ty = t[:, :1], t[:, 1:]
        w = np.concatenate([(1 - tx) * (1 - ty), tx * (1 - ty), (1 - tx) * ty, tx * ty], axis=1)
        w *= inside[:, None]
        rows = np.repeat(np.arange(len(pts)), 4)
        return sp.csr_matrix(
            (w.ravel(), (rows, (iy * nx + ix).ravel())), shape=(len(pts), self.size)
        )

    def regulariser(self, options: AlbedoMapOptions) -> sp.csr_matrix:
        """Gamma (K + second differences, K): the prior's rows (module docstring)."""
        ny, nx = self.shape
        rows = [sp.identity(self.size, format="csr") / options.variation]
        if nx >= 3:
            rows.append(sp.kron(sp.identity(ny), _second_differences(nx)) / options.smoothness)
        if ny >= 3:
            rows.append(sp.kron(_second_differences(ny), sp.identity(nx)) / options.smoothness)
        return sp.vstack(rows).tocsr()


def _second_differences(n: int) -> sp.csr_matrix:
    """(n - 2, n) the operator d_k = v_k - 2 v_(k+1) + v_(k+2)."""
    ones = np.ones(n - 2)
    return sp.diags([ones, -2.0 * ones, ones], [0, 1, 2], shape=(n - 2, n), format="csr")


@dataclass(frozen=True, eq=False)
class AlbedoMap:
    """An estimated albedo map: a = 1 + B delta (module docstring).

    Attributes:
        grid: its nodes.
        delta: (K,) each node's albedo minus 1.
        weight: (K,) the data's weight on each node (the diagonal of sum B_u^T B_u):
            0 where no selected pixel's footprint is, where delta is the prior's.
    """

    grid: AlbedoGrid
    delta: np.ndarray
    weight: np.ndarray

    def factor(self, points_xy_m: np.ndarray) -> np.ndarray:
        """(N,) a at wall points (N, 2) (1 off the grid)."""
        return 1.0 + self.grid.basis(points_xy_m) @ self.delta

    def image(self) -> np.ndarray:
        """(ny, nx) the albedo at the nodes, NaN where no pixel saw the wall."""
        a = 1.0 + self.delta
        return np.where(self.weight > 0.0, a, np.nan).reshape(self.grid.shape)

    def seen_range(self) -> tuple[float, float]:
        """(min, max) of the albedo over the nodes the pixels saw."""
        a = 1.0 + self.delta[self.weight > 0.0]
        return (float(a.min()), float(a.max())) if a.size else (1.0, 1.0)


class AlbedoProjection:
    """The albedo's variable projection over a fixed set of images' pixels.

    Args:
        grid: the nodes.
        bases: per image its B (N_i, K) (`AlbedoGrid.basis` of its footprints' centres).
        options: the prior.
    """

    def __init__(
        self, grid: AlbedoGrid, bases: list[sp.csr_matrix], options: AlbedoMapOptions
    ) -> None:
        self.grid = grid
        self.bases = bases
        self.gamma = grid.regulariser(options)
        self._gamma_gram = (self.gamma.T @ self.gamma).tocsc()

    @classmethod
    def over(cls, centers_xy_m: list[np.ndarray], options: AlbedoMapOptions) -> AlbedoProjection:
        """The projection over images whose pixels' footprint centres are
        `centers_xy_m` (per image (N_i, 2), world x, y), on the grid covering them."""
        grid = AlbedoGrid.covering(np.concatenate(centers_xy_m), options.spacing_m)
        return cls(grid, [grid.basis(c) for c in centers_xy_m], options)

    def factor(self, image: int, albedo: AlbedoMap) -> np.ndarray:
        """(N_i,) the albedo `albedo` at image `image`'s pixels."""
        return 1.0 + self.bases[image] @ albedo.delta

    def project(
        self,
        systems: list[np.ndarray],
        scaled_values: list[np.ndarray],
        offset_column: int,
        veils: list[np.ndarray | None] | None = None,
    ) -> tuple[AlbedoMap, list[np.ndarray], np.ndarray]:
        """Project the albedo out of the images' systems, in place.

        Args:
            systems: per image [J_i r_i] (N_i, n + 1) at delta = 0 (J = d r / d x).
            scaled_values: per image u_i (N_i,), its values above the offset over sigma
                that the wall reflects (the water's veil not in them).
            offset_column: the offset's column (its derivative is not scaled by a), or -1.
            veils: per image None or the part of [J_i r_i] (N_i, n + 1) that is the
                water's veil, which the albedo does not scale (default: none).

        Returns:
            (the map at delta*, per image a_i (N_i,), the prior block (rows, n + 1)).
        """
        n = systems[0].shape[1] - 1 if systems else 0
        weighted = [sp.diags(u) @ B for u, B in zip(scaled_values, self.bases, strict=True)]
        gram = self._gamma_gram.copy()
        rhs = np.zeros(self.grid.size)
        weight = np.zeros(self.grid.size)
        for Bu, A in zip(weighted, systems, strict=True):
            gram = gram + (Bu.T @ Bu)
            rhs += Bu.T @ A[:, n]
            weight += np.asarray(Bu.multiply(Bu).sum(axis=0)).ravel()
        lu = spla.splu(gram.tocsc())
        delta = lu.solve(rhs)
        scaled = [c for c in range(n) if c != offset_column]
        factors = []
        cross = np.zeros((self.grid.size, n))
        for B, Bu, A, veil in zip(
            self.bases, weighted, systems, veils or [None] * len(systems), strict=True
        ):
            a = 1.0 + B @ delta
            A[:, scaled] *= a[:, None]
            if veil is not None:  # a (J - J_veil) + J_veil
                A[:, scaled] -= (a - 1.0)[:, None] * veil[:, scaled]
            A[:, n] -= Bu @ delta
            cross += Bu.T @ A[:, :n]
            factors.append(a)
        along = lu.solve(cross) if n else cross  # M^-1 C (K, n)
        for Bu, A in zip(weighted, systems, strict=True):
            A[:, :n] -= Bu @ along
        prior = np.asfortranarray(np.column_stack([self.gamma @ along, self.gamma @ delta]))
        return AlbedoMap(self.grid, delta, weight), factors, prior


def with_albedo(render: Callable[[Medium], Values], medium: Medium, albedo: np.ndarray) -> Values:
    """render(medium), values above the offset (any shape; a masked array stays one),
    with the wall's light times `albedo` (its shape): the water's veil, which the wall
    does not reflect, is rendered apart (render(medium without it): twice the work) and
    left as it is."""
    values = render(medium)
    if not medium.scatters:
        return cast(Values, values * albedo)
    wall_values = render(replace(medium, backscatter_per_m=0.0))
    return cast(Values, values + (albedo - 1.0) * wall_values)
