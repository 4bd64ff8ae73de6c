"""Non-linear least squares for the light pose(s): residuals, Jacobian, solve.

`scipy.optimize.least_squares` (trf) minimises the weighted residuals
r = (m_obs - m_render(x)) / sigma of `CalibrationModel` with its analytic Jacobian
(pose and scale from the renderer's gradients; RID parameters, when estimated, by
central differences of the renderer). Every iteration is reported through the solver's
callback (`IterationReport`); the callback may stop the solve (`StopIteration`), which is
how `lightcal.core.session.SolverSession` steps, pauses and stops it.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import OptimizeResult, least_squares

from lightcal.core.pose import axis_from_angles, axis_jacobian
from lightcal.core.problem import ImageData, LightUnknown, Loss, ParameterLayout
from lightcal.core.render import shade
from lightcal.core.rotations import left_jacobian_so3

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

    def __post_init__(self) -> None:
        if self.loss not in ("linear", "huber", "soft_l1", "cauchy"):
            raise ValueError(
                f"loss: expected one of linear, huber, soft_l1, cauchy, got {self.loss!r}"
            )
        if not (self.f_scale > 0 and math.isfinite(self.f_scale)):
            raise ValueError(f"f_scale: expected a finite value > 0, got {self.f_scale}")
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
    """

    iteration: int
    x: np.ndarray
    cost: float
    gradient_norm: float
    per_image_rms: np.ndarray
    nfev: int


class CalibrationModel:
    """Residuals and Jacobian of a calibration problem.

    Args:
        images: the selected pixels of each image.
        unknowns: the lights to calibrate.
        options: solver options.
    """

    def __init__(
        self, images: list[ImageData], unknowns: list[LightUnknown], options: SolverOptions
    ) -> None:
        if not images:
            raise ValueError("calibration: expected at least one image with selected pixels")
        if not unknowns:
            raise ValueError("calibration: expected at least one light")
        self.images = images
        self.unknowns = unknowns
        self.options = options
        self.layout = ParameterLayout.build(
            unknowns,
            len(images),
            estimate_gains=options.estimate_gains,
            estimate_offset=options.estimate_offset,
            offset0=options.offset,
        )
        self.sizes = np.array([len(im.observed) for im in images])
        self.bounds = np.cumsum(np.concatenate([[0], self.sizes]))
        self.m = int(self.bounds[-1])
        self._cache_x: np.ndarray | None = None
        self._cache_r: np.ndarray | None = None
        self._cache_J_x: np.ndarray | None = None
        self._cache_J: np.ndarray | None = None
        self.nfev = 0

    # -- evaluation -------------------------------------------------------------------

    def predict(self, x: np.ndarray, *, want_grad: bool = False) -> list:
        """Render every image at x: list of (values (N,), Shading or None)."""
        rig = self.layout.rig(x)
        gains = self.layout.gain_factors(x)
        offset = self.layout.offset(x)
        out = []
        for i, im in enumerate(self.images):
            sh = shade(
                im.footprints,
                im.view,
                rig,
                offset=0.0,
                rid_subsamples=self.options.rid_subsamples,
                want_grad=want_grad,
            )
            values = offset + gains[i] * sh.values.filled(np.nan)
            out.append((values, sh))
        return out

    def residuals(self, x: np.ndarray) -> np.ndarray:
        """(m,) weighted residuals (m_obs - m_render) / sigma."""
        if self._cache_x is not None and np.array_equal(x, self._cache_x):
            assert self._cache_r is not None
            return self._cache_r
        self.nfev += 1
        r = np.empty(self.m)
        for i, (values, _) in enumerate(self.predict(x)):
            im = self.images[i]
            r[self.bounds[i] : self.bounds[i + 1]] = (im.observed - values) / im.sigma
        self._cache_x = x.copy()
        self._cache_r = r
        return r

    def jacobian(self, x: np.ndarray) -> np.ndarray:
        """(m, n) d residuals / d x."""
        if self._cache_J_x is not None and np.array_equal(x, self._cache_J_x):
            assert self._cache_J is not None
            return self._cache_J
        lay = self.layout
        J = np.zeros((self.m, lay.n))
        gains = lay.gain_factors(x)
        preds = self.predict(x, want_grad=True)
        rig = lay.rig(x)
        for i, (values, sh) in enumerate(preds):
            im = self.images[i]
            rows = slice(self.bounds[i], self.bounds[i + 1])
            inv_sigma = -1.0 / im.sigma  # d r / d m_render
            g = gains[i]
            for j, block in enumerate(lay.blocks):
                light = rig.lights[j]
                gp = sh.grad_position[j] * g
                gr = sh.grad_rotation[j] * g
                p = x[block.pose]
                cols = [gp]
                kind = block.param.kind
                if kind == "symmetric":
                    axis = axis_from_angles(p[3], p[4])
                    Ja = axis_jacobian(p[3], p[4])  # (3, 2)
                    cols.append(gr @ np.cross(axis[:, None], Ja, axis=0))
                elif kind == "general":
                    cols.append(gr @ left_jacobian_so3(p[3:6]))
                J[rows, block.pose] = np.concatenate(cols, axis=1) * inv_sigma[:, None]
                J[rows, block.log_scale] = g * light.scale * sh.flux[j] * inv_sigma
                if block.rid.stop > block.rid.start:
                    J[rows, block.rid] = self._rid_jacobian(x, i, j, block) * inv_sigma[:, None]
            base = values - lay.offset(x)
            if lay.gains.stop > lay.gains.start and i > 0:
                J[rows, lay.gains.start + i - 1] = base * inv_sigma
            if lay.offset_index is not None:
                J[rows, lay.offset_index] = inv_sigma
        self._cache_J_x = x.copy()
        self._cache_J = J
        return J

    def _rid_jacobian(self, x: np.ndarray, i: int, j: int, block) -> np.ndarray:
        """d m_render / d (RID params of light j) on image i by central differences."""
        im = self.images[i]
        lay = self.layout
        gain = lay.gain_factors(x)[i]
        out = np.empty((len(im.observed), block.rid.stop - block.rid.start))
        lights = list(lay.rig(x).lights)
        for c, k in enumerate(range(block.rid.start, block.rid.stop)):
            h = 1e-6 * max(1.0, abs(x[k]))
            vals = []
            for sgn in (1.0, -1.0):
                xs = x.copy()
                xs[k] += sgn * h
                lights[j] = lay.light_of(block, xs)
                from lightcal.core.scene import Rig

                sh = shade(
                    im.footprints,
                    im.view,
                    Rig(tuple(lights)),
                    rid_subsamples=self.options.rid_subsamples,
                )
                vals.append(gain * sh.values.filled(np.nan))
            out[:, c] = (vals[0] - vals[1]) / (2 * h)
        return out

    def per_image_rms(self, x: np.ndarray) -> np.ndarray:
        """(n_images,) RMS of m_obs - m_render per image (pixel value units)."""
        r = self.residuals(x)
        out = np.empty(len(self.images))
        for i, im in enumerate(self.images):
            d = r[self.bounds[i] : self.bounds[i + 1]] * im.sigma
            out[i] = float(np.sqrt(np.mean(d * d))) if d.size else float("nan")
        return out

    def report(self, x: np.ndarray, iteration: int) -> IterationReport:
        r = self.residuals(x)
        J = self.jacobian(x)
        return IterationReport(
            iteration,
            x.copy(),
            0.5 * float(r @ r),
            float(np.abs(J.T @ r).max()),
            self.per_image_rms(x),
            self.nfev,
        )

    # -- bounds -------------------------------------------------------------------------

    def parameter_bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """Box bounds: positions within +-position_bound_m and, along the camera axis, in
        front of the wall for every view whatever the lateral position in the box."""
        lo = np.full(self.layout.n, -np.inf)
        hi = np.full(self.layout.n, np.inf)
        b = self.options.position_bound_m
        for block in self.layout.blocks:
            s = block.pose.start
            lo[s : s + 3] = -b
            hi[s : s + 3] = b
            z0 = self.layout.x0[s + 2]
            lateral = np.abs(self.layout.x0[s : s + 2]).max() + 0.5
            z_hi = np.inf
            for im in self.images:
                R = im.view.R_camera_world
                cz = im.view.center_world[2]
                # world z of the light = cz + sum_k R[k, 2] t_k must stay > 0.
                if R[2, 2] < 0.0:
                    slack = cz - lateral * (abs(R[0, 2]) + abs(R[1, 2]))
                    z_hi = min(z_hi, 0.98 * slack / -R[2, 2])
            if z_hi > z0:
                hi[s + 2] = min(b, z_hi)
                lo[s : s + 2] = np.maximum(lo[s : s + 2], -lateral)
                hi[s : s + 2] = np.minimum(hi[s : s + 2], lateral)
        return lo, hi


@dataclass
class SolveOutcome:
    """What least_squares returned plus the iteration history."""

    x: np.ndarray
    status: int
    message: str
    success: bool
    iterations: int
    nfev: int
    cost: float
    time_s: float
    history: list[IterationReport] = field(default_factory=list)


def run_least_squares(
    model: CalibrationModel,
    x0: np.ndarray | None = None,
    *,
    on_iteration: Callable[[IterationReport], None] | None = None,
) -> SolveOutcome:
    """Minimise the model's cost from x0 (default: the layout's initial vector).

    `on_iteration` receives iteration 0 (the start) and then every iteration; raising
    StopIteration from it stops the solve (status -2).
    """
    opts = model.options
    x_start = model.layout.x0 if x0 is None else np.asarray(x0, dtype=np.float64)
    lo, hi = model.parameter_bounds()
    x_start = np.clip(x_start, lo + 1e-12, hi - 1e-12)
    history: list[IterationReport] = []
    t0 = time.perf_counter()

    def emit(rep: IterationReport) -> None:
        history.append(rep)
        if on_iteration is not None:
            on_iteration(rep)

    stopped_early = False
    try:
        emit(model.report(x_start, 0))
    except StopIteration:
        stopped_early = True
    if stopped_early:
        return SolveOutcome(
            x_start,
            -2,
            "stopped before the first iteration",
            False,
            0,
            model.nfev,
            history[0].cost,
            time.perf_counter() - t0,
            history,
        )

    hit_limit = False

    def callback(intermediate_result: OptimizeResult) -> None:
        nonlocal hit_limit
        nit = int(intermediate_result.nit)
        emit(model.report(np.asarray(intermediate_result.x), nit))
        if nit >= opts.max_iterations:
            hit_limit = True
            raise StopIteration

    res = least_squares(
        model.residuals,
        x_start,
        jac=model.jacobian,
        bounds=(lo, hi),
        method="trf",
        loss=opts.loss,
        f_scale=opts.f_scale,
        x_scale="jac",
        ftol=opts.tolerance,
        xtol=opts.tolerance,
        gtol=opts.tolerance,
        max_nfev=20 * opts.max_iterations,
        callback=callback,
    )
    iterations = history[-1].iteration if history else 0
    status, message = int(res.status), str(res.message)
    if hit_limit:
        status, message = 0, f"stopped after the maximum of {opts.max_iterations} iterations"
    return SolveOutcome(
        np.asarray(res.x),
        status,
        message,
        status > 0,
        iterations,
        model.nfev,
        float(res.cost),
        time.perf_counter() - t0,
        history,
    )
