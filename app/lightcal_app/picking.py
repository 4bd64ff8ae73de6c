"""From a click or a dragged rectangle in the 3D view to pixels of an image.

viser reports a click as a ray (origin, direction, world frame) and a rectangle as two
screen corners in [0, 1] (OpenCV image convention: (0, 0) top left). The browser's
camera turns a screen point into a ray; the ray hits the image plane of a camera
frustum, where the picture of that image is drawn: that gives the pixel.

Where viser draws the picture (its frustum geometry): for vertical field of view f,
aspect a and `scale` s, the picture is the rectangle at depth z = s / c in the frustum's
(OpenCV) camera frame, c = cbrt(tan(f/2)^2 a / 3), spanning |x| <= a z tan(f/2),
|y| <= z tan(f/2). Its left edge is pixel coordinate u = -1/2 and its right edge
u = W - 1/2 (pixel centres at integers), top y < 0.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from lightcal.core.rotations import matrix_from_quaternion_wxyz


@dataclass(frozen=True)
class FrustumPlane:
    """Where one image's picture sits in the world.

    Attributes:
        R_world_camera: (3, 3) rotation camera -> world.
        center_world: (3,) camera centre, m.
        depth_m: z of the picture in the camera frame.
        half_width_m, half_height_m: half extents of the picture.
        width_px, height_px: image size (full resolution).
    """

    R_world_camera: np.ndarray
    center_world: np.ndarray
    depth_m: float
    half_width_m: float
    half_height_m: float
    width_px: int
    height_px: int


def frustum_plane(
    R_world_camera: np.ndarray,
    center_world: np.ndarray,
    *,
    fov_y_rad: float,
    aspect: float,
    scale: float,
    width_px: int,
    height_px: int,
) -> FrustumPlane:
    """The picture rectangle of a frustum drawn by viser with these arguments."""
    tan_half = math.tan(fov_y_rad / 2.0)
    c = (tan_half * tan_half * aspect / 3.0) ** (1.0 / 3.0)
    depth = scale / c
    return FrustumPlane(
        np.asarray(R_world_camera, dtype=np.float64),
        np.asarray(center_world, dtype=np.float64),
        depth,
        depth * tan_half * aspect,
        depth * tan_half,
        width_px,
        height_px,
    )


def frustum_scale_for_depth(depth_m: float, *, fov_y_rad: float, aspect: float) -> float:
    """The viser frustum `scale` that puts the picture at `depth_m` from the camera centre."""
    tan_half = math.tan(fov_y_rad / 2.0)
    return depth_m * (tan_half * tan_half * aspect / 3.0) ** (1.0 / 3.0)


def ray_hit(
    plane: FrustumPlane, origin_world: np.ndarray, direction_world: np.ndarray
) -> tuple[float, float, float] | None:
    """Where a ray meets a picture.

    Args:
        plane: the picture.
        origin_world: (3,) ray origin.
        direction_world: (3,) ray direction (any length).

    Returns:
        (u, v, distance) with (u, v) full-resolution pixel coordinates and distance the ray
        parameter in units of |direction|, or None when the ray misses the picture (or
        runs parallel to it, or meets it behind the origin).
    """
    hit = _plane_point(plane, origin_world, direction_world)
    if hit is None:
        return None
    x, y, t = hit
    if abs(x) > plane.half_width_m or abs(y) > plane.half_height_m:
        return None
    u, v = _pixel_of(plane, x, y)
    return u, v, t


def _plane_point(
    plane: FrustumPlane, origin_world: np.ndarray, direction_world: np.ndarray
) -> tuple[float, float, float] | None:
    """(x, y) in the picture's plane (camera frame, m) where the ray meets it, and the
    ray parameter t > 0; None when parallel to it or behind the origin."""
    R = plane.R_world_camera
    o = R.T @ (np.asarray(origin_world, dtype=np.float64) - plane.center_world)
    d = R.T @ np.asarray(direction_world, dtype=np.float64)
    if abs(d[2]) < 1e-12:
        return None
    t = (plane.depth_m - o[2]) / d[2]
    if t <= 0.0:
        return None
    return float(o[0] + t * d[0]), float(o[1] + t * d[1]), float(t)


def _pixel_of(plane: FrustumPlane, x: float, y: float) -> tuple[float, float]:
    """Full-resolution pixel coordinates of the plane point (x, y) (pixel centres at
    integers)."""
    u = (x / plane.half_width_m + 1.0) * 0.5 * plane.width_px - 0.5
    v = (y / plane.half_height_m + 1.0) * 0.5 * plane.height_px - 0.5
    return float(u), float(v)


def plane_hit_unbounded(
    plane: FrustumPlane, origin_world: np.ndarray, direction_world: np.ndarray
) -> tuple[float, float] | None:
    """Pixel coordinates where a ray meets the picture's plane (may lie off the picture)."""
    hit = _plane_point(plane, origin_world, direction_world)
    return None if hit is None else _pixel_of(plane, hit[0], hit[1])


def pick(
    planes: Sequence[FrustumPlane | None], origin_world: np.ndarray, direction_world: np.ndarray
) -> tuple[int, float, float] | None:
    """The nearest picture a ray hits: (image index, u, v), or None (a None plane: a
    picture not shown, never hit)."""
    best: tuple[int, float, float] | None = None
    best_t = math.inf
    for i, plane in enumerate(planes):
        hit = None if plane is None else ray_hit(plane, origin_world, direction_world)
        if hit is not None and hit[2] < best_t:
            best_t = hit[2]
            best = (i, hit[0], hit[1])
    return best


def screen_ray(
    camera_position: np.ndarray,
    camera_wxyz: np.ndarray,
    *,
    fov_y_rad: float,
    aspect: float,
    screen_xy: tuple[float, float],
) -> tuple[np.ndarray, np.ndarray]:
    """The world ray through a screen point of a browser's (OpenCV-convention) camera.

    Args:
        camera_position: (3,) the browser camera's position.
        camera_wxyz: (4,) its orientation (camera -> world), viser's convention.
        fov_y_rad: its vertical field of view.
        aspect: its width / height.
        screen_xy: the point in [0, 1]^2, (0, 0) top left.

    Returns:
        origin (3,), unit direction (3,) in the world frame.
    """
    t = math.tan(fov_y_rad / 2.0)
    x = (2.0 * screen_xy[0] - 1.0) * t * aspect
    y = (2.0 * screen_xy[1] - 1.0) * t
    R = matrix_from_quaternion_wxyz(np.asarray(camera_wxyz, dtype=np.float64))
    d = R @ np.array([x, y, 1.0])
    return np.asarray(camera_position, dtype=np.float64), d / np.linalg.norm(d)


def rect_to_polygon(
    planes: Sequence[FrustumPlane | None],
    camera_position: np.ndarray,
    camera_wxyz: np.ndarray,
    *,
    fov_y_rad: float,
    aspect: float,
    screen_min: tuple[float, float],
    screen_max: tuple[float, float],
) -> tuple[int, np.ndarray] | None:
    """Map a dragged screen rectangle onto the picture under its centre.

    Returns:
        (image index, (4, 2) polygon of full-resolution pixel coordinates), clipped to
        the image, or None when the rectangle's centre is on no picture.
    """
    cx = 0.5 * (screen_min[0] + screen_max[0])
    cy = 0.5 * (screen_min[1] + screen_max[1])
    o, d = screen_ray(
        camera_position, camera_wxyz, fov_y_rad=fov_y_rad, aspect=aspect, screen_xy=(cx, cy)
    )
    hit = pick(planes, o, d)
    if hit is None:
        return None
    index = hit[0]
    plane = planes[index]
    assert plane is not None  # (hit)
    corners = [
        (screen_min[0], screen_min[1]),
        (screen_max[0], screen_min[1]),
        (screen_max[0], screen_max[1]),
        (screen_min[0], screen_max[1]),
    ]
    out = []
    for xy in corners:
        o, d = screen_ray(
            camera_position, camera_wxyz, fov_y_rad=fov_y_rad, aspect=aspect, screen_xy=xy
        )
        uv = plane_hit_unbounded(plane, o, d)
        if uv is None:
            return None
        out.append(uv)
    poly = np.array(out)
    poly[:, 0] = np.clip(poly[:, 0], -0.5, plane.width_px - 0.5)
    poly[:, 1] = np.clip(poly[:, 1], -0.5, plane.height_px - 0.5)
    return index, poly
