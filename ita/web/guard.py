"""The walls of `ita serve`: which requests reach the System Monitor at all.

    app = Starlette(routes, middleware=[Middleware(Guard, host="127.0.0.1")])

A pure ASGI middleware (not Starlette's BaseHTTPMiddleware), so it stands in front of
every route, the live stream included, and sees the body as it arrives:

* **Host.**  A request must name this server in its one `Host` header: `127.0.0.1`,
  `localhost` or `[::1]`, the address given with `ita serve --host`, or the address the
  connection reached (an IP literal), each with the port the server listens on; 421
  otherwise, and for a request without `Host` (HTTP/1.0).  A page of another site whose
  name was rebound to this machine (DNS rebinding) sends its own name, so it gets nothing.
* **Origin.**  A request that may change something (any method but GET, HEAD, OPTIONS)
  whose `Origin` is not `http://` one of those hosts gets 403 (a request without
  `Origin` is not from a browser's page; the app still wants `X-ITA: 1` of it).
* **Body size.**  A body over `MAX_BODY` (1 MB) gets 413: by its `Content-Length` before
  a byte is read, and a chunked one as soon as the count passes the limit while the app
  reads it.  A refusal closes the connection, so an unread body is not read either.
* **Errors.**  An exception no handler took becomes a 500 with a one-line JSON body and
  one line in the server's log, never a traceback.
"""

from __future__ import annotations

import ipaddress
import json
import logging
from collections.abc import Iterable
from dataclasses import dataclass

from starlette.types import ASGIApp, Message, Receive, Scope, Send

MAX_BODY = 1 << 20
LOCAL_NAMES = ("127.0.0.1", "localhost", "[::1]")
SAFE_METHODS = frozenset({"GET", "HEAD", "OPTIONS"})
DEFAULT_PORTS = {"http": 80, "https": 443, "ws": 80, "wss": 443}
LOG = "uvicorn.error"       # the server's own log (uvicorn's): one line an error, nothing a refusal


class BodyTooLarge(Exception):
    """Raised by the guarded `receive` once a body passes the limit (the guard answers 413)."""


@dataclass(frozen=True)
class Refusal:
    """Why a request is not served: its status and one line."""

    status: int
    message: str


def host_name(host: str) -> str:
    """`host` as it appears in a Host header: lower case, an IPv6 address in brackets."""
    host = host.strip().lower()
    if ":" in host and not host.startswith("["):
        return f"[{host}]"
    return host


def _ip_literal(host: str) -> bool:
    try:
        ipaddress.ip_address(host.strip("[]"))
    except ValueError:
        return False
    return True


def allowed_hosts(names: Iterable[str], port: int, scheme: str = "http") -> frozenset[str]:
    """The Host values naming this server: each name with the port (alone too when the
    port is the scheme's default, as a browser writes it)."""
    out = set()
    for name in names:
        out.add(f"{name}:{port}")
        if DEFAULT_PORTS.get(scheme) == port:
            out.add(name)
    return frozenset(out)


def _headers(scope: Scope, name: bytes) -> list[str]:
    return [v.decode("latin-1") for k, v in scope.get("headers", []) if k.lower() == name]


def _content_length(scope: Scope, limit: int) -> Refusal | None:
    values = set(_headers(scope, b"content-length"))
    if not values:
        return None
    if len(values) > 1 or not all(v.strip().isascii() and v.strip().isdigit() for v in values):
        return Refusal(400, "Content-Length must be one whole number")
    if int(values.pop().strip()) > limit:
        return Refusal(413, f"request body over {limit} bytes")
    return None


@dataclass(frozen=True)
class Walls:
    """What the guard allows: the names of this server besides the local ones, the
    largest body."""

    names: tuple[str, ...] = LOCAL_NAMES
    max_body: int = MAX_BODY

    @classmethod
    def for_host(cls, host: str | None, max_body: int = MAX_BODY) -> Walls:
        """The walls of a server listening on `host` (None: the local names alone)."""
        names = list(LOCAL_NAMES)
        if host and host_name(host) not in names:
            names.append(host_name(host))
        return cls(tuple(names), max_body)

    def hosts(self, scope: Scope) -> frozenset[str]:
        """The Host values naming this server for this connection (none when the
        server's port is unknown)."""
        server = scope.get("server")
        if not server or server[1] is None:
            return frozenset()
        names = list(self.names)
        local = host_name(str(server[0]))
        if _ip_literal(local) and local not in names:
            names.append(local)
        return allowed_hosts(names, int(server[1]), scope.get("scheme", "http"))

    def refusal(self, scope: Scope) -> Refusal | None:
        """Why this request is refused before the app sees it; None when it is not."""
        hosts = self.hosts(scope)
        given = _headers(scope, b"host")
        if len(given) != 1 or given[0].strip().lower() not in hosts:
            what = ("no Host header" if not given else "more than one Host header" if len(given) > 1
                    else f"Host {given[0][:80]!r}")
            port = (scope.get("server") or (None, None))[1]
            shown = ", ".join(f"{n}:{port}" for n in self.names) if port is not None else "its own address"
            return Refusal(421, f"{what}: this server answers only as {shown}")
        if scope.get("method", "GET") not in SAFE_METHODS:
            origins = _headers(scope, b"origin")
            scheme = "https" if scope.get("scheme") in ("https", "wss") else "http"
            if origins and (len(origins) > 1 or origins[0].strip().lower() not in {f"{scheme}://{h}" for h in hosts}):
                return Refusal(403, f"Origin {origins[0][:80]!r} is not this server's: a page of another site "
                                    "cannot change anything here")
        return _content_length(scope, self.max_body)


def _error_messages(status: int, message: str) -> tuple[Message, Message]:
    body = json.dumps({"error": message}).encode()
    start = {"type": "http.response.start", "status": status,
             "headers": [(b"content-type", b"application/json"), (b"content-length", str(len(body)).encode()),
                         (b"connection", b"close")]}
    return start, {"type": "http.response.body", "body": body, "more_body": False}


async def send_error(send: Send, status: int, message: str) -> None:
    """Answer `status` with `{"error": message}` and close the connection."""
    for m in _error_messages(status, message):
        await send(m)


def printable(text: str, limit: int = 200) -> str:
    """`text` cut to `limit` characters, anything unprintable (a newline too) as '?'."""
    return "".join(c if c.isprintable() else "?" for c in text[:limit])


def one_line(exc: BaseException) -> str:
    """An exception as one line: its type and the first line of its message."""
    text = str(exc).strip().splitlines()
    return f"{type(exc).__name__}: {printable(text[0])}" if text else type(exc).__name__


class Guard:
    """The ASGI middleware that keeps the walls (see the module's docstring)."""

    def __init__(self, app: ASGIApp, host: str | None = None, max_body: int = MAX_BODY) -> None:
        self.app = app
        self.walls = Walls.for_host(host, max_body)

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] not in ("http", "websocket"):
            await self.app(scope, receive, send)
            return
        refused = self.walls.refusal(scope)
        if refused is not None:
            if scope["type"] == "websocket":
                await send({"type": "websocket.close", "code": 1008, "reason": refused.message[:120]})
            else:
                await send_error(send, refused.status, refused.message)
            return
        if scope["type"] == "websocket":
            await self.app(scope, receive, send)
            return
        await self._http(scope, receive, send)

    async def _http(self, scope: Scope, receive: Receive, send: Send) -> None:
        limit = self.walls.max_body
        started = False
        received = 0

        async def counted() -> Message:
            nonlocal received
            message = await receive()
            if message["type"] == "http.request":
                received += len(message.get("body", b""))
                if received > limit:
                    raise BodyTooLarge(f"request body over {limit} bytes")
            return message

        async def watched(message: Message) -> None:
            nonlocal started
            if message["type"] == "http.response.start":
                started = True
            await send(message)

        try:
            await self.app(scope, counted, watched)
        except BodyTooLarge as exc:
            if not started:
                await send_error(send, 413, str(exc))
        except Exception as exc:  # noqa: BLE001 - the last wall: one line, never a traceback
            logging.getLogger(LOG).error("%s %s: %s", scope.get("method"), printable(scope.get("path", "")),
                                         one_line(exc))
            if not started:
                await send_error(send, 500, f"internal error ({type(exc).__name__}); the server's log has a line on it")
