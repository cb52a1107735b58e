"""`ita serve`: the System Monitor in a browser (a local web application over the archive)."""

from __future__ import annotations

from pathlib import Path

import click

from ita.cli.common import reports_errors
from ita.cli.runs import runs_dir_option

LOCAL = ("127.0.0.1", "localhost", "::1")


@click.command("serve")
@click.option("--host", default="127.0.0.1", show_default=True,
              help="Address to listen on. The default serves this machine only; anything else lets every "
                   "machine that reaches it start and stop runs (there is no login).")
@click.option("--port", type=click.IntRange(0, 65535), default=8765, show_default=True,
              help="Port to listen on (0: a free one, printed at start).")
@runs_dir_option
@reports_errors
def serve(host: str, port: int, runs_dir: Path | None) -> None:
    """Serve the System Monitor: runs, a live view of a running inspection (progress,
    current group, tool and measurement, last results, exceptions, time left), STOP,
    INTERRUPT and CONTINUE, a new run from the page, the results feature by feature,
    each result opened (range image with Vision's fit, gauge reading, plan, events,
    timeline, the arm's path in the workcell), the part in 3-D by decision or deviation,
    the Gantt chart, exports (CSV, JSON, HTML and PDF reports) and, for simulated runs,
    the scoring against the as-built part on its own page.

    Every script the pages use ships with the package: it works offline.  The server
    answers only requests that name it (Host 127.0.0.1, localhost or [::1], or --host,
    with its port: 421 otherwise), takes no POST from another site's page (403), no body
    over 1 MB (413) and no body that is not the request's JSON object (400).  Ctrl-C stops
    it within a second, live pages and all; runs it started go on (watch them with
    `ita monitor`).
    """
    import socket

    from ita.archive import runs_dir as default_runs_dir
    from ita.web.app import create_app
    from ita.web.server import serve as serve_app

    directory = default_runs_dir(runs_dir)
    if host not in LOCAL:
        click.echo(f"warning: listening on {host}: anyone who reaches it can start and stop runs", err=True)
    sock = socket.socket(socket.AF_INET6 if ":" in host else socket.AF_INET)
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
    try:
        sock.bind((host, port))
    except OSError as exc:
        from ita.errors import ItaError

        raise ItaError(f"cannot listen on {host}:{port}: {exc.strerror}") from None
    sock.listen(128)          # before the line below: a client that reads it can connect at once
    bound = sock.getsockname()[1]
    click.echo(f"ITA System Monitor on http://{host if ':' not in host else f'[{host}]'}:{bound}/ "
               f"(runs in {directory}); Ctrl-C to stop", err=True)
    serve_app(create_app(directory, host=host), sock)
