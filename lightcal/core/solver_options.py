"""The options of the calibration solve, its per-iteration report, the robust cost and
the robust loss's automatic scale.

`SolverOptions` is the one place the solver's defaults are written: the project file's
`solver` section (`lightcal.io.project.SolverSpec`) reads them from here.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

import numpy as np

from lightcal.core.albedo_map import AlbedoMapOptions
from lightcal.core.fall_off import FallOffUnknown
from lightcal.core.problem import Loss

# Each light's position may move at most this far (per camera-frame axis) from the origin.
DEFAULT_POSITION_BOUND_M = 5.0

FScale = float | Literal["auto"]
"""`SolverOptions.f_scale`: noise sigmas, or "auto" (from the linear solution's residuals)."""

# The robust losses' f_scale with `f_scale: auto`, in units of the residuals' robust
# standard deviation: for each loss the tuning constant c at which its M-estimator has
# 95 % asymptotic efficiency at the Gaussian, E[psi']^2 / E[psi^2] = 0.95 for N(0, 1)
# residuals, the usual choice (Holland and Welsch 1977; Huber, "Robust Statistics"):
# huber psi(u) = clip(u, -c, c): 1.345; cauchy psi(u) = u / (1 + (u/c)^2): 2.385;
# soft_l1 (pseudo-Huber) psi(u) = u / sqrt(1 + (u/c)^2): 1.287, from the same integral
# (tests/test_robust_loss.py evaluates it for all three). Pixels within about c robust
# sigmas of the linear fit keep nearly their least-squares weight; far ones lose it.
AUTO_F_SCALE_FACTORS: dict[str, float] = {"huber": 1.345, "soft_l1": 1.287, "cauchy": 2.385}

# sigma = 1.4826 MAD for Gaussian residuals (1 / Phi^-1(3/4)).
MAD_TO_SIGMA = 1.4826


@dataclass(frozen=True)
class SolverOptions:
    """Options of the calibration solve.

    Attributes:
        loss: robust loss of scipy.optimize.least_squares.
        f_scale: soft margin between inlier and outlier residuals, in noise sigmas, or
            "auto": a robust loss then first solves with the linear loss and takes
            `auto_f_scale` of that solution's residuals (`run_least_squares`). The
            linear loss ignores it.
        max_iterations: at most this many iterations (trf steps).
        estimate_gains: a free gain per image (exposure unknown); the first image's is fixed.
        estimate_offset: estimate the black level / ambient offset b.
        offset: the known offset, or the initial one when estimated.
        rid_subsamples: RID sub-sampling n x n per footprint.
        tolerance: ftol = xtol = gtol of least_squares.
        position_bound_m: box bound on each light's camera-frame position coordinates.
        compress: with the linear loss, hand trf the QR-compressed problem
            (`CalibrationModel.reduced`): the same iterates, at a cost and memory that
            no longer grow with the pixel count beyond one render per evaluation.
            None: when there are at least COMPRESS_MIN_PIXELS pixels (below, the
            per-image QR costs more than trf's SVD saves).
        reweight: when images carry a noise model (`ImageData.noise`), re-derive each
            pixel's sigma from the values rendered at the converged estimate and solve
            again from there: sigmas from the noisy observations weight pixels whose noise
            happened to be negative more, which biases the estimate (measured: ~3 mm at
            SNR ~35, removed by one re-weighting).
        estimate_ambient: estimate the room light's level a: g_i e_i a in image i, which
            grows with the exposure (`lightcal.core.problem`). Measured: 5 % room light
            moves the light 119 mm without it, 0.85 mm with it, and a dark room's
            position sigma grows 1.12x; off by default, as an estimated RID profile's
            tail trades with it (docs/model.md). Not a parameter when an estimated
            offset already is the same column (`ambient_estimated`).
        fall_off: a radial fall-off to estimate with the lights (`lightcal.core.fall_off`;
            the project's `sensor.estimate_fall_off`), or None: V = 1.
        albedo_map: the wall's albedo map to estimate with the lights
            (`lightcal.core.albedo_map`; the project's `wall.albedo_map`), or None: an
            even wall. It needs the linear loss.
    """

    loss: Loss = "linear"
    f_scale: FScale = "auto"
    max_iterations: int = 100
    estimate_gains: bool = False
    estimate_offset: bool = False
    offset: float = 0.0
    rid_subsamples: int = 1
    tolerance: float = 1e-12
    position_bound_m: float = DEFAULT_POSITION_BOUND_M
    compress: bool | None = None
    reweight: bool = True
    fall_off: FallOffUnknown | None = None
    estimate_ambient: bool = False
    albedo_map: AlbedoMapOptions | None = None

    def __post_init__(self) -> None:
        if self.loss not in ("linear", "huber", "soft_l1", "cauchy"):
            raise ValueError(
                f"loss: expected one of linear, huber, soft_l1, cauchy, got {self.loss!r}"
            )
        f = self.f_scale
        if f != "auto" and (
            isinstance(f, bool) or not isinstance(f, int | float) or not 0 < f < math.inf
        ):
            raise ValueError(f'f_scale: expected "auto" or a finite value > 0, got {f!r}')
        if self.compress is not None and not isinstance(self.compress, bool):
            raise ValueError(f"compress: expected true, false or null, got {self.compress!r}")
        if self.max_iterations < 1:
            raise ValueError(f"max_iterations: expected >= 1, got {self.max_iterations}")
        if self.albedo_map is not None and self.loss != "linear":
            raise ValueError(
                f"albedo map: expected the linear loss, got {self.loss!r} (the map is "
                "projected out by linear least squares)"
            )


@dataclass(frozen=True)
class IterationReport:
    """The state after one solver iteration (iteration 0: the start).

    Attributes:
        iteration: number of completed iterations.
        x: (n,) parameters.
        cost: 0.5 * sum of rho(r^2) (least_squares' cost) of the loss the iteration
            minimised (with f_scale "auto", the first iterations are the linear loss's).
        gradient_norm: max-norm of J^T r at x (linear loss), the first-order optimality.
        per_image_rms: (n_images,) RMS of the unweighted residual m_obs - m_render.
        nfev: residual evaluations so far.
        reweighted: the pixel weights come from rendered values (the re-weighted
            solve; its cost is not comparable with the iterations before it).
    """

    iteration: int
    x: np.ndarray
    cost: float
    gradient_norm: float
    per_image_rms: np.ndarray
    nfev: int
    reweighted: bool = False


def robust_cost(r: np.ndarray, loss: Loss, f_scale: FScale) -> float:
    """least_squares' cost 0.5 C^2 sum rho((r / C)^2) of residuals r (m,), C = f_scale
    (a number: a robust loss's "auto" is resolved by the solve before any cost; the
    linear loss ignores it)."""
    if loss == "linear":
        return 0.5 * float(r @ r)
    if isinstance(f_scale, str):
        raise ValueError(f"robust_cost: the {loss} loss needs a numeric f_scale, got {f_scale!r}")
    z = r / f_scale
    np.square(z, out=z)  # in place: one temporary of r's size, not two
    if loss == "huber":
        rho = np.where(z <= 1.0, z, 2.0 * np.sqrt(z) - 1.0)
    elif loss == "soft_l1":
        rho = 2.0 * (np.sqrt(1.0 + z) - 1.0)
    else:  # cauchy
        rho = np.log1p(z)
    return 0.5 * f_scale**2 * float(np.sum(rho))


def auto_f_scale(r: np.ndarray, loss: Loss) -> float:
    """The f_scale of `f_scale: auto`: c * 1.4826 * median(|r - median(r)|).

    Args:
        r: (m,) weighted residuals of the linear loss's solution (non-finite ones ignored).
        loss: the robust loss (c = `AUTO_F_SCALE_FACTORS[loss]`).

    Returns:
        f_scale in the residuals' units (noise sigmas): about c for residuals that are
        the pixel noise, c times the misfit's robust spread when the model errs. When
        the spread is 0 (an exact fit), c: the noise's own scale.
    """
    c = AUTO_F_SCALE_FACTORS[loss]
    finite = r[np.isfinite(r)]
    if finite.size == 0:
        return c
    spread = MAD_TO_SIGMA * float(np.median(np.abs(finite - np.median(finite))))
    return c * spread if spread > 0 and math.isfinite(spread) else c
