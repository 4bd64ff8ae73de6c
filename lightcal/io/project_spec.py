"""The project file's schema: the pydantic models of the JSON/YAML document.

`ProjectFile` and its sections (`CameraSpec`, `ImageSpec`, `LightSpec`, `SelectionSpec`,
`SolverSpec`, `WallSpec`, ...) say what a project may contain, with the ranges every
number must be in; `parse_project` validates a parsed document and names the field of
the first (most specific) problem; `project_schema` is what `lightcal schema` prints.
`lightcal.io.project` turns a validated file into in-memory objects.
"""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path
from typing import Annotated, Any, Literal

import numpy as np
from pydantic import (
    BaseModel,
    ConfigDict,
    Field,
    ValidationError,
    field_validator,
    model_validator,
)

from lightcal.core.rotations import matrix_from_rotvec
from lightcal.core.selection import SelectionOptions
from lightcal.core.solver import SolverOptions
from lightcal.core.solver_options import AUTO_F_SCALE_FACTORS
from lightcal.errors import InputError
from lightcal.io.albedo_map_spec import AlbedoMapSpec
from lightcal.io.medium_spec import MediumSpec
from lightcal.io.port_spec import PortSpec
from lightcal.io.sensor_spec import FallOffSpec, NoiseSpec, SensorSpec  # noqa: F401 (re-exported)
from lightcal.io.spec_errors import format_loc, on_literal_branch
from lightcal.io.surroundings_spec import SurroundingsSpec

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
    port: PortSpec | None = Field(
        default=None, description="the camera's flat port under water (docs/model.md)"
    )

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
MAX_LIGHT_OFFSET_M = 10.0
"""The farthest a light's initial guess may be from its camera along any axis, m (the
app's position widget and session file hold the same range)."""


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
    dark: str | None = Field(
        default=None,
        description="a photo of the same view with the light off and the same exposure, "
        "read as the image is and subtracted from it before the fit (room light)",
    )


# The defaults of the selection and solver sections are the core options' (defined once).
_SELECTION = SelectionOptions()
_SOLVER = SolverOptions()


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
    initial: InitialSpec | Literal["auto"] = Field(
        default="auto",
        description="the initial guess of the pose, or auto: from where the light's beam "
        "falls in the images (lightcal.core.beam_start; one light only)",
    )
    estimate_rid: Literal["none", "cos_power", "curve"] = "none"
    curve_knots: int = Field(default=6, ge=2, le=30)
    curve_max_angle_deg: float | None = Field(
        default=None,
        gt=0,
        le=89,
        description="range of a 'curve' RID; null: the largest angle the pixels are seen at",
    )
    port: PortSpec | None = Field(
        default=None,
        description="the light's flat port under water: its window's inner face distance_mm "
        "from the emitter along the light's axis (docs/model.md, \"The light's flat port\")",
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


def _options(options_cls: Any, *sections: BaseModel) -> Any:
    """An options dataclass from the project file's sections: every field of
    `options_cls` that a section has, taken from the first section that has it; the
    rest keep their option defaults. One copy for all options, so a field added to both
    the options and the file flows through without another line."""
    values: dict[str, Any] = {}
    for f in dataclasses.fields(options_cls):
        for section in sections:
            if f.name in type(section).model_fields:
                values[f.name] = getattr(section, f.name)
                break
    return options_cls(**values)


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

    def to_options(self) -> SelectionOptions:
        """The core's selection options (regions and mirror exclusion are applied apart)."""
        return _options(SelectionOptions, self)


WallModelName = Literal["lambertian", "plastic", "oren_nayar", "auto"]


class WallSpec(_Model):
    """The wall's reflectance (docs/model.md, "The wall").

    `parameters` by name: plastic `roughness` (GGX alpha), `ior`, `specular_weight`;
    oren_nayar `sigma_deg`. `estimate`: the parameters to estimate with the light(s);
    null: plastic roughness and specular_weight, oren_nayar sigma_deg. `auto`: fit
    Lambertian, test the fit, and where it fails also plastic and oren_nayar, keeping
    the model the Bayesian information criterion prefers. `flatness_mm`: how far the wall
    may depart from a plane (a dome or bowl of that depth), which the images cannot
    reveal; it enters the uncertainty (docs/model.md, "Uncertainty"). `mesh`: the wall's
    shape as a triangle mesh file (world frame, metres; relative to the project file),
    when it is not the plane z = 0 (docs/model.md, "Non-planar targets"); with a mesh,
    `flatness_mm` is the mesh's own tolerance.
    reveal; it enters the uncertainty (docs/model.md, "Uncertainty"). `albedo_map`: an
    uneven albedo shared by the views, estimated with the light (`AlbedoMapSpec`).
    """

    model: WallModelName = "lambertian"
    parameters: dict[str, float] = Field(default_factory=dict)
    estimate: list[str] | None = None
    flatness_mm: float = Field(
        default=0.0,
        ge=0.0,
        le=1000.0,
        allow_inf_nan=False,
        description="the wall's flatness tolerance, mm (0: flat); it widens the sigmas",
    )
    mesh: str | None = Field(
        default=None,
        description="the wall's shape: a triangle mesh file (any format trimesh reads), "
        "world frame, metres, relative to the project file; none: the plane z = 0",
    )
    albedo_map: AlbedoMapSpec | None = Field(
        default=None,
        description="estimate the wall's albedo map with the light (null: an even wall)",
    )

    @model_validator(mode="after")
    def _auto_alone(self) -> WallSpec:
        if self.model in ("auto", "lambertian") and (self.parameters or self.estimate):
            raise ValueError(f"the {self.model} wall takes no parameters and estimates none")
        return self


class SolverSpec(_Model):
    loss: Literal["linear", "huber", "soft_l1", "cauchy"] = _SOLVER.loss
    f_scale: Annotated[float, Field(gt=0)] | Literal["auto"] = Field(
        default=_SOLVER.f_scale,
        description="a robust loss's inlier scale, in noise sigmas; auto: solve with the "
        "linear loss first and take "
        + ", ".join(f"{c:g} ({loss})" for loss, c in AUTO_F_SCALE_FACTORS.items())
        + " times the robust spread (1.4826 MAD) of its residuals. The linear loss ignores it",
    )
    max_iterations: int = Field(default=_SOLVER.max_iterations, ge=1)
    estimate_gains: bool = _SOLVER.estimate_gains
    rid_subsamples: int = Field(default=_SOLVER.rid_subsamples, ge=1, le=16)
    tolerance: float = Field(default=_SOLVER.tolerance, ge=1e-15, le=1.0)
    position_bound_m: float = Field(default=_SOLVER.position_bound_m, gt=0)
    multistart: int = Field(default=0, ge=0, description="extra random starts")
    multistart_position_m: float = Field(default=0.3, gt=0)
    multistart_angle_deg: float = Field(default=30.0, gt=0)

    @field_validator("f_scale", mode="before")
    @classmethod
    def _auto_or_positive(cls, value: Any) -> Any:
        """One message for every wrong f_scale (not one per form the field may take)."""
        if value == "auto" and isinstance(value, str):
            return value
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise ValueError(f'Input should be a number > 0 or "auto", got {value!r}')
        if not math.isfinite(value):
            raise ValueError(f'Input should be a finite number > 0 or "auto", got {value}')
        if value <= 0:
            raise ValueError(f'Input should be greater than 0 or "auto", got {value}')
        return value

    def to_options(self, sensor: SensorSpec) -> SolverOptions:
        """The core's solver options (the offset and its estimation from `sensor`)."""
        return _options(SolverOptions, self, sensor)


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
    medium: MediumSpec = Field(default_factory=MediumSpec)
    surroundings: SurroundingsSpec | None = None


def parse_project(data: Any, source: str | Path) -> ProjectFile:
    """Validate a project document (already parsed JSON/YAML); InputError on any problem."""
    if not isinstance(data, dict):
        raise InputError(source, "expected a mapping (JSON object) at the top level")
    if {"lightcal_version", "parameters"} <= data.keys() and "camera" not in data:
        raise InputError(source, "a result file of lightcal calibrate, not a project file")
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
        err = max(errors, key=lambda e: (len(e["loc"]), not on_literal_branch(e)))
        more = f" (and {len(errors) - 1} more problems)" if len(errors) > 1 else ""
        if len({format_loc(e["loc"][:3]) for e in errors}) == 1:
            more = ""  # the other problems are the same field's other forms
        msg = err["msg"].removeprefix("Value error, ")
        raise InputError(source, f"{format_loc(err['loc'])}: {msg}{more}") from exc


def project_schema() -> dict[str, Any]:
    """The JSON Schema of the project file."""
    schema = ProjectFile.model_json_schema()
    schema["$id"] = "https://lightcal.example/schema/project-v1.json"
    schema["title"] = "lightcal project (version 1)"
    return schema
