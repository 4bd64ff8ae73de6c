"""Bounds on upload bytes held by the server while files arrive.

viser buffers every part of an upload in memory until the last one arrives, and trusts
the size the browser announces. `TransferGuard` watches viser's own upload messages:

- a transfer announced over the per-file limit, or beyond `max_transfers` at once
  from one browser, is dropped when it starts;
- before each part is buffered, the bytes received so far are counted against the
  size announced (a part that would pass it drops the transfer), against the per-file
  limit, against `per_client_bytes` for that browser's transfers together and against
  `total_bytes` for all browsers: a part over any of them drops its transfer.

A dropped transfer is forgotten (its parts are freed and the rest are ignored) and the
page is told why.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from lightcal_app.upload_checks import format_size

Reject = Callable[[int, str, str], None]
"""`reject(client id, file name, reason)`."""


class TransferGuard:
    """The upload bounds of one server.

    Args:
        server: the viser server.
        on_reject: told of each dropped transfer.
        limit: bytes per file.
        per_client_bytes: bytes in flight per browser.
        total_bytes: bytes in flight for all browsers.
        max_transfers: transfers at once per browser.
    """

    def __init__(
        self,
        server: Any,
        on_reject: Reject,
        *,
        limit: int,
        per_client_bytes: int | None = None,
        total_bytes: int | None = None,
        max_transfers: int = 4,
    ) -> None:
        self.on_reject = on_reject
        self.limit = limit
        self.per_client_bytes = per_client_bytes if per_client_bytes is not None else 2 * limit
        self.total_bytes = total_bytes if total_bytes is not None else 4 * limit
        self.max_transfers = max_transfers
        self._states: dict[str, dict[str, Any]] = server.gui._current_file_upload_states
        self._install(server._websock_server)

    def _install(self, ws: Any) -> None:
        from viser import _messages

        # After viser's own start handler (it creates the transfer), before its part
        # handler (which buffers the part): both run on the event loop, in list order.
        ws.register_handler(_messages.FileTransferStartUpload, self.on_start)
        ws._incoming_handlers.setdefault(_messages.FileTransferPart, []).insert(0, self.on_part)

    def _drop(self, transfer: str, reason: str) -> None:
        state = self._states.pop(transfer, None)
        if state is not None:
            self.on_reject(int(state["client_id"]), str(state["filename"]), reason)

    def on_start(self, client_id: int, message: Any) -> None:
        """A transfer starts (viser has just created its state)."""
        transfer = message.transfer_uuid
        if transfer not in self._states:
            return
        mine = [s for s in self._states.values() if s["client_id"] == client_id]
        if int(message.size_bytes) > self.limit:
            self._drop(
                transfer,
                f"the file is {format_size(int(message.size_bytes))}; uploads are limited to "
                f"{format_size(self.limit)} per file",
            )
        elif len(mine) > self.max_transfers:
            self._drop(transfer, f"at most {self.max_transfers} uploads at once")

    def on_part(self, client_id: int, message: Any) -> None:
        """A part arrives, before viser buffers it."""
        transfer = message.transfer_uuid
        state = self._states.get(transfer)
        if state is None:
            return
        n = len(message.content)
        received = int(state["transferred_bytes"]) + n
        mine = sum(
            int(s["transferred_bytes"])
            for s in self._states.values()
            if s["client_id"] == client_id
        )
        everyone = sum(int(s["transferred_bytes"]) for s in self._states.values())
        if received > int(state["total_bytes"]):
            self._drop(transfer, "more bytes arrived than the upload announced")
        elif received > self.limit:
            self._drop(transfer, f"uploads are limited to {format_size(self.limit)} per file")
        elif mine + n > self.per_client_bytes or everyone + n > self.total_bytes:
            self._drop(transfer, "too many uploads at once; try again when the others are done")
