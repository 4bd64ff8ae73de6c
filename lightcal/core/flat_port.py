"""The camera's flat port: refraction of the pixels' rays at a window into water.

Underwater the camera looks through a flat window (a "flat port"): a glass (or acrylic)
plate of thickness t and index n_g whose inner face lies at distance d from the centre
of projection, its normal along the optical axis (or tilted by a small angle), water of
index n_w outside. A pixel's ray leaves the centre of projection in air (the pinhole
direction r of the intrinsics and distortion, as without a port), is refracted at the
inner face (air -> glass) and at the outer face (glass -> water), and runs on in the
water from its exit point X_p on the outer face in direction w (docs/model.md, "The
camera's flat port").

Snell's law in vector form at an interface of unit normal n (pointing along the
propagation, into the second medium), eta = n_1 / n_2, for a unit direction r:

    cos_i = r . n,  cos_t = sqrt(1 - eta^2 (1 - cos_i^2)),  t = eta r + (cos_t - eta cos_i) n,

t the refracted unit direction (`refract`).

The port's faces are parallel, so n sin(theta) is the same in air, glass and water:
n_air sin(theta_air) = n_w sin(theta_w) whatever the glass, which only shifts the ray
sideways. With n_w >= n_air (and n_g >= n_air) there is no total internal reflection
for any ray that reaches the port: sin(theta) in each medium is n_air sin(theta_air) /
n <= 1. A flat port's faces are planes, so decentring it (moving it sideways) changes
nothing; only its distance, thickness, indices and tilt matter.

Frames: the camera's (OpenCV: x right, y down, z forward), metres.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

#: The refractive index of the air inside the housing (1, as refractive camera models
#: take it; the true 1.0003 changes the water's angles by 3e-4 relative).
AIR_INDEX = 1.0

#: The largest tilt of the port's normal from the optical axis accepted, degrees.
MAX_TILT_DEG = 20.0


@dataclass(frozen=True, eq=False)
class FlatPort:
    """A flat window in front of the camera, camera frame, metres.

    Args:
        distance_m: d, from the centre of projection to the port's inner face along its
            normal (the perpendicular distance), > 0.
        thickness_m: t, the window's thickness, >= 0 (0: one interface air -> water).
        glass_index: n_g, the window's refractive index (acrylic 1.49, glass 1.52),
            >= the air's.
        water_index: n_w, the water's (1.33-1.34), >= the air's.
        normal_camera: (3,) the port's normal (towards the water), camera frame; a unit
            vector with a positive z tilted at most `MAX_TILT_DEG` from the optical axis.
            Default the optical axis (0, 0, 1).
        air_index: the air's inside the housing.
    """

    distance_m: float
    thickness_m: float
    glass_index: float = 1.49
    water_index: float = 1.333
    normal_camera: np.ndarray = field(default_factory=lambda: np.array([0.0, 0.0, 1.0]))
    air_index: float = AIR_INDEX

    def __post_init__(self) -> None:
        for name, value, low in (
            ("distance_m", self.distance_m, 0.0),
            ("thickness_m", self.thickness_m, 0.0),
            ("air_index", self.air_index, 1.0),
        ):
            _check_number(f"port: {name}", value, low, strict=name == "distance_m")
        for name, value in (("glass_index", self.glass_index), ("water_index", self.water_index)):
            _check_number(f"port: {name}", value, 1.0, strict=False)
            if float(value) < float(self.air_index):
                raise ValueError(
                    f"port: {name}: expected an index >= the air's ({self.air_index}), got "
                    f"{value} (a port into a medium less dense than air is not a flat port)"
                )
        if self.distance_m > 1.0 or self.thickness_m > 0.2:
            raise ValueError(
                f"port: expected a distance up to 1 m and a thickness up to 0.2 m (metres, "
                f"not millimetres), got {self.distance_m} m and {self.thickness_m} m"
            )
        n = np.asarray(self.normal_camera, dtype=np.float64).reshape(-1)
        if n.shape != (3,) or not np.all(np.isfinite(n)) or np.linalg.norm(n) == 0.0:
            raise ValueError(f"port: normal_camera: expected a finite (3,) vector, got {n}")
        n = n / np.linalg.norm(n)
        tilt = math.degrees(math.acos(min(1.0, float(n[2])))) if n[2] > 0.0 else 180.0
        if tilt > MAX_TILT_DEG:
            raise ValueError(
                f"port: normal_camera: expected a normal within {MAX_TILT_DEG:g} degrees of "
                f"the optical axis (0, 0, 1), got one {tilt:.3g} degrees off"
            )
        for name in ("distance_m", "thickness_m", "glass_index", "water_index", "air_index"):
            object.__setattr__(self, name, float(getattr(self, name)))
        n.setflags(write=False)
        object.__setattr__(self, "normal_camera", n)

    @property
    def tilt_deg(self) -> float:
        """The angle between the port's normal and the optical axis, degrees."""
        return math.degrees(math.acos(min(1.0, float(self.normal_camera[2]))))

    def trace(self, rays_camera: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The pixels' rays through the port, camera frame.

        Args:
            rays_camera: (N, 3) directions from the centre of projection (any length,
                e.g. (x, y, 1) of undistorted normalised coordinates); NaN rows allowed.

        Returns:
            origins: (N, 3) where each ray leaves the port's outer face into the water,
                m (NaN where not ok).
            directions: (N, 3) its unit direction in the water (NaN where not ok).
            ok: (N,) the ray is finite and reaches the port (r . n > 0).
        """
        r = np.asarray(rays_camera, dtype=np.float64).reshape(-1, 3)
        n = self.normal_camera
        with np.errstate(invalid="ignore", divide="ignore"):
            r = r / np.linalg.norm(r, axis=1, keepdims=True)
            cos_air = r @ n
            ok = np.isfinite(cos_air) & (cos_air > 0.0)
            # The inner face: n . X = d.
            inner = r * (self.distance_m / cos_air)[:, None]
            g, ok_g = refract(r, n, self.air_index / self.glass_index)
            cos_glass = g @ n
            outer = inner + g * (self.thickness_m / cos_glass)[:, None]
            w, ok_w = refract(g, n, self.glass_index / self.water_index)
        # No total internal reflection from air into denser media (module docstring).
        assert not np.any(ok & ~(ok_g & ok_w)), "flat port: total internal reflection"
        outer[~ok] = np.nan
        w[~ok] = np.nan
        return outer, w, ok

    def describe(self) -> dict:
        """Its parameters, SI units, for results and messages."""
        return {
            "distance_m": self.distance_m,
            "thickness_m": self.thickness_m,
            "glass_index": self.glass_index,
            "water_index": self.water_index,
            "tilt_deg": self.tilt_deg,
        }


def refract(
    directions: np.ndarray, normal: np.ndarray, eta: float
) -> tuple[np.ndarray, np.ndarray]:
    """Snell's law in vector form at a plane interface.

    Args:
        directions: (N, 3) unit directions of the incident rays.
        normal: (3,) the interface's unit normal, on the side the rays go to
            (directions . normal > 0).
        eta: n_1 / n_2, the index the rays come from over the one they enter.

    Returns:
        refracted: (N, 3) unit directions, eta r + (cos_t - eta cos_i) n with
            cos_i = r . n, cos_t = sqrt(1 - eta^2 (1 - cos_i^2)); NaN where totally
            reflected.
        ok: (N,) not totally reflected (eta^2 sin^2_i <= 1).
    """
    cos_i = directions @ normal
    sin2_t = eta * eta * np.maximum(0.0, 1.0 - cos_i * cos_i)
    ok = sin2_t <= 1.0
    with np.errstate(invalid="ignore"):
        cos_t = np.sqrt(np.where(ok, 1.0 - sin2_t, np.nan))
    out = eta * directions + (cos_t - eta * cos_i)[:, None] * normal[None, :]
    return out, ok


def _check_number(name: str, value: object, low: float, *, strict: bool) -> None:
    if isinstance(value, bool) or not isinstance(value, int | float | np.floating):
        raise ValueError(f"{name}: expected a number, got {value!r}")
    v = float(value)
    if not math.isfinite(v) or v < low or (strict and v == low):
        raise ValueError(
            f"{name}: expected a finite value {'>' if strict else '>='} {low}, got {v}"
        )
