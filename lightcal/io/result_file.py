"""The result file: what `lightcal calibrate` writes (JSON, versioned).

Field names (also in the JSON Schema, `lightcal schema result`):

- ``version`` (1: other versions are refused), ``lightcal_version``, ``project`` (the
  project file's path) and ``project_id`` (`lightcal.io.project_identity`: plan, render
  and export --project refuse a result of another project).
- ``lights[]`` (at least one, each name once): per light ``name``; ``pose_kind``;
  ``position_m`` (emitter position in the camera frame, m); ``R_camera_light`` (3x3, light
  -> camera); ``quaternion_wxyz`` (same rotation, scalar first, w >= 0); ``axis_camera``
  (unit light axis in the camera frame); ``roll_deg``/``pitch_deg`` (the paper's angles:
  axis = R_x(roll) R_y(pitch) (0, 0, 1)); ``axis_angle_from_optical_axis_deg``; ``scale``;
  ``sigma`` (1-sigma of each of those, from the Jacobian at the solution, scaled by the
  residual variance); ``rid`` (the estimated profile when the RID was estimated).
- ``offset``, ``offset_sigma``, ``gains`` (per image, relative to the first).
- ``images[]``: ``name``, ``rms`` (RMS of observed minus rendered, pixel units), ``pixels``.
- ``iterations``, ``nfev``, ``status`` (scipy's, -2 stopped by the user, 0 iteration
  limit), ``message``, ``converged``, ``cost``, ``time_s``, ``warnings``; ``start``: where
  those iterations began when not at the initial guess (a large problem's first solve on
  a subsample of its pixels), in words; empty otherwise.
- ``parameters``: ``names``, ``x`` and ``covariance`` of the solver's parameter vector.
- ``fit``: is the fit explained by the noise, and does a misfit matter? ``adequate`` (no
  finding), ``explained_by_noise``, ``noise_source`` (model, image or none), ``chi2``,
  ``dof``, ``expected_chi2``, ``chi2_per_dof``, ``p_value``, ``excess_relative``,
  ``jackknife_ratio``, ``causes`` (every candidate cause's test: columns, statistic,
  p-value, relative effect, BIC gain, pose shift in sigmas, mm and deg, significant,
  material), ``floors``, the residuals against the ``mirror`` and ``incidence`` angles
  (for the plot), ``findings`` (what matters and what to try) and ``notes`` (what was
  seen but is too small to act on). docs/model.md, "Is the fit explained by the noise?".
- ``wall``: the wall model, its parameters, which were ``estimated`` and their ``sigma``.
- ``medium``: ``attenuation_per_m`` and ``backscatter_per_m`` (1/m; 0 in air),
  ``phase_g``, which parameters were ``estimated`` and their ``sigma``
  (`lightcal.core.medium`).
- ``ambient``, ``ambient_sigma``: the room light's level (pixel units at exposure and
  gain 1) when the project estimates it (``sensor.estimate_ambient``); null otherwise.
- ``channels``: colour channels solved jointly (``sensor.channels``): per channel its
  ``name``, its lights' ``scales`` and ``scale_sigmas`` (by light name), its ``ambient``
  and ``ambient_sigma``, and its ``medium`` (as ``medium``); the lights' ``scale``,
  ``ambient`` and ``medium`` are then the first channel's. Null: one channel.
- ``surroundings``: the surroundings' estimated albedos (``surfaces[i].estimate_albedo``):
  ``albedos`` (every surface's), ``estimated`` (their indices) and ``sigma`` (by index).
- ``fall_off``: the camera's fall-off when the project estimates it
  (``sensor.estimate_fall_off``): ``coefficients`` and ``sigma`` of r^2, r^4, ...,
  ``corner_value`` and ``corner_sigma`` (V at the sensor's corners); null otherwise.
- ``albedo_map``: the wall's albedo map when the project estimates it
  (``wall.albedo_map``): ``origin_xy_m``, ``spacing_m``, ``shape`` and ``values`` (the
  albedo over its mean at each node, null where unseen), ``range``, ``rms``; null otherwise.
- ``uncertainty``: the terms the covariance includes (pixel noise, camera poses, camera
  intrinsics, and the systematic terms when the fit is not explained by the noise), in
  words with their sizes; ``uncertainty_breakdown`` the same per term and light as
  numbers; ``undetermined``: what the data do not determine (sigmas null there);
  ``f_scale_used``: the robust loss's f_scale (null with the linear loss).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, ValidationError, field_validator, model_validator

from lightcal import __version__
from lightcal.core.rotations import ORTHONORMAL_TOL
from lightcal.errors import InputError
from lightcal.io.atomic import atomic_write_text
from lightcal.io.document import read_document
from lightcal.io.port_spec import PortSpec, port_section
from lightcal.io.result_fields import describe_result_schema

RESULT_VERSION = 1


class _Model(BaseModel):
    model_config = ConfigDict(extra="forbid")


class ResultPorts(_Model):
    """The flat ports a calibration looked and shone through (the project's `camera.port`
    and `lights[i].port`, mm), so that an export without the project still has them."""

    camera: PortSpec | None = Field(
        default=None, description="the camera's flat port (camera.port); null: none"
    )
    lights: dict[str, PortSpec] = Field(
        default_factory=dict, description="each ported light's port (lights[i].port) by name"
    )


def result_ports(camera_port: Any, light_ports: list[tuple[str, Any]]) -> ResultPorts | None:
    """The record of a project's ports (`FlatPort`s or None: the camera's, and each light's
    by name), or None without any."""
    lights = {name: port_section(port) for name, port in light_ports if port is not None}
    if camera_port is None and not lights:
        return None
    camera = None if camera_port is None else port_section(camera_port)
    return ResultPorts(camera=camera, lights=lights)


def project_ports(project: Any) -> ResultPorts | None:
    """`result_ports` of a `lightcal.io.project.Project`."""
    return result_ports(
        project.camera_port, [(u.initial.name, u.initial.port) for u in project.lights]
    )


def ports_left_out(ports: ResultPorts) -> str:
    """What an export without the project leaves out of a result calibrated through flat
    ports (`ResultFile.ports`), in words."""
    keys = (["camera.port"] if ports.camera is not None else []) + [
        f"the port of {name!r}" for name in ports.lights
    ]
    return (
        f"the result was calibrated through flat ports ({', '.join(keys)}); without "
        "--project the export carries the lights alone, without their ports"
    )


class PoseSigma(_Model):
    """1-sigma of each pose quantity; null where the data do not determine it (the
    result is then not converged: `undetermined` says why)."""

    model_config = ConfigDict(extra="forbid", allow_inf_nan=False)

    position_m: list[float | None]
    R_camera_light: list[list[float | None]]
    quaternion_wxyz: list[float | None]
    axis_camera: list[float | None]
    roll_deg: float | None = Field(ge=0)
    pitch_deg: float | None = Field(ge=0)
    axis_angle_from_optical_axis_deg: float | None = Field(ge=0)

    @field_validator("position_m", "axis_camera")
    @classmethod
    def _three(cls, value: list[float | None]) -> list[float | None]:
        return _sized(value, 3)

    @field_validator("quaternion_wxyz")
    @classmethod
    def _four(cls, value: list[float | None]) -> list[float | None]:
        return _sized(value, 4)

    @field_validator("R_camera_light")
    @classmethod
    def _three_by_three(cls, value: list[list[float | None]]) -> list[list[float | None]]:
        if len(value) != 3 or any(len(row) != 3 for row in value):
            raise ValueError("expected 3 x 3 sigmas, one per entry of R_camera_light")
        return value


def _sized(value: list[float | None], n: int) -> list[float | None]:
    """`value` when it has `n` sigmas (each >= 0 or null); ValueError otherwise."""
    if len(value) != n:
        raise ValueError(f"expected {n} sigmas, got {len(value)}")
    if any(v is not None and v < 0 for v in value):
        raise ValueError("expected sigmas >= 0 (or null: undetermined)")
    return value


class LightResultModel(_Model):
    # A pose is finite: NaN here is a broken file, named with its field on reading.
    model_config = ConfigDict(extra="forbid", allow_inf_nan=False)

    name: str
    pose_kind: str
    position_m: list[float] = Field(description="emitter position in the camera frame, m")
    R_camera_light: list[list[float]] = Field(description="rotation light -> camera")
    quaternion_wxyz: list[float]
    axis_camera: list[float] = Field(description="unit light axis, camera frame")
    roll_deg: float
    pitch_deg: float
    axis_angle_from_optical_axis_deg: float
    scale: float = Field(gt=0)
    scale_sigma: float | None
    sigma: PoseSigma = Field(description="1-sigma uncertainties of the fields above")
    rid: dict[str, Any] | None = None

    @field_validator("position_m", "axis_camera")
    @classmethod
    def _three_numbers(cls, value: list[float]) -> list[float]:
        if len(value) != 3:
            raise ValueError(f"expected 3 numbers (x, y, z in the camera frame), got {len(value)}")
        return value

    @field_validator("quaternion_wxyz")
    @classmethod
    def _four_numbers(cls, value: list[float]) -> list[float]:
        if len(value) != 4:
            raise ValueError(f"expected 4 numbers (w, x, y, z), got {len(value)}")
        return value

    @field_validator("R_camera_light")
    @classmethod
    def _rotation(cls, value: list[list[float]]) -> list[list[float]]:
        shape = (len(value), *{len(row) for row in value})
        if shape != (3, 3):
            got = " x ".join(str(n) for n in shape) if len(shape) == 2 else "rows of unequal length"
            raise ValueError(f"expected a 3 x 3 rotation matrix (light -> camera), got {got}")
        matrix = np.array(value)
        error = float(np.max(np.abs(matrix.T @ matrix - np.eye(3))))
        if error > ORTHONORMAL_TOL or np.linalg.det(matrix) < 0:
            raise ValueError(
                f"expected a rotation matrix (light -> camera: max |R^T R - I| <= "
                f"{ORTHONORMAL_TOL:g}, det +1), got max |R^T R - I| = {error:.3g}, "
                f"det {np.linalg.det(matrix):.3g}"
            )
        return value


class ImageResult(_Model):
    model_config = ConfigDict(extra="forbid", allow_inf_nan=False)

    name: str
    rms: float | None = Field(description="RMS of observed - rendered pixel values")
    pixels: int = Field(ge=0)
    gain: float = Field(gt=0, description="exposure gain relative to the first image")


class Parameters(_Model):
    names: list[str]
    x: list[float]
    covariance: list[list[float | None]] = Field(
        description="(n, n); null where the data do not determine a parameter"
    )

    @model_validator(mode="after")
    def _sizes(self) -> Parameters:
        n = len(self.names)
        if len(self.x) != n:
            raise ValueError(f"x: expected {n} values, one per name, got {len(self.x)}")
        if len(self.covariance) != n or any(len(row) != n for row in self.covariance):
            rows = {len(row) for row in self.covariance}
            got = f"{len(self.covariance)} x {'/'.join(str(r) for r in sorted(rows)) or 0}"
            raise ValueError(f"covariance: expected {n} x {n} (one row per name), got {got}")
        return self


class ResultFile(_Model):
    """A lightcal calibration result (version 1)."""

    version: int = Field(default=RESULT_VERSION, description="the file format's version")
    lightcal_version: str = __version__
    project: str | None = None
    project_id: str | None = Field(
        default=None,
        description=(
            "the identity of the project calibrated (lightcal.io.project_identity: a hash "
            "of its camera, image poses and lights); plan, render and export --project "
            "refuse a result of another project"
        ),
    )
    lights: list[LightResultModel] = Field(min_length=1)
    offset: float
    offset_sigma: float | None
    images: list[ImageResult]
    iterations: int
    nfev: int
    status: int
    message: str
    converged: bool
    cost: float
    time_s: float
    warnings: list[str]
    parameters: Parameters
    fit: dict[str, Any] | None = Field(
        default=None,
        description="the fit test: adequate, chi2, the candidate causes, findings and notes",
    )
    wall: dict[str, Any] = Field(
        default_factory=lambda: {"model": "lambertian"},
        description="wall model, parameters, estimated names and their sigma",
    )
    medium: dict[str, Any] = Field(
        default_factory=lambda: {"attenuation_per_m": 0.0, "estimated": [], "sigma": {}},
        description="the medium between the rig and the wall: attenuation_per_m and "
        "backscatter_per_m (1/m), phase_g, the estimated parameters' names and their sigma",
    )
    uncertainty: list[str] = Field(
        default_factory=list,
        description="the terms the covariance and sigmas include, in words with their sizes",
    )
    uncertainty_breakdown: list[dict[str, Any]] = Field(
        default_factory=list,
        description=(
            "per covariance term: its name, whether it is systematic, and per light the "
            "1-sigma norm of the position (m) and of the axis direction (deg)"
        ),
    )
    undetermined: list[str] = Field(
        default_factory=list,
        description="what the data do not determine (a result with any is not converged)",
    )
    f_scale_used: float | None = Field(
        default=None,
        description="the robust loss's f_scale the solve used, noise sigmas (null: linear loss)",
    )
    start: str = Field(
        default="",
        description="where the iterations began when not at the initial guess (empty: there)",
    )
    ambient: float | None = Field(
        default=None,
        description="the room light's level, pixel units at exposure and gain 1 "
        "(sensor.estimate_ambient); null when not estimated",
    )
    ambient_sigma: float | None = Field(default=None, description="1-sigma of ambient")
    channels: list[dict[str, Any]] | None = Field(
        default=None,
        description="colour channels solved jointly (sensor.channels): per channel its "
        "name, its lights' scales and their sigmas, its room light and its medium (as "
        "`medium`); the lights' `scale`, `ambient` and `medium` are the first channel's; "
        "null: one channel",
    )
    surroundings: dict[str, Any] | None = Field(
        default=None,
        description="the surroundings' surfaces' albedos when the calibration estimates "
        "any (surfaces[i].estimate_albedo): albedos (per surface), estimated (indices), "
        "sigma (by index); null otherwise",
    )
    ports: ResultPorts | None = Field(
        default=None,
        description="the flat ports the images were calibrated through (the project's "
        "camera.port and lights[i].port, mm); null: none",
    )
    fall_off: dict[str, Any] | None = Field(
        default=None,
        description="the camera's fall-off estimated with the lights (sensor.estimate_fall_off):"
        " coefficients, their sigma, V at the corners; null when not estimated",
    )
    albedo_map: dict[str, Any] | None = Field(
        default=None,
        description="the wall's albedo map estimated with the lights (wall.albedo_map): its "
        "grid and the albedo over its mean at each node; null when not estimated",
    )

    @field_validator("version")
    @classmethod
    def _known_version(cls, value: int) -> int:
        if value != RESULT_VERSION:
            raise ValueError(
                f"expected {RESULT_VERSION} (lightcal {__version__} reads result files of "
                f"version {RESULT_VERSION}), got {value}"
            )
        return value

    @model_validator(mode="after")
    def _unique_lights(self) -> ResultFile:
        names = [light.name for light in self.lights]
        twice = sorted({n for n in names if names.count(n) > 1})
        if twice:
            raise ValueError(f"lights: each light once by name, got {', '.join(twice)} twice")
        return self


def result_to_file(
    result,
    *,
    project: str | Path | None = None,
    project_id: str | None = None,
    ports: ResultPorts | None = None,
) -> ResultFile:
    """Convert a `lightcal.pipeline.CalibrationResult` to the file model; `project` is the
    project file's path, `project_id` its `project_identity`, `ports` its flat ports
    (`project_ports`)."""
    lights = [
        LightResultModel(
            name=lr.name,
            pose_kind=lr.pose_kind,
            **lr.pose.to_dict(),
            scale=lr.scale,
            scale_sigma=_nan_to_none(lr.scale_sigma),
            sigma=PoseSigma(**_nan_to_none(lr.sigma.to_dict())),
            rid=lr.rid,
        )
        for lr in result.lights
    ]
    images = [
        ImageResult(name=n, rms=_nan_to_none(r), pixels=p, gain=g)
        for n, r, p, g in zip(
            result.image_names, result.per_image_rms, result.pixels_used, result.gains, strict=True
        )
    ]
    return ResultFile(
        project=str(project) if project is not None else None,
        project_id=project_id,
        lights=lights,
        offset=result.offset,
        offset_sigma=result.offset_sigma,
        images=images,
        iterations=result.iterations,
        nfev=result.nfev,
        status=result.status,
        message=result.message,
        converged=result.converged,
        cost=result.cost,
        time_s=result.time_s,
        warnings=result.warnings,
        parameters=Parameters(
            names=result.parameter_names, x=result.x, covariance=result.covariance
        ),
        fit=result.fit or None,
        wall=result.wall,
        medium=_nan_to_none(result.medium),
        uncertainty=result.uncertainty_terms,
        uncertainty_breakdown=_nan_to_none(result.uncertainty_breakdown),
        undetermined=result.undetermined,
        f_scale_used=result.f_scale_used,
        start=result.start,
        fall_off=_nan_to_none(result.fall_off),
        albedo_map=result.albedo_map,
        ambient=result.ambient,
        ambient_sigma=_nan_to_none(result.ambient_sigma),
        channels=_nan_to_none(getattr(result, "channels", None)),
        surroundings=_nan_to_none(getattr(result, "surroundings", None)),
        ports=ports,
    )


def _nan_to_none(value: Any) -> Any:
    """value with every NaN float (nested in lists and dicts) replaced by None (JSON null)."""
    if isinstance(value, float):
        return None if value != value else value
    if isinstance(value, list):
        return [_nan_to_none(v) for v in value]
    if isinstance(value, dict):
        return {k: _nan_to_none(v) for k, v in value.items()}
    return value


def write_result(result_file: ResultFile, path: str | Path) -> None:
    """Write the result JSON atomically."""
    atomic_write_text(Path(path), result_file.model_dump_json(indent=2) + "\n")


def is_result_file(path: str | Path) -> bool:
    """Whether `path` holds a lightcal result (JSON with its `lightcal_version`,
    `parameters` and `lights`): what `calibrate --out` may replace without --force."""
    try:
        data = read_document(Path(path), what="result file", as_json=True)
    except InputError:
        return False
    return isinstance(data, dict) and {"lightcal_version", "parameters", "lights"} <= data.keys()


def read_result(path: str | Path) -> ResultFile:
    """Read a result JSON; InputError naming the file on any problem."""
    p = Path(path)
    data = read_document(p, what="result file", as_json=True)
    if isinstance(data, dict) and "lights" in data and {"camera", "images"} <= data.keys():
        raise InputError(
            p, "a project file, not a result: expected the result JSON of lightcal calibrate"
        )
    try:
        return ResultFile.model_validate(data)
    except ValidationError as exc:
        err = exc.errors()[0]
        loc = ".".join(str(x) for x in err["loc"])
        msg = err["msg"].removeprefix("Value error, ")
        raise InputError(p, f"{loc}: {msg}" if loc else msg) from exc


def result_schema() -> dict[str, Any]:
    schema = ResultFile.model_json_schema()
    schema["title"] = "lightcal result (version 1)"
    return describe_result_schema(schema)  # field descriptions, frame convention
