"""The same scene in water rendered by lightcal and by Mitsuba 3's volumetric path tracer.

The scene of `tests/mitsuba_peer.py` (a Lambertian wall of albedo 0.5, Mitsuba's `spot`
beside a distortion-free camera, lightcal given the spot's profile read from Mitsuba), with
the camera, the light and the wall inside a homogeneous absorbing medium: Mitsuba's
`homogeneous` medium (sigma_t = c, albedo 0: no scattering) filling a box around them,
rendered by `volpath`. lightcal renders the same view with `Medium(c)`
(docs/model.md, "Medium"). Mitsuba's film records radiance, so its image is
lightcal's times albedo / pi, up to its Monte Carlo noise.

**Noise.** With albedo 0 `volpath` estimates each segment's transmittance by free-flight
sampling: a sample survives with probability T = exp(-c (d_light + d_camera)) and weighs
1 / 1 (a path dies or lives), so a pixel's relative noise is sqrt((1 - T) / (T n)) at n
samples, far above that of the pixel's area sampling. `expected_noise` gives it per
pixel (~2e-3 at 2^16 samples); the test renders a small image with enough samples that
the median over its lit pixels is known to ~1e-4.

Frames as in `tests/mitsuba_peer.py` (Mitsuba's camera is OpenCV's turned half a turn
about z).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from tests.mitsuba_peer import ALBEDO, SPOT, _transform, spot_profile


@dataclass(frozen=True)
class WaterImages:
    """Both renderers' images of the scene in water, and the lit pixels.

    Attributes:
        ours: (H, W) lightcal's `radiance` values in water (NaN off the wall).
        theirs: (H, W) Mitsuba's radiance divided by albedo / pi (same units).
        path_m: (H, W) d_light + d_camera at each pixel's footprint centre, m.
        lit: (H, W) the pixels compared (lit above 30 % of the peak).
        spp: Mitsuba's samples per pixel.
        attenuation_per_m: c.
    """

    ours: np.ndarray
    theirs: np.ndarray
    path_m: np.ndarray
    lit: np.ndarray
    spp: int
    attenuation_per_m: float

    def relative(self, ours: np.ndarray | None = None) -> np.ndarray:
        """(n,) theirs / ours - 1 over the lit pixels (`ours` instead of `self.ours`)."""
        mine = self.ours if ours is None else ours
        return self.theirs[self.lit] / mine[self.lit] - 1.0

    def expected_noise(self) -> np.ndarray:
        """(n,) the relative standard deviation of Mitsuba's lit pixels (module docstring)."""
        t = np.exp(-self.attenuation_per_m * self.path_m[self.lit])
        return np.sqrt((1.0 - t) / (t * self.spp))


def render_in_water(
    width: int,
    height: int,
    spp: int,
    attenuation_per_m: float,
    variant: str,
    *,
    scattering_albedo: float = 0.0,
    phase_g: float = 0.0,
) -> tuple[WaterImages, object]:
    """Render the scene in water with both renderers; also returns lightcal's scene
    (camera, view, rig) for further renders. With a scattering albedo a (sigma_s =
    a sigma_t, Henyey-Greenstein phase g) Mitsuba renders single scattering (max_depth
    2: the camera ray's first interaction, on the wall or in the water, lit by the
    spot) and lightcal the same medium with beta = sigma_s pi / albedo of the wall."""
    import mitsuba as mi

    from lightcal.core.camera import Camera
    from lightcal.core.footprint import pixel_footprints
    from lightcal.core.medium import Medium
    from lightcal.core.pose import rotation_from_axis
    from lightcal.core.render import render_image
    from lightcal.core.rid import SymmetricTableRID
    from lightcal.core.scene import Light, Rig, View

    mi.set_variant("scalar_rgb")  # `spot_profile` reads scalar values
    theta = np.radians(np.arange(0.0, 60.01, 0.25))  # knots at the kinks (25, 40 degrees)
    rid = SymmetricTableRID(theta, spot_profile(mi, theta))
    mi.set_variant(variant)
    fx = 0.9 * width
    camera = Camera.from_params(
        fx=fx, fy=fx, cx=(width - 1) / 2, cy=(height - 1) / 2, width=width, height=height
    )
    view = View.looking_at(np.array([0.25, -0.15, 1.2]), np.array([0.0, 0.1, 0.0]))
    light_world = view.center_world + np.array([0.12, 0.03, -0.02])
    axis_world = np.array([0.05, 0.2, 0.0]) - light_world
    R_world_light = rotation_from_axis(axis_world / np.linalg.norm(axis_world))
    R_cw = view.R_camera_world
    light = Light(rid, R_cw @ (light_world - view.center_world), R_cw @ R_world_light, scale=1.0)
    rig = Rig.single(light)
    sigma_s = scattering_albedo * attenuation_per_m
    medium = Medium(attenuation_per_m, sigma_s * math.pi / ALBEDO, phase_g)
    ours = render_image(camera, view, rig, medium=medium).filled(np.nan)

    pixels = np.stack(np.meshgrid(np.arange(width), np.arange(height)), -1).reshape(-1, 2)
    fp = pixel_footprints(camera, view, pixels)
    centers = fp.centers_world
    path = np.linalg.norm(centers - light_world, axis=1)
    path += np.linalg.norm(centers - view.center_world, axis=1)

    T_world_cam = np.array(_transform(R_cw.T, view.center_world)) @ np.diag([-1.0, -1.0, 1, 1])
    top = float(view.center_world[2]) + 1.0
    scene = mi.load_dict(
        {
            "type": "scene",
            "integrator": {"type": "volpath", "max_depth": 2},
            "water": {
                "type": "homogeneous",
                "sigma_t": attenuation_per_m,
                "albedo": scattering_albedo,
                "phase": {"type": "hg", "g": phase_g},
            },
            "sensor": {
                "type": "perspective",
                "fov": math.degrees(2.0 * math.atan(width / 2 / fx)),
                "fov_axis": "x",
                "near_clip": 1e-5,  # the camera ray's first centimetre is in the water
                "to_world": mi.ScalarTransform4f(T_world_cam.tolist()),
                "medium": {"type": "ref", "id": "water"},
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
            "box": {
                "type": "cube",  # [-1, 1]^3: the water from just behind the wall to above the rig
                "to_world": mi.ScalarTransform4f()
                .translate([0.0, 0.0, (top - 0.5) / 2.0])
                .scale([4.0, 4.0, (top + 0.5) / 2.0]),
                "bsdf": {"type": "null"},
                "interior": {"type": "ref", "id": "water"},
            },
            "light": {
                **SPOT,
                "intensity": {"type": "rgb", "value": [1.0, 1.0, 1.0]},
                "to_world": mi.ScalarTransform4f(_transform(R_world_light, light_world)),
            },
        }
    )
    theirs = np.array(mi.render(scene, seed=1))[:, :, 0] / (ALBEDO / math.pi)
    # Inside the beam's core: the spot's kinks at 25 and 40 degrees are interpolated
    # (few 1e-4 off at the image corners, in air as in water: `tests/mitsuba_peer.py`).
    lit = np.isfinite(ours) & (ours > 0.3 * np.nanmax(ours)) & (theirs > 0.0)
    images = WaterImages(
        ours, theirs, path.reshape(height, width), lit, spp, float(attenuation_per_m)
    )
    return images, (camera, view, rig)
