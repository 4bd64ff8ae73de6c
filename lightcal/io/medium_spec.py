"""The project file's `medium` section: what lies between the rig and the wall.

    medium:
      attenuation_per_m: 0.2          # c, 1/m (the start when it is estimated)
      estimate: [attenuation_per_m]   # estimated with the light(s); default: given

Without the section the rig is in air (c = 0, nothing estimated). The model is
docs/model.md's "Medium"; `build_medium` turns the section into the core's
`MediumUnknown`.
"""

from __future__ import annotations

from typing import Literal

from pydantic import BaseModel, ConfigDict, Field, field_validator

from lightcal.core.medium import MAX_ATTENUATION_PER_M, Medium
from lightcal.core.problem import MediumUnknown

__all__ = ["MediumParameterName", "MediumSpec", "build_medium"]

MediumParameterName = Literal["attenuation_per_m"]


class MediumSpec(BaseModel):
    """The medium between the rig and the wall (docs/model.md, "Medium").

    `attenuation_per_m`: the attenuation coefficient c of a homogeneous medium, 1/m:
    every value is multiplied by exp(-c (d_light + d_camera)), the distances from the
    light and from the camera to the wall point. `estimate`: the parameters to estimate
    with the light(s), starting from the given values.
    """

    model_config = ConfigDict(extra="forbid", allow_inf_nan=False, frozen=True)

    attenuation_per_m: float = Field(
        default=0.0,
        ge=0.0,
        le=MAX_ATTENUATION_PER_M,
        description="attenuation coefficient c, 1/m (0: air; clear ocean water 0.05-0.5); "
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


def build_medium(spec: MediumSpec) -> MediumUnknown:
    """The core's `MediumUnknown` of a medium section."""
    return MediumUnknown(Medium(spec.attenuation_per_m), tuple(spec.estimate))
