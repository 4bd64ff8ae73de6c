"""The project file: one versioned JSON/YAML document describing a calibration.

`ProjectFile` (pydantic) is the file on disk; `load_project` validates it, resolves
relative paths against the file's folder, checks that every referenced file exists and
that the geometry makes sense (cameras in front of the wall, initial lights in front of
the wall in every view), and returns a `Project` of in-memory objects. Every problem is
an `InputError` naming the file and the field (e.g. ``images[3].T_camera_world``).
`lightcal schema` prints `ProjectFile.model_json_schema()`.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Annotated, Any, Literal

import numpy as np
import yaml
from pydantic import BaseModel, ConfigDict, Field, ValidationError, model_validator

from lightcal.core.camera import Camera
from lightcal.core.pose import axis_from_paper_angles, rotation_from_axis
from lightcal.core.problem import LightUnknown, WallUnknown
from lightcal.core.rid import RID, CosPowerRID, GaussianRID, IsotropicRID
from lightcal.core.rotations import matrix_from_rotvec
from lightcal.core.scene import Light, View
from lightcal.core.selection import SelectionOptions
from lightcal.core.solver import SolverOptions
from lightcal.core.wall import WALL_MODELS, make_wall
from lightcal.errors import InputError, LightcalError
from lightcal.io.atomic import atomic_write_text
from lightcal.io.document import read_document

PROJECT_VERSION: Literal[1] = 1

Vec3 = Annotated[list[float], Field(min_length=3, max_length=3)]
Mat3 = Annotated[list[Vec3], Field(min_length=3, max_length=3)]
PixelPoint = Annotated[list[float], Field(min_length=2, max_length=2)]


class _Model(BaseModel):
    model_config = ConfigDict(extra="forbid", allow_inf_nan=False, frozen=True)


class CameraSpec(_Model):
    """Intrinsics inline (fx, fy, cx, cy, width, height, dist) or `path` to a camera file
    (OpenCV YAML/JSON/XML or COLMAP cameras.txt)."""

    path: str | None = None
    camera_id: int | None = None
    fx: float | None = None
    fy: float | None = None
    cx: float | None = None
    cy: float | None = None
    skew: float = 0.0
    width: int | None = None
    height: int | None = None
    dist: list[float] = Field(default_factory=list)

    @model_validator(mode="after")
    def _one_source(self) -> CameraSpec:
        inline = [self.fx, self.fy, self.cx, self.cy, self.width, self.height]
        if self.path is None and any(v is None for v in inline):
            raise ValueError("give either path or all of fx, fy, cx, cy, width, height")
        if self.path is not None and any(v is not None for v in inline):
            raise ValueError("give either path or inline intrinsics, not both")
        return self


INTRINSIC_COUNTS = (4, 8, 9, 12)
"""Intrinsic parameters of a camera with 0, 4, 5 or 8 distortion coefficients."""

Mat6 = Annotated[
    list[Annotated[list[float], Field(min_length=6, max_length=6)]],
    Field(min_length=6, max_length=6),
]


MAX_DISTANCE_M = 10_000.0
"""The farthest a camera may be from the wall's origin along any axis, m."""
MAX_LIGHT_OFFSET_M = 100.0
"""The farthest a light's initial guess may be from its camera along any axis, m."""


class PoseSpec(_Model):
    """World -> camera extrinsics: `R` (3x3) or `rvec` (Rodrigues, radians), and `t` (m).

    `covariance` (optional, 6x6): the pose's uncertainty as the covariance of
    (delta, c): delta (rad) a rotation perturbation R -> exp(delta) R in the camera frame,
    c the camera centre in the world frame (m). `lightcal init` writes it from the marker
    fit; the calibration propagates it into the light's uncertainty.

    `d_pose_d_intrinsics` (optional, 6 x p): how the pose (delta, c) moves per unit
    change of each of the camera's intrinsic parameters (fx, fy, cx, cy, distortion,
    p = 4 + the number of distortion coefficients; `Camera.intrinsic_params`): a pose
    estimated with the camera's intrinsics shares their error. `lightcal init` writes it
    when the camera file has an intrinsics covariance; the calibration uses it to
    propagate that covariance (docs/model.md, "Uncertainty").
    """

    R: Mat3 | None = None
    rvec: Vec3 | None = None
    t: Vec3
    covariance: Mat6 | None = None
    d_pose_d_intrinsics: Annotated[list[list[float]], Field(min_length=6, max_length=6)] | None = (
        None
    )

    @model_validator(mode="after")
    def _one_rotation(self) -> PoseSpec:
        if (self.R is None) == (self.rvec is None):
            raise ValueError("give exactly one of R or rvec")
        if max(abs(v) for v in self.t) > MAX_DISTANCE_M:
            raise ValueError(
                f"t: {list(self.t)} m: expected a camera within {MAX_DISTANCE_M:g} m of the "
                "wall's origin (a translation this large is a unit or sign mistake)"
            )
        if self.covariance is not None:
            c = np.array(self.covariance, dtype=np.float64)
            if not np.all(np.isfinite(c)):
                raise ValueError("covariance: expected finite values")
            if not np.allclose(c, c.T, rtol=1e-6, atol=1e-300):
                raise ValueError("covariance: expected a symmetric matrix")
            if np.linalg.eigvalsh(0.5 * (c + c.T)).min() < -1e-12 * max(np.abs(c).max(), 1e-300):
                raise ValueError("covariance: expected a positive semi-definite matrix")
        if self.d_pose_d_intrinsics is not None:
            widths = {len(row) for row in self.d_pose_d_intrinsics}
            if len(widths) != 1 or widths.pop() not in INTRINSIC_COUNTS:
                raise ValueError(
                    "d_pose_d_intrinsics: expected 6 rows of 4, 8, 9 or 12 values (one per "
                    "intrinsic parameter: fx, fy, cx, cy, distortion)"
                )
            if not np.all(np.isfinite(np.array(self.d_pose_d_intrinsics, dtype=np.float64))):
                raise ValueError("d_pose_d_intrinsics: expected finite values")
        return self

    def covariance_matrix(self) -> np.ndarray | None:
        """(6, 6) covariance of (delta (rad), camera centre (m)), or None."""
        if self.covariance is None:
            return None
        c = np.array(self.covariance, dtype=np.float64)
        return 0.5 * (c + c.T)

    def intrinsics_jacobian(self) -> np.ndarray | None:
        """(6, p) d (delta, c) / d (fx, fy, cx, cy, distortion), or None."""
        if self.d_pose_d_intrinsics is None:
            return None
        return np.array(self.d_pose_d_intrinsics, dtype=np.float64)

    def rotation(self) -> np.ndarray:
        if self.R is not None:
            return np.array(self.R, dtype=np.float64)
        assert self.rvec is not None
        return matrix_from_rotvec(np.array(self.rvec, dtype=np.float64))


class ExposureSpec(_Model):
    """Exposure settings; the factor is t x ISO / N^2 relative to the first image."""

    exposure_time_s: float = Field(gt=0)
    iso: float = Field(default=100.0, gt=0)
    f_number: float = Field(default=1.0, gt=0)

    def factor(self) -> float:
        return self.exposure_time_s * self.iso / self.f_number**2


class ImageSpec(_Model):
    """One photograph of the wall."""

    path: str
    name: str | None = None
    T_camera_world: PoseSpec
    exposure: float | ExposureSpec | None = Field(
        default=None,
        description="relative exposure factor, or settings; null: from EXIF if present, else 1",
    )
    mask: str | None = Field(default=None, description="image of pixels to exclude (non-zero)")


class NoiseSpec(_Model):
    """Poisson-Gaussian noise: variance = gain * signal + read_variance (pixel units)."""

    gain: float = Field(ge=0)
    read_variance: float = Field(gt=0)


# The defaults of the selection and solver sections are the core options' (defined once).
_SELECTION = SelectionOptions()
_SOLVER = SolverOptions()


class SensorSpec(_Model):
    model: Literal["radiance", "cos4", "paper", "map"] = "radiance"
    vignetting: str | None = Field(default=None, description="fall-off map file for 'map'")
    channel: Literal["auto", "green_binned", "luminance", "R", "G", "G1", "G2", "B"] = "auto"
    black_level: float | None = Field(default=None, ge=0, description="subtracted on load")
    white_level: float | None = Field(default=None, gt=0)
    assume_linear: bool = False
    response: str | None = Field(default=None, description="camera response curve file")
    offset: float = Field(
        default=_SOLVER.offset, description="known (or initial) offset after black level"
    )
    estimate_offset: bool = _SOLVER.estimate_offset
    noise: NoiseSpec | None = None

    @model_validator(mode="after")
    def _map_needs_file(self) -> SensorSpec:
        if self.model == "map" and self.vignetting is None:
            raise ValueError("the 'map' sensor model needs a vignetting file")
        if (
            self.black_level is not None
            and self.white_level is not None
            and not self.white_level > self.black_level
        ):
            raise ValueError(
                f"white_level {self.white_level:g} must be above black_level {self.black_level:g}"
            )
        return self


class RIDSpec(_Model):
    """The light's angular profile."""

    type: Literal["isotropic", "cos_power", "gaussian", "half_angle", "table", "ies", "ldt"]
    m: float | None = Field(default=None, ge=0)
    sigma_deg: float | None = Field(default=None, gt=0)
    half_angle_deg: float | None = Field(default=None, gt=0, lt=90)
    profile: Literal["cos_power", "gaussian"] = "cos_power"
    path: str | None = None

    @model_validator(mode="after")
    def _fields_for_type(self) -> RIDSpec:
        need = {
            "cos_power": "m",
            "gaussian": "sigma_deg",
            "half_angle": "half_angle_deg",
            "table": "path",
            "ies": "path",
            "ldt": "path",
        }.get(self.type)
        if need is not None and getattr(self, need) is None:
            raise ValueError(f"RID type {self.type!r} needs {need}")
        return self


class InitialSpec(_Model):
    """Initial guess of a light's pose (camera frame) and scale."""

    position_m: Annotated[
        list[Annotated[float, Field(ge=-MAX_LIGHT_OFFSET_M, le=MAX_LIGHT_OFFSET_M)]],
        Field(min_length=3, max_length=3),
    ]
    axis_camera: Vec3 | None = None
    roll_deg: float | None = None
    pitch_deg: float | None = None
    R_camera_light: Mat3 | None = None
    scale: float | None = Field(default=None, gt=0, description="null: fitted linearly")

    @model_validator(mode="after")
    def _one_orientation(self) -> InitialSpec:
        given = [
            self.axis_camera is not None,
            self.roll_deg is not None or self.pitch_deg is not None,
            self.R_camera_light is not None,
        ]
        if sum(given) > 1:
            raise ValueError("give at most one of axis_camera, roll_deg/pitch_deg, R_camera_light")
        return self


class LightSpec(_Model):
    name: str = "light"
    rid: RIDSpec
    pose: Literal["auto", "isotropic", "symmetric", "general"] = "auto"
    initial: InitialSpec
    estimate_rid: Literal["none", "cos_power", "curve"] = "none"
    curve_knots: int = Field(default=6, ge=2, le=30)
    curve_max_angle_deg: float | None = Field(
        default=None,
        gt=0,
        le=89,
        description="range of a 'curve' RID; null: the largest angle the pixels are seen at",
    )


class RegionSpec(_Model):
    """A rectangle (two opposite corners) or polygon in pixel coordinates."""

    kind: Literal["rect", "polygon"]
    include: bool = True
    images: list[str] | None = Field(default=None, description="image names; null: all")
    points: list[PixelPoint] = Field(min_length=2)

    @model_validator(mode="after")
    def _count(self) -> RegionSpec:
        if self.kind == "rect" and len(self.points) != 2:
            raise ValueError("a rect needs exactly 2 points (opposite corners)")
        if self.kind == "polygon" and len(self.points) < 3:
            raise ValueError("a polygon needs at least 3 points")
        return self


class SelectionSpec(_Model):
    strategy: Literal["random", "grid", "all"] = _SELECTION.strategy
    n_per_image: int = Field(default=_SELECTION.n_per_image, ge=1)
    grid_step: int = Field(default=_SELECTION.grid_step, ge=1)
    binning: int = Field(default=_SELECTION.binning, ge=1)
    seed: int = Field(default=_SELECTION.seed, ge=0, le=2**32 - 1)
    min_signal: float | None = Field(
        default=_SELECTION.min_signal,
        description="values at or below are dropped; null: 5 read-noise sigmas",
    )
    regions: list[RegionSpec] = Field(default_factory=list)
    exclude_mirror_deg: float | None = Field(
        default=None,
        ge=0,
        lt=90,
        description="drop pixels whose half vector lies within this angle of the wall "
        "normal (re-derived from the estimate after the first convergence); null: keep all",
    )


WallModelName = Literal["lambertian", "plastic", "oren_nayar", "auto"]


class WallSpec(_Model):
    """The wall's reflectance (docs/model.md, "The wall").

    `parameters` by name: plastic `roughness` (GGX alpha), `ior`, `specular_weight`;
    oren_nayar `sigma_deg`. `estimate`: the parameters to estimate with the light(s);
    null: plastic roughness and specular_weight, oren_nayar sigma_deg. `auto`: fit
    Lambertian, test the fit, and where it fails also plastic and oren_nayar, keeping
    the model the Bayesian information criterion prefers.
    """

    model: WallModelName = "lambertian"
    parameters: dict[str, float] = Field(default_factory=dict)
    estimate: list[str] | None = None

    @model_validator(mode="after")
    def _auto_alone(self) -> WallSpec:
        if self.model in ("auto", "lambertian") and (self.parameters or self.estimate):
            raise ValueError(f"the {self.model} wall takes no parameters and estimates none")
        return self


class SolverSpec(_Model):
    loss: Literal["linear", "huber", "soft_l1", "cauchy"] = _SOLVER.loss
    f_scale: float = Field(default=_SOLVER.f_scale, gt=0)
    max_iterations: int = Field(default=_SOLVER.max_iterations, ge=1)
    estimate_gains: bool = _SOLVER.estimate_gains
    rid_subsamples: int = Field(default=_SOLVER.rid_subsamples, ge=1, le=16)
    tolerance: float = Field(default=_SOLVER.tolerance, ge=1e-15, le=1.0)
    position_bound_m: float = Field(default=_SOLVER.position_bound_m, gt=0)
    multistart: int = Field(default=0, ge=0, description="extra random starts")
    multistart_position_m: float = Field(default=0.3, gt=0)
    multistart_angle_deg: float = Field(default=30.0, gt=0)


class ProjectFile(_Model):
    """A lightcal calibration project (version 1)."""

    version: Literal[1] = PROJECT_VERSION
    camera: CameraSpec
    sensor: SensorSpec = Field(default_factory=SensorSpec)
    images: list[ImageSpec] = Field(min_length=1)
    lights: list[LightSpec] = Field(min_length=1)
    selection: SelectionSpec = Field(default_factory=SelectionSpec)
    solver: SolverSpec = Field(default_factory=SolverSpec)
    wall: WallSpec = Field(default_factory=WallSpec)


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

    @property
    def folder(self) -> Path:
        return self.path.parent


_UNION_BRANCHES = frozenset({"float", "int", "str", "bool", "list", "dict"})


def _format_loc(loc: tuple[Any, ...]) -> str:
    out = ""
    for part in loc:
        if isinstance(part, str) and (part in _UNION_BRANCHES or part.endswith("Spec")):
            continue  # the name of a union's branch (ExposureSpec, float), not a field
        if isinstance(part, int):
            out += f"[{part}]"
        else:
            out += ("." if out else "") + str(part)
    return out or "(top level)"


def parse_project(data: Any, source: str | Path) -> ProjectFile:
    """Validate a project document (already parsed JSON/YAML); InputError on any problem."""
    if not isinstance(data, dict):
        raise InputError(source, "expected a mapping (JSON object) at the top level")
    version = data.get("version", PROJECT_VERSION)
    if version != PROJECT_VERSION:
        raise InputError(
            source,
            f"version: this lightcal reads project version {PROJECT_VERSION}, got {version!r}",
        )
    try:
        return ProjectFile.model_validate(data)
    except ValidationError as exc:
        errors = exc.errors()
        # The most specific problem: where a value may take several forms (a number or
        # exposure settings), the branch that got deepest says what is wrong.
        err = max(errors, key=lambda e: len(e["loc"]))
        more = f" (and {len(errors) - 1} more problems)" if len(errors) > 1 else ""
        if len({_format_loc(e["loc"][:3]) for e in errors}) == 1:
            more = ""  # the other problems are the same field's other forms
        msg = err["msg"].removeprefix("Value error, ")
        raise InputError(source, f"{_format_loc(err['loc'])}: {msg}{more}") from exc


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
    return project_from_spec(spec, source)


def project_from_spec(spec: ProjectFile, source: Path) -> Project:
    """Build a `Project` from a validated spec whose relative paths resolve against
    `source`'s folder."""
    folder = source.parent
    camera = _build_camera(spec.camera, folder, source)
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
    exposures = _exposure_factors(spec, image_paths, source)
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
        try:
            R = _initial_rotation(ls.initial)
            light = Light(
                rid,
                np.array(ls.initial.position_m),
                R,
                scale=ls.initial.scale or 1.0,
                name=ls.name,
            )
        except ValueError as exc:
            raise InputError(source, f"{field}.initial: {exc}") from exc
        for i, view in enumerate(views):
            z = float(light.position_world(view)[2])
            if z <= 0.0:
                raise InputError(
                    source,
                    f"{field}.initial.position_m: the light is on or behind the wall in image "
                    f"{names[i]!r} (world z = {z:.3g} m); expected it in front (z > 0)",
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

    sel = spec.selection
    selection = SelectionOptions(
        strategy=sel.strategy,
        n_per_image=sel.n_per_image,
        grid_step=sel.grid_step,
        binning=sel.binning,
        seed=sel.seed,
        min_signal=sel.min_signal,
    )
    so = spec.solver
    solver = SolverOptions(
        loss=so.loss,
        f_scale=so.f_scale,
        max_iterations=so.max_iterations,
        estimate_gains=so.estimate_gains,
        estimate_offset=spec.sensor.estimate_offset,
        offset=spec.sensor.offset,
        rid_subsamples=so.rid_subsamples,
        tolerance=so.tolerance,
        position_bound_m=so.position_bound_m,
    )
    vignetting_path = (
        _resolve(folder, spec.sensor.vignetting, source, "sensor.vignetting", "vignetting file")
        if spec.sensor.vignetting
        else None
    )
    return Project(
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
    )


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


def _settings_value(e: Any) -> float:
    """t x ISO / N^2 with `ExposureSpec`'s defaults for settings unknown in every image."""
    iso = e.iso if e.iso is not None else 100.0
    f_number = e.f_number if e.f_number is not None else 1.0
    return float(e.exposure_time_s * iso / f_number**2)


def _exposure_factors(spec: ProjectFile, image_paths: list[Path], source: Path) -> list[float]:
    """Relative exposure g_i of every image.

    An explicit factor is used as given. Settings (an `ExposureSpec`, or the file's EXIF
    when `exposure` is null) become t x ISO / N^2 relative to the first image that has
    settings. When some images have settings, every image without an explicit factor
    must have them too (else its exposure would be a guess); when none has, g_i = 1.
    """
    from lightcal.io.exif import Exposure, read_exposure

    settings: list[Exposure | None] = []
    for i, im in enumerate(spec.images):
        if isinstance(im.exposure, ExposureSpec):
            e = im.exposure
            settings.append(Exposure(e.exposure_time_s, e.iso, e.f_number))
        elif im.exposure is None:
            exif = read_exposure(image_paths[i])
            settings.append(exif if exif is not None and exif.exposure_time_s else None)
        else:
            settings.append(None)
    known = [e for e in settings if e is not None]
    factors = []
    for i, im in enumerate(spec.images):
        if isinstance(im.exposure, float | int) and not isinstance(im.exposure, bool):
            factors.append(float(im.exposure))
        elif settings[i] is not None:
            try:
                # Validates that the same settings are known in both (else a guess).
                settings[i].relative_factor(known[0])  # type: ignore[union-attr]
            except ValueError as exc:
                raise InputError(source, f"images[{i}].exposure: {exc}") from exc
            factors.append(_settings_value(settings[i]) / _settings_value(known[0]))
        elif known:
            raise InputError(
                source,
                f"images[{i}].exposure: not given and {image_paths[i].name} has no EXIF "
                "exposure time, while other images' exposures come from settings; "
                "give the exposure of every image",
            )
        else:
            factors.append(1.0)
    return factors


def save_project(spec: ProjectFile, path: str | Path) -> None:
    """Write a project file atomically (YAML for .yaml/.yml, else JSON)."""
    p = Path(path)
    data = spec.model_dump(mode="json", exclude_none=True)
    if p.suffix.lower() in (".yaml", ".yml"):
        text = yaml.safe_dump(data, sort_keys=False)
    else:
        text = json.dumps(data, indent=2) + "\n"
    atomic_write_text(p, text)


def project_schema() -> dict[str, Any]:
    """The JSON Schema of the project file."""
    schema = ProjectFile.model_json_schema()
    schema["$id"] = "https://lightcal.example/schema/project-v1.json"
    schema["title"] = "lightcal project (version 1)"
    return schema


__all__ = [
    "PROJECT_VERSION",
    "LightcalError",
    "Project",
    "ProjectFile",
    "load_project",
    "parse_project",
    "project_schema",
    "save_project",
]
