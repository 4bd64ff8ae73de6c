"""The options of the calibration solve, its per-iteration report and the robust cost.

`SolverOptions` is the one place the solver's defaults are written: the project file's
`solver` section (`lightcal.io.project.SolverSpec`) reads them from here.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from lightcal.core.problem import Loss

# Each light's position may move at most this far (per camera-frame axis) from the origin.
DEFAULT_POSITION_BOUND_M = 5.0


@dataclass(frozen=True)
class SolverOptions:
    """Options of the calibration solve.

    Attributes:
        loss: robust loss of scipy.optimize.least_squares.
        f_scale: soft margin between inlier and outlier residuals (in sigma units).
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
    """

    loss: Loss = "linear"
    f_scale: float = 1.0
    max_iterations: int = 100
    estimate_gains: bool = False
    estimate_offset: bool = False
    offset: float = 0.0
    rid_subsamples: int = 1
    tolerance: float = 1e-12
    position_bound_m: float = DEFAULT_POSITION_BOUND_M
    compress: bool | None = None
    reweight: bool = True

    def __post_init__(self) -> None:
        if self.loss not in ("linear", "huber", "soft_l1", "cauchy"):
            raise ValueError(
                f"loss: expected one of linear, huber, soft_l1, cauchy, got {self.loss!r}"
            )
        if not (self.f_scale > 0 and math.isfinite(self.f_scale)):
            raise ValueError(f"f_scale: expected a finite value > 0, got {self.f_scale}")
        if self.compress is not None and not isinstance(self.compress, bool):
            raise ValueError(f"compress: expected true, false or null, got {self.compress!r}")
        if self.max_iterations < 1:
            raise ValueError(f"max_iterations: expected >= 1, got {self.max_iterations}")


@dataclass(frozen=True)
class IterationReport:
    """The state after one solver iteration (iteration 0: the start).

    Attributes:
        iteration: number of completed iterations.
        x: (n,) parameters.
        cost: 0.5 * sum of rho(r^2) (least_squares' cost).
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


def robust_cost(r: np.ndarray, loss: Loss, f_scale: float) -> float:
    """least_squares' cost 0.5 C^2 sum rho((r / C)^2) of residuals r (m,)."""
    z = r / f_scale
    np.square(z, out=z)  # in place: one temporary of r's size, not two
    if loss == "linear":
        rho = z
    elif loss == "huber":
        rho = np.where(z <= 1.0, z, 2.0 * np.sqrt(z) - 1.0)
    elif loss == "soft_l1":
        rho = 2.0 * (np.sqrt(1.0 + z) - 1.0)
    else:  # cauchy
        rho = np.log1p(z)
    return 0.5 * f_scale**2 * float(np.sum(rho))
