"""The app's one worker thread: it owns the solve and every redraw.

Callbacks (viser's thread pool, any browser) call the `Controller`'s action methods,
which only change `AppState` under its lock and queue requests. The worker thread
takes the requests in order, merges repeated ones, (re)computes the pixel selection,
drives the one `SolverSession` (step, run, pause, reset) and redraws what is dirty
inside `server.atomic()`, so several browsers clicking at once can neither corrupt the
state nor start two solves. The solver's own thread only records each iteration and
waits until the worker has drawn it (so the overlays follow every iteration).
"""

from __future__ import annotations

import logging
import threading
import time
import traceback
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

from lightcal.core.problem import ImageData, LightUnknown
from lightcal.core.scene import Rig
from lightcal.core.session import SolverSession
from lightcal.core.solver import CalibrationModel, IterationReport, SolveOutcome
from lightcal.errors import LightcalError
from lightcal.io.project import Project
from lightcal.pipeline import LoadedImages, fit_scales, measurements_for, summarise
from lightcal_app.actions import Actions
from lightcal_app.overlays import OverlayImages
from lightcal_app.pixel_selection import footprint_centres, project_with_selection, select_image
from lightcal_app.redraw import Redrawer
from lightcal_app.results import report_zip_bytes, result_json_bytes
from lightcal_app.scene3d import Scene3D
from lightcal_app.session_file import (
    SessionFile,
    apply_session,
    default_session_path,
    read_session,
    session_from_state,
    session_json,
    write_session,
)
from lightcal_app.state import (
    ALL_DIRT,
    AppState,
    Display,
    Download,
    LightGuess,
    take_frame,
)

log = logging.getLogger("lightcal.app")

# Requests handled once when several are queued (the first; it reads the latest state).
_MERGED = frozenset(("setup_changed",))
AUTOSAVE_INTERVAL_S = 0.5


class Controller(Actions):
    """State changes, the worker thread and the redraw.

    Args:
        server: the viser server.
        state: the shared state.
        truth: true light poses (demo mode) or None.
        session_path: where the session is autosaved (None: no autosave).
        state_dir: folder for uploads and sessions of read-only projects.
        follow_iterations: the solver waits for each iteration to be drawn.
    """

    def __init__(
        self,
        server: Any,
        state: AppState,
        *,
        truth: list[LightGuess] | None,
        session_path: Path | None,
        state_dir: Path,
        follow_iterations: bool = True,
    ) -> None:
        self.server = server
        self.state = state
        self.truth = truth
        self.session_path = session_path
        self.state_dir = state_dir
        self.upload_root = state_dir / "uploads"
        self.follow_iterations = follow_iterations
        self.follow_timeout_s = 10.0
        self.scene = Scene3D(server, on_gizmo=self._on_gizmo)
        self.redrawer = Redrawer(
            server, state, self.scene, OverlayImages(state.project, state.loaded)
        )
        self.redrawer.truth = truth
        self.session: SolverSession | None = None
        self.model: CalibrationModel | None = None
        self._model_index: list[int] = []
        self._image_data: list[ImageData | None] = [None] * len(state.project.names)
        self._selection_done = -1
        self._iteration_offset = 0
        self._last_autosave = 0.0
        self._last_session_state = "idle"
        self.startup_notes: list[tuple[str, str]] = []
        self._busy = False  # the worker is handling requests or drawing
        self._thread = threading.Thread(target=self._loop, name="lightcal-app-worker", daemon=True)

    @property
    def panels(self) -> Any:
        """The GUI (set by `lightcal_app.server` once it exists)."""
        return self.redrawer.panels

    @panels.setter
    def panels(self, panels: Any) -> None:
        self.redrawer.panels = panels

    @property
    def overlays(self) -> OverlayImages:
        """The pictures of the current project."""
        return self.redrawer.overlays

    @property
    def timings(self) -> dict[str, float]:
        """Seconds spent by the last redraw: pictures_s, send_s, redraw_s."""
        return self.redrawer.timings

    # ------------------------------------------------------------------ lifecycle

    def start(self, restored: SessionFile | None = None, *, source: str = "") -> None:
        """Compute the first selection (from a restored session if given), then start the
        worker thread, whose first redraw builds the scene."""
        if restored is not None:
            self._apply_session(restored, None, source)
        else:
            self._on_setup_changed()
        self._thread.start()

    def close(self) -> None:
        """Stop the solve and the worker; write the last autosave."""
        st = self.state
        with st.cond:
            st.closing = True
            st.cond.notify_all()
        if self._thread.is_alive():
            self._thread.join(timeout=10)
        session = self.session
        if session is not None:
            session.stop()
        self._autosave(force=True)

    def wait_idle(self, timeout: float = 30.0) -> bool:
        """Block until no request is queued, nothing is dirty and the solve is not running
        (tests and benchmarks). True if that happened within `timeout`."""
        st = self.state
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            with st.lock:
                busy = bool(st.requests) or bool(st.dirty) or self._busy
                session = self.session
            running = session is not None and (
                session.state == "running" or session.state != self._last_session_state
            )
            if not busy and not running:
                with st.lock:
                    if not st.requests and not st.dirty and not self._busy:
                        return True
            time.sleep(0.01)
        return False

    # ------------------------------------------------------------------ the worker

    def _loop(self) -> None:
        st = self.state
        while True:
            with st.cond:
                st.cond.wait_for(
                    lambda: st.closing or bool(st.requests) or bool(st.dirty), timeout=0.25
                )
                if st.closing:
                    return
                requests = list(st.requests)
                st.requests.clear()
                self._busy = True
            try:
                for kind, payload in _merge(requests):
                    self._handle(kind, payload)
                self._poll_session()
                with st.lock:
                    frame = take_frame(st) if st.dirty else None
                if frame is not None:
                    self.redrawer.redraw(frame)
                self._autosave()
            except Exception as exc:  # never let the worker die
                log.error("worker error: %s", traceback.format_exc())
                self.notify(None, "Internal error", f"{type(exc).__name__}: {exc}", error=True)
            finally:
                with st.cond:
                    self._busy = False
                    st.cond.notify_all()

    def _handle(self, kind: str, payload: dict[str, Any]) -> None:
        try:
            getattr(self, f"_do_{kind}")(**payload)
        except LightcalError as exc:
            self.notify(payload.get("client"), "Not possible", str(exc), error=True)

    # -- setup ---------------------------------------------------------------------------

    def _do_setup_changed(self) -> None:
        self._on_setup_changed()

    def _on_setup_changed(self) -> None:
        self._drop_session()
        st = self.state
        with st.lock:
            need = st.selection_rev != self._selection_done
        if need:
            self._compute_selection()
        self._set_guess_display()

    def _drop_session(self) -> None:
        st = self.state
        with st.cond:
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

    def _compute_selection(self) -> None:
        st = self.state
        with st.lock:
            project, loaded = st.project, st.loaded
            rev = st.selection_rev
            settings = [st.selection_of(i) for i in range(len(project.names))]
            regions = list(st.regions)
            points = [list(st.points.get(n, [])) for n in project.names]
        datas: list[ImageData | None] = []
        for i in range(len(project.names)):
            try:
                datas.append(select_image(project, loaded, i, settings[i], regions, points[i]))
            except LightcalError as exc:
                datas.append(None)
                self.notify(None, f"Selection failed for {project.names[i]}", str(exc), error=True)
        with st.lock:
            if st.project is not project:
                return
            self._image_data = datas
            self._selection_done = rev
            st.selected = [
                d.footprints.pixels if d is not None else np.zeros((0, 2), np.int64) for d in datas
            ]
            st.selected_binning = [s.binning if s.strategy == "all" else 1 for s in settings]
            st.selected_wall_points = [
                footprint_centres(d) if d is not None else np.zeros((0, 3)) for d in datas
            ]
            st.mark("selection", "light", "status")

    def _usable_data(self) -> tuple[list[ImageData], list[int]]:
        datas, index = [], []
        for i, d in enumerate(self._image_data):
            if d is not None and len(d.observed) > 0:
                datas.append(d)
                index.append(i)
        return datas, index

    def _unknowns(
        self, project: Project, guess: list[LightGuess], datas: list[ImageData]
    ) -> list[LightUnknown]:
        units = []
        for u, g in zip(project.lights, guess, strict=True):
            light = u.initial.replace(t_camera_light=g.position_m, R_camera_light=g.R_camera_light)
            units.append(replace(u, initial=light))
        auto = [j for j, ls in enumerate(project.spec.lights) if ls.initial.scale is None]
        if auto and datas:
            scales = fit_scales(datas, units, project.solver.offset, project.wall.initial)
            for j in auto:
                units[j] = replace(units[j], initial=units[j].initial.replace(scale=scales[j]))
        return units

    def _set_guess_display(self) -> None:
        st = self.state
        with st.lock:
            project = st.project
            guess = list(st.guess)
            gen = st.session_gen
            datas, _ = self._usable_data()
        units = self._unknowns(project, guess, datas)
        display = Display(
            Rig(tuple(u.initial for u in units)),
            tuple(1.0 for _ in project.names),
            project.solver.offset,
            "guess",
        )
        with st.lock:
            if st.session_gen == gen and st.project is project:
                st.display = display
                st.mark("overlays", "light", "widgets")

    # -- solve -----------------------------------------------------------------------------

    def _ensure_session(self, client: Any) -> bool:
        if self.session is not None:
            return True
        st = self.state
        with st.lock:
            project = st.project
            guess = list(st.guess)
            datas, index = self._usable_data()
            resume = st.resume_x
            saved_names = list(st.parameter_names)
            history = list(st.history)
            gen = st.session_gen
        if not datas:
            self.notify(
                client,
                "No pixels to fit",
                "No image has usable pixels: check the selection (Pixels tab) and the regions.",
                error=True,
            )
            return False
        units = self._unknowns(project, guess, datas)
        model = CalibrationModel(datas, units, project.solver, project.wall)
        session = SolverSession(
            model,
            on_iteration=lambda rep: self._on_iteration(gen, model, rep),
            on_finish=lambda out: st.request("finished", gen=gen, outcome=out),
        )
        offset = 0
        if (
            resume is not None
            and history
            and resume.shape == (model.layout.n,)
            and saved_names == list(model.layout.names)
        ):
            session.reset(resume)
            offset = history[-1].iteration
        with st.lock:
            if st.session_gen != gen:
                return False
            self.session = session
            self.model = model
            self._model_index = index
            self._iteration_offset = offset
            if not offset:
                st.history = []
            st.parameter_names = list(model.layout.names)
        return True

    def _estimate_display(self, model: CalibrationModel, x: np.ndarray) -> Display:
        gains = np.ones(len(self.state.project.names))
        g_model = model.layout.gain_factors(x)
        for k, i in enumerate(self._model_index):
            gains[i] = g_model[k]
        return Display(
            model.layout.rig(x), tuple(float(g) for g in gains), model.layout.offset(x), "estimate"
        )

    def _on_iteration(self, gen: int, model: CalibrationModel, rep: IterationReport) -> None:
        """Called by the solver's thread: record, then wait until drawn."""
        st = self.state
        display = self._estimate_display(model, rep.x)
        with st.cond:
            if st.session_gen != gen:
                return
            if self._iteration_offset:
                if rep.iteration == 0:
                    return  # the restored estimate, already in the history
                rep = replace(rep, iteration=rep.iteration + self._iteration_offset)
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

    def _do_step(self, client: Any = None) -> None:
        self._start_solving("step", client)

    def _do_run(self, client: Any = None) -> None:
        self._start_solving("run", client)

    def _start_solving(self, how: str, client: Any) -> None:
        st = self.state
        with st.lock:
            done = st.solver_state in ("finished", "stopped", "failed")
        if done:
            self.notify(client, "The solve has ended", "Press Reset to start again.")
            return
        if not self._ensure_session(client):
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

    def _do_pause(self, client: Any = None) -> None:
        if self.session is not None:
            self.session.pause()

    def _do_reset(self, client: Any = None) -> None:
        with self.state.lock:
            self.state.resume_x = None
            self.state.changed = True
        self._drop_session()
        self._set_guess_display()

    def _do_finished(self, gen: int, outcome: SolveOutcome) -> None:
        st = self.state
        with st.lock:
            if st.session_gen != gen or self.model is None:
                return
            model = self.model
            project, loaded = st.project, st.loaded
        result = None
        message = outcome.message
        try:
            # The fit test and the uncertainty with the images' noise and pose covariances.
            result = summarise(model, outcome, measurements_for(project, loaded, model))
        except Exception as exc:
            message = f"{outcome.message} (uncertainties failed: {exc})"
        with st.lock:
            if st.session_gen != gen:
                return
            st.result = result
            st.solver_state = "stopped" if outcome.status == -2 else "finished"
            st.solver_message = message
            self._last_session_state = st.solver_state
            st.mark("result", "status", changed=True)

    def _poll_session(self) -> None:
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
            self._interim_result()
        elif state == "failed":
            with st.lock:
                st.solver_state = "failed"
                st.solver_message = f"the solver failed: {session.error}"
                st.mark("status", changed=True)
            self.notify(None, "Solver failed", str(session.error), error=True)

    def _interim_result(self) -> None:
        """Uncertainties at the current estimate while the solve is paused."""
        st = self.state
        model, session = self.model, self.session
        if model is None or session is None:
            return
        with st.lock:
            history = list(st.history)
            gen = st.session_gen
        if not history:
            return
        last = history[-1]
        outcome = SolveOutcome(
            last.x.copy(),
            -2,
            f"paused after iteration {last.iteration}",
            False,
            last.iteration,
            last.nfev,
            last.cost,
            0.0,
            history,
        )
        try:
            result = summarise(model, outcome)
        except Exception:
            log.debug("interim summary failed", exc_info=True)
            return
        with st.lock:
            if st.session_gen == gen:
                st.result = result
                st.mark("result")

    # -- files -------------------------------------------------------------------------------

    def _send(self, client: Any, name: str, content: bytes) -> None:
        with self.state.lock:
            self.state.downloads = [*self.state.downloads[-4:], Download(name, content)]
        if client is not None:
            client.send_file_download(name, content, save_immediately=True)

    def _do_download(self, what: str, client: Any = None) -> None:
        st = self.state
        with st.lock:
            result, project, loaded, model = st.result, st.project, st.loaded, self.model
            settings, regions = st.selection, list(st.regions)
        stem = project.path.stem
        if what == "session":
            with st.lock:
                text = session_json(session_from_state(st))
            self._send(client, f"{stem}.session.json", text.encode())
            return
        if result is None or model is None:
            self.notify(client, "No result yet", "Run the solver first (Solve tab).")
            return
        if what == "result":
            self._send(client, f"{stem}.result.json", result_json_bytes(result, project))
        elif what == "report":
            self.notify(client, "Preparing the report", "Rendering every image at full size...")
            proj = project_with_selection(project, settings, regions)
            self._send(client, f"{stem}.report.zip", report_zip_bytes(proj, loaded, model, result))

    def saved_session_path(self) -> Path:
        """Where "Save session" writes."""
        project = self.state.project.path
        base = self.session_path if self.session_path is not None else project
        return base.parent / f"{project.stem}.saved-session.json"

    def _do_save_session(self, client: Any = None) -> None:
        st = self.state
        with st.lock:
            session = session_from_state(st)
        path = self.saved_session_path()
        write_session(session, path)
        self.notify(client, "Session saved", f"Written to {path}; also sent as a download.")
        self._send(client, path.name, session_json(session).encode())

    def _do_load_saved_session(self, client: Any = None) -> None:
        path = self.saved_session_path()
        self._apply_session(read_session(path), client, str(path))

    def _do_apply_session(self, session: SessionFile, client: Any = None, source: str = "") -> None:
        self._apply_session(session, client, source)

    def _apply_session(self, session: SessionFile, client: Any, source: str) -> list[str]:
        self._drop_session()
        st = self.state
        with st.lock:
            warnings = apply_session(st, session)
            st.resume_x = st.history[-1].x.copy() if st.history else None
            st.setup_rev += 1
            st.selection_rev += 1
            st.mark(*ALL_DIRT, changed=True)
        self._compute_selection()
        self._set_guess_display()
        self._restore_estimate()
        body = f"Restored from {source}." + "".join(f"\n- {w}" for w in warnings)
        self.notify(client, "Session restored", body)
        return warnings

    def _restore_estimate(self) -> None:
        """After a restore with a history: show its last estimate, ready to continue."""
        st = self.state
        with st.lock:
            resume = st.resume_x
            history = list(st.history)
        if resume is None or not history:
            return
        if not self._ensure_session(None) or self._iteration_offset == 0:
            with st.lock:
                st.history = []
                st.resume_x = None
                st.mark("plots", "status")
            self._drop_session()
            self._set_guess_display()
            return
        assert self.model is not None
        display = self._estimate_display(self.model, resume)
        with st.lock:
            st.history = history
            st.display = display
            st.solver_state = "paused"
            st.solver_message = f"restored at iteration {history[-1].iteration}"
            st.mark("plots", "status", "light", "overlays", "widgets")
        self._interim_result()

    def _do_switch_project(
        self,
        project: Project,
        loaded: LoadedImages,
        truth: list[LightGuess] | None,
        keep: bool,
        client: Any = None,
        note: str = "",
    ) -> None:
        self._drop_session()
        st = self.state
        with st.lock:
            saved = session_from_state(st) if keep else None
            st.load_project(project, loaded)
            if saved is not None:
                apply_session(st, saved.model_copy(update={"solve": None}))
            self.truth = truth
            self.redrawer.truth = truth
            self.redrawer.set_overlays(OverlayImages(project, loaded))
            self._image_data = [None] * len(project.names)
            self._selection_done = -1
            if not keep:
                self.session_path = default_session_path(project.path, self.state_dir)
            st.selection_rev += 1
            st.mark(*ALL_DIRT, changed=True)
        self._compute_selection()
        self._set_guess_display()
        self.notify(client, "Project updated", note or f"Now showing {project.path}.")

    def _autosave(self, *, force: bool = False) -> None:
        if self.session_path is None:
            return
        st = self.state
        now = time.monotonic()
        with st.lock:
            if not st.changed or (not force and now - self._last_autosave < AUTOSAVE_INTERVAL_S):
                return
            if st.solver_state == "running" and not force:
                return
            session = session_from_state(st)
            st.changed = False
        self._last_autosave = now
        try:
            write_session(session, self.session_path)
        except OSError as exc:
            log.warning("autosave failed: %s", exc)


def _merge(requests: list[tuple[str, dict[str, Any]]]) -> list[tuple[str, dict[str, Any]]]:
    """Keep the order but only the first of each merged kind (it reads the latest state)."""
    seen: set[str] = set()
    out = []
    for kind, payload in requests:
        if kind in _MERGED:
            if kind in seen:
                continue
            seen.add(kind)
        out.append((kind, payload))
    return out
