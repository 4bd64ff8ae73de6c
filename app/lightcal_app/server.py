"""Build and run the app: `build_app(project)` gives a running `LightcalApp`.

The server binds 127.0.0.1 unless told otherwise and never opens viser's share tunnel
(its button is hidden). Everything the browsers see is server-level, so every browser
shows the same state and a late joiner gets the current one.
"""

from __future__ import annotations

import contextlib
import io
import os
import signal
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import viser

from lightcal.errors import InputError, LightcalError
from lightcal.io.project import load_project
from lightcal.pipeline import load_images
from lightcal.resources import sample_project_dir
from lightcal_app.access import AccessGuard, guard_handshakes
from lightcal_app.controller import Controller
from lightcal_app.demo_truth import read_truth_lights, truth_path_for
from lightcal_app.message_gate import MessageGate
from lightcal_app.panels import Panels
from lightcal_app.session_file import SessionFile, default_session_path, read_session
from lightcal_app.state import AppState
from lightcal_app.transfer_guard import TransferGuard
from lightcal_app.uploads import MAX_UPLOAD_BYTES


def default_project_path() -> Path:
    """The bundled sample project (installed: package data; checkout: sample_data/)."""
    return sample_project_dir() / "project.json"


def default_state_dir() -> Path:
    """`$XDG_STATE_HOME/lightcal` (default ~/.local/state/lightcal)."""
    base = os.environ.get("XDG_STATE_HOME") or str(Path.home() / ".local" / "state")
    return Path(base) / "lightcal"


def disable_share_tunnel(server: viser.ViserServer) -> None:
    """Never open viser's share tunnel (to an outside service): hide its button (done by
    `Panels`), drop the browser's share requests and disable the method."""
    from viser import _messages

    ws = server._websock_server
    for message_cls in (_messages.ShareUrlRequest, _messages.ShareUrlDisconnect):
        if message_cls in ws._incoming_handlers:
            ws.unregister_handler(message_cls)

    def refuse(*args: Any, **kwargs: Any) -> None:
        raise RuntimeError("lightcal app: the share tunnel is disabled")

    setattr(server, "request_share_url", refuse)  # noqa: B010


@dataclass
class LightcalApp:
    """A running app.

    Attributes:
        server: the viser server.
        state: the shared state.
        controller: actions and the worker thread.
        panels: the GUI handles.
        url: where to open it (with the access token when one is needed).
        access: who may connect.
    """

    server: viser.ViserServer
    state: AppState
    controller: Controller
    panels: Panels
    url: str
    access: AccessGuard

    def wait_idle(self, timeout: float = 30.0) -> bool:
        """Block until every queued request is handled and drawn."""
        return self.controller.wait_idle(timeout)

    def close(self) -> None:
        """Stop the worker, the solve and the server (writes the last autosave)."""
        self.controller.close()
        self.server.stop()


def keep_aside(path: Path) -> Path:
    """Rename `path` to a new name beside it, `<name>.<UTC time>[-n].json`; returns it."""
    stamp = time.strftime("%Y%m%dT%H%M%SZ", time.gmtime())
    stem = path.name.removesuffix(".json")
    for n in range(1000):
        target = path.with_name(f"{stem}.{stamp}{f'-{n}' if n else ''}.json")
        try:
            os.link(path, target)  # never replaces: fails when the name is taken
        except FileExistsError:
            continue
        except OSError:  # a file system without hard links
            if target.exists():
                continue
            path.rename(target)
            return target
        path.unlink()
        return target
    raise InputError(path, "cannot keep the earlier session aside: 1000 names taken")


def build_app(
    project_path: str | Path,
    *,
    host: str = "127.0.0.1",
    port: int = 8080,
    demo: bool = False,
    session_path: Path | bool | None = True,
    restore: bool = True,
    state_dir: Path | None = None,
    follow_iterations: bool = True,
    upload_limit_bytes: int = MAX_UPLOAD_BYTES,
    say: Callable[[str], None] | None = None,
) -> LightcalApp:
    """Load a project and start the app's server.

    Args:
        project_path: the project file.
        host: interface to bind (127.0.0.1: this machine only).
        port: TCP port (0: any free port; viser takes the next free one when busy).
        demo: show the true light from `truth.json` beside the project; with the default
            `session_path`, start from the project's guess (no restore) and autosave to
            `<stem>.demo-session.json`, so a demo neither reopens a solved session nor
            overwrites the user's.
        session_path: the autosave file; True: the default (beside the project), False
            or None: no autosave.
        restore: restore the autosaved session when it exists.
        state_dir: folder for uploads (default `default_state_dir()`).
        follow_iterations: the solver waits for each iteration to be drawn.
        upload_limit_bytes: the per-file upload cap.
        say: told each step of the start in a few words (the terminal's progress).

    Raises:
        InputError: the project, its images or the truth file cannot be read.
    """
    path = Path(project_path).resolve()
    tell = say if say is not None else (lambda text: None)
    start = time.perf_counter()
    project = load_project(path)
    tell(f"reading the {len(project.names)} images of {path.name}")
    loaded = load_images(project)
    tell(f"images read ({time.perf_counter() - start:.1f} s); building the scene")
    truth = None
    if demo:
        truth = read_truth_lights(truth_path_for(path))
        if len(truth) != len(project.lights):
            raise InputError(
                truth_path_for(path),
                f"lights: {len(truth)} true lights but the project has {len(project.lights)}",
            )
    state_dir = state_dir if state_dir is not None else default_state_dir()
    if session_path is True and demo:
        # A demo starts from the project's guess every time, and autosaves beside the
        # user's own session, never over it.
        own = default_session_path(path, state_dir)
        session_file: Path | None = own.with_name(own.name.replace(".session.", ".demo-session."))
        restore = False
    elif session_path is True:
        session_file = default_session_path(path, state_dir)
    elif session_path is False or session_path is None:
        session_file = None
    else:
        session_file = Path(session_path)
    restored: SessionFile | None = None
    notes: list[tuple[str, str]] = []
    if not restore and not demo and session_file is not None and session_file.is_file():
        # Not restored, and not lost either: the autosave would replace it.
        kept = keep_aside(session_file)
        notes.append(
            ("Session kept", f"The earlier session was not restored; it is kept as {kept.name}.")
        )
    if restore and session_file is not None and session_file.is_file():
        try:
            restored = read_session(session_file)
        except LightcalError as exc:
            bad = session_file.with_suffix(session_file.suffix + ".bad")
            with contextlib.suppress(OSError):
                session_file.replace(bad)
            notes.append(("Session not restored", f"{exc}. The file was kept as {bad.name}."))

    access = AccessGuard.for_host(host)
    with contextlib.redirect_stdout(io.StringIO()), guard_handshakes(access):
        # viser's banner goes nowhere: we print the URL (with the token).
        server = viser.ViserServer(host=host, port=port, verbose=False)
    disable_share_tunnel(server)
    state = AppState(project, loaded)
    controller = Controller(
        server,
        state,
        truth=truth,
        session_path=session_file,
        state_dir=state_dir,
        follow_iterations=follow_iterations,
        upload_limit_bytes=upload_limit_bytes,
    )

    def reject(client_id: int, filename: str, reason: str) -> None:
        client = server.get_clients().get(client_id)
        controller.notify(
            client, f"Upload rejected: {filename}", f"{filename}: {reason}", error=True
        )

    TransferGuard(server, reject, limit=upload_limit_bytes)

    def refuse(client_id: int, label: str, reason: str) -> None:
        controller.notify(server.get_clients().get(client_id), "Value refused", reason, error=True)

    MessageGate(server, refuse)
    panels = Panels(server, controller)
    controller.panels = panels
    source = session_file.name if session_file is not None else ""
    controller.start(restored, source=source)
    if restored is not None:
        notes.append(
            (
                "Session restored",
                f"Your previous session (saved {restored.saved_at}) was restored from "
                f"{source}. To begin anew, start `lightcal app --fresh`.",
            )
        )
    controller.startup_notes = notes
    tell(f"scene built ({time.perf_counter() - start:.1f} s); the first pictures render now")

    @server.on_client_connect
    def _(client: Any) -> None:
        for title, body in controller.startup_notes:
            client.add_notification(title, body, auto_close_seconds=12.0)

    shown_host = "127.0.0.1" if host in ("0.0.0.0", "::", "") else host
    if ":" in shown_host:
        shown_host = f"[{shown_host}]"
    url = f"http://{shown_host}:{server.get_port()}{access.url_suffix()}"
    return LightcalApp(server, state, controller, panels, url, access)


def serve_forever(app: LightcalApp, on_ready: Callable[[], None] | None = None) -> None:
    """Keep the app running until Ctrl-C or SIGTERM, then close it (the final autosave
    runs in both cases). `on_ready` runs once SIGTERM is handled (e.g. to print the URL:
    a SIGTERM before that would end the process without the final autosave)."""
    stop = threading.Event()
    previous = None
    if threading.current_thread() is threading.main_thread():
        previous = signal.signal(signal.SIGTERM, lambda signum, frame: stop.set())
    if on_ready is not None:
        on_ready()
    try:
        while not stop.wait(1.0):
            pass
    finally:
        app.close()
        if previous is not None:
            signal.signal(signal.SIGTERM, previous)
