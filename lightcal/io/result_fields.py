"""Descriptions of the result file's fields and its frame convention, for `lightcal schema result`.

`describe_result_schema` adds them to the JSON Schema pydantic builds from
`lightcal.io.result_file` (a description given there with `Field` is kept). Frames and
units follow docs/conventions.md.
"""

from __future__ import annotations

from typing import Any

__all__ = ["FRAME_CONVENTION", "describe_result_schema"]

FRAME_CONVENTION = (
    "Every pose is given in the camera's OpenCV frame: x right, y down, z forward along "
    "the optical axis, origin at the optical centre; lengths in metres, angles in degrees "
    "in fields ending _deg. The light frame has +z along the light's axis and +x as the "
    "azimuth reference; T_camera_light = (R_camera_light, position_m) maps light-frame "
    "coordinates to camera-frame coordinates. `lightcal export` converts to OpenCV YAML, "
    "Blender, Mitsuba 3, IES and EULUMDAT."
)

_POSE = {
    "position_m": "emitter position in the camera frame (3,), metres",
    "R_camera_light": "rotation light -> camera (3, 3); column 2 is the light axis",
    "quaternion_wxyz": "R_camera_light as a unit quaternion, scalar first, w >= 0",
    "axis_camera": "unit light axis in the camera frame (3,)",
    "roll_deg": "the paper's roll: axis = R_x(roll) R_y(pitch) (0, 0, 1), degrees",
    "pitch_deg": "the paper's pitch (see roll_deg), degrees",
    "axis_angle_from_optical_axis_deg": "angle between the light axis and the camera's z",
}

_DESCRIPTIONS: dict[str, dict[str, str]] = {
    "": {
        "version": "result file format version",
        "lightcal_version": "the lightcal version that wrote the file",
        "project": "the project file calibrated (absolute path), if any",
        "lights": "one entry per calibrated light",
        "offset": "fitted dark offset, pixel units",
        "offset_sigma": "1-sigma of the offset (null when it was fixed)",
        "images": "per image: name, RMS residual, pixels used, gain",
        "iterations": "solver iterations",
        "nfev": "model evaluations",
        "status": "scipy least_squares status; -2 stopped by the user, 0 iteration limit",
        "message": "the solver's message",
        "converged": "the solver met its tolerances",
        "cost": "final cost, 1/2 the sum of squared weighted residuals",
        "time_s": "solve time, seconds",
        "warnings": "what the user should look at (dark lights, too little view variety, misfit)",
        "parameters": "the solver's parameter vector and its covariance",
    },
    "LightResultModel": {
        "name": "the light's name in the project",
        "pose_kind": "isotropic (position only), symmetric (position, axis) or general (full pose)",
        **_POSE,
        "scale": "fitted intensity scale, pixel units",
        "scale_sigma": "1-sigma of scale",
        "rid": "the estimated RID when the project asked for it: model, parameters, "
        "half_angle_deg, theta_deg and values (relative intensity, 1 on the axis)",
    },
    "PoseSigma": {key: f"1-sigma of {key}" for key in _POSE},
    "ImageResult": {
        "name": "the image's name in the project",
        "pixels": "pixels the solver used",
        "gain": "fitted gain relative to the first image",
    },
    "Parameters": {
        "names": "parameter names",
        "x": "parameter values at the solution",
        "covariance": "parameter covariance (n, n)",
    },
}


def describe_result_schema(schema: dict[str, Any]) -> dict[str, Any]:
    """Add field descriptions and the frame convention to the result's JSON Schema, in place."""
    schema["description"] = f"{schema.get('description', '').strip()} {FRAME_CONVENTION}".strip()
    for model, fields in _DESCRIPTIONS.items():
        node = schema if not model else schema.get("$defs", {}).get(model, {})
        properties = node.get("properties", {})
        for name, text in fields.items():
            if name in properties:
                properties[name].setdefault("description", text)
    return schema
