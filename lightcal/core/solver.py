"""Non-linear least squares for the light pose(s): the solve.

`scipy.optimize.least_squares` (trf) minimises the weighted residuals of a
`CalibrationModel` (lightcal/core/calibration_model.py) with its analytic Jacobian. Every
iteration is reported through the solver's callback (`IterationReport`); the callback may
stop the solve (`StopIteration`), which is how `lightcal.core.session.SolverSession`
steps, pauses and stops it.

A robust loss with `f_scale: auto` solves in two stages: the linear loss from the start,
then the robust loss from that solution with f_scale from its residuals (`auto_f_scale`).

The solver is three modules: `solver_options` (`SolverOptions`, `IterationReport`,
`robust_cost`, `auto_f_scale`), `calibration_model` (`CalibrationModel`) and this one
(`SolveOutcome`, `run_least_squares`), which also exports the names of the other two.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING

import numpy as np

from lightcal.core.blas_threads import single_threaded_blas
from lightcal.core.calibration_model import CalibrationModel
from lightcal.core.solver_options import (
    DEFAULT_POSITION_BOUND_M,
    IterationReport,
    SolverOptions,
    auto_f_scale,
    robust_cost,
)

if TYPE_CHECKING:
    from scipy.optimize import OptimizeResult

__all__ = [
    "CONVERGED_AHEAD",
    "DEFAULT_POSITION_BOUND_M",
    "CalibrationModel",
    "IterationReport",
    "SolveOutcome",
    "SolverOptions",
    "auto_f_scale",
    "robust_cost",
    "run_least_squares",
]


@dataclass
class SolveOutcome:
    """What least_squares returned plus the iteration history.

    `weights_at`: the parameters the final pixel weights were rendered at (None: the
    data's sigmas); `CalibrationModel.set_weights_at` restores them. `start`: where the
    solve started when a caller found the start by a solve of its own, in words (empty:
    the initial guess or the given x0); `start_costs`: that solve's cost per iteration,
    scaled to this problem's pixels (its last iterate is this solve's iteration 0).
    `f_scale_used`: the robust loss's f_scale in noise sigmas, the given one or the one
    `f_scale: auto` took from the linear stage's residuals; None with the linear loss, or
    when the solve stopped before the robust stage.
    """

    x: np.ndarray
    status: int
    message: str
    success: bool
    iterations: int
    nfev: int
    cost: float
    time_s: float
    history: list[IterationReport] = field(default_factory=list)
    weights_at: np.ndarray | None = None
    start: str = ""
    start_costs: list[float] = field(default_factory=list)
    f_scale_used: float | None = None

    @classmethod
    def stopped(
        cls, history: list[IterationReport], message: str, *, time_s: float = 0.0
    ) -> SolveOutcome:
        """An unfinished outcome (status -2) at the last report of `history` (non-empty):
        a solve stopped before its first iteration, or one paused by its caller."""
        last = history[-1]
        return cls(
            x=last.x.copy(),
            status=-2,
            message=message,
            success=False,
            iterations=last.iteration,
            nfev=last.nfev,
            cost=last.cost,
            time_s=time_s,
            history=history,
        )


CONVERGED_AHEAD = (
    "the Gauss-Newton step from the last iterate predicts a cost decrease below "
    "solver.tolerance times the cost (the step trf would take next and then stop)"
)


def run_least_squares(
    model: CalibrationModel,
    x0: np.ndarray | None = None,
    *,
    on_iteration: Callable[[IterationReport], None] | None = None,
    f_scale: float | None = None,
) -> SolveOutcome:
    """Minimise the model's cost from x0 (default: the layout's initial vector).

    `on_iteration` receives iteration 0 (the start) and then every iteration; raising
    StopIteration from it stops the solve (status -2). When the model re-weights
    (`CalibrationModel.reweights`), the first solve uses the data's sigmas; after it
    converges, the sigmas are re-derived from the rendered values and trf runs again
    from there, its iterations numbered on (the cost changes with the weights).

    A robust loss with `SolverOptions.f_scale` "auto" first solves with the linear loss
    (iteration 0 and the first iterations are that loss's); once it converges, f_scale
    is `auto_f_scale` of its residuals (or `f_scale`, when given: a caller comparing the
    costs of several solves keeps one) and the robust loss continues from its solution,
    its iterations numbered on. Robust losses give pixels beyond about f_scale less
    weight: with f_scale = 1 noise sigma and a misfit of 100 sigma every pixel is an
    outlier, and trf crawls away from the fit (on real photos, to the search box's edge).
    """
    opts = model.options
    auto = opts.loss != "linear" and opts.f_scale == "auto"
    try:
        if auto:
            model.options = replace(opts, loss="linear")
        return _solve(model, x0, on_iteration, opts, f_scale)
    finally:
        model.options = opts


def _solve(
    model: CalibrationModel,
    x0: np.ndarray | None,
    on_iteration: Callable[[IterationReport], None] | None,
    opts: SolverOptions,
    f_scale: float | None,
) -> SolveOutcome:
    """`run_least_squares` with `model.options` those of its first stage (`opts` with the
    linear loss for a robust loss's f_scale "auto"); `opts` the solve's own."""
    x_start = model.layout.x0 if x0 is None else np.asarray(x0, dtype=np.float64)
    lo, hi = model.parameter_bounds()
    x_start = np.clip(x_start, lo + 1e-12, hi - 1e-12)
    if model.weights_at is not None:
        model.set_weights_at(None)
    history: list[IterationReport] = []
    t0 = time.perf_counter()
    # time_s is the solver's: not the callbacks' (the app waits in them while paused).
    in_callbacks = [0.0]

    def emit(rep: IterationReport) -> None:
        history.append(rep)
        if on_iteration is not None:
            t = time.perf_counter()
            on_iteration(rep)
            in_callbacks[0] += time.perf_counter() - t

    def solver_time() -> float:
        return time.perf_counter() - t0 - in_callbacks[0]

    try:
        emit(model.report(x_start, 0))
    except StopIteration:
        return SolveOutcome.stopped(
            history, "stopped before the first iteration", time_s=solver_time()
        )
    linear_first = model.options.loss != opts.loss
    # None until a robust loss runs: the linear loss has no f_scale.
    f_used = None if opts.loss == "linear" or isinstance(opts.f_scale, str) else float(opts.f_scale)
    res, hit_limit = _trf(model, x_start, (lo, hi), 0, emit)
    if linear_first and res.status > 0 and not hit_limit:
        # The linear stage converged: its residuals set f_scale, and the robust loss goes
        # on from its solution (the cost changes with the loss, as with the weights).
        x_linear = np.asarray(res.x)
        compressed = model.compressed
        r = model.residuals(x_linear)
        f_used = auto_f_scale(r, opts.loss) if f_scale is None else float(f_scale)
        model.options = replace(opts, f_scale=f_used)
        if compressed:
            model.set_weights_at(None)  # drops the QR-compressed evaluations (linear costs)
        res, hit_limit = _trf(model, x_linear, (lo, hi), history[-1].iteration, emit)
    if model.reweights and res.status > 0 and not hit_limit:
        model.set_weights_at(np.asarray(res.x))
        res, hit_limit = _trf(model, np.asarray(res.x), (lo, hi), history[-1].iteration, emit)
    model.release_buffers()  # until the next solve or check: the peak memory is later
    iterations = history[-1].iteration
    status, message = int(res.status), str(res.message)
    if hit_limit:
        status, message = 0, f"stopped after the maximum of {opts.max_iterations} iterations"
    return SolveOutcome(
        x=np.asarray(res.x),
        status=status,
        message=message,
        success=status > 0,
        iterations=iterations,
        nfev=model.nfev,
        cost=float(res.cost),
        time_s=solver_time(),
        history=history,
        weights_at=None if model.weights_at is None else model.weights_at.copy(),
        f_scale_used=f_used,
    )


def _trf(
    model: CalibrationModel,
    x_start: np.ndarray,
    bounds: tuple[np.ndarray, np.ndarray],
    done: int,
    emit: Callable[[IterationReport], None],
) -> tuple[OptimizeResult, bool]:
    """One least_squares (trf) run after `done` iterations: (its result, hit the limit)."""
    # Imported where it is used: scipy.optimize takes 0.25-0.3 s to import, which a
    # command overlaps with its image decoding (`pipeline.load.prepare_solve`).
    from scipy.optimize import least_squares

    opts = model.options
    hit_limit = False
    converged_ahead = False

    def callback(intermediate_result: OptimizeResult) -> None:
        nonlocal hit_limit, converged_ahead
        x = np.asarray(intermediate_result.x)
        nit = done + int(intermediate_result.nit)
        emit(model.report(x, nit))
        if nit >= opts.max_iterations:
            hit_limit = True
            raise StopIteration
        # trf stops after a step whose cost change is below ftol * cost (and then holds
        # the point after it): when the Gauss-Newton step from x already predicts that,
        # the evaluation of that step would only confirm it.
        decrease = model.gauss_newton_decrease(x)
        if decrease is not None and decrease < opts.tolerance * float(intermediate_result.cost):
            converged_ahead = True
            raise StopIteration

    with single_threaded_blas():  # trf's SVD of a full (m, n) Jacobian: see blas_threads
        res = least_squares(
            model.solver_residuals,
            x_start,
            jac=model.solver_jacobian,
            bounds=bounds,
            method="trf",
            loss=opts.loss,
            f_scale=_number(opts.f_scale, opts.loss),
            x_scale="jac",
            ftol=opts.tolerance,
            xtol=opts.tolerance,
            gtol=opts.tolerance,
            max_nfev=20 * opts.max_iterations,
            callback=callback,
        )
    if converged_ahead:
        res.status, res.success, res.message = 2, True, CONVERGED_AHEAD
    return res, hit_limit


def _number(f_scale: float | str, loss: str) -> float:
    """The f_scale handed to least_squares: a number (the linear loss ignores it; a robust
    loss's "auto" is resolved by `run_least_squares` before trf runs)."""
    if isinstance(f_scale, str):
        assert loss == "linear", "f_scale auto reached trf with a robust loss"
        return 1.0
    return float(f_scale)
