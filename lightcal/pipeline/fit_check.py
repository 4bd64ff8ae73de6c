"""After a solve: is the fit explained by the noise, and how uncertain is the estimate?

`check_fit` gathers what every pixel says at the solution (`lightcal.pipeline.evidence`),
tests the candidate causes of a misfit (`lightcal.pipeline.cause_check`) and hands all of
it to `lightcal.core.misfit.diagnose`; it combines the pixel noise, the camera poses' and
intrinsics' covariances, the misfit and, when the residuals are not explained by those,
the systematic terms into the parameter covariance (`lightcal.core.uncertainty`;
docs/model.md, "Uncertainty").
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from lightcal.core.albedo_map import with_albedo
from lightcal.core.alternatives import (
    excess_covariance,
    jackknife_covariance,
)
from lightcal.core.footprint import Footprints
from lightcal.core.medium import Medium
from lightcal.core.misfit import FitDiagnosis, diagnose
from lightcal.core.misfit_verdict import significant_digits
from lightcal.core.render import shade
from lightcal.core.scene import View
from lightcal.core.solver import CalibrationModel
from lightcal.core.uncertainty import (
    IntrinsicsBlock,
    IntrinsicsTerms,
    PoseBlock,
    PoseTerms,
    intrinsics_sensitivity,
    intrinsics_terms,
    noise_inflation,
    perturbed_view,
    pose_sensitivity,
    pose_terms,
)
from lightcal.core.wall_flatness import bow_pose_perturbations
from lightcal.pipeline.cause_check import cause_tests, jackknife_ratio, pose_indices
from lightcal.pipeline.evidence import (
    CAUSE_ROWS,
    CHUNK_PIXELS,
    POSE_ROWS,
    ImageRows,
    PixelEvidence,
    TestedRows,
    pixel_evidence,
)
from lightcal.pipeline.measurements import Measurements

__all__ = [
    "CAUSE_ROWS",
    "CHUNK_PIXELS",
    "POSE_ROWS",
    "FitCheck",
    "ImageRows",
    "PixelEvidence",
    "TestedRows",
    "Uncertainty",
    "check_fit",
    "flatness_uncertainty",
    "intrinsics_uncertainty",
    "pixel_evidence",
    "pose_uncertainty",
]


#: Pixels per image used for the camera-pose and intrinsics sensitivities (a seeded random
def _renderer(
    model: CalibrationModel, x: np.ndarray
) -> Callable[[int, View, Footprints], np.ndarray]:
    """(i, view, footprints) -> image i's rendered values at the solution x."""
    lay = model.layout
    gains, offset, wall = lay.gain_factors(x), lay.offset(x), lay.wall_of(x)
    rid_subsamples = model.options.rid_subsamples
    albedo = model.albedo_map(x)

    def render(i: int, view: View, fp: Footprints) -> np.ndarray:
        channel = model.images[i].channel
        rig, medium = lay.rig(x, channel), lay.medium_of(x, channel)

        def through(medium: Medium) -> np.ndarray:
            sh = shade(
                fp, view, rig, offset=0.0, rid_subsamples=rid_subsamples, wall=wall, medium=medium
            )
            lights = float(gains[i]) * sh.values.filled(np.nan)
            return lay.sensor_values(lights, fp, x, float(gains[i]) * view.exposure, channel)

        if albedo is None:
            return offset + through(medium)
        # the wall's albedo where these footprints fall on it
        return offset + with_albedo(through, medium, albedo.factor(fp.centers_world[:, :2]))

    return render


def pose_uncertainty(
    model: CalibrationModel,
    x: np.ndarray,
    meas: Measurements,
    subsets: list[ImageRows],
    normal_inverse: np.ndarray,
) -> PoseTerms | None:
    """The camera poses' share of the covariance and of chi^2 (None without covariances),
    on each image's rows `subsets` (`pixel_evidence`)."""
    if meas.footprints_at is None or all(c is None for c in meas.pose_covariances):
        return None
    render = _renderer(model, x)
    footprints_at = meas.footprints_at
    blocks = []
    for sub in subsets:
        i, rows = sub.image, sub.rows
        cov = meas.pose_covariances[i]
        if cov is None:
            continue

        def render_i(view: View, fp: Footprints, i: int = i) -> np.ndarray:
            return render(i, view, fp)

        def footprints(view: View, i: int = i, rows: np.ndarray = rows) -> Footprints:
            return footprints_at(i, view, rows)

        S = pose_sensitivity(model.images[i].view, render_i, footprints, model.sigmas[i][rows])
        S[~np.all(np.isfinite(S), axis=1)] = 0.0  # pixels a perturbed pose pushes off the wall
        pose = None if meas.poses is None else meas.poses[i]
        blocks.append(PoseBlock(sub.J, S, cov, sub.noise_ratio, sub.row_scale, pose))
    return pose_terms(normal_inverse, blocks)


def flatness_uncertainty(
    model: CalibrationModel,
    x: np.ndarray,
    meas: Measurements,
    subsets: list[ImageRows],
    normal_inverse: np.ndarray,
) -> np.ndarray | None:
    """The wall flatness' share of the covariance (None when the wall is declared flat):
    b^2 dx dx^T, b the declared tolerance and dx the shift of the estimate a dome of unit
    depth causes, through the camera pose errors it is equivalent to
    (`lightcal.core.wall_flatness`): dx = -N^-1 sum_i J_i^T s_i, s_i = d r_i / d b by
    central differences (one perturbed view each way), on each image's rows `subsets`."""
    depth = meas.wall_flatness_m
    if not depth > 0.0 or meas.footprints_at is None:
        return None
    render = _renderer(model, x)
    footprints_at = meas.footprints_at
    points = np.array(
        [
            model.images[s.image].footprints.subset(s.rows).centers_now().mean(axis=0)
            for s in subsets
        ]
    )
    views = [model.images[s.image].view for s in subsets]
    directions = bow_pose_perturbations(views, points)
    h = 1e-4  # a 0.1 mm dome: linear, and far above round-off
    T = np.zeros(model.layout.n)
    for sub, view, dp in zip(subsets, views, directions, strict=True):
        i, rows = sub.image, sub.rows
        values = []
        for sign in (1.0, -1.0):
            v = perturbed_view(view, sign * h * dp)
            values.append(render(i, v, footprints_at(i, v, rows)))
        s = -(values[0] - values[1]) / (2.0 * h) / model.sigmas[i][rows]
        s[~np.isfinite(s)] = 0.0
        T += sub.row_scale * (sub.J.T @ s)
    dx = -normal_inverse @ T
    return depth**2 * np.outer(dx, dx)


def intrinsics_uncertainty(
    model: CalibrationModel,
    x: np.ndarray,
    meas: Measurements,
    subsets: list[ImageRows],
    normal_inverse: np.ndarray,
) -> IntrinsicsTerms | None:
    """The camera intrinsics' share of the covariance and of chi^2 (None without their
    covariance): S_K by central differences, one sigma of each parameter, with the camera
    and every pose (by its d_pose_d_intrinsics) moved and the footprints rebuilt, on each
    image's rows `subsets` (`pixel_evidence`)."""
    cov_K = meas.intrinsics_covariance
    footprints_with = meas.footprints_with
    if cov_K is None or footprints_with is None:
        return None
    p = cov_K.shape[0]
    steps = np.sqrt(np.maximum(np.diag(cov_K), 0.0))
    jacobians = meas.pose_intrinsics_jacobians or [None] * len(model.images)
    render = _renderer(model, x)
    blocks = []
    moved = 0
    for sub in subsets:
        i, rows = sub.image, sub.rows
        D = jacobians[i]
        moved += D is not None
        D_i = np.zeros((6, p)) if D is None else D

        def render_at(
            dK: np.ndarray, i: int = i, D_i: np.ndarray = D_i, rows: np.ndarray = rows
        ) -> np.ndarray:
            view = perturbed_view(model.images[i].view, D_i @ dK)
            return render(i, view, footprints_with(i, dK, view, rows))

        S = intrinsics_sensitivity(render_at, steps, model.sigmas[i][rows])
        S[~np.all(np.isfinite(S), axis=1)] = 0.0  # pixels pushed off the wall
        blocks.append(IntrinsicsBlock(sub.J, S, sub.noise_ratio, sub.row_scale))
    return intrinsics_terms(normal_inverse, cov_K, blocks, poses_moved=moved)


@dataclass(frozen=True)
class Uncertainty:
    """The parameter covariance and what it includes.

    Attributes:
        covariance: (n, n), the sum of `components`.
        terms: the terms included, in words.
        inflation: s^2, the factor on the pixel-noise term (misfit beyond the noise and
            the pose errors).
        pose: the camera poses' terms, or None.
        intrinsics: the camera intrinsics' terms, or None.
        components: (name, (n, n) covariance) of each term, in `terms`' order: "pixel
            noise", "camera poses", "camera intrinsics" (the statistical terms) and
            "systematic: ..." (docs/model.md, "Uncertainty").
    """

    covariance: np.ndarray
    terms: list[str]
    inflation: float
    pose: PoseTerms | None
    intrinsics: IntrinsicsTerms | None = None
    components: list[tuple[str, np.ndarray]] = field(default_factory=list)


def _inverse(A: np.ndarray) -> np.ndarray:
    try:
        return np.linalg.inv(A)
    except np.linalg.LinAlgError:
        return np.linalg.pinv(A)


@dataclass(frozen=True)
class FitCheck:
    """What `check_fit` finds at a solution.

    Attributes:
        diagnosis: the fit test.
        uncertainty: the parameter covariance and its terms.
        light_shares: (L,) each light's share of the rendered values over every pixel
            (`lightcal.pipeline.diagnose.dark_light_warnings`).
    """

    diagnosis: FitDiagnosis
    uncertainty: Uncertainty
    light_shares: np.ndarray


def check_fit(model: CalibrationModel, x: np.ndarray, meas: Measurements) -> FitCheck:
    """The fit diagnosis and the parameter covariance at the solution x.

    Every pixel is rendered once (`pixel_evidence`); the pose and intrinsics
    sensitivities then render their rows under perturbed cameras. The covariance is the
    statistical terms (pixel noise, camera poses, intrinsics) and, when the residuals
    are not explained by them, the systematic terms: each significant cause's shift
    dx dx^T and the leave-one-image-out jackknife's excess over the statistical
    covariance (docs/model.md, "Uncertainty").
    """
    ev = pixel_evidence(model, x, meas, noise_middle=meas.noise_source == "image")
    n = model.layout.n
    dof = model.m - n
    N = _inverse(model.normal_matrix(x))  # cached at x by the pass above
    pose = pose_uncertainty(model, x, meas, ev.subsets, N)
    intrinsics = intrinsics_uncertainty(model, x, meas, ev.subsets, N)
    extra = pose.expected_chi2_extra if pose is not None else 0.0
    extra += intrinsics.expected_chi2_extra if intrinsics is not None else 0.0
    chi2 = float(ev.r_noise @ ev.r_noise)
    known = meas.noise_source != "none"
    s2 = noise_inflation(chi2, dof, extra, sigma_is_noise=known)
    terms = []
    if meas.noise_source == "model":
        noise_cov = N
        terms.append("pixel noise (the sensor's noise model)")
    elif meas.noise_source == "image":
        # The solver's weights are not the noise: the sandwich N J^T W J N, W = 1 / ratio^2.
        assert ev.noise_middle is not None
        noise_cov = N @ ev.noise_middle @ N
        terms.append("pixel noise (estimated from the images)")
    else:
        noise_cov = N
        terms.append("pixel noise (the residuals' variance)")
    if known and math.sqrt(s2) >= 1.005:
        terms[-1] += f", inflated x{math.sqrt(s2):.2f} by the misfit"
    components: list[tuple[str, np.ndarray]] = [("pixel noise", s2 * noise_cov)]
    if pose is not None:
        components.append(("camera poses", pose.covariance))
        terms.append(f"camera poses ({pose.images} images' marker-fit covariances)")
    if intrinsics is not None:
        components.append(("camera intrinsics", intrinsics.covariance))
        terms.append(
            f"camera intrinsics ({intrinsics.parameters} parameters' calibration covariance, "
            f"{intrinsics.poses_moved} of {intrinsics.images} images' poses moved with them)"
        )
    flatness = flatness_uncertainty(model, x, meas, ev.subsets, N)
    if flatness is not None:
        components.append(("wall flatness", flatness))
        terms.append(
            f"wall flatness (a dome of {significant_digits(1e3 * meas.wall_flatness_m)} mm, "
            "`wall.flatness_mm`)"
        )
    statistical = sum((c for _, c in components), np.zeros((n, n)))
    P = pose_indices(model)
    causes, shifts = cause_tests(model, x, ev, statistical[np.ix_(P, P)], extra)
    jack = jackknife_covariance(
        model.normal_matrix(x), [(N_i, g_i) for N_i, g_i, _ in ev.image_grams]
    )
    jack_ratio = jackknife_ratio(jack, statistical, P)
    expected = dof + max(extra, 0.0)
    beyond = max(0.0, 1.0 - expected / chi2) if known and chi2 > 0 else math.nan
    excess_relative = math.sqrt(ev.residual2 * beyond / ev.signal2) if ev.signal2 > 0 else math.nan
    diagnosis = diagnose(
        ev.r_noise,
        ev.relative,
        ev.mirror_deg,
        ev.incidence_deg,
        n_params=n,
        noise_source=meas.noise_source,
        wall_model=model.layout.wall_unknown.initial.name,
        expected_extra=extra,
        signal=ev.signal,
        causes=causes,
        excess_relative=excess_relative,
        jackknife_ratio=jack_ratio,
    )
    if not diagnosis.explained:
        for c in causes:
            if c.significant and c.name in shifts:
                dx = shifts[c.name]
                components.append((f"systematic: {c.name}", np.outer(dx, dx)))
                terms.append(
                    f"systematic: the shift the {c.name} cause accounts for ({c.describe()})"
                )
        if jack is not None:
            components.append(("systematic: jackknife", excess_covariance(jack, statistical)))
            terms.append(
                "systematic: the leave-one-image-out jackknife's spread beyond the "
                f"statistical terms ({significant_digits(jack_ratio)}x their sigma in the "
                "pose's worst direction)"
            )
    cov = sum((c for _, c in components), np.zeros((n, n)))
    unc = Uncertainty(0.5 * (cov + cov.T), terms, s2, pose, intrinsics, components)
    return FitCheck(diagnosis, unc, ev.light_shares)
