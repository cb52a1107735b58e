"""The archive's SQLite schema, its version, and the migrations between versions.

One database holds every run.  Tables:

- schema_version(version, applied): one row per schema version applied.
- runs: one row per run; settings and totals are JSON objects (totals["specs"] is the
  number of specs the run set out to do; the Top Level may add cycle-time figures).
- results: one row per (run, spec), UNIQUE: the result of a spec is written once.  seq
  numbers the results of a run in the order they were recorded (1, 2, ...).  u is the
  standard uncertainty, k the coverage factor, u_expanded = k u (SQLite column names are
  case-insensitive, so "u" and "U" cannot both be columns).
- events: one row per event, numbered per run by seq (1, 2, ... with no gaps); spec_id
  ties an event to a measurement; payload is a JSON object.
- control: STOP / INTERRUPT requests from the System Monitor to the process running a
  run; `taken` is set when the run loop picks one up.
- details (version 2): per (run, spec) a JSON object of what a person needs to examine
  a result: the plan's steps, Vision's patches and fitted features in pixels, the
  gauge's reading, the arm's flown path (see `ita.toplevel.details`).  Written with the
  result, in its transaction.
- frames (version 2): the range frames an SLRA plan took, per (run, spec of the plan,
  n): meta is JSON (shape, window, pose, times), range and intensity are compressed
  images (`ita.archive.frames`).  Written with the plan's result, in its transaction.
"""

from __future__ import annotations

import sqlite3
from contextlib import suppress
from datetime import UTC, datetime

from ita.errors import ItaError

SCHEMA_VERSION = 2

DDL_V1 = """
CREATE TABLE IF NOT EXISTS schema_version (
    version  INTEGER PRIMARY KEY,
    applied  TEXT NOT NULL
);
CREATE TABLE IF NOT EXISTS runs (
    id        TEXT PRIMARY KEY,
    part      TEXT NOT NULL,
    part_dir  TEXT,
    seed      INTEGER,
    created   TEXT NOT NULL,
    status    TEXT NOT NULL CHECK (status IN ('running', 'interrupted', 'stopped', 'completed', 'failed')),
    pid       INTEGER,
    host      TEXT,
    settings  TEXT NOT NULL DEFAULT '{}',
    totals    TEXT NOT NULL DEFAULT '{}',
    ended     TEXT
);
CREATE TABLE IF NOT EXISTS results (
    run_id          TEXT NOT NULL REFERENCES runs(id),
    spec_id         TEXT NOT NULL,
    seq             INTEGER NOT NULL,
    outcome         TEXT NOT NULL CHECK (outcome IN ('measured', 'not_done', 'cannot_be_done')),
    value           REAL,
    u               REAL,
    k               REAL NOT NULL DEFAULT 2.0,
    u_expanded      REAL,
    nominal         REAL NOT NULL,
    lower           REAL NOT NULL,
    upper           REAL NOT NULL,
    decision        TEXT CHECK (decision IS NULL OR decision IN ('conforms', 'does_not_conform', 'uncertain')),
    tool            TEXT,
    reason          TEXT,
    sim_time_start  REAL,
    sim_time_end    REAL,
    wall_time       REAL NOT NULL,
    kind            TEXT,
    x               REAL,
    y               REAL,
    z               REAL,
    UNIQUE (run_id, spec_id),
    UNIQUE (run_id, seq),
    CHECK ((outcome = 'measured') = (value IS NOT NULL AND decision IS NOT NULL))
);
CREATE TABLE IF NOT EXISTS events (
    run_id     TEXT NOT NULL REFERENCES runs(id),
    seq        INTEGER NOT NULL,
    sim_time   REAL,
    wall_time  REAL NOT NULL,
    kind       TEXT NOT NULL,
    stream     TEXT,
    spec_id    TEXT,
    payload    TEXT NOT NULL DEFAULT '{}',
    PRIMARY KEY (run_id, seq)
);
CREATE INDEX IF NOT EXISTS events_by_spec ON events(run_id, spec_id);
CREATE INDEX IF NOT EXISTS events_by_kind ON events(run_id, kind);
CREATE TABLE IF NOT EXISTS control (
    id       INTEGER PRIMARY KEY AUTOINCREMENT,
    run_id   TEXT NOT NULL REFERENCES runs(id),
    command  TEXT NOT NULL CHECK (command IN ('STOP', 'INTERRUPT')),
    issued   REAL NOT NULL,
    taken    REAL
);
CREATE INDEX IF NOT EXISTS control_pending ON control(run_id, taken);
"""

# No semicolon may appear inside a statement (the migration splits on them).
DDL_V2 = """
CREATE TABLE IF NOT EXISTS details (
    run_id   TEXT NOT NULL REFERENCES runs(id),
    spec_id  TEXT NOT NULL,
    payload  TEXT NOT NULL DEFAULT '{}',
    PRIMARY KEY (run_id, spec_id)
);
CREATE TABLE IF NOT EXISTS frames (
    run_id     TEXT NOT NULL REFERENCES runs(id),
    spec_id    TEXT NOT NULL,
    n          INTEGER NOT NULL,
    meta       TEXT NOT NULL,
    range      BLOB NOT NULL,
    intensity  BLOB NOT NULL,
    PRIMARY KEY (run_id, spec_id, n)
);
"""

# version -> DDL that brings a database from version - 1 to version
MIGRATIONS: dict[int, str] = {1: DDL_V1, 2: DDL_V2}


class SchemaError(ItaError):
    """The database is not an ITA archive this ITA can use (too new, or not an archive)."""


def schema_version(conn: sqlite3.Connection) -> int:
    """The schema version of the database behind `conn`; 0 for an empty database."""
    has = conn.execute(
        "SELECT 1 FROM sqlite_master WHERE type = 'table' AND name = 'schema_version'").fetchone()
    if not has:
        tables = conn.execute("SELECT name FROM sqlite_master WHERE type = 'table'").fetchall()
        if tables:
            raise SchemaError(f"not an ITA archive (it has tables {sorted(t[0] for t in tables)} "
                              "but no schema_version)")
        return 0
    row = conn.execute("SELECT MAX(version) FROM schema_version").fetchone()
    return int(row[0] or 0)


def ensure_schema(conn: sqlite3.Connection, path: str = "") -> int:
    """Create or migrate the schema to SCHEMA_VERSION, in one transaction; return the version.

    Raises SchemaError when the database was written by a newer ITA.  `conn` must be in
    autocommit mode (isolation_level=None).
    """
    version = schema_version(conn)
    if version == SCHEMA_VERSION:
        return version
    _refuse_newer(version, path)
    conn.execute("BEGIN IMMEDIATE")
    try:
        version = schema_version(conn)  # another process may have migrated meanwhile
        _refuse_newer(version, path)
        now = datetime.now(UTC).isoformat(timespec="seconds")
        for v in range(version + 1, SCHEMA_VERSION + 1):
            for statement in MIGRATIONS[v].split(";"):
                if statement.strip():
                    conn.execute(statement)
            conn.execute("INSERT INTO schema_version(version, applied) VALUES (?, ?)", (v, now))
        conn.execute("COMMIT")
    except BaseException:
        if conn.in_transaction:  # SQLite may have rolled back itself (a full disk)
            with suppress(sqlite3.Error):
                conn.execute("ROLLBACK")
        raise
    return SCHEMA_VERSION


def _refuse_newer(version: int, path: str) -> None:
    if version > SCHEMA_VERSION:
        raise SchemaError(f"{path or 'archive'}: schema version {version} was written by a newer ITA; "
                          f"this one knows versions up to {SCHEMA_VERSION}")
