"""Synthetic camera views in front of the wall (docs/conventions.md: the wall is the world
plane z = 0, cameras at z > 0; degrees only in the `_deg` fields of `SceneConfig`).

- `sample_views`: camera poses in front of the wall, distances stratified over a range,
  varied tilts, azimuths and rolls; every optical axis hits the wall in front of the camera
  (the lit area, where lights mounted next to the camera point, is in view).
- `sample_exposure_times`; `perturb_view`: the marker / SfM error of a camera pose.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from lightcal.core.rotations import matrix_from_rotvec
from lightcal.core.scene import View
from lightcal.errors import InputError
from lightcal.synthetic.sampling import (
    check_positive_int,
    check_range,
    rotation_z,
)

MAX_VIEWS = 10_000
"""Most views of a scene (a project of more exceeds the project file's size limit)."""

MAX_TILT_DEG = 80.0
"""Largest accepted camera tilt: beyond it the wall is seen too grazingly to be useful."""


@dataclass(frozen=True)
class SceneConfig:
    """Where the cameras stand in front of the wall.

    Attributes:
        n_views: Number of images.
        distance_range_m: (min, max) distance from the camera centre to the wall along the
            optical axis, metres; stratified so every part of the range is used.
        tilt_range_deg: (min, max) angle between the optical axis and the wall normal,
            degrees (stratified too); the direction of the tilt is uniform.
        roll_range_deg: (min, max) rotation of the camera about its optical axis, degrees.
        target_spread_m: The optical axes hit the wall within +-spread of the world origin
            in x and y, metres.
        exposure_times_s: The shutter times an image may get (chosen at random), seconds.
    """

    n_views: int = 12
    distance_range_m: tuple[float, float] = (0.8, 2.5)
    tilt_range_deg: tuple[float, float] = (0.0, 35.0)
    roll_range_deg: tuple[float, float] = (-30.0, 30.0)
    target_spread_m: float = 0.3
    exposure_times_s: tuple[float, ...] = (1 / 60, 1 / 50, 1 / 40, 1 / 30)

    def __post_init__(self) -> None:
        check_positive_int("n_views", self.n_views)
        if self.n_views > MAX_VIEWS:
            raise InputError("n_views", f"expected at most {MAX_VIEWS} images, got {self.n_views}")
        check_range("distance_range_m", self.distance_range_m, low=1e-3, high=1e3)
        check_range("tilt_range_deg", self.tilt_range_deg, low=0.0, high=MAX_TILT_DEG)
        check_range("roll_range_deg", self.roll_range_deg, low=-180.0, high=180.0)
        if not (math.isfinite(self.target_spread_m) and self.target_spread_m >= 0.0):
            raise InputError(
                "target_spread_m", f"expected a finite value >= 0, got {self.target_spread_m!r}"
            )
        times = self.exposure_times_s
        if len(times) == 0 or not all(math.isfinite(t) and t > 0.0 for t in times):
            raise InputError(
                "exposure_times_s", f"expected one or more times > 0 seconds, got {times!r}"
            )


def _stratified(n: int, low: float, high: float, rng: np.random.Generator) -> NDArray[np.float64]:
    """(n,) one uniform sample in each of n equal strata of [low, high], in random order."""
    strata = (np.arange(n) + rng.uniform(size=n)) / n
    return low + (high - low) * strata[rng.permutation(n)]


def sample_views(config: SceneConfig, rng: np.random.Generator) -> list[View]:
    """Camera poses looking at the wall, exposure 1.

    Each camera looks at a target point T on the wall (its optical axis hits the wall
    there, so the principal point sees the wall), from distance d along the axis at tilt
    alpha from the wall normal in a random direction, then rolls about the axis.
    Distances and tilts are stratified (a Latin hypercube): n views cover n strata of
    each range.

    Args:
        config: The ranges.
        rng: Randomness.

    Returns:
        n_views views; `View.center_world` z = d cos(alpha) > 0.
    """
    n = config.n_views
    d_lo, d_hi = config.distance_range_m
    distances = _stratified(n, d_lo, d_hi, rng)
    tilt_lo, tilt_hi = config.tilt_range_deg
    tilts = _stratified(n, math.radians(tilt_lo), math.radians(tilt_hi), rng)
    azimuths = rng.uniform(0.0, 2.0 * math.pi, size=n)
    roll_lo, roll_hi = config.roll_range_deg
    rolls = rng.uniform(math.radians(roll_lo), math.radians(roll_hi), size=n)
    spread = config.target_spread_m
    targets = rng.uniform(-spread, spread, size=(n, 2))
    views = []
    for i in range(n):
        a, b = float(tilts[i]), float(azimuths[i])
        toward_camera = np.array(
            [math.sin(a) * math.cos(b), math.sin(a) * math.sin(b), math.cos(a)]
        )
        target = np.array([targets[i, 0], targets[i, 1], 0.0])
        center = target + distances[i] * toward_camera
        # World +y is "down" in the image before the roll (any up not along the axis works:
        # tilt <= 80 degrees keeps -y away from the axis).
        base = View.looking_at(center, target, up_world=(0.0, -1.0, 0.0))
        R = rotation_z(float(rolls[i])) @ base.R_camera_world
        views.append(View(R, -R @ center, 1.0))
    return views


def sample_exposure_times(config: SceneConfig, rng: np.random.Generator) -> NDArray[np.float64]:
    """(n_views,) shutter times, seconds, drawn from `config.exposure_times_s`."""
    choices = np.asarray(config.exposure_times_s, dtype=np.float64)
    return choices[rng.integers(0, choices.size, size=config.n_views)]


def perturb_view(
    view: View,
    rng: np.random.Generator,
    *,
    position_sigma_m: float,
    angle_sigma_rad: float,
    field: str = "position_sigma_m",
) -> View:
    """The pose a marker detector or SfM would report: the true one plus Gaussian error.

    The camera centre moves by N(0, position_sigma_m^2) along each world axis; the rotation
    is `exp(delta) @ R_camera_world` with delta ~ N(0, angle_sigma_rad^2) per camera axis.

    Args:
        view: The true view.
        rng: Randomness.
        position_sigma_m: Standard deviation of each centre coordinate, metres (>= 0).
        angle_sigma_rad: Standard deviation of each rotation-vector component, radians (>= 0).
        field: What the error names when the sigma puts the camera on or behind the wall.

    Returns:
        The perturbed view, same exposure.

    Raises:
        InputError: The perturbed camera is on or behind the wall (a sigma too large for
            the distance to the wall).
    """
    delta = rng.normal(0.0, 1.0, size=3) * angle_sigma_rad
    shift = rng.normal(0.0, 1.0, size=3) * position_sigma_m
    R = matrix_from_rotvec(delta) @ view.R_camera_world
    center = view.center_world + shift
    if center[2] <= 0.0:
        raise InputError(
            field,
            f"the error of {position_sigma_m * 1000.0:g} mm puts a measured camera on or behind "
            f"the wall (the true camera is {view.center_world[2]:.3g} m in front of it); "
            "expected a sigma much smaller than the distance to the wall",
        )
    return View(R, -R @ center, view.exposure)
