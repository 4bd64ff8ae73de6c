"""The solve behind the page, without a browser: selection, model, stepping, results.

`SolveService` owns the pixel selection as the user set it (`pixel_selection`), the
one `SolverSession` (step, run, pause, reset), and what the state shows of it (the
history, the display of the guess or the estimate, the result with uncertainties).
The model is built by `lightcal.pipeline` (`starting_lights`, as `lightcal calibrate`
does), from the images the user's selection leaves, and solved by the same engine as
`lightcal calibrate`: `lightcal.pipeline.calibrate` (multi-start, mirror exclusion,
`wall: auto`, the fit test and the uncertainty) runs in the session, its iterations
(every stage's, numbered on) passing the session's gate, so Step and Run walk through
the very solve the CLI makes. It imports no viser: tests drive it with an `AppState`
and a list for the messages.

All methods but `on_iteration` run on the worker thread. The solver's own thread calls
`on_iteration`, which records the iteration and waits until the worker has drawn it
(when `follow_iterations`), so the page follows every iteration.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable
from dataclasses import replace
from typing import Any, Literal

import numpy as np

from lightcal.core.problem import ImageData, LightUnknown
from lightcal.core.scene import Rig
from lightcal.core.session import SolverSession
from lightcal.core.solver import CalibrationModel, IterationReport, SolveOutcome
from lightcal.errors import LightcalError
from lightcal.io.project import Project
from lightcal.pipeline import measurements_for, starting_lights, summarise
from lightcal.pipeline.model import solver_options
from lightcal.pipeline.results import stop_reason
from lightcal.pipeline.solve import Calibration, calibrate, start_words
from lightcal_app.requests import Finished
from lightcal_app.results import MISFIT_WORDS
from lightcal_app.selection_service import Notify, SelectionService
from lightcal_app.session_file import session_from_state
from lightcal_app.solve_display import estimate_display, guess_display, pace_wait_s
from lightcal_app.solve_settings import restored_wall
from lightcal_app.state import AppState, Display, LightGuess, PreviousResult

log = logging.getLogger("lightcal.app")


class SolveService:
    """The selection and the solve of the state's project.

    Args:
        state: the shared state.
        notify: shows a message in the page.
        follow_iterations: the solver waits for each iteration to be drawn.
    """

    def __init__(self, state: AppState, *, notify: Notify, follow_iterations: bool = True) -> None:
        self.state = state
        self.notify = notify
        self.follow_iterations = follow_iterations
        self.follow_timeout_s = 10.0
        self.session: SolverSession | None = None
        self.model: CalibrationModel | None = None
        # The model the solve began with: the parameter vector's layout of the history
        # (a later stage's x begins with the same parameters).
        self.first_model: CalibrationModel | None = None
        self._model_index: list[int] = []  # project image of each model image
        self._model_setup_rev = -1  # the state's setup_rev when the model was built
        self.selection = SelectionService(state, notify=notify)
        self._iteration_offset = 0
        self._stage_offset = 0  # added to the iterations of the pipeline's later stages
        self._resuming = False  # the next iteration 0 is the restored estimate
        self._stage_model: CalibrationModel | None = None  # the model being solved
        self._last_session_state = "idle"
        self._shown_at = 0.0  # time.monotonic() when the last iteration was drawn

    # ------------------------------------------------------------------ setup

    def setup_changed(self) -> None:
        """The guess or the selection changed: the solve starts over."""
        self.drop()
        if self.selection.stale():
            self.selection.compute()
        self.show_guess()

    def project_changed(self) -> None:
        """The state shows another project: select its pixels, show its guess."""
        self.drop()
        self.selection.forget()
        self.selection.compute()
        self.show_guess()

    def drop(self) -> None:
        """Throw the solve away (its thread ends)."""
        st = self.state
        with st.cond:
            if (
                st.solver_state in ("converged", "not converged")
                and st.result is not None
                and st.finished_snapshot is not None
            ):
                # Kept, not lost: the page shows it and can bring it back (undo).
                st.previous = PreviousResult(st.finished_snapshot, st.result, st.solver_state)
            st.finished_snapshot = None
            session, self.session, self.model = self.session, None, None
            st.session_gen += 1
            st.history = []
            st.result = None
            st.solver_state = "idle"
            st.solver_message = ""
            self._iteration_offset = 0
            self._last_session_state = "idle"
            st.mark("plots", "status", "result", "widgets")
        if session is not None:
            session.stop()

    def reset(self) -> None:
        """Back to the guess; a restored estimate is forgotten."""
        with self.state.lock:
            self.state.resume_x = None
            self.state.resume_end = None
            self.state.changed = True
        self.drop()
        self.show_guess()

    def close(self) -> None:
        """End the solver's thread."""
        session = self.session
        if session is not None:
            session.stop()

    def running(self) -> bool:
        """A solve is iterating or has news the worker has not taken yet."""
        session = self.session
        return session is not None and (
            session.state == "running" or session.state != self._last_session_state
        )

    def _lights(
        self, project: Project, guess: list[LightGuess], datas: list[ImageData]
    ) -> list[LightUnknown]:
        posed = [
            replace(
                u,
                initial=u.initial.replace(
                    t_camera_light=g.t_camera_light, R_camera_light=g.R_camera_light
                ),
            )
            for u, g in zip(project.lights, guess, strict=True)
        ]
        return starting_lights(project, datas, posed)

    def show_guess(self) -> None:
        """Display the guess, with the scales fitted to the selection."""
        st = self.state
        with st.lock:
            project = st.solve_project
            guess = list(st.guess)
            gen, rev = st.session_gen, st.setup_rev
            datas, _ = self.selection.usable()
        units = self._lights(project, guess, datas)
        display = guess_display(project, Rig(tuple(u.initial for u in units)), rev)
        with st.lock:
            if st.session_gen == gen and st.solve_project is project:
                st.display = display
                st.mark("overlays", "light", "widgets")

    # ------------------------------------------------------------------ the solve

    def build_model(self) -> tuple[CalibrationModel, list[int]] | None:
        """The model of the user's selection and guess (scales fitted), and the project
        index of each of its images; None when no image has pixels."""
        st = self.state
        with st.lock:
            project, loaded = st.solve_project, st.loaded
            guess = list(st.guess)
            datas, index = self.selection.usable()
        if not datas:
            return None
        options = solver_options(project, loaded)  # the fall-off on the images' grid
        lights = self._lights(project, guess, datas)
        p = project
        model = CalibrationModel(
            datas, lights, options, p.wall, p.medium, p.surroundings, p.channels, p.media or None
        )
        return model, index

    def ensure_session(self, client: Any = None) -> bool:
        """Build the model and the solver session if there is none. False (with a
        message) when no image has pixels."""
        if self.session is not None:
            return True
        st = self.state
        with st.lock:
            resume = st.resume_x
            saved_names = list(st.parameter_names)
            history = list(st.history)
            gen, rev = st.session_gen, st.setup_rev
        built = self.build_model()
        if built is None:
            self.notify(
                client,
                "No pixels to fit",
                "No image has usable pixels: check the selection (Pixels tab) and the regions.",
                error=True,
            )
            return False
        model, index = built
        with st.lock:
            project, loaded = st.solve_project, st.loaded
        if resume is not None and history:
            project, model = restored_wall(project, model, saved_names)
        resumed = (
            resume is not None
            and bool(history)
            and resume.shape == (model.layout.n,)
            and saved_names == list(model.layout.names)
        )

        def work(x0: np.ndarray, gate: Callable[[IterationReport], None]) -> Calibration:
            # The CLI's engine; a restored estimate is where its first solve continues.
            return calibrate(
                project,
                loaded,
                model,
                x0=x0 if resumed else None,
                on_iteration=gate,
                on_model=self._solving,
                on_start=self._start_said,
                on_stage=self._stage_said,
            )

        session = SolverSession(
            model,
            on_iteration=lambda rep: self.on_iteration(gen, rep),
            on_finish=lambda out: st.request(Finished(gen, out)),
            work=work,
        )
        offset = 0
        if resumed:
            assert resume is not None
            session.reset(resume)
            offset = history[-1].iteration
        with st.lock:
            if st.session_gen != gen:
                return False
            self.session = session
            self.model = self.first_model = model
            self._model_index = index
            self._model_setup_rev = rev
            self._iteration_offset = offset
            self._stage_offset = offset  # a restored solve numbers on from its history
            self._resuming = bool(offset)
            self._stage_model = model
            if not offset:
                st.history = []
            st.parameter_names = list(model.layout.names)
        return True

    def _stage_said(self, text: str) -> None:
        """The pipeline says what it runs next (a wall it tries, mirror exclusion): the
        status shows it while the solve runs."""
        with self.state.lock:
            self.state.solver_message = f"({text})"
            self.state.mark("status")

    def _start_said(self, k: int, n: int) -> None:
        if n > 1:
            self._stage_said(start_words(k, n))

    def _solving(self, model: CalibrationModel) -> None:
        """The pipeline starts solving `model` (the first, a trimmed one or a wall's): the
        iterations that follow are its (their x are its parameter vectors)."""
        with self.state.lock:
            self._stage_model = model
            self.state.parameter_names = list(model.layout.names)  # a saved x's names

    def estimate_display(self, model: CalibrationModel, x: np.ndarray) -> Display:
        """What the page shows of the estimate `x` (n,)."""
        return estimate_display(
            model,
            x,
            n_images=len(self.state.project.names),
            model_index=self._model_index,
            setup_rev=self._model_setup_rev,
            fall_off=self.state.solve_project.spec.sensor.model,
        )

    def on_iteration(self, gen: int, rep: IterationReport) -> None:
        """Called by the solver's thread: record, then wait until drawn. Every stage of
        the pipeline starts at its own iteration 0 (a random start, the mirror-trimmed
        or another wall's model): numbered on after the last one shown."""
        st = self.state
        model = self._stage_model
        if model is None:
            return
        display = self.estimate_display(model, rep.x)
        session = self.session
        running = session is not None and session.unlimited
        with st.cond:
            if self.follow_iterations and st.history:
                # Run's readable pace: the page shows the previous iteration at least
                # min_iteration_s before this one (a reset or closing ends the wait).
                left = pace_wait_s(running, st.min_iteration_s, time.monotonic() - self._shown_at)
                if left > 0:
                    st.cond.wait_for(lambda: st.session_gen != gen or st.closing, timeout=left)
            if st.session_gen != gen:
                return
            if rep.iteration == 0 and st.history:
                if self._resuming:
                    self._resuming = False
                    return  # the restored estimate, already in the history
                # A later stage's start (a random start, the mirror-trimmed or another
                # wall's model): numbered on after the last iteration shown.
                self._stage_offset = st.history[-1].iteration + 1
            if self._stage_offset:
                rep = replace(rep, iteration=rep.iteration + self._stage_offset)
            st.history.append(rep)
            st.display = display
            st.solver_state = "running"
            st.mark("plots", "status", "light", "overlays", "widgets")
            if self.follow_iterations:
                it = rep.iteration
                st.cond.wait_for(
                    lambda: st.drawn >= (gen, it) or st.session_gen != gen or st.closing,
                    timeout=self.follow_timeout_s,
                )
                self._shown_at = time.monotonic()

    def start(self, how: Literal["step", "run"], client: Any = None) -> None:
        """ "step" (one iteration) or "run" (to convergence)."""
        st = self.state
        with st.lock:
            done = st.solver_state in ("converged", "not converged")
        if done:
            self.notify(client, "The solve has ended", "Press Reset to start again.")
            return
        if not self.ensure_session(client):
            return
        session = self.session
        assert session is not None
        with st.lock:
            st.solver_state = "running"
            st.solver_message = ""
            st.result = None
            st.mark("status", "result")
        if how == "step":
            session.step()
        else:
            session.run()

    def pause(self) -> None:
        if self.session is not None:
            self.session.pause()

    def finished(self, gen: int, outcome: SolveOutcome | Calibration) -> None:
        """The solve `gen` ended: its result with the uncertainties of the images (the
        pipeline's, when it ran the solve; computed here for a restored estimate)."""
        st = self.state
        with st.lock:
            if st.session_gen != gen or self.model is None:
                return
            model, project, loaded = self.model, st.solve_project, st.loaded
        result = None
        if isinstance(outcome, Calibration):
            model, result, outcome = outcome.model, outcome.result, outcome.outcome
        message = outcome.message
        if result is None:
            try:
                # The fit test and the uncertainty with the images' noise and poses.
                result = summarise(model, outcome, measurements_for(project, loaded, model))
            except Exception as exc:
                log.warning("uncertainties failed", exc_info=True)
                message = f"{outcome.message} (uncertainties failed: {type(exc).__name__})"
        with st.lock:
            if st.session_gen != gen:
                return
            # The solved model (mirror-trimmed, or the wall `auto` chose) is the one the
            # page draws and exports from now on.
            self.model = self._stage_model = model
            st.display = self.estimate_display(model, outcome.x)
            st.result, st.result_weights_at = result, model.weights_at
            # One vocabulary: idle, running, paused, converged, not converged (with why).
            converged = result.converged if result is not None else outcome.success
            st.solver_state = "converged" if converged else "not converged"
            st.solver_message = stop_reason(outcome.status, outcome.message) + (
                message.removeprefix(outcome.message)  # e.g. "(uncertainties failed: ...)"
            )
            if result is not None and result.converged and not result.fit_adequate:
                st.solver_message += f"; {MISFIT_WORDS}"
            self._last_session_state = st.solver_state
            st.finished_snapshot = session_from_state(st) if result is not None else None
            st.mark("result", "status", "light", "overlays", changed=True)

    def poll(self) -> None:
        """Take the session's news (paused, failed) into the state."""
        session = self.session
        if session is None:
            return
        state = session.state
        st = self.state
        if state == self._last_session_state:
            return
        self._last_session_state = state
        if state == "paused":
            with st.lock:
                st.solver_state = "paused"
                it = st.history[-1].iteration if st.history else 0
                st.solver_message = f"after iteration {it}"
                st.mark("status", changed=True)
            self.interim_result()
        elif state == "failed":
            error = session.error
            reason = str(error) if isinstance(error, LightcalError) else type(error).__name__
            with st.lock:
                st.solver_state = "not converged"
                st.solver_message = f"the solver failed: {reason}"
                st.mark("status", changed=True)
            log.warning("solver failed: %r", error, exc_info=error)
            self.notify(None, "Solver failed", reason, error=True)

    def interim_result(self) -> None:
        """Uncertainties at the current estimate while the solve is paused."""
        st = self.state
        model, session = self._stage_model or self.model, self.session
        if model is None or session is None:
            return
        with st.lock:
            history = list(st.history)
            gen = st.session_gen
        if not history:
            return
        outcome = SolveOutcome.stopped(history, f"paused after iteration {history[-1].iteration}")
        try:
            result = summarise(model, outcome)
        except Exception:
            log.debug("interim summary failed", exc_info=True)
            return
        with st.lock:
            if st.session_gen == gen:
                st.result = result
                st.mark("result")

    def restore_estimate(self) -> None:
        """After a restore with a history: show its last estimate, ready to continue."""
        st = self.state
        with st.lock:
            resume = st.resume_x
            history = list(st.history)
        if resume is None or not history:
            return
        if not self.ensure_session(None) or self._iteration_offset == 0:
            with st.lock:
                st.history = []
                st.resume_x = None
                st.resume_end = None
                st.mark("plots", "status")
            self.drop()
            self.show_guess()
            return
        assert self.model is not None
        display = self.estimate_display(self.model, resume)
        with st.lock:
            st.history = history
            st.display = display
            end = st.resume_end
            if end is None:
                st.solver_state = "paused"
                st.solver_message = f"restored at iteration {history[-1].iteration}"
            st.mark("plots", "status", "light", "overlays", "widgets")
        if end is None:
            self.interim_result()
            return
        # A finished solve: its status, reason, time and full result (fit test and
        # uncertainties with the images' noise and poses), as when it ended.
        last = history[-1]
        self.model.set_weights_at(end.weights_at)  # as its result was computed
        outcome = SolveOutcome(
            x=resume.copy(),
            status=end.status,
            message=end.message,
            success=end.state == "converged",
            iterations=last.iteration,
            nfev=last.nfev,
            cost=last.cost,
            time_s=end.time_s,
            history=history,
        )
        with st.lock:
            gen = st.session_gen
        self.finished(gen, outcome)
