"""What every tab's panel shares: the "programmatic write" flag and widget helpers.

Every handle is server-level (`server.gui`), so all browsers see the same panel. The
callbacks only call `Controller` actions (state changes under the lock, queued
requests); each panel's `update` writes the state back into its widgets during a
redraw. Those writes fire the widgets' own callbacks with `client None`; a thread-local
flag, shared by all panels, makes those callbacks ignore them, so they are not taken
for user edits.

Users' edits are one ordered stream, told apart from the panels' writes by time, not by
value: viser stamps a widget (`update_timestamp`) when a browser's value arrives, on its
event loop, in arrival order, and again when a panel writes it. `Programmatic` keeps per
widget the stamp of the last value that is no pending edit (the panels' write, or an edit
its callback applied). A newer stamp is a user's edit on its way: a redraw leaves that
widget alone, and its callback, whenever viser's thread pool runs it, applies the
widget's latest value under one lock (one edit at a time) and records its stamp; a late
callback of an edit applied already finds nothing newer and does nothing. An edit back to
the value the panels last wrote (A, B, A) is still an edit: its stamp is newer.
"""

from __future__ import annotations

import threading
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import Any

import viser

from lightcal.errors import LightcalError
from lightcal_app.controller import Controller
from lightcal_app.text import md_prose

_BUTTONS = (viser.GuiButtonHandle, viser.GuiButtonGroupHandle, viser.GuiUploadButtonHandle)


def _same(a: Any, b: Any) -> bool:
    try:
        return bool(a == b)
    except (TypeError, ValueError):  # arrays: compared element-wise
        return False


def rounded(v: float, digits: int) -> float:
    """`v` rounded for a widget (a plain float)."""
    return float(round(float(v), digits))


class Programmatic:
    """The panels' own widget writes, told apart from users' edits (see the module).

    - A thread-local flag: writes inside `writing()` are not user edits (their callbacks
      ignore them, see `TabPanel.guard`).
    - Per widget, the viser stamp (`update_timestamp`) of its last value that is no
      pending edit. `pending`: the widget holds a newer one, a user's edit whose callback
      has not applied it yet: `assign` leaves it alone. `begin` / `done` bracket the
      callback that applies it; `stream()` makes those callbacks one ordered stream.
    """

    def __init__(self) -> None:
        self._local = threading.local()
        self._lock = threading.Lock()
        self._stream = threading.RLock()
        # id(handle) -> (the handle, the stamp of its last value that is no pending edit).
        # Handles are unhashable; the reference kept here keeps an id from passing to a
        # newer widget.
        self._applied: dict[int, tuple[Any, float]] = {}

    @contextmanager
    def writing(self) -> Iterator[None]:
        old = getattr(self._local, "on", False)
        self._local.on = True
        try:
            yield
        finally:
            self._local.on = old

    def active(self) -> bool:
        return bool(getattr(self._local, "on", False))

    @contextmanager
    def stream(self) -> Iterator[None]:
        """One user edit applied at a time (callbacks run in viser's thread pool)."""
        with self._stream:
            yield

    @staticmethod
    def stamp(handle: Any) -> float:
        """When the widget's value last changed (viser's `update_timestamp`)."""
        return float(getattr(handle, "update_timestamp", 0.0))

    def pending(self, handle: Any) -> bool:
        """The widget holds a user's edit that no callback has applied yet."""
        with self._lock:
            seen = self._applied.get(id(handle))
        return seen is not None and self.stamp(handle) > seen[1]

    def assign(self, handle: Any, value: Any) -> None:
        """Set a widget's value (viser sends it to every browser and fires its callbacks),
        unless it holds that value already or a user's edit of it is on its way."""
        if self.pending(handle):
            return  # its callback applies it, then a redraw writes the state back
        if not _same(handle.value, value):
            handle.value = value
        self.record(handle)

    def record(self, handle: Any) -> None:
        """The widget's value is no user's pending edit (written by a panel, or by viser
        itself, e.g. when new options no longer hold the old value)."""
        with self._lock:
            seen = self._applied.get(id(handle))
            stamp = max(self.stamp(handle), seen[1] if seen is not None else 0.0)
            self._applied[id(handle)] = (handle, stamp)

    def begin(self, handle: Any) -> float | None:
        """A callback starts: the stamp of the user's edit it is to apply, or None when
        there is none (an earlier callback applied the widget's value already)."""
        with self._lock:
            seen = self._applied.get(id(handle))
        stamp = self.stamp(handle)
        if seen is not None and stamp <= seen[1]:
            return None
        return stamp

    def done(self, handle: Any, stamp: float) -> None:
        """The edit stamped `stamp` reached the state (or was refused): the next redraw
        writes the state's value, unless a newer edit is on its way."""
        with self._lock:
            seen = self._applied.get(id(handle))
            if seen is None or stamp > seen[1]:
                self._applied[id(handle)] = (handle, stamp)


class TabPanel:
    """A tab's widgets and their callbacks.

    Args:
        server: the viser server.
        ctl: where user actions go.
        flag: the shared programmatic-write flag.
    """

    def __init__(self, server: viser.ViserServer, ctl: Controller, flag: Programmatic) -> None:
        self.server = server
        self.gui = server.gui
        self.ctl = ctl
        self.flag = flag

    def guard(self, fn: Callable[[Any], None]) -> Callable[[Any], None]:
        """`fn` called for user edits only (not for the panel's own writes), one at a
        time, each edit once (see the module)."""

        def cb(event: Any) -> None:
            if event.client is None and self.flag.active():
                self.flag.record(event.target)  # the panels' own write, not an edit
                return
            button = isinstance(event.target, _BUTTONS)  # a click, not a value
            with self.flag.stream():
                stamp = None if button else self.flag.begin(event.target)
                if not button and stamp is None:
                    return  # an earlier callback applied this widget's value
                edited = event.target.value
                try:
                    fn(event)
                except LightcalError as exc:
                    # Refused in the page, with the reason; the widgets show the state again.
                    self.ctl.notify(event.client, "Value refused", str(exc), error=True)
                except (ValueError, TypeError, KeyError, IndexError, OverflowError):
                    # A value no widget of this page can send (a choice not offered, a
                    # string for a number): a page speaking for itself. Refused.
                    self.ctl.notify(
                        event.client,
                        "Value refused",
                        f"{str(edited)[:60]!r} is not a value this control takes",
                        error=True,
                    )
                finally:
                    # The edit is in the state, or refused: the next redraw (one is marked
                    # here, after `done`) writes the widget from the state again.
                    if stamp is not None:
                        self.flag.done(event.target, stamp)
                    self.ctl.state.mark("widgets")

        return cb


class LiveText:
    """A markdown that redraws fill and a callback can mark stale until the next one.

    A callback marks it *before* it queues the work, so the worker's redraw, which comes
    after, always replaces the mark with the fresh text (or the old one, when the edit
    was refused).

    Args:
        gui: where to add the markdown.
        text: the first text.
    """

    def __init__(self, gui: Any, text: str = "") -> None:
        self.handle = gui.add_markdown(text)
        self.text = text
        self.marked = False

    def show(self, text: str) -> None:
        """The fresh text (a redraw); clears the mark."""
        if text != self.text or self.marked:
            self.text, self.marked = text, False
            self.handle.content = text

    def mark_stale(self, work: str) -> None:
        """Say that `work` is under way and the text below is from before it."""
        self.marked = True
        self.handle.content = f"**⟳ updating** ({md_prose(work)}); until then, as before:  \n" + (
            self.text
        )
