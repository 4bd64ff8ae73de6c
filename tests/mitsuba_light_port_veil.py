"""The veil of a light behind its flat port, checked against Mitsuba 3 by reciprocity.

Mitsuba cannot render the veil as lightcal's scene has it: its particle tracer
(`ptracer`, `tests/mitsuba_light_port.py`) has no media, and a path traced from the
camera reaches a point light behind two delta (dielectric) interfaces only by chance.
The scene turned round can: the single-scattering measurement is symmetric in its two
ends, so

- the ported light becomes Mitsuba's `perspective` sensor, at the emitter, its axis
  the light's, behind the same two `dielectric` faces (`tests.mitsuba_port.port_faces`
  in the light's frame: d = 15 mm, t = 8 mm, acrylic into water), the water a
  `homogeneous` medium (sigma_t = c, albedo sigma_s / c, Henyey-Greenstein g) the outer
  face's interior; its pixels see the radiance L(u) arriving at the emitter in the air
  along each direction u (the camera's side of Mitsuba's `volpath` reaches the scattering
  points through the faces, and next-event estimation connects them to the spot, which
  is in the water);
- the camera's rays become Mitsuba's `spot` at the camera centre C, in the water, of
  intensity I_s within a cone of half-angle `CONE_DEG` about a direction o_0 (the
  pixel's cone of rays, widened);
- a black wall ends the rays at z = 0.

Then sum_pixels f(u) L(u) Omega_pixel = sigma_s I_s (n_a / n_w)^2 integral_cone S(o)
dOmega_o, f the ported light's RID (in air), S lightcal's veil integral of the ray from C
in direction o to the wall (`lightcal.core.light_port_veil.port_scatter`): the point
source sigma_s p I_s dOmega_o exp(-c t) dt at X of the spot's beam lights the emitter
through the port with the irradiance T_F exp(-c s_w) J / n_w^2 per unit intensity (J =
dOmega_air / dA_perp of the forward bundle; (n_a / n_w)^2 the radiance crossing from the
water into the air, which Mitsuba's `dielectric` applies in radiance transport) and the
phase function's angle is the same, mu = -w . o. The RID is a table that is 0 beyond
`THETA_MAX_DEG` (a smooth bump), so that the sensor's cropped film sees every direction
that counts; lightcal's cone integral is Gauss-Legendre in cos(theta) x uniform in phi.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from tests.mitsuba_peer import _transform
from tests.mitsuba_port import N_GLASS, N_WATER, port_faces

D_M, T_M = 0.015, 0.008
CONE_DEG = 8.0
THETA_MAX_DEG = 20.0
ATTENUATION, SIGMA_S, PHASE_G = 0.3, 0.24, 0.5


@dataclass(frozen=True)
class VeilComparison:
    """Mitsuba's f-weighted sum and lightcal's sigma_s I_s (n_a / n_w)^2 int S dOmega,
    and the sum's relative noise estimated from Mitsuba's pixels (two seeds)."""

    theirs: float
    ours: float
    noise: float


def _rid(theta_max: float) -> Any:
    """A smooth bump, ((cos theta - cos theta_max) / (1 - cos theta_max))^2, 0 beyond."""
    from lightcal.core.rid import SymmetricTableRID

    theta = np.linspace(0.0, math.radians(89.0), 891)
    bump = np.clip((np.cos(theta) - math.cos(theta_max)) / (1 - math.cos(theta_max)), 0, None)
    return SymmetricTableRID(theta, bump**2)


def _pixel_weights(size: int, fx: float, rid: Any) -> np.ndarray:
    """(size, size) sum over 4 x 4 sub-pixels of f(u) dOmega (pinhole, centred), the
    sub-pixels' solid angles exact (a rectangle's at unit distance)."""

    def corner(x: np.ndarray, y: np.ndarray) -> np.ndarray:
        return np.arctan(x * y / np.sqrt(1.0 + x * x + y * y))

    k = 4
    edges = (np.arange(size * k + 1) / k - size / 2) / fx
    x0, x1 = edges[:-1][None, :], edges[1:][None, :]
    y0, y1 = edges[:-1][:, None], edges[1:][:, None]
    omega = corner(x1, y1) - corner(x0, y1) - corner(x1, y0) + corner(x0, y0)
    xc, yc = 0.5 * (x0 + x1), 0.5 * (y0 + y1)
    theta = np.arctan(np.hypot(xc, yc))
    f = np.asarray(rid(theta, np.arctan2(yc, xc)), dtype=np.float64)
    return (f * omega).reshape(size, k, size, k).sum(axis=(1, 3))


def compare(size: int, spp: int, variant: str = "llvm_ad_rgb") -> VeilComparison:
    """Render the turned-round scene (module docstring) on size x size pixels covering
    +-(THETA_MAX_DEG + 1) degrees and integrate lightcal's veil over the spot's cone."""
    import mitsuba as mi

    from lightcal.core.flat_port import FlatPort
    from lightcal.core.light_port_veil import port_scatter
    from lightcal.core.medium import Medium
    from lightcal.core.pose import rotation_from_axis

    mi.set_variant(variant)
    light_world = np.array([0.0, 0.0, 1.2])
    R_world_light = rotation_from_axis(np.array([0.05, 0.0, -1.0]) / math.hypot(0.05, 1.0))
    camera_world = np.array([0.12, 0.02, 1.21])
    o_0 = np.array([0.0, 0.0, 0.6]) - camera_world
    o_0 /= np.linalg.norm(o_0)
    rid = _rid(math.radians(THETA_MAX_DEG))
    half = math.radians(THETA_MAX_DEG + 1.0)
    fx = size / 2 / math.tan(half)
    T_world_light = np.array(_transform(R_world_light, light_world))
    water = {"type": "ref", "id": "water"}
    spot_R = rotation_from_axis(o_0)
    scene = {
        "type": "scene",
        "integrator": {"type": "volpath", "max_depth": 4},
        "sensor": {
            "type": "perspective",
            "fov": math.degrees(2 * half),
            "fov_axis": "x",
            "to_world": mi.ScalarTransform4f(
                (T_world_light @ np.diag([-1.0, -1.0, 1.0, 1.0])).tolist()
            ),
            "film": {
                "type": "hdrfilm",
                "width": size,
                "height": size,
                "rfilter": {"type": "box"},
                "pixel_format": "rgb",
            },
            "sampler": {"type": "independent", "sample_count": spp},
        },
        "wall": {
            "type": "rectangle",
            "to_world": mi.ScalarTransform4f().scale([3.0, 3.0, 1.0]),
            "bsdf": {"type": "diffuse", "reflectance": {"type": "rgb", "value": [0.0] * 3}},
        },
        **port_faces(mi, T_world_light, water, 0.05, distance_m=D_M, thickness_m=T_M),
        "water": {
            "type": "homogeneous",
            "sigma_t": ATTENUATION,
            "albedo": SIGMA_S / ATTENUATION,
            "phase": {"type": "hg", "g": PHASE_G},
        },
        "spot": {
            "type": "spot",
            "cutoff_angle": CONE_DEG,
            "beam_width": CONE_DEG - 1e-3,
            "intensity": {"type": "rgb", "value": [1.0, 1.0, 1.0]},
            "to_world": mi.ScalarTransform4f(_transform(spot_R, camera_world)),
            "medium": water,
        },
    }
    loaded = mi.load_dict(scene)
    weights = _pixel_weights(size, fx, rid)
    sums = []
    for seed in (1, 2):
        radiance = np.array(mi.render(loaded, seed=seed))[:, :, 0]
        sums.append(float(np.sum(weights * radiance)))
    theirs = 0.5 * (sums[0] + sums[1])
    # lightcal: S over the spot's cone, Gauss-Legendre in cos(theta) x uniform in phi.
    n_t, n_p = 24, 48
    x, w = np.polynomial.legendre.leggauss(n_t)
    cos_lo = math.cos(math.radians(CONE_DEG))
    cos_t = cos_lo + (1 - cos_lo) * 0.5 * (x + 1)
    w_t = (1 - cos_lo) * 0.5 * w
    phi = (np.arange(n_p) + 0.5) * 2 * math.pi / n_p
    sin_t = np.sqrt(1 - cos_t**2)
    local = np.stack(
        [
            sin_t[:, None] * np.cos(phi)[None, :],
            sin_t[:, None] * np.sin(phi)[None, :],
            np.broadcast_to(cos_t[:, None], (n_t, n_p)),
        ],
        axis=-1,
    ).reshape(-1, 3)
    dirs = local @ spot_R.T
    ends = camera_world + dirs * (-camera_world[2] / dirs[:, 2])[:, None]
    port = FlatPort(D_M, T_M, N_GLASS, N_WATER)
    medium = Medium(ATTENUATION, 1.0, PHASE_G)
    s, _ = port_scatter(
        ends, camera_world, light_world, R_world_light, rid.data(), port, medium, False
    )
    integral = float(np.sum(s.reshape(n_t, n_p) * w_t[:, None]) * 2 * math.pi / n_p)
    ours = SIGMA_S * integral / N_WATER**2
    return VeilComparison(theirs, ours, abs(sums[0] - sums[1]) / (2 * theirs))
