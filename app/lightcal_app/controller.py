"""The app's machinery in one place: the user's actions, the worker, the services, the
redraw and the messages in the page.

`Controller` is what the panels talk to. It inherits the user's actions (`Actions`:
state changes and queued requests), and wires each request type to the service that
handles it on the worker thread: the solve (`SolveService`), files and sessions
(`FilesService`). The worker draws with `Redrawer` inside `server.atomic()`.
"""

from __future__ import annotations

import logging
from pathlib import Path
from typing import Any

from lightcal.io.project import Project
from lightcal.pipeline import LoadedImages
from lightcal_app import requests as rq
from lightcal_app.actions import Actions
from lightcal_app.files_service import FilesService
from lightcal_app.overlays import OverlayImages
from lightcal_app.photo_service import PhotoService
from lightcal_app.plan_service import PlanService
from lightcal_app.redraw import Redrawer
from lightcal_app.scene3d import Scene3D
from lightcal_app.session_file import SessionFile
from lightcal_app.solve_service import SolveService
from lightcal_app.state import AppState, LightGuess
from lightcal_app.text import public
from lightcal_app.uploads import MAX_UPLOAD_BYTES
from lightcal_app.worker import Worker

log = logging.getLogger("lightcal.app")


class Controller(Actions):
    """Actions, services, the worker thread and the redraw.

    Args:
        server: the viser server.
        state: the shared state.
        truth: true light poses (demo mode) or None.
        session_path: where the session is autosaved (None: no autosave).
        state_dir: folder for uploads and sessions of read-only projects.
        follow_iterations: the solver waits for each iteration to be drawn.
        upload_limit_bytes: the per-file upload cap.
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
        upload_limit_bytes: int = MAX_UPLOAD_BYTES,
    ) -> None:
        self.server = server
        self.scene = Scene3D(server, on_gizmo=self.on_gizmo)
        super().__init__(state, planes=self.scene.pickable_planes, notify=self.notify)
        self.redrawer = Redrawer(
            server, state, self.scene, OverlayImages(state.project, state.loaded)
        )
        self.redrawer.truth = truth
        self.solve = SolveService(state, notify=self.notify, follow_iterations=follow_iterations)
        self.files = FilesService(
            state,
            self.solve,
            notify=self.notify,
            deliver=_deliver,
            on_switch=self._on_switch,
            truth=truth,
            session_path=session_path,
            state_dir=state_dir,
            upload_limit_bytes=upload_limit_bytes,
        )
        self.plan = PlanService(state, self.solve, notify=self.notify, say=self._show_work)
        # A new project from photos (the Files tab's "New project from photos").
        self.photos = PhotoService(self.files, notify=self.notify, show_work=self._show_work)
        self.startup_notes: list[tuple[str, str]] = []
        solve, files, plan = self.solve, self.files, self.plan
        self.worker = Worker(
            state,
            handlers={
                rq.SetupChanged: lambda r: solve.setup_changed(),
                rq.Solve: lambda r: solve.start(r.how, r.client),
                rq.Pause: lambda r: solve.pause(),
                rq.Reset: lambda r: solve.reset(),
                rq.Finished: lambda r: solve.finished(r.gen, r.outcome),
                rq.PrepareDownload: files.download,
                rq.SaveSession: files.save_session,
                rq.LoadSavedSession: files.load_saved_session,
                rq.RestorePrevious: files.restore_previous,
                rq.ApplySession: files.apply_session,
                rq.SwitchProject: files.switch_project,
                rq.PlanViews: plan.plan,
                rq.BuildPhotoProject: self.photos.build,
            },
            redraw=self.redrawer.redraw,
            notify=self.notify,
            poll=solve.poll,
            after=self._after_round,
            running=solve.running,
            show_work=self._show_work,
        )

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

    def _on_switch(
        self, project: Project, loaded: LoadedImages, truth: list[LightGuess] | None
    ) -> None:
        self.redrawer.truth = truth
        self.redrawer.set_overlays(OverlayImages(project, loaded))

    # ------------------------------------------------------------------ lifecycle

    def start(self, restored: SessionFile | None = None, *, source: str = "") -> None:
        """Compute the first selection (from a restored session if given), then start the
        worker thread, whose first redraw builds the scene."""
        if restored is not None:
            self.files.restore(restored, None, source)
        else:
            self.solve.setup_changed()
        self.worker.start()

    def close(self) -> None:
        """Stop the solve and the worker; write the last autosave."""
        self.worker.stop()
        self.solve.close()
        self.files.autosave(force=True)

    def wait_idle(self, timeout: float = 30.0) -> bool:
        """Block until no request is queued, nothing is dirty and the solve is not running
        (tests and benchmarks). True if that happened within `timeout`."""
        return self.worker.wait_idle(timeout)

    def _after_round(self) -> None:
        """The end of each worker round: the autosave, then the Plan tab's read-out."""
        self.files.autosave()
        self.plan.refresh()

    def _show_work(self, text: str) -> None:
        """The page's busy line (set from the worker; nothing before the GUI exists)."""
        panels = self.redrawer.panels
        if panels is not None:
            panels.show_work(text)

    # ------------------------------------------------------------------ messages

    def notify(self, client: Any, title: str, body: str, *, error: bool = False) -> None:
        """A message in the page: a notification (for `client`, else every browser) and
        the messages box (everyone). Any server folder is cut from the text here, once,
        for both (notifications show plain text; the box escapes it for markdown)."""
        title, body = public(title), public(body)
        st = self.state
        with st.lock:
            st.messages = [*st.messages[-5:], (("⚠ " if error else "") + title, body)]
            st.mark("status")
        targets = [client] if client is not None else list(self.server.get_clients().values())
        for c in targets:
            try:
                c.add_notification(
                    title,
                    body,
                    color="red" if error else "blue",
                    auto_close_seconds=None if error else 8.0,
                )
            except Exception:  # a browser that just left
                log.debug("notification failed", exc_info=True)


def _deliver(client: Any, name: str, content: bytes) -> None:
    client.send_file_download(name, content, save_immediately=True)
