"""The OpenCV export: a FileStorage YAML (or XML/JSON) of each light's pose, sigmas and RID.

Per light, beside the 4x4 `T_camera_light`, the pose as OpenCV's pose functions give one
(`cv2.solvePnP`, `cv2.Rodrigues`): `rvec` (3x1, a rotation vector) and `tvec` (3x1,
metres) with X_camera = R(rvec) X_light + tvec, the light frame -> camera frame (what
solvePnP returns for an object's model frame); `tvec` is the emitter's position in the
camera frame. `pose_covariance` (6x6) is their covariance in the order (rvec_x, rvec_y,
rvec_z, tvec_x, tvec_y, tvec_z), OpenCV's order of the pose in `cv2.projectPoints`'
Jacobian: the result's parameter covariance (`parameters.covariance`) of the light's
position and its solver angles, mapped through the Jacobian of (rvec, tvec) at the
solution (`pose_covariance`). A rotationally symmetric light's spin about its axis is
not determined: its rotation covariance has rank 2 (zero along the axis); an isotropic
light's rotation rows and columns are NaN.

A result calibrated in water adds, after `lights`, a `medium` map: `attenuation_per_m`,
`backscatter_per_m`, `phase_g`, each's `sigma_<name>` (NaN where given) and the
`estimated` names (`MEDIUM_NOTE`). A result in air writes none: the file is what it was.

The file holds no intrinsics. Exported with a project whose camera looked through a flat
port (`camera.port`), it adds a `camera_port` map (`lightcal.io.export_port`): the
port's numbers and a note that the camera frame is the housing's, its intrinsics those
in air behind the port. Each light behind a flat port of its own (`lights[i].port`)
gets a `port` map in its entry (`lightcal.io.export_light_port`): the port's numbers and
a note that the pose is the emitter's, behind the port, and the RID the emitter's in air.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from lightcal.core.flat_port import FlatPort
from lightcal.core.light_axis import axis_from_angles, rotation_from_axis
from lightcal.core.rotations import matrix_from_rotvec, rotvec_from_matrix
from lightcal.io.escaping import plain_line
from lightcal.io.export_light_port import LightPort, write_opencv_light_port
from lightcal.io.export_lights import FRAME_NOTE, light_rid, light_transform
from lightcal.io.export_medium import NAMES as MEDIUM_NAMES
from lightcal.io.export_medium import ExportMedium, export_medium
from lightcal.io.export_port import write_opencv_port
from lightcal.io.result_file import LightResultModel, ResultFile

__all__ = ["opencv_text", "opencv_yaml", "pose_covariance", "rvec_tvec"]

POSITION_NAMES = ("x_m", "y_m", "z_m")
ROTATION_NAMES = {"symmetric": ("a_rad", "b_rad"), "general": ("dx_rad", "dy_rad", "dz_rad")}
"""The solver's rotation parameters of each pose kind (`lightcal.core.pose`)."""

_STEP = 1e-6
"""Central-difference step of the rotation parameters, radians."""

RVEC_NOTE = (
    "rvec, tvec: light -> camera as cv2.solvePnP gives a model's pose: "
    "X_camera = R(rvec) X_light + tvec (metres); pose_covariance: 6x6 of "
    "(rvec_x, rvec_y, rvec_z, tvec_x, tvec_y, tvec_z)"
)


def rvec_tvec(light: LightResultModel) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """(3,) rotation vector and (3,) translation of `T_camera_light` (light -> camera)."""
    T = light_transform(light)
    return rotvec_from_matrix(T[:3, :3]), T[:3, 3].copy()


def _chart(kind: str, p: NDArray[np.float64]) -> NDArray[np.float64]:
    if kind == "symmetric":
        return rotation_from_axis(axis_from_angles(float(p[0]), float(p[1])))
    return matrix_from_rotvec(p)


def pose_covariance(result: ResultFile, light: LightResultModel) -> NDArray[np.float64]:
    """(6, 6) covariance of (rvec, tvec) of `light` (module docstring); NaN where the
    result's covariance does not say (undetermined, or an isotropic light's rotation)."""
    names = result.parameters.names
    prefix = f"{light.name}."
    kind = light.pose_kind if light.pose_kind in ROTATION_NAMES else "isotropic"
    wanted = [prefix + n for n in (*POSITION_NAMES, *ROTATION_NAMES.get(kind, ()))]
    out = np.full((6, 6), math.nan)
    if not all(n in names for n in wanted):
        return out
    index = [names.index(n) for n in wanted]
    full = np.array(
        [[math.nan if v is None else v for v in row] for row in result.parameters.covariance],
        dtype=np.float64,
    )
    C = full[np.ix_(index, index)]
    J = np.zeros((6, len(index)))
    J[3:, :3] = np.eye(3)
    if kind != "isotropic":
        p0 = np.array(result.parameters.x, dtype=np.float64)[index[3:]]
        R = np.array(light.R_camera_light, dtype=np.float64)
        # R(p) = chart(p) chart(p0)^T R: the chart's change about the written rotation
        base = _chart(kind, p0).T @ R
        for k in range(p0.size):
            step = np.zeros_like(p0)
            step[k] = _STEP
            plus = rotvec_from_matrix(_chart(kind, p0 + step) @ base)
            minus = rotvec_from_matrix(_chart(kind, p0 - step) @ base)
            J[:3, 3 + k] = (plus - minus) / (2.0 * _STEP)
        out = J @ C @ J.T
    else:
        out[3:, 3:] = C
    return out


def opencv_yaml(
    result: ResultFile,
    source: str | Path,
    port: FlatPort | None = None,
    light_ports: Mapping[str, LightPort] | None = None,
) -> bytes:
    """The FileStorage YAML of every light (`lightcal.io.export`'s `opencv` format);
    `port`, the project's camera port, adds its `camera_port` map, `light_ports` (by the
    lights' names) a `port` map to each ported light's entry."""
    import cv2

    fs = cv2.FileStorage(
        "export.yaml",
        cv2.FILE_STORAGE_WRITE | cv2.FILE_STORAGE_MEMORY | cv2.FILE_STORAGE_FORMAT_YAML,
    )
    fs.write("lightcal_version", opencv_text(result.lightcal_version))
    fs.write("frame", FRAME_NOTE)
    fs.write("pose_note", RVEC_NOTE)
    fs.write("lights_count", len(result.lights))
    fs.startWriteStruct("lights", cv2.FileNode_SEQ)
    for light in result.lights:
        sigma = light.sigma  # every sigma is known: `export_files` refuses undetermined
        fs.startWriteStruct("", cv2.FileNode_MAP)
        fs.write("name", opencv_text(light.name))
        fs.write("pose_kind", light.pose_kind)
        fs.write("T_camera_light", light_transform(light))
        rvec, tvec = rvec_tvec(light)
        fs.write("rvec", rvec.reshape(3, 1))
        fs.write("tvec", tvec.reshape(3, 1))
        fs.write("pose_covariance", pose_covariance(result, light))
        fs.write("position_m", np.array(light.position_m, dtype=np.float64).reshape(3, 1))
        fs.write("axis_camera", np.array(light.axis_camera, dtype=np.float64).reshape(3, 1))
        fs.write("scale", float(light.scale))
        fs.write("sigma_position_m", np.array(sigma.position_m, dtype=np.float64).reshape(3, 1))
        fs.write("sigma_axis_camera", np.array(sigma.axis_camera, dtype=np.float64).reshape(3, 1))
        fs.write("sigma_R_camera_light", np.array(sigma.R_camera_light, dtype=np.float64))
        fs.write("sigma_roll_deg", _known(sigma.roll_deg))
        fs.write("sigma_pitch_deg", _known(sigma.pitch_deg))
        fs.write("sigma_axis_angle_deg", _known(sigma.axis_angle_from_optical_axis_deg))
        fs.write("sigma_scale", _known(light.scale_sigma))
        rid = light_rid(light, source)
        if rid is not None:
            fs.write("rid_model", rid.model)
            fs.write("rid_half_angle_rad", rid.half_angle_rad)
            if rid.phi_rad is None:
                # (n, 2): theta_rad, relative intensity
                fs.write("rid_table", np.column_stack([rid.theta_rad, rid.values]))
            else:
                fs.write("rid_theta_rad", rid.theta_rad.reshape(-1, 1))
                fs.write("rid_phi_rad", rid.phi_rad.reshape(-1, 1))
                fs.write("rid_grid", rid.values)  # (n_phi, n_theta)
        if light_ports and light.name in light_ports:
            write_opencv_light_port(fs, light_ports[light.name])
        fs.endWriteStruct()
    fs.endWriteStruct()
    medium = export_medium(result, source)
    if medium is not None:
        _write_medium(fs, medium)
    if port is not None:
        write_opencv_port(fs, port)
    return fs.releaseAndGetString().encode("utf-8")


MEDIUM_NOTE = (
    "the medium between the rig and the wall (homogeneous): attenuation_per_m c (extinction, "
    "1/m), backscatter_per_m beta = sigma_s pi / rho (1/m, the scattering coefficient "
    "relative to the wall's diffuse reflectance rho), phase_g the Henyey-Greenstein g; "
    "sigma_*: 1-sigma of an estimated parameter, NaN for a given one"
)


def _write_medium(fs: Any, medium: ExportMedium) -> None:
    """The `medium` map: c, beta, g, their sigmas and the estimated names (after `lights`;
    a result in air has none)."""
    import cv2

    fs.startWriteStruct("medium", cv2.FileNode_MAP)
    fs.write("note", MEDIUM_NOTE)
    for name in MEDIUM_NAMES:
        fs.write(name, medium.value(name))
    for name in MEDIUM_NAMES:
        fs.write(f"sigma_{name}", medium.sigma_of(name))
    fs.startWriteStruct("estimated", cv2.FileNode_SEQ)
    for name in medium.estimated:
        fs.write("", name)
    fs.endWriteStruct()
    fs.endWriteStruct()


def _known(v: float | None) -> float:
    """A sigma of a determined result (NaN if it is not)."""
    return math.nan if v is None else float(v)


_YAML_KEYWORDS = frozenset(["null", "~", "true", "false", "yes", "no", "on", "off", "y", "n"])
"""Plain scalars a YAML 1.1 reader takes for null or a boolean, in lower case."""


def opencv_text(text: str) -> str:
    """`text` as `plain_line` for `cv2.FileStorage.write`, which reads back the same.

    cv2 quotes and escapes a string itself, but cuts it at a NUL, refuses one longer than
    its buffer, and writes one that starts and ends with the same quote character as it
    is (as if already quoted: `"a" b: "c"` would add a key): that one is quoted here. So
    is a YAML keyword (`null`, `true`, `off`, ...), which cv2 writes bare and reads back
    as empty or a number, and other YAML readers as null or a boolean.
    """
    line = plain_line(text)
    quoted = line and line[0] == line[-1] and line[0] in "\"'"
    if quoted or line.lower() in _YAML_KEYWORDS:
        return '"' + line.replace("\\", "\\\\").replace('"', '\\"') + '"'
    return line
