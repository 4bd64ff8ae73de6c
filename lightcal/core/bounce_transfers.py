"""The bounce term's transfers at one attenuation of the medium, and the copies' radiance
(`lightcal.core.bounce`; docs/model.md, "Inter-reflection").

K copies (a surface patch, one side) and J wall nodes exchange light through

- G_SS (K, K): the irradiance at copy c per unit radiance of copy d,
- G_SW (K, J): at copy c per unit radiance of wall cell j,
- G_WS (J, K): at node j per unit radiance of copy c.

In air they are `BounceMap`'s. In a homogeneous absorbing medium of attenuation c (1/m)
each pair's transfer is attenuated over the distance r between the points the kernel
uses (copy centre to copy centre, copy centre to wall node): G_ab(c) = G_ab exp(-c R_ab)
elementwise, whose derivative is D_ab = d G_ab(c) / dc = -R_ab G_ab(c) (`attenuated`,
`slopes`). The copies' radiance solves L = rho (S + G_SS L + b G_SW (W + G_WS L)), b =
rho_w / pi, S (K,) and W (J,) the beam's irradiance, or its Neumann series cut after n
reflections (`Transfers.radiance`); `radiance_slope` is its derivative with respect to c,
`albedo_slopes` with respect to surfaces' albedos.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.linalg import lu_factor, lu_solve
from scipy.spatial.distance import cdist

__all__ = [
    "TransferSlopes",
    "Transfers",
    "albedo_slopes",
    "attenuated",
    "pair_distances",
    "radiance_slope",
    "slopes",
]


@dataclass(frozen=True, eq=False)
class Transfers:
    """The transfers among K copies and J wall nodes at one attenuation.

    Attributes:
        G_SS: (K, K), G_SW: (K, J), G_WS: (J, K): see the module docstring.
        rho: (K,) each copy's albedo / pi.
        wall_albedo: rho_w, the wall's albedo.
        bounces: None for every bounce, or n reflections (the Neumann series cut).
        lu: with every bounce, the LU factors of I - rho (G_SS + wall_rho G_SW G_WS);
            None otherwise.
    """

    G_SS: np.ndarray
    G_SW: np.ndarray
    G_WS: np.ndarray
    rho: np.ndarray
    wall_albedo: float
    bounces: int | None
    lu: tuple[np.ndarray, np.ndarray] | None

    @classmethod
    def build(
        cls,
        G_SS: np.ndarray,
        G_SW: np.ndarray,
        G_WS: np.ndarray,
        rho: np.ndarray,
        wall_albedo: float,
        bounces: int | None,
    ) -> Transfers:
        """The transfers, with the LU factors when every bounce is kept (a (K, J) x (J, K)
        product and a K x K factorisation)."""
        lu = None
        if bounces is None:
            # The surfaces light each other directly and through the wall (the wall's
            # radiance holds their light too: rho_w / pi (e_W + G_WS L)).
            through_wall = wall_albedo / math.pi * (G_SW @ G_WS)
            lu = lu_factor(np.eye(len(rho)) - rho[:, None] * (G_SS + through_wall))
        return cls(G_SS, G_SW, G_WS, rho, wall_albedo, bounces, lu)

    def radiance(self, sources: np.ndarray) -> np.ndarray:
        """(K, c) the copies' radiance per unit intensity of sources (K + J, c): every
        bounce, or the light of paths with at most `bounces` reflections between the
        light and the pixel's wall point."""
        K = len(self.rho)
        b = self.wall_albedo / math.pi
        if self.lu is not None:
            rhs = sources[:K] + b * (self.G_SW @ sources[K:])
            return np.asarray(lu_solve(self.lu, self.rho[:, None] * rhs))
        assert self.bounces is not None
        rho = self.rho[:, None]
        surfaces = rho * sources[:K]  # s_1: paths light -> surface
        wall = b * sources[K:]  # w_1: light -> wall
        total = surfaces.copy()
        for _ in range(
            self.bounces - 1
        ):  # s_(m+1) = rho (G_SS s_m + G_SW w_m), w_(m+1) = b G_WS s_m
            surfaces, wall = (
                rho * (self.G_SS @ surfaces + self.G_SW @ wall),
                b * (self.G_WS @ surfaces),
            )
            total += surfaces
        return np.asarray(total)


@dataclass(frozen=True, eq=False)
class TransferSlopes:
    """The transfers' derivatives with respect to the attenuation c, D = -R G(c).

    Attributes:
        D_SS: (K, K), D_SW: (K, J), D_WS: (J, K), per 1/m.
    """

    D_SS: np.ndarray
    D_SW: np.ndarray
    D_WS: np.ndarray


def pair_distances(centres: np.ndarray, nodes: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(K, K) the distances between copy centres (K, 3) and (K, J) from the copies'
    centres to the wall nodes (J, 3), m."""
    return cdist(centres, centres), cdist(centres, nodes)


def attenuated(
    air: Transfers, R_SS: np.ndarray, R_SW: np.ndarray, attenuation_per_m: float
) -> Transfers:
    """The transfers `air` in a medium of attenuation c (1/m): each times exp(-c r), r its
    pair's distance (R_SS (K, K), R_SW (K, J), m; G_WS takes R_SW's transpose)."""
    c = attenuation_per_m
    E_SW = np.exp(-c * R_SW)
    return Transfers.build(
        air.G_SS * np.exp(-c * R_SS),
        air.G_SW * E_SW,
        air.G_WS * E_SW.T,
        air.rho,
        air.wall_albedo,
        air.bounces,
    )


def slopes(at_c: Transfers, R_SS: np.ndarray, R_SW: np.ndarray) -> TransferSlopes:
    """d G(c) / dc = -R G(c) of the transfers at c (distances as `attenuated`)."""
    return TransferSlopes(-R_SS * at_c.G_SS, -R_SW * at_c.G_SW, -R_SW.T * at_c.G_WS)


def radiance_slope(
    t: Transfers,
    d: TransferSlopes,
    sources: np.ndarray,
    sources_dc: np.ndarray,
    radiance: np.ndarray,
) -> np.ndarray:
    """(K,) d L / dc: the derivative of the copies' radiance L (K,) (`Transfers.radiance`
    of sources (K + J,)) with respect to c, the sources' own derivative (K + J,) given.

    Every bounce: M L = rho (S + b G_SW W) with M = I - rho (G_SS + b G_SW G_WS), so
    M L' = rho (S' + D_SS L + b (G_SW (W' + D_WS L) + D_SW (W + G_WS L))). n bounces:
    the series' recursion differentiated term by term.
    """
    K = len(t.rho)
    b = t.wall_albedo / math.pi
    S, W = sources[:K], sources[K:]
    dS, dW = sources_dc[:K], sources_dc[K:]
    if t.lu is not None:
        inner = dS + d.D_SS @ radiance
        inner += b * (t.G_SW @ (dW + d.D_WS @ radiance) + d.D_SW @ (W + t.G_WS @ radiance))
        return np.asarray(lu_solve(t.lu, t.rho * inner))
    assert t.bounces is not None
    surfaces, wall = t.rho * S, b * W
    d_surfaces, d_wall = t.rho * dS, b * dW
    total = d_surfaces.copy()
    for _ in range(t.bounces - 1):
        d_surfaces, d_wall = (
            t.rho * (d.D_SS @ surfaces + t.G_SS @ d_surfaces + d.D_SW @ wall + t.G_SW @ d_wall),
            b * (d.D_WS @ surfaces + t.G_WS @ d_surfaces),
        )
        surfaces, wall = (
            t.rho * (t.G_SS @ surfaces + t.G_SW @ wall),
            b * (t.G_WS @ surfaces),
        )
        total += d_surfaces
    return np.asarray(total)


def albedo_slopes(
    t: Transfers, sources: np.ndarray, radiance: np.ndarray, masks: np.ndarray
) -> np.ndarray:
    """(K, m) d L / d a_k: the derivative of the copies' radiance L (K,) (`Transfers.
    radiance` of sources (K + J,)) with respect to the albedo a_k of the copies in column
    k of masks (K, m) (bool: a surface's copies), rho = a / pi.

    Every bounce: M L = rho (S + b G_SW W), so M L' = (mask / pi) (S + b G_SW W + G_SS L
    + b G_SW G_WS L), the light arriving at those copies. n bounces: the series'
    recursion differentiated term by term.
    """
    K = len(t.rho)
    b = t.wall_albedo / math.pi
    S, W = sources[:K], sources[K:]
    unit = masks.astype(np.float64) / math.pi  # d rho / d a_k
    if t.lu is not None:
        arriving = S + b * (t.G_SW @ W) + t.G_SS @ radiance + b * (t.G_SW @ (t.G_WS @ radiance))
        return np.asarray(lu_solve(t.lu, unit * arriving[:, None]))
    assert t.bounces is not None
    rho = t.rho[:, None]
    surfaces, wall = t.rho * S, b * W
    d_surfaces = unit * S[:, None]
    d_wall = np.zeros((len(W), masks.shape[1]))
    total = d_surfaces.copy()
    for _ in range(t.bounces - 1):
        arriving = t.G_SS @ surfaces + t.G_SW @ wall
        d_surfaces, d_wall = (
            unit * arriving[:, None] + rho * (t.G_SS @ d_surfaces + t.G_SW @ d_wall),
            b * (t.G_WS @ d_surfaces),
        )
        surfaces, wall = t.rho * arriving, b * (t.G_WS @ surfaces)
        total += d_surfaces
    return np.asarray(total)
