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

Readers (`ita runs`, `ita results`, the System Monitor) may read while a run writes: WAL
lets readers and one writer proceed together; writers wait up to `busy_timeout` seconds.
"""

from __future__ import annotations

import json
import os
import secrets
import socket
import sqlite3
import time
from collections.abc import Iterable, Iterator, Mapping, Sequence
from contextlib import contextmanager
from datetime import UTC, datetime
from pathlib import Path
from typing import Any, Self

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
from ita.archive.schema import ensure_schema
from ita.errors import ItaError
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
             busy_timeout: float = 10.0) -> Archive:
        """Open (by default creating) the archive at `path` (default: `archive_path()`).

        durable: synchronous=FULL (survive power loss too) instead of NORMAL (survive a
        killed process).  create=False raises NoArchive when there is no database yet.
        Raises SchemaError for a database of a newer ITA, or one that is not an archive.
        """
        path = Path(path) if path is not None else archive_path()
        if not path.exists():
            if not create:
                raise NoArchive(f"no archive at {path} (no run has been recorded there)")
            path.parent.mkdir(parents=True, exist_ok=True)
        try:
            conn = sqlite3.connect(str(path), timeout=busy_timeout, isolation_level=None)
            conn.execute(f"PRAGMA busy_timeout = {int(busy_timeout * 1000)}")
            conn.execute("PRAGMA journal_mode = WAL")
            conn.execute(f"PRAGMA synchronous = {'FULL' if durable else 'NORMAL'}")
            conn.execute("PRAGMA foreign_keys = ON")
        except sqlite3.DatabaseError as exc:
            raise ArchiveError(f"{path}: cannot open as an SQLite archive: {exc}") from None
        try:
            ensure_schema(conn, str(path))
        except BaseException:
            conn.close()
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
        except BaseException:
            self._conn.execute("ROLLBACK")
            raise
        self._conn.execute("COMMIT")

    def integrity_check(self) -> str:
        """SQLite's PRAGMA integrity_check: "ok" when the file is sound."""
        return "\n".join(r[0] for r in self._conn.execute("PRAGMA integrity_check"))

    # -------------------------------------------------------------------- runs
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

    def update_totals(self, run_id: str, **values: Any) -> dict[str, Any]:
        """Merge `values` into the run's totals (a JSON object); returns the new totals."""
        with self._write() as c:
            row = c.execute("SELECT totals FROM runs WHERE id = ?", (run_id,)).fetchone()
            if row is None:
                raise UnknownRun(f"no run {run_id!r}")
            totals = json.loads(row[0])
            totals.update(values)
            c.execute("UPDATE runs SET totals = ? WHERE id = ?", (_json(totals), run_id))
        return json.loads(_json(totals))

    def runs(self) -> list[RunInfo]:
        """Every run, in the order they were created."""
        rows = self._conn.execute(f"SELECT {_RUN_COLUMNS} FROM runs ORDER BY rowid").fetchall()
        return [self._run_info(r) for r in rows]

    def run(self, run_id: str) -> RunInfo:
        """The run `run_id` (exact id); UnknownRun when there is none."""
        row = self._conn.execute(f"SELECT {_RUN_COLUMNS} FROM runs WHERE id = ?", (run_id,)).fetchone()
        if row is None:
            raise UnknownRun(f"no run {run_id!r} in {self.path}")
        return self._run_info(row)

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
                       json.loads(row[8]), json.loads(row[9]), row[10], int(done), self.last_sim_time(rid))

    def last_sim_time(self, run_id: str) -> float | None:
        """The latest simulated time recorded in the run (events and result ends), or None.

        A continued run should carry on its simulated clock from here.
        """
        a = self._conn.execute("SELECT MAX(sim_time) FROM events WHERE run_id = ?", (run_id,)).fetchone()[0]
        b = self._conn.execute("SELECT MAX(sim_time_end) FROM results WHERE run_id = ?", (run_id,)).fetchone()[0]
        known = [t for t in (a, b) if t is not None]
        return max(known) if known else None

    # ----------------------------------------------------------------- results
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

    def details(self, run_id: str, spec_id: str) -> dict[str, Any]:
        """What was kept beside the result of `spec_id` ({} when nothing)."""
        row = self._conn.execute("SELECT payload FROM details WHERE run_id = ? AND spec_id = ?",
                                 (run_id, spec_id)).fetchone()
        return json.loads(row[0]) if row else {}

    def frames(self, run_id: str, spec_id: str) -> list[StoredFrame]:
        """The range frames the plan of `spec_id` took, in order (n)."""
        rows = self._conn.execute("SELECT spec_id, n, meta, range, intensity FROM frames WHERE run_id = ? "
                                  "AND spec_id = ? ORDER BY n", (run_id, spec_id)).fetchall()
        return [decode(*r) for r in rows]

    def frame_count(self, run_id: str) -> int:
        """How many range frames the run keeps."""
        return int(self._conn.execute("SELECT COUNT(*) FROM frames WHERE run_id = ?", (run_id,)).fetchone()[0])

    def done_spec_ids(self, run_id: str) -> set[str]:
        """Ids of the specs that have a result in the run (any outcome): skip them on continue."""
        return {r[0] for r in self._conn.execute("SELECT spec_id FROM results WHERE run_id = ?", (run_id,))}

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

    def result(self, run_id: str, spec_id: str) -> StoredResult | None:
        """The result of `spec_id` in the run, or None."""
        row = self._conn.execute(f"SELECT {_RESULT_COLUMNS} FROM results WHERE run_id = ? AND spec_id = ?",
                                 (run_id, spec_id)).fetchone()
        return None if row is None else _stored_result(row)

    def decision_counts(self, run_id: str) -> dict[str, int]:
        """Results per decision ("conforms", ...) and per unmeasured outcome ("not_done", ...)."""
        rows = self._conn.execute(
            "SELECT COALESCE(decision, outcome), COUNT(*) FROM results WHERE run_id = ? GROUP BY 1", (run_id,))
        return {k: n for k, n in rows}

    # ------------------------------------------------------------------ events
    def record_event(self, run_id: str, event: Event) -> int:
        """Commit one event now; returns its seq."""
        return self.record_events(run_id, [event])[0]

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
        return [Event(kind, stream, sim, json.loads(payload), spec, seq, wall)
                for seq, sim, wall, kind, stream, spec, payload in rows]

    # ----------------------------------------------------------------- control
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
            return int(cur.lastrowid)

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

    def pending_control(self, run_id: str) -> list[ControlRequest]:
        """Requests not yet taken, oldest first."""
        rows = self._conn.execute("SELECT id, run_id, command, issued, taken FROM control "
                                  "WHERE run_id = ? AND taken IS NULL ORDER BY id", (run_id,)).fetchall()
        return [ControlRequest(r[0], r[1], ControlCommand(r[2]), r[3], r[4]) for r in rows]


def _stored_result(r: Sequence[Any]) -> StoredResult:
    (run_id, spec_id, seq, outcome, value, u, k, _u_exp, nominal, lower, upper, decision, tool, reason,
     t0, t1, wall, kind, x, y, z) = r
    point = None if x is None else (x, y, z)
    return StoredResult(spec_id, Outcome(outcome), nominal, lower, upper, value, u, k,
                        None if decision is None else Decision(decision), tool, reason, t0, t1, kind, point,
                        run_id=run_id, seq=seq, wall_time=wall)
