"""The project file's `surroundings` section: surfaces near the wall that light it back.

    surroundings:
      wall_albedo: 0.8              # the wall's diffuse reflectance (for the bounce only)
      patch_m: 0.1                  # the mesh's patch side, m
      bounces: 3                    # keep paths of up to 3 reflections (default: all)
      surfaces:
        - name: ceiling
          corner_m: [-2.2, -0.21, 0.0]   # world frame, m: the wall is z = 0
          edge_u_m: [2.8, 0.0, 0.0]
          edge_v_m: [0.0, 0.0, 0.5]
          albedo: 0.8
          estimate_albedo: true     # solve it with the light, from 0.8 (default: given)

Without the section nothing surrounds the wall. The model is docs/model.md's
"Inter-reflection"; `build_surroundings` turns the section into the core's
`Surroundings`, whose checks (a surface behind the wall, in its plane, of zero size, ...)
become the project's errors.
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import numpy as np
from pydantic import BaseModel, ConfigDict, Field

from lightcal.core.surroundings import (
    DEFAULT_PATCH_M,
    MAX_SURFACES,
    PATCH_RANGE_M,
    Surface,
    Surroundings,
)
from lightcal.errors import InputError

__all__ = ["SurfaceSpec", "SurroundingsSpec", "build_surroundings", "surroundings_spec"]

_Vec3 = Annotated[list[float], Field(min_length=3, max_length=3)]


class _Model(BaseModel):
    model_config = ConfigDict(extra="forbid", allow_inf_nan=False, frozen=True)


class SurfaceSpec(_Model):
    """A planar rectangle corner + s edge_u + t edge_v (s, t in [0, 1]), world frame, m;
    Lambertian of `albedo` on both sides."""

    name: str = Field(default="", description="how messages name it (default surfaces[i])")
    corner_m: _Vec3 = Field(description="one corner, world frame, m (the wall is z = 0)")
    edge_u_m: _Vec3 = Field(description="the first edge from that corner, m")
    edge_v_m: _Vec3 = Field(description="the second edge from that corner, m")
    albedo: float = Field(ge=0.0, lt=1.0, description="its diffuse reflectance, 0 to 1")
    estimate_albedo: bool = Field(
        default=False, description="estimate its albedo with the light, from `albedo`"
    )


class SurroundingsSpec(_Model):
    """Surfaces near the wall (a ceiling, a side wall) whose bounce light the model adds
    to every pixel (docs/model.md, "Inter-reflection"). Pixels that see them, or wall
    they shadow, must be masked."""

    surfaces: list[SurfaceSpec] = Field(min_length=1, max_length=MAX_SURFACES)
    wall_albedo: float = Field(
        default=0.8, gt=0.0, lt=1.0, description="the wall's diffuse reflectance (the bounce's)"
    )
    patch_m: float = Field(
        default=DEFAULT_PATCH_M,
        ge=PATCH_RANGE_M[0],
        le=PATCH_RANGE_M[1],
        description="the side of the mesh's patches (the wall's cells: half), m",
    )
    bounces: int | None = Field(
        default=None,
        ge=1,
        le=50,
        description="reflections between the light and the wall point a pixel sees to keep "
        "(default: all, as in a room; 3 for a path tracer's max_depth 5)",
    )


def build_surroundings(spec: SurroundingsSpec | None, source: str | Path) -> Surroundings | None:
    """The core's `Surroundings` of the section (None without it). A `medium:` beside it
    attenuates the bounce light as it does the direct light (docs/model.md,
    "Inter-reflection").

    Raises:
        InputError: a surface the core refuses (named `surroundings.surfaces[i]`).
    """
    if spec is None:
        return None
    surfaces = []
    for k, s in enumerate(spec.surfaces):
        where = f"surroundings.surfaces[{k}]"
        name = f"{where} ({s.name})" if s.name else where
        try:
            corner, u, v = (
                np.array(a, dtype=np.float64) for a in (s.corner_m, s.edge_u_m, s.edge_v_m)
            )
            surfaces.append(Surface(corner, u, v, s.albedo, name))
        except ValueError as exc:
            raise InputError(source, str(exc)) from exc
    estimated = tuple(k for k, s in enumerate(spec.surfaces) if s.estimate_albedo)
    return Surroundings(tuple(surfaces), spec.wall_albedo, spec.patch_m, spec.bounces, estimated)


def surroundings_spec(surroundings: Surroundings) -> SurroundingsSpec:
    """The section that declares `surroundings` (`lightcal synth --declare-surroundings`)."""
    surfaces = [
        SurfaceSpec(
            name=s.name,
            corner_m=s.corner_world.tolist(),
            edge_u_m=s.edge_u_world.tolist(),
            edge_v_m=s.edge_v_world.tolist(),
            albedo=s.albedo,
            estimate_albedo=k in surroundings.estimate_albedo,
        )
        for k, s in enumerate(surroundings.surfaces)
    ]
    return SurroundingsSpec(
        surfaces=surfaces,
        wall_albedo=surroundings.wall_albedo,
        patch_m=surroundings.patch_m,
        bounces=surroundings.bounces,
    )
