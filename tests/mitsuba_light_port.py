"""A light behind a flat port, rendered by lightcal and by Mitsuba 3's particle tracer.

The scene of `tests/mitsuba_port.py` turned round: the camera is in the water (no port
on its side), the light in a housing. Mitsuba's `spot` (lightcal given its profile read
from Mitsuba, `tests/mitsuba_peer.py`) shines through a flat port of acrylic (n_g 1.49,
`T_M` = 8 mm thick, its inner face `D_M` = 15 mm in front of the emitter, normal along
the light's axis) into water (n_w 1.333) onto a Lambertian wall of albedo 0.5, 1.2 m
from the camera. Mitsuba's port is two parallel `rectangle`s, `PORT_HALF_SIDE_M` = 3 cm
half side, with `dielectric` BSDFs whose normals face the emitter, so that a ray from it
meets each on its front (exterior) side (`tests.mitsuba_port.port_faces` in the
light's frame):

- the inner face (z_l = d): ext_ior 1.0 (the housing's air), int_ior 1.49;
- the outer face (z_l = d + t): ext_ior 1.49, int_ior 1.333.

**Why the particle tracer.** A path traced from the camera reaches the wall and then
needs the spot: a delta light behind two delta (specular) interfaces, which next-event
estimation cannot connect to and no BSDF sample hits. Mitsuba's `ptracer` starts the
paths at the emitter (the spot's cone sampled uniformly, each particle weighted by the
profile), samples refraction or reflection at each face with the Fresnel reflectance's
probability (the exact unpolarised one; the light reflected between the faces followed
to `max_depth`), and connects each diffuse wall hit to the pinhole camera by a shadow
ray, splatting it into the pixel it projects to. `ptracer` "does not support media
(volumes)" (its documentation and source, src/integrators/ptracer.cpp; measured: a
`homogeneous` medium of sigma_t = 2 /m as the outer face's interior changes nothing,
the median relative difference from lightcal's render in clear water -1.7e-4 at 4096
particles a pixel): the water here is only the outer face's index. Absorption behind
the light's port, exp(-c (|P - E| + |P - C|)), depends on the port only through the
path length in the water |P - E|: `trace_light_paths` checks it against Mitsuba's own
refraction (its `dielectric` sampled, its surfaces intersected).

**No radiance constant.** A path tracer's `dielectric` scales the radiance it refracts
by eta^2 (`TransportMode::Radiance`: the camera's port's (n_air / n_w)^2); in the
particle tracer (`TransportMode::Importance`) a refracted particle keeps its weight
(measured: the sampled weight of a refraction into acrylic is 1 in importance mode and
1 / 1.49^2 in radiance mode), and `ptracer` splats without any eta factor: the flux
leaving the emitter into a solid angle in the air is what lands on the wall (less
Fresnel's share), as lightcal's port flux has it. The wall's radiance is albedo / pi
times its irradiance and the camera is in the same water: `theirs` is Mitsuba's value
divided by albedo / pi, nothing else.

**Noise.** Particles spread over the spot's cone (solid angle 2 pi (1 - cos 40 deg));
a pixel receives a Poisson number of them, lambda = n_particles Omega_air / Omega_cone
T_F (Omega_air the pixel's footprint's solid angle in the air, T_F the port's
transmittance), each weighted by the profile (nearly constant across a pixel): a pixel's
relative noise is about 1 / sqrt(lambda) (`LightPortImages.expected_noise`).

Frames as in `tests/mitsuba_peer.py`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from tests.mitsuba_peer import ALBEDO, SPOT, _transform, spot_profile
from tests.mitsuba_port import N_GLASS, N_WATER, port_faces

D_M, T_M = 0.015, 0.008
PORT_HALF_SIDE_M = 0.03

CONE_SR = 2.0 * math.pi * (1.0 - math.cos(math.radians(SPOT["cutoff_angle"])))  # type: ignore[arg-type]
"""The solid angle the spot's particles are drawn from, sr."""


@dataclass(frozen=True)
class LightPortImages:
    """Both renderers' images of the light behind its port, and the lit pixels.

    Attributes:
        ours: (H, W) lightcal's `radiance` values (the light's port, Fresnel included).
        theirs: (H, W) Mitsuba's radiance / (albedo / pi).
        fresnel: (H, W) the port's Fresnel transmittance at each footprint centre's air
            angle.
        solid_angle_sr: (H, W) each pixel footprint's solid angle in the air, sr.
        lit: (H, W) the pixels compared (lit above 30 % of the peak).
        spp: Mitsuba's particles per pixel (n_particles / (H W)).
    """

    ours: np.ndarray
    theirs: np.ndarray
    fresnel: np.ndarray
    solid_angle_sr: np.ndarray
    lit: np.ndarray
    spp: int

    def relative(self, ours: np.ndarray | None = None) -> np.ndarray:
        """(n,) theirs / ours - 1 over the lit pixels (`ours` instead of `self.ours`)."""
        mine = self.ours if ours is None else ours
        with np.errstate(divide="ignore", invalid="ignore"):
            return self.theirs[self.lit] / mine[self.lit] - 1.0

    def expected_noise(self) -> np.ndarray:
        """(n,) the relative standard deviation of Mitsuba's lit pixels (module
        docstring): 1 / sqrt(lambda) of the particles that reach each."""
        n = self.spp * self.ours.size
        lam = n * self.solid_angle_sr[self.lit] / CONE_SR * self.fresnel[self.lit]
        return 1.0 / np.sqrt(lam)


def light_port_scene(width: int, height: int) -> tuple[Any, Any, Any, Any]:
    """lightcal's scene: (camera, view, rig with the spot behind its port, the port)."""
    import mitsuba as mi

    from lightcal.core.camera import Camera
    from lightcal.core.flat_port import FlatPort
    from lightcal.core.pose import rotation_from_axis
    from lightcal.core.rid import SymmetricTableRID
    from lightcal.core.scene import Light, Rig, View

    mi.set_variant("scalar_rgb")  # `spot_profile` reads scalar values
    theta = np.radians(np.arange(0.0, 60.01, 0.25))  # knots at the kinks (25, 40 degrees)
    rid = SymmetricTableRID(theta, spot_profile(mi, theta))
    fx = 0.9 * width
    camera = Camera.from_params(
        fx=fx, fy=fx, cx=(width - 1) / 2, cy=(height - 1) / 2, width=width, height=height
    )
    view = View.looking_at(np.array([0.25, -0.15, 1.2]), np.array([0.0, 0.1, 0.0]))
    R_cw = view.R_camera_world
    light_world = view.center_world + R_cw.T @ np.array([0.15, 0.03, 0.0])
    # The spot aims 0.2 m off where the camera looks: the lit pixels span the field.
    axis_world = np.array([-0.15, 0.25, 0.0]) - light_world
    R_world_light = rotation_from_axis(axis_world / np.linalg.norm(axis_world))
    port = FlatPort(D_M, T_M, N_GLASS, N_WATER)
    light = Light(
        rid, R_cw @ (light_world - view.center_world), R_cw @ R_world_light, scale=1.0,
        port=port,
    )  # fmt: skip
    return camera, view, Rig.single(light), port


def _air_geometry(camera: Any, view: Any, light: Any) -> tuple[np.ndarray, np.ndarray]:
    """(H W,) each pixel footprint's solid angle in the air and the port's Fresnel
    transmittance at its centre's air angle."""
    from lightcal.core.footprint import pixel_footprints
    from lightcal.core.fresnel import port_transmittance
    from lightcal.core.light_port import port_paths
    from tests.light_port_numpy import spherical_triangle  # the NumPy oracle's

    port = light.port
    pixels = np.stack(np.meshgrid(np.arange(camera.width), np.arange(camera.height)), -1)
    fp = pixel_footprints(camera, view, pixels.reshape(-1, 2))
    L = light.position_world(view)
    R = light.rotation_world(view)
    corners = fp.corners_world[:, 0]  # (M, 4, 3): one quad per pixel
    u = port_paths(((corners - L) @ R).reshape(-1, 3), port).directions_light
    u = u.reshape(corners.shape)
    a, _ = spherical_triangle(u[:, 0], u[:, 1], u[:, 2], False)
    b, _ = spherical_triangle(u[:, 0], u[:, 2], u[:, 3], False)
    centre = port_paths((fp.centers_world - L) @ R, port)
    fresnel, _ = port_transmittance(
        centre.cos_air, port.air_index, port.glass_index, port.water_index
    )
    return np.abs(a + b), fresnel


def render_light_port(
    width: int,
    height: int,
    spp: int,
    variant: str,
    *,
    half_side_m: float = PORT_HALF_SIDE_M,
    max_depth: int = 12,
    samples_per_pass: int = 4096,
    seed: int = 1,
) -> tuple[LightPortImages, tuple[Any, Any, Any, Any]]:
    """Render the scene with both renderers (`spp` particles per pixel); also returns
    lightcal's scene (camera, view, rig, port) for further renders."""
    import mitsuba as mi

    from lightcal.core.render import render_image

    camera, view, rig, port = light_port_scene(width, height)
    light = rig.lights[0]
    ours = render_image(camera, view, rig, rid_subsamples=4).filled(np.nan)
    omega, fresnel = _air_geometry(camera, view, light)

    mi.set_variant(variant)
    R_cw = view.R_camera_world
    T_world_cam = np.array(_transform(R_cw.T, view.center_world))
    T_world_light = np.array(_transform(light.rotation_world(view), light.position_world(view)))
    scene_dict: dict[str, Any] = {
        "type": "scene",
        "integrator": {
            "type": "ptracer",
            "max_depth": max_depth,
            "hide_emitters": True,
            "samples_per_pass": samples_per_pass,
        },
        "sensor": {
            "type": "perspective",
            "fov": math.degrees(2.0 * math.atan(width / 2 / float(camera.K[0, 0]))),
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
            "sampler": {"type": "independent", "sample_count": spp},
        },
        "wall": {
            "type": "rectangle",  # [-1, 1]^2 at z = 0, normal +z: scaled to 6 x 6 m
            "to_world": mi.ScalarTransform4f().scale([3.0, 3.0, 1.0]),
            "bsdf": {"type": "diffuse", "reflectance": {"type": "rgb", "value": [ALBEDO] * 3}},
        },
        **port_faces(
            mi,
            T_world_light,
            None,
            half_side_m,
            distance_m=port.distance_m,
            thickness_m=port.thickness_m,
        ),
        "light": {
            **SPOT,
            "intensity": {"type": "rgb", "value": [1.0, 1.0, 1.0]},
            "to_world": mi.ScalarTransform4f(T_world_light.tolist()),
        },
    }
    scene = mi.load_dict(scene_dict)
    radiance = np.array(mi.render(scene, seed=seed))[:, :, 0]
    theirs = radiance / (ALBEDO / math.pi)
    lit = np.isfinite(ours) & (ours > 0.3 * np.nanmax(ours)) & (theirs > 0.0)
    shape = (height, width)
    images = LightPortImages(ours, theirs, fresnel.reshape(shape), omega.reshape(shape), lit, spp)
    return images, (camera, view, rig, port)


@dataclass(frozen=True)
class TracedPaths:
    """lightcal's refracted paths to wall points and Mitsuba's tracing of them.

    Attributes:
        points_world: (M, 3) the wall points P (footprint centres), m.
        arrivals_world: (M, 3) where Mitsuba's ray, leaving the emitter along lightcal's
            air direction and refracted by its `dielectric` faces, meets the wall, m.
        water_m: (M,) lightcal's path length in the water, |P - E| (`PortPaths.water_m`).
        their_water_m: (M,) Mitsuba's: from its exit point on the outer face to its
            arrival on the wall.
    """

    points_world: np.ndarray
    arrivals_world: np.ndarray
    water_m: np.ndarray
    their_water_m: np.ndarray


def trace_light_paths(points_world: np.ndarray, scene: tuple[Any, Any, Any, Any]) -> TracedPaths:
    """Trace lightcal's air directions to `points_world` (M, 3) through the port with
    Mitsuba's ray intersection (which surface, its plane) and `dielectric` refraction
    (scalar_rgb: float32), the check of the water path on which the light's absorption
    depends (`ptracer` has no media). The points are carried in float64 between
    surfaces; Mitsuba's float32 directions leave about 1e-7 m at the wall."""
    import mitsuba as mi

    from lightcal.core.light_port import port_paths

    _, view, rig, port = scene
    light = rig.lights[0]
    L, R = light.position_world(view), light.rotation_world(view)
    paths = port_paths((points_world - L) @ R, port)
    mi.set_variant("scalar_rgb")
    T_world_light = np.array(_transform(R, L))
    faces = port_faces(
        mi,
        T_world_light,
        None,
        PORT_HALF_SIDE_M,
        distance_m=port.distance_m,
        thickness_m=port.thickness_m,
    )
    wall = {"type": "rectangle", "to_world": mi.ScalarTransform4f().scale([3.0, 3.0, 1.0])}
    scene_mi = mi.load_dict({"type": "scene", "wall": wall, **faces})
    ctx = mi.BSDFContext(mi.TransportMode.Importance)
    arrivals = np.full((len(points_world), 3), np.nan)
    water = np.full(len(points_world), np.nan)
    for i, u in enumerate(paths.directions_light @ R.T):
        origin, direction = np.array(L, dtype=np.float64), u
        si = scene_mi.ray_intersect(mi.Ray3f(mi.Point3f(*origin), mi.Vector3f(*direction)))
        for face in range(3):  # the inner face, the outer face, the wall
            # `spawn_ray` moves a ray's origin off its surface by about 2e-4 (1 + |p|) m
            # (float32 self-intersection), which shifts a refracted ray sideways by
            # 1e-4 m: the next surface is found from there, and the exact point is
            # where the ray from the exact origin meets that surface's plane.
            if face > 0:
                si = scene_mi.ray_intersect(si.spawn_ray(mi.Vector3f(*direction)))
            n = np.array(si.n, dtype=np.float64)
            along = float((np.array(si.p) - origin) @ n) / float(direction @ n)
            exact = origin + along * direction
            if face == 2:
                arrivals[i], water[i] = exact, along
                break
            si.p = mi.Point3f(*exact)
            bs, _ = si.bsdf().sample(ctx, si, 1.0 - 1e-7, mi.Point2f(0.5, 0.5))
            assert mi.has_flag(bs.sampled_type, mi.BSDFFlags.DeltaTransmission)
            origin, direction = exact, np.array(si.to_world(bs.wo), dtype=np.float64)
    return TracedPaths(points_world, arrivals, paths.water_m, water)
