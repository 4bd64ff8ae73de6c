"""Exact solid angles of planar triangles and quads (vectorised NumPy reference).

Van Oosterom & Strackee (1983): for a triangle with vertices a, b, c relative to the
viewpoint,

    tan(Omega / 2) = a . (b x c) / (|a||b||c| + (a.b)|c| + (a.c)|b| + (b.c)|a|).

The triple product is evaluated as a . ((b - a) x (c - a)), which is the same number
but free of the cancellation that ruins b x c for tiny, distant triangles: footprints of
1e-12 sr keep their relative precision. The result is signed: positive when a, b, c run
clockwise seen from the viewpoint (a . (e1 x e2) > 0). A quad is split into (P1, P2, P3) and
(P1, P3, P4); its solid angle is the absolute value of the signed sum, exact for any
simple planar quad.

The compiled kernels in `lightcal.core.kernels.solid_angle` implement the same formulas;
this module is the readable reference that the tests hold them to.
"""

from __future__ import annotations

import numpy as np


def triangle_solid_angle(
    viewpoint: np.ndarray, p1: np.ndarray, p2: np.ndarray, p3: np.ndarray
) -> np.ndarray:
    """Signed solid angle of triangles seen from a viewpoint.

    Args:
        viewpoint: (3,) or (N, 3) point the triangles are seen from.
        p1, p2, p3: (N, 3) triangle vertices.

    Returns:
        (N,) signed solid angles, steradians, in (-2 pi, 2 pi).
    """
    a = p1 - viewpoint
    e1 = p2 - p1
    e2 = p3 - p1
    b = p2 - viewpoint
    c = p3 - viewpoint
    numerator = np.einsum("ij,ij->i", a, np.cross(e1, e2))
    la = np.linalg.norm(a, axis=-1)
    lb = np.linalg.norm(b, axis=-1)
    lc = np.linalg.norm(c, axis=-1)
    denominator = (
        la * lb * lc
        + np.einsum("ij,ij->i", a, b) * lc
        + np.einsum("ij,ij->i", a, c) * lb
        + np.einsum("ij,ij->i", b, c) * la
    )
    return 2.0 * np.arctan2(numerator, denominator)


def quad_solid_angle(viewpoint: np.ndarray, corners: np.ndarray) -> np.ndarray:
    """Solid angle of planar quads (corners in cyclic order) seen from a viewpoint.

    Args:
        viewpoint: (3,) or (N, 3).
        corners: (N, 4, 3) quad corners P1..P4 in cyclic order.

    Returns:
        (N,) solid angles, steradians, >= 0.
    """
    p1, p2, p3, p4 = (corners[:, k] for k in range(4))
    return np.abs(
        triangle_solid_angle(viewpoint, p1, p2, p3) + triangle_solid_angle(viewpoint, p1, p3, p4)
    )


def quad_area_in_plane(corners: np.ndarray) -> np.ndarray:
    """Area of planar quads lying in z = 0 (shoelace via the diagonals).

    Args:
        corners: (N, 4, 3) or (N, 4, 2) corners in cyclic order.

    Returns:
        (N,) areas, m^2.
    """
    d1 = corners[:, 2, :2] - corners[:, 0, :2]
    d2 = corners[:, 3, :2] - corners[:, 1, :2]
    return 0.5 * np.abs(d1[:, 0] * d2[:, 1] - d1[:, 1] * d2[:, 0])


def subdivide_quads(corners: np.ndarray, n: int) -> np.ndarray:
    """Split planar quads into n x n sub-quads that tile them exactly.

    Grid points are the bilinear interpolation of the corners; the sub-quads' straight
    edges run between grid points, so the outer ones lie on the original edges.

    Args:
        corners: (N, 4, 3) quads in cyclic order P1 (s=0,t=0), P2 (1,0), P3 (1,1), P4 (0,1).
        n: Subdivisions per side, >= 1.

    Returns:
        (N, n * n, 4, 3) sub-quads, same orientation as their parent.
    """
    s = np.linspace(0.0, 1.0, n + 1)
    ss, tt = np.meshgrid(s, s, indexing="xy")  # (n+1, n+1): rows t, columns s
    w1 = (1 - ss) * (1 - tt)
    w2 = ss * (1 - tt)
    w3 = ss * tt
    w4 = (1 - ss) * tt
    grid = (
        w1[None, :, :, None] * corners[:, None, None, 0]
        + w2[None, :, :, None] * corners[:, None, None, 1]
        + w3[None, :, :, None] * corners[:, None, None, 2]
        + w4[None, :, :, None] * corners[:, None, None, 3]
    )  # (N, n+1, n+1, 3)
    q = np.stack(
        [grid[:, :-1, :-1], grid[:, :-1, 1:], grid[:, 1:, 1:], grid[:, 1:, :-1]], axis=3
    )  # (N, n, n, 4, 3)
    return q.reshape(corners.shape[0], n * n, 4, 3)
