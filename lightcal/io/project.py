"""The project file: one versioned JSON/YAML document describing a calibration.

`ProjectFile` (pydantic) is the file on disk; `load_project` validates it, resolves relative
paths against the file's folder, checks that every referenced file exists and that the
geometry makes sense (cameras in front of the wall, initial lights in front of the wall in
every view), and returns a `Project` of in-memory objects. Every problem is an `InputError`
naming the file and the field (e.g. ``images[3].T_camera_world``). `lightcal schema`
prints `ProjectFile.model_json_schema()`.
"""

from __future__ import annotations

import dataclasses
import json
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import cast

import numpy as np
import yaml

from lightcal.core.camera import Camera
from lightcal.core.fall_off import FallOffUnknown
from lightcal.core.flat_port import FlatPort
from lightcal.core.pose import axis_from_paper_angles, rotation_from_axis
from lightcal.core.problem import LightUnknown, MediumUnknown, WallUnknown
from lightcal.core.rid import RID, CosPowerRID, GaussianRID, IsotropicRID
from lightcal.core.scene import Light, View
from lightcal.core.selection import SelectionOptions
from lightcal.core.solver import SolverOptions
from lightcal.core.surroundings import Surroundings
from lightcal.core.wall import WALL_MODELS, make_wall
from lightcal.core.wall_mesh import WallMesh
from lightcal.errors import InputError
from lightcal.io.albedo_map_spec import albedo_map_options
from lightcal.io.atomic import atomic_write_text
from lightcal.io.dark_frames import dark_paths
from lightcal.io.document import read_document
from lightcal.io.exposure_factors import exposure_factors
from lightcal.io.images import Channel
from lightcal.io.medium_spec import build_media
from lightcal.io.port_spec import build_light_port, build_port
from lightcal.io.project_channels import check_channel_terms, with_channels
from lightcal.io.project_keys import check_no_ignored_keys
from lightcal.io.project_spec import (
    INTRINSIC_COUNTS,
    MAX_DISTANCE_M,
    MAX_LIGHT_OFFSET_M,
    PROJECT_VERSION,
    CameraSpec,
    ExposureSpec,
    ImageSpec,
    InitialSpec,
    LightSpec,
    Mat3,
    Mat6,
    NoiseSpec,
    PixelPoint,
    PoseSpec,
    ProjectFile,
    RegionSpec,
    RIDSpec,
    SelectionSpec,
    SensorSpec,
    SolverSpec,
    Vec3,
    WallModelName,
    WallSpec,
    parse_project,
    project_schema,
)
from lightcal.io.surroundings_spec import build_surroundings
from lightcal.io.wall_mesh_file import read_wall_mesh

__all__ = [
    "INTRINSIC_COUNTS",
    "MAX_DISTANCE_M",
    "MAX_LIGHT_OFFSET_M",
    "PROJECT_VERSION",
    "CameraSpec",
    "ExposureSpec",
    "ImageSpec",
    "InitialSpec",
    "LightSpec",
    "Mat3",
    "Mat6",
    "NoiseSpec",
    "PixelPoint",
    "PoseSpec",
    "Project",
    "ProjectFile",
    "RIDSpec",
    "RegionSpec",
    "SelectionSpec",
    "SensorSpec",
    "SolverSpec",
    "Vec3",
    "WallModelName",
    "WallSpec",
    "build_rid",
    "build_wall",
    "load_project",
    "parse_project",
    "project_from_spec",
    "project_schema",
    "save_project",
]


@dataclass(frozen=True, eq=False)
class Project:
    """A validated project with its paths resolved and its objects built.

    Attributes:
        spec: the file's content.
        path: the project file; folder: the folder relative paths resolve against.
        camera: the intrinsics.
        views: one per image.
        image_paths, mask_paths: resolved paths (mask None when absent).
        names: image labels.
        lights: the lights to calibrate.
        selection: pixel selection options; solver: solver options.
        vignetting_path: resolved fall-off map file or None.
        wall: the wall model and what to estimate of it (Lambertian for `auto`, whose
            candidates the pipeline fits in turn: `spec.wall.model`).
        pose_covariances: per image, the (6, 6) covariance of its pose (see `PoseSpec`)
            or None.
        pose_intrinsics_jacobians: per image, the (6, p) d (delta, c) / d intrinsics of
            its pose (`PoseSpec.d_pose_d_intrinsics`, p = 4 + camera.n_dist) or None.
        dark_paths: per image, its resolved light-off photo (`images[i].dark`) or None
            (`lightcal.io.dark_frames`); empty: none.
        medium: the medium between the rig and the wall and what to estimate of it.
        wall_mesh: the wall's shape (`wall.mesh`), or None: the plane z = 0.
        surroundings: surfaces near the wall whose bounce light the model adds, or None.
        channels: the colour channels solved jointly (`sensor.channels`), or empty: then
            each image is one entry; with channels each image is one entry per channel,
            its channel `channel_of[i]` and its image `spec_index[i]` of `spec.images`
            (named `name[channel]`), and `media` has each channel's medium (`medium` the
            first's).
        camera_port: the camera's flat port (`camera.port`), or None: straight rays.
    """

    spec: ProjectFile
    path: Path
    camera: Camera
    views: list[View]
    image_paths: list[Path]
    mask_paths: list[Path | None]
    names: list[str]
    lights: list[LightUnknown]
    selection: SelectionOptions
    solver: SolverOptions
    vignetting_path: Path | None
    wall: WallUnknown = field(default_factory=WallUnknown)
    pose_covariances: list[np.ndarray | None] = field(default_factory=list)
    pose_intrinsics_jacobians: list[np.ndarray | None] = field(default_factory=list)
    dark_paths: list[Path | None] = field(default_factory=list)
    medium: MediumUnknown = field(default_factory=MediumUnknown)
    wall_mesh: WallMesh | None = None
    surroundings: Surroundings | None = None
    channels: tuple[str, ...] = ()
    channel_of: list[int] = field(default_factory=list)
    spec_index: list[int] = field(default_factory=list)
    media: tuple[MediumUnknown, ...] = ()
    camera_port: FlatPort | None = None

    @property
    def folder(self) -> Path:
        return self.path.parent

    def spec_image(self, i: int) -> int:
        """The index in `spec.images` of entry i."""
        return self.spec_index[i] if self.spec_index else i

    def channel_index(self, i: int) -> int:
        """Entry i's channel among `channels` (0 without channels)."""
        return self.channel_of[i] if self.channel_of else 0

    def channel_name(self, i: int) -> Channel:
        """The channel entry i is read in (`sensor.channel` without channels)."""
        if not self.channels:
            return self.spec.sensor.channel
        return cast("Channel", self.channels[self.channel_index(i)])

    def photo_name(self, i: int) -> str:
        """The name of entry i's photo (its name without the channel)."""
        im = self.spec.images[self.spec_image(i)]
        return im.name or Path(im.path).stem


def _resolve(folder: Path, rel: str, source: Path, field: str, what: str) -> Path:
    p = Path(rel)
    p = p if p.is_absolute() else folder / p
    if not p.is_file():
        raise InputError(source, f"{field}: {what} not found: {p}")
    return p


def build_rid(spec: RIDSpec, folder: Path, source: Path, field: str) -> RID:
    """The RID object a `RIDSpec` describes (reads table/IES/LDT files)."""
    if spec.type == "isotropic":
        return IsotropicRID()
    if spec.type == "cos_power":
        assert spec.m is not None
        return CosPowerRID(spec.m)
    if spec.type == "gaussian":
        assert spec.sigma_deg is not None
        return GaussianRID(math.radians(spec.sigma_deg))
    if spec.type == "half_angle":
        assert spec.half_angle_deg is not None
        half = math.radians(spec.half_angle_deg)
        if spec.profile == "gaussian":
            return GaussianRID.from_half_angle(half)
        return CosPowerRID.from_half_angle(half)
    assert spec.path is not None
    path = _resolve(folder, spec.path, source, f"{field}.path", "RID file")
    if spec.type == "table":
        from lightcal.io.photometric_table import read_rid_csv

        return read_rid_csv(path)
    if spec.type == "ies":
        from lightcal.io.ies import read_ies
        from lightcal.io.photometric_table import table_to_rid

        return table_to_rid(read_ies(path))
    from lightcal.io.eulumdat import read_ldt
    from lightcal.io.photometric_table import table_to_rid

    return table_to_rid(read_ldt(path))


def _initial_rotation(init: InitialSpec) -> np.ndarray:
    if init.R_camera_light is not None:
        return np.array(init.R_camera_light, dtype=np.float64)
    if init.axis_camera is not None:
        axis = np.array(init.axis_camera, dtype=np.float64)
        norm = float(np.linalg.norm(axis))
        if norm == 0.0:
            raise ValueError("axis_camera: expected a non-zero vector")
        return rotation_from_axis(axis / norm)
    if init.roll_deg is not None or init.pitch_deg is not None:
        axis = axis_from_paper_angles(
            math.radians(init.roll_deg or 0.0), math.radians(init.pitch_deg or 0.0)
        )
        return rotation_from_axis(axis)
    return np.eye(3)


def _build_camera(spec: CameraSpec, folder: Path, source: Path) -> Camera:
    if spec.path is not None:
        from lightcal.io.camera_file import read_camera

        return read_camera(
            _resolve(folder, spec.path, source, "camera.path", "camera file"),
            camera_id=spec.camera_id,
        )
    assert spec.fx is not None and spec.fy is not None and spec.cx is not None
    assert spec.cy is not None and spec.width is not None and spec.height is not None
    try:
        return Camera.from_params(
            fx=spec.fx,
            fy=spec.fy,
            cx=spec.cx,
            cy=spec.cy,
            width=spec.width,
            height=spec.height,
            dist=tuple(spec.dist),
            skew=spec.skew,
        )
    except ValueError as exc:
        raise InputError(source, f"camera: {exc}") from exc


def load_project(path: str | Path) -> Project:
    """Read and validate a project file (JSON, or YAML for .yaml/.yml)."""
    source = Path(path).resolve()
    spec = parse_project(
        read_document(source, what="project file", as_json=source.suffix.lower() == ".json"),
        source,
    )
    check_no_ignored_keys(spec, source)  # a key the file gives that lightcal would not use
    return project_from_spec(spec, source)


def project_from_spec(spec: ProjectFile, source: Path) -> Project:
    """Build a `Project` from a validated spec whose relative paths resolve against
    `source`'s folder."""
    folder = source.parent
    camera = _build_camera(spec.camera, folder, source)
    wall_mesh = None
    if spec.wall.mesh is not None:
        path = _resolve(folder, spec.wall.mesh, source, "wall.mesh", "wall mesh file")
        wall_mesh = read_wall_mesh(path)
    # A light behind the wall's lowest point is behind it (with a mesh: a bound).
    floor_z = 0.0 if wall_mesh is None else wall_mesh.z_range_m[0]
    where_floor = "" if wall_mesh is None else " m, the wall mesh's lowest point"
    sel = spec.selection
    if sel.strategy == "all" and sel.binning > min(camera.width, camera.height):
        raise InputError(
            source,
            f"selection.binning: {sel.binning} is larger than the image "
            f"({camera.width}x{camera.height}); expected at most "
            f"{min(camera.width, camera.height)}",
        )
    views: list[View] = []
    image_paths: list[Path] = []
    mask_paths: list[Path | None] = []
    names: list[str] = []
    for i, im in enumerate(spec.images):
        field = f"images[{i}]"
        image_paths.append(_resolve(folder, im.path, source, f"{field}.path", "image file"))
        mask_paths.append(
            _resolve(folder, im.mask, source, f"{field}.mask", "mask file") if im.mask else None
        )
        names.append(im.name or Path(im.path).stem)
    # One file twice counts its noise twice: sigmas too small (confidently wrong).
    seen: dict[Path, int] = {}
    for i, path in enumerate(image_paths):
        first = seen.setdefault(path.resolve(), i)
        if first != i:
            raise InputError(
                source,
                f"images[{i}].path: the same file as images[{first}] ({path.name}): a copy "
                "adds no information and would count its noise twice; expected each photo once",
            )
    exposures = exposure_factors(spec, image_paths, source)
    for i, im in enumerate(spec.images):
        if not (math.isfinite(exposures[i]) and exposures[i] > 0.0):
            raise InputError(
                source, f"images[{i}].exposure: expected a finite value > 0, got {exposures[i]!r}"
            )
        try:
            views.append(
                View(im.T_camera_world.rotation(), np.array(im.T_camera_world.t), exposures[i])
            )
        except ValueError as exc:
            raise InputError(source, f"images[{i}].T_camera_world: {exc}") from exc
    if len(set(names)) != len(names):
        dup = next(n for n in names if names.count(n) > 1)
        raise InputError(source, f"images: two images are named {dup!r}; names must be unique")

    lights: list[LightUnknown] = []
    for j, ls in enumerate(spec.lights):
        field = f"lights[{j}]"
        rid = build_rid(ls.rid, folder, source, f"{field}.rid")
        light_port = build_light_port(spec, j, source)
        if ls.initial == "auto":
            if len(spec.lights) > 1:
                raise InputError(
                    source,
                    f"{field}.initial: auto guesses one light from its beam; with "
                    f"{len(spec.lights)} lights, give each its initial pose",
                )
            # At the camera centre looking ahead, until the images are read
            # (lightcal.pipeline.auto_start.with_auto_initial puts it on its beam).
            light = Light(rid, np.zeros(3), np.eye(3), name=ls.name, port=light_port)
        else:
            try:
                R = _initial_rotation(ls.initial)
                light = Light(
                    rid,
                    np.array(ls.initial.position_m),
                    R,
                    scale=ls.initial.scale or 1.0,
                    name=ls.name,
                    port=light_port,
                )
            except ValueError as exc:
                raise InputError(source, f"{field}.initial: {exc}") from exc
        for i, view in enumerate(views):
            z = float(light.position_world(view)[2])
            if z <= floor_z:
                raise InputError(
                    source,
                    f"{field}.initial.position_m: the light is on or behind the wall in image "
                    f"{names[i]!r} (world z = {z:.3g} m); expected it in front "
                    f"(z > {floor_z:.3g}{where_floor})",
                )
        pose_kind = None if ls.pose == "auto" else ls.pose
        lights.append(
            LightUnknown(
                light,
                pose_kind=pose_kind,
                estimate_rid=ls.estimate_rid,
                curve_knots=ls.curve_knots,
                curve_max_angle_rad=(
                    math.radians(ls.curve_max_angle_deg) if ls.curve_max_angle_deg else None
                ),
            )
        )
    if len({ls.name for ls in spec.lights}) != len(spec.lights):
        raise InputError(source, "lights: light names must be unique")

    selection = spec.selection.to_options()
    solver = spec.solver.to_options(spec.sensor)
    if (estimated := spec.sensor.estimate_fall_off) is not None:
        binning = sel.binning if sel.strategy == "all" else 1  # the selection's super-pixels
        fall_off = FallOffUnknown(estimated.order, camera.width, camera.height, binning)
        solver = dataclasses.replace(solver, fall_off=fall_off)
    albedo = albedo_map_options(spec.wall.albedo_map, spec.solver.loss, source)
    solver = dataclasses.replace(solver, albedo_map=albedo)
    vignetting_path = (
        _resolve(folder, spec.sensor.vignetting, source, "sensor.vignetting", "vignetting file")
        if spec.sensor.vignetting
        else None
    )
    channels = tuple(spec.sensor.channels or ())
    media = build_media(spec.medium, spec.sensor.model, source, channels)
    check_channel_terms(spec, views, source)
    project = Project(
        spec,
        source,
        camera,
        views,
        image_paths,
        mask_paths,
        names,
        lights,
        selection,
        solver,
        vignetting_path,
        build_wall(spec.wall, source),
        [im.T_camera_world.covariance_matrix() for im in spec.images],
        _intrinsics_jacobians(spec, camera, source),
        dark_paths(spec, folder, source, image_paths),
        media[0],
        wall_mesh,
        build_surroundings(spec.surroundings, source),
        camera_port=build_port(spec, source),
    )
    return with_channels(project, media) if channels else project


def _intrinsics_jacobians(
    spec: ProjectFile, camera: Camera, source: Path
) -> list[np.ndarray | None]:
    """Each image's `d_pose_d_intrinsics`, checked against the camera's parameter count."""
    p = 4 + camera.n_dist
    out = []
    for k, im in enumerate(spec.images):
        D = im.T_camera_world.intrinsics_jacobian()
        if D is not None and D.shape != (6, p):
            raise InputError(
                source,
                f"images[{k}].T_camera_world.d_pose_d_intrinsics: expected 6 x {p} (the "
                f"camera's fx, fy, cx, cy and {camera.n_dist} distortion coefficients), got "
                f"6 x {D.shape[1]}",
            )
        out.append(D)
    return out


def build_wall(spec: WallSpec, source: Path) -> WallUnknown:
    """The `WallUnknown` of a wall spec (file names and degrees there, radians here)."""
    if spec.model in ("lambertian", "auto"):
        return WallUnknown()
    cls = WALL_MODELS[spec.model]
    internal = {_FILE_PARAMETER.get(n, n): n for n in cls.parameter_names}
    expected = ", ".join(internal)
    for where, names in (("parameters", list(spec.parameters)), ("estimate", spec.estimate)):
        unknown = [n for n in names or [] if n not in internal]
        if unknown:
            raise InputError(
                source,
                f"wall.{where}: the {spec.model} wall has no parameter "
                f"{', '.join(map(repr, unknown))}; expected {expected}",
            )
    params = {
        internal[n]: math.radians(v) if n.endswith("_deg") else v
        for n, v in spec.parameters.items()
    }
    try:
        wall = make_wall(spec.model, params)
    except ValueError as exc:
        raise InputError(source, f"wall.parameters: {exc}") from exc
    if spec.estimate is None:
        return WallUnknown(wall, cls.default_estimate)
    if len(set(spec.estimate)) != len(spec.estimate):
        raise InputError(source, "wall.estimate: expected each parameter once")
    return WallUnknown(wall, tuple(internal[n] for n in spec.estimate))


#: Wall parameters whose file name differs from the model's (degrees in files).
_FILE_PARAMETER = {"sigma": "sigma_deg"}


def save_project(spec: ProjectFile, path: str | Path) -> None:
    """Write a project file atomically (YAML for .yaml/.yml, else JSON)."""
    p = Path(path)
    data = spec.model_dump(mode="json", exclude_none=True)
    if p.suffix.lower() in (".yaml", ".yml"):
        text = yaml.safe_dump(data, sort_keys=False)
    else:
        text = json.dumps(data, indent=2) + "\n"
    atomic_write_text(p, text)
