"""A point-sampled renderer of a wall that is not flat: a height field z = h(x, y).

The calibration's renderer (`lightcal.core.render`) knows the plane z = 0 only, and
integrates the light over each pixel's footprint. Synthetic data of a bowed wall (the
`bow` departure, `lightcal.synthetic.departures`) needs the wall's true shape instead;
this module renders it by sampling one point per pixel (test data only, not the model):

1. The pixel centre's ray, undistorted and back-projected, d = R^T K^-1 (u, v, 1), meets
   the height field at P = C + lambda d: lambda solves g(lambda) = C_z + lambda d_z -
   h(C_xy + lambda d_xy) = 0 by Newton's method from the plane's hit (`intersect`).
2. The wall's normal there is n = (-h_x, -h_y, 1) / |...|.
3. Each light's irradiance per unit intensity I0 is E = f(theta, phi) cos(incidence) / d^2,
   f the light's RID (evaluated as the renderer does), incidence the angle between n and
   the direction to the light, d the distance to it; times the wall's relative
   reflectance B (docs/model.md, "The wall", with the local normal) and the light's scale.
4. The sensor terms of docs/model.md, step 5, for one point: `radiance` 1, `map` V(u, v),
   `cos4` cos^4 of the ray through the mean of the pixel's undistorted corners, `paper`
   the pixel's solid angle seen from the camera (its footprint's A cos(theta_v) / d^2);
   times the exposure.

The footprint integral of the flat renderer and this point sample agree to second order
in the footprint's size: for h = 0 within 1e-4 relative on lit pixels
(`tests/test_synth_departures.py`). Shadows the wall casts on itself are not modelled
(the slopes of `BowedWall` stay below 0.2). A pixel whose centre ray misses the wall, does
not converge or sees the wall from behind is masked.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from lightcal.core.camera import Camera
from lightcal.core.footprint import SensorModel
from lightcal.core.render import corner_grid
from lightcal.core.rotations import in_normal_frames
from lightcal.core.scene import Rig, View
from lightcal.core.wall import LAMBERTIAN, WallReflectance

__all__ = [
    "BowedWall",
    "SurfaceShading",
    "intersect",
    "pixel_rays_world",
    "point_sensor_weights",
    "render_height_field",
    "shade_height_field",
    "surface_points",
]

_NEWTON_STEPS = 30
"""Most Newton steps of `intersect` (a paraboloid cap converges in 3-5)."""

_HIT_TOL_M = 1e-12
"""A ray meets the wall where |g(lambda)| is below this, metres."""


@dataclass(frozen=True)
class BowedWall:
    """The height field z = depth_m max(0, 1 - |(x, y) - center|^2 / radius^2).

    A paraboloid cap over a disc: depth_m > 0 bulges towards the cameras (z > 0), < 0 is
    a bowl; the plane z = 0 outside the disc (and for depth 0).

    Attributes:
        depth_m: Height at the centre, metres.
        center_xy_m: (x0, y0) the disc's centre on the wall, metres.
        radius_m: The disc's radius R, metres (> 0).
    """

    depth_m: float
    center_xy_m: tuple[float, float] = (0.0, 0.0)
    radius_m: float = 1.0

    def __post_init__(self) -> None:
        if not (math.isfinite(self.radius_m) and self.radius_m > 0.0):
            raise ValueError(f"radius_m: expected a finite value > 0, got {self.radius_m!r}")
        if not math.isfinite(self.depth_m):
            raise ValueError(f"depth_m: expected a finite value, got {self.depth_m!r}")

    def _offsets(self, xy_m: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.bool_]]:
        """(N, 2) offsets from the centre, over radius; (N,) inside the disc."""
        q = (xy_m - np.asarray(self.center_xy_m)) / self.radius_m
        return q, np.sum(q * q, axis=-1) < 1.0

    def height(self, xy_m: NDArray[np.float64]) -> NDArray[np.float64]:
        """h at (N, 2) wall points (x, y), metres -> (N,) metres."""
        q, inside = self._offsets(xy_m)
        return np.where(inside, self.depth_m * (1.0 - np.sum(q * q, axis=-1)), 0.0)

    def gradient(self, xy_m: NDArray[np.float64]) -> NDArray[np.float64]:
        """(dh/dx, dh/dy) at (N, 2) wall points -> (N, 2), dimensionless."""
        q, inside = self._offsets(xy_m)
        return np.where(inside[:, None], (-2.0 * self.depth_m / self.radius_m) * q, 0.0)

    def normals(self, xy_m: NDArray[np.float64]) -> NDArray[np.float64]:
        """Unit normals (N, 3) towards the cameras (n_z > 0) at (N, 2) wall points."""
        grad = self.gradient(xy_m)
        n = np.concatenate([-grad, np.ones((grad.shape[0], 1))], axis=1)
        return n / np.linalg.norm(n, axis=1, keepdims=True)


def pixel_rays_world(camera: Camera, view: View) -> tuple[NDArray[np.float64], NDArray[np.bool_]]:
    """The rays of every pixel centre in the world frame.

    Returns:
        rays_world: (H * W, 3) R^T (x, y, 1), (x, y) the undistorted normalised
            coordinates; row-major pixels (row v, column u); NaN where not valid.
        valid: (H * W,) the undistortion succeeded.
    """
    v, u = np.mgrid[0 : camera.height, 0 : camera.width]
    pixels = np.stack([u.ravel(), v.ravel()], axis=1).astype(np.float64)
    rays_camera, valid = camera.rays_camera(pixels)
    return rays_camera @ view.R_camera_world, valid


def intersect(
    origin_world: NDArray[np.float64], rays_world: NDArray[np.float64], wall: BowedWall
) -> tuple[NDArray[np.float64], NDArray[np.bool_]]:
    """Where rays from one point meet the height field (Newton's method on lambda).

    Args:
        origin_world: (3,) the rays' origin C (z > 0), metres.
        rays_world: (N, 3) directions d (any length; NaN rows are misses).
        wall: The height field.

    Returns:
        points_world: (N, 3) C + lambda d (NaN where not valid).
        valid: (N,) the ray meets the wall in front of C, from the front, and converged.
    """
    c = np.asarray(origin_world, dtype=np.float64)
    d = np.asarray(rays_world, dtype=np.float64)
    with np.errstate(invalid="ignore", divide="ignore"):
        lam = np.where(d[:, 2] < 0.0, -c[2] / d[:, 2], np.nan)
    ok = np.isfinite(lam)
    lam = np.where(ok, lam, 1.0)
    slope = d[:, 2]
    for _ in range(_NEWTON_STEPS):
        xy = c[:2] + lam[:, None] * d[:, :2]
        g = c[2] + lam * d[:, 2] - wall.height(xy)
        slope = d[:, 2] - np.sum(wall.gradient(xy) * d[:, :2], axis=1)
        with np.errstate(invalid="ignore", divide="ignore"):
            step = np.where(ok & (slope < 0.0), g / slope, 0.0)
        lam = lam - step
        if not np.any(np.abs(step) > 1e-15 * np.abs(lam)):
            break
    points = c + lam[:, None] * d
    g = points[:, 2] - wall.height(points[:, :2])
    valid = ok & (lam > 0.0) & (slope < 0.0) & (np.abs(g) < _HIT_TOL_M)
    points[~valid] = np.nan
    return points, valid


def surface_points(
    camera: Camera, view: View, wall: BowedWall
) -> tuple[NDArray[np.float64], NDArray[np.bool_]]:
    """The wall point of every pixel centre: (H, W, 3) world points and (H, W) validity."""
    rays, ok = pixel_rays_world(camera, view)
    points, valid = intersect(view.center_world, rays, wall)
    valid &= ok
    return points.reshape(camera.height, camera.width, 3), valid.reshape(
        camera.height, camera.width
    )


def _unit_solid_angle(
    a: NDArray[np.float64], b: NDArray[np.float64], c: NDArray[np.float64]
) -> NDArray[np.float64]:
    """Solid angle of spherical triangles of unit vertices (..., 3) (Van Oosterom-Strackee)."""
    numerator = np.abs(np.sum(a * np.cross(b, c), axis=-1))
    denominator = 1.0 + np.sum(a * b, axis=-1) + np.sum(a * c, axis=-1) + np.sum(b * c, axis=-1)
    return 2.0 * np.arctan2(numerator, denominator)


def point_sensor_weights(
    camera: Camera, sensor: SensorModel, vignetting: NDArray[np.float64] | None
) -> tuple[NDArray[np.float64], NDArray[np.bool_]]:
    """(H, W) the point-sampled sensor term of each pixel and (H, W) its validity."""
    shape = (camera.height, camera.width)
    if sensor == "radiance":
        return np.ones(shape), np.ones(shape, dtype=np.bool_)
    if sensor == "map":
        if vignetting is None or vignetting.shape != shape:
            raise ValueError(f"vignetting: expected an {shape} map for the 'map' sensor model")
        return np.asarray(vignetting, dtype=np.float64), np.ones(shape, dtype=np.bool_)
    grid_xy, grid_ok = corner_grid(camera)
    ok = grid_ok[:-1, :-1] & grid_ok[:-1, 1:] & grid_ok[1:, 1:] & grid_ok[1:, :-1]
    if sensor == "cos4":
        mean = (grid_xy[:-1, :-1] + grid_xy[:-1, 1:] + grid_xy[1:, 1:] + grid_xy[1:, :-1]) / 4.0
        cos2 = 1.0 / (1.0 + np.sum(mean * mean, axis=-1))
        return cos2 * cos2, ok
    # paper: the solid angle of the pixel's four corner rays.
    rays = np.concatenate([grid_xy, np.ones((*grid_xy.shape[:2], 1))], axis=-1)
    rays /= np.linalg.norm(rays, axis=-1, keepdims=True)
    p1, p2, p3, p4 = rays[:-1, :-1], rays[:-1, 1:], rays[1:, 1:], rays[1:, :-1]
    return _unit_solid_angle(p1, p2, p3) + _unit_solid_angle(p1, p3, p4), ok


@dataclass(frozen=True, eq=False)
class SurfaceShading:
    """One view of the height-field wall, per light.

    Attributes:
        values: (L, H, W) each light's contribution (scale and exposure included; 0 where
            it does not light the point; NaN where the pixel is not valid).
        points_world: (H, W, 3) each pixel centre's point on the wall, metres.
        valid: (H, W) pixels with a value.
    """

    values: NDArray[np.float64]
    points_world: NDArray[np.float64]
    valid: NDArray[np.bool_]


def shade_height_field(
    camera: Camera,
    view: View,
    rig: Rig,
    wall_shape: BowedWall,
    *,
    sensor: SensorModel = "radiance",
    vignetting: NDArray[np.float64] | None = None,
    wall: WallReflectance = LAMBERTIAN,
) -> SurfaceShading:
    """Each light's point-sampled image of the height-field wall (module docstring).

    Args:
        camera: The intrinsics.
        view: The camera pose and exposure.
        rig: The lights (scales applied).
        wall_shape: The height field.
        sensor: The sensor's fall-off model.
        vignetting: (H, W) fall-off map of the "map" model.
        wall: The wall's reflectance relative to Lambertian (B).

    Returns:
        The per-light values, the wall points and the valid pixels.
    """
    weight, weight_ok = point_sensor_weights(camera, sensor, vignetting)
    points_hw, hit_hw = surface_points(camera, view, wall_shape)
    points = points_hw.reshape(-1, 3)
    to_camera = view.center_world - points
    to_camera /= np.linalg.norm(to_camera, axis=1, keepdims=True)
    normals = wall_shape.normals(points[:, :2])
    valid = hit_hw.ravel() & weight_ok.ravel() & (np.sum(to_camera * normals, axis=1) > 0.0)
    p, n, v = points[valid], normals[valid], to_camera[valid]
    scale_sensor = view.exposure * weight.ravel()[valid]
    values = np.full((len(rig.lights), points.shape[0]), np.nan)
    for j, light in enumerate(rig.lights):
        out = np.zeros(p.shape[0])
        L_world = light.position_world(view)
        if L_world[2] > 0.0:  # as the renderer: a light on or behind the wall lights nothing
            to_light = L_world - p
            distance = np.linalg.norm(to_light, axis=1)
            l_dir = to_light / distance[:, None]
            cos_incidence = np.sum(l_dir * n, axis=1)
            u_light = -l_dir @ light.rotation_world(view)  # light -> point, light frame
            theta = np.arccos(np.clip(u_light[:, 2], -1.0, 1.0))
            phi = np.arctan2(u_light[:, 1], u_light[:, 0])
            f = light.rid(theta, phi)
            out = np.where(cos_incidence > 0.0, f * cos_incidence / distance**2, 0.0)
            if not wall.is_lambertian:
                b, _ = wall.factor(in_normal_frames(l_dir, n), in_normal_frames(v, n))
                out = out * b
            out = light.scale * scale_sensor * out
        values[j, valid] = out
    shape = (camera.height, camera.width)
    return SurfaceShading(values.reshape(len(rig.lights), *shape), points_hw, valid.reshape(shape))


def render_height_field(
    camera: Camera,
    view: View,
    rig: Rig,
    wall_shape: BowedWall,
    *,
    sensor: SensorModel = "radiance",
    vignetting: NDArray[np.float64] | None = None,
    wall: WallReflectance = LAMBERTIAN,
) -> np.ma.MaskedArray:
    """(H, W) the whole rig's image of the height-field wall, masked where not valid
    (arguments as `shade_height_field`)."""
    shading = shade_height_field(
        camera, view, rig, wall_shape, sensor=sensor, vignetting=vignetting, wall=wall
    )
    total = shading.values.sum(axis=0)
    return np.ma.masked_array(total, mask=~shading.valid)
