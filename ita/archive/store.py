"""The results archive: an embedded SQLite database of runs, results, events and control.

    archive = Archive.open(archive_path())                 # ita_home()/runs/archive.sqlite
    run_id = archive.create_run("bulkhead", part_dir, seed=1, total=len(specs))
    for spec in specs:                                     # continue: skip archive.done_spec_ids(run_id)
        archive.record_event(run_id, Event("plan_start", "top", t, {"spec": spec.id}))
        ...
        archive.record_result(run_id, Result.measured(spec, value, u, tool="us_tool"),
                              events=[Event("reply", "gauge", t1, {"cmd": 7, "status": "ok"})])
    archive.set_status(run_id, RunStatus.COMPLETED)

Durability.  Every write is one transaction, committed before the call returns.  The
database is in WAL mode with synchronous=NORMAL: a COMMIT has appended the transaction's
frames (with its commit marker and checksums) to the -wal file by write(2) before it
returns; those bytes are then in the kernel's page cache, which a SIGKILL of the process
cannot take back, and the next process (or a concurrent reader) sees the transaction.  A
process killed in the middle of a transaction leaves frames without a commit marker,
which SQLite ignores on recovery: the transaction is simply not there.  So a committed
result survives SIGKILL, and a half-written one does not exist.  Only an OS crash or a
power loss can lose the last commits with NORMAL; `durable=True` selects
synchronous=FULL (an fsync per commit) for those, at a cost of milliseconds per commit.

Exactly once.  A result and the events given with it are written in one transaction:
both or neither.  results has UNIQUE(run_id, spec_id); recording a spec that already
has a result in the run changes nothing (not the result, not its events) and returns
False: the first result stands.  A continued run asks `done_spec_ids` and skips those.
One deliberate exception, with its record: `supersede` takes results out when the cell's
interim check found the arm (or the part) off since they were measured; an event keeps
what was taken out, and the run measures them again.

Readers (`ita runs`, `ita results`, the System Monitor) may read while a run writes: WAL
lets readers and one writer proceed together; writers wait up to `busy_timeout` seconds.
An archive this process may not write (its file or directory read-only) is opened
read-only for the readers (create=False): it is listed and reported.

Errors.  Every SQLite error, text that is not UTF-8 and stored value that does not decode
(bad JSON, an unknown status, a frame that does not decompress), at open and in every
method, is one ArchiveError naming the file: ArchiveUnreadable ("ARCHIVE: cannot be read
(...)") for damage, ArchiveFull ("ARCHIVE: no space left on device"), ArchiveReadOnly, or
"cannot be written (...)" for another failed write, whose transaction is rolled back.  The
CLI and the web server each turn it into one line.
"""

from __future__ import annotations

import functools
import json
import os
import secrets
import socket
import sqlite3
import stat
import time
import urllib.parse
import zlib
from collections.abc import Callable, Iterable, Iterator, Mapping, Sequence
from contextlib import contextmanager, suppress
from dataclasses import replace
from datetime import UTC, datetime
from pathlib import Path
from typing import Any, Concatenate, ParamSpec, Protocol, Self, TypeVar

from ita.archive.decision import Decision
from ita.archive.frames import StoredFrame, decode, encode
from ita.archive.model import (
    ControlCommand,
    ControlRequest,
    Event,
    EventKind,
    Outcome,
    Result,
    RunInfo,
    RunStatus,
    StoredResult,
)
from ita.archive.schema import (
    SCHEMA_VERSION,
    SchemaError,
    ensure_schema,
    schema_version,
)
from ita.errors import ItaError, NoSpaceLeft
from ita.paths import ita_home

DB_FILE = "archive.sqlite"
ENV_RUNS = "ITA_RUNS"


class ArchiveError(ItaError):
    """A request the archive cannot satisfy (unknown or ambiguous run, run busy, ...)."""


class UnknownRun(ArchiveError):
    """No run has that id (or prefix)."""


class RunBusy(ArchiveError):
    """The run is being run by a live process."""


class NoArchive(ArchiveError):
    """There is no archive database at the path (and it was not to be created)."""


class ArchiveUnreadable(ArchiveError):
    """The archive cannot be read: its file is damaged, is not an archive, or is not a file.

    Raised for any damage SQLite reports, text that is not UTF-8 and stored values that do
    not decode (bad JSON, an unknown status), at open and on every read: one line naming
    the file, exit code 2.
    """

    def __init__(self, path: Path | str, reason: str):
        self.path = Path(path)
        self.reason = reason
        super().__init__(f"{path}: cannot be read ({reason})")


class NotAnArchive(ArchiveUnreadable, SchemaError):
    """The file is an SQLite database, but not an ITA archive."""


class ArchiveReadOnly(ArchiveError):
    """A write to an archive that this process may only read (its file or directory is read-only)."""


class ArchiveFull(NoSpaceLeft, ArchiveError):
    """A write to the archive failed for want of room; the transaction was rolled back."""


#: what a stored value that does not decode raises (json, enums, int(), zlib, numpy reshape)
_DECODE_ERRORS = (ValueError, TypeError, KeyError, OverflowError, zlib.error)


#: SQLite's I/O errors of writing (a file-size limit gives these where a full disk gives SQLITE_FULL)
_WRITE_IOERRS = frozenset({sqlite3.SQLITE_IOERR_WRITE, sqlite3.SQLITE_IOERR_FSYNC, sqlite3.SQLITE_IOERR_DIR_FSYNC,
                           sqlite3.SQLITE_IOERR_TRUNCATE, sqlite3.SQLITE_IOERR_SHMSIZE})


def _database_error(path: Path, exc: sqlite3.DatabaseError, writing: bool = False) -> ArchiveError:
    """The archive error a failed SQLite call stands for: full, read-only, busy, not
    writable or unreadable (damage is unreadable, even met while `writing`)."""
    extended = getattr(exc, "sqlite_errorcode", None) or 0
    code = extended & 0xFF
    if code == sqlite3.SQLITE_FULL:
        return ArchiveFull(str(path))
    if extended in _WRITE_IOERRS:
        return ArchiveError(f"{path}: cannot be written ({exc}, {getattr(exc, 'sqlite_errorname', '')}: is the "
                            "disk full, or the file-size limit reached?)")
    if code == sqlite3.SQLITE_READONLY:
        return ArchiveReadOnly(f"{path}: cannot be written (read-only: {exc})")
    if code in (sqlite3.SQLITE_BUSY, sqlite3.SQLITE_LOCKED):
        return ArchiveError(f"{path}: busy ({exc}); another process holds it, try again")
    if writing and code not in (sqlite3.SQLITE_CORRUPT, sqlite3.SQLITE_NOTADB):
        return ArchiveError(f"{path}: cannot be written ({exc})")
    return ArchiveUnreadable(path, str(exc))


def _unreadable(path: Path, exc: BaseException, writing: bool = False) -> ArchiveError:
    """The archive error for `exc` met while reading, or while `writing`."""
    if isinstance(exc, sqlite3.DatabaseError):
        return _database_error(path, exc, writing)
    if isinstance(exc, UnicodeDecodeError):
        return ArchiveUnreadable(path, f"stored text is not UTF-8: {exc}")
    return ArchiveUnreadable(path, f"a stored value is damaged: {type(exc).__name__}: {exc}")


P = ParamSpec("P")
R = TypeVar("R")


class _Guard(Protocol):
    """What `_guarded` makes: a decorator of Archive's methods that keeps their signatures."""

    def __call__(self, method: Callable[Concatenate[Archive, P], R], /) -> Callable[Concatenate[Archive, P], R]: ...


def _guarded(*decode_errors: type[BaseException], writing: bool = False) -> _Guard:
    """A method of Archive whose SQLite errors, text that is not UTF-8 and (for readers,
    `decode_errors`) stored values that do not decode become one ArchiveError naming the
    file.  The programming errors of a caller (sqlite3.ProgrammingError, InterfaceError)
    pass through."""
    caught: tuple[type[BaseException], ...] = (sqlite3.DatabaseError, UnicodeDecodeError, *decode_errors)

    def decorate(method: Callable[Concatenate[Archive, P], R]) -> Callable[Concatenate[Archive, P], R]:
        @functools.wraps(method)
        def wrapper(self: Archive, *args: P.args, **kwargs: P.kwargs) -> R:
            try:
                return method(self, *args, **kwargs)
            except ItaError:
                raise
            except sqlite3.ProgrammingError:
                raise
            except caught as exc:
                raise _unreadable(self.path, exc, writing) from exc

        return wrapper

    return decorate


_reads = _guarded(*_DECODE_ERRORS)
_writes = _guarded(writing=True)
_updates = _guarded(*_DECODE_ERRORS, writing=True)  # a write of what it has just read


def runs_dir(explicit: Path | str | None = None) -> Path:
    """The runs directory: `explicit`, else $ITA_RUNS, else ita_home()/runs (not created here)."""
    if explicit:
        return Path(explicit).expanduser()
    env = os.environ.get(ENV_RUNS)
    if env:
        return Path(env).expanduser()
    return ita_home() / "runs"


def archive_path(directory: Path | str | None = None) -> Path:
    """The archive database in the runs directory (see `runs_dir`)."""
    return runs_dir(directory) / DB_FILE


def new_run_id(now: datetime | None = None) -> str:
    """A fresh run id, 'r' + UTC date and time + 4 random hex digits: r20261121-153012-ab12."""
    now = now or datetime.now(UTC)
    return f"r{now:%Y%m%d-%H%M%S}-{secrets.token_hex(2)}"


def _json(obj: Any) -> str:
    def default(o: Any) -> Any:
        if hasattr(o, "item"):  # numpy scalars
            return o.item()
        if hasattr(o, "tolist"):  # numpy arrays
            return o.tolist()
        if hasattr(o, "value"):  # enums
            return o.value
        if isinstance(o, (set, frozenset)):
            return sorted(o, key=str)
        return str(o)

    return json.dumps(dict(obj or {}), default=default, sort_keys=True)


def _now_iso() -> str:
    return datetime.now(UTC).isoformat(timespec="seconds")


_RESULT_COLUMNS = ("run_id, spec_id, seq, outcome, value, u, k, u_expanded, nominal, lower, upper, decision, "
                   "tool, reason, sim_time_start, sim_time_end, wall_time, kind, x, y, z")
_RUN_COLUMNS = "id, part, part_dir, seed, created, status, pid, host, settings, totals, ended"


class Archive:
    """One connection to an archive database.  Use `Archive.open`; close it (or use `with`).

    Not shared between threads; each process (or thread) opens its own.
    """

    def __init__(self, conn: sqlite3.Connection, path: Path):
        self._conn = conn
        self.path = path

    # ----------------------------------------------------------------- opening
    @classmethod
    def open(cls, path: Path | str | None = None, *, create: bool = True, durable: bool = False,
             busy_timeout: float = 10.0, read_only: bool | None = None) -> Archive:
        """Open (by default creating) the archive at `path` (default: `archive_path()`).

        durable: synchronous=FULL (survive power loss too) instead of NORMAL (survive a
        killed process).  create=False raises NoArchive when there is no database yet (or
        its file is empty).  read_only: open for reading only, writing nothing beside it;
        None (the default) chooses it for create=False when this process may not write the
        file or its directory, so a read-only archive can still be listed and reported.
        Raises ArchiveUnreadable for a file that is damaged, not an archive or not a
        regular file, SchemaError for a database of a newer ITA.
        """
        path = Path(path) if path is not None else archive_path()
        made = False  # this call makes the file: on failure it removes it again
        try:
            info = path.stat()
        except FileNotFoundError:
            if not create:
                raise NoArchive(f"no archive at {path} (no run has been recorded there)") from None
            path.parent.mkdir(parents=True, exist_ok=True)
            made = True
        else:
            if not stat.S_ISREG(info.st_mode):
                raise ArchiveUnreadable(path, f"{_file_kind(info.st_mode)}, not a file")
            if not create and info.st_size == 0:
                raise NoArchive(f"no archive at {path} (the file is empty: no run has been recorded there)")
        if read_only is None:
            read_only = not create and not _may_write(path)
        conn = None
        try:
            conn = _connect(path, read_only, busy_timeout)
            conn.execute(f"PRAGMA busy_timeout = {int(busy_timeout * 1000)}")
            if read_only:
                _check_readable_schema(conn, path)
            else:
                conn.execute("PRAGMA journal_mode = WAL")
                conn.execute(f"PRAGMA synchronous = {'FULL' if durable else 'NORMAL'}")
                conn.execute("PRAGMA foreign_keys = ON")
                ensure_schema(conn, str(path))
        except BaseException as exc:
            if conn is not None:
                conn.close()
            if made:  # nothing left behind: not an empty database, nor its -wal and -shm
                for leftover in (path, path.with_name(path.name + "-wal"), path.with_name(path.name + "-shm")):
                    leftover.unlink(missing_ok=True)
            if isinstance(exc, SchemaError) and "newer ITA" not in str(exc):
                raise NotAnArchive(path, str(exc)) from None
            if isinstance(exc, (sqlite3.DatabaseError, UnicodeDecodeError)) \
                    and not isinstance(exc, sqlite3.ProgrammingError):
                raise _unreadable(path, exc) from None
            raise
        return cls(conn, path)

    def close(self) -> None:
        self._conn.close()

    def __enter__(self) -> Self:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    @contextmanager
    def _write(self) -> Iterator[sqlite3.Connection]:
        """One write transaction: taken at once (IMMEDIATE), committed or rolled back."""
        self._conn.execute("BEGIN IMMEDIATE")
        try:
            yield self._conn
            self._conn.execute("COMMIT")
        except BaseException:
            if self._conn.in_transaction:  # SQLite may have rolled back itself (a full disk)
                with suppress(sqlite3.Error):
                    self._conn.execute("ROLLBACK")
            raise

    @_reads
    def integrity_check(self) -> str:
        """SQLite's PRAGMA integrity_check: "ok" when the file is sound."""
        return "\n".join(r[0] for r in self._conn.execute("PRAGMA integrity_check"))

    # -------------------------------------------------------------------- runs
    @_writes
    def create_run(self, part: str, part_dir: Path | str | None = None, *, seed: int | None = None,
                   settings: Mapping[str, Any] | None = None, total: int | None = None,
                   run_id: str | None = None, pid: int | None = None, host: str | None = None,
                   sim_time: float | None = 0.0) -> str:
        """Register a new RUNNING run of this process (or `pid`); returns its id.

        total: the number of specs the run sets out to do (totals["specs"]).  A run_start
        event (top stream) is recorded with it.
        """
        pid = os.getpid() if pid is None else pid
        host = socket.gethostname() if host is None else host
        totals = {} if total is None else {"specs": int(total)}
        with self._write() as c:
            rid = run_id or new_run_id()
            while run_id is None and c.execute("SELECT 1 FROM runs WHERE id = ?", (rid,)).fetchone():
                rid = new_run_id()
            c.execute(f"INSERT INTO runs({_RUN_COLUMNS}) VALUES (?,?,?,?,?,?,?,?,?,?,NULL)",
                      (rid, part, None if part_dir is None else str(part_dir), seed, _now_iso(),
                       RunStatus.RUNNING.value, pid, host, _json(settings), _json(totals)))
            self._insert_events(c, rid, [Event(EventKind.RUN_START, "top", sim_time,
                                               {"pid": pid, "host": host, "total": total})])
        return rid

    @_writes
    def resume_run(self, run_id: str, *, pid: int | None = None, host: str | None = None,
                   sim_time: float | None = None, force: bool = False) -> RunInfo:
        """Take up a run again in this process (or `pid`): status RUNNING, a resume event.

        Refuses (RunBusy) a run still RUNNING in a live process, or on another host where
        that cannot be checked, and (ArchiveError) a COMPLETED run, unless `force`.  STOP and
        INTERRUPT requests left untaken by the previous process are discarded.
        """
        info = self.run(run_id)
        if not force:
            if info.status is RunStatus.RUNNING and info.alive is not False:
                where = f"pid {info.pid} on {info.host}"
                raise RunBusy(f"run {run_id} is running ({where}); wait for it to end, or stop it first "
                              f"(ita monitor {run_id} --stop) and then continue it")
            if info.status is RunStatus.COMPLETED:
                raise ArchiveError(f"run {run_id} is completed; there is nothing to continue")
        pid = os.getpid() if pid is None else pid
        host = socket.gethostname() if host is None else host
        if sim_time is None:
            sim_time = self.last_sim_time(run_id)
        with self._write() as c:
            dropped = c.execute("UPDATE control SET taken = ? WHERE run_id = ? AND taken IS NULL",
                                (time.time(), run_id)).rowcount
            c.execute("UPDATE runs SET status = ?, pid = ?, host = ?, ended = NULL WHERE id = ?",
                      (RunStatus.RUNNING.value, pid, host, run_id))
            self._insert_events(c, run_id, [Event(EventKind.RESUME, "top", sim_time, {
                "pid": pid, "host": host, "previous_status": info.state_label, "done": info.done,
                "discarded_control": dropped})])
        return self.run(run_id)

    @_writes
    def set_status(self, run_id: str, status: RunStatus | str, *, event: Event | None = None) -> None:
        """Set the run's status (with `event`, e.g. a stop event, in the same transaction).

        Any status but RUNNING also sets `ended`.
        """
        status = RunStatus(status)
        ended = None if status is RunStatus.RUNNING else _now_iso()
        with self._write() as c:
            if not c.execute("UPDATE runs SET status = ?, ended = ? WHERE id = ?",
                             (status.value, ended, run_id)).rowcount:
                raise UnknownRun(f"no run {run_id!r}")
            if event is not None:
                self._insert_events(c, run_id, [event])

    @_updates
    def update_totals(self, run_id: str, **values: Any) -> dict[str, Any]:
        """Merge `values` into the run's totals (a JSON object); returns the new totals."""
        with self._write() as c:
            row = c.execute("SELECT totals FROM runs WHERE id = ?", (run_id,)).fetchone()
            if row is None:
                raise UnknownRun(f"no run {run_id!r}")
            totals = _stored_object(row[0])
            totals.update(values)
            c.execute("UPDATE runs SET totals = ? WHERE id = ?", (_json(totals), run_id))
        return json.loads(_json(totals))

    @_reads
    def runs(self, prefix: str = "") -> list[RunInfo]:
        """Every run (whose id starts with `prefix`), in the order they were created."""
        rows = self._conn.execute(f"SELECT {_RUN_COLUMNS} FROM runs WHERE substr(id, 1, ?) = ? ORDER BY rowid",
                                  (len(prefix), prefix)).fetchall()
        return [self._run_info(r) for r in rows]

    @_reads
    def run(self, run_id: str) -> RunInfo:
        """The run `run_id` (exact id); UnknownRun when there is none."""
        row = self._conn.execute(f"SELECT {_RUN_COLUMNS} FROM runs WHERE id = ?", (run_id,)).fetchone()
        if row is None:
            raise UnknownRun(f"no run {run_id!r} in {self.path}")
        return self._run_info(row)

    @_reads
    def resolve(self, ref: str) -> str:
        """The id of the run `ref` names: an exact id, a unique prefix of one, or "last"."""
        ref = ref.strip()
        if ref == "last":
            row = self._conn.execute("SELECT id FROM runs ORDER BY rowid DESC LIMIT 1").fetchone()
            if row is None:
                raise UnknownRun(f"no runs in {self.path}")
            return row[0]
        if not ref:
            raise UnknownRun("empty run id")
        if self._conn.execute("SELECT 1 FROM runs WHERE id = ?", (ref,)).fetchone():
            return ref
        ids = [r[0] for r in self._conn.execute(
            "SELECT id FROM runs WHERE substr(id, 1, ?) = ? ORDER BY id", (len(ref), ref))]
        if not ids:
            raise UnknownRun(f"no run {ref!r} in {self.path} (see `ita runs`)")
        if len(ids) > 1:
            shown = ", ".join(ids[:5]) + (", ..." if len(ids) > 5 else "")
            raise ArchiveError(f"run prefix {ref!r} is ambiguous: {len(ids)} runs match ({shown})")
        return ids[0]

    def _run_info(self, row: Sequence[Any]) -> RunInfo:
        rid = row[0]
        done = self._conn.execute("SELECT COUNT(*) FROM results WHERE run_id = ?", (rid,)).fetchone()[0]
        return RunInfo(rid, row[1], row[2], row[3], row[4], RunStatus(row[5]), row[6], row[7],
                       _stored_object(row[8]), _stored_object(row[9]), row[10], int(done), self.last_sim_time(rid))

    @_reads
    def last_sim_time(self, run_id: str) -> float | None:
        """The latest simulated time recorded in the run (events and result ends), or None.

        A continued run should carry on its simulated clock from here.
        """
        a = self._conn.execute("SELECT MAX(sim_time) FROM events WHERE run_id = ?", (run_id,)).fetchone()[0]
        b = self._conn.execute("SELECT MAX(sim_time_end) FROM results WHERE run_id = ?", (run_id,)).fetchone()[0]
        known = [t for t in (a, b) if t is not None]
        return max(known) if known else None

    # ----------------------------------------------------------------- results
    @_writes
    def record_result(self, run_id: str, result: Result, events: Iterable[Event] = (), *,
                      details: Mapping[str, Any] | None = None, frames: Iterable[StoredFrame] = ()) -> bool:
        """Commit `result` and `events` (in order, after it) in one transaction.

        Events without a spec_id get the result's.  details: a JSON-ready object kept
        beside the result (`details`); frames: the range frames of its plan (`frames`).
        Returns True when written; False, and nothing written, when the run already has
        a result for this spec (the first result stands).  UnknownRun for an unknown run.
        """
        events = list(events)
        frames = list(frames)
        with self._write() as c:
            if not c.execute("SELECT 1 FROM runs WHERE id = ?", (run_id,)).fetchone():
                raise UnknownRun(f"no run {run_id!r} in {self.path}")
            if c.execute("SELECT 1 FROM results WHERE run_id = ? AND spec_id = ?",
                         (run_id, result.spec_id)).fetchone():
                return False
            seq = c.execute("SELECT COALESCE(MAX(seq), 0) + 1 FROM results WHERE run_id = ?",
                            (run_id,)).fetchone()[0]
            point = result.point or (None, None, None)
            c.execute(f"INSERT INTO results({_RESULT_COLUMNS}) VALUES ({','.join('?' * 21)})", (
                run_id, result.spec_id, seq, result.outcome.value, result.value, result.u, result.k, result.U,
                result.nominal, result.lower, result.upper,
                None if result.decision is None else result.decision.value, result.tool, result.reason,
                result.sim_time_start, result.sim_time_end, time.time(), result.kind, *point))
            self._insert_events(c, run_id, events, default_spec=result.spec_id)
            if details:
                c.execute("INSERT OR REPLACE INTO details(run_id, spec_id, payload) VALUES (?, ?, ?)",
                          (run_id, result.spec_id, _json(details)))
            for f in frames:
                c.execute("INSERT OR REPLACE INTO frames(run_id, spec_id, n, meta, range, intensity) "
                          "VALUES (?, ?, ?, ?, ?, ?)", (run_id, f.spec_id, f.n, *encode(f)))
        return True

    @_writes
    def supersede(self, run_id: str, spec_ids: Sequence[str], event: Event) -> list[str]:
        """Take the results of `spec_ids` out of the run (with their details and frames), in
        one transaction with `event`, which gets the results taken out (spec, value, U,
        decision, outcome) in its payload's ``superseded``: what the cell's interim check
        found wrong since they were measured (an arm off its calibration) is measured
        again, and nothing is lost.  The specs whose results were taken out, in order."""
        with self._write() as c:
            if not c.execute("SELECT 1 FROM runs WHERE id = ?", (run_id,)).fetchone():
                raise UnknownRun(f"no run {run_id!r} in {self.path}")
            gone: list[dict[str, Any]] = []
            for spec_id in spec_ids:
                row = c.execute(f"SELECT {_RESULT_COLUMNS} FROM results WHERE run_id = ? AND spec_id = ?",
                                (run_id, spec_id)).fetchone()
                if row is None:
                    continue
                r = _stored_result(row)
                gone.append({"spec": spec_id, "value": r.value, "U": r.U, "outcome": r.outcome.value,
                             "decision": None if r.decision is None else r.decision.value, "reason": r.reason})
                for table in ("results", "details", "frames"):
                    c.execute(f"DELETE FROM {table} WHERE run_id = ? AND spec_id = ?", (run_id, spec_id))
            self._insert_events(c, run_id, [replace(event, payload={**event.payload, "superseded": gone})])
        return [g["spec"] for g in gone]

    @_writes
    def record_pending(self, run_id: str, spec_id: str, events: Iterable[Event] = (), *,
                       details: Mapping[str, Any] | None = None, frames: Iterable[StoredFrame] = ()) -> None:
        """Commit what a measurement whose result is not decided yet has made (its events,
        details and range frames) in one transaction, with no result: a result waiting for
        its network.  Its later `record_result` replaces the details and frames it gives.
        Events without a spec_id get `spec_id`."""
        events = list(events)
        frames = list(frames)
        with self._write() as c:
            if not c.execute("SELECT 1 FROM runs WHERE id = ?", (run_id,)).fetchone():
                raise UnknownRun(f"no run {run_id!r} in {self.path}")
            self._insert_events(c, run_id, events, default_spec=spec_id)
            if details:
                c.execute("INSERT OR REPLACE INTO details(run_id, spec_id, payload) VALUES (?, ?, ?)",
                          (run_id, spec_id, _json(details)))
            for f in frames:
                c.execute("INSERT OR REPLACE INTO frames(run_id, spec_id, n, meta, range, intensity) "
                          "VALUES (?, ?, ?, ?, ?, ?)", (run_id, f.spec_id, f.n, *encode(f)))

    @_reads
    def details(self, run_id: str, spec_id: str) -> dict[str, Any]:
        """What was kept beside the result of `spec_id` ({} when nothing)."""
        row = self._conn.execute("SELECT payload FROM details WHERE run_id = ? AND spec_id = ?",
                                 (run_id, spec_id)).fetchone()
        return _stored_object(row[0]) if row else {}

    @_reads
    def frames(self, run_id: str, spec_id: str) -> list[StoredFrame]:
        """The range frames the plan of `spec_id` took, in order (n)."""
        rows = self._conn.execute("SELECT spec_id, n, meta, range, intensity FROM frames WHERE run_id = ? "
                                  "AND spec_id = ? ORDER BY n", (run_id, spec_id)).fetchall()
        return [decode(*r) for r in rows]

    @_reads
    def frame_count(self, run_id: str) -> int:
        """How many range frames the run keeps."""
        return int(self._conn.execute("SELECT COUNT(*) FROM frames WHERE run_id = ?", (run_id,)).fetchone()[0])

    @_reads
    def done_spec_ids(self, run_id: str) -> set[str]:
        """Ids of the specs that have a result in the run (any outcome): skip them on continue."""
        return {r[0] for r in self._conn.execute("SELECT spec_id FROM results WHERE run_id = ?", (run_id,))}

    @_reads
    def results(self, run_id: str, *, failed_only: bool = False, after: int | None = None,
                last: int | None = None) -> list[StoredResult]:
        """The run's results in the order recorded; failed_only: all but CONFORMS; after:
        only those with a seq above it; last: only the last n."""
        sql = f"SELECT {_RESULT_COLUMNS} FROM results WHERE run_id = ?"
        args: list[Any] = [run_id]
        if failed_only:
            sql += " AND (decision IS NULL OR decision != 'conforms')"
        if after is not None:
            sql += " AND seq > ?"
            args.append(int(after))
        if last is not None:
            rows = self._conn.execute(sql + " ORDER BY seq DESC LIMIT ?", [*args, int(last)]).fetchall()[::-1]
        else:
            rows = self._conn.execute(sql + " ORDER BY seq", args).fetchall()
        return [_stored_result(r) for r in rows]

    @_reads
    def merged_results(self, runs: Iterable[str], handed: Iterable[str] = ()) -> dict[str, StoredResult]:
        """The results of several runs as one (a two-arm run: its arms' runs, then its
        hand-over runs), by spec: each spec's result in the runs, a hand-over run's where
        it measured the spec (or the spec has none yet).  Runs the archive lacks are skipped."""
        known = {r.id for r in self.runs()}
        last: dict[str, StoredResult] = {}
        for run_id in runs:
            if run_id in known:
                last.update({r.spec_id: r for r in self.results(run_id)})
        for run_id in handed:
            if run_id in known:
                last.update({r.spec_id: r for r in self.results(run_id)
                             if r.outcome is Outcome.MEASURED or r.spec_id not in last})
        return last

    @_reads
    def result(self, run_id: str, spec_id: str) -> StoredResult | None:
        """The result of `spec_id` in the run, or None."""
        row = self._conn.execute(f"SELECT {_RESULT_COLUMNS} FROM results WHERE run_id = ? AND spec_id = ?",
                                 (run_id, spec_id)).fetchone()
        return None if row is None else _stored_result(row)

    @_reads
    def decision_counts(self, run_id: str) -> dict[str, int]:
        """Results per decision ("conforms", ...) and per unmeasured outcome ("not_done", ...)."""
        rows = self._conn.execute(
            "SELECT COALESCE(decision, outcome), COUNT(*) FROM results WHERE run_id = ? GROUP BY 1", (run_id,))
        return {k: n for k, n in rows}

    # ------------------------------------------------------------------ events
    @_writes
    def record_event(self, run_id: str, event: Event) -> int:
        """Commit one event now; returns its seq."""
        return self.record_events(run_id, [event])[0]

    @_writes
    def record_events(self, run_id: str, events: Iterable[Event]) -> list[int]:
        """Commit events in one transaction, in order; returns their seqs."""
        events = list(events)
        with self._write() as c:
            if not c.execute("SELECT 1 FROM runs WHERE id = ?", (run_id,)).fetchone():
                raise UnknownRun(f"no run {run_id!r} in {self.path}")
            return self._insert_events(c, run_id, events)

    def _insert_events(self, c: sqlite3.Connection, run_id: str, events: Sequence[Event],
                       default_spec: str | None = None) -> list[int]:
        if not events:
            return []
        first = c.execute("SELECT COALESCE(MAX(seq), 0) + 1 FROM events WHERE run_id = ?", (run_id,)).fetchone()[0]
        now = time.time()
        seqs = list(range(first, first + len(events)))
        c.executemany(
            "INSERT INTO events(run_id, seq, sim_time, wall_time, kind, stream, spec_id, payload) "
            "VALUES (?,?,?,?,?,?,?,?)",
            [(run_id, s, e.sim_time, now, e.kind, e.stream, e.spec_id or default_spec, _json(e.payload))
             for s, e in zip(seqs, events)])
        return seqs

    @_reads
    def count_events(self, run_id: str, kind: str) -> int:
        """How many events of `kind` the run has."""
        row = self._conn.execute("SELECT COUNT(*) FROM events WHERE run_id = ? AND kind = ?", (run_id, kind)).fetchone()
        return int(row[0])

    @_reads
    def events(self, run_id: str, *, kinds: Iterable[str] | None = None,
               spec_id: str | None = None, after: int | None = None, last: int | None = None) -> list[Event]:
        """The run's events in order (seq), optionally of some kinds, of one spec, with a
        seq above `after`, or only the `last` n of them."""
        sql = "SELECT seq, sim_time, wall_time, kind, stream, spec_id, payload FROM events WHERE run_id = ?"
        args: list[Any] = [run_id]
        if after is not None:
            sql += " AND seq > ?"
            args.append(int(after))
        if kinds is not None:
            kinds = [getattr(k, "value", k) for k in kinds]
            sql += f" AND kind IN ({','.join('?' * len(kinds))})"
            args += kinds
        if spec_id is not None:
            sql += " AND spec_id = ?"
            args.append(spec_id)
        if last is not None:
            rows = self._conn.execute(sql + " ORDER BY seq DESC LIMIT ?", [*args, int(last)]).fetchall()[::-1]
        else:
            rows = self._conn.execute(sql + " ORDER BY seq", args).fetchall()
        return [Event(kind, stream, sim, _stored_object(payload), spec, seq, wall)
                for seq, sim, wall, kind, stream, spec, payload in rows]

    # ----------------------------------------------------------------- control
    @_writes
    def issue_control(self, run_id: str, command: ControlCommand | str) -> int:
        """Ask the process running `run_id` to STOP or INTERRUPT; returns the request id.

        ArchiveError when the run is not RUNNING.
        """
        command = ControlCommand(str(getattr(command, "value", command)).upper())
        with self._write() as c:
            row = c.execute("SELECT status FROM runs WHERE id = ?", (run_id,)).fetchone()
            if row is None:
                raise UnknownRun(f"no run {run_id!r} in {self.path}")
            if row[0] != RunStatus.RUNNING.value:
                raise ArchiveError(f"run {run_id} is {row[0]}, not running")
            cur = c.execute("INSERT INTO control(run_id, command, issued) VALUES (?, ?, ?)",
                            (run_id, command.value, time.time()))
            assert cur.lastrowid is not None   # the row just inserted
            return cur.lastrowid

    @_updates
    def take_control(self, run_id: str) -> ControlRequest | None:
        """For the Top Level: the strongest pending request (STOP over INTERRUPT), or None.

        Every pending request of the run is marked taken.
        """
        with self._write() as c:
            rows = c.execute("SELECT id, run_id, command, issued, taken FROM control "
                             "WHERE run_id = ? AND taken IS NULL ORDER BY id", (run_id,)).fetchall()
            if not rows:
                return None
            now = time.time()
            c.execute("UPDATE control SET taken = ? WHERE run_id = ? AND taken IS NULL", (now, run_id))
        reqs = [ControlRequest(r[0], r[1], ControlCommand(r[2]), r[3], now) for r in rows]
        stops = [r for r in reqs if r.command is ControlCommand.STOP]
        return (stops or reqs)[0]

    @_reads
    def pending_control(self, run_id: str) -> list[ControlRequest]:
        """Requests not yet taken, oldest first."""
        rows = self._conn.execute("SELECT id, run_id, command, issued, taken FROM control "
                                  "WHERE run_id = ? AND taken IS NULL ORDER BY id", (run_id,)).fetchall()
        return [ControlRequest(r[0], r[1], ControlCommand(r[2]), r[3], r[4]) for r in rows]


def _stored_object(text: str | bytes) -> dict[str, Any]:
    """A JSON object the archive stored (settings, totals, a payload); ValueError when the
    text is not one (the reader that called it reports the archive damaged)."""
    value = json.loads(text)
    if not isinstance(value, dict):
        raise ValueError(f"a JSON object was stored, not {type(value).__name__}")
    return value


def _may_write(path: Path) -> bool:
    """Whether this process may write the archive file, and its directory (for -wal and -shm)."""
    return os.access(path, os.W_OK) and os.access(path.parent, os.W_OK | os.X_OK)


def _file_kind(mode: int) -> str:
    """What a path that is not a regular file is, in words."""
    for test, word in ((stat.S_ISDIR, "a directory"), (stat.S_ISFIFO, "a FIFO"), (stat.S_ISSOCK, "a socket"),
                       (stat.S_ISCHR, "a character device"), (stat.S_ISBLK, "a block device")):
        if test(mode):
            return word
    return "not a regular file"


def _connect(path: Path, read_only: bool, busy_timeout: float) -> sqlite3.Connection:
    """A connection in autocommit mode; read_only: SQLite's mode=ro, and immutable=1 when
    even that cannot open (a WAL archive in a read-only directory has no -shm to share)."""
    if not read_only:
        return sqlite3.connect(str(path), timeout=busy_timeout, isolation_level=None)
    uri = "file:" + urllib.parse.quote(str(path))  # relative stays relative
    conn = sqlite3.connect(f"{uri}?mode=ro", uri=True, timeout=busy_timeout, isolation_level=None)
    try:
        conn.execute("SELECT COUNT(*) FROM sqlite_master").fetchone()
        return conn
    except sqlite3.OperationalError as exc:
        conn.close()
        if (getattr(exc, "sqlite_errorcode", 0) or 0) & 0xFF not in (sqlite3.SQLITE_CANTOPEN,
                                                                    sqlite3.SQLITE_READONLY):
            raise
    return sqlite3.connect(f"{uri}?immutable=1", uri=True, timeout=busy_timeout, isolation_level=None)


def _check_readable_schema(conn: sqlite3.Connection, path: Path) -> None:
    """For a read-only archive: its schema must be this ITA's (it cannot be migrated)."""
    version = schema_version(conn)
    if version == 0:
        raise NoArchive(f"no archive at {path} (the database is empty: no run has been recorded there)")
    if version > SCHEMA_VERSION:
        raise SchemaError(f"{path}: schema version {version} was written by a newer ITA; "
                          f"this one knows versions up to {SCHEMA_VERSION}")
    if version < SCHEMA_VERSION:
        raise ArchiveReadOnly(f"{path}: schema version {version} needs bringing up to version "
                              f"{SCHEMA_VERSION}, and the archive is read-only here")


def _stored_result(r: Sequence[Any]) -> StoredResult:
    (run_id, spec_id, seq, outcome, value, u, k, _u_exp, nominal, lower, upper, decision, tool, reason,
     t0, t1, wall, kind, x, y, z) = r
    point = None if x is None else (x, y, z)
    return StoredResult(spec_id, Outcome(outcome), nominal, lower, upper, value, u, k,
                        None if decision is None else Decision(decision), tool, reason, t0, t1, kind, point,
                        run_id=run_id, seq=seq, wall_time=wall)
