"""What every tab's panel shares: the "programmatic write" flag and widget helpers.

Every handle is server-level (`server.gui`), so all browsers see the same panel. The
callbacks only call `Controller` actions (state changes under the lock, queued
requests); each panel's `update` writes the state back into its widgets during a
redraw. Those writes fire the widgets' own callbacks with `client None`; a thread-local
flag, shared by all panels, makes those callbacks ignore them, so they are not taken
for user edits.
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
    """The panels' own widget writes, told apart from users' edits.

    - A thread-local flag: writes inside `writing()` are not user edits (their callbacks
      ignore them, see `TabPanel.guard`).
    - Per widget, its last value that did not come from a user (a redraw's, or one
      written inside `writing()`). A widget that holds another value was edited by a
      user since, and that edit is on its way to the state: viser stores a browser's
      value, then runs the widget's callbacks on a worker thread, which reads it back.
      A redraw in between leaves such a widget alone (`assign`), so it does not undo the
      edit before the callback has read it. The callback's end `release`s the widget:
      the next redraw writes it from the state again, whatever it holds (a refused or a
      normalised value). A callback that starts when its widget holds no pending edit
      any more does nothing (`taken`): an earlier one applied the value.
    """

    def __init__(self) -> None:
        self._local = threading.local()
        self._lock = threading.Lock()
        # id(handle) -> (the handle, its last value not from a user). Handles are
        # unhashable; the reference kept here keeps an id from passing to a newer widget.
        self._written: dict[int, tuple[Any, Any]] = {}

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

    def assign(self, handle: Any, value: Any) -> None:
        """Set a widget's value (viser sends it to every browser and fires its callbacks),
        unless it holds that value already or a user's edit of it has not reached the
        state yet (see the class)."""
        current = handle.value
        with self._lock:
            seen = self._written.get(id(handle))
        if seen is not None and not _same(current, seen[1]):
            return  # a user's edit on its way to the state: its callback releases it
        if not _same(current, value):
            handle.value = value
        self.record(handle)

    def record(self, handle: Any) -> None:
        """The widget's value is not a user's (written by a panel, or by viser itself, e.g.
        when new options no longer hold the old value)."""
        with self._lock:
            self._written[id(handle)] = (handle, handle.value)

    def taken(self, handle: Any) -> bool:
        """The widget holds a value that is no user's pending edit: one an earlier
        callback read and brought to the state, or one the panels wrote. A callback that
        starts after that (viser's pool runs them late) has no edit of its own left to
        apply, and must not take the panels' value for one."""
        with self._lock:
            seen = self._written.get(id(handle))
        return seen is not None and _same(handle.value, seen[1])

    def release(self, handle: Any, edited: Any) -> None:
        """A user's edit of `handle` to the value `edited` reached the state (or was
        refused): the next redraw writes the state's value (a normalised one, or the old
        one after a refusal). A widget that holds another value by now was edited again,
        and stays left alone until that edit's callback ends."""
        with self._lock:
            if _same(handle.value, edited):
                self._written[id(handle)] = (handle, edited)


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
        """`fn` called for user edits only (not for the panel's own writes)."""

        def cb(event: Any) -> None:
            if event.client is None and self.flag.active():
                self.flag.record(event.target)  # the panels' own write, not an edit
                return
            button = isinstance(event.target, _BUTTONS)  # a click, not a value
            if not button and self.flag.taken(event.target):
                return
            edited = event.target.value
            try:
                fn(event)
            except LightcalError as exc:
                # Refused in the page, with the reason; the widgets show the state again.
                self.ctl.notify(event.client, "Value refused", str(exc), error=True)
            except (ValueError, TypeError, KeyError, IndexError, OverflowError):
                # A value no widget of this page can send (a choice not offered, a string
                # for a number): a page speaking for itself. Refused; nothing changed.
                self.ctl.notify(
                    event.client,
                    "Value refused",
                    f"{str(edited)[:60]!r} is not a value this control takes",
                    error=True,
                )
            finally:
                # The edit is in the state, or refused: the next redraw (one is marked
                # here, after the release) writes the widget from the state again.
                if not button:
                    self.flag.release(event.target, edited)
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
