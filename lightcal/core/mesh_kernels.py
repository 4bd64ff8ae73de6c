"""Compiled (numba) ray-mesh intersection of `lightcal.core.wall_mesh`.

The rays of one view all leave the camera centre C; ray c has the direction
d_c = R^T (x_c, y_c, 1), (x_c, y_c) its undistorted normalised coordinates. A triangle
in front of the camera can only be hit by the rays whose (x, y) lie inside its
projection (X/Z, Y/Z), a convex polygon; so the rays are sorted into a uniform grid of
buckets over their (x, y) (a counting sort), and each triangle tests only the rays of
the buckets its projected bounding box covers (no distortion enters: the test is in
undistorted coordinates). A triangle that reaches behind the camera (Z <= 0 at a
vertex) projects to an unbounded region: its box is clipped to the part in front
(Z >= `Z_MIN_M`) and then to the buckets' extent; one wholly behind is skipped.

The test is Moeller and Trumbore's (1997) in the world frame, edges taken inclusive
(barycentric coordinates down to -`EDGE_TOL`, so that a ray through a shared edge
hits one of its triangles); the nearest hit in front of the camera is kept. The hit
point is rebuilt from the barycentric coordinates, P = V0 + u (V1 - V0) + v (V2 - V0),
not as C + t d: on a triangle of the plane z = 0 its z is exactly 0 (the planar
renderer's corners, to round-off).
"""

from __future__ import annotations

import math

import numba
import numpy as np

#: A ray hits a triangle when its barycentric coordinates are >= -EDGE_TOL (and their
#: sum <= 1 + EDGE_TOL): inclusive edges (relative to the triangle's size).
EDGE_TOL = 1e-12

#: The part of a triangle nearer the camera plane than this (m) is left out of its
#: projected box (rays leave the camera forward: Z = t > 0).
Z_MIN_M = 1e-9


@numba.njit(cache=True)
def bucket_rays(
    xs: np.ndarray, ys: np.ndarray, ok: np.ndarray, n_bx: int, n_by: int, box: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Counting sort of the valid rays into n_bx x n_by buckets over box.

    Args:
        xs, ys: (M,) the rays' undistorted normalised coordinates.
        ok: (M,) the rays to sort (the others are in no bucket).
        n_bx, n_by: the buckets per side (>= 1).
        box: (4,) x_min, y_min, x_max, y_max of the valid rays.

    Returns:
        start: (n_bx n_by + 1,) bucket b holds items[start[b] : start[b + 1]].
        items: (number of valid rays,) ray indices.
    """
    m = xs.shape[0]
    sx = n_bx / max(box[2] - box[0], 1e-300)
    sy = n_by / max(box[3] - box[1], 1e-300)
    counts = np.zeros(n_bx * n_by + 1, dtype=np.int64)
    which = np.full(m, -1, dtype=np.int64)
    for c in range(m):
        if not ok[c]:
            continue
        bx = min(n_bx - 1, max(0, int((xs[c] - box[0]) * sx)))
        by = min(n_by - 1, max(0, int((ys[c] - box[1]) * sy)))
        which[c] = by * n_bx + bx
        counts[which[c] + 1] += 1
    for b in range(n_bx * n_by):
        counts[b + 1] += counts[b]
    items = np.empty(counts[-1], dtype=np.int64)
    fill = counts[:-1].copy()
    for c in range(m):
        if which[c] >= 0:
            items[fill[which[c]]] = c
            fill[which[c]] += 1
    return counts, items


@numba.njit(cache=True, inline="always")
def _project_box(vc: np.ndarray, box: np.ndarray) -> tuple[bool, float, float, float, float]:
    """The bounding box (x0, y0, x1, y1) of the projection of the part Z >= Z_MIN_M of
    the triangle vc (3, 3) (camera frame, rows the vertices), clipped to box; False when
    no part is in front."""
    x0 = math.inf
    y0 = math.inf
    x1 = -math.inf
    y1 = -math.inf
    front = False
    for a in range(3):
        za = vc[a, 2]
        if za >= Z_MIN_M:
            front = True
            px = vc[a, 0] / za
            py = vc[a, 1] / za
            x0 = min(x0, px)
            x1 = max(x1, px)
            y0 = min(y0, py)
            y1 = max(y1, py)
        b = (a + 1) % 3
        zb = vc[b, 2]
        if (za - Z_MIN_M) * (zb - Z_MIN_M) < 0.0:  # the edge crosses Z = Z_MIN_M
            s = (Z_MIN_M - za) / (zb - za)
            px = (vc[a, 0] + s * (vc[b, 0] - vc[a, 0])) / Z_MIN_M
            py = (vc[a, 1] + s * (vc[b, 1] - vc[a, 1])) / Z_MIN_M
            x0 = min(x0, px)
            x1 = max(x1, px)
            y0 = min(y0, py)
            y1 = max(y1, py)
    if not front:
        return False, 0.0, 0.0, 0.0, 0.0
    return (
        True,
        max(x0, box[0]),
        max(y0, box[1]),
        min(x1, box[2]),
        min(y1, box[3]),
    )


@numba.njit(cache=True)
def intersect_rays(
    vertices_world: np.ndarray,
    faces: np.ndarray,
    R_camera_world: np.ndarray,
    center_world: np.ndarray,
    xs: np.ndarray,
    ys: np.ndarray,
    ok: np.ndarray,
    n_bx: int,
    n_by: int,
    box: np.ndarray,
    start: np.ndarray,
    items: np.ndarray,
    out_points: np.ndarray,
    out_t: np.ndarray,
    out_face: np.ndarray,
) -> None:
    """The nearest triangle each ray of one view hits (module docstring).

    Args:
        vertices_world: (V, 3) the mesh's vertices, world frame, m.
        faces: (F, 3) int64 vertex indices of its triangles.
        R_camera_world: (3, 3) the view's rotation; center_world: (3,) its centre C, m.
        xs, ys, ok: (M,) the rays (undistorted normalised coordinates; ok: valid).
        n_bx, n_by, box, start, items: the buckets of `bucket_rays`.
        out_points: (M, 3) written where hit: the hit points, world frame, m.
        out_t: (M,) in: inf; out: the hit's t (P = C + t d, d = R^T (x, y, 1)), inf on
            a miss.
        out_face: (M,) written where hit: the triangle's index.
    """
    R = R_camera_world
    C = center_world
    sx = n_bx / max(box[2] - box[0], 1e-300)
    sy = n_by / max(box[3] - box[1], 1e-300)
    vc = np.empty((3, 3))
    for f in range(faces.shape[0]):
        for a in range(3):
            v = faces[f, a]
            dx = vertices_world[v, 0] - C[0]
            dy = vertices_world[v, 1] - C[1]
            dz = vertices_world[v, 2] - C[2]
            for r in range(3):
                vc[a, r] = R[r, 0] * dx + R[r, 1] * dy + R[r, 2] * dz
        front, x0, y0, x1, y1 = _project_box(vc, box)
        if not front or x0 > x1 or y0 > y1:
            continue
        # The box grows by a relative hair: round-off of the projection at its edges.
        pad = 1e-9 * (1.0 + max(abs(x0), abs(x1), abs(y0), abs(y1)))
        x0 -= pad
        y0 -= pad
        x1 += pad
        y1 += pad
        bx0 = min(n_bx - 1, max(0, int((x0 - box[0]) * sx)))
        bx1 = min(n_bx - 1, max(0, int((x1 - box[0]) * sx)))
        by0 = min(n_by - 1, max(0, int((y0 - box[1]) * sy)))
        by1 = min(n_by - 1, max(0, int((y1 - box[1]) * sy)))
        i0 = faces[f, 0]
        i1 = faces[f, 1]
        i2 = faces[f, 2]
        v0x = vertices_world[i0, 0]
        v0y = vertices_world[i0, 1]
        v0z = vertices_world[i0, 2]
        e1x = vertices_world[i1, 0] - v0x
        e1y = vertices_world[i1, 1] - v0y
        e1z = vertices_world[i1, 2] - v0z
        e2x = vertices_world[i2, 0] - v0x
        e2y = vertices_world[i2, 1] - v0y
        e2z = vertices_world[i2, 2] - v0z
        sx0 = C[0] - v0x
        sy0 = C[1] - v0y
        sz0 = C[2] - v0z
        # q = s x e1 is the same for every ray of the view.
        qx = sy0 * e1z - sz0 * e1y
        qy = sz0 * e1x - sx0 * e1z
        qz = sx0 * e1y - sy0 * e1x
        t_num = e2x * qx + e2y * qy + e2z * qz
        for by in range(by0, by1 + 1):
            for bx in range(bx0, bx1 + 1):
                b = by * n_bx + bx
                for j in range(start[b], start[b + 1]):
                    c = items[j]
                    x = xs[c]
                    y = ys[c]
                    if x < x0 or x > x1 or y < y0 or y > y1:
                        continue
                    # d = R^T (x, y, 1)
                    rdx = R[0, 0] * x + R[1, 0] * y + R[2, 0]
                    rdy = R[0, 1] * x + R[1, 1] * y + R[2, 1]
                    rdz = R[0, 2] * x + R[1, 2] * y + R[2, 2]
                    px = rdy * e2z - rdz * e2y
                    py = rdz * e2x - rdx * e2z
                    pz = rdx * e2y - rdy * e2x
                    det = e1x * px + e1y * py + e1z * pz
                    if det == 0.0:
                        continue
                    inv = 1.0 / det
                    u = (sx0 * px + sy0 * py + sz0 * pz) * inv
                    if u < -EDGE_TOL or u > 1.0 + EDGE_TOL:
                        continue
                    v = (rdx * qx + rdy * qy + rdz * qz) * inv
                    if v < -EDGE_TOL or u + v > 1.0 + EDGE_TOL:
                        continue
                    t = t_num * inv
                    if t <= 0.0 or t >= out_t[c]:
                        continue
                    out_t[c] = t
                    out_face[c] = f
                    out_points[c, 0] = v0x + u * e1x + v * e2x
                    out_points[c, 1] = v0y + u * e1y + v * e2y
                    out_points[c, 2] = v0z + u * e1z + v * e2z
