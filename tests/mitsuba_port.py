"""The camera behind a flat port, rendered by lightcal and by Mitsuba 3's path tracers.

The scene of `tests/mitsuba_medium.py` (a Lambertian wall of albedo 0.5, Mitsuba's
`spot` beside a distortion-free camera, lightcal given the spot's profile read from
Mitsuba) with the camera in a housing: a flat port of acrylic (n_g 1.49, 10 mm thick,
its inner face 20 mm in front of the centre of projection, normal along the optical
axis) between the camera's air and the water (n_w 1.333) in which the wall and the spot
are. Mitsuba's port is two parallel `rectangle`s, 0.8 m square, with `dielectric`
BSDFs whose normals face the camera, so that a camera ray meets each on its front
(exterior) side:

- the inner face (z_c = d): ext_ior 1.0 (the housing's air), int_ior 1.49;
- the outer face (z_c = d + t): ext_ior 1.49, int_ior 1.333, and in water that absorbs
  the `homogeneous` medium (sigma_t = c, albedo 0) as its interior: a ray that crosses
  it towards the wall enters the water, one reflected back into the glass leaves it.

Mitsuba's `dielectric` samples reflection or refraction with the Fresnel reflectance's
probability (the exact unpolarised one, no polarisation in `rgb` variants) and follows
the light reflected between the faces to any depth, so its render holds the port's
Fresnel transmittance with the inner reflections; lightcal's holds
`lightcal.core.fresnel.port_transmittance` of each pixel's ray.

No absorption: `path` (the water only an index); with absorption: `volpath`. A
unidirectional path tracer reaches the wall through the port's two delta interfaces and
connects the wall to the spot by next-event estimation: there is no port on the light's
side (the spot is in the water, 60 mm in front of the camera, beyond the port's outer
face; the shadow rays from the wall do not meet the port).

**The radiance's constant.** Radiance over n^2 is conserved along a refracted ray, so
the radiance the camera receives in the housing's air is the wall's in the water times
(n_air / n_w)^2 (and the Fresnel transmittance). Mitsuba's `dielectric` applies this
factor in radiance transport (eta^2 on each refraction: (1 / 1.49)^2 (1.49 / 1.333)^2),
lightcal leaves it to the light's scale: `theirs` is Mitsuba's radiance divided by
albedo / pi and by (n_air / n_w)^2 (`RADIANCE_CONSTANT`).

**Noise.** Each face sends a sample back with the Fresnel reflectance's probability (a
path then leaves the scene: it is worth 0 or 1), so a pixel's relative noise is
sqrt((1 - F) / (F n)) at n samples, F the port's transmittance (0.958 on the axis:
2e-3 at 2^12 samples); in water `volpath`'s free-flight sampling adds
sqrt((1 - T) / (T n)) (`tests/mitsuba_medium.py`).

Frames as in `tests/mitsuba_peer.py` (Mitsuba's camera is OpenCV's turned half a turn
about z).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from tests.mitsuba_peer import ALBEDO, SPOT, _transform, spot_profile

D_M, T_M, N_GLASS, N_WATER = 0.02, 0.01, 1.49, 1.333
PORT_HALF_SIDE_M = 0.05

RADIANCE_CONSTANT = (1.0 / N_WATER) ** 2
"""(n_air / n_w)^2: the radiance crossing from the water into the housing's air."""


@dataclass(frozen=True)
class PortImages:
    """Both renderers' images of the scene behind the port, and the lit pixels.

    Attributes:
        ours: (H, W) lightcal's `radiance` values through the port (Fresnel included).
        theirs: (H, W) Mitsuba's radiance / (albedo / pi) / (n_air / n_w)^2.
        fresnel: (H, W) the port's Fresnel factor of each pixel in lightcal's model.
        lit: (H, W) the pixels compared (lit above 30 % of the peak).
        path_m: (H, W) d_light + d_camera in the water at each footprint's centre, m.
        spp: Mitsuba's samples per pixel.
        attenuation_per_m: c.
    """

    ours: np.ndarray
    theirs: np.ndarray
    fresnel: np.ndarray
    lit: np.ndarray
    path_m: np.ndarray
    spp: int
    attenuation_per_m: float

    def relative(self, ours: np.ndarray | None = None) -> np.ndarray:
        """(n,) theirs / ours - 1 over the lit pixels (`ours` instead of `self.ours`)."""
        mine = self.ours if ours is None else ours
        with np.errstate(divide="ignore", invalid="ignore"):
            return self.theirs[self.lit] / mine[self.lit] - 1.0

    def expected_noise(self) -> np.ndarray:
        """(n,) the relative standard deviation of Mitsuba's lit pixels (module docstring):
        the port's and the water's Bernoulli samples."""
        f = self.fresnel[self.lit] * np.exp(-self.attenuation_per_m * self.path_m[self.lit])
        return np.sqrt((1.0 - f) / (f * self.spp))


def port_faces(
    mi: Any,
    T_world_camera: np.ndarray,
    medium: dict | None,
    half_side_m: float,
    *,
    distance_m: float = D_M,
    thickness_m: float = T_M,
) -> dict[str, dict[str, Any]]:
    """The port's two dielectric faces (module docstring), world frame; `medium` (a
    Mitsuba `ref`) the outer face's interior, or None. `T_world_camera` is the frame of
    the port's owner (its +z the port's normal): the camera's, or a light's."""
    faces = {}
    for name, z_c, ext_ior, int_ior in (
        ("port_inner", distance_m, 1.0, N_GLASS),
        ("port_outer", distance_m + thickness_m, N_GLASS, N_WATER),
    ):
        # The rectangle's normal +z turned to -z_c: facing the camera.
        local = np.diag([half_side_m, -half_side_m, -1.0, 1.0])
        local[2, 3] = z_c
        face: dict[str, Any] = {
            "type": "rectangle",
            "to_world": mi.ScalarTransform4f((T_world_camera @ local).tolist()),
            "bsdf": {"type": "dielectric", "int_ior": int_ior, "ext_ior": ext_ior},
        }
        if medium is not None and name == "port_outer":
            face["interior"] = medium
        faces[name] = face
    return faces


def render_through_port(
    width: int,
    height: int,
    spp: int,
    attenuation_per_m: float,
    variant: str,
    *,
    half_side_m: float = PORT_HALF_SIDE_M,
    max_depth: int = 12,
    sigma_s_per_m: float = 0.0,
    phase_g: float = 0.5,
) -> tuple[PortImages, tuple[Any, Any, Any, Any]]:
    """Render the scene behind the port with both renderers; also returns lightcal's
    scene (camera, view, rig, port) for further renders. With `sigma_s_per_m` > 0 the
    water scatters (Henyey-Greenstein `phase_g`; lightcal's beta = sigma_s pi / albedo):
    give `max_depth` 4 for single scattering (the two faces count as interactions)."""
    import mitsuba as mi

    from lightcal.core.camera import Camera
    from lightcal.core.flat_port import FlatPort
    from lightcal.core.fresnel import port_transmittance
    from lightcal.core.medium import AIR, Medium
    from lightcal.core.port_footprints import port_footprints
    from lightcal.core.port_render import render_image_through_port
    from lightcal.core.pose import rotation_from_axis
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
    R_cw = view.R_camera_world
    light_world = view.center_world + R_cw.T @ np.array([0.12, 0.03, 0.06])
    # The spot aims 0.2 m off where the camera looks: the lit pixels span the field.
    axis_world = np.array([-0.15, 0.25, 0.0]) - light_world
    R_world_light = rotation_from_axis(axis_world / np.linalg.norm(axis_world))
    light = Light(rid, R_cw @ (light_world - view.center_world), R_cw @ R_world_light, scale=1.0)
    rig = Rig.single(light)
    port = FlatPort(D_M, T_M, N_GLASS, N_WATER)
    medium = AIR
    if attenuation_per_m > 0.0:
        medium = Medium(attenuation_per_m, sigma_s_per_m * math.pi / ALBEDO, phase_g)
    ours = render_image_through_port(camera, view, rig, port, medium=medium, rid_subsamples=4)
    pixels = np.stack(np.meshgrid(np.arange(width), np.arange(height)), -1).reshape(-1, 2)
    fp = port_footprints(camera, view, pixels, port)
    centers = fp.centers_world
    path = np.linalg.norm(centers - light_world, axis=1)
    assert fp.port_exits_world is not None
    path += np.linalg.norm(centers - fp.port_exits_world, axis=1)
    # lightcal's Fresnel factor of each pixel: that of its centre's ray (no distortion).
    xy, _ = camera.pixels_to_normalized(pixels.astype(float))
    cos_air = 1.0 / np.sqrt(1.0 + np.sum(xy * xy, axis=1))
    fresnel, _ = port_transmittance(cos_air, 1.0, N_GLASS, N_WATER)

    T_world_cam = np.array(_transform(R_cw.T, view.center_world))
    water_ref = {"type": "ref", "id": "water"} if attenuation_per_m > 0.0 else None
    scene_dict: dict[str, Any] = {
        "type": "scene",
        "integrator": (
            {"type": "volpath", "max_depth": max_depth}
            if water_ref
            else {"type": "path", "max_depth": max_depth}
        ),
        "sensor": {
            "type": "perspective",
            "fov": math.degrees(2.0 * math.atan(width / 2 / fx)),
            "fov_axis": "x",
            "to_world": mi.ScalarTransform4f(
                (T_world_cam @ np.diag([-1.0, -1.0, 1.0, 1.0])).tolist()
            ),
            "film": {
                "type": "hdrfilm",
                "width": width,
                "height": height,
                "rfilter": {"type": "box"},
                "pixel_format": "rgb",
            },
            "sampler": {"type": "multijitter", "sample_count": spp},
        },
        "wall": {
            "type": "rectangle",  # [-1, 1]^2 at z = 0, normal +z: scaled to 6 x 6 m
            "to_world": mi.ScalarTransform4f().scale([3.0, 3.0, 1.0]),
            "bsdf": {"type": "diffuse", "reflectance": {"type": "rgb", "value": [ALBEDO] * 3}},
        },
        **port_faces(mi, T_world_cam, water_ref, half_side_m),
        "light": {
            **SPOT,
            "intensity": {"type": "rgb", "value": [1.0, 1.0, 1.0]},
            "to_world": mi.ScalarTransform4f(_transform(R_world_light, light_world)),
        },
    }
    if water_ref is not None:
        scene_dict["water"] = {
            "type": "homogeneous",
            "sigma_t": attenuation_per_m,
            "albedo": sigma_s_per_m / attenuation_per_m,
            "phase": {"type": "hg", "g": phase_g},
        }
        scene_dict["light"]["medium"] = water_ref
    scene = mi.load_dict(scene_dict)
    radiance = np.array(mi.render(scene, seed=1))[:, :, 0]
    theirs = radiance / (ALBEDO / math.pi) / RADIANCE_CONSTANT
    ours_f = ours.filled(np.nan)
    lit = np.isfinite(ours_f) & (ours_f > 0.3 * np.nanmax(ours_f)) & (theirs > 0.0)
    images = PortImages(
        ours_f,
        theirs,
        fresnel.reshape(height, width),
        lit,
        path.reshape(height, width),
        spp,
        float(attenuation_per_m),
    )
    return images, (camera, view, rig, port)
