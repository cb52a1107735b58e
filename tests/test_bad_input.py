"""Every other bad input (issue 28, part 3): a damaged or read-only archive, a campaign of
too many runs, part parameters out of range, seeds and numbers out of range, a full disk,
a mesh with NaN vertices.  Each is one `error:` line (or a click usage error naming the
range), exit code 2, and nothing left behind.

Everything here writes under tmp_path and runs in well under a minute: no inspection run
(the archive's runs are synthetic, tests/archive_synth.py).
"""

from __future__ import annotations

import contextlib
import errno
import os
import re
import resource
import signal
import sqlite3
import subprocess
import sys
import time
import tracemalloc
from pathlib import Path

import numpy as np
import pytest
from archive_synth import fake_specs, record_synthetic_run, true_values
from click.testing import CliRunner

from ita.archive import Archive, ArchiveError, Event, RunStatus
from ita.cli import main

REPO = Path(__file__).resolve().parent.parent
PARAMS = REPO / "bulkhead" / "part.toml"


def run(*args: str):
    return CliRunner().invoke(main, list(args))


def one_error_line(output: str) -> str:
    """The output's one line, which must be an `error:` line (no traceback, nothing else)."""
    lines = [line for line in output.splitlines() if line.strip()]
    assert len(lines) == 1, output
    assert lines[0].startswith("error: ") and "Traceback" not in output, output
    return lines[0]


# -- the archive -----------------------------------------------------------------------


@pytest.fixture(scope="module")
def good_archive(tmp_path_factory: pytest.TempPathFactory) -> bytes:
    """The bytes of an archive holding one synthetic run of 30 specs."""
    runs = tmp_path_factory.mktemp("good") / "runs"
    runs.mkdir()
    specs = fake_specs(30)
    with Archive.open(runs / "archive.sqlite") as archive:
        record_synthetic_run(archive, specs, true_values(specs), status=RunStatus.COMPLETED)
    return (runs / "archive.sqlite").read_bytes()


def _flipped(data: bytes, at: int, value: int) -> bytes:
    out = bytearray(data)
    out[at] = value
    return bytes(out)


def _table_name_at(data: bytes, table: bytes) -> int:
    """Where sqlite_master's tbl_name column of `table` starts (its record: type, name, tbl_name)."""
    at = data.find(b"table" + table + table)
    assert at > 0
    return at + len(b"table") + len(table)


DAMAGE = {
    # one flipped byte in a table name of the schema: not UTF-8 (today a UnicodeDecodeError, exit 1)
    "table name not UTF-8": lambda d: _flipped(d, _table_name_at(d, b"runs") + 1, 0xFF),
    "results' table name not UTF-8": lambda d: _flipped(d, _table_name_at(d, b"results") + 1, 0xFF),
    "table name changed": lambda d: _flipped(d, _table_name_at(d, b"events") + 1, ord("X")),
    "header's magic": lambda d: _flipped(d, 3, 0),
    "header's page count": lambda d: _flipped(d, 28, 0xFF),
    "truncated": lambda d: d[: len(d) // 2],
    "truncated header": lambda d: d[:100],
    "random bytes": lambda d: bytes(random_bytes(len(d))),
}


def random_bytes(n: int) -> bytes:
    import random

    return random.Random(28).randbytes(n)


@pytest.mark.parametrize("damage", list(DAMAGE))
@pytest.mark.parametrize("command", [["runs"], ["results", "last"], ["report", "last", "-o", "{out}"]])
def test_a_damaged_archive_is_one_line_naming_it(good_archive: bytes, tmp_path: Path, damage: str, command):
    runs = tmp_path / "runs"
    runs.mkdir()
    path = runs / "archive.sqlite"
    path.write_bytes(DAMAGE[damage](good_archive))
    out = tmp_path / "report.html"
    result = run(*[a.format(out=out) for a in command], "--runs-dir", str(runs))
    assert result.exit_code == 2, result.output
    assert one_error_line(result.output).startswith(f"error: {path}: cannot be read (")
    assert not out.exists()


@pytest.mark.parametrize("kind", ["directory", "fifo"])
def test_something_not_a_file_where_the_archive_is(tmp_path: Path, kind: str):
    runs = tmp_path / "runs"
    runs.mkdir()
    path = runs / "archive.sqlite"
    path.mkdir() if kind == "directory" else os.mkfifo(path)
    for command in (["runs"], ["results", "last"]):
        result = run(*command, "--runs-dir", str(runs))
        assert result.exit_code == 2, result.output
        word = "a directory" if kind == "directory" else "a FIFO"
        assert one_error_line(result.output) == f"error: {path}: cannot be read ({word}, not a file)"
    with pytest.raises(ArchiveError, match="not a file"):
        Archive.open(path)                       # not even to create one


def _damage_a_value(path: Path, sql: str) -> None:
    conn = sqlite3.connect(path, isolation_level=None)
    conn.execute("PRAGMA ignore_check_constraints = 1")
    conn.execute(sql)
    conn.close()


@pytest.mark.parametrize("sql,read", [
    ("UPDATE runs SET settings = '{not json'", lambda a, rid: a.runs()),
    ("UPDATE runs SET totals = '[1, 2]'", lambda a, rid: a.run(rid)),
    ("UPDATE runs SET status = 'sleeping'", lambda a, rid: a.runs()),
    ("UPDATE results SET reason = CAST(X'FF00' AS TEXT) WHERE seq = 1", lambda a, rid: a.results(rid)),
    ("UPDATE results SET outcome = 'guessed' WHERE seq = 2", lambda a, rid: a.results(rid)),
    ("UPDATE events SET payload = 'null' WHERE seq = 3", lambda a, rid: a.events(rid)),
    ("UPDATE control SET command = 'DANCE'", lambda a, rid: a.pending_control(rid)),
    ("UPDATE frames SET range = X'00112233'", lambda a, rid: a.frames(rid, "s0001")),
    ("UPDATE details SET payload = '\"text\"'", lambda a, rid: a.details(rid, "s0001")),
])
def test_a_stored_value_that_does_not_decode_is_one_archive_error(tmp_path: Path, sql: str, read):
    """Damage SQLite does not see (bad JSON, an unknown status, text that is not UTF-8, a
    frame that does not decompress) is found by the reader: ArchiveUnreadable naming the file."""
    from ita.archive import StoredFrame
    from ita.archive.store import ArchiveUnreadable

    path = tmp_path / "archive.sqlite"
    specs = fake_specs(6)
    with Archive.open(path) as archive:
        rid = record_synthetic_run(archive, specs, true_values(specs), status=RunStatus.RUNNING)
        archive.record_pending(rid, "s0001", details={"plan": [1]}, frames=[
            StoredFrame("s0001", 0, np.ones((2, 2)), np.ones((2, 2)), np.eye(4), (30.0, 20.0))])
        archive.issue_control(rid, "STOP")
    _damage_a_value(path, sql)
    with Archive.open(path, create=False) as archive, pytest.raises(ArchiveUnreadable) as err:
        read(archive, rid)
    assert str(err.value).startswith(f"{path}: cannot be read (") and "\n" not in str(err.value)


def test_an_empty_archive_file_is_no_archive_and_stays_empty(tmp_path: Path):
    runs = tmp_path / "runs"
    runs.mkdir()
    (runs / "archive.sqlite").write_bytes(b"")
    result = run("runs", "--runs-dir", str(runs))
    assert result.exit_code == 0 and "no runs" in result.output
    result = run("results", "last", "--runs-dir", str(runs))
    assert result.exit_code == 2 and "the file is empty" in one_error_line(result.output)
    assert (runs / "archive.sqlite").stat().st_size == 0          # a reader wrote nothing into it
    assert sorted(p.name for p in runs.iterdir()) == ["archive.sqlite"]


def test_a_wal_of_garbage_is_ignored(good_archive: bytes, tmp_path: Path):
    runs = tmp_path / "runs"
    runs.mkdir()
    (runs / "archive.sqlite").write_bytes(good_archive)
    (runs / "archive.sqlite-wal").write_bytes(random_bytes(50_000))
    result = run("runs", "--runs-dir", str(runs), "--json")
    assert result.exit_code == 0, result.output
    assert '"status": "completed"' in result.output


def _list_report_and_write(runs: Path, out: Path) -> str:
    """`ita runs` and `ita report` of the archive in `runs`, then a write to it: what the
    write said."""
    listed = run("runs", "--runs-dir", str(runs))
    assert listed.exit_code == 0 and "synthetic" in listed.output and "completed" in listed.output, listed.output
    reported = run("report", "last", "--no-score", "-o", str(out), "--runs-dir", str(runs))
    assert reported.exit_code == 0 and out.stat().st_size > 10_000, reported.output
    with Archive.open(runs / "archive.sqlite", create=False) as archive, pytest.raises(ArchiveError) as err:
        archive.set_status(archive.resolve("last"), RunStatus.FAILED)
    return str(err.value)


def test_an_archive_this_process_may_not_write_is_opened_read_only(good_archive: bytes, tmp_path: Path,
                                                                   monkeypatch):
    """What a user who may not write the archive (or its directory) sees, whoever runs the
    test (root may write anything, so the permission is made to say no)."""
    from ita.archive import store

    runs = tmp_path / "runs"
    runs.mkdir()
    (runs / "archive.sqlite").write_bytes(good_archive)
    monkeypatch.setattr(store, "_may_write", lambda _path: False)
    said = _list_report_and_write(runs, tmp_path / "r.html")
    assert said.startswith(f"{runs / 'archive.sqlite'}: cannot be written (read-only")
    assert (runs / "archive.sqlite").read_bytes() == good_archive


@pytest.mark.skipif(os.geteuid() == 0, reason="root writes read-only files and directories")
@pytest.mark.parametrize("what", ["file", "directory"])
def test_a_read_only_archive_can_be_listed_and_reported(good_archive: bytes, tmp_path: Path, what: str):
    """A read-only archive file, or a cleanly closed archive in a read-only directory (no
    -wal or -shm to share: opened immutable): listed, reported, a write refused, nothing
    made beside it in the read-only directory."""
    runs = tmp_path / "runs"
    runs.mkdir()
    (runs / "archive.sqlite").write_bytes(good_archive)
    (runs / "archive.sqlite").chmod(0o444 if what == "file" else 0o644)
    runs.chmod(0o755 if what == "file" else 0o555)
    try:
        said = _list_report_and_write(runs, tmp_path / "r.html")
    finally:
        runs.chmod(0o755)
    assert said.startswith(f"{runs / 'archive.sqlite'}: cannot be written (read-only")
    left = sorted(p.name for p in runs.iterdir())
    if what == "directory":
        assert left == ["archive.sqlite"]
    else:  # a reader in a writable directory shares the writer's -wal and -shm, as SQLite does
        assert set(left) <= {"archive.sqlite", "archive.sqlite-wal", "archive.sqlite-shm"}


def test_read_only_by_request(good_archive: bytes, tmp_path: Path):
    path = tmp_path / "archive.sqlite"
    path.write_bytes(good_archive)
    with Archive.open(path, create=False, read_only=True) as archive:
        rid = archive.resolve("last")
        assert len(archive.results(rid)) == 30
        with pytest.raises(ArchiveError, match="cannot be written"):
            archive.record_event(rid, Event("note", "top", 1.0))
    assert path.read_bytes() == good_archive


def _in_child_with_file_limit(code: str, limit: int, cwd: Path) -> subprocess.CompletedProcess[str]:
    """Python `code` in a child whose files cannot grow past `limit` bytes (RLIMIT_FSIZE:
    a write past it fails with EFBIG, as on a full disk; Python ignores SIGXFSZ)."""
    def limited() -> None:
        resource.setrlimit(resource.RLIMIT_FSIZE, (limit, limit))

    env = dict(os.environ, PYTHONPATH=f"{REPO}{os.pathsep}{REPO / 'tests'}")
    return subprocess.run([sys.executable, "-c", code], preexec_fn=limited, capture_output=True, text=True,
                          timeout=120, cwd=cwd, env=env)


def test_a_full_disk_under_the_archive_is_one_error_and_leaves_nothing(tmp_path: Path):
    """No room to create the archive: one ArchiveError, and no empty database, -wal or -shm
    left.  Room to create it but not for a large event: the transaction is rolled back,
    the archive keeps what it had."""
    code = """
import sys
from ita.archive import Archive, ArchiveError, Event
try:
    Archive.open("runs/archive.sqlite")
except ArchiveError as exc:
    print(exc)
"""
    (tmp_path / "runs").mkdir()
    done = _in_child_with_file_limit(code, 3000, tmp_path)
    assert done.returncode == 0, done.stderr
    assert done.stdout.startswith("runs/archive.sqlite: cannot be written (disk I/O error"), done.stdout
    assert list((tmp_path / "runs").iterdir()) == []
    code = """
from ita.archive import Archive, ArchiveError, Event
with Archive.open("runs/archive.sqlite") as archive:
    rid = archive.create_run("p", total=1)
    try:
        archive.record_event(rid, Event("note", "top", 1.0, {"text": "x" * 2_000_000}))
    except ArchiveError as exc:
        print(exc)
    print(len(archive.events(rid)))
"""
    done = _in_child_with_file_limit(code, 1_000_000, tmp_path)
    assert done.returncode == 0, done.stderr
    message, events = done.stdout.strip().splitlines()
    assert message.startswith("runs/archive.sqlite: cannot be written (") and events == "1"


def test_sqlite_full_is_no_space_left():
    from ita.archive.store import _database_error
    from ita.errors import NoSpaceLeft

    exc = sqlite3.OperationalError("database or disk is full")
    exc.sqlite_errorcode = sqlite3.SQLITE_FULL
    error = _database_error(Path("runs/archive.sqlite"), exc)
    assert isinstance(error, NoSpaceLeft) and isinstance(error, ArchiveError)
    assert str(error) == "runs/archive.sqlite: no space left on device"


# -- campaigns ---------------------------------------------------------------------------


def test_a_campaign_of_too_many_runs_is_refused_before_anything_is_made(tmp_path: Path):
    seeds = ", ".join(str(i) for i in range(3000))
    path = tmp_path / "huge.toml"
    path.write_text(f"[parts]\nseeds = [{seeds}]\n[appraisers]\nseeds = [{seeds}]\ntrials = 999\n")
    tracemalloc.start()
    started = time.monotonic()
    try:
        result = run("campaign", str(path))
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert result.exit_code == 2, result.output
    line = one_error_line(result.output)
    assert "[parts.seeds x appraisers.seeds x appraisers.trials]" in line
    assert "8,991,000,000 runs" in line and "at most 100,000" in line
    assert time.monotonic() - started < 10 and peak < 50e6
    assert sorted(p.name for p in tmp_path.iterdir()) == ["huge.toml"]


@pytest.mark.parametrize("seeds", ["[-1]", "[9223372036854775808]", "[99999999999999999999]"])
def test_campaign_seeds_have_a_range(tmp_path: Path, seeds: str):
    path = tmp_path / "c.toml"
    path.write_text(f"[parts]\nseeds = {seeds}\n[appraisers]\nseeds = [1]\n")
    result = run("campaign", str(path))
    assert result.exit_code == 2
    assert "[parts.seeds]" in one_error_line(result.output) and "from 0 to 9223372036854775807" in result.output


# -- part parameters ---------------------------------------------------------------------


def _params(tmp_path: Path, old: str, new: str) -> Path:
    text = PARAMS.read_text(encoding="utf-8")
    assert old in text, old
    path = tmp_path / "params.toml"
    path.write_text(text.replace(old, new, 1), encoding="utf-8")
    return path


RIBS = "x = [-950.0, -650.0, -300.0, 300.0, 650.0, 950.0]"


@pytest.mark.parametrize("old,new,field,says", [
    ("width = 2500.0", "width = -2500.0", "outline.width", "range 10 .. 5000"),
    ("width = 2500.0", "width = nan", "outline.width", "range 10 .. 5000, got nan"),
    ("thickness = 2.5", "thickness = inf", "web.thickness", "range 0.5 .. 50, got inf"),
    ("width = 1000.0", "width = 2600.0", "opening.width", "must stay inside the outline's flange"),
    ("fastener_pitch = 60.0", "fastener_pitch = 1e-9", "outer_flange.fastener_pitch", "range 5 .. 5000"),
    ("segments = 16", "segments = 100000000", "outer_flange.segments", "range 1 .. 200"),
    (RIBS, "x = [" + ", ".join(f"{-1199.5 + i:.1f}" for i in range(2400)) + "]", "stiffeners.x", "at most 30"),
    (RIBS, "x = []", "stiffeners", "at most 1,000,000 mm^2"),
    ("corner_radius = 350.0", "corner_radius = 0.0", "outline.corner_radius", "range > 0 .. 2500"),
    ("corner_radius = 350.0", "corner_radius = 900.0", "outline.corner_radius", "more than half"),
    ("seed = 1987", "seed = 99999999999999999999999", "part.seed", "range 0 .. 9223372036854775807"),
    ("fastener_diameter = 6.35", "fastener_diameter = 30.0", "outer_flange.fastener_diameter", "does not fit"),
])
def test_part_parameters_out_of_range_are_refused_at_once(tmp_path: Path, old: str, new: str, field: str,
                                                          says: str):
    params = _params(tmp_path, old, new)
    started = time.monotonic()
    result = run("part", "new", str(tmp_path / "made"), "--params", str(params))
    took = time.monotonic() - started
    assert result.exit_code == 2, result.output
    assert one_error_line(result.output).startswith(f"error: {params} [{field}]: ") and says in result.output
    assert took < 1.0, took
    assert sorted(p.name for p in tmp_path.iterdir()) == ["params.toml"]


def test_every_number_of_part_toml_has_its_range_written_beside_it():
    """bulkhead/part.toml is the schema: each numeric field's line (or, for [opening], the
    comment under its header) says `range LO .. HI`, the range the code checks."""
    import tomllib
    from typing import get_type_hints

    from ita.part.limits import RANGES
    from ita.part.params import BulkheadParams

    kinds = {table: kind.__name__ for table, kind in get_type_hints(BulkheadParams).items()}

    text = PARAMS.read_text(encoding="utf-8")
    data = tomllib.loads(text)
    table, notes = "", {}
    for line in text.splitlines():
        header = re.match(r"\[(\w+)\]", line)
        if header:
            table = header.group(1)
        key = re.match(r"(\w+)\s*=", line)
        if key and "range" in line:
            notes[(table, key.group(1))] = line
        elif line.startswith("#") and table:
            for k, bound in re.findall(r"(\w+): range ([^,]+)", line):
                notes.setdefault((table, k), f"range {bound}")
    numeric = [(t, k) for t, keys in data.items() for k, v in keys.items()
               if isinstance(v, (int, float, list)) and not isinstance(v, bool)]
    assert len(numeric) > 40
    for table, key in numeric:
        bound = RANGES[kinds[table]].get(key)
        assert bound is not None, f"{table}.{key} has no range in ita/part/limits.py"
        assert f"range {bound}" in notes.get((table, key), ""), f"{table}.{key}: its range is not written"


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGINT])
def test_a_signal_during_generation_removes_the_temporary_directory(tmp_path: Path, sig: signal.Signals):
    env = dict(os.environ, PYTHONPATH=str(REPO), ITA_HOME=str(tmp_path / "home"))
    proc = subprocess.Popen([sys.executable, "-m", "ita.cli", "part", "new", str(tmp_path / "made")],
                            env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        deadline = time.monotonic() + 60
        while not list(tmp_path.glob(".made-*")) and proc.poll() is None and time.monotonic() < deadline:
            time.sleep(0.02)
        assert list(tmp_path.glob(".made-*")), "generation did not start"
        time.sleep(0.3)
        proc.send_signal(sig)
        proc.communicate(timeout=60)
    finally:
        with contextlib.suppress(ProcessLookupError):
            proc.kill()
    assert proc.returncode == (128 + signal.SIGTERM if sig == signal.SIGTERM else 1)
    assert not list(tmp_path.glob(".made-*")) and not (tmp_path / "made").exists()


# -- seeds and other numbers -------------------------------------------------------------


@pytest.mark.parametrize("seed", ["-1", "99999999999999999999999"])
@pytest.mark.parametrize("command", [["inspect", "--limit", "1"], ["measure", "X"], ["part", "new", "{dir}"],
                                     ["part", "calibrate"], ["part", "asbuilt"], ["path", "problems", "-o", "{out}"]])
def test_every_seed_has_a_range(tmp_path: Path, command, seed: str):
    args = [a.format(dir=tmp_path / "made", out=tmp_path / "p.json") for a in command]
    if command[0] == "inspect":
        args += ["--runs-dir", str(tmp_path / "runs")]
    result = run(*args, "--seed", seed)
    assert result.exit_code == 2, result.output
    assert f"Invalid value for '--seed': {seed} is not in the range 0<=x<=9223372036854775807" in result.output
    assert "Traceback" not in result.output and list(tmp_path.iterdir()) == []


def test_inspect_seed_out_of_range_in_a_process(tmp_path: Path):
    """Today a traceback (numpy's, or SQLite's OverflowError after the run was made)."""
    env = dict(os.environ, PYTHONPATH=str(REPO), ITA_HOME=str(tmp_path / "home"))
    done = subprocess.run([sys.executable, "-m", "ita.cli", "inspect", "--seed", "-1", "--runs-dir",
                           str(tmp_path / "runs")], capture_output=True, text=True, timeout=60, env=env)
    assert done.returncode == 2 and "0<=x<=9223372036854775807" in done.stderr and "Traceback" not in done.stderr
    assert not (tmp_path / "runs").exists()


@pytest.mark.parametrize("args", [
    ["monitor", "last", "--interval", "nan"],
    ["monitor", "last", "--interval", "-1"],
    ["kb", "query", "true", "--time-limit", "nan"],
    ["kb", "query", "true", "--time-limit", "inf"],
    ["pddl", "solve", "{file}", "{file}", "--time-limit", "nan"],
    ["sequence", "tsp", "{file}", "--time-budget", "nan"],
    ["spec", "validate", "--max-distance", "inf"],
    ["part", "asbuilt", "--seed", "1", "--spread", "nan"],
    ["path", "problems", "-o", "{out}", "--n", "1000000000"],
])
def test_numbers_that_are_not_finite_or_too_large_are_refused(tmp_path: Path, args):
    (tmp_path / "f.txt").write_text("x")
    result = run(*[a.format(file=tmp_path / "f.txt", out=tmp_path / "p.json") for a in args])
    assert result.exit_code == 2, result.output
    assert "Invalid value for" in result.output and "range" in result.output
    assert sorted(p.name for p in tmp_path.iterdir()) == ["f.txt"]


# -- a full disk -------------------------------------------------------------------------


def test_a_full_disk_in_an_atomic_write_names_the_file_and_leaves_no_temporary_file(tmp_path: Path, monkeypatch):
    from ita.errors import ItaError
    from ita.files import atomic

    target = tmp_path / "specs.csv"
    target.write_text("old\n")

    def full(_fd: int) -> None:
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    monkeypatch.setattr(atomic.os, "fsync", full)
    with pytest.raises(ItaError) as err:
        atomic.write_atomic(target, "new\n" * 1000)
    assert str(err.value) == f"{target}: no space left on device"
    assert target.read_text() == "old\n" and sorted(p.name for p in tmp_path.iterdir()) == ["specs.csv"]

    def half(tmp: Path) -> None:
        tmp.write_text("half")
        raise OSError(errno.EFBIG, os.strerror(errno.EFBIG))

    with pytest.raises(ItaError) as err:
        atomic.write_with(tmp_path / "plot.png", half)
    assert str(err.value).startswith(f"{tmp_path / 'plot.png'}: no space left for it: file too large")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["specs.csv"]


@pytest.mark.skipif(not os.path.exists("/dev/full"), reason="needs /dev/full")
def test_a_full_disk_under_the_macrop_store(knowledge_base, tmp_path: Path):
    """The MACROP store, which SWI-Prolog writes: today a raw Prolog I/O message on a stream
    and its temporary file left.  Its temporary file made a link to /dev/full (a write
    there fails with ENOSPC): one NoSpaceLeft naming the store, the link gone, the store
    as it was."""
    from ita.errors import ItaError
    from ita.planning.operation import OperationPlanner

    store = tmp_path / "macrops" / "part.pl"
    with OperationPlanner(knowledge_base, store) as planner:
        planner.save()
        before = store.read_bytes()
        tmp = store.with_name("part.pl.tmp")
        tmp.symlink_to("/dev/full")
        with pytest.raises(ItaError) as err:
            planner.save()
        assert str(err.value) == f"{store}: no space left on device"
        assert not tmp.is_symlink() and store.read_bytes() == before
    assert sorted(p.name for p in store.parent.iterdir()) == ["part.pl"]


# -- meshes ------------------------------------------------------------------------------

FACET = "facet normal 0 0 1\nouter loop\nvertex {}\nvertex {} 0 0\nvertex 0 {} 0\nendloop\nendfacet\n"


def _part_dir(tmp_path: Path, mesh: bytes, name: str = "m.stl") -> Path:
    from ita.specs.io import COLUMNS

    part = tmp_path / "part"
    part.mkdir()
    (part / name).write_bytes(mesh)
    (part / "specs.csv").write_text(",".join(COLUMNS) + "\n", encoding="utf-8")
    return part


def _binary_stl(triangles: list[list[tuple[float, float, float]]]) -> bytes:
    import struct

    out = bytearray(b"\0" * 80 + struct.pack("<I", len(triangles)))
    for tri in triangles:
        out += struct.pack("<3f", 0, 0, 1) + b"".join(struct.pack("<3f", *v) for v in tri) + b"\0\0"
    return bytes(out)


@pytest.mark.parametrize("kind", ["ascii", "binary"])
def test_triangles_with_nan_or_infinite_vertices_are_dropped_and_counted(tmp_path: Path, kind: str):
    if kind == "ascii":
        mesh = ("solid x\n" + FACET.format("nan 0 0", 1, 1) + FACET.format("0 0 0", 100, 100)
                + FACET.format("0 inf 0", 1, 1) + FACET.format("0 0 0", 50, 60) + "endsolid x\n").encode()
    else:
        good = [(0.0, 0.0, 0.0), (100.0, 0.0, 0.0), (0.0, 100.0, 0.0)]
        mesh = _binary_stl([[(float("inf"), 0.0, 0.0), (1.0, 0.0, 0.0), (0.0, 1.0, 0.0)], good,
                            [(0.0, float("nan"), 0.0), (1.0, 0.0, 0.0), (0.0, 1.0, 0.0)],
                            [(0.0, 0.0, 0.0), (50.0, 0.0, 0.0), (0.0, 60.0, 0.0)]])
    part = _part_dir(tmp_path, mesh)
    result = run("part", "info", "--part", str(part))
    assert result.exit_code == 0, result.output
    assert (f"warning: {part / 'm.stl'}: dropped 2 of 4 triangles, each with a vertex with NaN or infinite "
            "coordinates (2 left)") in result.output
    assert "Warning" not in result.output.replace("warning:", "")
