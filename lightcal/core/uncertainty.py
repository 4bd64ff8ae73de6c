"""The light's uncertainty: pixel noise, camera-pose and intrinsics error and misfit, propagated.

A calibration's estimate x minimises |r(x, p)|^2, r the weighted residuals and p the
camera poses, which are themselves measured (markers, SfM) with covariances Sigma_i.
To first order, an error dp_i in image i's pose moves the estimate by

    dx = -(J^T J)^-1 J_i^T S_i dp_i,    S_i = d r_i / d p_i  (N_i, 6),

so the covariance of x is

    Cov(x) = s^2 (J^T J)^-1  +  sum_i G_i Sigma_i G_i^T,   G_i = (J^T J)^-1 J_i^T S_i.

The first term is the pixel noise; s^2 inflates it by the misfit (below). The pose
parameterisation is that of `PoseSpec.covariance`: (delta, c), delta a rotation
perturbation R -> exp(delta) R in the camera frame and c the camera centre (world, m).
S_i is computed by central differences of the renderer (new footprints for each
perturbed pose), 12 renders per image.

The camera's intrinsics K (fx, fy, cx, cy, distortion: `Camera.intrinsic_params`, p of
them) have a covariance Sigma_K from their calibration. Their error is one for every
image, and each marker pose was estimated with them: an error dK moves image i's pose by
D_i dK (D_i = `PoseSpec.d_pose_d_intrinsics`, 6 x p; 0 for a pose that does not depend
on K) as well as its pixels' rays. With S_K = d r / d K (m, p) over all images (central
differences: camera AND poses moved, footprints rebuilt), dx = -(J^T J)^-1 J^T S_K dK:

    Cov_K(x) = G_K Sigma_K G_K^T,   G_K = (J^T J)^-1 T_K,   T_K = J^T S_K = sum_i J_i^T S_K,i,

one shared parameter vector (the images' T_K,i add before the quadratic form: the error
does not average down over images).

Pose and intrinsics errors also leave residuals the light cannot absorb; their expected
contribution to chi^2 is sum_i tr(Sigma_i (S_i^T S_i - T_i^T (J^T J)^-1 T_i)),
T_i = J_i^T S_i, plus tr(Sigma_K (S_K^T S_K - T_K^T (J^T J)^-1 T_K)), so the expected
chi^2 is E = (m - n) + those, and s^2 = max(1, chi^2 / E) when sigma is the real
noise (only residuals beyond what the noise and the pose errors explain inflate the
covariance), chi^2 / (m - n) otherwise (sigma = 1: the residual variance is the noise).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from lightcal.core.footprint import Footprints
from lightcal.core.rotations import matrix_from_rotvec
from lightcal.core.scene import View

#: Finite-difference steps of the pose sensitivity: rotation (rad) and centre (m).
ROTATION_STEP_RAD = 1e-6
CENTER_STEP_M = 1e-6


def perturbed_view(view: View, dp: np.ndarray) -> View:
    """`view` with its rotation turned by exp(dp[:3]) and its centre moved by dp[3:] (m)."""
    R = matrix_from_rotvec(np.asarray(dp[:3], dtype=np.float64)) @ view.R_camera_world
    center = view.center_world + np.asarray(dp[3:], dtype=np.float64)
    return View(R, -R @ center, view.exposure)


def _central_differences(
    render_at: Callable[[np.ndarray], np.ndarray], steps: np.ndarray, sigma: np.ndarray
) -> np.ndarray:
    """d r / d q (N, len(steps)) of r = (m_obs - m) / sigma, m = render_at(dq), by central
    differences; a step of 0 gives a zero column."""
    out = np.zeros((sigma.size, steps.size))
    for k, h in enumerate(steps):
        if not h > 0.0:
            continue
        values = []
        for sign in (1.0, -1.0):
            dq = np.zeros(steps.size)
            dq[k] = sign * h
            values.append(render_at(dq))
        # r = (obs - m) / sigma  =>  dr/dq = -(dm/dq) / sigma.
        out[:, k] = -(values[0] - values[1]) / (2.0 * h) / sigma
    return out


def pose_sensitivity(
    view: View,
    render: Callable[[View, Footprints], np.ndarray],
    footprints_at: Callable[[View], Footprints],
    sigma: np.ndarray,
) -> np.ndarray:
    """d r / d (delta, c) (N, 6) of one image's weighted residuals r = (m_obs - m) / sigma.

    Args:
        view: the image's measured pose.
        render: rendered values (N,) of the image's pixels for a view and their footprints.
        footprints_at: the image's pixels' footprints for a (perturbed) view.
        sigma: (N,) the residuals' weights.
    """

    def render_at(dp: np.ndarray) -> np.ndarray:
        v = perturbed_view(view, dp)
        return render(v, footprints_at(v))

    steps = np.array([ROTATION_STEP_RAD] * 3 + [CENTER_STEP_M] * 3)
    return _central_differences(render_at, steps, sigma)


@dataclass(frozen=True)
class PoseBlock:
    """One image's share of the pose terms, on a subset of its pixels.

    Attributes:
        J: (k, n) rows of the weighted Jacobian d r / d x.
        S: (k, 6) the same rows of d r / d (delta, c).
        covariance: (6, 6) the image's pose covariance.
        noise_ratio: (k,) solver sigma / noise sigma of those rows (1 when the solver
            weights by the noise).
        row_scale: N_i / k, the image's pixels per subset row (sums over the subset are
            scaled by it: an unbiased estimate of the sums over all pixels).
        pose: which camera pose it was taken from: blocks of one pose (a photo's colour
            channels, `sensor.channels`) share one pose error; None: a pose of its own.
    """

    J: np.ndarray
    S: np.ndarray
    covariance: np.ndarray
    noise_ratio: np.ndarray
    row_scale: float = 1.0
    pose: int | None = None


@dataclass(frozen=True)
class PoseTerms:
    """What the camera poses' uncertainty adds.

    Attributes:
        covariance: (n, n) sum_i G_i Sigma_i G_i^T.
        expected_chi2_extra: sum_i tr(Sigma_i (S_i^T S_i - T_i^T (J^T J)^-1 T_i)) in noise
            units: the residuals the poses' errors leave on average.
        images: how many camera poses (images) carried a covariance.
    """

    covariance: np.ndarray
    expected_chi2_extra: float
    images: int


def pose_terms(normal_inverse: np.ndarray, blocks: list[PoseBlock]) -> PoseTerms:
    """Combine per-image sensitivities into the covariance and chi^2 terms.

    Args:
        normal_inverse: (n, n) (J^T J)^-1 of the solver's weighted Jacobian.
        blocks: one per image with a pose covariance.
    """
    n = normal_inverse.shape[0]
    cov = np.zeros((n, n))
    extra = 0.0
    # Per pose: T = sum J^T S, Tn the same noise-weighted, SS = sum Sn^T Sn, its covariance.
    poses: dict[object, list] = {}
    for k, b in enumerate(blocks):
        Sn = b.S * b.noise_ratio[:, None]
        parts = [
            b.row_scale * (b.J.T @ b.S),  # (n, 6)
            b.row_scale * ((b.J * b.noise_ratio[:, None] ** 2).T @ b.S),
            b.row_scale * (Sn.T @ Sn),
        ]
        key = ("image", k) if b.pose is None else ("pose", b.pose)
        if key in poses:
            for total, part in zip(poses[key], parts, strict=False):
                total += part
        else:
            poses[key] = [*parts, b.covariance]
    for T, Tn, SS, covariance in poses.values():
        G = normal_inverse @ T
        cov += G @ covariance @ G.T
        extra += float(np.trace(covariance @ (SS - Tn.T @ normal_inverse @ T)))
    return PoseTerms(0.5 * (cov + cov.T), extra, len(poses))


def intrinsics_sensitivity(
    render_at: Callable[[np.ndarray], np.ndarray], steps: np.ndarray, sigma: np.ndarray
) -> np.ndarray:
    """d r / d K (N, p) of one image's weighted residuals r = (m_obs - m) / sigma.

    Args:
        render_at: rendered values (N,) of the image's pixels with the camera's intrinsics
            moved by dK (p,) and the image's pose by D_i dK, footprints rebuilt.
        steps: (p,) central-difference steps; a step of 0 gives a zero column (a
            parameter without variance).
        sigma: (N,) the residuals' weights.
    """
    return _central_differences(render_at, steps, sigma)


@dataclass(frozen=True)
class IntrinsicsBlock:
    """One image's share of the intrinsics term, on a subset of its pixels.

    Attributes:
        J: (k, n) rows of the weighted Jacobian d r / d x.
        S: (k, p) the same rows of d r / d K (camera and pose moved).
        noise_ratio: (k,) solver sigma / noise sigma of those rows.
        row_scale: N_i / k (as `PoseBlock`).
    """

    J: np.ndarray
    S: np.ndarray
    noise_ratio: np.ndarray
    row_scale: float = 1.0


@dataclass(frozen=True)
class IntrinsicsTerms:
    """What the camera intrinsics' uncertainty adds.

    Attributes:
        covariance: (n, n) G_K Sigma_K G_K^T.
        expected_chi2_extra: tr(Sigma_K (S_K^T S_K - T_K^T (J^T J)^-1 T_K)) in noise units.
        parameters: p, the number of intrinsic parameters.
        images: how many images entered S_K.
        poses_moved: how many of them had a pose that moves with the intrinsics (D_i).
    """

    covariance: np.ndarray
    expected_chi2_extra: float
    parameters: int
    images: int
    poses_moved: int


def intrinsics_terms(
    normal_inverse: np.ndarray,
    covariance: np.ndarray,
    blocks: list[IntrinsicsBlock],
    *,
    poses_moved: int = 0,
) -> IntrinsicsTerms:
    """The intrinsics' covariance and chi^2 terms (see the module docstring).

    Args:
        normal_inverse: (n, n) (J^T J)^-1 of the solver's weighted Jacobian.
        covariance: (p, p) Sigma_K.
        blocks: one per image.
        poses_moved: how many images' poses moved with the intrinsics (for the report).
    """
    n, p = normal_inverse.shape[0], covariance.shape[0]
    T = np.zeros((n, p))
    Tn = np.zeros((n, p))
    StS = np.zeros((p, p))
    for b in blocks:
        T += b.row_scale * (b.J.T @ b.S)
        Tn += b.row_scale * ((b.J * b.noise_ratio[:, None] ** 2).T @ b.S)
        Sn = b.S * b.noise_ratio[:, None]
        StS += b.row_scale * (Sn.T @ Sn)
    G = normal_inverse @ T
    cov = G @ covariance @ G.T
    extra = float(np.trace(covariance @ (StS - Tn.T @ normal_inverse @ T)))
    return IntrinsicsTerms(0.5 * (cov + cov.T), extra, p, len(blocks), poses_moved)


def noise_inflation(chi2: float, dof: int, extra: float, *, sigma_is_noise: bool) -> float:
    """s^2 of the pixel-noise term (see the module docstring)."""
    if dof <= 0:
        return 1.0
    if not sigma_is_noise:
        return chi2 / dof
    return max(1.0, chi2 / (dof + max(extra, 0.0)))
