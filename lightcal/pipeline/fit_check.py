"""After a solve: is the fit explained by the noise, and how uncertain is the estimate?

`check_fit` gathers, per selected pixel, the residual in noise units, the relative
residual and the mirror and incidence angles at the solution, and hands them to
`lightcal.core.misfit.diagnose`; `estimate_uncertainty` combines the pixel noise, the
camera poses' and intrinsics' covariances and the misfit into the parameter covariance
(`lightcal.core.uncertainty`; docs/model.md, "Uncertainty").
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from lightcal.core.footprint import Footprints
from lightcal.core.misfit import FitDiagnosis, diagnose
from lightcal.core.misfit_kernels import add_weighted_gram, mirror_incidence, noise_residuals
from lightcal.core.render import shade
from lightcal.core.scene import Light, View
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
class ImageRows:
    """One image's seeded subset of rows (at most `POSE_ROWS`), where the camera-pose and
    intrinsics sensitivities are computed.

    Attributes:
        image: the image's index in the model.
        rows: (k,) sorted row indices into the image's pixels.
        J: (k, n) those rows of the weighted Jacobian d r / d x at the solution.
        noise_ratio: (k,) their solver sigma / noise sigma.
        row_scale: N_i / k (sums over the subset are scaled by it).
    """

    image: int
    rows: np.ndarray
    J: np.ndarray
    noise_ratio: np.ndarray
    row_scale: float


@dataclass(frozen=True)
class PixelEvidence:
    """Per selected pixel of every image, at the solution (model image order, concatenated),
    and what the uncertainty needs of every pixel, all from one pass over the images.

    Attributes:
        r_noise: (m,) residuals in noise units (solver units when the noise is unknown).
        relative: (m,) float32 (m_obs - m_render) / m_render.
        mirror_deg, incidence_deg: (m,) float32 angles of the brightest light at each
            pixel, degrees.
        subsets: per image, the rows of the pose and intrinsics sensitivities.
        noise_middle: (n, n) sum_i J_i^T W_i J_i with W_i = 1 / noise_ratio^2 (the
            noise covariance's sandwich when the solver's weights are not the noise),
            or None when not asked for.
        light_shares: (L,) each light's share of the rendered values, summed over the
            pixels (`dark_light_warnings`).
    """

    r_noise: np.ndarray
    relative: np.ndarray
    mirror_deg: np.ndarray
    incidence_deg: np.ndarray
    subsets: list[ImageRows]
    noise_middle: np.ndarray | None
    light_shares: np.ndarray


def pixel_evidence(
    model: CalibrationModel,
    x: np.ndarray,
    meas: Measurements,
    *,
    noise_middle: bool = False,
    seed: int = 0,
) -> PixelEvidence:
    """The residuals and angles `check_fit` tests and the rows the sensitivities use (see
    `PixelEvidence`), in one evaluation at x (`CalibrationModel.evaluate_visiting`): the
    residuals, J^T J, each pixel's Jacobian row and each light's flux are rendered once.

    Args:
        noise_middle: also sum J_i^T W_i J_i (`PixelEvidence.noise_middle`).
        seed: seeds each image's row subset.
    """
    lay = model.layout
    n = lay.n
    rig, gains, offset = lay.rig(x), lay.gain_factors(x), lay.offset(x)
    scales = np.array([light.scale for light in rig.lights])
    # Filled image by image (lists of parts and their concatenation held every figure
    # twice: 0.6 GB for a dense 9.5 M pixel problem). The angles and relative residuals
    # only choose and fill the diagnosis' bins: float32 (angles to 4e-6 degrees, relative
    # residuals to 6e-8 of their value) saves 12 bytes a pixel; r_noise enters chi^2.
    r_noise = np.empty(model.m)
    relative, mirror, incidence = (np.empty(model.m, dtype=np.float32) for _ in range(3))
    subsets: list[ImageRows] = []
    middle = np.zeros((n, n)) if noise_middle else None
    shares = [np.zeros(len(rig.lights))]

    def visit(i: int, A: np.ndarray, fluxes: np.ndarray) -> None:
        rows = slice(model.bounds[i], model.bounds[i + 1])
        n_i = A.shape[0]
        noise = meas.noise[i]
        ratio = np.empty(n_i)
        noise_residuals(
            A[:, n],
            model.sigmas[i],
            model.images[i].observed,
            offset,
            np.empty(0) if noise is None else np.array(noise, dtype=np.float64),
            r_noise[rows],
            relative[rows],
            ratio,
        )
        shares[0] = shares[0] + gains[i] * scales * fluxes.sum(axis=1)
        lit = fluxes * scales[:, None] * gains[i]
        _angles(model, i, rig.lights, lit, mirror[rows], incidence[rows])
        subset = np.arange(n_i)
        if n_i > POSE_ROWS:
            rng = np.random.default_rng([seed, i])
            subset = np.sort(rng.choice(n_i, POSE_ROWS, replace=False))
        subsets.append(ImageRows(i, subset, A[subset, :n], ratio[subset], n_i / subset.size))
        if middle is not None:
            add_weighted_gram(A, n, ratio, middle)

    model.evaluate_visiting(x, visit)
    model.release_buffers()  # not needed by the checks that follow
    return PixelEvidence(r_noise, relative, mirror, incidence, subsets, middle, shares[0])


def _angles(
    model: CalibrationModel,
    i: int,
    lights: tuple[Light, ...],
    lit: np.ndarray,
    mirror: np.ndarray,
    incidence: np.ndarray,
) -> None:
    """Write the mirror and incidence angles (N_i,) of image i's pixels, each for the
    light that gives it the most of its value (lit (L, N_i))."""
    im = model.images[i]
    lights_world = np.array([light.position_world(im.view) for light in lights])
    for c in _chunks(len(im.footprints)):  # chunks bound the centres' temporaries
        centers = im.footprints.subset(c).centers_now()
        mirror_incidence(
            centers, lights_world, lit[:, c], im.view.center_world, mirror[c], incidence[c]
        )


#: Pixels per chunk of the checks' per-pixel work (its temporaries: a few MB each).
CHUNK_PIXELS = 1 << 16


def _chunks(n: int) -> list[slice]:
    """Slices of at most CHUNK_PIXELS covering range(n)."""
    return [slice(k, min(n, k + CHUNK_PIXELS)) for k in range(0, n, CHUNK_PIXELS)]


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
        blocks.append(PoseBlock(sub.J, S, cov, sub.noise_ratio, sub.row_scale))
    return pose_terms(normal_inverse, blocks)


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
    sensitivities then render their rows under perturbed cameras.
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
        assert ev.noise_middle is not None
        noise_cov = N @ ev.noise_middle @ N
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
    unc = Uncertainty(0.5 * (cov + cov.T), terms, s2, pose, intrinsics)
    return FitCheck(diagnosis, unc, ev.light_shares)
