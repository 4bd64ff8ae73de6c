"""The lights' flat ports (the project's `lights[i].port`) as the exports write them.

A light behind a flat port (docs/model.md, "The light's flat port") was calibrated as
its emitter: the result's pose is the emitter's, in the housing's air behind the port,
and its RID the emitter's in air (a light with a port has a given RID: an estimated one
is refused). The port itself is the project's, so `lightcal export --project P` knows
it (`light_ports_of`, keyed by the light's name):

- `mitsuba`: each ported light's two faces, `disk`s with `dielectric` BSDFs whose
  normals face the emitter (inner face: int_ior n_g, ext_ior n_air; outer face: int_ior
  n_w, ext_ior n_g), in the light's frame (to_world = the emitter's @ the face's), of
  radius `light_face_radius_m` (the spot's cone at the outer face, with a margin, kept
  out of the sensor's field). A path tracer cannot reach a point light behind two delta
  interfaces: the scene's integrator is Mitsuba's particle tracer (`ptracer`), which
  starts at the emitters and connects each diffuse hit to the sensor. `ptracer` has no media and its
  connection to the sensor is a shadow ray that a camera's port would block, so a result
  in water, or a camera behind its own port, is refused (`MITSUBA_WATER_REFUSAL`,
  `MITSUBA_CAMERA_PORT_REFUSAL`). Checked against lightcal's render
  (`tests/test_export_light_port.py`; the same scene by hand in
  `tests/mitsuba_light_port.py`).
- `opencv`: a `port` map in the light's entry (the port's numbers and `LIGHT_PORT_NOTE`).
- `ros`: a comment in the launch file (`LIGHT_PORT_NOTE`).
- `ies`, `ldt`: the RID written is the emitter's in air; the file's origin text says the
  light is behind its port (`origin_suffix`).
- `blender`: refused (`BLENDER_LIGHT_REFUSAL`): its light would shine straight.

Without a light port every file is what it was.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from lightcal.core.camera import Camera
from lightcal.core.camera_frames import mitsuba_from_opencv
from lightcal.core.flat_port import FlatPort
from lightcal.core.light_port import air_sines
from lightcal.io.export_port import face_transform, port_text

__all__ = [
    "BLENDER_LIGHT_REFUSAL",
    "LIGHT_PORT_NOTE",
    "MITSUBA_CAMERA_PORT_REFUSAL",
    "MITSUBA_WATER_REFUSAL",
    "LightPort",
    "light_face_radius_m",
    "light_ports_of",
    "mitsuba_light_port_lines",
    "origin_suffix",
    "ptracer_lines",
    "write_opencv_light_port",
]

LIGHT_PORT_NOTE = (
    "the light shone through a flat port (the project's lights[i].port): its pose is the "
    "emitter's, behind the port in the housing's air, and its RID the emitter's in air; in "
    "the water its beam is refracted at the port's two faces (narrower, brighter on the axis)"
)

BLENDER_LIGHT_REFUSAL = (
    "the Blender export does not carry a light's flat port: its light would shine straight "
    "into the water with the emitter's in-air RID; export --format mitsuba, which carries "
    "the port, or leave out --project for the lights alone"
)

MITSUBA_WATER_REFUSAL = (
    "the Mitsuba export of a light behind a flat port needs the particle tracer (ptracer: "
    "no path tracer reaches a point light through the port's faces), which has no media; "
    "a result in water cannot be rendered with it: leave out --project for the lights "
    "alone, without their ports"
)

MITSUBA_CAMERA_PORT_REFUSAL = (
    "the Mitsuba export of a light behind a flat port needs the particle tracer, whose "
    "connection to the sensor the camera's own port (camera.port) would block: no Mitsuba "
    "integrator renders both ports; leave out --project for the lights alone"
)


@dataclass(frozen=True)
class LightPort:
    """A light's port and the project key that declares it (`lights[i].port`)."""

    key: str
    port: FlatPort


def light_ports_of(lights: Iterable[tuple[str, FlatPort | None]]) -> dict[str, LightPort]:
    """The ported lights of a project, by name, from its lights' (name, port) in order."""
    return {
        name: LightPort(f"lights[{index}].port", port)
        for index, (name, port) in enumerate(lights)
        if port is not None
    }


def light_face_radius_m(
    port: FlatPort,
    cutoff_rad: float,
    T_camera_light: NDArray[np.float64],
    camera: Camera | None,
) -> float:
    """The radius of a light port's round faces, m: 1.5 times the reach of the cone's
    edge (at most 80 degrees) at the outer face plus twice the thickness, cut to 0.9
    times the nearest point where the sensor's image edge rays cross the faces' planes
    (the particle tracer connects the wall to the sensor by shadow rays, which faces in
    the sensor's field would block; a real port is a few centimetres wide)."""
    s = math.sin(min(cutoff_rad, math.radians(80.0))) * port.air_index
    reach = port.distance_m * s / math.sqrt(port.air_index**2 - s * s)
    reach += port.thickness_m * s / math.sqrt(port.glass_index**2 - s * s)
    radius = 1.5 * reach / max(float(port.normal_camera[2]), 0.5) + 2.0 * port.thickness_m
    if camera is None:
        return radius
    w, h = camera.width, camera.height
    edge = np.linspace(0.0, 1.0, 33)[:, None]
    corners = np.array([[-0.5, -0.5], [w - 0.5, -0.5], [w - 0.5, h - 0.5], [-0.5, h - 0.5]])
    pts = np.concatenate([(1 - edge) * corners[i] + edge * corners[(i + 1) % 4] for i in range(4)])
    xy, ok = camera.pixels_to_normalized(pts)
    R, t = T_camera_light[:3, :3], T_camera_light[:3, 3]
    rays = np.column_stack([xy[ok], np.ones(int(np.sum(ok)))]) @ R  # light frame
    origin = -t @ R  # the sensor's centre, light frame
    n = np.asarray(port.normal_camera, dtype=np.float64)
    nearest = math.inf
    for offset in (port.distance_m, port.distance_m + port.thickness_m):
        with np.errstate(divide="ignore", invalid="ignore"):
            along = (offset - origin @ n) / (rays @ n)
        hits = origin + along[:, None] * rays
        radial = np.linalg.norm(hits - np.outer(hits @ n, n), axis=1)
        front = np.isfinite(along) & (along > 0.0)
        if np.any(front):
            nearest = min(nearest, float(np.min(radial[front])))
    return min(radius, 0.9 * nearest)


def mitsuba_light_port_lines(
    ident: str,
    lp: LightPort,
    T_camera_light: NDArray[np.float64],
    cutoff_rad: float,
    camera: Camera | None,
) -> list[str]:
    """A light port's two dielectric faces in the sensor's frame (module docstring);
    `ident` the emitter's id (the faces' ids start with it)."""
    from lightcal.io.escaping import xml_attribute, xml_comment

    port = lp.port
    radius = light_face_radius_m(port, cutoff_rad, T_camera_light, camera)
    offset_out = port.distance_m + port.thickness_m
    rim = float(air_sines(np.array([radius]), np.array([offset_out + 1e-9]), port)[0][0])
    lines = [
        f"    <!-- The light's flat port ({xml_comment(lp.key)}: {port_text(port)}), in front",
        "         of the emitter in its frame: two dielectric disks of radius "
        f"{radius * 1e3:.4g} mm, their",
        "         normals facing the emitter, the water outside; the outer face's rim is",
        f"         {math.degrees(math.asin(rim)):.3g} degrees off the axis in the air (light "
        "beyond it is not refracted). -->",
    ]
    faces = (
        ("port_inner", port.distance_m, port.air_index, port.glass_index),
        ("port_outer", port.distance_m + port.thickness_m, port.glass_index, port.water_index),
    )
    for suffix, offset, ext_ior, int_ior in faces:
        M = mitsuba_from_opencv(T_camera_light @ face_transform(port, offset, radius))
        lines += [
            f'    <shape type="disk" id={xml_attribute(f"{ident}_{suffix}")}>',
            '        <transform name="to_world"><matrix value="'
            + " ".join(repr(float(v)) for v in M.ravel())
            + '"/></transform>',
            '        <bsdf type="dielectric">',
            f'            <float name="int_ior" value="{int_ior!r}"/>',
            f'            <float name="ext_ior" value="{ext_ior!r}"/>',
            "        </bsdf>",
            "    </shape>",
        ]
    return lines


def ptracer_lines() -> list[str]:
    """The particle tracer of a scene with light ports (module docstring)."""
    return [
        "    <!-- A light behind a flat port: Mitsuba's particle tracer (paths start at the",
        "         emitters, refract through the ports and connect each diffuse hit to the",
        "         sensor). sample_count is its particles per pixel: a pixel's relative noise",
        "         is about 1 / sqrt(sample_count (its solid angle) / (the spot's cone's)),",
        "         raise it (2^14 and more) and keep samples_per_pass small (memory). -->",
        '    <default name="max_depth" value="-1"/>',
        '    <default name="samples_per_pass" value="1"/>',
        '    <integrator type="ptracer">',
        '        <integer name="max_depth" value="$max_depth"/>',
        '        <integer name="samples_per_pass" value="$samples_per_pass"/>',
        '        <boolean name="hide_emitters" value="true"/>',
        "    </integrator>",
    ]


def origin_suffix(lp: LightPort) -> str:
    """What a photometric file's origin text adds for a light behind a port: short, an
    EULUMDAT report line holds 78 characters."""
    return f"; in air, behind {lp.key}"


def write_opencv_light_port(fs: Any, lp: LightPort) -> None:
    """The `port` map of a light's entry in the opencv file."""
    import cv2

    port = lp.port
    fs.startWriteStruct("port", cv2.FileNode_MAP)
    fs.write("note", LIGHT_PORT_NOTE)
    fs.write("key", lp.key)
    fs.write("distance_m", port.distance_m)
    fs.write("thickness_m", port.thickness_m)
    fs.write("glass_index", port.glass_index)
    fs.write("water_index", port.water_index)
    fs.write("air_index", port.air_index)
    fs.write("normal_light", np.asarray(port.normal_camera, dtype=np.float64).reshape(3, 1))
    fs.endWriteStruct()
