"""The flat ports in the 3D view: the camera's (`camera.port`) and the lights'
(`lights[i].port`), each a thin translucent slab between the port's two faces.

The camera's port hangs below each frustum node (`/cameras/<i>/port`, camera frame, so
it moves with the frustum): its inner face at the port's distance along its normal, its
outer face the thickness further, each the rectangle (in the face's plane) that the
frustum's drawn opening crosses there, the outer one where the frustum's corner rays
leave the glass. A light's port hangs below the light's node on every camera
(`/cameras/<i>/light<j>/port`, light frame, its normal the light's +z unless tilted):
the polygon its beam's cut-off cone crosses on each face. Frames and units: metres, the
camera's OpenCV axes (docs/model.md, "The camera's flat port", "The light's flat port").
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from lightcal.core.flat_port import FlatPort
from lightcal_app.beam_shapes import air_ring, port_faces_hits, port_reach_rad

PORT_RGB = (70, 150, 235)
PORT_OPACITY = 0.35


def frustum_corner_rays(fov_y_rad: float, aspect: float) -> np.ndarray:
    """(4, 3) the drawn frustum's corner directions, camera frame (OpenCV: y down): top
    left, top right, bottom right, bottom left (viser's frustum is symmetric:
    |x| <= aspect tan(fov/2) z, |y| <= tan(fov/2) z; `lightcal_app.picking`)."""
    ty = math.tan(0.5 * fov_y_rad)
    tx = aspect * ty
    return np.array([[-tx, -ty, 1.0], [tx, -ty, 1.0], [tx, ty, 1.0], [-tx, ty, 1.0]])


def face_basis(normal: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two unit vectors spanning a face of this normal: u along x as far as it can be,
    v = normal x u (along +y for the normal +z)."""
    n = np.asarray(normal, dtype=np.float64)
    u = np.array([1.0, 0.0, 0.0]) - n[0] * n
    u /= np.linalg.norm(u)
    return u, np.cross(n, u)


def bounding_rectangle(points: np.ndarray, normal: np.ndarray) -> np.ndarray:
    """(4, 3) the smallest rectangle with sides along `face_basis(normal)` around points
    (N, 3) of one face (coplanar), in the order of `frustum_corner_rays`."""
    u, v = face_basis(normal)
    origin = points.mean(axis=0)
    cu, cv = (points - origin) @ u, (points - origin) @ v
    corners = [
        (cu.min(), cv.min()),
        (cu.max(), cv.min()),
        (cu.max(), cv.max()),
        (cu.min(), cv.max()),
    ]
    return np.array([origin + a * u + b * v for a, b in corners])


def camera_port_faces(
    port: FlatPort, *, fov_y_rad: float, aspect: float
) -> tuple[np.ndarray, np.ndarray]:
    """The camera port's inner and outer faces as drawn, ((4, 3), (4, 3)) corners, camera
    frame, m: the rectangles around where the frustum's corner rays cross the inner face
    and leave the outer one (`FlatPort.trace`)."""
    inner, outer = port_faces_hits(port, frustum_corner_rays(fov_y_rad, aspect))
    n = port.normal_camera
    return bounding_rectangle(inner, n), bounding_rectangle(outer, n)


def light_port_faces(
    port: FlatPort, theta_cut_air_rad: float, *, n: int = 48
) -> tuple[np.ndarray, np.ndarray]:
    """A light port's inner and outer faces as drawn, ((n, 3), (n, 3)) polygons, light
    frame, m: where the beam's cut-off cone (air angle, capped at `port_reach_rad`)
    crosses the inner face and leaves the outer one."""
    rays = air_ring(theta_cut_air_rad, n, cap_rad=port_reach_rad(port))
    return port_faces_hits(port, rays)


def slab_mesh(inner: np.ndarray, outer: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The closed slab between two convex polygons (k, 3) of corresponding vertices:
    vertices (2k, 3) (inner then outer) and faces (4k - 4, 3)."""
    k = len(inner)
    j = np.arange(1, k - 1)
    caps = [np.stack([np.zeros(k - 2, np.int64), j, j + 1], axis=1)]
    caps.append(caps[0] + k)
    i = np.arange(k)
    nxt = (i + 1) % k
    sides = [np.stack([i, nxt, k + nxt], axis=1), np.stack([i, k + nxt, k + i], axis=1)]
    return np.vstack([inner, outer]), np.concatenate(caps + sides)


def slab_edges(inner: np.ndarray, outer: np.ndarray) -> np.ndarray:
    """The two faces' outlines, (2k, 2, 3) segments."""
    return np.concatenate(
        [np.stack([face, np.roll(face, -1, axis=0)], axis=1) for face in (inner, outer)]
    )


def draw_port_slab(scene: Any, base: str, inner: np.ndarray, outer: np.ndarray) -> list[Any]:
    """The slab `base`/port (translucent) and its faces' outlines `base`/port_edges."""
    vertices, faces = slab_mesh(inner, outer)
    mesh = scene.add_mesh_simple(
        f"{base}/port",
        vertices.astype(np.float32),
        faces.astype(np.uint32),
        color=PORT_RGB,
        opacity=PORT_OPACITY,
        side="double",
        cast_shadow=False,
        receive_shadow=False,
    )
    edges = scene.add_line_segments(
        f"{base}/port_edges",
        slab_edges(inner, outer).astype(np.float32),
        PORT_RGB,
        thickness=1.5,
        thickness_units="screen",
    )
    return [mesh, edges]
