"""A project's identity: which project a result belongs to.

A result is only meaningful with the project it was calibrated on: `plan`, `render`
and `export --project` put its light poses back into that project's camera and views.
A result of another project that happens to name a light alike would be used silently.
So `lightcal calibrate` writes `project_id` into the result: a hash of what the result
depends on, and each command that reads a result with a project checks it first.

What the identity covers: the camera (intrinsics, distortion, image size), every image's
name and pose, every light's name and RID (its kind and parameters; a photometric
file by its content, not its path), and the camera's and lights' flat ports where there
are any (a project without ports hashes as before ports existed). What it leaves out,
because a result stays valid across them: paths (a project folder that moved), the
initial guesses (the app writes a solution back as the next start), the selection, the
solver and the wall model.
"""

from __future__ import annotations

import hashlib
import json
from pathlib import Path
from typing import Any

import numpy as np

from lightcal.core.flat_port import FlatPort
from lightcal.errors import InputError
from lightcal.io.project import Project

PREFIX = "sha256:"
DIGITS = 16  # hex digits kept: 64 bits, ample to tell projects apart


def _numbers(values: Any) -> list[str]:
    """Floats as 9 significant digits: equal projects hash equal across BLAS builds."""
    return [f"{float(v):.9g}" for v in np.asarray(values, dtype=float).ravel()]


def _rid_identity(rid_spec: dict[str, Any], folder: Path) -> dict[str, Any]:
    out = {k: v for k, v in rid_spec.items() if k != "path" and v is not None}
    path = rid_spec.get("path")
    if path:
        file = (folder / path).resolve()
        try:
            out["file_sha256"] = hashlib.sha256(file.read_bytes()).hexdigest()
        except OSError:  # load_project already read it: gone since, identify it by name
            out["file"] = Path(path).name
    return out


def _port_identity(port: FlatPort) -> list[str]:
    return _numbers(
        [port.distance_m, port.thickness_m, port.glass_index, port.water_index, *port.normal_camera]
    )


def project_identity(project: Project) -> str:
    """`sha256:` and 16 hex digits identifying the project's camera, views and lights."""
    camera = project.camera
    camera_content: dict[str, Any] = {
        "K": _numbers(camera.K),
        "dist": _numbers(camera.dist),
        "size": [int(camera.width), int(camera.height)],
    }
    if project.camera_port is not None:
        camera_content["port"] = _port_identity(project.camera_port)
    lights: list[dict[str, Any]] = []
    for spec, unknown in zip(project.spec.lights, project.lights, strict=True):
        light = {"name": spec.name, "rid": _rid_identity(spec.rid.model_dump(), project.folder)}
        if unknown.initial.port is not None:
            light["port"] = _port_identity(unknown.initial.port)
        lights.append(light)
    content = {
        "camera": camera_content,
        "views": [
            {"name": name, "R": _numbers(view.R_camera_world), "t": _numbers(view.t_camera_world)}
            for name, view in zip(project.names, project.views, strict=True)
        ],
        "lights": lights,
    }
    text = json.dumps(content, sort_keys=True, separators=(",", ":"))
    return PREFIX + hashlib.sha256(text.encode()).hexdigest()[:DIGITS]


def check_result_of(project: Project, result_path: Path, result_project_id: str | None) -> None:
    """InputError unless the result at `result_path` was calibrated on `project`.

    A result without `project_id` (written before lightcal 0.9 or by hand) is accepted:
    there is nothing to check it against.
    """
    if result_project_id is None:
        return
    own = project_identity(project)
    if result_project_id != own:
        raise InputError(
            result_path,
            f"the result is of another project (project_id {result_project_id}; "
            f"{project.path} is {own}: its camera, image poses or lights differ); "
            "calibrate this project, or give the project the result was calibrated on",
        )
