"""Who may talk to the server: the page's own origin, and the access token off loopback.

Every HTTP request and websocket handshake goes through `AccessGuard.check` before
viser sees it (`guard_handshakes` puts it in front of viser's own `process_request`):

- The `Host` header must name this machine when the server listens on loopback only
  (a DNS-rebinding page resolves its own name to 127.0.0.1), and an `Origin` header,
  which every browser sends with a websocket handshake, must be the page's own origin:
  a page from another site cannot open the websocket and press buttons.
- When the server listens on another interface, every request must carry the access
  token, as a notebook server's: `?token=...` in the URL printed at start (the answer
  sets it as a cookie, so the page's own requests carry it), or that cookie.

A refused request gets 403 with one line saying why; nothing of the app is served.
"""

from __future__ import annotations

import hmac
import http
import ipaddress
import secrets
import threading
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from http.cookies import CookieError, SimpleCookie
from typing import Any
from urllib.parse import parse_qs, urlsplit

COOKIE = "lightcal_token"
LOOPBACK_NAMES = frozenset(("localhost", "127.0.0.1", "::1"))


def is_loopback(host: str) -> bool:
    """True when `host` (an interface to bind) is this machine only."""
    if host in LOOPBACK_NAMES:
        return True
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return False


def _host_name(netloc: str) -> str:
    """The host of 'host:port' or '[v6]:port', lower case, without brackets."""
    return (urlsplit(f"//{netloc}").hostname or "").lower()


class AccessGuard:
    """The checks of one server.

    Args:
        host: the interface the server binds.
        token: the access token (None: none required, for loopback).
    """

    def __init__(self, host: str, *, token: str | None) -> None:
        self.host = host
        self.token = token
        self.loopback = is_loopback(host)

    @classmethod
    def for_host(cls, host: str) -> AccessGuard:
        """No token on loopback; a fresh random token on any other interface."""
        return cls(host, token=None if is_loopback(host) else secrets.token_urlsafe(24))

    def url_suffix(self) -> str:
        """What the printed URL ends with ('/?token=...' or '')."""
        return f"/?token={self.token}" if self.token else ""

    def refusal(self, path: str, headers: Any) -> str | None:
        """Why a request is refused (None: allowed).

        Args:
            path: the request target, with its query.
            headers: the request headers (`get(name)`).
        """
        host = headers.get("Host") or ""
        if self.loopback and _host_name(host) not in LOOPBACK_NAMES:
            return "this app answers only requests to localhost"
        origin = headers.get("Origin")
        if origin is not None:
            parts = urlsplit(origin)
            if parts.scheme not in ("http", "https") or parts.netloc.lower() != host.lower():
                return "requests from another web page (origin) are refused"
        if self.token is not None and not self._has_token(path, headers):
            return "open the app with the URL printed at start (it holds the access token)"
        return None

    def _has_token(self, path: str, headers: Any) -> bool:
        assert self.token is not None
        given = parse_qs(urlsplit(path).query).get("token", [])
        try:
            cookie = SimpleCookie(headers.get("Cookie") or "")
        except CookieError:
            cookie = SimpleCookie()
        if COOKIE in cookie:
            given.append(cookie[COOKIE].value)
        return any(hmac.compare_digest(g.encode(), self.token.encode()) for g in given)

    def process_request(self, connection: Any, request: Any, inner: Callable | None) -> Any:
        """A websockets `process_request`: refuse, or let `inner` (viser's) answer and
        set the token cookie on the answer."""
        reason = self.refusal(request.path, request.headers)
        if reason is not None:
            return connection.respond(http.HTTPStatus.FORBIDDEN, f"lightcal app: {reason}\n")
        response = inner(connection, request) if inner is not None else None
        if response is not None and self.token is not None:
            response.headers["Set-Cookie"] = (
                f"{COOKIE}={self.token}; Path=/; HttpOnly; SameSite=Strict"
            )
        return response


_SERVE_LOCK = threading.Lock()


@contextmanager
def guard_handshakes(guard: AccessGuard) -> Iterator[None]:
    """While a viser server is created inside, its websockets server gets `guard` in
    front of viser's own `process_request` (viser has no hook of its own for this).

    `websockets.asyncio.server.serve` is replaced for that one call (under a lock);
    RuntimeError when the server was not created through it, so a server never runs
    without the guard.
    """
    import websockets.asyncio.server as ws_server

    original = ws_server.serve
    used = threading.Event()

    class GuardedServe(original):  # type: ignore[misc, valid-type]
        def __init__(self, *args: Any, process_request: Any = None, **kwargs: Any) -> None:
            setattr(ws_server, "serve", original)  # noqa: B010  (one server only)
            used.set()

            def process(connection: Any, request: Any) -> Any:
                return guard.process_request(connection, request, process_request)

            super().__init__(*args, process_request=process, **kwargs)

    with _SERVE_LOCK:
        setattr(ws_server, "serve", GuardedServe)  # noqa: B010
        try:
            yield
        finally:
            setattr(ws_server, "serve", original)  # noqa: B010
    if not used.is_set():
        raise RuntimeError("lightcal app: could not install the access guard on viser's server")
