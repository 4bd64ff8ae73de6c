"""The outcome of a calibration: per-light poses with 1-sigma uncertainties, the
fitted scales, gains and offset, the warnings, and `summarise`, which builds it."""

from __future__ import annotations

import functools
import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, ClassVar

import numpy as np

from lightcal.core.medium import AIR
from lightcal.core.misfit_verdict import significant_digits
from lightcal.core.pose import describe_pose
from lightcal.core.rid import CosPowerRID
from lightcal.core.solver import CalibrationModel, IterationReport, SolveOutcome
from lightcal.pipeline.albedo_result import albedo_map_summary
from lightcal.pipeline.channel_result import (
    channel_summaries,
    medium_summary,
    medium_summary_at,
    surroundings_summary,
)
from lightcal.pipeline.diagnose import dark_light_warnings, variety_warnings
from lightcal.pipeline.fall_off_result import fall_off_problems, fall_off_summary, fall_off_warnings
from lightcal.pipeline.fit_check import check_fit
from lightcal.pipeline.measurements import Measurements, model_only


@dataclass(frozen=True, eq=False)
class PoseSummary:
    """A light pose described in the camera frame (see `lightcal.core.pose.describe_pose`),
    or the 1-sigma uncertainties of those quantities, component by component.

    Attributes:
        t_camera_light: (3,) emitter position in the camera frame, metres.
        R_camera_light: (3, 3) rotation, light frame -> camera frame.
        quaternion_wxyz: (4,) quaternion of `R_camera_light`, w >= 0.
        axis_camera: (3,) unit light axis.
        roll_deg, pitch_deg: the paper's angles of the axis.
        axis_angle_from_optical_axis_deg: angle between the light axis and camera +z.

    The arrays are read-only float64. `to_vector` / `from_vector` lay the quantities out
    as one flat (22,) vector (for propagating the covariance); `to_dict` / `from_dict`
    the JSON-ready form, keyed by the result file's names (`FILE_NAMES`: the position is
    `position_m` there, as in `describe_pose`).
    """

    t_camera_light: np.ndarray
    R_camera_light: np.ndarray
    quaternion_wxyz: np.ndarray
    axis_camera: np.ndarray
    roll_deg: float
    pitch_deg: float
    axis_angle_from_optical_axis_deg: float

    SHAPES: ClassVar[dict[str, tuple[int, ...]]] = {
        "t_camera_light": (3,),
        "R_camera_light": (3, 3),
        "quaternion_wxyz": (4,),
        "axis_camera": (3,),
        "roll_deg": (),
        "pitch_deg": (),
        "axis_angle_from_optical_axis_deg": (),
    }
    SIZE: ClassVar[int] = sum(math.prod(shape) for shape in SHAPES.values())  # 22
    # Field -> key in the result file (and `describe_pose`), where they differ.
    FILE_NAMES: ClassVar[dict[str, str]] = {"t_camera_light": "position_m"}

    def __post_init__(self) -> None:
        for name, shape in self.SHAPES.items():
            if shape:
                a = np.array(getattr(self, name), dtype=np.float64)
                if a.shape != shape:
                    raise ValueError(f"{name} has shape {a.shape}, expected {shape}")
                a.setflags(write=False)
                object.__setattr__(self, name, a)
            else:
                object.__setattr__(self, name, float(getattr(self, name)))

    @classmethod
    def of_pose(cls, R_camera_light: np.ndarray, t_camera_light: np.ndarray) -> PoseSummary:
        """The description of the pose (R_camera_light, t_camera_light)."""
        return cls.from_dict(describe_pose(R_camera_light, t_camera_light))

    def to_vector(self) -> np.ndarray:
        """(22,) the fields in declaration order, arrays flattened row by row."""
        return np.concatenate([np.ravel(getattr(self, name)) for name in self.SHAPES])

    @classmethod
    def from_vector(cls, v: np.ndarray) -> PoseSummary:
        """The inverse of `to_vector`."""
        v = np.asarray(v, dtype=np.float64)
        if v.shape != (cls.SIZE,):
            raise ValueError(f"pose vector has shape {v.shape}, expected ({cls.SIZE},)")
        values: dict[str, Any] = {}
        start = 0
        for name, shape in cls.SHAPES.items():
            n = math.prod(shape)
            values[name] = v[start : start + n].reshape(shape) if shape else v[start]
            start += n
        return cls(**values)

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready: nested lists of floats and floats under the result file's names, as
        `describe_pose` gives."""
        out: dict[str, Any] = {}
        for name, shape in self.SHAPES.items():
            value = getattr(self, name)
            out[self.FILE_NAMES.get(name, name)] = value.tolist() if shape else value
        return out

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> PoseSummary:
        """The inverse of `to_dict` (also reads `describe_pose`'s dictionaries)."""
        return cls(**{name: data[cls.FILE_NAMES.get(name, name)] for name in cls.SHAPES})

    def __eq__(self, other: object) -> bool:  # unhashable, as it defines __eq__
        if not isinstance(other, PoseSummary):
            return NotImplemented
        return bool(np.array_equal(self.to_vector(), other.to_vector()))


@dataclass(frozen=True)
class LightResult:
    """One calibrated light.

    Attributes:
        name: the light's name.
        pose: the calibrated pose.
        sigma: 1-sigma of the pose's quantities (position and vectors per component).
        scale, scale_sigma: the fitted scale.
        pose_kind: isotropic, symmetric or general.
        rid: estimated RID description (None when the RID was given).
    """

    name: str
    pose: PoseSummary
    sigma: PoseSummary
    scale: float
    scale_sigma: float
    pose_kind: str
    rid: dict | None


@dataclass(frozen=True)
class CalibrationResult:
    """Everything a calibration produced (written as result JSON)."""

    lights: list[LightResult]
    offset: float
    offset_sigma: float | None
    gains: list[float]
    image_names: list[str]
    per_image_rms: list[float]
    pixels_used: list[int]
    iterations: int
    nfev: int
    status: int
    message: str
    converged: bool
    cost: float
    time_s: float
    warnings: list[str]
    parameter_names: list[str]
    x: list[float]
    covariance: list[list[float]]
    history: list[IterationReport] = field(default_factory=list, repr=False)
    fit: dict = field(default_factory=dict)
    wall: dict = field(default_factory=lambda: {"model": "lambertian"})
    # The medium: {"attenuation_per_m", "estimated", "sigma"} (`medium_summary`).
    medium: dict = field(default_factory=lambda: medium_summary(AIR))
    uncertainty_terms: list[str] = field(default_factory=list)
    # Per term of the covariance: {"term", "systematic", "lights": [{"name",
    # "position_sigma_m", "axis_sigma_deg"}]} (`uncertainty_breakdown`).
    uncertainty_breakdown: list[dict] = field(default_factory=list)
    # What the data do not determine, in words (a result with any is not converged).
    undetermined: list[str] = field(default_factory=list)
    # The robust loss's f_scale (noise sigmas) the solve used; None with the linear loss.
    f_scale_used: float | None = None
    start: str = ""  # `SolveOutcome.start`: where the reported iterations began
    start_costs: list[float] = field(default_factory=list, repr=False)  # and its costs
    fall_off: dict | None = None  # the estimated fall-off (`fall_off_summary`), or None
    # The room light's level at exposure and gain 1 and its sigma; None: not estimated.
    ambient: float | None = None
    ambient_sigma: float | None = None
    albedo_map: dict | None = None  # the estimated albedo map (`albedo_map_summary`)
    channels: list[dict] | None = None  # per colour channel (`channel_summaries`)
    surroundings: dict | None = None  # the estimated albedos (`surroundings_summary`)

    @property
    def fit_adequate(self) -> bool:
        """The residuals are explained by the noise (true when the fit was not tested)."""
        return bool(self.fit.get("adequate", True))


def _numeric_jacobian(fn: Callable[[np.ndarray], np.ndarray], x: np.ndarray) -> np.ndarray:
    y0 = np.asarray(fn(x), dtype=np.float64)
    J = np.zeros((y0.size, x.size))
    for k in range(x.size):
        h = 1e-7 * max(1.0, abs(x[k]))
        xp = x.copy()
        xm = x.copy()
        xp[k] += h
        xm[k] -= h
        J[:, k] = (np.asarray(fn(xp)) - np.asarray(fn(xm))).ravel() / (2 * h)
    return J


def _light_pose(model: CalibrationModel, j: int, x: np.ndarray) -> PoseSummary:
    """The pose of light j at parameters x."""
    block = model.layout.blocks[j]
    R, t = block.param.to_pose(x[block.pose])
    return PoseSummary.of_pose(R, t)


def _light_pose_vector(model: CalibrationModel, j: int, x: np.ndarray) -> np.ndarray:
    return _light_pose(model, j, x).to_vector()


def summarise(
    model: CalibrationModel,
    outcome: SolveOutcome,
    measurements: Measurements | None = None,
    *,
    notes: list[str] | None = None,
) -> CalibrationResult:
    """Turn a solve into a `CalibrationResult` with uncertainties, the fit test and warnings.

    Args:
        model: the solved model.
        outcome: the solve.
        measurements: each image's noise and pose covariance (`measurements_for`);
            default: what the model carries (its noise model if any, no pose terms).
        notes: extra lines for the result's warnings (e.g. what `auto` chose).
    """
    x = outcome.x
    fit = check_fit(model, x, measurements or model_only(model))
    diagnosis, unc = fit.diagnosis, fit.uncertainty
    lay = model.layout
    unknown = undetermined_parameters(model, x)
    cov = unc.covariance.copy()
    cov[unknown, :] = np.nan
    cov[:, unknown] = np.nan
    lights = []
    jacobians = []
    for j, block in enumerate(lay.blocks):
        pose = _light_pose(model, j, x)
        G = _numeric_jacobian(functools.partial(_light_pose_vector, model, j), x)
        jacobians.append(G)
        sig = np.sqrt(np.clip(np.diag(G @ cov @ G.T), 0, None))
        scale = lay.light_of(block, x).scale  # exp(log-scale), clipped as the model
        rid_desc = None
        if block.unknown.estimate_rid != "none":
            rid = lay.rid_of(block, x)
            theta = np.linspace(0, math.radians(89), 90)
            rid_desc = {
                "model": block.unknown.estimate_rid,
                "parameters": x[block.rid].tolist(),
                "half_angle_deg": math.degrees(rid.half_angle_rad),
                "theta_deg": np.degrees(theta).tolist(),
                "values": np.asarray(rid(theta)).tolist(),
            }
            if block.unknown.estimate_rid == "cos_power":
                assert isinstance(rid, CosPowerRID)
                rid_desc["m"] = rid.m
        lights.append(
            LightResult(
                block.unknown.initial.name,
                pose,
                PoseSummary.from_vector(sig),
                scale,
                scale * math.sqrt(max(cov[block.log_scale, block.log_scale], 0.0)),
                block.param.kind,
                rid_desc,
            )
        )
    bound_warnings = _bound_warnings(model, x)
    dark = dark_light_warnings(model, x, fit.light_shares)
    undetermined = (
        [
            f"the data do not determine {', '.join(lay.names[k] for k in unknown)}: no pixel "
            "responds to them, or only together (the normal matrix is singular there); their "
            "sigmas are undetermined"
        ]
        if unknown
        else []
    )
    undetermined += dark  # a light that lights no selected pixel: its pose is not determined
    fall_off = fall_off_summary(model, x, cov)
    undetermined += fall_off_problems(model, x, fall_off)
    breakdown = _breakdown(model, unc.components, jacobians, unknown)
    offset_sigma = None
    if lay.offset_index is not None:
        offset_sigma = math.sqrt(max(cov[lay.offset_index, lay.offset_index], 0.0))
    return CalibrationResult(
        lights=lights,
        offset=lay.offset(x),
        offset_sigma=offset_sigma,
        gains=lay.gain_factors(x).tolist(),
        image_names=[im.name for im in model.images],
        per_image_rms=model.per_image_rms(x).tolist(),
        pixels_used=[len(im.observed) for im in model.images],
        iterations=outcome.iterations,
        nfev=outcome.nfev,
        status=outcome.status,
        message=outcome.message,
        # A solve stopped by the search box did not find a minimum, whatever trf says; one
        # that leaves a parameter undetermined did not determine the pose.
        converged=outcome.success and not bound_warnings and not undetermined,
        cost=outcome.cost,
        time_s=outcome.time_s,
        warnings=(
            bound_warnings
            + dark
            + undetermined[: 1 if unknown else 0]
            + variety_warnings(model, np.nan_to_num(cov))
            + [f"misfit: {f}" for f in diagnosis.findings]
            + fall_off_warnings(fall_off)
            + list(notes or [])
        ),
        parameter_names=list(lay.names),
        x=x.tolist(),
        covariance=cov.tolist(),
        history=outcome.history,
        fit=diagnosis.to_dict(),
        wall=_wall_summary(model, x, cov),
        medium=medium_summary_at(model, x, cov),
        uncertainty_terms=_sized_terms(unc.terms, breakdown),
        uncertainty_breakdown=breakdown,
        undetermined=undetermined,
        f_scale_used=outcome.f_scale_used,
        start=outcome.start,
        start_costs=outcome.start_costs,
        fall_off=fall_off,
        ambient=None if lay.ambient_index is None else lay.ambient(x),
        ambient_sigma=(
            None
            if lay.ambient_index is None
            else math.sqrt(max(cov[lay.ambient_index, lay.ambient_index], 0.0))
        ),
        albedo_map=albedo_map_summary(model, x),
        channels=channel_summaries(model, x, cov),
        surroundings=surroundings_summary(model, x, cov),
    )


def undetermined_parameters(model: CalibrationModel, x: np.ndarray) -> list[int]:
    """The parameters the data do not determine at x: those no pixel responds to (a zero
    column of J) and those that carry the null directions of the normal matrix J^T J
    scaled to unit diagonal (eigenvalues below 1e-12: a correlation of 1 - 1e-12)."""
    N = model.normal_matrix(x)
    d = np.diag(N).copy()
    zero = [k for k in range(d.size) if not (np.isfinite(d[k]) and d[k] > 0.0)]
    keep = [k for k in range(d.size) if k not in zero]
    out = set(zero)
    if keep:
        s = 1.0 / np.sqrt(d[keep])
        Ns = N[np.ix_(keep, keep)] * np.outer(s, s)
        if np.all(np.isfinite(Ns)):
            w, V = np.linalg.eigh(0.5 * (Ns + Ns.T))
            for j in np.flatnonzero(w < 1e-12):
                v = np.abs(V[:, j])
                out.update(keep[k] for k in np.flatnonzero(v >= 0.5 * v.max()))
        else:
            out.update(keep)
    return sorted(out)


def _breakdown(
    model: CalibrationModel,
    components: list[tuple[str, np.ndarray]],
    jacobians: list[np.ndarray],
    unknown: list[int],
) -> list[dict]:
    """Each covariance term's size: per light the 1-sigma norm of its position (m) and of
    its axis direction (deg)."""
    index = {name: k for k, name in enumerate(PoseSummary.SHAPES)}
    sizes = [math.prod(shape) for shape in PoseSummary.SHAPES.values()]
    starts = np.concatenate([[0], np.cumsum(sizes)])
    position = slice(starts[index["t_camera_light"]], starts[index["t_camera_light"] + 1])
    axis = slice(starts[index["axis_camera"]], starts[index["axis_camera"] + 1])
    out = []
    for name, C in components:
        C = C.copy()
        C[unknown, :] = np.nan
        C[:, unknown] = np.nan
        lights = []
        for block, G in zip(model.layout.blocks, jacobians, strict=True):
            V = G @ C @ G.T
            lights.append(
                {
                    "name": block.unknown.initial.name,
                    "position_sigma_m": _trace_sigma(V[position, position]),
                    "axis_sigma_deg": (
                        math.degrees(_trace_sigma(V[axis, axis]))
                        if block.param.kind != "isotropic"
                        else None
                    ),
                }
            )
        out.append({"term": name, "systematic": name.startswith("systematic"), "lights": lights})
    return out


def _sized_terms(terms: list[str], breakdown: list[dict]) -> list[str]:
    """Each term in words with its size: "...: 1.2 mm, 0.031 deg" (the largest over the
    lights)."""
    if len(terms) != len(breakdown):
        return terms
    out = []
    for text, b in zip(terms, breakdown, strict=True):
        position = [x["position_sigma_m"] for x in b["lights"]]
        axis = [x["axis_sigma_deg"] for x in b["lights"] if x["axis_sigma_deg"] is not None]
        size = [f"{significant_digits(1e3 * max(position))} mm" if position else ""]
        if axis:
            size.append(f"{significant_digits(max(axis))} deg")
        out.append(f"{text}: {', '.join(t for t in size if t)}")
    return out


def _trace_sigma(V: np.ndarray) -> float:
    """sqrt(trace V) (the 1-sigma norm of a vector with covariance V); NaN stays NaN."""
    t = float(np.trace(V))
    return math.sqrt(max(t, 0.0)) if math.isfinite(t) else math.nan


def _wall_summary(model: CalibrationModel, x: np.ndarray, cov: np.ndarray) -> dict:
    """The wall model, its parameters and the 1-sigma of the estimated ones."""
    lay = model.layout
    wall = lay.wall_of(x)
    out = wall.describe()
    sig: dict[str, float] = {}
    for k, name in enumerate(lay.wall_unknown.estimate):
        s = math.sqrt(max(cov[lay.wall.start + k, lay.wall.start + k], 0.0))
        if name == "sigma":
            sig["sigma_deg"] = math.degrees(s)
        else:
            sig[name] = s
    out["estimated"] = ["sigma_deg" if n == "sigma" else n for n in lay.wall_unknown.estimate]
    out["sigma"] = sig
    return out


def _bound_warnings(model: CalibrationModel, x: np.ndarray) -> list[str]:
    """One line per light whose position ends on the solver's search box."""
    lo, hi = model.parameter_bounds()
    out = []
    for block in model.layout.blocks:
        s = block.pose.start
        hits = []
        for k, axis in enumerate("xyz"):
            v, a, b = x[s + k], lo[s + k], hi[s + k]
            tol = 1e-7 * max(1.0, abs(v))
            if (np.isfinite(a) and v - a <= tol) or (np.isfinite(b) and b - v <= tol):
                hits.append(f"{axis} = {v:+.4f} m")
        if hits:
            out.append(
                f"light {block.unknown.initial.name}: its position ends on the edge of the "
                f"solver's search box ({', '.join(hits)}; solver.position_bound_m = "
                f"{model.options.position_bound_m:g} m, and in front of the wall in every "
                "view): the solve stopped there, not at a minimum; check the initial guess, "
                "the camera poses and the bound"
            )
    return out


_STOP_REASONS = {
    -2: "stopped before convergence",
    -1: "the solver could not start (improper input)",
    0: "the iteration limit was reached before convergence (solver.max_iterations)",
    1: "the gradient vanished (a minimum)",
    2: "the cost stopped decreasing (its relative change, or the change the next "
    "Gauss-Newton step predicts, fell below solver.tolerance)",
    3: "the parameters stopped changing (their relative step fell below solver.tolerance)",
    4: "the cost and the parameters stopped changing (below solver.tolerance)",
}


def stop_reason(status: int, message: str = "") -> str:
    """Why the solve stopped, in plain words (trf's status codes; -2: stopped by the user
    or the app)."""
    if status == 0 and message:
        return message  # lightcal's own words, with the limit that was reached
    return _STOP_REASONS.get(status, message or f"status {status}")
