"""Synthetic images of a flat texture (a printed board) on the wall, for tests and sample data.

`render_plane_image` ray-casts every pixel of a distorted camera onto the wall z = 0 of the
world frame (docs/conventions.md) and samples a texture placed there, so that a board drawn by
`lightcal.capture.boards` appears exactly where its world coordinates say. `look_at_pose`
builds camera poses that look at a point of the wall.
"""

from __future__ import annotations

import functools
from typing import Any

import cv2
import numpy as np
from numpy.typing import ArrayLike, NDArray

from lightcal.core.camera import Camera

_ROWS_PER_CHUNK = 512
"""Sub-pixel rows back-projected at once (bounds the temporaries of large images)."""


def look_at_pose(
    center_world_m: ArrayLike,
    target_world_m: ArrayLike,
    *,
    up_world: ArrayLike = (0.0, 1.0, 0.0),
    roll_rad: float = 0.0,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """The pose of a camera at `center_world_m` whose optical axis passes through a target.

    The image's "up" (camera -y) is `up_world` projected on the image plane, then the
    camera is rolled by `roll_rad` about its optical axis.

    Args:
        center_world_m: (3,) camera centre in the world frame, metres.
        target_world_m: (3,) world point on the optical axis, metres.
        up_world: (3,) world direction that appears upwards in the image.
        roll_rad: Rotation about the optical axis (camera x towards camera y), radians.

    Returns:
        R_camera_world: (3, 3).
        t_camera_world: (3,), so that X_c = R_camera_world X_w + t_camera_world.
    """
    center = np.asarray(center_world_m, dtype=np.float64)
    forward = np.asarray(target_world_m, dtype=np.float64) - center
    z_c = forward / np.linalg.norm(forward)
    up = np.asarray(up_world, dtype=np.float64)
    down = -(up - (up @ z_c) * z_c)
    y_c = down / np.linalg.norm(down)
    x_c = np.cross(y_c, z_c)
    R = np.stack([x_c, y_c, z_c])
    c, s = np.cos(roll_rad), np.sin(roll_rad)
    R = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]) @ R
    return R, -R @ center


def render_plane_image(
    camera: Camera,
    R_camera_world: ArrayLike,
    t_camera_world: ArrayLike,
    texture: ArrayLike,
    texture_px_per_m: float,
    texture_origin_world_m: ArrayLike,
    *,
    background: float = 0.5,
    supersample: int = 2,
) -> NDArray[np.float64]:
    """Image of a texture lying on the wall z = 0, seen by a distorted camera.

    Each pixel is split into `supersample` x `supersample` sub-pixels whose centres are
    back-projected (`camera.pixels_to_normalized`), intersected with the plane z = 0 and
    looked up in the texture with bilinear interpolation (`cv2.remap`); the pixel value is
    their mean (box-filter anti-aliasing). A texture finer than the sub-pixels' median
    footprint is first area-averaged (`cv2.INTER_AREA`) to about one texel per sub-pixel,
    so that point sampling does not alias; symmetric blurs leave edges in place.
    Sub-pixels whose ray misses the plane, points
    away from it, falls outside the distortion model's valid region or outside the
    texture see `background`.

    Texture placement: texture pixel (col, row) covers the wall square
    x in x0 + [col, col + 1] / px_per_m, y in y0 - [row + 1, row] / px_per_m, with
    (x0, y0) = `texture_origin_world_m` its top-left corner and rows running towards
    world -y (as `lightcal.capture.boards.BoardRendering` places a board). Image pixels follow
    docs/conventions.md (OpenCV): pixel (u, v) has its centre at integer (u, v), so no half-pixel
    shift is needed when these images are fed to OpenCV or to lightcal.

    Args:
        camera: Intrinsics, distortion and image size.
        R_camera_world: (3, 3) world -> camera rotation.
        t_camera_world: (3,) world -> camera translation, metres.
        texture: (h, w) float texture values (e.g. reflectance in [0, 1]).
        texture_px_per_m: Texture pixels per metre on the wall.
        texture_origin_world_m: (2,) world (x, y) of the texture's top-left corner, metres.
        background: Value wherever the texture is not seen.
        supersample: Sub-pixels per pixel side (>= 1).

    Returns:
        image: (camera.height, camera.width) float64.
    """
    if isinstance(supersample, bool) or not isinstance(supersample, int) or supersample < 1:
        raise ValueError(f"supersample: expected an int >= 1, got {supersample!r}")
    R = np.asarray(R_camera_world, dtype=np.float64)
    t = np.asarray(t_camera_world, dtype=np.float64)
    tex: NDArray[Any] = np.ascontiguousarray(np.asarray(texture, dtype=np.float32))
    x0, y0 = np.asarray(texture_origin_world_m, dtype=np.float64)
    n = supersample
    x, y, valid = _subpixel_normalized(
        camera.K.tobytes(), camera.dist.tobytes(), camera.width, camera.height, n
    )
    # The ray (x, y, 1) of the camera frame, X_w = C + lam R^T (x, y, 1), meets z = 0 at
    # lam = -C_z / d_z with d_z = (R^T (x, y, 1))_z: a homography of (x, y, 1) for the
    # wall point, which lies in front of the camera (lam > 0) where d_z has the sign of -C_z.
    center = -R.T @ t
    Rt = R.T
    H_wall = np.stack(
        [center[0] * Rt[2] - center[2] * Rt[0], center[1] * Rt[2] - center[2] * Rt[1], Rt[2]]
    )

    def texel_maps(px_per_m_x: float, px_per_m_y: float, step: int) -> tuple[Any, Any, Any]:
        """Texel (col, row) of every `step`-th sub-pixel, and whether it sees the wall."""
        A = np.array(
            [
                [px_per_m_x, 0.0, -px_per_m_x * x0 - 0.5],
                [0.0, -px_per_m_y, px_per_m_y * y0 - 0.5],
                [0.0, 0.0, 1.0],
            ]
        )
        # float32 arithmetic (Python-float coefficients do not promote): texel coordinates
        # to ~1e-4 texel, far below what the tests resolve, at half the memory traffic.
        h = [float(value) for value in (A @ H_wall).ravel()]
        xs, ys, ok = x[::step, ::step], y[::step, ::step], valid[::step, ::step]
        with np.errstate(divide="ignore", invalid="ignore"):
            den = h[6] * xs + h[7] * ys + h[8]
            col = (h[0] * xs + h[1] * ys + h[2]) / den
            row = (h[3] * xs + h[4] * ys + h[5]) / den
        hit = ok & (den * -float(np.sign(center[2])) > 0.0) & np.isfinite(col) & np.isfinite(row)
        return col, row, hit

    # Pre-filter: where a sub-pixel covers more than one texel, point sampling would
    # alias; area-average the texture down to about one texel per sub-pixel first.
    px_per_m_x = px_per_m_y = float(texture_px_per_m)
    texels_per_subpixel = _median_footprint(*texel_maps(px_per_m_x, px_per_m_y, 8), step=8)
    if texels_per_subpixel > 1.0:
        height, width = tex.shape
        new_width = max(1, round(width / texels_per_subpixel))
        new_height = max(1, round(height / texels_per_subpixel))
        tex = cv2.resize(tex, (new_width, new_height), interpolation=cv2.INTER_AREA)
        px_per_m_x *= new_width / width
        px_per_m_y *= new_height / height
    col, row, hit = texel_maps(px_per_m_x, px_per_m_y, 1)
    outside = np.float32(-10.0)
    samples = cv2.remap(
        tex,
        np.where(hit, col, outside),
        np.where(hit, row, outside),
        interpolation=cv2.INTER_LINEAR,
        borderMode=cv2.BORDER_CONSTANT,
        borderValue=float(background),
    )
    # The mean of each n x n block (exact for an integer factor).
    return cv2.resize(samples, (camera.width, camera.height), interpolation=cv2.INTER_AREA).astype(
        np.float64
    )


def _median_footprint(
    col: NDArray[np.float64], row: NDArray[np.float64], hit: NDArray[np.bool_], *, step: int
) -> float:
    """Median side (square root of the area) of a sub-pixel's footprint, in texels.

    Args:
        col, row: (h, w) texel coordinates of every `step`-th sub-pixel.
        hit: (h, w) where they are valid.
        step: Sub-pixels between neighbouring samples.
    """
    dc_x, dr_x = np.diff(col, axis=1)[:-1], np.diff(row, axis=1)[:-1]
    dc_y, dr_y = np.diff(col, axis=0)[:, :-1], np.diff(row, axis=0)[:, :-1]
    both = hit[:-1, :-1] & hit[1:, :-1] & hit[:-1, 1:]
    area = np.abs(dc_x * dr_y - dr_x * dc_y)[both] / step**2
    return float(np.sqrt(np.median(area))) if area.size else 0.0


@functools.lru_cache(maxsize=1)
def _subpixel_normalized(
    K_bytes: bytes, dist_bytes: bytes, width: int, height: int, supersample: int
) -> tuple[NDArray[np.float32], NDArray[np.float32], NDArray[np.bool_]]:
    """Undistorted normalised coordinates of every sub-pixel centre (pose independent).

    The undistortion is solved exactly (`camera.pixels_to_normalized`) at the pixel centres
    and one pixel beyond the border, and interpolated bilinearly to the sub-pixel centres:
    the interpolation error is h^2 / 8 times the map's curvature (h = 1 px), under 1e-4 px
    for the distortion of ordinary lenses, at a quarter of the cost of solving every
    sub-pixel.

    Returns:
        x, y: (height * supersample, width * supersample) float32 each (to ~1e-7, i.e.
            1e-4 px), 0 where not valid.
        valid: (height * supersample, width * supersample), all four neighbours valid.
    """
    K = np.frombuffer(K_bytes, dtype=np.float64).reshape(3, 3)
    dist = np.frombuffer(dist_bytes, dtype=np.float64)
    camera = Camera(K=K, dist=dist, width=width, height=height)
    u = np.arange(-1, width + 1, dtype=np.float64)
    v = np.arange(-1, height + 1, dtype=np.float64)
    x_px = np.zeros((v.size, u.size))
    y_px = np.zeros((v.size, u.size))
    ok_px = np.zeros((v.size, u.size), dtype=bool)
    for row0 in range(0, v.size, _ROWS_PER_CHUNK):
        rows = v[row0 : row0 + _ROWS_PER_CHUNK]
        uu, vv = np.meshgrid(u, rows)
        xy, ok = camera.pixels_to_normalized(np.stack([uu.ravel(), vv.ravel()], axis=1))
        block = slice(row0, row0 + rows.size)
        x_px[block] = np.where(ok, xy[:, 0], 0.0).reshape(rows.size, u.size)
        y_px[block] = np.where(ok, xy[:, 1], 0.0).reshape(rows.size, u.size)
        ok_px[block] = ok.reshape(rows.size, u.size)

    n = supersample
    offsets = (np.arange(n) + 0.5) / n - 0.5
    x = np.empty((height * n, width * n))
    y = np.empty((height * n, width * n))
    valid = np.empty((height * n, width * n), dtype=bool)
    for j, dv in enumerate(offsets):
        r0 = int(np.floor(dv)) + 1  # index of the upper neighbour row (border shift 1)
        fv = dv - np.floor(dv)
        for k, du in enumerate(offsets):
            c0 = int(np.floor(du)) + 1
            fu = du - np.floor(du)
            weights = ((1 - fv) * (1 - fu), (1 - fv) * fu, fv * (1 - fu), fv * fu)
            blocks = (
                (slice(r0, r0 + height), slice(c0, c0 + width)),
                (slice(r0, r0 + height), slice(c0 + 1, c0 + 1 + width)),
                (slice(r0 + 1, r0 + 1 + height), slice(c0, c0 + width)),
                (slice(r0 + 1, r0 + 1 + height), slice(c0 + 1, c0 + 1 + width)),
            )
            x[j::n, k::n] = sum(w * x_px[b] for w, b in zip(weights, blocks, strict=True))
            y[j::n, k::n] = sum(w * y_px[b] for w, b in zip(weights, blocks, strict=True))
            valid[j::n, k::n] = np.logical_and.reduce([ok_px[b] for b in blocks])
    x[~valid] = 0.0
    y[~valid] = 0.0
    x32, y32 = x.astype(np.float32), y.astype(np.float32)
    for array in (x32, y32, valid):
        array.flags.writeable = False
    return x32, y32, valid
