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


def assign(handle: Any, value: Any) -> None:
    """Set a widget's value (viser sends it to every browser and fires its callbacks),
    unless it holds that value already: a redraw that rewrites every widget from the state
    then leaves alone the ones a user is editing at that moment."""
    try:
        same = bool(handle.value == value)
    except (TypeError, ValueError):  # arrays: compared element-wise
        same = False
    if not same:
        handle.value = value


def rounded(v: float, digits: int) -> float:
    """`v` rounded for a widget (a plain float)."""
    return float(round(float(v), digits))


class Programmatic:
    """A thread-local flag: widget writes inside `writing()` are not user edits."""

    def __init__(self) -> None:
        self._local = threading.local()

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
                return
            try:
                fn(event)
            except LightcalError as exc:
                # Refused in the page, with the reason; the widgets show the state again.
                self.ctl.notify(event.client, "Value refused", str(exc), error=True)
                self.ctl.state.mark("widgets")
            except (ValueError, TypeError, KeyError, IndexError, OverflowError):
                # A value no widget of this page can send (a choice not offered, a string
                # for a number): a page speaking for itself. Refused; nothing changed.
                value = getattr(getattr(event, "target", None), "value", None)
                self.ctl.notify(
                    event.client,
                    "Value refused",
                    f"{str(value)[:60]!r} is not a value this control takes",
                    error=True,
                )
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
