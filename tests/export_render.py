"""An exported Mitsuba scene rendered by Mitsuba 3 beside lightcal's render of the same view.

`result_of_project(project, scales)` writes the result a calibration of `project` would
give if it found the project's initial lights (pose, RID) with the given scales: the
comparison is of the export, not of a solve, so no solve is run. `compare_view` exports
it with the project's camera (`lightcal export --format mitsuba --project`), adds a
Lambertian wall of albedo `ALBEDO` in the pose of one of the project's views (the
exported scene is in the camera's frame: the wall's `to_world` is
diag(-1, -1, 1, 1) T_camera_world, docs/conventions.md), renders it with Mitsuba's
`direct` integrator, and compares pi / ALBEDO times Mitsuba's image with lightcal's
`render_image` of the same lights and view on the camera without its distortion
(Mitsuba's `perspective` has none): no fitted scale, so the lights' intensities are
checked too.

Figures (`ExportComparison`): the median and 99th percentile of |Mitsuba / lightcal - 1|
over the lit pixels (lightcal's value above 5 % of its peak), and the distance between
the two images' beam centroids (value-weighted mean pixel over the pixels both render).
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from lightcal.core.camera import Camera
from lightcal.core.medium import AIR, Medium
from lightcal.core.pose import describe_pose
from lightcal.core.render import render_image
from lightcal.core.scene import Light, Rig
from lightcal.io.project import Project
from lightcal.io.result_file import (
    ImageResult,
    LightResultModel,
    Parameters,
    PoseSigma,
    ResultFile,
    write_result,
)

ALBEDO = 0.5
LIT_LEVEL = 0.05


@dataclass(frozen=True)
class ExportComparison:
    median_rel: float
    p99_rel: float
    centroid_px: float
    lit: int


def placeholder_sigma() -> PoseSigma:
    """Sigmas of 1 mm and 0.1 deg (a result written by a test, not a solve)."""
    return PoseSigma(
        position_m=[1e-3] * 3,
        R_camera_light=[[1e-3] * 3] * 3,
        quaternion_wxyz=[1e-3] * 4,
        axis_camera=[1e-3] * 3,
        roll_deg=0.1,
        pitch_deg=0.1,
        axis_angle_from_optical_axis_deg=0.1,
    )


def _light_model(light: Light, kind: str) -> LightResultModel:
    pose = describe_pose(light.R_camera_light, light.t_camera_light)
    return LightResultModel(
        name=light.name,
        pose_kind=kind,
        **pose,
        scale=light.scale,
        scale_sigma=0.01 * light.scale,
        sigma=placeholder_sigma(),
        rid=None,
    )


def project_lights(project: Project, scales: list[float]) -> list[Light]:
    """The project's initial lights with the given scales."""
    return [
        Light(u.initial.rid, u.initial.t_camera_light, u.initial.R_camera_light, s, u.initial.name)
        for u, s in zip(project.lights, scales, strict=True)
    ]


def stub_result(
    lights: list[LightResultModel],
    *,
    project: str,
    image_names: list[str],
    message: str,
    medium: dict | None = None,
) -> ResultFile:
    """A result file of `lights` with placeholder solve fields (one iteration, converged),
    for the exports' tests; `medium` as the result file holds it (None: in air)."""
    extra = {} if medium is None else {"medium": medium}
    return ResultFile(
        lightcal_version="0.1.0",
        project=project,
        lights=lights,
        offset=0.0,
        offset_sigma=None,
        images=[ImageResult(name=n, rms=0.1, pixels=10, gain=1.0) for n in image_names],
        iterations=1,
        nfev=1,
        status=1,
        message=message,
        converged=True,
        cost=1.0,
        time_s=0.0,
        warnings=[],
        parameters=Parameters(names=["x"], x=[0.0], covariance=[[1.0]]),
        **extra,
    )


def result_of_project(
    project: Project, scales: list[float], path: Path, medium: Medium = AIR
) -> Path:
    """A result file holding the project's initial lights with `scales` (no RID estimated),
    calibrated in `medium` (given)."""
    lights = project_lights(project, scales)
    result = stub_result(
        [_light_model(light, u.kind()) for light, u in zip(lights, project.lights, strict=True)],
        project=str(project.path),
        image_names=list(project.names),
        message="made by tests/export_render.py",
        medium={**medium.describe(), "estimated": [], "sigma": {}},
    )
    write_result(result, path)
    return path


def undistorted(camera: Camera) -> Camera:
    return Camera.from_params(
        fx=camera.fx,
        fy=camera.fy,
        cx=camera.cx,
        cy=camera.cy,
        width=camera.width,
        height=camera.height,
    )


def mitsuba_render(
    xml_path: Path, T_camera_world: np.ndarray, variant: str, spp: int = 16
) -> np.ndarray:
    """(H, W) Mitsuba's render of the exported scene with a wall added (module docstring).

    A scene in water keeps its own integrator (`volpath`), loaded with `max_depth` 2:
    the wall's direct light and single scattering, lightcal's model."""
    import mitsuba as mi

    mi.set_variant(variant)
    tree = ET.parse(xml_path)
    scene = tree.getroot()
    in_water = scene.find("integrator") is not None
    if not in_water:
        ET.SubElement(scene, "integrator", {"type": "direct"})
    wall = ET.SubElement(scene, "shape", {"type": "rectangle"})
    to_world = np.diag([-1.0, -1.0, 1.0, 1.0]) @ T_camera_world @ np.diag([20.0, 20.0, 1.0, 1.0])
    transform = ET.SubElement(wall, "transform", {"name": "to_world"})
    ET.SubElement(
        transform, "matrix", {"value": " ".join(repr(float(v)) for v in to_world.ravel())}
    )
    bsdf = ET.SubElement(wall, "bsdf", {"type": "diffuse"})
    ET.SubElement(bsdf, "rgb", {"name": "reflectance", "value": repr(ALBEDO)})
    for count in scene.iter("integer"):
        if count.get("name") == "sample_count":
            count.set("value", str(spp))
    with_wall = xml_path.with_name(xml_path.stem + "_with_wall.xml")
    tree.write(with_wall)
    options = {"max_depth": 2} if in_water else {}
    image = np.array(mi.render(mi.load_file(str(with_wall), **options)), dtype=np.float64)
    return image[:, :, 0] * math.pi / ALBEDO


def _centroid(image: np.ndarray) -> np.ndarray:
    rows, cols = np.indices(image.shape)
    w = image.sum()
    return np.array([(cols * image).sum() / w, (rows * image).sum() / w])


def both_renders(
    project: Project,
    lights: list[Light],
    xml_path: Path,
    view_index: int,
    variant: str,
    *,
    medium: Medium = AIR,
    spp: int = 16,
) -> tuple[np.ndarray, np.ndarray]:
    """(H, W) lightcal's render of the view in `medium` and (H, W) Mitsuba's of the
    exported scene with the wall, times pi / ALBEDO (NaN where lightcal's is invalid)."""
    view = project.views[view_index]
    camera = undistorted(project.camera)
    ours = render_image(camera, view, Rig(tuple(lights)), medium=medium).filled(np.nan)
    T = np.eye(4)
    T[:3, :3] = view.R_camera_world
    T[:3, 3] = view.t_camera_world
    theirs = mitsuba_render(xml_path, T, variant, spp) * view.exposure  # scale at exposure 1
    return ours, theirs


def compare_view(
    project: Project, lights: list[Light], xml_path: Path, view_index: int, variant: str
) -> ExportComparison:
    ours, theirs = both_renders(project, lights, xml_path, view_index, variant)
    both = np.isfinite(ours) & np.isfinite(theirs)
    lit = both & (ours > LIT_LEVEL * np.nanmax(ours))
    rel = np.abs(theirs[lit] / ours[lit] - 1.0)
    shift = _centroid(np.where(both, theirs, 0.0)) - _centroid(np.where(both, ours, 0.0))
    return ExportComparison(
        float(np.median(rel)),
        float(np.percentile(rel, 99)),
        float(np.hypot(*shift)),
        int(lit.sum()),
    )
