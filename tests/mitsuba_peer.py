"""The same scene rendered by lightcal and by Mitsuba 3, an independent renderer.

A perspective camera (no distortion) 1.6 m from a Lambertian wall of albedo 0.5, lit by
Mitsuba's `spot` emitter beside the camera. lightcal gets the spot's angular profile as a
table RID read from Mitsuba itself (`spot_profile`: the emitter's intensity queried
direction by direction) and renders with the `radiance` sensor model, which is what
Mitsuba's film records. The two images should then differ by the constant albedo / pi
(a Lambertian wall's radiance per unit irradiance) and Mitsuba's pixel sampling noise.

Used by `tests/test_render_mitsuba.py` and the `mitsuba` row of `benchmarks/render.py`.
Frames: lightcal's camera is OpenCV's (x right, y down, z forward); Mitsuba's looks
along +z with +y up and +x left, a half turn about z: T_world_mitsuba_camera =
T_world_camera diag(-1, -1, 1, 1). The light's +z is its axis in both.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from typing import Any

import numpy as np

ALBEDO = 0.5
SPOT = {"type": "spot", "cutoff_angle": 40.0, "beam_width": 25.0}


@dataclass(frozen=True)
class PeerResult:
    """lightcal's and Mitsuba's images of one scene (the lit pixels compared)."""

    ours_s: float
    mitsuba_s: float
    scale: float  # median of Mitsuba / lightcal over the lit pixels (expected ALBEDO / pi)
    median_rel: float  # median |ratio / scale - 1|
    p99_rel: float
    lit: int


def _transform(R: np.ndarray, t: np.ndarray) -> list[list[float]]:
    M = np.eye(4)
    M[:3, :3] = R
    M[:3, 3] = t
    return M.tolist()


def spot_profile(mi: Any, theta_rad: np.ndarray) -> np.ndarray:
    """Mitsuba's spot intensity at angles theta from its axis (relative to the axis)."""
    emitter = mi.load_dict({**SPOT, "intensity": {"type": "rgb", "value": [1.0, 1.0, 1.0]}})
    it = mi.Interaction3f()
    out = []
    for t in theta_rad:
        it.p = mi.Point3f(math.sin(t), 0.0, math.cos(t))  # 1 m from the emitter
        _, weight = emitter.sample_direction(it, mi.Point2f(0.5, 0.5))
        out.append(float(weight[0]))
    values = np.maximum(np.array(out), 0.0)
    return values / values[0]


def compare(width: int, height: int, spp: int) -> PeerResult:
    """Render the scene with both renderers and compare them (see the module docstring)."""
    import mitsuba as mi

    from lightcal.core.camera import Camera
    from lightcal.core.pose import rotation_from_axis
    from lightcal.core.render import render_image
    from lightcal.core.rid import SymmetricTableRID
    from lightcal.core.scene import Light, Rig, View

    mi.set_variant("scalar_rgb")
    fx = 0.9 * width
    camera = Camera.from_params(
        fx=fx, fy=fx, cx=(width - 1) / 2, cy=(height - 1) / 2, width=width, height=height
    )
    view = View.looking_at(np.array([0.25, -0.15, 1.6]), np.array([0.0, 0.1, 0.0]))
    light_world = view.center_world + np.array([0.12, 0.03, -0.02])
    axis_world = np.array([0.0, 0.15, 0.0]) - light_world
    R_world_light = rotation_from_axis(axis_world / np.linalg.norm(axis_world))
    theta = np.radians(np.arange(0.0, 60.01, 0.25))  # knots at the kinks (25, 40 degrees)
    rid = SymmetricTableRID(theta, spot_profile(mi, theta))
    R_cw = view.R_camera_world
    light = Light(rid, R_cw @ (light_world - view.center_world), R_cw @ R_world_light, scale=1.0)
    rig = Rig.single(light)
    render_image(camera, view, rig)  # kernels loaded
    t0 = time.perf_counter()
    ours = render_image(camera, view, rig).filled(np.nan)
    ours_s = time.perf_counter() - t0

    T_world_cam = np.array(_transform(R_cw.T, view.center_world)) @ np.diag([-1.0, -1.0, 1, 1])
    scene = mi.load_dict(
        {
            "type": "scene",
            "integrator": {"type": "direct", "emitter_samples": 1, "bsdf_samples": 0},
            "sensor": {
                "type": "perspective",
                "fov": math.degrees(2.0 * math.atan(width / 2 / fx)),
                "fov_axis": "x",
                "to_world": mi.ScalarTransform4f(T_world_cam.tolist()),
                "film": {
                    "type": "hdrfilm",
                    "width": width,
                    "height": height,
                    "rfilter": {"type": "box"},
                    "pixel_format": "rgb",
                },
                "sampler": {"type": "independent", "sample_count": spp},
            },
            "wall": {
                "type": "rectangle",  # [-1, 1]^2 at z = 0, normal +z: scaled to 6 x 6 m
                "to_world": mi.ScalarTransform4f().scale([3.0, 3.0, 1.0]),
                "bsdf": {
                    "type": "diffuse",
                    "reflectance": {"type": "rgb", "value": [ALBEDO] * 3},
                },
            },
            "light": {
                **SPOT,
                "intensity": {"type": "rgb", "value": [1.0, 1.0, 1.0]},
                "to_world": mi.ScalarTransform4f(_transform(R_world_light, light_world)),
            },
        }
    )
    t0 = time.perf_counter()
    theirs = np.array(mi.render(scene))[:, :, 0]
    mitsuba_s = time.perf_counter() - t0
    lit = np.isfinite(ours) & (ours > 0.05 * np.nanmax(ours)) & (theirs > 0.0)
    ratio = theirs[lit] / ours[lit]
    scale = float(np.median(ratio))
    rel = np.abs(ratio / scale - 1.0)
    return PeerResult(
        ours_s,
        mitsuba_s,
        scale,
        float(np.median(rel)),
        float(np.percentile(rel, 99)),
        int(lit.sum()),
    )
