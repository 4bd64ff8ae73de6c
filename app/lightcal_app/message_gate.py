"""Every widget message from a page, checked against its widget before viser takes it.

viser stores a widget's new value and sends it to every other browser before any
callback of ours runs, casting it to the widget's type on the way (a 24-digit number
becomes a Python int no browser can be sent, so every other page failed). `MessageGate`
sits in front of viser's handler of `GuiUpdateMessage`: only a "value" may change,
and it must fit the widget as built (`check_widget_value`): a button or a checkbox
sends a bool, a number a finite number within the widget's min/max (an integer when its
step is), a vector as many finite numbers as it has, each within its min/max, a
dropdown one of its options. A refused value never reaches viser: the sender's widget
is set back to the value it had and the page is told why (`refuse`).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Coroutine
from typing import Any

from lightcal.errors import InputError
from lightcal_app.limits import MAX_INT, MAX_NAME_LENGTH

Refuse = Callable[[int, str, str], None]
"""`refuse(client id, widget label, reason)`."""


def _number(label: str, value: object, low: Any, high: Any, integer: bool) -> float | int:
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise InputError(label, f"expected a number, got {str(value)[:40]!r}")
    low = -MAX_INT if low is None else low
    high = MAX_INT if high is None else high
    kind = "an integer" if integer else "a number"
    ok = math.isfinite(value) and low <= value <= high and (not integer or value == int(value))
    if not ok:
        shown = f"{value:.6g}" if isinstance(value, float) else str(value)[:40]
        raise InputError(label, f"expected {kind} from {low:g} to {high:g}, got {shown}")
    return int(value) if integer else float(value)


def _at(bound: Any, k: int) -> Any:
    return bound[k] if isinstance(bound, tuple | list) else bound


def check_widget_value(state: Any, value: object) -> object:
    """`value` as the widget of `state` (viser's `handle._impl`) takes it; InputError
    naming the widget's label when it does not fit."""
    props = state.props
    label = str(getattr(props, "label", "") or "value")
    current = state.value
    if state.is_button or isinstance(current, bool):
        if not isinstance(value, bool):
            raise InputError(label, f"expected true or false, got {str(value)[:40]!r}")
        return value
    options = getattr(props, "options", None)
    if options is not None:
        if not isinstance(value, str) or len(value) > MAX_NAME_LENGTH or value not in options:
            raise InputError(label, f"expected one of the choices offered, got {str(value)[:60]!r}")
        return value
    low, high = getattr(props, "min", None), getattr(props, "max", None)
    if isinstance(current, tuple):
        if not isinstance(value, list | tuple) or len(value) != len(current):
            raise InputError(label, f"expected {len(current)} numbers, got {str(value)[:60]}")
        return tuple(
            _number(label, v, _at(low, k), _at(high, k), False) for k, v in enumerate(value)
        )
    if isinstance(current, int | float):
        step = getattr(props, "step", None)
        integer = isinstance(current, int) and (step is None or float(step) == int(step))
        return _number(label, value, low, high, integer)
    raise InputError(label, "this control takes no value from a page")


class MessageGate:
    """Installed in front of viser's `GuiUpdateMessage` handler of `server`.

    Args:
        server: the viser server (its widgets are server-level).
        refuse: told of each refused message.
    """

    def __init__(self, server: Any, refuse: Refuse) -> None:
        from viser import _messages

        self.server = server
        self.refuse = refuse
        self._message_cls = _messages.GuiUpdateMessage
        ws = server._websock_server
        handlers = ws._incoming_handlers[_messages.GuiUpdateMessage]
        self._viser: list[Callable[[int, Any], Coroutine | None]] = list(handlers)
        handlers[:] = [self.on_update]

    def _widget(self, uuid: str) -> Any:
        handle = self.server.gui._gui_input_handle_from_uuid.get(uuid)
        return None if handle is None else handle._impl

    async def on_update(self, client_id: int, message: Any) -> None:
        """A page changed a widget: pass it on to viser checked, or refuse it."""
        state = self._widget(message.uuid)
        if state is not None and not state.removed:
            try:
                if set(message.updates) != {"value"}:
                    raise InputError(str(state.props.label), "only the value may change")
                value = check_widget_value(state, message.updates["value"])
            except InputError as exc:
                self._reset(client_id, state)
                self.refuse(client_id, str(state.props.label), str(exc))
                return
            message = self._message_cls(message.uuid, {"value": value})
        for handler in self._viser:
            result = handler(client_id, message)
            if result is not None:
                await result

    def _reset(self, client_id: int, state: Any) -> None:
        """The sender's widget shows the value it had again."""
        client = self.server.get_clients().get(client_id)
        if client is not None and not state.is_button:
            client._websock_connection.queue_message(
                self._message_cls(state.uuid, {"value": state.value})
            )
