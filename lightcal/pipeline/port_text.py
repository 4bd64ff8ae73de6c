"""The flat ports in words: the camera's (`camera.port`) and each light's
(`lights[i].port`), and the angles a light's beam keeps in the water behind its port.

What the page's Light tab says of a project's ports (and what the CLI can print): one
sentence a port, "camera behind a flat port: 20 mm to the glass, 10 mm acrylic (n 1.49)
into water (n 1.333)". A light's sentence adds its beam in the water: the port's faces
are parallel, so a ray's angle to the port's normal obeys n_air sin(theta_air) = n_w
sin(theta_w) whatever the glass (docs/model.md, "The camera's flat port", "The light's
flat port"), and the RID's half-intensity and cut-off angles, given in air, narrow to
`water_angle_rad` of them.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

from lightcal.core.flat_port import FlatPort
from lightcal.core.rid import RID
from lightcal.core.scene import Light

__all__ = [
    "CUT_OFF_LEVEL",
    "beam_angles_rad",
    "light_port_sentence",
    "port_lines",
    "port_sentence",
    "water_angle_rad",
]

CUT_OFF_LEVEL = 0.01
"""The RID's level at its cut-off angle (the cone the page draws thin)."""


def water_angle_rad(theta_air_rad: float, port: FlatPort) -> float:
    """The angle to the port's normal, in the water, of a ray that leaves its owner at
    `theta_air_rad` to that normal in the air: asin(n_air sin(theta_air) / n_w).

    An angle of 90 degrees or more never reaches the port; it is taken as 90 degrees
    (the grazing ray), whose water angle, asin(n_air / n_w), bounds every ray's.
    """
    if not math.isfinite(theta_air_rad) or theta_air_rad < 0.0:
        raise ValueError(f"theta_air_rad: expected a finite angle >= 0, got {theta_air_rad}")
    s = port.air_index * math.sin(min(theta_air_rad, 0.5 * math.pi)) / port.water_index
    return math.asin(min(1.0, s))


def beam_angles_rad(rid: RID, port: FlatPort | None) -> tuple[float, float]:
    """(half-intensity angle, cut-off angle) of a light's beam where it meets the wall,
    radians: the RID's own (levels 0.5 and `CUT_OFF_LEVEL`, in air) without a port, the
    water's behind one (`water_angle_rad`)."""
    half = rid.angle_at_level_rad(0.5)
    cut = rid.angle_at_level_rad(CUT_OFF_LEVEL)
    if port is None:
        return half, cut
    return water_angle_rad(half, port), water_angle_rad(cut, port)


def window_name(glass_index: float) -> str:
    """What a window of this index most likely is: acrylic (1.49), glass (1.45-1.56)
    or, otherwise, a window."""
    if abs(glass_index - 1.49) <= 0.005:
        return "acrylic"
    if 1.45 <= glass_index <= 1.56:
        return "glass"
    return "window"


def port_sentence(port: FlatPort, owner: str = "camera") -> str:
    """ "camera behind a flat port: 20 mm to the glass, 10 mm acrylic (n 1.49) into water
    (n 1.333)"; a tilted port says its tilt."""
    glass = f"{port.thickness_m * 1e3:.3g} mm {window_name(port.glass_index)}"
    if port.thickness_m == 0.0:
        glass = "a window of thickness 0"
    else:
        glass += f" (n {port.glass_index:.3g})"
    text = (
        f"{owner} behind a flat port: {port.distance_m * 1e3:.3g} mm to the glass, {glass} "
        f"into water (n {port.water_index:.4g})"
    )
    if port.tilt_deg > 0.0:
        text += f", tilted {port.tilt_deg:.3g}° from the axis"
    return text


def light_port_sentence(name: str, port: FlatPort, rid: RID) -> str:
    """`port_sentence` of a light's port and its beam in the water: "led behind a flat
    port: ...; its beam in the water: half intensity at 22.0°, cut-off at 44.8° (in air
    30.0° and 70.2°)"."""
    half_air, cut_air = beam_angles_rad(rid, None)
    half, cut = beam_angles_rad(rid, port)
    return (
        f"{port_sentence(port, name)}; its beam in the water: half intensity at "
        f"{math.degrees(half):.1f}°, cut-off at {math.degrees(cut):.1f}° (in air "
        f"{math.degrees(half_air):.1f}° and {math.degrees(cut_air):.1f}°)"
    )


def port_lines(camera_port: FlatPort | None, lights: Sequence[Light]) -> list[str]:
    """The ports of a project in words, one line each: the camera's (`port_sentence`),
    then each ported light's (`light_port_sentence`); empty without a port (what
    `lightcal calibrate` prints before it solves)."""
    lines = [] if camera_port is None else [port_sentence(camera_port, "camera")]
    return lines + [
        light_port_sentence(light.name, light.port, light.rid)
        for light in lights
        if light.port is not None
    ]
