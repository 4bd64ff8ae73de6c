"""The outcome of a calibration: per-light poses with 1-sigma uncertainties, the
fitted scales, gains and offset, the warnings, and `summarise`, which builds it."""

from __future__ import annotations

import functools
import math
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from lightcal.core.pose import describe_pose
from lightcal.core.rid import CosPowerRID
from lightcal.core.solver import CalibrationModel, IterationReport, SolveOutcome
from lightcal.pipeline.diagnose import covariance, dark_light_warnings, variety_warnings


@dataclass(frozen=True)
class LightResult:
    """One calibrated light.

    Attributes:
        name: the light's name.
        pose: `describe_pose` output (position_m, R_camera_light, quaternion_wxyz,
            axis_camera, roll_deg, pitch_deg, axis_angle_from_optical_axis_deg).
        sigma: 1-sigma of the same quantities (same keys; position and vectors per component).
        scale, scale_sigma: the fitted scale.
        pose_kind: isotropic, symmetric or general.
        rid: estimated RID description (None when the RID was given).
    """

    name: str
    pose: dict
    sigma: dict
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


def _pose_vector(model: CalibrationModel, j: int, x: np.ndarray) -> np.ndarray:
    block = model.layout.blocks[j]
    R, t = block.param.to_pose(x[block.pose])
    d = describe_pose(R, t)
    return np.concatenate(
        [
            d["position_m"],
            np.ravel(d["R_camera_light"]),
            d["quaternion_wxyz"],
            d["axis_camera"],
            [d["roll_deg"], d["pitch_deg"], d["axis_angle_from_optical_axis_deg"]],
        ]
    )


def _split_pose_vector(v: np.ndarray) -> dict:
    return {
        "position_m": v[0:3].tolist(),
        "R_camera_light": v[3:12].reshape(3, 3).tolist(),
        "quaternion_wxyz": v[12:16].tolist(),
        "axis_camera": v[16:19].tolist(),
        "roll_deg": float(v[19]),
        "pitch_deg": float(v[20]),
        "axis_angle_from_optical_axis_deg": float(v[21]),
    }


def summarise(model: CalibrationModel, outcome: SolveOutcome) -> CalibrationResult:
    """Turn a solve into a `CalibrationResult` with uncertainties and warnings."""
    x = outcome.x
    cov = covariance(model, x)
    lay = model.layout
    lights = []
    for j, block in enumerate(lay.blocks):
        v = _pose_vector(model, j, x)
        G = _numeric_jacobian(functools.partial(_pose_vector, model, j), x)
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
                _split_pose_vector(v),
                _split_pose_vector(sig),
                scale,
                scale * math.sqrt(max(cov[block.log_scale, block.log_scale], 0.0)),
                block.param.kind,
                rid_desc,
            )
        )
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
        converged=outcome.success,
        cost=outcome.cost,
        time_s=outcome.time_s,
        warnings=dark_light_warnings(model, x) + variety_warnings(model, cov),
        parameter_names=list(lay.names),
        x=x.tolist(),
        covariance=cov.tolist(),
        history=outcome.history,
    )
