"""The ROS export: each light as a static transform from the camera's optical frame.

`lightcal export --format ros --out lights.launch.xml` writes a ROS 2 launch file (one
`tf2_ros static_transform_publisher` node per light, the equivalent ROS 2 and ROS 1
command lines in its comment) and, beside it, `lights.urdf`: a URDF fragment with a fixed
joint per light, to paste into the robot's description.

Frames: lightcal's camera frame (x right, y down, z forward) is REP-103's camera
*optical* frame, `camera_optical_frame` here (rename it to the robot's, e.g.
`<camera>_optical_frame`); it relates to the camera's body frame (x forward, y left,
z up) by the fixed rotation rpy = (-pi/2, 0, -pi/2). Each light's child frame is named
after the light (letters, digits and `_` kept, anything else `_`), +z its axis.

The transform published is `T_camera_light`: the light's pose in the optical frame,
mapping light-frame coordinates to the camera's (ROS: parent `camera_optical_frame`,
child the light). Quaternions are in ROS's order **x y z w** (scalar last, as SciPy's
`Rotation.as_quat`); lightcal's result files write them scalar first (`quaternion_wxyz`).
URDF's `rpy` are fixed-axis roll, pitch, yaw: R = Rz(yaw) Ry(pitch) Rx(roll).

A result calibrated in water says so in the launch file's comment (c, beta, g and their
sigmas, `lightcal.io.export_medium`): tf has no place for a medium. Exported with a
project whose camera looked through a flat port (`camera.port`), the comment says so too
(`lightcal.io.export_port.PORT_NOTE`): the optical frame is the camera's in its housing,
its intrinsics (in the camera's own calibration) the housing's in air behind the port.
A light behind a flat port of its own (`lights[i].port`) gets a note too
(`lightcal.io.export_light_port.LIGHT_PORT_NOTE`): its transform is the emitter's.
In air, without a port, the files are what they were.
"""

from __future__ import annotations

import math
import re
import textwrap
from collections.abc import Mapping
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from lightcal.core.flat_port import FlatPort
from lightcal.core.rotations import quaternion_wxyz_from_matrix
from lightcal.io.escaping import xml_comment
from lightcal.io.export_light_port import LIGHT_PORT_NOTE, LightPort
from lightcal.io.export_lights import light_transform
from lightcal.io.export_medium import export_medium
from lightcal.io.export_port import PORT_NOTE, port_text
from lightcal.io.result_file import ResultFile

__all__ = ["PARENT_FRAME", "frame_name", "quaternion_xyzw", "ros_files", "rpy_from_matrix"]

PARENT_FRAME = "camera_optical_frame"


def frame_name(name: str) -> str:
    """A ROS frame (and URDF link) name for a light: [A-Za-z0-9_], not starting with a digit."""
    safe = re.sub(r"[^A-Za-z0-9_]", "_", name)[:100] or "light"
    return f"light_{safe}" if safe[0].isdigit() else safe


def quaternion_xyzw(R: NDArray[np.float64]) -> NDArray[np.float64]:
    """(4,) ROS's quaternion (x, y, z, w) of a rotation matrix, w >= 0."""
    w, x, y, z = quaternion_wxyz_from_matrix(R)
    return np.array([x, y, z, w])


def rpy_from_matrix(R: NDArray[np.float64]) -> tuple[float, float, float]:
    """URDF's (roll, pitch, yaw), radians, with R = Rz(yaw) Ry(pitch) Rx(roll)."""
    pitch = math.atan2(-float(R[2, 0]), math.hypot(float(R[0, 0]), float(R[1, 0])))
    if math.hypot(float(R[0, 0]), float(R[1, 0])) < 1e-12:  # gimbal lock: yaw = 0
        return math.atan2(-float(R[1, 2]), float(R[1, 1])), pitch, 0.0
    return (
        math.atan2(float(R[2, 1]), float(R[2, 2])),
        pitch,
        math.atan2(float(R[1, 0]), float(R[0, 0])),
    )


def _numbers(values: object) -> str:
    return " ".join(repr(float(v)) for v in values)  # type: ignore[attr-defined]


def _frames(result: ResultFile) -> list[str]:
    """Each light's frame name, made unique with a suffix where names collide."""
    names: list[str] = []
    for light in result.lights:
        name = frame_name(light.name)
        while name in names or name == PARENT_FRAME:
            name += "_"
        names.append(name)
    return names


def _medium_lines(result: ResultFile, source: str | Path) -> list[str]:
    """The comment's note of a result in water (none in air)."""
    medium = export_medium(result, source)
    if medium is None:
        return []
    text = (
        f"The calibration was made in a medium: {medium.text()} (attenuation c and "
        "backscatter beta = sigma_s pi / rho in 1/m, rho the wall's albedo; phase_g the "
        "Henyey-Greenstein g). The transforms do not depend on it; tf has no place for it."
    )
    return [f"     {line}" for line in textwrap.wrap(xml_comment(text, max_chars=4000), 84)]


def _port_lines(port: FlatPort | None) -> list[str]:
    """The comment's note of a camera behind a flat port (none without)."""
    if port is None:
        return []
    text = f"Camera port ({port_text(port)}): {PORT_NOTE}."
    return [f"     {line}" for line in textwrap.wrap(xml_comment(text, max_chars=4000), 84)]


def _light_port_lines(child: str, lp: LightPort) -> list[str]:
    """The comment's note of a light behind a flat port."""
    text = f"Light {child} port ({lp.key}: {port_text(lp.port)}): {LIGHT_PORT_NOTE}."
    return [f"     {line}" for line in textwrap.wrap(xml_comment(text, max_chars=4000), 84)]


def _launch(
    result: ResultFile,
    source: str | Path,
    port: FlatPort | None = None,
    light_ports: Mapping[str, LightPort] | None = None,
) -> str:
    lines = [
        '<?xml version="1.0" encoding="utf-8"?>',
        f"<!-- lightcal {xml_comment(result.lightcal_version)}: the calibrated lights as static",
        f"     transforms from {PARENT_FRAME}, REP-103's camera optical frame (x right, y down,",
        "     z forward: lightcal's camera frame; rename it to your camera's). Each transform",
        "     is T_camera_light: the light's pose in that frame (parent: the camera, child:",
        "     the light, +z its axis). Quaternions in ROS's order x y z w (scalar last).",
        "     From a shell, ROS 2: ros2 run tf2_ros static_transform_publisher ARGS, with a",
        "     node's args below; ROS 1 (x y z qx qy qz qw parent child):",
    ]
    nodes = []
    for light, child in zip(result.lights, _frames(result), strict=True):
        T = light_transform(light)
        xyz, q = T[:3, 3], quaternion_xyzw(T[:3, :3])
        ros2 = " ".join(
            f"--{key} {float(v)!r}" for key, v in zip(("x", "y", "z"), xyz, strict=True)
        )
        ros2 += " " + " ".join(
            f"--{key} {float(v)!r}" for key, v in zip(("qx", "qy", "qz", "qw"), q, strict=True)
        )
        lines += [
            f"     rosrun tf2_ros static_transform_publisher {_numbers(xyz)}",
            f"         {_numbers(q)} {PARENT_FRAME} {child}",
        ]
        nodes.append(
            f'    <node pkg="tf2_ros" exec="static_transform_publisher"'
            f' name="lightcal_{child}"\n'
            f'          args="{ros2} --frame-id {PARENT_FRAME} --child-frame-id {child}"/>'
        )
    lines += _medium_lines(result, source)
    lines += _port_lines(port)
    for light, child in zip(result.lights, _frames(result), strict=True):
        if light_ports and light.name in light_ports:
            lines += _light_port_lines(child, light_ports[light.name])
    lines[-1] += " -->"
    lines += [
        "<launch>",
        *nodes,
        "</launch>",
    ]
    return "\n".join(lines) + "\n"


def _urdf(result: ResultFile) -> str:
    lines = [
        '<?xml version="1.0" encoding="utf-8"?>',
        "<!-- lightcal: a fixed joint per calibrated light, from REP-103's camera optical",
        f"     frame ({PARENT_FRAME}: x right, y down, z forward) to the light (+z its axis).",
        "     origin xyz in metres; rpy fixed-axis roll, pitch, yaw in radians",
        "     (R = Rz(yaw) Ry(pitch) Rx(roll)). Paste the links and joints into your robot's",
        "     description, the parent renamed to your camera's optical frame. -->",
        '<robot name="lightcal_lights">',
        f'    <link name="{PARENT_FRAME}"/>',
    ]
    for light, child in zip(result.lights, _frames(result), strict=True):
        T = light_transform(light)
        rpy = _numbers(rpy_from_matrix(T[:3, :3]))
        lines += [
            f'    <link name="{child}"/>',
            f'    <joint name="{PARENT_FRAME}_to_{child}" type="fixed">',
            f'        <parent link="{PARENT_FRAME}"/>',
            f'        <child link="{child}"/>',
            f'        <origin xyz="{_numbers(T[:3, 3])}" rpy="{rpy}"/>',
            "    </joint>",
        ]
    lines.append("</robot>")
    return "\n".join(lines) + "\n"


def urdf_path(out: Path) -> Path:
    """The URDF beside the launch file: `lights.launch.xml` -> `lights.urdf`."""
    stem = out.name[: -len(".launch.xml")] if out.name.endswith(".launch.xml") else out.stem
    return out.with_name(stem + ".urdf")


def ros_files(
    result: ResultFile,
    out: Path,
    source: str | Path = "",
    port: FlatPort | None = None,
    light_ports: Mapping[str, LightPort] | None = None,
) -> dict[Path, bytes]:
    """The launch file (`out`) and the URDF fragment beside it (`urdf_path`); a result in
    water, a camera behind a flat `port` (the project's) or lights behind theirs
    (`light_ports`, by name) say so in the launch file's comment (`source`: the result's
    path, for errors)."""
    return {
        out: _launch(result, source, port, light_ports).encode("utf-8"),
        urdf_path(out): _urdf(result).encode("utf-8"),
    }
