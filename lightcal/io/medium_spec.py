"""The project file's `medium` section: what lies between the rig and the wall.

    medium:
      attenuation_per_m: 0.2          # c, 1/m (the start when it is estimated)
      backscatter_per_m: 0.5          # beta, 1/m: single scattering along the rays (radiance)
      phase_g: 0.9                    # its Henyey-Greenstein asymmetry (given)
      estimate: [attenuation_per_m, backscatter_per_m]   # default: given

Without the section the rig is in air (c = 0, nothing estimated). With
`sensor.channels` (colour channels solved jointly) c and beta may be lists, one value
per channel (a number: the same start in every channel); each channel then has its own
medium, all estimating the same parameters, and `phase_g` is shared. The model is
docs/model.md's "Medium"; `build_media` turns the section into the core's
`MediumUnknown`, one per channel.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Annotated, Literal

from pydantic import BaseModel, ConfigDict, Field, field_validator

from lightcal.core.medium import MAX_ATTENUATION_PER_M, MAX_BACKSCATTER_PER_M, MAX_PHASE_G, Medium
from lightcal.core.problem import MediumUnknown
from lightcal.errors import InputError

__all__ = ["MediumParameterName", "MediumSpec", "build_media", "build_medium"]

MediumParameterName = Literal["attenuation_per_m", "backscatter_per_m", "phase_g"]

_Attenuation = Annotated[float, Field(ge=0.0, le=MAX_ATTENUATION_PER_M)]
_Backscatter = Annotated[float, Field(ge=0.0, le=MAX_BACKSCATTER_PER_M)]


class MediumSpec(BaseModel):
    """The medium between the rig and the wall (docs/model.md, "Medium").

    `attenuation_per_m`: the attenuation coefficient c of a homogeneous medium, 1/m:
    every value is multiplied by exp(-c (d_light + d_camera)), the distances from the
    light and from the camera to the wall point. `backscatter_per_m`: beta, the light the
    beam scatters back along each pixel's ray, relative to the wall's diffuse reflectance
    (sigma_s pi / albedo), 1/m; `phase_g` the Henyey-Greenstein asymmetry of that
    scattering. `estimate`: the parameters to estimate with the light(s), starting from
    the given values (`phase_g` only with backscatter, which it shapes).
    """

    model_config = ConfigDict(extra="forbid", allow_inf_nan=False, frozen=True)

    attenuation_per_m: _Attenuation | list[_Attenuation] = Field(
        default=0.0,
        description="attenuation coefficient c, 1/m (0: air; clear ocean water 0.05-0.5); "
        "the start when estimated; a list: one per `sensor.channels`",
    )
    backscatter_per_m: _Backscatter | list[_Backscatter] = Field(
        default=0.0,
        description="backscatter coefficient beta relative to the wall's diffuse "
        "reflectance (sigma_s pi / albedo), 1/m; the start when estimated; a list: one per "
        "`sensor.channels`",
    )
    phase_g: float = Field(
        default=0.9,
        ge=-MAX_PHASE_G,
        le=MAX_PHASE_G,
        description="Henyey-Greenstein asymmetry g of the scattering (ocean water ~0.9); "
        "the start when estimated",
    )
    estimate: list[MediumParameterName] = Field(
        default_factory=list, description="the medium's parameters to estimate"
    )

    @field_validator("estimate")
    @classmethod
    def _once(cls, value: list[str]) -> list[str]:
        if len(set(value)) != len(value):
            raise ValueError("expected each parameter once")
        return value


def build_medium(spec: MediumSpec, sensor_model: str, source: str | Path) -> MediumUnknown:
    """The core's `MediumUnknown` of a medium section of one channel (see `build_media`)."""
    return build_media(spec, sensor_model, source, ())[0]


def build_media(
    spec: MediumSpec, sensor_model: str, source: str | Path, channels: Sequence[str]
) -> tuple[MediumUnknown, ...]:
    """One `MediumUnknown` per channel of `channels` (one without channels); a list of
    values needs one per channel. Backscatter (given or estimated) needs the `radiance`
    sensor model (the renderer's backscatter is a radiance)."""
    n = max(1, len(channels))
    attenuation = _per_channel(spec.attenuation_per_m, "attenuation_per_m", channels, source)
    backscatter = _per_channel(spec.backscatter_per_m, "backscatter_per_m", channels, source)
    scatters = max(backscatter) > 0.0 or "backscatter_per_m" in spec.estimate
    if scatters and sensor_model != "radiance":
        raise InputError(
            source,
            "medium.backscatter_per_m: the backscatter is modelled for sensor.model "
            f"radiance; got {sensor_model!r}",
        )
    if "phase_g" in spec.estimate and not scatters:
        raise InputError(
            source,
            "medium.estimate: phase_g shapes the backscatter; expected backscatter_per_m > 0 "
            "or estimated beside it",
        )
    return tuple(
        MediumUnknown(Medium(attenuation[k], backscatter[k], spec.phase_g), tuple(spec.estimate))
        for k in range(n)
    )


def _per_channel(
    value: float | list[float], key: str, channels: Sequence[str], source: str | Path
) -> list[float]:
    """`value` per channel: a number for every channel, a list one per channel."""
    n = max(1, len(channels))
    if not isinstance(value, list):
        return [float(value)] * n
    if not channels:
        raise InputError(
            source,
            f"medium.{key}: a list gives one value per colour channel; expected a number, "
            "or sensor.channels",
        )
    if len(value) != n:
        raise InputError(
            source,
            f"medium.{key}: expected one value per channel of sensor.channels "
            f"({', '.join(channels)}: {n}), got {len(value)}",
        )
    return [float(v) for v in value]
