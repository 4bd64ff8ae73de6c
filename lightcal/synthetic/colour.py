"""Colour datasets: the wall photographed through water whose attenuation (and backscatter)
differ by colour channel (`SynthConfig.channels`, `lightcal synth --attenuation C_R C_G C_B`).

Each view is one 3-channel 16-bit image (OpenCV's B, G, R planes in a PNG; R, G, B samples
in an RGB TIFF: `lightcal.io.images.read_image(path, channel=...)` reads either). Channel
k is rendered by the same imaging as single-channel data (`lightcal.synthetic.imaging`),
with the light scales times `ColourChannels.relative_colour()[k]` and the water
(c_k, beta_k; g shared), and goes through the same sensor model with its own noise draws
(the sensor stream's draws, channel R, then G, then B, per view). A departure that is not
colour-blind is per channel the single-channel one of that channel: the room light
(`ambient`) is F times the brightest beam value of that channel's median image. The
corner's bounce (computed for one water) is refused, and so is a declared albedo map beside
declared channels (the joint solve of `sensor.channels` models neither).

What truth.json records of a colour dataset (the single-channel truth is unchanged), in
the shape of the Mitsuba `rgb_water` truth (tests/mitsuba_datasets.py) and of the
calibration result's `channels`:

- `channels`: one entry per channel in the order R, G, B: `name`, `colour` (the relative
  colour: `--colour` over its largest value), `scales` (each light's scale in DN at the
  first image's exposure: the light's `scale` times `colour`), `medium`
  (`attenuation_per_m` c, `backscatter_per_m` beta, `phase_g`) and, with room light,
  `ambient_per_exposure_dn`;
- `lights[j].scale`: the list of that light's scales per channel, `lights[j].channels` the
  channels' names (`relative_scale` stays the light's relative scale before the colour);
- `departures.attenuation.coefficient_per_m` and `departures.backscatter.beta_per_m`: lists
  per channel, with `channels` beside them; `departures.ambient`'s `reference_view`,
  `reference_peak_dn`, `reference_exposure`, `per_exposure_dn` and `levels_dn`: lists per
  channel (each the single-channel value of that channel), with `channels`;
- `views[i].peak_signal_dn` and `views[i].saturated_pixels`: lists per channel.

The project: with `ColourChannels.declare` it solves the channels jointly
(`sensor.channels: [R, G, B]`, the medium's values lists per channel); without, it reads
the images' luminance (`sensor.channel: auto`), the mix of three waters the in-air or
one-water model does not describe.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from lightcal.core.scene import Rig
from lightcal.errors import InputError
from lightcal.io.sensor_spec import ColourChannel
from lightcal.synthetic.departures import Departures
from lightcal.synthetic.imaging import AmbientLevels, Imaging

if TYPE_CHECKING:
    from lightcal.synthetic.dataset import SynthConfig

__all__ = [
    "CHANNEL_NAMES",
    "MAX_COLOUR_RATIO",
    "ColourChannels",
    "check_colour_config",
    "colour_truth",
    "declared_channels",
    "stack_channels",
]

CHANNEL_NAMES: tuple[ColourChannel, ...] = ("R", "G", "B")
"""A colour dataset's channels, in the order of every per-channel list."""

MAX_COLOUR_RATIO = 100.0
"""Largest ratio of two `ColourChannels.colour` values: a channel 100 times darker than
the brightest holds no beam above the noise."""

_Triple = tuple[float, float, float]


@dataclass(frozen=True)
class ColourChannels:
    """The channels of a colour dataset (module docstring).

    Attributes:
        attenuation_per_m: (c_R, c_G, c_B), each as `Departures.attenuation_per_m`, 1/m.
        backscatter_per_m: (beta_R, beta_G, beta_B), each as
            `Departures.backscatter_per_m`, 1/m (the phase g is `Departures.phase_g`).
        colour: The wall-times-light colour: each channel's light scale relative to the
            others, > 0; divided by its largest value, so that the brightest channel gets
            the exposure target of a single-channel dataset.
        declare: The project solves the channels jointly (`sensor.channels`) with the
            medium it declares; else it reads one channel (the luminance).
    """

    attenuation_per_m: _Triple = (0.0, 0.0, 0.0)
    backscatter_per_m: _Triple = (0.0, 0.0, 0.0)
    colour: _Triple = (1.0, 1.0, 1.0)
    declare: bool = False

    def __post_init__(self) -> None:
        n = len(CHANNEL_NAMES)
        for name in ("attenuation_per_m", "backscatter_per_m", "colour"):
            values = getattr(self, name)
            if len(values) != n:
                raise InputError(name, f"expected {n} values (R G B), got {len(values)}")
        for c, beta in zip(self.attenuation_per_m, self.backscatter_per_m, strict=True):
            Departures(attenuation_per_m=c, backscatter_per_m=beta)  # each value's checks
        for value in self.colour:
            if not (math.isfinite(value) and value > 0.0):
                raise InputError("colour", f"expected finite values > 0, got {value:g}")
        if max(self.colour) > MAX_COLOUR_RATIO * min(self.colour):
            got = " ".join(f"{v:g}" for v in self.colour)
            raise InputError(
                "colour",
                f"expected values within a factor {MAX_COLOUR_RATIO:g} of each other (a "
                f"channel {MAX_COLOUR_RATIO:g} times darker holds no beam), got {got}",
            )

    @property
    def names(self) -> tuple[ColourChannel, ...]:
        return CHANNEL_NAMES

    def relative_colour(self) -> NDArray[np.float64]:
        """(3,) `colour` over its largest value."""
        colour = np.asarray(self.colour, dtype=np.float64)
        return colour / colour.max()

    def widest(self, departures: Departures) -> Departures:
        """`departures` with the largest c and beta of the channels (what the checks of
        a single water, and the departures' names in truth.json, see)."""
        return dataclasses.replace(
            departures,
            attenuation_per_m=max(self.attenuation_per_m),
            backscatter_per_m=max(self.backscatter_per_m),
        )

    def imagings(self, imaging: Imaging) -> list[Imaging]:
        """One imaging per channel: `imaging` (its bow, texture, fall-offs) with the
        channel's water and its light scales times the relative colour."""
        out = []
        for k, weight in enumerate(self.relative_colour()):
            lights = imaging.rig.lights
            rig = Rig(tuple(light.replace(scale=light.scale * weight) for light in lights))
            out.append(
                dataclasses.replace(
                    imaging,
                    rig=rig,
                    attenuation_per_m=self.attenuation_per_m[k],
                    backscatter_per_m=self.backscatter_per_m[k],
                )
            )
        return out


def check_colour_config(config: SynthConfig) -> None:
    """What a colour dataset refuses (`SynthConfig.channels`; nothing without it)."""
    channels = config.channels
    if channels is None:
        return
    departures = config.departures
    if departures.attenuation_per_m != 0.0 or departures.backscatter_per_m != 0.0:
        raise InputError(
            "departures",
            "with channels the water is per channel (channels.attenuation_per_m, "
            "channels.backscatter_per_m); expected departures without attenuation and "
            "backscatter",
        )
    if departures.corner is not None:
        raise InputError(
            "corner",
            "not in a colour dataset: the bounce light is computed for one water, and the "
            "joint solve of colour channels does not model surroundings",
        )
    if channels.declare and config.albedo_map:
        raise InputError(
            "albedo_map",
            "not beside declared colour channels: the joint solve of sensor.channels does "
            "not model an albedo map",
        )


def declared_channels(channels: ColourChannels | None) -> list[ColourChannel] | None:
    """The project's `sensor.channels`: the names when `channels` are declared, else None."""
    return list(CHANNEL_NAMES) if channels is not None and channels.declare else None


def stack_channels(planes: list[NDArray[np.uint16]]) -> NDArray[np.uint16]:
    """(H, W, 3) the R, G, B planes in OpenCV's B, G, R order (`encode_image`'s)."""
    return np.dstack(planes[::-1])


def colour_truth(
    truth: dict[str, Any],
    channels: ColourChannels,
    *,
    phase_g: float,
    ambients: list[AmbientLevels] | None,
    view_channels: list[dict[str, list[Any]]],
) -> dict[str, Any]:
    """truth.json of a colour dataset from its single-channel document (module docstring).

    Args:
        truth: `truth_document`'s content, written with the first channel's ambient and
            the widest water's departure names (`ColourChannels.widest`).
        channels: The colour channels.
        phase_g: The water's Henyey-Greenstein g.
        ambients: Each channel's room light, or None without.
        view_channels: Per view, its per-channel fields (`peak_signal_dn`,
            `saturated_pixels`: one value per channel).
    """
    names = list(channels.names)
    colour = channels.relative_colour()
    for light in truth["lights"]:
        scale = light["scale"]
        light["scale"] = [scale * float(w) for w in colour]
        light["channels"] = names
    entries = []
    for k, name in enumerate(names):
        entry: dict[str, Any] = {
            "name": name,
            "colour": float(colour[k]),
            "scales": [light["scale"][k] for light in truth["lights"]],
            "medium": {
                "attenuation_per_m": channels.attenuation_per_m[k],
                "backscatter_per_m": channels.backscatter_per_m[k],
                "phase_g": phase_g,
            },
        }
        if ambients is not None:
            entry["ambient_per_exposure_dn"] = ambients[k].per_exposure_dn
        entries.append(entry)
    truth["channels"] = entries
    for view, fields in zip(truth["views"], view_channels, strict=True):
        view.update(fields)
    found = truth.get("departures", {})
    if "attenuation" in found:
        found["attenuation"]["coefficient_per_m"] = list(channels.attenuation_per_m)
        found["attenuation"]["channels"] = names
    if "backscatter" in found:
        found["backscatter"]["beta_per_m"] = list(channels.backscatter_per_m)
        found["backscatter"]["channels"] = names
    if "ambient" in found and ambients is not None:
        levels = found["ambient"]
        view_names = [view["name"] for view in truth["views"]]
        levels["reference_view"] = [view_names[a.reference] for a in ambients]
        levels["reference_peak_dn"] = [a.reference_peak_dn for a in ambients]
        levels["reference_exposure"] = [a.reference_exposure for a in ambients]
        levels["per_exposure_dn"] = [a.per_exposure_dn for a in ambients]
        levels["levels_dn"] = [list(a.levels_dn) for a in ambients]
        levels["channels"] = names
    return truth
