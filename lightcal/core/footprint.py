"""Pixel footprints on the wall and the light-independent sensor weights.

A pixel (u, v) covers [u - 1/2, u + 1/2] x [v - 1/2, v + 1/2] (OpenCV: centres at
integers). Its four corners are undistorted, turned into rays and intersected with the
wall z = 0: the footprint quad. A pixel whose corner ray misses the wall (or fails to
undistort) is invalid. A super-pixel of a b x b binned image is the union of its b^2
pixels' footprints. Up to `MAX_QUADS_PER_SIDE` pixels a side it is represented by those
b^2 quads, so its flux is exact; beyond, its pixels are merged into s x s groups of
g x g (b = s g, `quads_per_side`), each group one quad with the group's outer corners and
the mean of its members' sensor weights (a weight multiplies flux; the group's flux is
its members' sum). Solid angle is additive, so only the RID's and the sensor weights'
variation inside a group is approximated (`tests/test_footprint_merge.py`); validity,
area and the members' sensor terms (cos^4, the map) stay the members'.

Sensor models (docs/model.md, step 5); a pixel's value is
offset + gain * sum_lights scale * sum_k weight_k * Phi_k / I0 over its quads k, with

- ``radiance``: weight = 1 / A (A the footprint's area): irradiance, V = 1;
- ``cos4``: weight = cos^4(alpha) / A, alpha the angle between the optical axis and the
  ray through the mean of the pixel's undistorted corner coordinates;
- ``map``: weight = V(u, v) / A with V a per-pixel fall-off map (H, W);
- ``paper``: weight_k = cos(theta_v) / d^2 / b^2 per quad (d the distance from the quad's
  centroid to the camera centre, theta_v the viewing angle from the wall normal).

For the first three a super-pixel uses the mean V of its pixels and the union's area:
the value of one big pixel. `paper` values of a super-pixel are the mean of its pixels'.

The work is one parallel compiled pass (`footprint_kernels`) that writes the outputs
directly. A dense selection reads its corners from the camera's cached corner grid
(`corner_grid`, built once per camera); a sparse one undistorts its own corners. Both give
the same valid pixels and, from the same corners, the same arithmetic; the grid's corners
agree with the direct undistortion to round-off (~1e-15 in normalised coordinates, not bit
for bit: the grid seeds each corner from its neighbours). A sparse selection keeps its
quads (96 bytes each); a dense one does not (for 9.5 M pixels that was 0.9 GB): its
`Footprints` hold the grid and the view (`GridCorners`), and the kernels that need the
quads recompute them from there per block of pixels (a wall intersection per corner, cheap
beside the flux it feeds).
"""

from __future__ import annotations

import functools
from dataclasses import dataclass
from typing import Literal

import numba
import numpy as np

from lightcal.core import footprint_grid_kernels as gk
from lightcal.core import footprint_kernels as fk
from lightcal.core.camera import Camera
from lightcal.core.corner_grid import GRID_CACHE, CornerGrid
from lightcal.core.kernels.sensor import (
    SENSOR_COS4,
    SENSOR_MAP,
    SENSOR_PAPER,
    SENSOR_RADIANCE,
)
from lightcal.core.scene import View

SensorModel = Literal["radiance", "cos4", "paper", "map"]
SENSOR_MODELS: tuple[SensorModel, ...] = ("radiance", "cos4", "paper", "map")

SENSOR_CODES = {
    "radiance": SENSOR_RADIANCE,
    "cos4": SENSOR_COS4,
    "paper": SENSOR_PAPER,
    "map": SENSOR_MAP,
}
"""The kernels' code of each sensor model."""

MAX_QUADS_PER_SIDE = 2
"""At most this many footprint quads per side of a super-pixel (`quads_per_side`): a
super-pixel of b x b pixels is integrated over (b / g)^2 quads of g x g pixels each,
g = b / MAX_QUADS_PER_SIDE when that divides evenly (solid angle is additive: only the
RID's and the sensor weights' variation inside a group is approximated; docs/model.md)."""

GRID_MIN_CORNER_SHARE = 0.5
"""Build the camera's corner grid for a selection whose own corners number at least this
share of the grid's (H+1)(W+1) (see `_corner_grid_for`)."""

# Placeholders for the kernel's unused grid / map arguments.
_NO_GRID: CornerGrid = (np.zeros((1, 1, 2)), np.zeros((1, 1), dtype=np.bool_))
_NO_MAP = np.ones((1, 1))


@dataclass(frozen=True, eq=False)
class GridCorners:
    """Where the corners of a view's footprints come from when they are not kept: the
    camera's undistorted corner grid and the view's pose (the quads are recomputed from
    them, bit for bit, by the kernels that need them; `footprint_grid_kernels`).

    Attributes:
        grid_xy: (H+1, W+1, 2) the camera's corner grid, undistorted normalised
            coordinates (`corner_grid`; shared, read-only by convention).
        grid_ok: (H+1, W+1) its validity.
        R_camera_world: (3, 3) the view's rotation.
        center_world: (3,) the camera centre, m.
        binning: the super-pixel side in cells of `grid_xy`: its quads per side. With
            merged quads (`quads_per_side`: g x g pixels a quad) the grid is the camera's
            taken at every g-th corner (`_strided_grid`), so a super-pixel of b pixels
            spans b / g of its cells.
    """

    grid_xy: np.ndarray
    grid_ok: np.ndarray
    R_camera_world: np.ndarray
    center_world: np.ndarray
    binning: int

    def quads(self, pixels: np.ndarray) -> np.ndarray:
        """(N, s^2, 4, 3) the footprint quads of `pixels` (N, 2), world frame, m."""
        out = np.empty((pixels.shape[0], self.binning**2, 4, 3))
        kernel = gk.grid_corners_parallel if len(pixels) > 4096 else gk.grid_corners_serial
        kernel(pixels, self.binning, *self._args(), out)
        return out

    def centers(self, pixels: np.ndarray) -> np.ndarray:
        """(N, 3) the means of the quads' corners of `pixels` (`quad_corner_means`)."""
        out = np.empty((pixels.shape[0], 3))
        chunk = max(1, fk.CHUNK_CORNERS // (4 * self.binning**2))
        with numba.parallel_chunksize(1):
            gk.grid_centers_parallel(pixels, self.binning, *self._args(), chunk, out)
        return out

    def _args(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        return self.grid_xy, self.grid_ok, self.R_camera_world, self.center_world


@dataclass(frozen=True, eq=False)
class Footprints:
    """Footprints of N (super-)pixels of one view.

    The quads are either kept (`stored_corners`, 96 bytes a quad: a sparse selection) or
    read from the camera's corner grid when needed (`grid`: a dense selection, whose
    pixels share corners; the solver's kernels read them from there).

    Attributes:
        pixels: (N, 2) int32 pixel indices (u, v) in the (binned) image.
        stored_corners: (N, K, 4, 3) the K = s^2 footprint quads of each pixel
            (`quads_per_side`: s = b unless merged), world frame, m (NaN for invalid
            pixels), or None when `grid` gives them.
        weights: (N, K) sensor weight of each quad (0 for invalid pixels).
        valid: (N,) pixels whose every corner ray hits the wall in front of the camera.
        area_m2: (N,) footprint area (the union's), m^2.
        grid: where the quads come from when they are not kept, else None.
        normals_world: (N, 3) on a wall mesh (`lightcal.core.wall_mesh`), each
            footprint's unit normal (its vector area) turned towards the camera (NaN for
            invalid pixels): a light lights the pixel only on that side. None on the
            plane z = 0 (normal +z).
        sensor: the sensor model the weights carry.
        port_exits_world: (N, 3) behind the camera's flat port
            (`lightcal.core.port_footprints`), where each pixel's rays leave the port
            into the water (the mean of its corners' exit points, as the centre is of
            its corners), world frame, m: the camera side's path in the medium starts
            there (`camera_side`). None without a port (the camera centre).
        port_transmittance: (N,) behind the camera's flat port, the port's Fresnel
            transmittance of each pixel's rays (the mean over its member pixels; 0 where
            invalid): what the water's veil and the room light seen through the port
            carry (the wall's light carries it in `weights`). None without a port.
        image_shape: (hb, wb) when these are every pixel of a whole (binned) image in
            row-major order, as the whole-image renderers build them: a ported light's
            veil is then computed on `medium.scatter_grid`'s nodes and interpolated
            (`light_port_veil.add_port_veil`); None (any selection, the solver's) for
            every pixel's own.
    """

    pixels: np.ndarray
    stored_corners: np.ndarray | None
    weights: np.ndarray
    valid: np.ndarray
    area_m2: np.ndarray
    grid: GridCorners | None = None
    normals_world: np.ndarray | None = None
    sensor: SensorModel = "radiance"
    port_exits_world: np.ndarray | None = None
    port_transmittance: np.ndarray | None = None
    image_shape: tuple[int, int] | None = None

    def __post_init__(self) -> None:
        if (self.stored_corners is None) == (self.grid is None):
            raise ValueError("footprints: expected either stored corners or a corner grid")

    def __len__(self) -> int:
        return int(self.pixels.shape[0])

    @property
    def corners_world(self) -> np.ndarray:
        """(N, K, 4, 3) the footprint quads, world frame, m (NaN for invalid pixels).

        Kept ones as they are; otherwise computed from the corner grid on each access
        (N K x 96 bytes): the solver's kernels do not need them.
        """
        if self.stored_corners is not None:
            return self.stored_corners
        assert self.grid is not None
        quads = self.grid.quads(self.pixels)
        # Merged quads read only the groups' corners: a pixel made invalid by a member's
        # inner corner is NaN as its kept quads are.
        quads[~self.valid] = np.nan
        return quads

    def subset(self, rows: np.ndarray | slice) -> Footprints:
        """The footprints of rows (k,) (indices, a boolean mask or a slice: views) of these
        pixels."""
        return Footprints(
            self.pixels[rows],
            None if self.stored_corners is None else self.stored_corners[rows],
            self.weights[rows],
            self.valid[rows],
            self.area_m2[rows],
            self.grid,
            None if self.normals_world is None else self.normals_world[rows],
            self.sensor,
            None if self.port_exits_world is None else self.port_exits_world[rows],
            None if self.port_transmittance is None else self.port_transmittance[rows],
        )

    def camera_side(self, center_world: np.ndarray) -> np.ndarray:
        """Where the rays to the footprints start in the medium: the camera centre
        `center_world` (3,) itself, or behind a flat port each pixel's exit point from
        it (N, 3) (`port_exits_world`), world frame, m."""
        return center_world if self.port_exits_world is None else self.port_exits_world

    @property
    def room_light_factor(self) -> np.ndarray | None:
        """(N,) what the sensor model makes of a uniform unit radiance on the wall (room
        light): its fall-off at each pixel, cos^4 or the map's mean V (a quad's weight
        times the footprint's area: V / A x A); None for `radiance` (1) and `paper`,
        whose values are not radiances (the room light is then taken as uniform); behind
        a flat port `radiance`'s is the port's transmittance (`port_transmittance`)."""
        if self.sensor == "radiance" and self.port_transmittance is not None:
            return np.where(self.valid, self.port_transmittance, 0.0)
        if self.sensor not in ("cos4", "map"):
            return None
        return np.where(self.valid, self.weights[:, 0] * self.area_m2, 0.0)

    @functools.cached_property
    def centers_world(self) -> np.ndarray:
        """(N, 3) footprint centres (the mean of all quad corners), world frame, m.

        Where the wall's reflectance is evaluated (`lightcal.core.wall`); NaN if invalid.
        Kept once computed (the wall models read them every evaluation); `centers_now`
        gives them without keeping them.
        """
        return self._centers()

    def centers_now(self) -> np.ndarray:
        """`centers_world` if already kept, else computed and not kept (N x 24 bytes)."""
        kept = self.__dict__.get("centers_world")  # functools.cached_property's slot
        return kept if kept is not None else self._centers()

    def _centers(self) -> np.ndarray:
        if self.stored_corners is not None:
            return quad_corner_means(self.stored_corners)
        assert self.grid is not None
        centers = self.grid.centers(self.pixels)
        # Merged quads read only the groups' corners: a pixel made invalid by a member's
        # inner corner is NaN as its kept quads would be.
        centers[~self.valid] = np.nan
        return centers


def quad_corner_means(corners_world: np.ndarray) -> np.ndarray:
    """(N, 3) means of the K * 4 corners of each pixel of corners_world (N, K, 4, 3).

    A running sum over the few corners (numpy's `mean(axis=1)` over a short strided axis
    is several times slower; the same additions in the same order, bit for bit).
    """
    n = corners_world.shape[0]
    corners = corners_world.reshape(n, -1, 3)
    total = corners[:, 0].copy()
    for j in range(1, corners.shape[1]):
        total += corners[:, j]
    total /= corners.shape[1]
    return total


def check_pixels(pixels: np.ndarray, width: int, height: int, name: str = "pixels") -> np.ndarray:
    """Validate (N, 2) integer pixel indices inside a width x height image; returns int64."""
    p = np.asarray(pixels)
    if p.ndim != 2 or p.shape[1] != 2:
        raise ValueError(f"{name}: expected an (N, 2) array of (u, v) indices, got shape {p.shape}")
    if p.dtype.kind == "f":
        if not np.all(np.isfinite(p)) or np.any(p != np.round(p)):
            raise ValueError(
                f"{name}: expected integer pixel indices (pixel centres are at integers)"
            )
    elif p.dtype.kind not in "iu":
        raise ValueError(f"{name}: expected integer pixel indices, got dtype {p.dtype}")
    p = p.astype(np.int64)
    bad = (p[:, 0] < 0) | (p[:, 0] >= width) | (p[:, 1] < 0) | (p[:, 1] >= height)
    if np.any(bad):
        i = int(np.argmax(bad))
        raise ValueError(
            f"{name}: pixel ({p[i, 0]}, {p[i, 1]}) lies outside the {width}x{height} image"
        )
    return p


def pixel_footprints(
    camera: Camera,
    view: View,
    pixels: np.ndarray,
    *,
    sensor: SensorModel = "radiance",
    vignetting: np.ndarray | None = None,
    binning: int = 1,
    max_quads_per_side: int | None = MAX_QUADS_PER_SIDE,
) -> Footprints:
    """Footprints and sensor weights of (super-)pixels.

    Args:
        camera: intrinsics of the full-resolution image.
        view: its pose.
        pixels: (N, 2) integer (u, v) indices in the image binned by `binning`.
        sensor: the sensor fall-off model (module docstring).
        vignetting: (H, W) fall-off map of the full-resolution image, for sensor "map".
        binning: b >= 1; super-pixel (u, v) covers pixels [u b, u b + b) x [v b, v b + b).
        max_quads_per_side: merge a super-pixel's pixels into at most this many quads per
            side (`quads_per_side`); None: one quad per pixel (exact).

    Returns:
        The footprints: K = s^2 quads per pixel, s = `quads_per_side(b, ...)`.
    """
    b, p, vmap, s = checked_selection(
        camera, pixels, sensor, vignetting, binning, max_quads_per_side
    )
    vmap = _NO_MAP if vmap is None else vmap
    n = p.shape[0]
    step = b // s
    k = s * s
    grid = _corner_grid_for(camera, n, b)
    grid_xy, grid_ok = _NO_GRID if grid is None else grid
    # With the grid the quads are not kept: the kernels that need them read the grid.
    corners = np.empty((n, k, 4, 3) if grid is None else (1, 1, 4, 3))
    weights = np.empty((n, k))
    valid = np.empty(n, dtype=np.bool_)
    area = np.empty(n)
    # Writable copies (a few numbers): numba compiles once per read-only flag, and
    # cameras and views hold read-only or writable arrays depending on their origin.
    R_camera_world = np.array(view.R_camera_world, dtype=np.float64)
    center_world = np.array(view.center_world, dtype=np.float64)
    args = (
        p,
        b,
        step,
        grid is not None,
        grid_xy,
        grid_ok,
        np.array(camera.K, dtype=np.float64),
        np.array(camera.dist, dtype=np.float64),
        R_camera_world,
        center_world,
        SENSOR_CODES[sensor],
        vmap,
        grid is None,
    )
    outputs = (corners, weights, valid, area)
    chunk_pixels = max(1, fk.CHUNK_CORNERS // (b + 1) ** 2)
    if n <= chunk_pixels:
        fk.pixel_footprints_serial(*args, *outputs)
    else:
        # Dynamic scheduling of the chunks: the machine's cores may be shared.
        with numba.parallel_chunksize(1):
            fk.pixel_footprints_parallel(*args, chunk_pixels, *outputs)
    if grid is None:
        return Footprints(p, corners, weights, valid, area, sensor=sensor)
    if step > 1:
        grid_xy, grid_ok = _strided_grid(grid_xy, grid_ok, step)
    source = GridCorners(grid_xy, grid_ok, R_camera_world, center_world, s)
    return Footprints(p, None, weights, valid, area, source, sensor=sensor)


def checked_selection(
    camera: Camera,
    pixels: np.ndarray,
    sensor: SensorModel,
    vignetting: np.ndarray | None,
    binning: int,
    max_quads_per_side: int | None,
) -> tuple[int, np.ndarray, np.ndarray | None, int]:
    """`pixel_footprints`' arguments checked: (b, the pixels (N, 2) int32, the map for
    `map` or None, s = `quads_per_side`); ValueError naming the argument otherwise."""
    if not (isinstance(binning, int | np.integer) and binning >= 1):
        raise ValueError(f"binning: expected an integer >= 1, got {binning!r}")
    if sensor not in SENSOR_MODELS:
        raise ValueError(f"sensor: expected one of {', '.join(SENSOR_MODELS)}, got {sensor!r}")
    b = int(binning)
    # int32: 8 bytes a pixel less than check_pixels' int64 (images are < 2^31 pixels wide).
    p = check_pixels(pixels, camera.width // b, camera.height // b).astype(np.int32)
    vmap = check_vignetting(vignetting, camera) if sensor == "map" else None
    return b, p, vmap, quads_per_side(b, max_quads_per_side)


def quads_per_side(binning: int, max_quads_per_side: int | None = MAX_QUADS_PER_SIDE) -> int:
    """s, the footprint quads per side of a super-pixel of b = `binning` pixels.

    b itself (one quad per pixel: exact) when b <= max_quads_per_side, when it is None or
    when max_quads_per_side does not divide b; else max_quads_per_side, each quad covering
    g x g pixels, g = b / s.
    """
    b = int(binning)
    if max_quads_per_side is None:
        return b
    m = int(max_quads_per_side)
    if m < 1:
        raise ValueError(f"max_quads_per_side: expected an integer >= 1, got {m}")
    return m if b > m and b % m == 0 else b


_STRIDED: list[tuple[np.ndarray, int, CornerGrid]] = []


def _strided_grid(grid_xy: np.ndarray, grid_ok: np.ndarray, step: int) -> CornerGrid:
    """The corner grid at every `step`-th corner (contiguous; kept for the last grid
    asked: the views of a project share their camera's grid)."""
    for source, g, strided in _STRIDED:
        if source is grid_xy and g == step:
            return strided
    strided = (
        np.ascontiguousarray(grid_xy[::step, ::step]),
        np.ascontiguousarray(grid_ok[::step, ::step]),
    )
    _STRIDED[:] = [(grid_xy, step, strided)]
    return strided


def _corner_grid_for(camera: Camera, n_pixels: int, binning: int) -> CornerGrid | None:
    """The camera's corner grid when reading the corners from it pays, else None.

    A cached grid always pays (a look-up is ~10x cheaper than an undistortion). Otherwise
    the direct path undistorts the (b+1)^2 corners of each of the n_pixels super-pixels,
    the grid (H+1)(W+1) corners once per camera (it is cached for the next views). It is
    built when the selection's corners number at least `GRID_MIN_CORNER_SHARE` of the
    grid's: the following views of the camera are then ~4x cheaper (every pixel of a
    binning-1 image: 0.04 s instead of 0.4 s of CPU for 375,000 pixels); a sparse
    selection on a large sensor undistorts only its own corners. (The share was set when
    the grid cost about as much per corner as the direct path; since issue 12 a grid
    corner is ~20x cheaper, so the first call with the grid costs well under the direct
    path's.)
    """
    grid = GRID_CACHE.lookup(camera)
    n_corners = n_pixels * (binning + 1) ** 2
    n_grid = (camera.height + 1) * (camera.width + 1)
    if grid is None and n_corners >= GRID_MIN_CORNER_SHARE * n_grid:
        grid = GRID_CACHE.get(camera)
    return grid


def check_vignetting(vignetting: np.ndarray | None, camera: Camera) -> np.ndarray:
    """Validate a (H, W) fall-off map for the `map` sensor model."""
    if vignetting is None:
        raise ValueError("vignetting: the 'map' sensor model needs a fall-off map, got none")
    v = np.asarray(vignetting, dtype=np.float64)
    if v.shape != (camera.height, camera.width):
        raise ValueError(
            f"vignetting: expected a map of shape ({camera.height}, {camera.width}) "
            f"(the camera's image), got {v.shape}"
        )
    if not np.all(np.isfinite(v)) or np.any(v <= 0.0):
        raise ValueError("vignetting: expected finite values > 0")
    return np.ascontiguousarray(v)


def room_light_image(
    camera: Camera, sensor: SensorModel, vignetting: np.ndarray | None = None
) -> np.ndarray | None:
    """(H, W) `Footprints.room_light_factor` of every full-resolution pixel: cos^4 of the
    angle of the ray through the mean of its undistorted corners (`cos4`), the map
    (`map`); None for `radiance` and `paper` (uniform). NaN where a corner fails."""
    if sensor == "map":
        return check_vignetting(vignetting, camera)
    if sensor != "cos4":
        return None
    grid_xy, grid_ok = GRID_CACHE.get(camera)
    ok = grid_ok[:-1, :-1] & grid_ok[:-1, 1:] & grid_ok[1:, 1:] & grid_ok[1:, :-1]
    mean = (grid_xy[:-1, :-1] + grid_xy[:-1, 1:] + grid_xy[1:, 1:] + grid_xy[1:, :-1]) / 4.0
    cos2 = 1.0 / (1.0 + np.sum(mean * mean, axis=-1))
    return np.where(ok, cos2 * cos2, np.nan)
