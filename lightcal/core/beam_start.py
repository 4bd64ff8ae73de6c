"""An initial guess of a light's pose from where its beam falls in the images.

Each image of the wall shows the beam's bright spot. Where the light's axis meets the
wall is about where the wall is brightest (exactly so for a narrow beam on a wall seen
square-on; a wide beam's peak leans towards the nearest part of the wall). The spot's
centre, back-projected through the camera onto the wall, is a point of the axis in the
camera frame, since the light moves with the camera. Seen from several distances, those
points line up along the axis:

1. per image: the wall's brightness, block-averaged to at most `WORK_SIDE` pixels and
   smoothed (a Gaussian of `BLUR_FRACTION` of the side, masked pixels left out); the
   connected region above `PEAK_LEVEL` of its maximum; its brightness-weighted centroid,
   back-projected onto the wall (z = 0, or its mesh): the sighting `P_i` (camera frame,
   m), with the peak's brightness per unit exposure `b_i` and the wall normal `n_i`
   (camera frame);
2. the axis: the line through the `P_i` (their principal direction), pointing into the
   scene;
3. the light's place on that line. Along the axis the irradiance falls as
   `cos(incidence) / d^2`, so `sqrt(cos_i / b_i)` is linear in the distance `s_i` along
   the line, and zero where the light is: a straight-line fit gives it. When that fit is
   poor (a wide beam, vignetting) or puts the light more than `MAX_OFFSET_M` from the
   camera, the point of the line nearest the camera centre is taken: the light is
   mounted beside the camera.

With one usable image (or sightings that do not spread along a line), the axis is the
direction from the camera centre to the spot, and the light sits at the camera centre.
The guess only has to put the solver in the basin of the solution; docs/model.md,
"Initial guess".
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy import ndimage

from lightcal.core.camera import Camera
from lightcal.core.scene import View
from lightcal.core.selection import bin_values
from lightcal.core.wall_mesh import WallMesh, mesh_footprints

WORK_SIDE = 400
"""Images are block-averaged to at most this many pixels a side before smoothing."""
BLUR_FRACTION = 0.03
"""The smoothing Gaussian's sigma, as a fraction of the (binned) image's longer side."""
PEAK_LEVEL = 0.85
"""The spot: the connected region above this fraction of the smoothed maximum."""
MAX_OFFSET_M = 0.5
"""A light farther than this from the camera centre is not believed (mounted beside it)."""
MIN_SPREAD_M = 0.05
"""Sightings must spread at least this far along the axis to define it."""
MIN_R2 = 0.9
"""The brightness law's straight-line fit must explain this share of the variance."""


@dataclass(frozen=True)
class Sighting:
    """Where one image shows the beam.

    Attributes:
        image: the image's index.
        pixel: (2,) the spot's centre, full-resolution pixels (u, v).
        point_camera: (3,) that point on the wall, camera frame, m.
        brightness: the smoothed peak value per unit exposure.
        wall_normal_camera: (3,) the wall's unit normal in the camera frame.
    """

    image: int
    pixel: NDArray[np.float64]
    point_camera: NDArray[np.float64]
    brightness: float
    wall_normal_camera: NDArray[np.float64]


@dataclass(frozen=True)
class BeamGuess:
    """The guess: `position_camera` (3,) m and `axis_camera` (3,) unit, both in the camera
    frame; `sightings` used; `how` the light's place on the axis was found, in words."""

    position_camera: NDArray[np.float64]
    axis_camera: NDArray[np.float64]
    sightings: tuple[Sighting, ...]
    how: str


def sight_beam(
    values: NDArray[np.float64],
    usable: NDArray[np.bool_],
    camera: Camera,
    view: View,
    *,
    image: int = 0,
    mesh: WallMesh | None = None,
) -> Sighting | None:
    """The beam's spot in one image, or None when the image shows none (dark, or a spot
    whose ray misses the wall).

    Args:
        values: (H, W) linear pixel values (saturated pixels at their clipped value).
        usable: (H, W) False where a pixel is masked or unknown.
        camera: the intrinsics of `values` (binned if the image was).
        view: the image's camera pose and exposure.
        image: the image's index, kept in the sighting.
        mesh: the wall's shape (`wall.mesh`): the spot's ray meets it there, the normal
            is that of its nearest pixel's footprint; None: the plane z = 0.
    """
    h, w = values.shape
    b = max(1, int(np.ceil(max(h, w) / WORK_SIDE)))
    ok = usable & np.isfinite(values)
    filled = np.where(ok, values, 0.0)
    weight = ok.astype(np.float64)
    if b > 1:
        filled, weight = bin_values(filled, b), bin_values(weight, b)
    sigma = BLUR_FRACTION * max(filled.shape)
    num = ndimage.gaussian_filter(filled, sigma, mode="constant")
    den = ndimage.gaussian_filter(weight, sigma, mode="constant")
    with np.errstate(invalid="ignore", divide="ignore"):
        smooth = np.where(den > 0.2, num / den, np.nan)
    if not np.isfinite(smooth).any():
        return None
    peak = float(np.nanmax(smooth))
    if not peak > 0:
        return None
    region = np.nan_to_num(smooth, nan=0.0) >= PEAK_LEVEL * peak
    labels, _ = ndimage.label(region)
    top = np.unravel_index(int(np.nanargmax(smooth)), smooth.shape)
    spot = labels == labels[top]
    excess = np.where(spot, smooth - PEAK_LEVEL * peak, 0.0)
    rows, cols = np.indices(smooth.shape)
    total = float(excess.sum())
    v_b, u_b = float((rows * excess).sum() / total), float((cols * excess).sum() / total)
    pixel = np.array([(u_b + 0.5) * b - 0.5, (v_b + 0.5) * b - 0.5])
    rays, valid = camera.rays_camera(pixel[None, :])
    if not valid[0]:
        return None
    R, t = view.R_camera_world, view.t_camera_world
    centre_world = -R.T @ t
    if mesh is not None:
        points, hit = mesh.intersect(view, rays[:, :2], valid)
        nearest = np.clip(np.round(pixel), 0, [camera.width - 1, camera.height - 1])
        fp = mesh_footprints(camera, view, nearest[None, :].astype(np.int64), mesh)
        if not (hit[0] and fp.valid[0]) or fp.normals_world is None:
            return None  # the spot's ray misses the mesh
        return Sighting(
            image=image,
            pixel=pixel,
            point_camera=R @ (points[0] - centre_world),
            brightness=peak / view.exposure,
            wall_normal_camera=R @ fp.normals_world[0],
        )
    direction_world = R.T @ rays[0]
    if abs(direction_world[2]) < 1e-12:
        return None
    s = -centre_world[2] / direction_world[2]
    if not s > 0:
        return None  # the ray meets the wall's plane behind the camera
    return Sighting(
        image=image,
        pixel=pixel,
        point_camera=s * rays[0],
        brightness=peak / view.exposure,
        wall_normal_camera=R @ np.array([0.0, 0.0, 1.0]),
    )


def guess_from_sightings(sightings: Sequence[Sighting]) -> BeamGuess | None:
    """The light's position and axis from the sightings (see the module); None without
    any."""
    if not sightings:
        return None
    points = np.array([s.point_camera for s in sightings])
    centre = points.mean(axis=0)
    if len(sightings) >= 2:
        _, _, vt = np.linalg.svd(points - centre)
        axis = vt[0]
    else:
        axis = centre.copy()
    axis = axis / np.linalg.norm(axis)
    if axis[2] < 0:
        axis = -axis  # into the scene
    along = (points - centre) @ axis
    nearest = centre - (centre @ axis) * axis  # the line's point nearest the camera centre
    if len(sightings) < 2 or np.ptp(along) < MIN_SPREAD_M:
        direction = centre / np.linalg.norm(centre)
        return BeamGuess(
            np.zeros(3),
            direction,
            tuple(sightings),
            "one spot (or spots at one distance): the axis from the camera centre to it",
        )
    cos = np.array([abs(axis @ s.wall_normal_camera) for s in sightings])
    bright = np.array([s.brightness for s in sightings])
    y = np.sqrt(cos / bright)
    slope, intercept = np.polyfit(along, y, 1)
    fitted = slope * along + intercept
    r2 = 1.0 - float(np.sum((y - fitted) ** 2)) / max(float(np.sum((y - y.mean()) ** 2)), 1e-300)
    if len(sightings) >= 3 and slope > 0 and r2 >= MIN_R2:
        s0 = -intercept / slope
        position = centre + s0 * axis
        if np.linalg.norm(position) <= MAX_OFFSET_M and s0 < along.min():
            return BeamGuess(
                position,
                axis,
                tuple(sightings),
                f"the spots' 1/d^2 fall-off along the axis (R^2 {r2:.3f})",
            )
    return BeamGuess(nearest, axis, tuple(sightings), "the axis's point nearest the camera centre")
