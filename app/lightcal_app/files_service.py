"""Files in and out of the page, without a browser: uploads, downloads, sessions.

`FilesService` checks uploads with the project readers (`lightcal_app.uploads`) and
queues the project switch, prepares downloads (result, report, session), saves and
restores sessions, and autosaves the session after changes. It imports no viser: a
download goes to `deliver(client, name, bytes)` and messages to `notify`.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any, TypeVar

from lightcal.errors import LightcalError
from lightcal.io.project import Project
from lightcal.pipeline import LoadedImages
from lightcal_app.demo_truth import read_truth_lights, truth_path_for
from lightcal_app.pixel_selection import project_with_selection
from lightcal_app.requests import (
    ApplySession,
    LoadSavedSession,
    PrepareDownload,
    RestorePrevious,
    SaveSession,
    SwitchProject,
)
from lightcal_app.results import export_download, report_zip_bytes, result_json_bytes
from lightcal_app.session_file import (
    SessionFile,
    apply_session,
    default_session_path,
    parse_session,
    read_session,
    remove_stale_temps,
    session_from_state,
    session_json,
    write_session,
)
from lightcal_app.solve_service import Notify, SolveService
from lightcal_app.state import ALL_DIRT, AppState, Download, LightGuess
from lightcal_app.upload_checks import format_size, project_paths
from lightcal_app.uploads import (
    MAX_UPLOAD_BYTES,
    Place,
    receive_image,
    receive_project,
    receive_rid,
)

log = logging.getLogger("lightcal.app")

T = TypeVar("T")


def received_or_refused(
    notify: Notify, client: Any, name: str, receive: Callable[[], T]
) -> T | None:
    """`receive()` for the upload `name`; None when it refuses it, with the reason in the
    page (a reader's unexpected failure: the exception's kind only, details in the log)."""
    try:
        return receive()
    except LightcalError as exc:
        notify(client, f"Upload rejected: {name}", str(exc), error=True)
    except Exception as exc:  # a reader's unexpected failure: no details in the page
        log.warning("upload %r failed", name, exc_info=True)
        reason = f"{name}: the file could not be read ({type(exc).__name__})"
        notify(client, f"Upload rejected: {name}", reason, error=True)
    return None


AUTOSAVE_INTERVAL_S = 0.5

Deliver = Callable[[Any, str, bytes], None]
"""`deliver(client, name, content)`: send a file to one browser."""


class FilesService:
    """Uploads, downloads and sessions of the app.

    Args:
        state: the shared state.
        solve: the solve (its model goes into the report; a restore drops it).
        notify: shows a message in the page.
        deliver: sends a file to a browser (called only when a browser asked).
        on_switch: told the new project's images and truth after a project switch.
        truth: the true lights (demo mode) or None.
        session_path: the autosave file (None: no autosave).
        state_dir: folder for uploads and for sessions of read-only projects.
        upload_limit_bytes: the per-file upload cap.
    """

    def __init__(
        self,
        state: AppState,
        solve: SolveService,
        *,
        notify: Notify,
        deliver: Deliver,
        on_switch: Callable[[Project, LoadedImages, list[LightGuess] | None], None],
        truth: list[LightGuess] | None,
        session_path: Path | None,
        state_dir: Path,
        upload_limit_bytes: int = MAX_UPLOAD_BYTES,
    ) -> None:
        self.state = state
        self.solve = solve
        self.notify = notify
        self.deliver = deliver
        self.on_switch = on_switch
        self.truth = truth
        self.session_path = session_path
        self.state_dir = state_dir
        self.upload_root = state_dir / "uploads"
        self.upload_limit = upload_limit_bytes
        self._last_autosave = 0.0
        self._autosave_failed = False
        for path in (session_path, self.saved_session_path()):
            if path is not None:
                remove_stale_temps(path)

    # ------------------------------------------------------------------ uploads

    def kept_folders(self) -> tuple[Path, ...]:
        """The folders the project shown reads from (never removed to make room)."""
        with self.state.lock:
            project = self.state.project
        folder = project.folder
        return (folder, *((folder / p).parent for _, p in project_paths(project.spec)))

    def _place(self) -> Place:
        """Where uploads go; the folders the project shown reads from stay."""
        return Place(self.upload_root, self.upload_limit, self.kept_folders())

    def _upload(self, name: str, client: Any, receive: Callable[[], SwitchProject]) -> None:
        request = received_or_refused(self.notify, client, name, receive)
        if request is not None:
            self.state.request(request)

    def upload_project(self, name: str, content: bytes, client: Any = None) -> None:
        """A project (zip or project file) replaces the one shown."""

        def receive() -> SwitchProject:
            project, loaded = receive_project(name, content, self._place())
            truth = None
            truth_file = truth_path_for(project.path)
            if self.truth is not None and truth_file.is_file():  # demo mode: its ghost too
                truth = read_truth_lights(truth_file)
                if len(truth) != len(project.lights):
                    truth = None
            note = f"Project {name} loaded: {len(project.names)} images."
            return SwitchProject(project, loaded, truth, False, note, client=client)

        self._upload(name, client, receive)

    def upload_image(self, name: str, content: bytes, client: Any = None) -> None:
        """An image replaces the project image of the same file name."""

        def receive() -> SwitchProject:
            with self.state.lock:
                project = self.state.project
            new, loaded, index = receive_image(name, content, project, self._place())
            note = f"Image {project.names[index]} replaced by {name}."
            return SwitchProject(new, loaded, self.truth, True, note, client=client)

        self._upload(name, client, receive)

    def upload_rid(self, name: str, content: bytes, light: str, client: Any = None) -> None:
        """An IES/LDT file becomes the RID of the light named `light`."""

        def receive() -> SwitchProject:
            with self.state.lock:
                project = self.state.project
            names = [u.initial.name for u in project.lights]
            j = names.index(light) if light in names else 0
            new, loaded = receive_rid(name, content, project, j, self._place())
            note = f"Light {names[j]} now uses the RID of {name}."
            return SwitchProject(new, loaded, self.truth, True, note, client=client)

        self._upload(name, client, receive)

    def upload_session(self, name: str, content: bytes, client: Any = None) -> None:
        """A session file to restore."""
        try:
            session = parse_session(content, name)
        except LightcalError as exc:
            self.notify(client, "Session not loaded", str(exc), error=True)
            return
        self.state.request(ApplySession(session, name, client=client))

    def switch_project(self, req: SwitchProject) -> None:
        """Show the request's project (worker)."""
        self.solve.drop()
        st = self.state
        with st.lock:
            saved = session_from_state(st) if req.keep else None
            st.load_project(req.project, req.loaded)
            if saved is not None:
                apply_session(st, saved.model_copy(update={"solve": None}))
            self.truth = req.truth
            self.on_switch(req.project, req.loaded, req.truth)
            if not req.keep:
                self.session_path = default_session_path(req.project.path, self.state_dir)
            st.selection_rev += 1
            st.mark(*ALL_DIRT, changed=True)
        self.solve.project_changed()
        self.notify(req.client, "Project updated", req.note or "Another project is shown.")

    # ------------------------------------------------------------------ downloads

    def _send(self, client: Any, name: str, content: bytes) -> None:
        with self.state.lock:
            self.state.downloads = [*self.state.downloads[-4:], Download(name, content)]
        if client is not None:
            self.deliver(client, name, content)

    def download(self, req: PrepareDownload) -> None:
        """Prepare the result, the report or the session for the browser (worker)."""
        st, client = self.state, req.client
        with st.lock:
            result, project, loaded, model = st.result, st.project, st.loaded, self.solve.model
            settings, regions = st.selection, list(st.regions)
        stem = project.path.stem
        if req.what == "session":
            with st.lock:
                text = session_json(session_from_state(st))
            self._send(client, f"{stem}.session.json", text.encode())
            return
        if result is None or model is None:
            self.notify(client, "No result yet", "Run the solver first (Solve tab).")
            return
        if req.what == "result":
            self._send(client, f"{stem}.result.json", result_json_bytes(result, project))
        elif req.what == "export":
            name, content = export_download(result, project, req.export_format or "")
            self._send(client, name, content)
        elif req.what == "report":
            self.notify(client, "Preparing the report", "Rendering every image...")
            proj = project_with_selection(project, settings, regions)
            name = f"{stem}.report.zip"
            try:
                content = report_zip_bytes(proj, loaded, model, result, full_size=req.full_size)
            except Exception as exc:  # said in place of "Preparing the report"
                log.warning("report failed", exc_info=True)
                self.notify(client, "Report failed", f"{type(exc).__name__}: {exc}", error=True)
                return
            self._send(client, name, content)
            size = format_size(len(content))
            self.notify(client, "Report ready", f"{name} ({size}) sent as a download.")

    # ------------------------------------------------------------------ sessions

    def saved_session_path(self) -> Path:
        """Where "Save session" writes."""
        project = self.state.project.path
        base = self.session_path if self.session_path is not None else project
        return base.parent / f"{project.stem}.saved-session.json"

    def save_session(self, req: SaveSession) -> None:
        st = self.state
        with st.lock:
            session = session_from_state(st)
        path = self.saved_session_path()
        write_session(session, path)
        self.notify(
            req.client, "Session saved", f"Written as {path.name}; also sent as a download."
        )
        self._send(req.client, path.name, session_json(session).encode())

    def load_saved_session(self, req: LoadSavedSession) -> None:
        path = self.saved_session_path()
        self.restore(read_session(path), req.client, path.name)

    def apply_session(self, req: ApplySession) -> None:
        self.restore(req.session, req.client, req.source)

    def restore_previous(self, req: RestorePrevious) -> None:
        """Undo: the finished result an edit replaced, with the settings it had. The
        draft it replaces becomes the previous result in turn only if it had finished."""
        with self.state.lock:
            previous, self.state.previous = self.state.previous, None
        if previous is None:
            self.notify(req.client, "Nothing to restore", "No earlier result is kept.")
            return
        self.restore(
            previous.session, req.client, "the previous result", title="Previous result restored"
        )

    def restore(
        self, session: SessionFile, client: Any, source: str, *, title: str = "Session restored"
    ) -> list[str]:
        """Put a session into the state and continue its solve where it stopped."""
        self.solve.drop()
        st = self.state
        with st.lock:
            st.resume_end = None
            warnings = apply_session(st, session)
            st.resume_x = st.history[-1].x.copy() if st.history else None
            st.setup_rev += 1
            st.selection_rev += 1
            st.mark(*ALL_DIRT, changed=True)
        self.solve.selection.compute()
        self.solve.show_guess()
        self.solve.restore_estimate()
        body = f"Restored from {source}." + "".join(f"\n- {w}" for w in warnings)
        self.notify(client, title, body)
        return warnings

    def autosave(self, *, force: bool = False) -> None:
        """Write the session when it changed (at most every `AUTOSAVE_INTERVAL_S`, not
        while the solver runs, unless `force`). A failure keeps the last good file and
        says so once in the page, until a save works again."""
        if self.session_path is None:
            return
        st = self.state
        now = time.monotonic()
        with st.lock:
            if not st.changed or (not force and now - self._last_autosave < AUTOSAVE_INTERVAL_S):
                return
            if st.solver_state == "running" and not force:
                return
            st.changed = False  # a failure waits for the next change: no loop of retries
            try:
                session: SessionFile | None = session_from_state(st)
            except Exception as exc:
                session, error = None, exc
        self._last_autosave = now
        if session is not None:
            try:
                write_session(session, self.session_path)
                self._autosave_failed = False
                return
            except Exception as exc:
                error = exc
        log.warning("autosave failed: %r", error)
        if not self._autosave_failed:
            self._autosave_failed = True
            self.notify(
                None,
                "Autosave failed",
                f"The session could not be saved ({type(error).__name__}); the last saved "
                "file is kept. Use Files > Save session to try again.",
                error=True,
            )
