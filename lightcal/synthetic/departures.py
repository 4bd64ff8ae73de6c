"""Departures of synthetic data from what its project declares (`lightcal synth`, issue 24).

A synthetic dataset's project says what a user would declare: a flat Lambertian wall,
the `radiance` sensor model with linear data and no offset, the light's plain profile,
camera poses with the covariance of their measurement. Each departure makes the images
(or the measured poses) differ from that declaration in one everyday way, so that the
calibration's diagnostics can be tested on data whose fault is known:

| name | field | what the data does |
|---|---|---|
| `ambient` | `ambient_fraction` | room light: a uniform value on every pixel |
| `undeclared_vignetting` | `undeclared_vignetting` | a radial lens fall-off nobody declared |
| `rid_rim` | `rid_rim_amplitude` | the light's profile has a bright rim at its half angle |
| `gamma` | `gamma` | a non-linear (tone curve) response |
| `pose_error` | `pose_error_m`, `pose_error_deg` | poses worse than their covariance says |
| `bow` | `bow_m` | the wall bulges towards the cameras (or is dented) |
| `albedo_texture` | `albedo_texture_amplitude` | the wall's albedo varies smoothly |
| `attenuation` | `attenuation_per_m` | a clear but absorbing medium (water) |
| `backscatter` | `backscatter_per_m`, `phase_g` | the water scatters the beam back to the camera |
| `corner` | `corner` | a ceiling and a side wall light the wall back (inter-reflection) |
| `port` | `port` | the camera looks through a flat port (refraction) |
| `light_port` | `light_port` | the lights shine through flat ports (refraction, Fresnel) |

The exact definitions are in `Departures`; `lightcal.synthetic.imaging` applies them and
`describe` writes the parameters that truth.json records under "departures" (name ->
parameters; the key is absent when the data has no departure, so that such datasets stay
byte-identical to those written before departures existed: `read_departures`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from lightcal.errors import InputError

__all__ = [
    "BOW_RADIUS_M",
    "DEPARTURE_NAMES",
    "MAX_BOW_M",
    "RIM_WIDTH_FRACTION",
    "Departures",
    "read_departures",
]

DEPARTURE_NAMES = (
    "ambient",
    "undeclared_vignetting",
    "rid_rim",
    "gamma",
    "pose_error",
    "bow",
    "albedo_texture",
    "attenuation",
    "backscatter",
    "corner",
    "port",
    "light_port",
)
"""The departures' names in truth.json, in the order they are listed there."""

RIM_WIDTH_FRACTION = 0.15
"""w / theta_half of the bright rim of `rid_rim` (the Gaussian's 1/e half width)."""

BOW_RADIUS_M = 1.0
"""Radius R of the bowed disc of `bow`, metres."""

MAX_BOW_M = 0.1
"""Largest |depth| of `bow`, metres: the slope at the disc's rim stays <= 2 depth / R = 0.2."""


MAX_AMPLITUDE = 10.0
"""Largest `ambient_fraction` and `rid_rim_amplitude`: beyond, the beam is lost under them
(and huge values overflow the sensor's noise)."""

GAMMA_RANGE = (0.1, 10.0)
"""Accepted `gamma`: beyond, every value above black is stored as black or as white."""

MAX_ATTENUATION_PER_M = 2.0
"""Largest `attenuation_per_m`, 1/m: beyond, exp(-C d) leaves no beam over metres."""

MAX_BACKSCATTER_PER_M = 100.0
"""Largest `backscatter_per_m`, 1/m."""

MAX_POSE_ERROR_M = 0.1
"""Largest `pose_error_m`, metres."""

MAX_POSE_ERROR_DEG = 10.0
"""Largest `pose_error_deg`, degrees."""


def _check(name: str, value: float, ok: bool, expected: str) -> None:
    if not (math.isfinite(value) and ok):
        raise InputError(name, f"expected {expected}, got {value:g}")


@dataclass(frozen=True)
class Departures:
    """How the synthetic data departs from its project (module docstring). The defaults
    depart in nothing.

    Attributes:
        ambient_fraction: F >= 0. Room light: a uniform radiance is added to every pixel,
            F times the brightest value of the beam in the dataset's median image (the
            image whose beam peak is the lower median of all images' peaks) at that
            image's exposure, scaled by each image's exposure (constant light in the room:
            it grows with exposure time as the beam does). It goes through the sensor's
            fall-off (`map`, `cos4`) like the beam. The project still estimates no offset.
        undeclared_vignetting: (k1, k2) or None. The images carry the radial fall-off
            V = 1 + k1 r^2 + k2 r^4 (r normalised by the half diagonal, centred: the
            convention of `RadialVignetting` and `--vignetting`); the project declares the
            `radiance` sensor model (only allowed with it) and writes no map.
        rid_rim_amplitude: A >= 0. The light's true profile is the declared one times
            1 + A exp(-((theta - theta_half) / w)^2), theta_half its half-intensity angle
            (per azimuth for a 2-D table), w = `RIM_WIDTH_FRACTION` theta_half. The
            project gets the plain profile.
        gamma: G > 0. The stored value above black is W (x / W)^(1/G), x the linear
            (noisy) value above black and W = white - black the usable range (negative x
            clip at 0): a camera's tone curve, with the black and white levels unchanged.
            The project still declares linear data.
        pose_error_m: sigma >= 0, metres: an extra error of each measured camera centre
            coordinate, on top of the declared pose noise (`SynthConfig.pose_noise_m`);
            the project's pose covariance stays that of the pose noise alone.
        pose_error_deg: sigma >= 0, degrees: likewise for each rotation-vector component.
        bow_m: b, |b| <= `MAX_BOW_M` metres. The wall is the height field
            z = b max(0, 1 - |(x, y) - (x0, y0)|^2 / R^2), R = `BOW_RADIUS_M`, (x0, y0) the
            mean of the points where the views' optical axes meet the plane z = 0:
            b > 0 bulges towards the cameras, b < 0 a bowl (dent) away from them.
        albedo_texture_amplitude: A in [0, 1). The wall's albedo is 1 + A t(x, y), t a
            smooth random field in [-1, 1] with features of 10-30 cm
            (`lightcal.synthetic.texture`), shared by all views.
        attenuation_per_m: C >= 0, 1/m. A medium (clear water): each light's contribution
            to a pixel is multiplied by exp(-C (d_light + d_camera)), the distances from
            the light and from the camera centre to the pixel's point on the wall.
        corner: (D, depth, albedo) or None. A ceiling and a side wall, `depth` m deep, meet
            the wall at right angles D m from where the views look, Lambertian of
            `albedo` like the wall: their bounce light is added to every pixel, and the
            pixels that see them or wall they shadow are black
            (`lightcal.synthetic.bounce_reference`: brute force, not the model's code).
        backscatter_per_m: beta >= 0, 1/m, and phase_g: g in [-0.99, 0.99]. The medium
            scatters each light's beam back along the pixels' rays: each pixel gains
            beta S, S the single-scattering integral with the Henyey-Greenstein phase g
            (`lightcal.core.medium.backscatter`, attenuated by C) along the ray to the
            pixel centre's point on the wall (the `radiance` sensor model only).
        port: (distance_mm, thickness_mm, glass_index, water_index) or None. The camera
            looks through a flat port (`lightcal.core.flat_port`): each pixel's ray is
            refracted into the water (`lightcal.synthetic.port_imaging`, point-sampled
            with its own Snell's law), the camera's attenuation from its exit point.
        light_port: (distance_mm, thickness_mm, glass_index, water_index) or None. Every
            light shines through a flat port along its axis
            (`lightcal.synthetic.light_port_imaging`: the air direction by its own
            solve, the irradiance point-sampled), its attenuation from the port.
    """

    ambient_fraction: float = 0.0
    undeclared_vignetting: tuple[float, float] | None = None
    rid_rim_amplitude: float = 0.0
    gamma: float = 1.0
    pose_error_m: float = 0.0
    pose_error_deg: float = 0.0
    bow_m: float = 0.0
    albedo_texture_amplitude: float = 0.0
    attenuation_per_m: float = 0.0
    backscatter_per_m: float = 0.0
    phase_g: float = 0.9
    corner: tuple[float, float, float] | None = None
    port: tuple[float, float, float, float] | None = None
    light_port: tuple[float, float, float, float] | None = None

    def __post_init__(self) -> None:
        for name in ("ambient_fraction", "rid_rim_amplitude", "attenuation_per_m"):
            value = getattr(self, name)
            _check(name, value, value >= 0.0, "a finite value >= 0")
        for name in ("pose_error_m", "pose_error_deg"):
            value = getattr(self, name)
            _check(name, value, value >= 0.0, "a finite value >= 0")
        _check("gamma", self.gamma, self.gamma > 0.0, "a finite value > 0")
        _check(
            "backscatter_per_m",
            self.backscatter_per_m,
            self.backscatter_per_m >= 0.0,
            "a finite value >= 0",
        )
        _check("phase_g", self.phase_g, abs(self.phase_g) <= 0.99, "a value in [-0.99, 0.99]")
        for name, high, unit in (
            ("ambient_fraction", MAX_AMPLITUDE, ""),
            ("rid_rim_amplitude", MAX_AMPLITUDE, ""),
            ("attenuation_per_m", MAX_ATTENUATION_PER_M, " per metre"),
            ("backscatter_per_m", MAX_BACKSCATTER_PER_M, " per metre"),
            ("pose_error_m", MAX_POSE_ERROR_M, " m"),
            ("pose_error_deg", MAX_POSE_ERROR_DEG, " degrees"),
        ):
            value = getattr(self, name)
            _check(name, value, value <= high, f"at most {high:g}{unit}")
        low, high = GAMMA_RANGE
        _check("gamma", self.gamma, low <= self.gamma <= high, f"a value in [{low:g}, {high:g}]")
        _check(
            "bow_m",
            self.bow_m,
            abs(self.bow_m) <= MAX_BOW_M,
            f"a value within +-{MAX_BOW_M:g} m",
        )
        _check(
            "albedo_texture_amplitude",
            self.albedo_texture_amplitude,
            0.0 <= self.albedo_texture_amplitude < 1.0,
            "a value in [0, 1)",
        )
        if self.corner is not None:
            d, depth, albedo = (float(v) for v in self.corner)
            _check("corner", d, 0.05 <= d <= 5.0, "a distance D of 0.05 to 5 m")
            _check("corner", depth, 0.01 <= depth <= 5.0, "a depth of 0.01 to 5 m")
            _check("corner", albedo, 0.0 < albedo < 1.0, "an albedo in (0, 1)")
        for name in ("port", "light_port"):
            if getattr(self, name) is None:
                continue
            from lightcal.core.flat_port import FlatPort

            try:
                d, t, n_g, n_w = (float(v) for v in getattr(self, name))
                FlatPort(d / 1000.0, t / 1000.0, n_g, n_w)
            except (TypeError, ValueError) as exc:
                raise InputError(name, str(exc)) from exc
        coeffs = self.undeclared_vignetting
        if coeffs is not None and (
            len(coeffs) != 2 or not all(math.isfinite(float(c)) for c in coeffs)
        ):
            raise InputError(
                "undeclared_vignetting", f"expected two finite numbers k1 k2, got {coeffs!r}"
            )

    @property
    def names(self) -> tuple[str, ...]:
        """The departures this configuration has, in `DEPARTURE_NAMES` order."""
        on = {
            "ambient": self.ambient_fraction > 0.0,
            "undeclared_vignetting": self.undeclared_vignetting is not None,
            "rid_rim": self.rid_rim_amplitude > 0.0,
            "gamma": self.gamma != 1.0,
            "pose_error": self.pose_error_m > 0.0 or self.pose_error_deg > 0.0,
            "bow": self.bow_m != 0.0,
            "albedo_texture": self.albedo_texture_amplitude > 0.0,
            "attenuation": self.attenuation_per_m > 0.0,
            "backscatter": self.backscatter_per_m > 0.0,
            "corner": self.corner is not None,
            "port": self.port is not None,
            "light_port": self.light_port is not None,
        }
        return tuple(name for name in DEPARTURE_NAMES if on[name])

    @property
    def changes_beam(self) -> bool:
        """Whether the beam's image needs more than the flat renderer (`render_image`):
        a bowed wall, an albedo texture, attenuation, backscatter, a corner or a port."""
        return (
            self.corner is not None
            or self.port is not None
            or self.light_port is not None
            or self.bow_m != 0.0
            or self.albedo_texture_amplitude > 0.0
            or self.attenuation_per_m > 0.0
            or self.backscatter_per_m > 0.0
        )


def read_departures(truth: dict[str, Any]) -> dict[str, dict[str, Any]]:
    """The departures a truth.json records (name -> parameters; {} for none).

    Args:
        truth: The content of a truth.json (`lightcal.synthetic.dataset.read_truth`).

    Raises:
        InputError: "departures" is not a mapping of known names to mappings.
    """
    found = truth.get("departures", {})
    if not isinstance(found, dict) or not all(
        name in DEPARTURE_NAMES and isinstance(value, dict) for name, value in found.items()
    ):
        raise InputError(
            "departures",
            f"expected a mapping of {', '.join(DEPARTURE_NAMES)} to their parameters",
        )
    return found
