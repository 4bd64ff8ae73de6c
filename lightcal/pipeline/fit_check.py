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
from dataclasses import dataclass, field, replace

import numpy as np

from lightcal.core.alternatives import (
    AlternativeFit,
    GramBlocks,
    RowSet,
    excess_covariance,
    fit_alternative,
    gram_of_columns,
    jackknife_covariance,
    mahalanobis,
)
from lightcal.core.footprint import Footprints
from lightcal.core.misfit import CauseTest, FitDiagnosis, diagnose, significant_digits
from lightcal.core.misfit_causes import PixelFeatures, cause_columns
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
        image_grams: per image, (J_i^T J_i (n, n), J_i^T r_i (n,), J_i^T diag(sigma^2)
            J_i (n, n)) over all its pixels (solver units): the jackknife and the
            `images` cause.
        signal: (m,) float32 m_render - offset (every light).
        signal2: sum over every pixel of (m_render - offset)^2.
        residual2: sum over every pixel of (m_obs - m_render)^2 (value units).
        tested: the rows the other causes are tested on (`TestedRows`).
    """

    r_noise: np.ndarray
    relative: np.ndarray
    mirror_deg: np.ndarray
    incidence_deg: np.ndarray
    subsets: list[ImageRows]
    noise_middle: np.ndarray | None
    light_shares: np.ndarray
    image_grams: list[tuple[np.ndarray, np.ndarray, np.ndarray]]
    signal: np.ndarray
    signal2: float
    residual2: float
    tested: TestedRows


#: Most pixels per image the candidate causes of a misfit are tested on (a seeded subset).
CAUSE_ROWS = 10_000


@dataclass(frozen=True)
class TestedRows:
    """The rows the candidate causes are tested on (`lightcal.core.alternatives`), every
    image's seeded subset of at most `CAUSE_ROWS` concatenated.

    Attributes:
        J: (k, n) the weighted Jacobian's rows, solver units.
        r: (k,) the weighted residuals.
        sigma: (k,) the solver's sigmas (value units per solver unit).
        features: what the causes' patterns need of these pixels.
    """

    J: np.ndarray
    r: np.ndarray
    sigma: np.ndarray
    features: PixelFeatures


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
    grams: list[tuple[np.ndarray, np.ndarray, np.ndarray]] = []
    signal_all = np.empty(model.m, dtype=np.float32)
    sums = [0.0, 0.0]  # signal^2, residual^2

    def exposure(i: int) -> float:
        return float(model.images[i].view.exposure)

    tested_J: list[np.ndarray] = []
    tested_r: list[np.ndarray] = []
    tested_sigma: list[np.ndarray] = []
    tested_features: list[PixelFeatures] = []

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
        J_i, r_i, sigma_i = A[:, :n], A[:, n], model.sigmas[i]
        Js = J_i * sigma_i[:, None]
        grams.append((J_i.T @ J_i, J_i.T @ r_i, Js.T @ Js))
        signal = lit.sum(axis=0)
        signal_all[rows] = signal
        residual = r_i * sigma_i
        sums[0] += float(signal @ signal)
        sums[1] += float(residual @ residual)
        rows_c = np.arange(n_i)
        if n_i > CAUSE_ROWS:
            rng = np.random.default_rng([seed, i, 1])
            rows_c = np.sort(rng.choice(n_i, CAUSE_ROWS, replace=False))
        tested_J.append(J_i[rows_c].copy())
        tested_r.append(r_i[rows_c].copy())
        tested_sigma.append(sigma_i[rows_c])
        tested_features.append(
            _features(model, i, rig.lights, lit[:, rows_c], rows_c, gains[i] * exposure(i))
        )

    model.evaluate_visiting(x, visit)
    model.release_buffers()  # not needed by the checks that follow
    tested = TestedRows(
        np.concatenate(tested_J) if tested_J else np.zeros((0, n)),
        np.concatenate(tested_r) if tested_r else np.zeros(0),
        np.concatenate(tested_sigma) if tested_sigma else np.zeros(0),
        PixelFeatures.concatenate(tested_features) if tested_features else _no_features(),
    )
    return PixelEvidence(
        r_noise,
        relative,
        mirror,
        incidence,
        subsets,
        middle,
        shares[0],
        grams,
        signal_all,
        sums[0],
        sums[1],
        tested,
    )


def _no_features() -> PixelFeatures:
    z = np.zeros(0)
    return PixelFeatures(z, z, np.zeros((0, 2)), np.zeros((0, 3)), np.zeros((0, 3)), z, z, z, z)


def _features(
    model: CalibrationModel,
    i: int,
    lights: tuple[Light, ...],
    lit: np.ndarray,
    rows: np.ndarray,
    gain: float,
) -> PixelFeatures:
    """The cause patterns' inputs (`PixelFeatures`) at rows (k,) of image i, lit (L, k)
    each light's value there; each pixel's light is the one that gives it the most."""
    im = model.images[i]
    view = im.view
    centers = im.footprints.subset(rows).centers_now()
    brightest = np.argmax(lit, axis=0) if lit.shape[0] > 1 else np.zeros(rows.size, dtype=int)
    lights_world = np.array([light.position_world(view) for light in lights])
    axes_world = np.array([light.rotation_world(view)[:, 2] for light in lights])
    to_light = lights_world[brightest] - centers
    d_light = np.linalg.norm(to_light, axis=1)
    to_camera = view.center_world[None, :] - centers
    d_camera = np.linalg.norm(to_camera, axis=1)
    cos_light = np.einsum("ij,ij->i", -to_light, axes_world[brightest]) / d_light
    ray_camera = (centers - view.center_world[None, :]) @ view.R_camera_world.T
    field_tan2 = (ray_camera[:, 0] ** 2 + ray_camera[:, 1] ** 2) / ray_camera[:, 2] ** 2
    return PixelFeatures(
        signal=lit.sum(axis=0),
        gain=np.full(rows.size, gain),
        wall_xy=centers[:, :2].copy(),
        to_light=to_light / d_light[:, None],
        to_camera=to_camera / d_camera[:, None],
        d_light=d_light,
        d_camera=d_camera,
        light_angle=np.arccos(np.clip(cos_light, -1.0, 1.0)),
        field_tan2=field_tan2,
    )


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


def pose_indices(model: CalibrationModel) -> np.ndarray:
    """The indices of every light's pose parameters in the model's x."""
    return np.concatenate(
        [np.arange(b.pose.start, b.pose.stop) for b in model.layout.blocks]
    ).astype(np.int64)


def pose_shift(model: CalibrationModel, x: np.ndarray, dx: np.ndarray) -> tuple[float, float]:
    """The largest light position (m) and axis (deg) change from x to x + dx."""
    lay = model.layout
    position, axis = 0.0, 0.0
    x1 = x + dx
    for block in lay.blocks:
        R0, t0 = block.param.to_pose(x[block.pose])
        R1, t1 = block.param.to_pose(x1[block.pose])
        position = max(position, float(np.linalg.norm(t1 - t0)))
        c = float(np.clip(R0[:, 2] @ R1[:, 2], -1.0, 1.0))
        axis = max(axis, math.degrees(math.acos(c)))
    return position, axis


def _image_cause(
    ev: PixelEvidence, N: np.ndarray, P: np.ndarray, rss: float, m: int
) -> AlternativeFit:
    """The `images` cause: every image its own deviation of the lights' pose parameters P
    (columns J_i[:, P] on image i's rows only), on every pixel."""
    grams = ev.image_grams
    k = P.size
    K = len(grams)
    n = N.shape[0]
    StS = np.zeros((K * k, K * k))
    CtC = np.zeros((K * k, K * k))
    StJ = np.zeros((K * k, n))
    CtK = np.zeros((K * k, n))
    KtK = np.zeros((n, n))
    Str = np.zeros(K * k)
    g = np.zeros(n)
    for i, (N_i, g_i, H_i) in enumerate(grams):
        block = slice(i * k, (i + 1) * k)
        StS[block, block] = N_i[np.ix_(P, P)]
        CtC[block, block] = H_i[np.ix_(P, P)]
        StJ[block] = N_i[P]
        CtK[block] = H_i[P]
        KtK += H_i
        Str[block] = g_i[P]
        g += g_i
    rows = RowSet(N, g, rss, m, ev.signal2)
    return fit_alternative(rows, GramBlocks(StS, StJ, Str, CtC, CtK, KtK))


def cause_tests(
    model: CalibrationModel,
    x: np.ndarray,
    ev: PixelEvidence,
    statistical_pose_cov: np.ndarray,
    expected_extra: float,
) -> tuple[list[CauseTest], dict[str, np.ndarray]]:
    """Every candidate cause of a misfit fitted beside the model
    (`lightcal.core.alternatives`), and each one's shift of x (n,).

    The causes of `misfit_causes.cause_columns` are tested on the seeded rows
    `ev.tested`; `images` on every pixel, its cost decrease less what the camera poses'
    declared errors leave (`expected_extra`: they make each image want its own pose)."""
    P = pose_indices(model)
    t = ev.tested
    out: list[CauseTest] = []
    shifts: dict[str, np.ndarray] = {}
    if t.r.size > model.layout.n + 1:
        rows = RowSet(
            t.J.T @ t.J,
            t.J.T @ t.r,
            float(t.r @ t.r),
            int(t.r.size),
            float(t.features.signal @ t.features.signal),
        )
        for name, (C, signs) in cause_columns(t.features).items():
            S = C / t.sigma[:, None]
            fit = fit_alternative(rows, gram_of_columns(S, t.J, t.r, t.sigma, signs))
            out.append(_cause_test(model, x, name, fit, statistical_pose_cov, P))
            shifts[name] = fit.shift
    N_full = model.normal_matrix(x)
    r_full = model.residuals(x)
    rss = float(r_full @ r_full)
    fit = _image_cause(ev, N_full, P, rss, model.m)
    if fit.k > 0:
        adjusted = max(fit.delta_chi2 - max(expected_extra, 0.0), 0.0)
        if adjusted != fit.delta_chi2:
            dof2 = model.m - model.layout.n - fit.k
            rss1 = max(rss - fit.delta_chi2, 1e-300)
            f_stat = (adjusted / fit.k) / (rss1 / dof2)
            from scipy import special

            fit = replace(
                fit,
                delta_chi2=adjusted,
                f_statistic=f_stat,
                p_value=float(special.fdtrc(fit.k, dof2, f_stat)),
            )
    out.append(
        CauseTest(
            "images",
            fit.k,
            fit.delta_chi2,
            fit.f_statistic,
            fit.p_value,
            fit.relative_effect,
            fit.bic_gain,
            math.nan,
            math.nan,
            math.nan,
        )
    )
    return out, shifts


def _cause_test(
    model: CalibrationModel,
    x: np.ndarray,
    name: str,
    fit: AlternativeFit,
    statistical_pose_cov: np.ndarray,
    P: np.ndarray,
) -> CauseTest:
    position, axis = pose_shift(model, x, fit.shift)
    return CauseTest(
        name,
        fit.k,
        fit.delta_chi2,
        fit.f_statistic,
        fit.p_value,
        fit.relative_effect,
        fit.bic_gain,
        mahalanobis(fit.shift[P], statistical_pose_cov),
        position,
        axis,
    )


def _jackknife_ratio(jack: np.ndarray | None, statistical: np.ndarray, P: np.ndarray) -> float:
    """sqrt of the largest generalised eigenvalue of the jackknife's pose block over the
    statistical one: how many statistical sigmas the jackknife's sigma is in the pose's
    worst direction (NaN without a jackknife)."""
    if jack is None:
        return math.nan
    excess = jack[np.ix_(P, P)]
    c = statistical[np.ix_(P, P)]
    w, U = np.linalg.eigh(0.5 * (c + c.T))
    top = float(w.max()) if w.size else 0.0
    if not top > 0.0:
        return math.nan
    keep = w > 1e-12 * top
    W = U[:, keep] / np.sqrt(w[keep])
    lam = np.linalg.eigvalsh(W.T @ excess @ W)
    return float(math.sqrt(max(float(lam.max()), 0.0)))


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
    statistical = sum((c for _, c in components), np.zeros((n, n)))
    P = pose_indices(model)
    causes, shifts = cause_tests(model, x, ev, statistical[np.ix_(P, P)], extra)
    jack = jackknife_covariance(
        model.normal_matrix(x), [(N_i, g_i) for N_i, g_i, _ in ev.image_grams]
    )
    jack_ratio = _jackknife_ratio(jack, statistical, P)
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
