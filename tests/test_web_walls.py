"""The walls of `ita serve` (issue 28): it answers only requests that name it, takes no
change from another site's page, reads no body over 1 MB, takes only the bodies its
requests are made of, answers errors in one line, stops at once on Ctrl-C and leaves no
zombie behind its runs.

In-process tests call `create_app` through Starlette's TestClient (as if served on
127.0.0.1:8765) or as a bare ASGI app; the rest start a real `ita serve` on 127.0.0.1
with a free port (ITA_HOME and the runs under tmp_path).  No run of the inspection is
started: the runner's Python is replaced by a script that writes down its arguments.
"""

from __future__ import annotations

import asyncio
import contextlib
import json
import logging
import os
import re
import select
import signal
import socket
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from archive_synth import fake_specs, record_synthetic_run, true_values

from ita.archive import Archive, RunStatus, archive_path

pytestmark = pytest.mark.filterwarnings("ignore:Using `httpx` with `starlette.testclient`")

REPO = Path(__file__).resolve().parent.parent
BASE = "http://127.0.0.1:8765"
MB = 1 << 20
X_ITA = {"X-ITA": "1"}


# ------------------------------------------------------------------------------ set-up
def _specs_csv(n: int) -> str:
    from ita.specs.io import format_specs
    from ita.specs.model import MeasurementKind, MeasurementSpec

    return format_specs([MeasurementSpec(f"WT-{i}", MeasurementKind.parse("web_thickness"), "web-1",
                                         (10.0 * i, 0.0, 0.0), (0.0, 0.0, 1.0), 2.5, -0.1, 0.1)
                         for i in range(n)])


@pytest.fixture()
def site(tmp_path: Path) -> dict[str, Any]:
    """An app on a runs directory with a running synthetic run, a part directory of 3
    specs, and a stand-in for the runner's Python that records its arguments and ends."""
    from starlette.testclient import TestClient

    from ita.web.app import create_app

    runs = tmp_path / "runs"
    specs = fake_specs(5)
    with Archive.open(archive_path(runs)) as a:
        rid = record_synthetic_run(a, specs, true_values(specs), status=RunStatus.RUNNING, upto=2)
    part = tmp_path / "part"
    part.mkdir()
    (part / "specs.csv").write_text(_specs_csv(3), encoding="utf-8")
    fake = tmp_path / "fake-python"
    fake.write_text(f'#!/bin/sh\necho "$$ $@" >> "{tmp_path / "child-args"}"\n', encoding="utf-8")
    fake.chmod(0o755)
    app = create_app(runs)
    app.state.ita.procs.python = str(fake)
    return {"app": app, "client": TestClient(app, base_url=BASE), "runs": runs, "run": rid, "part": part,
            "args": tmp_path / "child-args"}


@pytest.fixture()
def server_log() -> Iterator[list[logging.LogRecord]]:
    """The records the server's log ("uvicorn.error") gets during the test."""
    records: list[logging.LogRecord] = []

    class Keep(logging.Handler):
        def emit(self, record: logging.LogRecord) -> None:
            records.append(record)

    logger, handler = logging.getLogger("uvicorn.error"), Keep(logging.DEBUG)
    logger.addHandler(handler)
    try:
        yield records
    finally:
        logger.removeHandler(handler)


def _asgi(app: Any, *, method: str = "POST", path: str = "/api/runs/r1/control", headers: list[tuple[bytes, bytes]],
          receive: Any = None, http_version: str = "1.1") -> tuple[int, bytes]:
    """Call the app as a server would; the status and body it answers."""
    sent: list[dict[str, Any]] = []

    async def nothing() -> dict[str, Any]:
        return {"type": "http.request", "body": b"", "more_body": False}

    async def send(message: dict[str, Any]) -> None:
        sent.append(message)

    scope = {"type": "http", "asgi": {"version": "3.0", "spec_version": "2.3"}, "http_version": http_version,
             "method": method, "scheme": "http", "path": path, "raw_path": path.encode(), "root_path": "",
             "query_string": b"", "headers": headers, "server": ("127.0.0.1", 8765),
             "client": ("127.0.0.1", 50000)}
    asyncio.run(asyncio.wait_for(app(scope, receive or nothing, send), 30))
    start = next(m for m in sent if m["type"] == "http.response.start")
    return start["status"], b"".join(m.get("body", b"") for m in sent if m["type"] == "http.response.body")


def _one_line_error(response: Any) -> str:
    message = response.json()["error"]
    assert isinstance(message, str) and message and "\n" not in message and "Traceback" not in message
    return message


def _children(site: dict[str, Any]) -> list[str]:
    """A line per child the runner started: its pid and arguments."""
    return site["args"].read_text().splitlines() if site["args"].exists() else []


# ------------------------------------------------------------------------- Host, Origin
@pytest.mark.parametrize("host", ["attacker.example", "attacker.example:8765", "127.0.0.1:9999", "localhost",
                                  "127.0.0.2:8765", "localhost.:8765", "127.0.0.1:8765.attacker.example"])
def test_a_host_not_naming_this_server_is_refused(site, host: str) -> None:
    """DNS rebinding: a page of attacker.example, its name pointed at 127.0.0.1, sends
    Host attacker.example; it gets neither pages, nor data, nor a run."""
    client = site["client"]
    for path in ("/", "/api/runs", f"/api/runs/{site['run']}/report", "/assets/ita.js"):
        r = client.get(path, headers={"Host": host})
        assert r.status_code == 421, path
        assert "127.0.0.1:8765" in _one_line_error(r)
    r = client.post("/api/runs", headers={"Host": host, **X_ITA}, json={"part": str(site["part"]), "limit": 1})
    assert r.status_code == 421
    time.sleep(0.2)
    assert _children(site) == []


@pytest.mark.parametrize("host", ["127.0.0.1:8765", "localhost:8765", "[::1]:8765", "LOCALHOST:8765"])
def test_this_servers_own_names_are_served(site, host: str) -> None:
    r = site["client"].get("/api/runs", headers={"Host": host})
    assert r.status_code == 200 and r.json()[0]["id"] == site["run"]


def test_the_host_given_with_host_is_served_too(site) -> None:
    from starlette.testclient import TestClient

    from ita.web.app import create_app

    own = TestClient(create_app(site["runs"], host="192.0.2.7"), base_url=BASE)
    assert own.get("/api/runs", headers={"Host": "192.0.2.7:8765"}).status_code == 200
    assert own.get("/api/runs", headers={"Host": "192.0.2.8:8765"}).status_code == 421
    assert site["client"].get("/api/runs", headers={"Host": "192.0.2.7:8765"}).status_code == 421


def test_a_request_without_host_is_refused(site) -> None:
    """HTTP/1.0 needs no Host; the server does not guess."""
    status, body = _asgi(site["app"], method="GET", path="/api/runs", headers=[], http_version="1.0")
    assert status == 421 and "no Host" in json.loads(body)["error"]
    two = [(b"host", b"127.0.0.1:8765"), (b"host", b"attacker.example")]
    assert _asgi(site["app"], method="GET", path="/api/runs", headers=two)[0] == 421


@pytest.mark.parametrize("origin", ["http://attacker.example", "http://127.0.0.1:8765.attacker.example", "null",
                                    "https://127.0.0.1:8765", "http://127.0.0.1:9999"])
def test_a_change_from_another_origin_is_refused(site, origin: str) -> None:
    """A POST whose Origin is not this server's gets 403, X-ITA or not: STOP never
    reaches the running run, and no run is started."""
    client, rid = site["client"], site["run"]
    r = client.post(f"/api/runs/{rid}/control", headers={"Origin": origin, **X_ITA}, json={"command": "STOP"})
    assert r.status_code == 403 and "Origin" in _one_line_error(r)
    r = client.post("/api/runs", headers={"Origin": origin, **X_ITA}, json={"part": str(site["part"]), "limit": 1})
    assert r.status_code == 403
    with Archive.open(archive_path(site["runs"])) as a:
        assert a.pending_control(rid) == []
    time.sleep(0.2)
    assert _children(site) == []


def test_a_change_from_this_origin_needs_x_ita_still(site) -> None:
    client, rid = site["client"], site["run"]
    r = client.post(f"/api/runs/{rid}/control", headers={"Origin": BASE}, json={"command": "STOP"})
    assert r.status_code == 403 and "X-ITA" in _one_line_error(r)
    r = client.post(f"/api/runs/{rid}/control", headers={"Origin": BASE, **X_ITA}, json={"command": "stop"})
    assert r.status_code == 200 and r.json()["sent"] == "STOP"
    with Archive.open(archive_path(site["runs"])) as a:
        assert [c.command.value for c in a.pending_control(rid)] == ["STOP"]


# --------------------------------------------------------------------------- body size
def test_a_body_announced_over_1_mb_is_refused_unread(site) -> None:
    """Content-Length 400 MB: 413 before a byte of it is read."""
    reads = []

    async def receive() -> dict[str, Any]:
        reads.append(1)
        return {"type": "http.request", "body": b"x" * MB, "more_body": len(reads) < 8}

    headers = [(b"host", b"127.0.0.1:8765"), (b"x-ita", b"1"), (b"content-type", b"application/json"),
               (b"content-length", b"400000000")]
    status, body = _asgi(site["app"], headers=headers, receive=receive)
    assert status == 413 and "1048576" in json.loads(body)["error"]
    assert reads == []


def test_a_streamed_body_is_cut_at_1_mb(site) -> None:
    """A chunked body of 8 MB: the app reads 1 MB and one chunk more, then 413."""
    reads = []

    async def receive() -> dict[str, Any]:
        reads.append(1)
        return {"type": "http.request", "body": b" " * (64 * 1024), "more_body": len(reads) < 128}

    headers = [(b"host", b"127.0.0.1:8765"), (b"x-ita", b"1"), (b"transfer-encoding", b"chunked")]
    for path in ("/api/runs/r1/control", "/api/runs"):
        reads.clear()
        status, _ = _asgi(site["app"], path=path, headers=headers, receive=receive)
        assert status == 413 and len(reads) == 17, path
    r = site["client"].post("/api/runs", headers=X_ITA, content=iter([b" " * MB, b"{}"]))
    assert r.status_code == 413
    assert _children(site) == []


# ------------------------------------------------------------------------------ bodies
START_BODIES = [
    (b"", "not JSON"),
    (b"[1, 2]", "JSON array"),
    (b'"go"', "JSON string"),
    (b"null", "JSON null"),
    (b"{\"seed\": 1", "not JSON"),
    (b"\xff\xfe{}", "UTF-8"),
    (b"[" * 100_000, "nested"),
    (b'{"seed": NaN}', "finite"),
    (b'{"seed": Infinity}', "finite"),
    (b'{"faults": -Infinity}', "finite"),
    (b'{"faults": 1e400}', "finite"),
    (b'{"seed": 1' + b"0" * 5000 + b"}", "not JSON"),
    (b'{"seed": -1}', "seed"),
    (b'{"seed": 9223372036854775808}', "seed"),
    (b'{"seed": true}', "seed"),
    (b'{"seed": 1.5}', "seed"),
    (b'{"seed": "7x"}', "seed"),
    (b'{"seed": [7]}', "seed"),
    (b'{"limit": 0, "part": "PART"}', "limit"),
    (b'{"limit": 4, "part": "PART"}', "1 to 3"),
    (b'{"limit": "-1", "part": "PART"}', "limit"),
    (b'{"limit": true, "part": "PART"}', "limit"),
    (b'{"limit": 2.0, "part": "PART"}', "limit"),
    (b'{"faults": 1.5}', "faults"),
    (b'{"faults": -0.01}', "faults"),
    (b'{"faults": false}', "faults"),
    (b'{"faults": "nan"}', "faults"),
    (b'{"part": 7}', "part"),
    (b'{"part": "/no/such/part/dir"}', "part"),
    (b'{"part": "a\\u0000b"}', "part"),
    (b'{"part": "' + b"x" * 5000 + b'"}', "part"),
    (b'{"limit": 1, "part": "NOSPECS"}', "part"),
    (b'{"colour": "red"}', "unknown field 'colour'"),
    (b'{"serial": 42}', "serial"),
    (b'{"serial": "SN\\n1"}', "serial"),
    (b'{"serial": "' + b"x" * 65 + b'"}', "serial"),
    (b'{"operator": ["A"]}', "operator"),
    (b'{"operator": "A\\u001b[2J"}', "operator"),
    (b'{"inject": "melt_probe:after=3"}', "inject"),
    (b'{"inject": "broken_probe:after=soon"}', "inject"),
    (b'{"inject": 7}', "inject"),
    (b'{"inject": "' + b"transient " * 9 + b'"}', "at most 8"),
    (b'{"inject": "transient:after=' + b"1" * 90 + b'"}', "at most 8"),
    (b'{"inject": "transient;rm -rf /"}', "inject"),
]


@pytest.mark.parametrize(("body", "says"), START_BODIES, ids=range(len(START_BODIES)))
def test_a_bad_start_body_is_a_400_naming_its_field(site, tmp_path, server_log, body: bytes, says: str) -> None:
    (tmp_path / "nospecs").mkdir()
    body = body.replace(b"PART", str(site["part"]).encode()).replace(b"NOSPECS", str(tmp_path / "nospecs").encode())
    r = site["client"].post("/api/runs", headers={**X_ITA, "Content-Type": "application/json"}, content=body)
    assert r.status_code == 400
    assert says in _one_line_error(r)
    assert not [rec for rec in server_log if rec.exc_info or rec.levelno >= logging.ERROR]
    time.sleep(0.1)
    assert _children(site) == []


@pytest.mark.parametrize(("body", "says"), [(b"{}", "no command"), (b'{"command": 5}', "command"),
                                            (b'{"command": "REBOOT"}', "REBOOT"), (b'["STOP"]', "JSON array"),
                                            (b'{"command": "STOP", "x": 1}', "unknown field 'x'"),
                                            (b'{"command": NaN}', "finite")])
def test_a_bad_control_body_is_a_400(site, body: bytes, says: str) -> None:
    r = site["client"].post(f"/api/runs/{site['run']}/control", headers=X_ITA, content=body)
    assert r.status_code == 400 and says in _one_line_error(r)
    with Archive.open(archive_path(site["runs"])) as a:
        assert a.pending_control(site["run"]) == []


def _state(pid: int) -> str | None:
    """A process's state letter (Z: a zombie), None when it is gone."""
    try:
        return Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except (FileNotFoundError, ProcessLookupError):
        return None


def test_a_good_body_starts_the_run_and_its_child_is_reaped(site) -> None:
    """The page's strings (limit "2", seed "7") and a fault rate reach `ita inspect`; the
    child, once it has ended, is reaped without another request (no zombie)."""
    body = {"part": f"  {site['part']}  ", "limit": "2", "seed": "7", "faults": 0.05,
            "inject": "transient@controller:after=5"}
    r = site["client"].post("/api/runs", headers=X_ITA, json=body)
    assert r.status_code == 201
    run_id = r.json()["run"]
    deadline = time.monotonic() + 10
    while not _children(site) and time.monotonic() < deadline:
        time.sleep(0.05)
    pid, *args = _children(site)[0].split()
    while _state(int(pid)) is not None and time.monotonic() < deadline:
        time.sleep(0.05)
    assert _state(int(pid)) is None, f"child {pid} is {_state(int(pid))} (Z: a zombie)"
    assert site["app"].state.ita.procs.pid(run_id) == int(pid)
    assert args[:3] == ["-m", "ita.cli", "inspect"]
    flags = dict(zip(args[3::2], args[4::2], strict=True))
    assert flags == {"--run-id": run_id, "--seed": "7", "--limit": "2", "--faults": "0.05",
                     "--inject": "transient@controller:after=5",
                     "--part": str(site["part"].resolve()), "--runs-dir": str(site["runs"])}


# ------------------------------------------------------------------------------ errors
def test_a_damaged_archive_is_a_one_line_answer(site, server_log) -> None:
    archive_path(site["runs"]).write_bytes(b"not an archive at all " * 200)
    client = site["client"]
    for path in ("/api/runs", f"/api/runs/{site['run']}/state", f"/api/runs/{site['run']}/report",
                 f"/runs/{site['run']}/results.csv"):
        r = client.get(path)
        assert 400 <= r.status_code < 500, path
        _one_line_error(r)
    assert not [rec for rec in server_log if rec.exc_info]


def test_a_run_id_no_run_can_have_is_a_404(site) -> None:
    for rid in ("r%00x", "a%20b", "x" * 100):
        r = site["client"].get(f"/api/runs/{rid}/state")
        assert r.status_code == 404 and "no run" in _one_line_error(r)


def test_an_unexpected_error_is_a_one_line_500(site, server_log, monkeypatch) -> None:
    import ita.web.app as web_app

    def boom(state: Any) -> Any:
        raise ZeroDivisionError("division by zero\nsecond line")

    monkeypatch.setattr(web_app, "_runs", boom)
    r = site["client"].get("/api/runs")
    assert r.status_code == 500 and "ZeroDivisionError" in _one_line_error(r)
    assert [(rec.levelno, rec.exc_info) for rec in server_log] == [(logging.ERROR, None)]
    assert "\n" not in server_log[0].getMessage() and "division by zero" in server_log[0].getMessage()
    assert site["client"].get("/").status_code == 200


# ------------------------------------------------------------------- the real server
def _read_line(stream: Any, timeout: float) -> str:
    ready, _, _ = select.select([stream], [], [], timeout)
    return stream.readline() if ready else ""


@contextlib.contextmanager
def _served(tmp_path: Path) -> Iterator[tuple[subprocess.Popen, int]]:
    """`ita serve --port 0` on 127.0.0.1 (ITA_HOME and runs under tmp_path); its port."""
    env = dict(os.environ, ITA_HOME=str(tmp_path / "home"), PYTHONPATH=str(REPO))
    server = subprocess.Popen([sys.executable, "-m", "ita.cli", "serve", "--port", "0", "--runs-dir",
                               str(tmp_path / "runs")], stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL,
                              stderr=subprocess.PIPE, env=env, cwd=tmp_path, text=True)
    try:
        line = _read_line(server.stderr, 60)
        match = re.search(r"http://127\.0\.0\.1:(\d+)/", line)
        assert match, f"ita serve said {line!r}"
        port, deadline = int(match.group(1)), time.monotonic() + 30
        while True:             # listening already (it listens before it says so), or soon
            try:
                socket.create_connection(("127.0.0.1", port), timeout=5).close()
                break
            except ConnectionRefusedError:
                assert time.monotonic() < deadline and server.poll() is None, "ita serve does not listen"
                time.sleep(0.05)
        yield server, port
    finally:
        if server.poll() is None:
            server.kill()
        server.wait(10)
        server.stderr.close()


def _connect(port: int) -> socket.socket:
    return socket.create_connection(("127.0.0.1", port), timeout=10)


def _read_all(sock: socket.socket) -> bytes:
    out = b""
    with contextlib.suppress(ConnectionResetError, TimeoutError):
        while chunk := sock.recv(65536):
            out += chunk
    return out


def _ask(port: int, head: str) -> bytes:
    """One request (its head, with `Connection: close`); the whole answer."""
    with _connect(port) as s:
        s.sendall(head.encode("latin-1"))
        return _read_all(s)


def _head(method: str, path: str, port: int, *more: str) -> str:
    return "\r\n".join([f"{method} {path} HTTP/1.1", f"Host: 127.0.0.1:{port}", "Connection: close", *more, "", ""])


def _peak_rss_mb(pid: int) -> float:
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        if line.startswith("VmHWM:"):
            return int(line.split()[1]) / 1024
    raise AssertionError("no VmHWM")


def _stream(port: int, head: str, total: int, chunk: int = 64 * 1024) -> tuple[int, bytes]:
    """Send a chunked body of `total` bytes, stopping as soon as an answer comes; the
    bytes sent and the answer."""
    piece = b"%x\r\n" % chunk + b"{" * chunk + b"\r\n"
    sent = 0
    with _connect(port) as s:
        s.sendall(head.encode("latin-1"))
        try:
            while sent < total and not select.select([s], [], [], 0)[0]:
                s.sendall(piece)
                sent += chunk
            else:
                if sent >= total:
                    s.sendall(b"0\r\n\r\n")
        except (BrokenPipeError, ConnectionResetError):
            pass
        return sent, _read_all(s)


def test_the_real_server_refuses_big_bodies_without_reading_them(tmp_path) -> None:
    """`ita serve` with a 400 MB Content-Length answers 413 at once, and a 32 MB chunked
    body 413 after about 1 MB: its peak memory hardly moves.  HTTP/1.0 without Host gets
    421, bad bodies 400, a damaged archive one line (on the live stream too); its log
    has no traceback."""
    with _served(tmp_path) as (server, port):
        assert _ask(port, _head("GET", "/api/runs", port)).startswith(b"HTTP/1.1 200")
        before = _peak_rss_mb(server.pid)
        post = ("POST", "/api/runs/r1/control", port, "X-ITA: 1", "Content-Type: application/json")
        announced = _ask(port, _head(*post, "Content-Length: 400000000"))
        assert announced.startswith(b"HTTP/1.1 413"), announced[:200]
        sent, streamed = _stream(port, _head(*post, "Transfer-Encoding: chunked"), 32 * MB)
        assert streamed.startswith(b"HTTP/1.1 413"), streamed[:200]
        assert sent < 16 * MB
        grown = _peak_rss_mb(server.pid) - before
        assert grown < 16, f"the server's peak memory grew {grown:.0f} MB"
        old = _ask(port, "GET /api/runs HTTP/1.0\r\n\r\n")
        assert old.startswith(b"HTTP/1.1 421"), old[:200]
        for body in (b"[1]", b'{"command": NaN}', b"\xff"):
            bad = _ask(port, _head(*post, f"Content-Length: {len(body)}") + body.decode("latin-1"))
            assert bad.startswith(b"HTTP/1.1 400"), bad[:200]
        archive_path(tmp_path / "runs").parent.mkdir(parents=True, exist_ok=True)
        archive_path(tmp_path / "runs").write_bytes(b"damaged " * 1000)
        assert _ask(port, _head("GET", "/api/runs", port)).startswith(b"HTTP/1.1 409")
        with _connect(port) as live:     # the live view says so, and goes on
            live.sendall(_head("GET", "/api/runs/r1/live", port).encode())
            seen = b""
            while b"\n\n" not in seen.partition(b"event: problem")[2]:
                chunk = live.recv(65536)
                assert chunk, seen
                seen += chunk
            assert b"archive.sqlite" in seen
        server.send_signal(signal.SIGINT)
        server.wait(10)
        log = server.stderr.read()
    assert "Traceback" not in log, log


def test_ctrl_c_stops_the_server_within_a_second_with_a_live_page_open(tmp_path) -> None:
    """A page's live stream (server-sent events) and an idle keep-alive connection open:
    Ctrl-C ends `ita serve` in under a second, exit 0, no traceback; the stream is ended."""
    with _served(tmp_path) as (server, port):
        live = _connect(port)
        live.sendall(f"GET /api/runs/r1/live HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\n\r\n".encode())
        seen = b""
        while b"event: state" not in seen:
            chunk = live.recv(65536)
            assert chunk, seen
            seen += chunk
        idle = _connect(port)
        idle.sendall(f"GET /api/runs HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\n\r\n".encode())
        assert idle.recv(65536).startswith(b"HTTP/1.1 200")
        start = time.monotonic()
        server.send_signal(signal.SIGINT)
        code = server.wait(10)
        took = time.monotonic() - start
        log = server.stderr.read()
        live.settimeout(2)
        rest = _read_all(live)
        live.close()
        idle.close()
    assert took < 1.0, f"Ctrl-C took {took:.2f} s"
    assert code == 0 and "Traceback" not in log, log
    assert rest.endswith(b"0\r\n\r\n"), rest[-100:]


# ------------------------------------------------------------------ the spec editor's walls
@pytest.fixture
def editor_part(tmp_path: Path) -> Path:
    from user_parts import make_rim_plate

    return make_rim_plate(tmp_path / "rim")


def _add(site, part: Path, spec: dict, headers=X_ITA):
    return site["client"].post(f"/api/parts/specs?dir={part}", headers=headers, json={"action": "add", "spec": spec})


GOOD = {"id": "WT-9", "kind": "web_thickness", "feature": "P9", "x": -100, "y": 50, "z": 3, "nx": 0, "ny": 0,
        "nz": 1, "nominal": 3, "lower": -0.127, "upper": 0.127, "datum": "A"}


@pytest.mark.parametrize(("query", "says"), [
    ("", "dir"), ("dir=/no/such/dir", "not a directory"), ("dir=" + "x" * 5000, "dir"),
])
def test_the_editor_opens_only_a_part_directory(site, query: str, says: str) -> None:
    r = site["client"].get(f"/api/parts/specs?{query}")
    assert r.status_code == 400 and says in _one_line_error(r)


def test_the_editor_refuses_what_would_break_a_specs_file_and_writes_nothing(site, editor_part: Path) -> None:
    before = (editor_part / "specs.csv").read_bytes()
    client = site["client"]
    assert _add(site, editor_part, GOOD, headers={}).status_code == 403                       # no X-ITA
    for spec, says in [({**GOOD, "z": 9.5}, "from the part's surface"),                      # off the part
                       ({**GOOD, "note": "a\nb"}, "one line"), ({**GOOD, "colour": 1}, "unknown field"),
                       ({**GOOD, "nominal": [1]}, "text or a number"), ({"id": "X"}, "missing"),
                       ({**GOOD, "id": "WT-1"}, "WT-1"),                                        # an id it has
                       ({**GOOD, "kind": "hole_diameter", "feature": "Q"}, "not found")]:       # no hole there
        r = _add(site, editor_part, spec)
        assert r.status_code == 400 and says in _one_line_error(r), (spec, r.json())
    for body, says in [({"action": "burn"}, "action"), ({"action": "remove", "id": 7}, "id"),
                       ({"action": "add", "spec": "x"}, "spec"), ({"action": "undo", "x": 1}, "unknown field")]:
        r = client.post(f"/api/parts/specs?dir={editor_part}", headers=X_ITA, json=body)
        assert r.status_code == 400 and says in _one_line_error(r), body
    r = client.get(f"/api/parts/pick?dir={editor_part}&at=1,2")
    assert r.status_code == 400 and "three finite numbers" in _one_line_error(r)
    r = client.get(f"/api/parts/pick?dir={editor_part}&at=-100,50,3&kind=depth")
    assert r.status_code == 400 and "kind" in _one_line_error(r)
    assert (editor_part / "specs.csv").read_bytes() == before


def test_undo_puts_the_file_back_only_when_nobody_changed_it_since(site, editor_part: Path) -> None:
    client = site["client"]
    before = (editor_part / "specs.csv").read_bytes()
    r = client.post(f"/api/parts/specs?dir={editor_part}", headers=X_ITA, json={"action": "undo"})
    assert r.status_code == 400 and "nothing to undo" in _one_line_error(r)
    assert _add(site, editor_part, GOOD).status_code == 200
    assert b"WT-9" in (editor_part / "specs.csv").read_bytes()
    r = client.post(f"/api/parts/specs?dir={editor_part}", headers=X_ITA, json={"action": "undo"})
    assert r.status_code == 200 and (editor_part / "specs.csv").read_bytes() == before
    assert _add(site, editor_part, GOOD).status_code == 200
    changed = (editor_part / "specs.csv").read_bytes() + b"\n"                       # another program's edit
    (editor_part / "specs.csv").write_bytes(changed)
    r = client.post(f"/api/parts/specs?dir={editor_part}", headers=X_ITA, json={"action": "undo"})
    assert r.status_code == 400 and "changed since" in _one_line_error(r)
    assert (editor_part / "specs.csv").read_bytes() == changed
