"""A non-planar target given as a triangle mesh, and pixel footprints on it.

The planar model (docs/model.md) takes the wall as the plane z = 0. A `WallMesh` is the
wall's true shape (a bowed wall, a seafloor patch from SfM) in the same world frame:
metres, the cameras at z > 0 looking at it. Footprints on it (`mesh_footprints`) are
built as on the plane: each pixel corner's ray, undistorted and back-projected, meets
the mesh exactly (the nearest triangle it hits, `lightcal.core.mesh_kernels`); the four
hits of a pixel make its footprint quad, now a quad in 3-D. What follows is the planar
model's:

- the flux on a quad is the light's intensity integrated over its solid angle (two
  spherical triangles), exact for any quad in 3-D (`kernels.quad_flux.quad_flux`: quads
  off the plane z = 0 never take the plane's fast paths);
- the irradiance divides the flux by the quad's true area, 0.5 |(P3 - P1) x (P4 - P2)|
  (the vector area; for a planar quad its area exactly);
- a Lambertian wall's radiance is rho / pi times the irradiance, whatever its normal;
  the other reflectance models' B takes each footprint's own normal
  (`apply_wall_on_mesh`).

What is approximated: a pixel whose four corner rays meet different triangles gets the
quad through its four hits, not the mesh's crease inside it (second order in the
footprint's size over the crease's radius); the mesh's own shadows on itself are not
modelled. A light lights a pixel only when it lies in front of the footprint's plane
(on the camera's side of it: `Footprints.normals_world`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from lightcal.core import mesh_kernels as mk
from lightcal.core.camera import Camera
from lightcal.core.flat_port import FlatPort
from lightcal.core.footprint import (
    MAX_QUADS_PER_SIDE,
    Footprints,
    SensorModel,
    checked_selection,
    pixel_footprints,
)
from lightcal.core.kernels.wall import MU_FLOOR, brdf_many
from lightcal.core.port_footprints import port_footprints
from lightcal.core.scene import View
from lightcal.core.wall import WallReflectance

#: Rays per bucket of the ray sort, on average (`mesh_kernels.bucket_rays`).
RAYS_PER_BUCKET = 4


@dataclass(frozen=True, eq=False)
class WallMesh:
    """A triangle mesh of the wall, world frame, metres.

    Args:
        vertices_world: (V, 3) vertex positions, finite.
        faces: (F, 3) vertex indices of each triangle (F >= 1), in range.
    """

    vertices_world: np.ndarray
    faces: np.ndarray
    z_range_m: tuple[float, float] = field(init=False)

    def __post_init__(self) -> None:
        v = np.asarray(self.vertices_world, dtype=np.float64)
        f = np.asarray(self.faces)
        if v.ndim != 2 or v.shape[1] != 3 or v.shape[0] < 3:
            raise ValueError(
                f"vertices: expected an (V, 3) array of V >= 3 points, got shape {v.shape}"
            )
        if f.ndim != 2 or f.shape[1] != 3 or f.shape[0] < 1:
            raise ValueError(f"faces: expected an (F, 3) array of F >= 1 triangles, got {f.shape}")
        if f.dtype.kind not in "iu":
            raise ValueError(f"faces: expected integer vertex indices, got dtype {f.dtype}")
        if not np.all(np.isfinite(v)):
            bad = int(np.argmax(~np.all(np.isfinite(v), axis=1)))
            raise ValueError(f"vertices: expected finite coordinates, vertex {bad} is {v[bad]}")
        if f.min() < 0 or f.max() >= v.shape[0]:
            raise ValueError(
                f"faces: expected vertex indices in 0..{v.shape[0] - 1}, got "
                f"{int(f.min())}..{int(f.max())}"
            )
        object.__setattr__(self, "vertices_world", np.ascontiguousarray(v))
        object.__setattr__(self, "faces", np.ascontiguousarray(f, dtype=np.int64))
        used = self.vertices_world[self.faces.ravel()]
        object.__setattr__(self, "z_range_m", (float(used[:, 2].min()), float(used[:, 2].max())))

    def intersect(
        self, view: View, xy: np.ndarray, ok: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """Where the rays of undistorted normalised coordinates xy (M, 2) from the view's
        camera centre first meet the mesh.

        Args:
            view: the camera pose.
            xy: (M, 2) undistorted normalised coordinates of the rays.
            ok: (M,) the rays to trace (others miss).

        Returns:
            points_world: (M, 3) the hits, m (NaN on a miss).
            hit: (M,) the ray meets a triangle in front of the camera.
        """
        m = xy.shape[0]
        points = np.full((m, 3), np.nan)
        t = np.full(m, np.inf)
        face = np.full(m, -1, dtype=np.int64)
        ok = np.asarray(ok, dtype=np.bool_) & np.all(np.isfinite(xy), axis=1)
        if not np.any(ok):
            return points, np.zeros(m, dtype=np.bool_)
        xs = np.ascontiguousarray(xy[:, 0], dtype=np.float64)
        ys = np.ascontiguousarray(xy[:, 1], dtype=np.float64)
        box = np.array([xs[ok].min(), ys[ok].min(), xs[ok].max(), ys[ok].max()])
        n_side = max(1, int(math.sqrt(int(ok.sum()) / RAYS_PER_BUCKET)))
        start, items = mk.bucket_rays(xs, ys, ok, n_side, n_side, box)
        mk.intersect_rays(
            self.vertices_world,
            self.faces,
            np.ascontiguousarray(view.R_camera_world, dtype=np.float64),
            np.ascontiguousarray(view.center_world, dtype=np.float64),
            xs,
            ys,
            ok,
            n_side,
            n_side,
            box,
            start,
            items,
            points,
            t,
            face,
        )
        return points, np.isfinite(t)


def mesh_footprints(
    camera: Camera,
    view: View,
    pixels: np.ndarray,
    mesh: WallMesh,
    *,
    sensor: SensorModel = "radiance",
    vignetting: np.ndarray | None = None,
    binning: int = 1,
    max_quads_per_side: int | None = MAX_QUADS_PER_SIDE,
) -> Footprints:
    """Footprints and sensor weights of (super-)pixels on a mesh (`pixel_footprints`'
    arguments, the plane replaced by `mesh`; its quads are kept, with the footprints'
    normals).

    A super-pixel is valid when every corner of its b x b pixels hits the mesh; its
    area is the sum of its pixels' quads' areas; merged quads (`quads_per_side`) take
    the groups' outer corners, as on the plane. The `paper` weight cos(theta_v) / d^2
    takes theta_v from the quad's own normal.
    """
    b, p, vmap, s = checked_selection(
        camera, pixels, sensor, vignetting, binning, max_quads_per_side
    )
    step = b // s
    n = p.shape[0]
    # The (b+1)^2 lattice of each super-pixel's corners, as full-resolution corner
    # indices (row, col): corner (r, c) sits at pixel coordinates (c - 1/2, r - 1/2).
    offs = np.arange(b + 1)
    rows = p[:, 1, None, None] * b + offs[None, :, None]
    cols = p[:, 0, None, None] * b + offs[None, None, :]
    keys = (rows * (camera.width + 1) + cols).ravel().astype(np.int64)
    unique, inverse = np.unique(keys, return_inverse=True)
    corner_px = np.stack(
        [unique % (camera.width + 1) - 0.5, unique // (camera.width + 1) - 0.5], axis=1
    ).astype(np.float64)
    xy, ok = camera.pixels_to_normalized(corner_px)
    points, hit = mesh.intersect(view, xy, ok)
    lattice = points[inverse].reshape(n, b + 1, b + 1, 3)
    lattice_xy = xy[inverse].reshape(n, b + 1, b + 1, 2)
    valid = np.asarray(hit[inverse].reshape(n, -1).all(axis=1), dtype=np.bool_)
    # Member quads P1..P4 = lattice (j, i), (j, i+1), (j+1, i+1), (j+1, i).
    q1, q2 = lattice[:, :-1, :-1], lattice[:, :-1, 1:]
    q3, q4 = lattice[:, 1:, 1:], lattice[:, 1:, :-1]
    vector_area = 0.5 * np.cross(q3 - q1, q4 - q2)  # (n, b, b, 3)
    member_area = np.linalg.norm(vector_area, axis=-1)
    area = member_area.reshape(n, -1).sum(axis=1)
    # The footprint's normal: its vector area, turned towards the camera.
    normal = vector_area.reshape(n, -1, 3).sum(axis=1)
    centroid = lattice.reshape(n, -1, 3).mean(axis=1)
    flip = np.einsum("ij,ij->i", normal, view.center_world - centroid) < 0.0
    normal[flip] *= -1.0
    with np.errstate(invalid="ignore", divide="ignore"):
        normal /= np.linalg.norm(normal, axis=1, keepdims=True)
        terms = _sensor_terms(sensor, view, p, b, lattice, lattice_xy, normal, vmap)
    k = s * s
    if sensor == "paper":  # a group's weight: the mean of its members'
        weights = terms.reshape(n, s, step, s, step).mean(axis=(2, 4)).reshape(n, k)
    else:
        v_mean = terms.reshape(n, -1).mean(axis=1)
        with np.errstate(invalid="ignore", divide="ignore"):
            weights = np.repeat((v_mean / area)[:, None], k, axis=1)
    g = lattice[:, ::step, ::step]
    corners = np.stack(
        [g[:, :-1, :-1], g[:, :-1, 1:], g[:, 1:, 1:], g[:, 1:, :-1]], axis=3
    ).reshape(n, k, 4, 3)
    corners = np.ascontiguousarray(corners)
    corners[~valid] = np.nan
    weights = np.where(valid[:, None], weights, 0.0)
    area = np.where(valid, area, np.nan)
    normal[~valid] = np.nan
    return Footprints(
        p, corners, np.ascontiguousarray(weights), valid, area, normals_world=normal, sensor=sensor
    )


def wall_footprints(
    camera: Camera,
    view: View,
    pixels: np.ndarray,
    *,
    mesh: WallMesh | None,
    sensor: SensorModel = "radiance",
    vignetting: np.ndarray | None = None,
    binning: int = 1,
    port: FlatPort | None = None,
) -> Footprints:
    """The footprints of pixels on the wall: on `mesh` when given (`mesh_footprints`),
    else on the plane z = 0 (`pixel_footprints`); through the camera's flat `port` when
    given (`lightcal.core.port_footprints`: on the plane only; None: the numbers
    without a port, bit for bit)."""
    if port is not None:
        if mesh is not None:
            raise ValueError(
                "camera port: footprints through a flat port are modelled on the plane "
                "z = 0 only, not on a wall mesh"
            )
        return port_footprints(
            camera, view, pixels, port, sensor=sensor, vignetting=vignetting, binning=binning
        )
    if mesh is None:
        return pixel_footprints(
            camera, view, pixels, sensor=sensor, vignetting=vignetting, binning=binning
        )
    return mesh_footprints(
        camera, view, pixels, mesh, sensor=sensor, vignetting=vignetting, binning=binning
    )


def _sensor_terms(
    sensor: SensorModel,
    view: View,
    pixels: np.ndarray,
    b: int,
    lattice: np.ndarray,
    lattice_xy: np.ndarray,
    normal: np.ndarray,
    vmap: np.ndarray | None,
) -> np.ndarray:
    """(N, b, b) each member pixel's sensor term (docs/model.md, step 5): `radiance` 1,
    `cos4` cos^4 of its mean undistorted corner, `map` V(u, v), `paper`
    cos(theta_v) / d^2 / b^2 (the quad's normal `normal` (N, 3) of the super-pixel)."""
    n = pixels.shape[0]
    if sensor == "radiance":
        return np.ones((n, b, b))
    if sensor == "cos4":
        xy = lattice_xy
        mean = (xy[:, :-1, :-1] + xy[:, :-1, 1:] + xy[:, 1:, 1:] + xy[:, 1:, :-1]) / 4.0
        cos2 = 1.0 / (1.0 + np.sum(mean * mean, axis=-1))
        return np.asarray(cos2 * cos2)
    if sensor == "map":
        assert vmap is not None
        offs = np.arange(b)
        rows = pixels[:, 1, None, None] * b + offs[None, :, None]
        cols = pixels[:, 0, None, None] * b + offs[None, None, :]
        return np.asarray(vmap[rows, cols])
    q = lattice
    centroid = (q[:, :-1, :-1] + q[:, :-1, 1:] + q[:, 1:, 1:] + q[:, 1:, :-1]) / 4.0
    out = view.center_world - centroid
    d2 = np.sum(out * out, axis=-1)
    cos_v = np.einsum("nijk,nk->nij", out, normal) / np.sqrt(d2)
    return np.asarray(cos_v / d2 / (b * b))


def light_behind_mesh(
    footprints: Footprints, L_world: np.ndarray, flux: np.ndarray, grad: np.ndarray | None
) -> None:
    """Zero flux (N,) and grad (N, 6) where the light L_world (3,) is on or behind the
    footprint's plane on a wall mesh (the other side from the camera:
    `Footprints.normals_world`)."""
    assert footprints.normals_world is not None
    with np.errstate(invalid="ignore"):
        facing = np.einsum("ij,ij->i", footprints.normals_world, L_world - footprints.centers_world)
    dark = ~(facing > 0.0)
    flux[dark] = 0.0
    if grad is not None:
        grad[dark] = 0.0


def apply_wall_on_mesh(
    footprints: Footprints,
    L_world: np.ndarray,
    camera_world: np.ndarray,
    wall: WallReflectance,
    flux: np.ndarray,
    grad: np.ndarray | None,
    wall_grad_out: np.ndarray | None,
) -> None:
    """`render`'s wall factor on a mesh: flux (N,) *= B at the footprint centres with each
    footprint's own normal n (`Footprints.normals_world`), and the chain rule on grad
    (N, 6) and wall_grad_out (N, P), as `kernels.wall.apply_wall` does with n = +z.
    camera_world: (3,) the camera centre, or (N, 3) where each pixel's ray starts in
    the water behind a flat port (`Footprints.camera_side`).

    B is a function of mu_l = l . n, q = l . v and mu_v = v . n (`kernels.wall.brdf_many`),
    so dB/dL = (I - l l^T) (dB/dmu_l n + dB/dq v) / |L - P|; B and its derivatives are 0
    where the light or the camera is behind the footprint's plane.
    """
    assert footprints.normals_world is not None
    n = footprints.normals_world
    to_light = L_world - footprints.centers_world
    to_camera = camera_world - footprints.centers_world
    with np.errstate(invalid="ignore", divide="ignore"):
        r_l = np.linalg.norm(to_light, axis=1)
        ul = to_light / r_l[:, None]
        uv = to_camera / np.linalg.norm(to_camera, axis=1, keepdims=True)
        mu_l = np.einsum("ij,ij->i", ul, n)
        mu_v = np.einsum("ij,ij->i", uv, n)
        q = np.einsum("ij,ij->i", ul, uv)
        ok = (mu_l > 0.0) & (mu_v > 0.0)
    d = wall.data()
    b, b_mu, b_q, dp = brdf_many(
        np.where(ok, np.maximum(mu_l, MU_FLOOR), MU_FLOOR),
        np.where(ok, q, 0.0),
        np.where(ok, np.maximum(mu_v, MU_FLOOR), MU_FLOOR),
        d.kind,
        d.params,
        d.tables,
    )
    b = np.where(ok, b, 0.0)
    f0 = np.where(ok, flux, 0.0)
    flux[:] = f0 * b
    if grad is None:
        return
    g = np.where(ok, b_mu, 0.0)[:, None] * n + np.where(ok, b_q, 0.0)[:, None] * uv
    lg = np.einsum("ij,ij->i", ul, g)
    with np.errstate(invalid="ignore", divide="ignore"):
        s = np.where(b != 0.0, f0 / r_l, 0.0)
    grad[:, :3] = b[:, None] * grad[:, :3] + s[:, None] * (g - ul * lg[:, None])
    grad[:, 3:] *= b[:, None]
    if wall_grad_out is not None and wall_grad_out.shape[1] > 0:
        wall_grad_out[:] = f0[:, None] * np.where(ok[:, None], dp[:, : wall_grad_out.shape[1]], 0.0)
