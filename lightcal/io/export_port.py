"""The camera's flat port (the project's `camera.port`) as the exports write it.

A calibration behind a flat port (docs/model.md, "The camera's flat port") used the
intrinsics of the camera in its housing, in air, and traced each pixel's ray through the
port's two faces into the water. The result holds the lights' poses in that camera's
frame (its centre of projection in the housing's air); the port itself is the
project's, so `lightcal export --project P` knows it:

- `mitsuba`: the port's two faces, `rectangle`s with `dielectric` BSDFs whose normals
  face the sensor (inner face: int_ior n_g, ext_ior n_air; outer face: int_ior n_w,
  ext_ior n_g), in the sensor's frame as the emitters are, each a square of half side
  `face_half_side_m` (the field of view at the outer face, with a margin). In water the
  outer face's interior is the exported medium (the sensor then sits in the housing's
  air, the emitters in the water); in air the water is only the index. Checked against
  lightcal's render through the port (`tests/test_export_port.py`; the same scene built
  by hand in `tests/mitsuba_port.py`).
- `opencv`: a `camera_port` map (the port's numbers and `PORT_NOTE`).
- `ros`: a comment in the launch file (`PORT_NOTE`).
- `blender`: refused (`BLENDER_REFUSAL`): its camera would see through straight rays.

Without a port every file is what it was.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numpy.typing import NDArray

from lightcal.core.camera import Camera
from lightcal.core.camera_frames import mitsuba_from_opencv
from lightcal.core.flat_port import FlatPort

__all__ = [
    "BLENDER_REFUSAL",
    "PORT_NOTE",
    "face_half_side_m",
    "face_transform",
    "mitsuba_port_lines",
    "port_text",
    "write_opencv_port",
]

PORT_NOTE = (
    "the camera looked through a flat port (the project's camera.port): the poses are in "
    "the frame of the camera in its housing, its centre of projection in the housing's air, "
    "and the intrinsics the calibration used are the housing's in air, behind the port, "
    "not those of a pinhole calibrated through the port in water (whose focal lengths are "
    "about water_index times larger); each pixel's ray is refracted at the port's two faces"
)

BLENDER_REFUSAL = (
    "the Blender export does not carry the camera's flat port: its camera would see "
    "through straight rays with the housing's in-air intrinsics; export --format mitsuba, "
    "which carries the port, or leave out --project for the lights alone"
)


def port_text(port: FlatPort) -> str:
    """One line: the port's numbers, millimetres and indices."""
    return (
        f"distance_mm {port.distance_m * 1e3:.6g}, thickness_mm {port.thickness_m * 1e3:.6g}, "
        f"glass_index {port.glass_index:.6g}, water_index {port.water_index:.6g}, "
        f"tilt_deg {port.tilt_deg:.3g}"
    )


def face_half_side_m(port: FlatPort, camera: Camera | None) -> float:
    """Half the side of the port's square faces, m: 1.5 times the reach of the image's
    corner and edge rays at the outer face plus twice the thickness (the inner
    reflections' shift); without a camera a 127 degree field."""
    reach = 2.0
    if camera is not None:
        w, h = camera.width, camera.height
        edge = np.array(
            [[-0.5, -0.5], [w / 2, -0.5], [w - 0.5, -0.5], [w - 0.5, h / 2],
             [w - 0.5, h - 0.5], [w / 2, h - 0.5], [-0.5, h - 0.5], [-0.5, h / 2]]
        )  # fmt: skip
        xy, ok = camera.pixels_to_normalized(edge)
        if np.all(ok):
            reach = float(np.max(np.abs(xy)))
    depth = (port.distance_m + port.thickness_m) / max(float(port.normal_camera[2]), 0.5)
    return 1.5 * reach * depth + 2.0 * port.thickness_m


def face_transform(port: FlatPort, offset_m: float, half_side_m: float) -> NDArray[np.float64]:
    """(4, 4) a `rectangle`'s to_world in the OpenCV camera frame: the plane
    n . X = offset_m, its normal -n (facing the camera), the square's half side."""
    n = port.normal_camera
    z = -n
    x = np.cross([0.0, 1.0, 0.0], z)
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    M = np.eye(4)
    M[:3, 0], M[:3, 1], M[:3, 2] = half_side_m * x, half_side_m * y, z
    M[:3, 3] = offset_m * n
    return M


def mitsuba_port_lines(
    port: FlatPort, camera: Camera | None, medium_ident: str | None
) -> list[str]:
    """The port's two dielectric faces in the sensor's frame (module docstring);
    `medium_ident` the outer face's interior, or None in air."""
    from lightcal.io.escaping import xml_attribute

    half = face_half_side_m(port, camera)
    lines = [
        "    <!-- The camera's flat port (the project's camera.port: " + port_text(port) + ").",
        "         Two dielectric faces, their normals facing the sensor, in the sensor's frame",
        "         as the emitters are: in a scene whose sensor has to_world S, use S @ M.",
        "         The radiance the sensor records carries (n_air / n_w)^2 (Mitsuba's",
        "         dielectric scales what it refracts by eta^2), which lightcal leaves to the",
        "         light's scale: divide by it to compare with lightcal's values. The",
        "         intrinsics are the housing's in air, behind the port. -->",
    ]
    faces = (
        ("lightcal_port_inner", port.distance_m, port.air_index, port.glass_index),
        (
            "lightcal_port_outer",
            port.distance_m + port.thickness_m,
            port.glass_index,
            port.water_index,
        ),
    )
    for ident, offset, ext_ior, int_ior in faces:
        M = mitsuba_from_opencv(face_transform(port, offset, half))
        lines += [
            f'    <shape type="rectangle" id={xml_attribute(ident)}>',
            '        <transform name="to_world"><matrix value="'
            + " ".join(repr(float(v)) for v in M.ravel())
            + '"/></transform>',
            '        <bsdf type="dielectric">',
            f'            <float name="int_ior" value="{int_ior!r}"/>',
            f'            <float name="ext_ior" value="{ext_ior!r}"/>',
            "        </bsdf>",
        ]
        if medium_ident is not None and ident == "lightcal_port_outer":
            lines.append(f'        <ref name="interior" id={xml_attribute(medium_ident)}/>')
        lines.append("    </shape>")
    return lines


def write_opencv_port(fs: Any, port: FlatPort) -> None:
    """The `camera_port` map of the opencv file (after `lights`)."""
    import cv2

    fs.startWriteStruct("camera_port", cv2.FileNode_MAP)
    fs.write("note", PORT_NOTE)
    fs.write("distance_m", port.distance_m)
    fs.write("thickness_m", port.thickness_m)
    fs.write("glass_index", port.glass_index)
    fs.write("water_index", port.water_index)
    fs.write("air_index", port.air_index)
    fs.write("normal_camera", np.asarray(port.normal_camera, dtype=np.float64).reshape(3, 1))
    fs.write("tilt_deg", port.tilt_deg if math.isfinite(port.tilt_deg) else math.nan)
    fs.endWriteStruct()
