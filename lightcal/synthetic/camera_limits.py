"""The limits of a synthetic camera, checked before a dataset is rendered.

An image the renderer can hold (and the image readers accept), focal lengths giving a field
of view of 0.5 to 170 degrees, a principal point inside the image, and a distortion that
maps the image's field one-to-one within a factor 5. Beyond them the wall leaves the view
and the rendering fails only afterwards, with "the lights illuminate nothing". Errors name
the configuration field (`size`, `fx`, `fy`, `cx`, `cy`, `dist`), which `lightcal synth`
renames after its options.
"""

from __future__ import annotations

import math

import numpy as np

from lightcal.core.camera import Camera
from lightcal.errors import InputError

MAX_SIDE_PX = 65535
"""Largest image width or height (that of the image readers)."""

MAX_MEGAPIXELS = 100
"""Largest image, megapixels (the renderer holds several float arrays of this size)."""

FIELD_OF_VIEW_DEG = (0.5, 170.0)
"""Accepted field of view across the width (fx) or the height (fy), degrees."""

DISTORTION_SCALE = (0.2, 5.0)
"""Accepted factor of the radial distortion on a radius, out to the image's corners."""


def check_image_size(width: int, height: int) -> None:
    """`width` x `height` pixels: positive, at most `MAX_SIDE_PX` a side and
    `MAX_MEGAPIXELS`."""
    if width <= 0 or height <= 0:
        raise InputError("size", f"expected > 0, got {width} x {height}")
    if max(width, height) > MAX_SIDE_PX or width * height > MAX_MEGAPIXELS * 1_000_000:
        raise InputError(
            "size",
            f"expected at most {MAX_SIDE_PX} pixels a side and {MAX_MEGAPIXELS} megapixels, "
            f"got {width} x {height}",
        )


def check_intrinsics(
    width: int,
    height: int,
    *,
    fx: float | None = None,
    fy: float | None = None,
    cx: float | None = None,
    cy: float | None = None,
) -> None:
    """The given focal lengths (pixels) within `FIELD_OF_VIEW_DEG` across the image, the
    given principal point (pixels) inside it; None: not given (a default)."""
    low, high = (math.radians(a) / 2.0 for a in FIELD_OF_VIEW_DEG)
    for name, value, size, across in (("fx", fx, width, "width"), ("fy", fy, height, "height")):
        if value is None:
            continue
        f_low, f_high = size / (2.0 * math.tan(high)), size / (2.0 * math.tan(low))
        if not (f_low <= value <= f_high):  # (NaN too)
            raise InputError(
                name,
                f"expected {f_low:.4g} to {f_high:.4g} px (a field of view of "
                f"{FIELD_OF_VIEW_DEG[0]:g} to {FIELD_OF_VIEW_DEG[1]:g} degrees across the "
                f"{size}-pixel {across}), got {value:g}",
            )
    for name, value, size in (("cx", cx, width), ("cy", cy, height)):
        if value is not None and not (0.0 <= value <= size):
            raise InputError(
                name, f"expected a principal point inside the image, 0 to {size} px, got {value:g}"
            )


def check_distortion(camera: Camera) -> None:
    """The distorted radius grows with the radius and stays within `DISTORTION_SCALE` times
    it, out to the radius of the image's corners (of the distorted image: an approximation
    that catches wild coefficients)."""
    dist = camera.dist_opencv
    if not any(dist):
        return
    k = np.zeros(8)
    k[: len(dist)] = dist
    corners_x = np.array([0.0, camera.width, 0.0, camera.width])
    corners_y = np.array([0.0, 0.0, camera.height, camera.height])
    r_max = float(
        np.max(np.hypot((corners_x - camera.cx) / camera.fx, (corners_y - camera.cy) / camera.fy))
    )
    r = np.linspace(0.0, r_max, 257)[1:]  # (256,)
    r2 = r * r
    low, high = DISTORTION_SCALE
    with np.errstate(all="ignore"):
        denominator = 1.0 + r2 * (k[5] + r2 * (k[6] + r2 * k[7]))
        factor = (1.0 + r2 * (k[0] + r2 * (k[1] + r2 * k[4]))) / denominator
        ok = (
            np.all(np.isfinite(factor))
            and np.all(denominator > 0.0)
            and np.all(np.diff(r * factor) > 0.0)
            and np.all((factor >= low) & (factor <= high))
        )
    if not ok:
        raise InputError(
            "dist",
            f"{' '.join(f'{c:g}' for c in dist)}: expected a distortion that grows with the "
            f"radius and scales it by {low:g} to {high:g} out to the image's corners",
        )
