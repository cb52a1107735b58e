"""Serving the System Monitor: uvicorn with the limits it needs and a prompt stop.

    serve(create_app(runs_dir, host=host), sock)     # until Ctrl-C

uvicorn's own limits back the app's walls (:mod:`ita.web.guard`): the h11 protocol with
its request head capped at `HEAD_LIMIT`, at most `MAX_CONNECTIONS` connections (503
past them), idle connections closed after `KEEP_ALIVE_S`.  On Ctrl-C (or SIGTERM) the
app is told before uvicorn waits for open connections, so every live stream ends at once
and the server is gone in well under a second; a request still busy after `GRACE_S` is
cancelled.  Runs the server started go on (they are processes of their own).
"""

from __future__ import annotations

import socket
from collections.abc import Callable

import uvicorn
from starlette.applications import Starlette

HEAD_LIMIT = 16 * 1024
MAX_CONNECTIONS = 64
KEEP_ALIVE_S = 5
GRACE_S = 1


class MonitorServer(uvicorn.Server):
    """uvicorn's server, calling `on_stop` as soon as it begins to shut down."""

    def __init__(self, config: uvicorn.Config, on_stop: Callable[[], None]) -> None:
        super().__init__(config)
        self.on_stop = on_stop

    async def shutdown(self, sockets: list[socket.socket] | None = None) -> None:
        self.on_stop()
        await super().shutdown(sockets=sockets)


def server_config(app: Starlette) -> uvicorn.Config:
    """The uvicorn configuration of `ita serve` (the socket is given to `run`)."""
    return uvicorn.Config(app, http="h11", h11_max_incomplete_event_size=HEAD_LIMIT,
                          limit_concurrency=MAX_CONNECTIONS, timeout_keep_alive=KEEP_ALIVE_S,
                          timeout_graceful_shutdown=GRACE_S, log_level="warning", access_log=False)


def serve(app: Starlette, sock: socket.socket) -> None:
    """Serve `app` (made by `create_app`) on the bound socket until Ctrl-C or SIGTERM."""
    server = MonitorServer(server_config(app), on_stop=app.state.ita.stop)
    try:
        server.run(sockets=[sock])
    except KeyboardInterrupt:    # uvicorn raises the Ctrl-C it caught again once it has stopped
        pass
