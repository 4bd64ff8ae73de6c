"""After a solve: is the fit explained by the noise, and how uncertain is the estimate?

`check_fit` gathers, per selected pixel, the residual in noise units, the relative
residual and the mirror and incidence angles at the solution, and hands them to
`lightcal.core.misfit.diagnose`; `estimate_uncertainty` combines the pixel noise, the
camera poses' and intrinsics' covariances and the misfit into the parameter covariance
(`lightcal.core.uncertainty`; docs/model.md, "Uncertainty").
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterator
from dataclasses import dataclass

import numpy as np

from lightcal.core.footprint import Footprints
from lightcal.core.misfit import FitDiagnosis, diagnose, pixel_angles
from lightcal.core.problem import poisson_gaussian_sigma
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
from lightcal.pipeline.measurements import Measurements

#: Pixels per image used for the camera-pose and intrinsics sensitivities (a seeded random
#: subset; the sums it enters are scaled to the image's pixel count).
POSE_ROWS = 3000


@dataclass(frozen=True)
class PixelEvidence:
    """Per selected pixel of every image, at the solution (model image order, concatenated).

    Attributes:
        r_noise: (m,) residuals in noise units (solver units when the noise is unknown).
        relative: (m,) (m_obs - m_render) / m_render.
        mirror_deg, incidence_deg: (m,) angles of the brightest light at each pixel.
        noise_ratio: per image (N_i,) solver sigma / noise sigma.
    """

    r_noise: np.ndarray
    relative: np.ndarray
    mirror_deg: np.ndarray
    incidence_deg: np.ndarray
    noise_ratio: list[np.ndarray]


def pixel_evidence(model: CalibrationModel, x: np.ndarray, meas: Measurements) -> PixelEvidence:
    """The residuals and angles `check_fit` tests (see `PixelEvidence`)."""
    lay = model.layout
    r_w = model.residuals(x)
    rig, gains, offset, wall = lay.rig(x), lay.gain_factors(x), lay.offset(x), lay.wall_of(x)
    scales = np.array([light.scale for light in rig.lights])
    # Filled image by image (lists of parts and their concatenation held every figure
    # twice: 0.6 GB for a dense 9.5 M pixel problem).
    r_noise, relative, mirror, incidence = (np.empty(model.m) for _ in range(4))
    ratios = []
    for i, im in enumerate(model.images):
        rows = slice(model.bounds[i], model.bounds[i + 1])
        d = r_w[rows] * model.sigmas[i]
        rendered = im.observed - d
        noise = meas.noise[i]
        sigma_n = (
            model.sigmas[i] if noise is None else poisson_gaussian_sigma(rendered - offset, noise)
        )
        ratios.append(model.sigmas[i] / sigma_n)
        r_noise[rows] = d / sigma_n
        with np.errstate(divide="ignore", invalid="ignore"):
            relative[rows] = np.where(rendered - offset > 0, d / (rendered - offset), 0.0)
        flux = shade(im.footprints, im.view, rig, wall=wall).flux * scales[:, None] * gains[i]
        brightest = np.argmax(flux, axis=0)
        del flux
        centers = im.footprints.centers_now()  # not kept: 24 bytes a pixel
        mirror_i = mirror[rows]
        incidence_i = incidence[rows]
        for j, light in enumerate(rig.lights):
            sel = brightest == j
            if sel.any():
                mirror_i[sel], incidence_i[sel] = pixel_angles(
                    centers[sel], light.position_world(im.view), im.view.center_world
                )
    return PixelEvidence(r_noise, relative, mirror, incidence, ratios)


def _image_subsets(
    model: CalibrationModel, x: np.ndarray, seed: int
) -> Iterator[tuple[int, np.ndarray, np.ndarray, float]]:
    """Per image: (i, J_i, rows, row_scale), rows the seeded subset (at most `POSE_ROWS`)
    the sensitivities use and row_scale = N_i / len(rows)."""
    for i, J_i in model.image_jacobians(x):
        n_i = len(model.images[i].observed)
        rows = np.arange(n_i)
        if n_i > POSE_ROWS:
            rows = np.sort(np.random.default_rng([seed, i]).choice(n_i, POSE_ROWS, replace=False))
        yield i, J_i, rows, n_i / rows.size


def _renderer(
    model: CalibrationModel, x: np.ndarray
) -> Callable[[int, View, Footprints], np.ndarray]:
    """(i, view, footprints) -> image i's rendered values at the solution x."""
    lay = model.layout
    rig, gains, offset, wall = lay.rig(x), lay.gain_factors(x), lay.offset(x), lay.wall_of(x)
    rid_subsamples = model.options.rid_subsamples

    def render(i: int, view: View, fp: Footprints) -> np.ndarray:
        sh = shade(fp, view, rig, offset=0.0, rid_subsamples=rid_subsamples, wall=wall)
        return offset + float(gains[i]) * sh.values.filled(np.nan)

    return render


def pose_uncertainty(
    model: CalibrationModel,
    x: np.ndarray,
    meas: Measurements,
    ratios: list[np.ndarray],
    normal_inverse: np.ndarray,
    *,
    seed: int = 0,
) -> PoseTerms | None:
    """The camera poses' share of the covariance and of chi^2 (None without covariances)."""
    if meas.footprints_at is None or all(c is None for c in meas.pose_covariances):
        return None
    render = _renderer(model, x)
    footprints_at = meas.footprints_at
    blocks = []
    for i, J_i, rows, row_scale in _image_subsets(model, x, seed):
        cov = meas.pose_covariances[i]
        if cov is None:
            continue

        def render_i(view: View, fp: Footprints, i: int = i) -> np.ndarray:
            return render(i, view, fp)

        def footprints(view: View, i: int = i, rows: np.ndarray = rows) -> Footprints:
            return footprints_at(i, view, rows)

        S = pose_sensitivity(model.images[i].view, render_i, footprints, model.sigmas[i][rows])
        S[~np.all(np.isfinite(S), axis=1)] = 0.0  # pixels a perturbed pose pushes off the wall
        blocks.append(PoseBlock(J_i[rows], S, cov, ratios[i][rows], row_scale))
    return pose_terms(normal_inverse, blocks)


def intrinsics_uncertainty(
    model: CalibrationModel,
    x: np.ndarray,
    meas: Measurements,
    ratios: list[np.ndarray],
    normal_inverse: np.ndarray,
    *,
    seed: int = 0,
) -> IntrinsicsTerms | None:
    """The camera intrinsics' share of the covariance and of chi^2 (None without their
    covariance): S_K by central differences, one sigma of each parameter, with the camera
    and every pose (by its d_pose_d_intrinsics) moved and the footprints rebuilt."""
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
    for i, J_i, rows, row_scale in _image_subsets(model, x, seed):
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
        blocks.append(IntrinsicsBlock(J_i[rows], S, ratios[i][rows], row_scale))
    return intrinsics_terms(normal_inverse, cov_K, blocks, poses_moved=moved)


@dataclass(frozen=True)
class Uncertainty:
    """The parameter covariance and what it includes.

    Attributes:
        covariance: (n, n).
        terms: the terms included, in words.
        inflation: s^2, the factor on the pixel-noise term (misfit beyond the noise and
            the pose errors).
        pose: the camera poses' terms, or None.
        intrinsics: the camera intrinsics' terms, or None.
    """

    covariance: np.ndarray
    terms: list[str]
    inflation: float
    pose: PoseTerms | None
    intrinsics: IntrinsicsTerms | None = None


def _inverse(A: np.ndarray) -> np.ndarray:
    try:
        return np.linalg.inv(A)
    except np.linalg.LinAlgError:
        return np.linalg.pinv(A)


def check_fit(
    model: CalibrationModel, x: np.ndarray, meas: Measurements
) -> tuple[FitDiagnosis, Uncertainty]:
    """The fit diagnosis and the parameter covariance at the solution x."""
    ev = pixel_evidence(model, x, meas)
    n = model.layout.n
    dof = model.m - n
    N = _inverse(model.normal_matrix(x))
    pose = pose_uncertainty(model, x, meas, ev.noise_ratio, N)
    intrinsics = intrinsics_uncertainty(model, x, meas, ev.noise_ratio, N)
    extra = pose.expected_chi2_extra if pose is not None else 0.0
    extra += intrinsics.expected_chi2_extra if intrinsics is not None else 0.0
    chi2 = float(ev.r_noise @ ev.r_noise)
    known = meas.noise_source != "none"
    diagnosis = diagnose(
        ev.r_noise,
        ev.relative,
        ev.mirror_deg,
        ev.incidence_deg,
        n_params=n,
        noise_source=meas.noise_source,
        wall_model=model.layout.wall_unknown.initial.name,
        expected_extra=extra,
    )
    s2 = noise_inflation(chi2, dof, extra, sigma_is_noise=known)
    terms = []
    if meas.noise_source == "model":
        noise_cov = N
        terms.append("pixel noise (the sensor's noise model)")
    elif meas.noise_source == "image":
        # The solver's weights are not the noise: the sandwich N J^T W J N, W = 1 / ratio^2.
        middle = np.zeros((n, n))
        for i, J_i in model.image_jacobians(x):
            w = 1.0 / ev.noise_ratio[i] ** 2
            middle += (J_i * w[:, None]).T @ J_i
        noise_cov = N @ middle @ N
        terms.append("pixel noise (estimated from the images)")
    else:
        noise_cov = N
        terms.append("pixel noise (the residuals' variance)")
    cov = s2 * noise_cov
    if pose is not None:
        cov = cov + pose.covariance
        terms.append(f"camera poses ({pose.images} images' marker-fit covariances)")
    if intrinsics is not None:
        cov = cov + intrinsics.covariance
        terms.append(
            f"camera intrinsics ({intrinsics.parameters} parameters' calibration covariance, "
            f"{intrinsics.poses_moved} of {intrinsics.images} images' poses moved with them)"
        )
    if known and math.sqrt(s2) >= 1.005:
        terms.append(f"misfit: the noise term inflated x{math.sqrt(s2):.2f} in sigma")
    return diagnosis, Uncertainty(0.5 * (cov + cov.T), terms, s2, pose, intrinsics)
