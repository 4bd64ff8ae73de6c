"""The transfer between cells and points of `lightcal.synthetic.bounce_reference`, by
Gauss-Legendre quadrature whose order grows as two cells come close (numba kernels).

The transfer from a cell b (centre, normal n_b, two edges, area A_b, uniform unit
radiance) to a cell a (centre, normal n_a, two edges; a point when its edges are 0) is
the mean over a of the irradiance

    G[a, b] = mean_{x in a} integral_{y in b} max(0, cos_x) max(0, cos_y) exp(-c r) / r^2 dA_y,

r = |y - x|, c the medium's attenuation (1/m, 0 in air). Each cell is integrated by the
product Gauss-Legendre rule of order n = min(MAX_ORDER, ceil(ORDER_PER_RATIO h / r)) in
each direction (h its longest edge, r the distance between the centres): one point far
away, more as the cells come close (the kernel is smooth where r >> h, and the rule of
order n integrates a polynomial of degree 2n - 1 exactly). Whether a surface hides b from
a is tested between the centres (a surface does not hide its own cells).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange
from numpy.typing import NDArray

__all__ = ["MAX_ORDER", "ORDER_PER_RATIO", "gather", "gauss_tables", "planes_of", "transfer"]

#: The largest quadrature order per direction.
MAX_ORDER = 10

#: The order per direction is ORDER_PER_RATIO h / r, rounded up (h the cell's longest
#: edge, r the distance between the centres).
ORDER_PER_RATIO = 6.0


def gauss_tables(max_order: int = MAX_ORDER) -> tuple[NDArray, NDArray]:
    """((m + 1, m), (m + 1, m)) nodes on [-1/2, 1/2] and weights summing to 1 of the
    Gauss-Legendre rules of order 1..m (row n, first n entries; row 0 unused)."""
    nodes = np.zeros((max_order + 1, max_order))
    weights = np.zeros((max_order + 1, max_order))
    for n in range(1, max_order + 1):
        x, w = np.polynomial.legendre.leggauss(n)
        nodes[n, :n] = x / 2.0
        weights[n, :n] = w / 2.0
    return nodes, weights


def planes_of(corners: NDArray, edges_u: NDArray, edges_v: NDArray) -> NDArray:
    """(S, 4, 3) the surfaces' corner, normal u x v and dual edges (x . du, x . dv: the
    coordinates s, t of an offset x in the surface's plane) from their corners and edges
    (S, 3)."""
    n = np.cross(edges_u, edges_v)
    nn = np.einsum("si,si->s", n, n)[:, None]
    du = np.cross(edges_v, n) / nn
    dv = np.cross(n, edges_u) / nn
    return np.stack([corners, n, du, dv], axis=1)


@njit(cache=True)
def _blocked(a: NDArray, b: NDArray, owner_a: int, owner_b: int, planes: NDArray) -> bool:
    """Whether the open segment a -> b crosses a surface that owns neither end."""
    for k in range(planes.shape[0]):
        if k == owner_a:
            continue
        if k == owner_b:
            continue
        c, n = planes[k, 0], planes[k, 1]
        da = (a[0] - c[0]) * n[0] + (a[1] - c[1]) * n[1] + (a[2] - c[2]) * n[2]
        db = (b[0] - c[0]) * n[0] + (b[1] - c[1]) * n[1] + (b[2] - c[2]) * n[2]
        if da * db >= 0.0:
            continue
        t = da / (da - db)
        s_ = 0.0
        t_ = 0.0
        for i in range(3):
            x = a[i] + t * (b[i] - a[i]) - c[i]
            s_ += x * planes[k, 2, i]
            t_ += x * planes[k, 3, i]
        if 0.0 < s_ < 1.0 and 0.0 < t_ < 1.0:
            return True
    return False


@njit(cache=True)
def _order(h: float, r: float, ratio: float, max_order: int) -> int:
    if h <= 0.0:
        return 1
    if r <= 0.0:
        return max_order
    return min(max_order, max(1, math.ceil(ratio * h / r)))


@njit(cache=True)
def _pair(
    ca: NDArray,
    na: NDArray,
    ea: NDArray,
    ha: float,
    cb: NDArray,
    nb: NDArray,
    eb: NDArray,
    hb: float,
    attenuation_per_m: float,
    ratio: float,
    nodes: NDArray,
    weights: NDArray,
) -> float:
    """G[a, b] / A_b of the module docstring for one pair (centres (3,), normals (3,),
    edges (2, 3), longest edges h, m)."""
    d0 = cb - ca
    r = math.sqrt(d0[0] ** 2 + d0[1] ** 2 + d0[2] ** 2)
    max_order = nodes.shape[1]
    n_a = _order(ha, r, ratio, max_order)
    n_b = _order(hb, r, ratio, max_order)
    total = 0.0
    for ia in range(n_a):
        for ja in range(n_a):
            wa = weights[n_a, ia] * weights[n_a, ja]
            xa = ca[0] + nodes[n_a, ia] * ea[0, 0] + nodes[n_a, ja] * ea[1, 0]
            ya = ca[1] + nodes[n_a, ia] * ea[0, 1] + nodes[n_a, ja] * ea[1, 1]
            za = ca[2] + nodes[n_a, ia] * ea[0, 2] + nodes[n_a, ja] * ea[1, 2]
            for ib in range(n_b):
                for jb in range(n_b):
                    dx = cb[0] + nodes[n_b, ib] * eb[0, 0] + nodes[n_b, jb] * eb[1, 0] - xa
                    dy = cb[1] + nodes[n_b, ib] * eb[0, 1] + nodes[n_b, jb] * eb[1, 1] - ya
                    dz = cb[2] + nodes[n_b, ib] * eb[0, 2] + nodes[n_b, jb] * eb[1, 2] - za
                    cos_a = dx * na[0] + dy * na[1] + dz * na[2]
                    cos_b = -(dx * nb[0] + dy * nb[1] + dz * nb[2])
                    if cos_a <= 0.0 or cos_b <= 0.0:
                        continue
                    r2 = dx * dx + dy * dy + dz * dz
                    k = cos_a * cos_b / (r2 * r2)
                    if attenuation_per_m > 0.0:
                        k *= math.exp(-attenuation_per_m * math.sqrt(r2))
                    total += wa * weights[n_b, ib] * weights[n_b, jb] * k
    return total


@njit(cache=True, parallel=True)
def transfer(
    a_centres: NDArray,
    a_normals: NDArray,
    a_edges: NDArray,
    a_owner: NDArray,
    b_centres: NDArray,
    b_normals: NDArray,
    b_edges: NDArray,
    b_area: NDArray,
    b_owner: NDArray,
    planes: NDArray,
    attenuation_per_m: float,
    ratio: float,
    nodes: NDArray,
    weights: NDArray,
) -> NDArray:
    """(Na, Nb) G[a, b] of the module docstring: cells a (centres (Na, 3), normals
    (Na, 3), edges (Na, 2, 3), owners (Na,): the surface index, -1 for the wall) and b
    (likewise, areas (Nb,)); 0 between cells of one surface."""
    out = np.zeros((a_centres.shape[0], b_centres.shape[0]))
    for i in prange(a_centres.shape[0]):
        ha = max(_norm(a_edges[i, 0]), _norm(a_edges[i, 1]))
        for j in range(b_centres.shape[0]):
            if a_owner[i] >= 0 and a_owner[i] == b_owner[j]:
                continue
            hb = max(_norm(b_edges[j, 0]), _norm(b_edges[j, 1]))
            if _facing_away(a_centres[i], a_normals[i], b_centres[j], b_normals[j], ha + hb):
                continue
            if _blocked(a_centres[i], b_centres[j], a_owner[i], b_owner[j], planes):
                continue
            g = _pair(
                a_centres[i],
                a_normals[i],
                a_edges[i],
                ha,
                b_centres[j],
                b_normals[j],
                b_edges[j],
                hb,
                attenuation_per_m,
                ratio,
                nodes,
                weights,
            )
            out[i, j] = g * b_area[j]
    return out


@njit(cache=True, parallel=True)
def gather(
    points: NDArray,
    b_centres: NDArray,
    b_normals: NDArray,
    b_edges: NDArray,
    b_area: NDArray,
    b_owner: NDArray,
    radiance: NDArray,
    planes: NDArray,
    attenuation_per_m: float,
    ratio: float,
    nodes: NDArray,
    weights: NDArray,
) -> NDArray:
    """(P,) the irradiance at wall points (P, 3) (normal +z) from cells b of radiance
    (Nb,): sum_b G[p, b] radiance_b."""
    out = np.zeros(points.shape[0])
    up = np.array([0.0, 0.0, 1.0])
    none = np.zeros((2, 3))
    n_planes = planes.shape[0]
    n_cells = b_centres.shape[0]
    cell_side = np.empty((n_cells, n_planes))  # signed distances to the planes (x |n|)
    cell_h = np.empty(n_cells)
    for j in range(n_cells):
        cell_h[j] = max(_norm(b_edges[j, 0]), _norm(b_edges[j, 1]))
        for k in range(n_planes):
            cell_side[j, k] = _side(b_centres[j], planes[k])
    for p in prange(points.shape[0]):
        point_side = np.empty(n_planes)
        for k in range(n_planes):
            point_side[k] = _side(points[p], planes[k])
        total = 0.0
        for j in range(n_cells):
            if radiance[j] == 0.0:
                continue
            if _facing_away(points[p], up, b_centres[j], b_normals[j], cell_h[j]):
                continue
            hidden = False
            for k in range(n_planes):
                if k == b_owner[j] or point_side[k] * cell_side[j, k] >= 0.0:
                    continue
                if _crosses(points[p], b_centres[j], point_side[k], cell_side[j, k], planes[k]):
                    hidden = True
                    break
            if hidden:
                continue
            g = _pair(
                points[p],
                up,
                none,
                0.0,
                b_centres[j],
                b_normals[j],
                b_edges[j],
                cell_h[j],
                attenuation_per_m,
                ratio,
                nodes,
                weights,
            )
            total += g * b_area[j] * radiance[j]
        out[p] = total
    return out


@njit(cache=True)
def _side(x: NDArray, plane: NDArray) -> float:
    """(x - corner) . n of a plane (corner, n, du, dv) (4, 3)."""
    return (
        (x[0] - plane[0, 0]) * plane[1, 0]
        + (x[1] - plane[0, 1]) * plane[1, 1]
        + (x[2] - plane[0, 2]) * plane[1, 2]
    )


@njit(cache=True)
def _crosses(a: NDArray, b: NDArray, da: float, db: float, plane: NDArray) -> bool:
    """Whether the segment a -> b, whose ends lie da and db (opposite signs) from the
    plane, crosses it inside its parallelogram."""
    t = da / (da - db)
    s_ = 0.0
    t_ = 0.0
    for i in range(3):
        x = a[i] + t * (b[i] - a[i]) - plane[0, i]
        s_ += x * plane[2, i]
        t_ += x * plane[3, i]
    return 0.0 < s_ < 1.0 and 0.0 < t_ < 1.0


@njit(cache=True)
def _norm(v: NDArray) -> float:
    return math.sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2])


@njit(cache=True)
def _facing_away(a: NDArray, na: NDArray, b: NDArray, nb: NDArray, reach: float) -> bool:
    """Whether no point within `reach` of centre b faces a point within `reach` of centre a
    (each behind the other's plane by more than `reach`): the pair's transfer is 0."""
    d0 = b[0] - a[0]
    d1 = b[1] - a[1]
    d2 = b[2] - a[2]
    return (d0 * na[0] + d1 * na[1] + d2 * na[2] < -2.0 * reach) or (
        d0 * nb[0] + d1 * nb[1] + d2 * nb[2] > 2.0 * reach
    )
