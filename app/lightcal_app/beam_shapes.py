"""The shapes of a light's beam in the 3D view: cones around the light's +z axis, in the
light's frame, and the same cones refracted by the light's flat port.

Without a port the beam is a straight cone from the emitter at the RID's half-intensity
and cut-off angles (`cone_lines`, `cone_mesh`). Behind a port (`Light.port`) each of the
cone's rays runs in the air to the port's inner face, through the glass and on in the
water, narrower (n_air sin(theta_air) = n_w sin(theta_w)): `ported_beam_rings` traces
them through `FlatPort.trace`, and `ring_lines` / `ring_mesh` draw the bent cone.
"""

from __future__ import annotations

import itertools
import math

import numpy as np

from lightcal.core.flat_port import FlatPort
from lightcal.core.rid import RID

CONE_MAX_ANGLE_RAD = math.radians(85.0)


def cone_mesh(
    half_angle_rad: float, length_m: float, *, n: int = 40
) -> tuple[np.ndarray, np.ndarray]:
    """An open cone with its apex at the origin around +z.

    Args:
        half_angle_rad: angle between the axis and the surface (capped at 85 degrees).
        length_m: slant length.
        n: segments around the axis.

    Returns:
        vertices (n + 1, 3) and faces (n, 3).
    """
    a = min(max(half_angle_rad, 1e-3), CONE_MAX_ANGLE_RAD)
    r = length_m * math.sin(a)
    h = length_m * math.cos(a)
    phi = np.linspace(0.0, 2.0 * math.pi, n, endpoint=False)
    ring = np.stack([r * np.cos(phi), r * np.sin(phi), np.full(n, h)], axis=1)
    vertices = np.vstack([np.zeros((1, 3)), ring])
    k = np.arange(n)
    faces = np.stack([np.zeros(n, np.int64), 1 + k, 1 + (k + 1) % n], axis=1)
    return vertices, faces


def cone_lines(
    half_angle_rad: float, length_m: float, *, n_ring: int = 48, n_generators: int = 8
) -> np.ndarray:
    """Outline of the cone of `cone_mesh`: its end ring and some generator lines.

    Returns:
        (n_ring + n_generators, 2, 3) line segments.
    """
    a = min(max(half_angle_rad, 1e-3), CONE_MAX_ANGLE_RAD)
    r = length_m * math.sin(a)
    h = length_m * math.cos(a)
    phi = np.linspace(0.0, 2.0 * math.pi, n_ring + 1)
    ring = np.stack([r * np.cos(phi), r * np.sin(phi), np.full(phi.shape, h)], axis=1)
    segs = [np.stack([ring[:-1], ring[1:]], axis=1)]
    k = np.arange(n_generators) * (n_ring // n_generators)
    gen = np.zeros((n_generators, 2, 3))
    gen[:, 1] = ring[k]
    segs.append(gen)
    return np.concatenate(segs)


def rid_angles(rid: RID) -> tuple[float, float]:
    """(half-intensity angle, 1 % cut-off angle) of a RID, radians."""
    return rid.angle_at_level_rad(0.5), rid.angle_at_level_rad(0.01)


def port_reach_rad(port: FlatPort) -> float:
    """The largest air angle from the light's axis drawn through a port: the cones' cap,
    less the port's tilt (every ray drawn reaches the port's inner face)."""
    return min(CONE_MAX_ANGLE_RAD, math.radians(89.0 - port.tilt_deg))


def air_ring(theta_air_rad: float, n: int, *, cap_rad: float = CONE_MAX_ANGLE_RAD) -> np.ndarray:
    """(n, 3) unit directions at `theta_air_rad` (clipped to [1e-3, cap_rad]) around +z."""
    a = min(max(theta_air_rad, 1e-3), cap_rad)
    phi = np.linspace(0.0, 2.0 * math.pi, n, endpoint=False)
    s = math.sin(a)
    return np.stack([s * np.cos(phi), s * np.sin(phi), np.full(n, math.cos(a))], axis=1)


def port_faces_hits(port: FlatPort, rays: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Where rays from the port's owner (its frame) cross the port's inner face and leave
    its outer face: ((N, 3), (N, 3)), m; NaN for a ray that does not reach it."""
    r = rays / np.linalg.norm(rays, axis=1, keepdims=True)
    with np.errstate(invalid="ignore", divide="ignore"):
        cos = r @ port.normal_camera
        inner = r * np.where(cos > 0.0, port.distance_m / cos, np.nan)[:, None]
    outer, _, _ = port.trace(r)
    return inner, outer


def ported_beam_rings(
    theta_air_rad: float, length_m: float, port: FlatPort, *, n: int = 48
) -> np.ndarray:
    """The cone of air angle `theta_air_rad` around the light's +z axis, refracted by its
    port: (4, n, 3) rings, light frame, m: the emitter (n copies), the rays' points on the
    port's inner face, their exit points on its outer face, and their ends in the water,
    each ray `length_m` long in all (at least its path through the port)."""
    r = air_ring(theta_air_rad, n, cap_rad=port_reach_rad(port))
    inner, outer = port_faces_hits(port, r)
    _, water, _ = port.trace(r)
    travelled = np.linalg.norm(inner, axis=1) + np.linalg.norm(outer - inner, axis=1)
    end = outer + np.maximum(length_m - travelled, 0.0)[:, None] * water
    return np.stack([np.zeros((n, 3)), inner, outer, end])


def ring_lines(rings: np.ndarray, *, n_generators: int = 8) -> np.ndarray:
    """Outline of a beam given by rings (k, n, 3), as `cone_lines` draws a cone: the last
    ring closed and `n_generators` rays through every ring. Returns (S, 2, 3) segments."""
    n = rings.shape[1]
    end = rings[-1]
    segs = [np.stack([end, np.roll(end, -1, axis=0)], axis=1)]
    pick = np.arange(n_generators) * (n // n_generators)
    for a, b in itertools.pairwise(rings):
        segs.append(np.stack([a[pick], b[pick]], axis=1))
    return np.concatenate(segs)


def ring_mesh(rings: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The open surface through rings (k, n, 3) whose first ring is one point (the apex),
    as `cone_mesh` draws a cone: vertices (1 + (k - 1) n, 3), faces (n (2k - 3), 3)."""
    k, n, _ = rings.shape
    vertices = np.vstack([rings[0, :1], rings[1:].reshape(-1, 3)])
    j = np.arange(n)
    nxt = (j + 1) % n
    faces = [np.stack([np.zeros(n, np.int64), 1 + j, 1 + nxt], axis=1)]
    for ring in range(1, k - 1):
        a, b = 1 + (ring - 1) * n, 1 + ring * n
        faces.append(np.stack([a + j, b + j, b + nxt], axis=1))
        faces.append(np.stack([a + j, b + nxt, a + nxt], axis=1))
    return vertices, np.concatenate(faces)
