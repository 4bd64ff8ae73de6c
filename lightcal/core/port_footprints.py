"""Pixel footprints on the wall z = 0 seen through the camera's flat port.

As `lightcal.core.footprint.pixel_footprints` does in air, each pixel corner is
undistorted (the intrinsics and distortion of the camera in its housing, as without a
port) and turned into a ray; the ray is refracted through the port
(`lightcal.core.flat_port.FlatPort.trace`: air -> glass -> water) and runs on in the
water from its exit point X_p on the port's outer face; where it meets the wall z = 0 is
the footprint's corner. A corner ray that misses the wall in front of the port makes the
pixel invalid. The four corners make the footprint quad, and everything after is the
planar model's (docs/model.md, "The camera's flat port"):

- the flux on the quad is the light's intensity over its solid angle (the quad lies on
  z = 0, so the renderer's plane paths apply);
- the `radiance` sensor model's weight is 1 / A (A the quad's area, the footprint's
  irradiance): the radiance a pixel sees through the port is the wall's times
  (n_air / n_w)^2 (radiance over n^2 is conserved along a refracted ray), a constant
  factor that the light's scale absorbs; `cos4` and `map` are fall-offs of the lens,
  taken in the air as without a port (the cos^4 of the ray's angle in the air);
- every sensor model's weight is multiplied by the port's Fresnel transmittance
  (`lightcal.core.fresnel.port_transmittance`, both faces and their inner reflections)
  at the angle in the air of each member pixel's ray (the mean of its corners'
  undistorted coordinates, as `cos4` takes it): a fixed factor per pixel, a radial
  fall-off of 0.958 on the axis to 0.948 at 45 degrees for acrylic into water, which
  does not depend on the solver's parameters;
- `paper` (cos(theta_v) / d^2 from the camera centre) is refused: its d has no
  meaning once the ray bends;
- each pixel keeps the mean of its corners' exit points (`Footprints.port_exits_world`)
  where the camera side's path in the medium starts (|P - X_p|, not |P - C|), and the
  footprints carry their normal +z (`Footprints.normals_world`) so that a
  non-Lambertian wall's B takes the viewing direction from the port's exit point
  (`lightcal.core.wall_mesh.apply_wall_on_mesh`, which on the plane gives the planar
  kernel's numbers).

The corners' rays: a sparse selection undistorts and traces its own corners; a dense one
(corners at least `GRID_MIN_CORNER_SHARE` of the camera's), or any selection once the
camera's port lattice is cached, reads them from that lattice (`camera_port_rays`: every
pixel corner traced once per camera and port, the whole image's fused kernel's too) and
moves them to the view. The two agree to round-off (the corner grid's undistortion,
`lightcal.core.corner_grid`).

Not here: a wall mesh behind a port (refused by `wall_footprints`), footprints that do
not keep their quads (a dense selection's are kept: 96 bytes a quad), and the light's
port.
"""

from __future__ import annotations

from collections import OrderedDict
from dataclasses import replace
from threading import Lock

import numpy as np

from lightcal.core.camera import Camera
from lightcal.core.corner_grid import GRID_CACHE
from lightcal.core.flat_port import FlatPort
from lightcal.core.footprint import (
    GRID_MIN_CORNER_SHARE,
    MAX_QUADS_PER_SIDE,
    Footprints,
    SensorModel,
    checked_selection,
    quad_corner_means,
)
from lightcal.core.fresnel import port_transmittance
from lightcal.core.kernels.port_corners import lattice_on_wall
from lightcal.core.scene import View


def port_rays_world(
    camera: Camera, view: View, port: FlatPort, pixels_xy: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The rays of pixel coordinates through the port, world frame.

    Args:
        camera: intrinsics and distortion (of the camera in its housing).
        view: its pose.
        port: the camera's flat port.
        pixels_xy: (M, 2) pixel coordinates (u, v).

    Returns:
        origins: (M, 3) the exit points from the port, m (NaN where not ok).
        directions: (M, 3) the unit directions in the water.
        xy: (M, 2) the undistorted normalised coordinates (the rays in the air).
        ok: (M,) undistorted and through the port.
    """
    xy, ok = camera.pixels_to_normalized(pixels_xy)
    rays = np.concatenate([xy, np.ones((xy.shape[0], 1))], axis=1)
    origins_c, dirs_c, through = port.trace(rays)
    R = view.R_camera_world
    # R^T X_c + C row by row (einsum: numpy's (M, 3) @ (3, 3) is ~10x slower here)
    origins = np.einsum("ij,jk->ik", origins_c, R) + view.center_world
    return origins, np.einsum("ij,jk->ik", dirs_c, R), xy, ok & through


def wall_hits(
    origins: np.ndarray, directions: np.ndarray, ok: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Where rays (M, 3) from origins (M, 3) meet the wall z = 0 in front of them:
    (points (M, 3) with z exactly 0, NaN on a miss; hit (M,))."""
    with np.errstate(invalid="ignore", divide="ignore"):
        lam = -origins[:, 2] / directions[:, 2]
        hit = ok & (directions[:, 2] < 0.0) & (lam > 0.0) & np.isfinite(lam)
    points = origins + lam[:, None] * directions
    points[:, 2] = 0.0
    points[~hit] = np.nan
    return points, hit


def port_footprints(
    camera: Camera,
    view: View,
    pixels: np.ndarray,
    port: FlatPort,
    *,
    sensor: SensorModel = "radiance",
    vignetting: np.ndarray | None = None,
    binning: int = 1,
    max_quads_per_side: int | None = MAX_QUADS_PER_SIDE,
) -> Footprints:
    """Footprints and sensor weights of (super-)pixels on the wall z = 0 through the
    camera's flat port (`pixel_footprints`' arguments and `port`).

    A super-pixel is valid when every corner of its b x b pixels reaches the wall; its
    area is the sum of its pixels' quads' areas; merged quads (`quads_per_side`) take the
    groups' outer corners, as without a port. The quads are kept.
    """
    if sensor == "paper":
        raise ValueError(
            "sensor: the 'paper' model (cos(theta_v) / d^2 from the camera centre) is not "
            "defined behind a flat port; use radiance, cos4 or map"
        )
    b, p, vmap, s = checked_selection(
        camera, pixels, sensor, vignetting, binning, max_quads_per_side
    )
    n = p.shape[0]
    # The (b+1)^2 lattice of each super-pixel's corners, as full-resolution corner
    # indices (row, col): corner (r, c) sits at pixel coordinates (c - 1/2, r - 1/2).
    offs = np.arange(b + 1)
    rows = p[:, 1, None, None] * b + offs[None, :, None]
    cols = p[:, 0, None, None] * b + offs[None, None, :]
    rays = _port_rays_for(camera, port, rows.size)
    fresnel = None
    if rays is None:  # a sparse selection: its own corners, undistorted and traced
        keys = (rows * (camera.width + 1) + cols).ravel().astype(np.int64)
        unique, inverse = np.unique(keys, return_inverse=True)
        corner_px = np.stack(
            [unique % (camera.width + 1) - 0.5, unique // (camera.width + 1) - 0.5], axis=1
        ).astype(np.float64)
        origins, directions, xy, ok = port_rays_world(camera, view, port, corner_px)
        points, hit = wall_hits(origins, directions, ok)
        shape = (n, b + 1, b + 1)
        lattice = points[inverse].reshape(*shape, 3)
        exits = origins[inverse].reshape(*shape, 3)
        lattice_xy = xy[inverse].reshape(*shape, 2)
        corner_hit = hit[inverse].reshape(shape)
    else:  # the camera's lattice, traced once (`camera_port_rays`), moved to the view
        exits_c, dirs_c, grid_xy, grid_ok, fresnel_image = rays
        members = np.arange(b)
        fresnel = fresnel_image[
            p[:, 1, None, None] * b + members[None, :, None],
            p[:, 0, None, None] * b + members[None, None, :],
        ]
        exits, lattice, lattice_xy, corner_hit = lattice_on_wall(
            exits_c, dirs_c, grid_ok, grid_xy, view.R_camera_world, view.center_world,
            rows, cols,
        )  # fmt: skip
    valid = np.asarray(corner_hit.reshape(n, -1).all(axis=1), dtype=np.bool_)
    return _assembled(p, b, s, lattice, exits, lattice_xy, valid, sensor, vmap, port, fresnel)


def _port_rays_for(
    camera: Camera, port: FlatPort, n_corners: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray] | None:
    """The camera's port lattice (`camera_port_rays`) when reading a selection's corners
    from it pays: it is cached, or the selection's corners number at least
    `GRID_MIN_CORNER_SHARE` of its (H+1)(W+1) (as `footprint`'s corner grid); else None
    (the selection traces its own corners)."""
    with _RAYS_LOCK:
        cached = _RAYS.get(_rays_key(camera, port))
    if cached is not None:
        return cached  # type: ignore[return-value]
    if n_corners >= GRID_MIN_CORNER_SHARE * (camera.height + 1) * (camera.width + 1):
        return camera_port_rays(camera, port)
    return None


def _assembled(
    p: np.ndarray,
    b: int,
    s: int,
    lattice: np.ndarray,
    exits: np.ndarray,
    lattice_xy: np.ndarray,
    valid: np.ndarray,
    sensor: SensorModel,
    vmap: np.ndarray | None,
    port: FlatPort,
    fresnel: np.ndarray | None = None,
) -> Footprints:
    """The footprints of super-pixels p (N, 2) of b x b pixels (s quads per side) from
    their corner lattices on the wall (N, b+1, b+1, 3), the lattices' exit points from
    the port (same shape), undistorted coordinates (N, b+1, b+1, 2) and validity (N,);
    `fresnel` (N, b, b) the member pixels' `fresnel_factors` when known."""
    step = b // s
    n = p.shape[0]
    # Member quads P1..P4 = lattice (j, i), (j, i+1), (j+1, i+1), (j+1, i); on z = 0 the
    # area is the z component of the vector area 0.5 (P3 - P1) x (P4 - P2).
    d13 = lattice[:, 1:, 1:, :2] - lattice[:, :-1, :-1, :2]
    d24 = lattice[:, 1:, :-1, :2] - lattice[:, :-1, 1:, :2]
    member_area = 0.5 * np.abs(d13[..., 0] * d24[..., 1] - d13[..., 1] * d24[..., 0])
    area = member_area.reshape(n, -1).sum(axis=1)
    if fresnel is None:
        fresnel = fresnel_factors(lattice_xy, port)
    terms = _sensor_terms(sensor, p, b, lattice_xy, vmap) * fresnel
    transmittance = np.where(valid, fresnel.reshape(n, -1).mean(axis=1), 0.0)
    k = s * s
    with np.errstate(invalid="ignore", divide="ignore"):
        weight = terms.reshape(n, -1).mean(axis=1) / area
    weights = np.repeat(weight[:, None], k, axis=1)

    def quads(grid: np.ndarray) -> np.ndarray:
        g = grid[:, ::step, ::step]
        q = np.stack([g[:, :-1, :-1], g[:, :-1, 1:], g[:, 1:, 1:], g[:, 1:, :-1]], axis=3)
        return np.ascontiguousarray(q.reshape(n, k, 4, 3))

    corners = quads(lattice)
    corners[~valid] = np.nan
    exits_mean = quad_corner_means(quads(exits))
    exits_mean[~valid] = np.nan
    weights = np.where(valid[:, None], weights, 0.0)
    area = np.where(valid, area, np.nan)
    normals = np.zeros((n, 3))
    normals[:, 2] = 1.0
    normals[~valid] = np.nan
    return Footprints(
        p,
        corners,
        np.ascontiguousarray(weights),
        valid,
        area,
        normals_world=normals,
        sensor=sensor,
        port_exits_world=exits_mean,
        port_transmittance=transmittance,
    )


def image_footprints_through_port(
    camera: Camera,
    view: View,
    port: FlatPort,
    *,
    sensor: SensorModel = "radiance",
    vignetting: np.ndarray | None = None,
    binning: int = 1,
) -> Footprints:
    """`port_footprints` of every super-pixel of the image, row by row (exact quads:
    b per side): read from the camera's lattice traced through the port once per
    (camera, port) (`camera_port_rays`, cached), moved to the view."""
    if sensor == "paper":
        return port_footprints(camera, view, np.zeros((0, 2), np.int64), port, sensor=sensor)
    hb, wb = camera.height // int(binning), camera.width // int(binning)
    v, u = np.mgrid[0:hb, 0:wb]
    pixels = np.stack([u.ravel(), v.ravel()], axis=1)
    whole = port_footprints(
        camera, view, pixels, port, sensor=sensor, vignetting=vignetting, binning=binning,
        max_quads_per_side=None,
    )  # fmt: skip
    return replace(whole, image_shape=(hb, wb))  # a ported light's veil on a node grid


_RAYS: OrderedDict[tuple[bytes, tuple[float, ...]], tuple[np.ndarray, ...]] = OrderedDict()
"""`camera_port_rays`' cache."""
_RAYS_LOCK = Lock()
_RAYS_KEPT = 2
_RAYS_MAX_CORNERS = 4_000_000
"""Lattices kept only up to this many corners (~300 MB: a 4 MP camera, or a larger one
binned as the page renders it); a larger one is traced again each time."""


def camera_port_rays(
    camera: Camera, port: FlatPort
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Every pixel corner's ray through the port, camera frame: exit points and water
    directions (H+1, W+1, 3) (NaN where not ok), undistorted coordinates (H+1, W+1, 2)
    and ok (H+1, W+1), and every pixel's `fresnel_factors` (H, W); the last
    `_RAYS_KEPT` (camera, port) pairs cached, up to `_RAYS_MAX_CORNERS` corners. The
    whole image's footprints here and its fused kernel (`kernels.port_image`) share them."""
    key = _rays_key(camera, port)
    with _RAYS_LOCK:
        cached = _RAYS.get(key)
        if cached is not None:
            _RAYS.move_to_end(key)
            return cached  # type: ignore[return-value]
    grid_xy, grid_ok = GRID_CACHE.get(camera)
    rays = np.concatenate([grid_xy, np.ones((*grid_xy.shape[:2], 1))], axis=2)
    exits, dirs, through = port.trace(rays.reshape(-1, 3))
    ok = grid_ok & through.reshape(grid_ok.shape)
    xy = np.where(grid_ok[..., None], grid_xy, np.nan)
    fresnel = fresnel_factors(xy[None], port)[0]
    value = (exits.reshape(rays.shape), dirs.reshape(rays.shape), grid_xy, ok, fresnel)
    if ok.size > _RAYS_MAX_CORNERS:
        return value
    with _RAYS_LOCK:
        _RAYS[key] = value
        while len(_RAYS) > _RAYS_KEPT:
            _RAYS.popitem(last=False)
    return value


def _rays_key(camera: Camera, port: FlatPort) -> tuple[bytes, tuple[float, ...]]:
    """`camera_port_rays`' cache key: what the camera's grid depends on, and the port."""
    return (
        GRID_CACHE.key(camera),
        (port.distance_m, port.thickness_m, port.glass_index, port.water_index,
         port.air_index, *port.normal_camera),
    )  # fmt: skip


def port_transmittance_image(camera: Camera, port: FlatPort) -> np.ndarray:
    """(H, W) the port's Fresnel transmittance of every pixel's rays (`fresnel_factors`
    of the camera's corner lattice, cached with it; NaN where a corner fails)."""
    return camera_port_rays(camera, port)[4]


def fresnel_factors(lattice_xy: np.ndarray, port: FlatPort) -> np.ndarray:
    """(N, b, b) the port's Fresnel transmittance of each member pixel's ray.

    Args:
        lattice_xy: (N, b + 1, b + 1, 2) the undistorted normalised coordinates of the
            super-pixels' corner lattices (NaN where a corner did not undistort).
        port: the camera's flat port.

    The ray of a pixel is that through the mean of its four corners' coordinates (the
    ray `cos4` takes); its angle to the port's normal in the air fixes the angles in
    the glass and the water; a port of thickness 0 is one interface air -> water. NaN
    corners give NaN (the pixel is invalid anyway).
    """
    xy = lattice_xy
    mean = (xy[:, :-1, :-1] + xy[:, :-1, 1:] + xy[:, 1:, 1:] + xy[:, 1:, :-1]) / 4.0
    rays = np.concatenate([mean, np.ones((*mean.shape[:-1], 1))], axis=-1)
    with np.errstate(invalid="ignore"):
        cos_air = (rays @ port.normal_camera) / np.linalg.norm(rays, axis=-1)
        ok = np.isfinite(cos_air) & (cos_air > 0.0)
        # Thickness 0 is one interface air -> water (no glass), as `FlatPort.trace` has it.
        glass = port.glass_index if port.thickness_m > 0.0 else port.water_index
        t, _ = port_transmittance(
            np.where(ok, cos_air, 1.0).ravel(), port.air_index, glass, port.water_index
        )
    return np.where(ok, t.reshape(cos_air.shape), np.nan)


def _sensor_terms(
    sensor: SensorModel, pixels: np.ndarray, b: int, lattice_xy: np.ndarray, vmap: np.ndarray | None
) -> np.ndarray:
    """(N, b, b) each member pixel's sensor term: `radiance` 1, `cos4` cos^4 of its mean
    undistorted corner (the ray's angle in the air), `map` V(u, v)."""
    n = pixels.shape[0]
    if sensor == "radiance":
        return np.ones((n, b, b))
    if sensor == "cos4":
        xy = lattice_xy
        mean = (xy[:, :-1, :-1] + xy[:, :-1, 1:] + xy[:, 1:, 1:] + xy[:, 1:, :-1]) / 4.0
        cos2 = 1.0 / (1.0 + np.sum(mean * mean, axis=-1))
        return np.asarray(cos2 * cos2)
    assert sensor == "map" and vmap is not None
    offs = np.arange(b)
    rows = pixels[:, 1, None, None] * b + offs[None, :, None]
    cols = pixels[:, 0, None, None] * b + offs[None, None, :]
    return np.asarray(vmap[rows, cols])
