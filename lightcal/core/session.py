"""Step-by-step control of a calibration solve (what the app drives).

`SolverSession` runs `run_least_squares` in one worker thread. The solver's
per-iteration callback reports every iteration and then waits at a gate that the
controls open: `step()` lets exactly one more iteration through, `run()` all of them,
`pause()` closes the gate again, `stop()` ends the solve (the best estimate so far is
kept), `reset()` stops and returns to the initial guess. Controls may be called from
any thread; at most one solve runs at a time.

Given a `work`, the session drives that instead: any solve of several stages that
reports its iterations through one callback (the app runs `lightcal.pipeline.calibrate`
so, the same solve as `lightcal calibrate`). Its iterations pass the same gate; `stop()`
cancels it (`SolveCancelled` raised from the gate, no outcome: a multi-stage solve has
no one best estimate to keep).
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from typing import Any, Literal

import numpy as np

from lightcal.core.solver import CalibrationModel, IterationReport, SolveOutcome, run_least_squares

SessionState = Literal["idle", "paused", "running", "finished", "stopped", "failed"]

Work = Callable[[np.ndarray, Callable[[IterationReport], None]], Any]
"""`work(x0, on_iteration)`: a solve from x0 (n,) reporting every iteration; returns its
outcome (what `on_finish` receives)."""


class SolveCancelled(Exception):
    """Raised from the gate of a session with a `work` when `stop()` cancels it."""


class SolverSession:
    """Drive a solve iteration by iteration.

    Args:
        model: the calibration model (residuals, Jacobian, options); its initial vector is
            the start.
        on_iteration: called from the worker thread with each `IterationReport`.
        on_finish: called from the worker thread with the `SolveOutcome` (also after stop),
            or with what `work` returned (not after a stop: it cancels the work).
        work: the solve to drive (see the module docstring); default `run_least_squares`
            of the model.
    """

    def __init__(
        self,
        model: CalibrationModel,
        *,
        on_iteration: Callable[[IterationReport], None] | None = None,
        on_finish: Callable[[Any], None] | None = None,
        work: Work | None = None,
    ) -> None:
        self.model = model
        self._on_iteration = on_iteration
        self._on_finish = on_finish
        self._work_fn = work
        self._cond = threading.Condition()
        self._state: SessionState = "idle"
        self._budget = 0  # iterations allowed through the gate; -1: unlimited
        self._stop = False
        self._thread: threading.Thread | None = None
        self.history: list[IterationReport] = []
        self.outcome: Any = None  # a SolveOutcome, or what `work` returned
        self.error: BaseException | None = None
        self.x0 = model.layout.x0.copy()

    # -- state ----------------------------------------------------------------------------

    @property
    def state(self) -> SessionState:
        with self._cond:
            return self._state

    @property
    def unlimited(self) -> bool:
        """Running to the end (`run`), not a number of steps (`step`)."""
        with self._cond:
            return self._budget < 0

    @property
    def latest(self) -> IterationReport | None:
        with self._cond:
            return self.history[-1] if self.history else None

    @property
    def x(self) -> np.ndarray:
        """The current estimate (the last reported iteration, else the initial guess)."""
        latest = self.latest
        return latest.x.copy() if latest is not None else self.x0.copy()

    # -- controls ---------------------------------------------------------------------------

    def step(self) -> None:
        """Let one more iteration run (starts the solve if needed)."""
        with self._cond:
            if self._state in ("finished", "stopped", "failed"):
                return
            if self._budget >= 0:
                self._budget += 1
            self._state = "running"
            self._cond.notify_all()
        self._ensure_started()

    def run(self) -> None:
        """Run until convergence, `pause()` or `stop()` (starts the solve if needed)."""
        with self._cond:
            if self._state in ("finished", "stopped", "failed"):
                return
            self._budget = -1
            self._state = "running"
            self._cond.notify_all()
        self._ensure_started()

    def pause(self) -> None:
        """Hold the solve after the current iteration."""
        with self._cond:
            if self._state == "running":
                # The worker finishes its iteration and reports "paused" at the gate.
                self._budget = 0
                self._cond.notify_all()

    def stop(self, *, wait: bool = True) -> None:
        """End the solve, keeping the best estimate so far."""
        with self._cond:
            self._stop = True
            self._cond.notify_all()
            thread = self._thread
        if wait and thread is not None and thread is not threading.current_thread():
            thread.join()

    def reset(self, x0: np.ndarray | None = None) -> None:
        """Stop any solve and start over from x0 (default: the initial guess)."""
        self.stop()
        with self._cond:
            if x0 is not None:
                self.x0 = np.asarray(x0, dtype=np.float64).copy()
            self._thread = None
            self._stop = False
            self._budget = 0
            self._state = "idle"
            self.history = []
            self.outcome = None
            self.error = None

    def wait(self, timeout: float | None = None) -> bool:
        """Block until the solve ends or holds at the gate; True if it did within timeout."""
        with self._cond:
            return self._cond.wait_for(lambda: self._state != "running", timeout)

    # -- worker ---------------------------------------------------------------------------

    def _ensure_started(self) -> None:
        with self._cond:
            if self._thread is not None:
                return
            self._thread = threading.Thread(target=self._work, name="lightcal-solver", daemon=True)
            thread = self._thread
        thread.start()

    def _gate(self, report: IterationReport) -> None:
        with self._cond:
            self.history.append(report)
        if self._on_iteration is not None:
            self._on_iteration(report)
        with self._cond:
            # Iteration 0 is the start: it does not use up a step.
            if report.iteration > 0 and self._budget > 0:
                self._budget -= 1
            if self._budget == 0 and not self._stop:
                self._state = "paused"
            self._cond.notify_all()
            self._cond.wait_for(lambda: self._stop or self._budget != 0)
            if self._stop:
                raise StopIteration if self._work_fn is None else SolveCancelled
            self._state = "running"

    def _work(self) -> None:
        try:
            if self._work_fn is not None:
                done = self._work_fn(self.x0.copy(), self._gate)
            else:
                done = run_least_squares(self.model, self.x0, on_iteration=self._gate)
        except SolveCancelled:
            with self._cond:
                self._state = "stopped"
                self._cond.notify_all()
            return
        except BaseException as exc:  # reported to the caller through state/error
            with self._cond:
                self.error = exc
                self._state = "failed"
                self._cond.notify_all()
            return
        with self._cond:
            if isinstance(done, SolveOutcome) and done.status == -2 and self.history:
                done.x = self.history[-1].x.copy()
            self.outcome = done
            stopped = isinstance(done, SolveOutcome) and done.status == -2
            self._state = "stopped" if stopped else "finished"
            self._cond.notify_all()
        if self._on_finish is not None:
            self._on_finish(done)
