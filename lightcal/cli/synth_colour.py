"""`lightcal synth`'s colour datasets: `--attenuation` and `--backscatter` take one value
or three (R G B), and three (either option) make a colour dataset
(`lightcal.synthetic.colour`): every view a 3-channel 16-bit image, channel k in water of
c_k and beta_k (one value: the same in every channel), the light's scale per channel
relative as `--colour R G B` (default 1 1 1).

With `--declare-medium` the project solves the channels jointly: `sensor.channels:
[R, G, B]` and the medium as lists per channel (given: the true values; estimated: from a
rough guess, c = `START_ATTENUATION_PER_M` in every channel and, when the water scatters,
beta = `START_BACKSCATTER_PER_M`). Without it the project reads the luminance
(`sensor.channel: auto`), a mix of three waters.

Cheap imports only: `lightcal --help` builds the parser from here.
"""

from __future__ import annotations

import argparse
from typing import TYPE_CHECKING, Any

from lightcal.cli.synth_options import build
from lightcal.errors import InputError

if TYPE_CHECKING:
    from lightcal.io.medium_spec import MediumSpec
    from lightcal.synthetic.colour import ColourChannels

__all__ = ["START_ATTENUATION_PER_M", "START_BACKSCATTER_PER_M", "colour_medium", "water_of"]

START_ATTENUATION_PER_M = 0.2
"""c every channel starts from when a colour dataset's project estimates it, 1/m."""

START_BACKSCATTER_PER_M = 0.5
"""beta every channel starts from when it is estimated, 1/m."""

_COLOUR = "a colour dataset (three --attenuation or --backscatter values, R G B)"


def _values(args: argparse.Namespace, dest: str, option: str) -> list[float]:
    values = getattr(args, dest)
    if values is None:
        return [0.0]
    if len(values) not in (1, 3):
        raise InputError(option, f"expected 1 value or 3 (R G B), got {len(values)}")
    return [float(v) for v in values]


def water_of(args: argparse.Namespace) -> tuple[argparse.Namespace, ColourChannels | None]:
    """The options with `attenuation` and `backscatter` single numbers (0 in a colour
    dataset, whose water is the channels'), and the colour channels (None: one channel).

    Raises:
        InputError: naming the option: 2 values, a value out of range, `--colour` without
            a colour dataset, a departure a colour dataset cannot have.
    """
    attenuation = _values(args, "attenuation", "--attenuation")
    backscatter = _values(args, "backscatter", "--backscatter")
    if len(attenuation) == 1 and len(backscatter) == 1:
        if args.colour is not None:
            raise InputError("--colour", f"applies to {_COLOUR} only")
        single = {"attenuation": attenuation[0], "backscatter": backscatter[0]}
        return argparse.Namespace(**{**vars(args), **single}), None
    from lightcal.synthetic.colour import ColourChannels

    if args.corner is not None:
        raise InputError(
            "--corner",
            f"not in {_COLOUR}: its bounce light is computed for one water, and the joint "
            "solve of colour channels does not model surroundings",
        )
    if args.declare_albedo_map and args.declare_medium is not None:
        raise InputError(
            "--declare-albedo-map",
            f"not with --declare-medium in {_COLOUR}: its project solves the channels "
            "jointly (sensor.channels), which does not model an albedo map",
        )
    triple = [attenuation * 3 if len(attenuation) == 1 else attenuation]
    triple.append(backscatter * 3 if len(backscatter) == 1 else backscatter)
    colour = args.colour
    channels = build(
        lambda: ColourChannels(
            attenuation_per_m=(triple[0][0], triple[0][1], triple[0][2]),
            backscatter_per_m=(triple[1][0], triple[1][1], triple[1][2]),
            colour=(1.0, 1.0, 1.0) if colour is None else (colour[0], colour[1], colour[2]),
            declare=args.declare_medium is not None,
        )
    )
    return argparse.Namespace(**{**vars(args), "attenuation": 0.0, "backscatter": 0.0}), channels


def colour_medium(args: argparse.Namespace, channels: ColourChannels) -> MediumSpec:
    """The project's `medium` of a colour dataset (module docstring; air without
    `--declare-medium`)."""
    from lightcal.io.medium_spec import MediumSpec

    if args.declare_medium is None:
        return MediumSpec()
    g = args.phase_g
    scatters = max(channels.backscatter_per_m) > 0.0
    if args.declare_medium == "estimated":
        names: list[Any] = ["attenuation_per_m"]
        if scatters:
            names.append("backscatter_per_m")
        return build(
            lambda: MediumSpec(
                attenuation_per_m=[START_ATTENUATION_PER_M] * 3,
                backscatter_per_m=[START_BACKSCATTER_PER_M if scatters else 0.0] * 3,
                phase_g=g,
                estimate=names,
            )
        )
    if not (max(channels.attenuation_per_m) > 0.0 or scatters):
        raise InputError(
            "--declare-medium",
            "given: expected --attenuation C > 0 or --backscatter BETA > 0 (the medium to declare)",
        )
    return build(
        lambda: MediumSpec(
            attenuation_per_m=list(channels.attenuation_per_m),
            backscatter_per_m=list(channels.backscatter_per_m),
            phase_g=g,
        )
    )
