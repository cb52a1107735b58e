"""The walls alone: the operating system's confinement of the knowledge-base query child
(ita/logic/confine.py), with no Prolog check in front of it.

The child is started exactly as `ita kb query` starts it (ita.logic.sandbox.query: the
same bwrap namespaces, seccomp filter, rlimits and user), but on the fixture
tests/walls_entry.pl, which calls the goal bare: no goal_hazard/2, no library(sandbox).
Every goal below would do harm without the walls (the control test shows it does, run
without them); each test asserts the harm did not happen (no file made, changed or
removed, no secret in anything the child sent back, no connection or byte received, no
process left), not only an exit code.

Each case runs three times when the suite runs as root: as root (the child becomes
nobody before bwrap starts), as root where nobody cannot read the project (the child
stays root outside its user namespace, with no capability), and as an unprivileged
user (uid 4242, a user of no name: the test drops to it before bwrap starts, so bwrap
and the goal never hold a right of root's); as any other user it runs as that user.
"""

from __future__ import annotations

import dataclasses
import os
import secrets
import shutil
import socket
import stat
import subprocess
import tempfile
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

from ita.errors import ItaError
from ita.logic.confine import Jail
from ita.logic.sandbox import SandboxFiles, SandboxLimits, query

ENTRY = Path(__file__).with_name("walls_entry.pl")
OTHER_UID = 4242          # an unprivileged user the test drops to when it runs as root
MARK = "31.4159"          # a sleep no other process on the machine runs
VICTIM = "victim.\n"


@dataclasses.dataclass(frozen=True)
class Arena:
    """A world-writable directory (like /tmp) that any user could harm without walls."""

    path: Path
    secret_other: str     # content of a mode-600 file of another user
    secret_own: str       # content of a mode-600 file of the user the child runs as
    port: int             # a TCP port on 127.0.0.1 where the test listens
    udp_port: int         # a UDP port on 127.0.0.1 where the test listens


def _users() -> list[str]:
    return ["root", "root-kept", "unprivileged"] if os.geteuid() == 0 else ["caller"]


@pytest.fixture(scope="module")
def entry() -> Iterator[Path]:
    """The fixture, copied where every user can read it (the checkout may lie in a
    directory only its owner can enter, as CI's temporary clone does)."""
    directory = Path(tempfile.mkdtemp(prefix="ita-walls-entry-"))
    os.chmod(directory, 0o755)
    copy = directory / ENTRY.name
    shutil.copyfile(ENTRY, copy)
    os.chmod(copy, 0o644)
    yield copy
    shutil.rmtree(directory)


@pytest.fixture(scope="module")
def jail(entry: Path) -> Jail:
    return SandboxFiles((), (), entry).jail()


@pytest.fixture(params=_users())
def who(request: pytest.FixtureRequest, jail: Jail) -> tuple[str, Jail, int]:
    """(name, the jail as that user starts it, the uid the child runs as)."""
    if request.param == "unprivileged":
        return "unprivileged", dataclasses.replace(jail, user=(OTHER_UID, OTHER_UID)), OTHER_UID
    if request.param == "root-kept":
        return "root-kept", dataclasses.replace(jail, user=None), 0
    uid = jail.user[0] if jail.user else os.geteuid()
    return request.param, jail, uid


@pytest.fixture()
def arena(who: tuple[str, Jail, int]) -> Iterator[Arena]:
    _, _, uid = who
    # Under the system's temporary directory so that every user can reach it, as the
    # escape's world-writable directory could; removed at the end.
    path = Path(tempfile.mkdtemp(prefix="ita-walls-"))
    os.chmod(path, 0o1777)
    (path / "victim").write_text(VICTIM, encoding="utf-8")
    os.chmod(path / "victim", 0o666)
    other, own = secrets.token_hex(8), secrets.token_hex(8)
    (path / "secret_other").write_text(other, encoding="utf-8")
    os.chmod(path / "secret_other", 0o600)
    (path / "secret_own").write_text(own, encoding="utf-8")
    os.chmod(path / "secret_own", 0o600)
    if os.geteuid() == 0:
        os.chown(path / "secret_other", 0 if uid != 0 else OTHER_UID, 0)
        os.chown(path / "secret_own", uid, uid)
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as tcp, \
            socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as udp:
        tcp.bind(("127.0.0.1", 0))
        tcp.listen(4)
        udp.bind(("127.0.0.1", 0))
        yield Arena(path, other, own, tcp.getsockname()[1], udp.getsockname()[1])
        _assert_no_connection(tcp, udp)
    shutil.rmtree(path)


def _assert_no_connection(tcp: socket.socket, udp: socket.socket) -> None:
    """Nothing in the listeners' queues: the child has ended, so a connection it made
    or a datagram it sent would be waiting there already."""
    tcp.setblocking(False)
    udp.setblocking(False)
    try:
        conn, _ = tcp.accept()
    except (socket.timeout, BlockingIOError):
        conn = None
    if conn is not None:
        conn.close()
        pytest.fail("the child connected to the test's TCP port")
    try:
        data = udp.recv(4096)
    except (socket.timeout, BlockingIOError):
        data = b""
    assert data == b"", "the child sent a datagram to the test's UDP port"


def _run(goal: str, jail: Jail, time_limit: float = 5.0) -> str:
    """What the child sent back (its outcome and whatever it printed), or the error."""
    printed: list[str] = []
    entry = Path(jail.mounts[0][0]) / ENTRY.name
    try:
        result = query(goal, SandboxFiles((), (), entry), SandboxLimits(time_limit=time_limit),
                       echo=printed.append, jail=jail)
        sent = " ".join(row[0] for row in result.rows)
    except ItaError as exc:
        sent = f"{type(exc).__name__}: {exc}"
    return sent + "\n" + "".join(printed)


def _untouched(arena: Arena) -> None:
    names = sorted(p.name for p in arena.path.iterdir())
    assert names == ["secret_other", "secret_own", "victim"], names
    victim = arena.path / "victim"
    assert victim.read_text(encoding="utf-8") == VICTIM
    assert stat.S_IMODE(victim.stat().st_mode) == 0o666


def _no_process_left() -> None:
    """No process on the machine runs the marked sleep or the fixture (the namespace
    died with the query)."""
    deadline = time.monotonic() + 2.0
    while True:
        found = []
        for entry in Path("/proc").iterdir():
            if not entry.name.isdigit():
                continue
            try:
                cmdline = (entry / "cmdline").read_bytes().decode("utf-8", "replace")
                state = (entry / "stat").read_text().rsplit(")", 1)[1].split()[0]
            except (OSError, IndexError):
                continue
            if state != "Z" and (MARK in cmdline or "walls_entry.pl" in cmdline):
                found.append((entry.name, cmdline.replace("\0", " ")))
        if not found or time.monotonic() > deadline:
            break
        time.sleep(0.05)
    assert not found, found


HARM = {
    "shell/1": "shell('touch {a}/pwned')",
    "shell/2": "shell('echo x >> {a}/victim', S), S == 0",
    "process_create/3 on PATH": "process_create(path(touch), ['{a}/pwned'], [])",
    "process_create/3 of swipl": ("process_create('{swipl}', ['-g', \"open('{a}/pwned', write, S), "
                                  "close(S)\", '-t', halt], [])"),
    "open/3 write": "open('{a}/pwned', write, S), write(S, x), close(S)",
    "open/3 append": "open('{a}/victim', append, S), write(S, x), close(S)",
    "open/4 update": "open('{a}/victim', update, S, []), write(S, y), close(S)",
    "make_directory/1": "make_directory('{a}/pwned')",
    "delete_file/1": "delete_file('{a}/victim')",
    "rename_file/2": "rename_file('{a}/victim', '{a}/pwned')",
    "chmod/2": "use_module(library(filesex)), chmod('{a}/victim', +x)",
    "link_file/3": "link_file('{a}/victim', '{a}/pwned', symbolic)",
    "fork/1 and a file": ("use_module(library(unix)), fork(P), "
                          "( P == child -> open('{a}/pwned', write, S), close(S), halt ; true )"),
}


@pytest.mark.parametrize("case", sorted(HARM))
def test_no_process_and_no_change_to_files(case, who, arena, jail):
    goal = HARM[case].format(a=arena.path, swipl=jail.program)
    _run(goal, who[1])
    _untouched(arena)
    _no_process_left()


READS = {
    "/etc/passwd": "read_file_to_string('/etc/passwd', S, []), throw(S)",
    "/proc of another process": "read_file_to_string('/proc/1/environ', S, []), throw(S)",
    "/proc/self/status": "read_file_to_string('/proc/self/status', S, []), throw(S)",
    "mode-600 file of another user": "read_file_to_string('{a}/secret_other', S, []), throw(S)",
    "mode-600 file of its own user": "read_file_to_string('{a}/secret_own', S, []), throw(S)",
}


@pytest.mark.parametrize("case", sorted(READS))
def test_nothing_outside_prolog_and_the_kb_is_read(case, who, arena):
    sent = _run(READS[case].format(a=arena.path), who[1])
    for secret in (arena.secret_other, arena.secret_own, "root:x:0:0", "PATH=", "Uid:"):
        assert secret not in sent, (case, sent[:300])
    _untouched(arena)


def _listed_dirs() -> list[Path]:
    """Home directories of other users, and the system's temporary directory."""
    dirs = [Path("/root"), Path(tempfile.gettempdir())]
    home = Path("/home")
    if home.is_dir():
        dirs.append(home)
        dirs += [p for p in home.iterdir() if p.is_dir()]
    return [d for d in dirs if d.is_dir()]


@pytest.mark.parametrize("directory", _listed_dirs(), ids=str)
def test_no_directory_listing_elsewhere(directory, who, arena):
    sent = _run(f"directory_files('{directory}', L), throw(L)", who[1])
    real = {name for name in os.listdir(directory) if len(name) >= 4}
    if directory == Path(tempfile.gettempdir()):
        assert arena.path.name in real     # the listing would name the arena
    leaked = sorted(name for name in real if name in sent)
    assert not leaked, (directory, leaked, sent[:300])
    _untouched(arena)


def test_no_network(who, arena):
    """Neither TCP nor UDP reaches the test's ports on 127.0.0.1 (the fixture's
    teardown asserts no connection and no datagram arrived)."""
    goals = [f"use_module(library(socket)), tcp_connect('127.0.0.1':{arena.port}, S, []), "
             "format(S, 'pwned~n', []), close(S)",
             f"use_module(library(socket)), tcp_connect(localhost:{arena.port}, S, []), close(S)",
             f"use_module(library(socket)), udp_socket(S), "
             f"udp_send(S, pwned, '127.0.0.1':{arena.udp_port}, [])"]
    for goal in goals:
        sent = _run(goal, who[1])
        assert "error" in sent, sent[:300]
    _untouched(arena)


def test_no_process_outlives_the_goal(who, arena, jail):
    """A detached, setsid-style child and a goal killed at its time limit: nothing of
    either is left once the query has returned."""
    detached = (f"process_create('{jail.program}', ['-g', 'sleep({MARK})', '-t', halt], "
                "[detached(true), process(_)])")
    _run(detached, who[1])
    _no_process_left()
    forked = ("use_module(library(unix)), fork(P), "
              f"( P == child -> detach_IO, sleep({MARK}) ; true )")
    _run(forked, who[1])
    _no_process_left()
    thread = f"thread_create(sleep({MARK}), _, [detached(true)])"
    _run(thread, who[1])
    _no_process_left()
    started = time.monotonic()
    sent = _run(f"sleep({MARK})", who[1], time_limit=1.0)
    assert "time limit" in sent and time.monotonic() - started < 10
    _no_process_left()
    _untouched(arena)


def test_an_honest_goal_still_answers(who, arena):
    """The walls leave Prolog itself working: arithmetic, its library, its output."""
    sent = _run("use_module(library(lists)), sum_list([1, 2, 3], 6), format('hello~n')", who[1])
    assert sent.startswith("true") and "hello" in sent


def test_without_the_walls_the_harm_happens(arena, who, entry):
    """Control: the same fixture and goal, started as the same user with no walls,
    writes the file; so the tests above fail if the walls fall."""
    name, jail, uid = who
    goal = f"open('{arena.path}/control', write, S), write(S, x), close(S)"
    request = ('{"goal": ' + _json_text(goal) + "}\n").encode()

    def as_user() -> None:
        if os.geteuid() == 0 and uid != 0:
            os.setgroups([])
            os.setgid(uid)
            os.setuid(uid)

    proc = subprocess.run([jail.program, "-q", "-f", "none", "--no-packs", "-g", "kb_sandbox:sandbox_main",
                           "-t", "halt(4)", str(entry)], input=request, capture_output=True, timeout=60,
                          preexec_fn=as_user, cwd="/")
    assert proc.returncode == 0, proc.stderr
    assert (arena.path / "control").read_text() == "x"
    (arena.path / "control").unlink()


def _json_text(text: str) -> str:
    import json

    return json.dumps(text)


# -- where the walls cannot be raised, no goal runs ------------------------------------

def test_no_bubblewrap_refuses_with_a_clear_error(tmp_path, monkeypatch):
    from click.testing import CliRunner

    from ita.cli import main

    bin_dir = tmp_path / "bin"
    bin_dir.mkdir()
    for tool in ("swipl", "ldd"):
        found = shutil.which(tool)
        assert found is not None
        (bin_dir / tool).symlink_to(found)
    monkeypatch.setenv("PATH", str(bin_dir))
    monkeypatch.setenv("ITA_HOME", str(tmp_path / "home"))
    for args in (["kb", "query", "true"], ["kb", "why", "true"], ["kb", "shell"]):
        result = CliRunner().invoke(main, args, input="true\n")
        assert result.exit_code == 2, result.output
        assert "error: bubblewrap (bwrap) is not installed" in result.output, result.output
        assert "Traceback" not in result.output


def test_a_kernel_without_user_namespaces_refuses_with_a_clear_error(tmp_path, jail):
    """bwrap that cannot make its namespaces (as on a kernel that forbids them to
    unprivileged users): the goal does not run, the error says why."""
    fake = tmp_path / "bwrap"
    marker = tmp_path / "ran"
    fake.write_text("#!/bin/sh\n"
                    "echo 'bwrap: No permissions to creating new namespace, likely because the kernel "
                    "does not allow non-privileged user namespaces.' >&2\n"
                    "exit 1\n")
    fake.chmod(0o755)
    broken = dataclasses.replace(jail, bwrap=str(fake), user=None)
    goal = f"open('{marker}', write, S), close(S)"
    with pytest.raises(ItaError) as caught:
        query(goal, SandboxFiles((), (), Path(jail.mounts[0][0]) / ENTRY.name), SandboxLimits(time_limit=5),
              jail=broken)
    text = str(caught.value)
    assert "cannot confine the query process" in text and "user namespaces" in text, text
    assert "\n" not in text
    assert not marker.exists()
