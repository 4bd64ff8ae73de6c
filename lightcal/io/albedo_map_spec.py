"""The project's `wall.albedo_map`: the wall's albedo map estimated with the light."""

from __future__ import annotations

from pathlib import Path

from pydantic import BaseModel, ConfigDict, Field

from lightcal.core.albedo_map import AlbedoMapOptions
from lightcal.errors import InputError


class AlbedoMapSpec(BaseModel):
    """The wall's albedo map, estimated with the light (docs/model.md, "The albedo map"):
    a bilinear field on a grid of nodes over the wall, the same in every view, solved
    at every step of the solve (it is not a solver parameter). It needs the linear loss
    and many pixels per node (a dense selection: `strategy: all`)."""

    model_config = ConfigDict(extra="forbid", allow_inf_nan=False, frozen=True)

    spacing_mm: float = Field(
        default=25.0,
        ge=1.0,
        le=1000.0,
        allow_inf_nan=False,
        description="the distance between the grid's nodes, mm",
    )
    variation: float = Field(
        default=0.3,
        gt=0.0,
        le=10.0,
        allow_inf_nan=False,
        description="the prior 1-sigma of the albedo about its mean (0.3: +-30 %)",
    )
    smoothness: float = Field(
        default=0.05,
        gt=0.0,
        le=10.0,
        allow_inf_nan=False,
        description="the prior 1-sigma of a second difference of three neighbouring nodes",
    )


def albedo_map_options(a: AlbedoMapSpec | None, loss: str, source: Path) -> AlbedoMapOptions | None:
    """The options of a project's `wall.albedo_map` `a` (None: none), given its solver's
    `loss`; refused with a robust loss (the map is projected out by linear least
    squares)."""
    if a is None:
        return None
    if loss != "linear":
        raise InputError(
            source,
            f"wall.albedo_map: expected solver.loss linear, got {loss!r} (the "
            "albedo map is solved by linear least squares)",
        )
    return AlbedoMapOptions(a.spacing_mm / 1000.0, a.variation, a.smoothness)
