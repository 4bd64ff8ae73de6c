"""The app's one worker thread: it takes the queued requests in order and draws.

Callbacks (viser's thread pool, any browser) only change `AppState` under its lock and
queue typed requests (`lightcal_app.requests`). The worker takes them in order, merges
repeated ones, hands each to the handler registered for its type, then lets the solve
report its state (`poll`), draws what is dirty (`redraw`, given a `Frame`) and runs
`after` (the autosave). So several browsers clicking at once can neither corrupt the
state nor start two solves. Nothing here knows viser.
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable, Mapping
from typing import Any

from lightcal.errors import LightcalError
from lightcal_app.requests import Request, client_of, merge, work_of
from lightcal_app.state import AppState, Frame, take_frame

log = logging.getLogger("lightcal.app")

REPEAT_S = 60.0
"""An internal error is shown again at most this often."""

Notify = Callable[..., None]
"""`notify(client, title, body, *, error=False)`: a message in the page."""


class Worker:
    """The thread that handles requests and redraws.

    Args:
        state: the shared state (its `requests`, `dirty` and `cond`).
        handlers: per request type, the function that handles it.
        redraw: draws a frame.
        notify: shows a message in the page.
        poll: called after the requests of each round (the solve's state).
        after: called at the end of each round (the autosave).
        running: True while a solve runs (for `wait_idle`).
        show_work: shows what the worker is doing ("" when it is idle), called from
            the worker before the work, so that the page says it while it lasts.
    """

    def __init__(
        self,
        state: AppState,
        *,
        handlers: Mapping[type, Callable[[Any], None]],
        redraw: Callable[[Frame], None],
        notify: Notify,
        poll: Callable[[], None] = lambda: None,
        after: Callable[[], None] = lambda: None,
        running: Callable[[], bool] = lambda: False,
        show_work: Callable[[str], None] = lambda text: None,
    ) -> None:
        self.state = state
        self.handlers = dict(handlers)
        self.redraw = redraw
        self.notify = notify
        self.poll = poll
        self.after = after
        self.running = running
        self.show_work = show_work
        self._shown_work = ""
        self.busy = False  # handling requests or drawing
        self._reported: dict[str, float] = {}  # internal error -> when last shown
        self._thread = threading.Thread(target=self._loop, name="lightcal-app-worker", daemon=True)

    def start(self) -> None:
        self._thread.start()

    def stop(self, timeout: float = 10.0) -> None:
        """Ask the loop to end and wait for it."""
        st = self.state
        with st.cond:
            st.closing = True
            st.cond.notify_all()
        if self._thread.is_alive():
            self._thread.join(timeout=timeout)

    def wait_idle(self, timeout: float = 30.0) -> bool:
        """Block until no request is queued, nothing is dirty and no solve runs (tests and
        benchmarks). True if that happened within `timeout`."""
        st = self.state
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            with st.lock:
                busy = bool(st.requests) or bool(st.dirty) or self.busy
            if not busy and not self.running():
                with st.lock:
                    if not st.requests and not st.dirty and not self.busy:
                        return True
            time.sleep(0.01)
        return False

    def handle(self, request: Request) -> None:
        """Run one request's handler; an expected failure is a message to who asked."""
        handler = self.handlers.get(type(request))
        if handler is None:
            raise TypeError(f"no handler for {type(request).__name__}")
        try:
            handler(request)
        except LightcalError as exc:
            self.notify(client_of(request), "Not possible", str(exc), error=True)

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
                self.busy = True
            try:
                self._round(requests)
            finally:
                with st.cond:
                    self.busy = False
                    st.cond.notify_all()

    def _say(self, text: str) -> None:
        if text != self._shown_work:
            self._shown_work = text
            try:
                self.show_work(text)
            except Exception:  # the busy line is a courtesy: never stop the work for it
                log.debug("busy line failed", exc_info=True)

    def _round(self, requests: list[Request]) -> None:
        st = self.state
        merged = merge(requests)
        with st.lock:
            drawing = bool(st.dirty & {"overlays", "selection", "scene"})
        work = list(dict.fromkeys(work_of(r) for r in merged))
        if drawing:
            work.append("drawing the pictures")
        if work:
            self._say("; ".join(work))
        try:
            for request in merged:
                self.handle(request)
            self.poll()
            with st.lock:
                frame = take_frame(st) if st.dirty else None
            if frame is not None:
                self.redraw(frame)
        except Exception as exc:  # never let the worker die
            self._internal_error(exc)
        try:
            self.after()
        except Exception as exc:
            self._internal_error(exc)
        with st.lock:
            idle = not st.requests and not st.dirty
        if idle:
            self._say("solving" if self.running() else "")

    def _internal_error(self, exc: Exception) -> None:
        """Log it; show it in the page unless the same error was shown in the last
        `REPEAT_S` seconds (the message's own redraw must not start a loop of errors)."""
        text = f"{type(exc).__name__}: {exc}"
        now = time.monotonic()
        if now - self._reported.get(text, -REPEAT_S) < REPEAT_S:
            log.debug("worker error (again): %s", text)
            return
        log.exception("worker error")
        self._reported = {k: t for k, t in self._reported.items() if now - t < REPEAT_S}
        self._reported[text] = now
        self.notify(None, "Internal error", text, error=True)
