"""A light's beam in the 3D view, below the light's node on a camera (light frame):
its cones at the RID's half-intensity (bold) and cut-off (thin) angles, straight in air
(`cone_lines`) or refracted into the water by the light's flat port
(`ported_beam_rings`), then the port itself (`lightcal_app.port_scene`); on the gizmo a
translucent half-intensity cone and, behind a port, a label with the water's angles
(n_air sin(theta_air) = n_w sin(theta_w), `water_angle_rad`).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from lightcal.core.flat_port import FlatPort
from lightcal.pipeline.port_text import water_angle_rad
from lightcal_app.beam_shapes import cone_lines, cone_mesh, ported_beam_rings, ring_lines, ring_mesh
from lightcal_app.port_scene import draw_port_slab, light_port_faces


def beam_label(half_air_rad: float, cut_air_rad: float, port: FlatPort) -> str:
    """ "beam in water: 22.0° half, 44.8° cut-off (in air 30.0°, 70.2°; flat port)"."""
    w_half, w_cut = (math.degrees(water_angle_rad(a, port)) for a in (half_air_rad, cut_air_rad))
    return (
        f"beam in water: {w_half:.1f}° half, {w_cut:.1f}° cut-off (in air "
        f"{math.degrees(half_air_rad):.1f}°, {math.degrees(cut_air_rad):.1f}°; flat port)"
    )


def draw_beam(
    scene: Any,
    base: str,
    angles_air_rad: tuple[float, float],
    length_m: float,
    port: FlatPort | None,
    *,
    rgb: tuple[int, int, int],
) -> list[Any]:
    """The cone outlines `base`/cone_half and `base`/cone_cut (air angles, refracted
    behind a port) and the port's slab; returns the port's nodes (none without one)."""
    widths = {"cone_half": 2.0, "cone_cut": 1.0}
    for (name, width), angle in zip(widths.items(), angles_air_rad, strict=True):
        lines = (
            cone_lines(angle, length_m)
            if port is None
            else ring_lines(ported_beam_rings(angle, length_m, port))
        )
        scene.add_line_segments(
            f"{base}/{name}",
            lines.astype(np.float32),
            rgb,
            thickness=width,
            thickness_units="screen",
        )
    if port is None:
        return []
    return draw_port_slab(scene, base, *light_port_faces(port, angles_air_rad[1]))


def draw_beam_fill(
    scene: Any,
    base: str,
    angles_air_rad: tuple[float, float],
    length_m: float,
    port: FlatPort | None,
    *,
    rgb: tuple[int, int, int],
) -> list[Any]:
    """The translucent half-intensity cone `base`/cone_fill and, behind a port, the
    label `base`/beam_label at the cone's end; returns the label (none without one)."""
    half = angles_air_rad[0]
    v, f = (
        cone_mesh(half, length_m)
        if port is None
        else ring_mesh(ported_beam_rings(half, length_m, port, n=40))
    )
    scene.add_mesh_simple(
        f"{base}/cone_fill",
        v.astype(np.float32),
        f.astype(np.uint32),
        color=rgb,
        opacity=0.25,
        side="double",
        cast_shadow=False,
        receive_shadow=False,
    )
    if port is None:
        return []
    text = beam_label(*angles_air_rad, port)
    return [scene.add_label(f"{base}/beam_label", text, position=(0.0, 0.0, length_m))]
