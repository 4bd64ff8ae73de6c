"""The candidate camera poses of capture planning (`lightcal.pipeline.plan`).

Candidates are a grid in front of the wall: each camera looks at the wall's centre (the
mean point where the project's optical axes meet the wall) from a distance d along its
axis, tilted by `tilt` from the wall normal towards `azimuth`, rolled about its axis. A
candidate is kept when its four image corners see the wall inside its extent (the wall's
size, centred on that point) and at least `min_lit_pixels` of its grid pixels are lit;
`candidate_image` renders its synthetic selection at the current estimate.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from lightcal.core.camera import Camera
from lightcal.core.flat_port import FlatPort
from lightcal.core.problem import ImageData, poisson_gaussian_sigma
from lightcal.core.render import shade
from lightcal.core.rotations import matrix_from_rotvec
from lightcal.core.scene import View
from lightcal.core.solver import CalibrationModel
from lightcal.core.wall_mesh import WallMesh, wall_footprints

#: Candidate grid defaults: distances (m), tilts (deg), azimuths (deg), rolls (deg).
DISTANCES_M = (0.6, 0.9, 1.3, 1.8, 2.5)
TILTS_DEG = (0.0, 15.0, 30.0, 45.0)
AZIMUTHS_DEG = (0.0, 45.0, 90.0, 135.0, 180.0, 225.0, 270.0, 315.0)
ROLLS_DEG = (0.0, 90.0)
#: The wall's size (m, width and height) the cameras must keep their view within.
WALL_SIZE_M = 3.0


@dataclass(frozen=True)
class PlanGrid:
    """The candidate camera poses' grid (see the module docstring)."""

    distances_m: tuple[float, ...] = DISTANCES_M
    tilts_deg: tuple[float, ...] = TILTS_DEG
    azimuths_deg: tuple[float, ...] = AZIMUTHS_DEG
    rolls_deg: tuple[float, ...] = ROLLS_DEG
    wall_size_m: float = WALL_SIZE_M
    pixels_per_view: int = 200
    min_lit_pixels: int = 30
    min_fraction: float = 0.02


@dataclass(frozen=True)
class Candidate:
    """One candidate camera pose: its geometry and its `View` (world-to-camera)."""

    distance_m: float
    tilt_deg: float
    azimuth_deg: float
    roll_deg: float
    target_world: np.ndarray
    view: View

    def instruction(self) -> str:
        """The pose as a plain instruction (directions as you face the wall)."""
        where = f"{self.distance_m:.2f} m from the wall point ({self.target_world[0]:+.2f}, "
        where += f"{self.target_world[1]:+.2f}) m, aimed at it"
        if self.tilt_deg < 0.5:
            tilt = "square to the wall"
        else:
            tilt = f"tilted {self.tilt_deg:.0f} deg, the camera moved {self.side()}"
        roll = "no roll" if abs(self.roll_deg) < 0.5 else f"rolled {self.roll_deg:+.0f} deg"
        return f"{where}, {tilt}, {roll}"

    def side(self) -> str:
        """Where the camera is moved (world +x is the left as you face the wall, +y down)."""
        a = math.radians(self.azimuth_deg)
        dx, dy = math.cos(a), math.sin(a)
        words = []
        if dy < -0.38:
            words.append("up")
        elif dy > 0.38:
            words.append("down")
        if dx > 0.38:
            words.append("left")
        elif dx < -0.38:
            words.append("right")
        return "-".join(words) + " (as you face the wall)"


def candidate_view(
    distance_m: float,
    tilt_deg: float,
    azimuth_deg: float,
    roll_deg: float,
    target_world: np.ndarray,
    exposure: float = 1.0,
) -> Candidate:
    """The camera looking at `target_world` (3,) from `distance_m` along its axis, tilted
    `tilt_deg` from the wall normal towards `azimuth_deg`, rolled `roll_deg` about its axis
    (the construction of `lightcal.synthetic.views.sample_views`)."""
    a, b = math.radians(tilt_deg), math.radians(azimuth_deg)
    toward_camera = np.array([math.sin(a) * math.cos(b), math.sin(a) * math.sin(b), math.cos(a)])
    target = np.asarray(target_world, dtype=np.float64)
    center = target + distance_m * toward_camera
    base = View.looking_at(center, target, up_world=(0.0, -1.0, 0.0))
    R = matrix_from_rotvec(np.array([0.0, 0.0, math.radians(roll_deg)])) @ base.R_camera_world
    view = View(R, -R @ center, exposure)
    return Candidate(distance_m, tilt_deg, azimuth_deg, roll_deg, target[:2].copy(), view)


def wall_centre(views: list[View]) -> np.ndarray:
    """(3,) the mean point where the views' optical axes meet the wall z = 0."""
    hits = []
    for v in views:
        axis = v.R_camera_world[2]
        if axis[2] < -1e-9:
            c = v.center_world
            hits.append(c - c[2] / axis[2] * axis)
    return np.mean(hits, axis=0) if hits else np.zeros(3)


def candidates(
    camera: Camera,
    grid: PlanGrid,
    target_world: np.ndarray,
    exposure: float,
    *,
    mesh: WallMesh | None = None,
    port: FlatPort | None = None,
) -> list[Candidate]:
    """The grid's poses whose image corners see the wall within its extent (on `mesh`,
    the wall's shape, when given: a corner that misses it drops the pose; through the
    camera's flat `port` when given)."""
    corners = np.array(
        [
            [0, 0],
            [camera.width - 1, 0],
            [0, camera.height - 1],
            [camera.width - 1, camera.height - 1],
        ]
    )
    half = grid.wall_size_m / 2.0
    out = []
    for d in grid.distances_m:
        for t in grid.tilts_deg:
            for az in grid.azimuths_deg if t > 0 else grid.azimuths_deg[:1]:
                for roll in grid.rolls_deg:
                    c = candidate_view(d, t, az, roll, target_world, exposure)
                    fp = wall_footprints(camera, c.view, corners, mesh=mesh, port=port)
                    if not np.all(fp.valid):
                        continue
                    pts = fp.corners_world.reshape(-1, 3)
                    if np.all(np.abs(pts[:, :2] - target_world[:2]) <= half):
                        out.append(c)
    return out


def candidate_image(
    model: CalibrationModel,
    x: np.ndarray,
    camera: Camera,
    view: View,
    grid: PlanGrid,
    name: str = "candidate",
    *,
    peak: float | None = None,
    mesh: WallMesh | None = None,
    port: FlatPort | None = None,
) -> ImageData | None:
    """A synthetic selection of `view`'s pixels rendered at the estimate x: about
        `grid.pixels_per_view` lit pixels on a regular grid, observed = rendered (+ offset),
        sigma from the noise model (or the images' median sigma); None when too few are lit.
        With `peak` the view's exposure is set so that its brightest pixel reads `peak` above
        the offset (as a photographer exposes each view; `typical_peak`). Its footprints are on
    `mesh` and through the camera's flat `port` when given."""
    side = max(2, math.ceil(math.sqrt(4 * grid.pixels_per_view)))
    us = np.linspace(0, camera.width - 1, side).round()
    vs = np.linspace(0, camera.height - 1, max(2, side * camera.height // camera.width)).round()
    pix = np.stack(np.meshgrid(us, vs), -1).reshape(-1, 2).astype(np.int64)
    pix = np.unique(pix, axis=0)
    fp = wall_footprints(camera, view, pix, mesh=mesh, port=port)
    lay = model.layout
    rig, wall = lay.rig(x), lay.wall_of(x)
    values = shade(
        fp,
        view,
        rig,
        rid_subsamples=model.options.rid_subsamples,
        wall=wall,
        medium=lay.medium_of(x),
    )
    v = lay.sensor_values(values.values.filled(np.nan), fp, x, view.exposure)
    ok = fp.valid & np.isfinite(v)
    if not ok.any():
        return None
    peak_value = float(np.max(v[ok]))
    ok &= v > grid.min_fraction * peak_value
    if peak is not None and peak_value > 0.0:
        ratio = peak / peak_value
        view = View(view.R_camera_world, view.t_camera_world, view.exposure * ratio)
        v = v * ratio
    keep = np.nonzero(ok)[0]
    if len(keep) < grid.min_lit_pixels:
        return None
    if len(keep) > grid.pixels_per_view:
        keep = keep[np.linspace(0, len(keep) - 1, grid.pixels_per_view).round().astype(int)]
    signal = v[keep]
    noise = next((im.noise for im in model.images if im.noise is not None), None)
    if noise is not None:
        sigma = poisson_gaussian_sigma(signal, noise)
    else:
        sigma = np.full(len(keep), float(np.median(np.concatenate(model.sigmas))))
    offset = lay.offset(x)
    fp = wall_footprints(camera, view, pix[keep], mesh=mesh, port=port)
    return ImageData(name, view, fp, signal + offset, sigma)
