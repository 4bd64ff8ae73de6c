"""The project file's `camera.port` and `lights[i].port`: flat ports under water.

    camera:
      fx: ...
      port:
        distance_mm: 20        # centre of projection -> the port's inner face
        thickness_mm: 10       # the window's thickness
        glass_index: 1.49      # acrylic (glass 1.52)
        water_index: 1.333     # fresh water (sea water 1.34)

Without it the camera's rays are straight from its centre (in air, or underwater with
intrinsics that absorb the port). With it the footprints are built through the port
(docs/model.md, "The camera's flat port"; `lightcal.core.port_footprints`); the
intrinsics are then those of the camera in its housing, in air. `build_port` turns the
section into the core's `FlatPort` and refuses what is not modelled behind a port,
naming the key.

A light's port, `lights[i].port` (the same keys; `distance_mm` from the emitter to the
window's inner face along the light's axis), is the light's housing window
(docs/model.md, "The light's flat port"; `lightcal.core.light_port`): `build_light_port`.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from pydantic import BaseModel, ConfigDict, Field

from lightcal.core.flat_port import FlatPort
from lightcal.errors import InputError

__all__ = ["PortSpec", "build_light_port", "build_port", "port_section"]


class PortSpec(BaseModel):
    """A flat port (docs/model.md, "The camera's flat port", "The light's flat port"): a
    window of thickness `thickness_mm` and index `glass_index` whose inner face lies
    `distance_mm` in front of the centre of projection (the emitter, for a light's), its
    normal along the optical axis (the light's axis), water of index `water_index`
    outside."""

    model_config = ConfigDict(extra="forbid", allow_inf_nan=False, frozen=True)

    distance_mm: float = Field(
        gt=0.0, le=1000.0, description="centre of projection to the port's inner face, mm"
    )
    thickness_mm: float = Field(ge=0.0, le=200.0, description="the window's thickness, mm")
    glass_index: float = Field(
        default=1.49, ge=1.0, le=3.0, description="the window's refractive index"
    )
    water_index: float = Field(
        default=1.333, ge=1.0, le=2.0, description="the water's refractive index"
    )


def build_port(spec: Any, source: Path) -> FlatPort | None:
    """The project's camera port (`spec`: the `ProjectFile`), or None; InputError naming
    `camera.port` when it is combined with what is not modelled behind a port: a wall
    mesh, the `paper` sensor model, the wall's albedo map, the
    surroundings' bounce light, the automatic initial guess (the beam's rays are traced
    straight)."""
    port_spec: PortSpec | None = spec.camera.port
    if port_spec is None:
        return None
    refusals = []
    if spec.wall.mesh is not None:
        refusals.append("wall.mesh (footprints through a port are on the plane z = 0 only)")
    if spec.sensor.model == "paper":
        refusals.append("sensor.model: paper (its d and theta_v assume straight rays)")
    if spec.wall.albedo_map is not None:
        refusals.append("wall.albedo_map (its image is traced along straight rays)")
    if spec.surroundings is not None:
        refusals.append("surroundings (their bounce light is traced from the camera centre)")
    if any(ls.initial == "auto" for ls in spec.lights):
        refusals.append("lights[].initial: auto (the beam is sighted along straight rays)")
    return _flat_port(port_spec, "camera.port", refusals, source)


def build_light_port(spec: Any, index: int, source: Path) -> FlatPort | None:
    """Light `index`'s port (`spec`: the `ProjectFile`), or None; InputError naming
    `lights[index].port` when it is combined with what is not modelled behind a light's
    port: a wall mesh, a wall model other than Lambertian (its B would need the water
    direction at the wall), the surroundings' bounce light, an estimated RID (its
    columns take the straight direction) and the automatic initial guess (the beam is
    sighted along straight rays). The medium's backscatter is modelled behind the port
    (`lightcal.core.light_port_veil`)."""
    light = spec.lights[index]
    port_spec: PortSpec | None = light.port
    field = f"lights[{index}]"
    key = f"{field}.port"
    if port_spec is None:
        return None
    refusals = []
    if spec.wall.mesh is not None:
        refusals.append("wall.mesh (the flux through the port is on the plane z = 0 only)")
    if spec.wall.model != "lambertian":
        refusals.append(
            f"wall.model: {spec.wall.model} (a non-Lambertian wall's reflectance needs the "
            "water direction at the wall)"
        )
    if spec.surroundings is not None:
        refusals.append("surroundings (their bounce light is traced straight from the light)")
    if light.estimate_rid != "none":
        refusals.append(
            f"{field}.estimate_rid: {light.estimate_rid} (its columns take the straight "
            "direction, not the air's)"
        )
    if light.initial == "auto":
        refusals.append(f"{field}.initial: auto (the beam is sighted along straight rays)")
    return _flat_port(port_spec, key, refusals, source)


def _flat_port(port_spec: PortSpec, key: str, refusals: list[str], source: Path) -> FlatPort:
    """The core's `FlatPort` of a port's section (mm to m), or InputError naming `key`:
    what is not modelled beside it (`refusals`), or a value the core refuses."""
    if refusals:
        raise InputError(source, f"{key}: not modelled together with {'; '.join(refusals)}")
    try:
        return FlatPort(
            port_spec.distance_mm / 1000.0,
            port_spec.thickness_mm / 1000.0,
            port_spec.glass_index,
            port_spec.water_index,
        )
    except ValueError as exc:
        raise InputError(source, f"{key}: {exc}") from exc


def port_section(port: FlatPort) -> PortSpec:
    """The project file's section of a `FlatPort` (m to mm): what a result records."""
    return PortSpec(
        distance_mm=port.distance_m * 1000.0,
        thickness_mm=port.thickness_m * 1000.0,
        glass_index=port.glass_index,
        water_index=port.water_index,
    )
