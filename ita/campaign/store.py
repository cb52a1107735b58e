"""The campaign archive: one SQLite file holding every run of a campaign.

    store = CampaignStore.open(out_dir / "campaign.sqlite")
    store.check_tasks(tasks)          # a campaign file changed under finished runs is refused
    store.done()                      # keys of the runs that finished
    store.record(record)              # one run, its results, diagnoses and faults: one transaction

A run is recorded once, whole, when it ends (a campaign killed meanwhile loses only the
runs it was in the middle of; started again it runs only what is missing).
"""

from __future__ import annotations

import json
import sqlite3
from collections.abc import Iterable
from pathlib import Path
from typing import Any

from ita.errors import InputError, Location

__all__ = ["CAMPAIGN_FILE", "CampaignStore"]

CAMPAIGN_FILE = "campaign.sqlite"

_SCHEMA = """
CREATE TABLE IF NOT EXISTS runs (
    key        TEXT PRIMARY KEY,
    part_seed  INTEGER NOT NULL,
    appraiser  INTEGER NOT NULL,
    trial      INTEGER NOT NULL,
    sim_seed   INTEGER NOT NULL,
    settings   TEXT NOT NULL,
    status     TEXT,
    summary    TEXT,
    score      TEXT,
    wall_s     REAL,
    host       TEXT,
    finished   REAL
);
CREATE TABLE IF NOT EXISTS results (
    key      TEXT NOT NULL REFERENCES runs(key),
    spec_id  TEXT NOT NULL,
    kind     TEXT,
    outcome  TEXT NOT NULL,
    value    REAL,
    u        REAL,
    big_u    REAL,
    low      REAL,
    high     REAL,
    decision TEXT,
    tool     TEXT,
    reason   TEXT,
    PRIMARY KEY (key, spec_id)
);
CREATE TABLE IF NOT EXISTS diagnoses (
    key     TEXT NOT NULL REFERENCES runs(key),
    n       INTEGER NOT NULL,
    payload TEXT NOT NULL,
    PRIMARY KEY (key, n)
);
CREATE TABLE IF NOT EXISTS faults (
    key     TEXT NOT NULL REFERENCES runs(key),
    n       INTEGER NOT NULL,
    payload TEXT NOT NULL,
    PRIMARY KEY (key, n)
);
"""


class CampaignStore:
    """The campaign archive in one SQLite file (see the module doc)."""

    def __init__(self, conn: sqlite3.Connection, path: Path) -> None:
        self.conn = conn
        self.path = path

    @classmethod
    def open(cls, path: Path, *, create: bool = True) -> CampaignStore:
        path = Path(path)
        if not create and not path.is_file():
            raise InputError([(Location(str(path)), "no campaign archive here (run `ita campaign FILE.toml` first)")])
        path.parent.mkdir(parents=True, exist_ok=True)
        conn = sqlite3.connect(path, timeout=30.0)
        conn.execute("PRAGMA journal_mode=WAL")
        conn.execute("PRAGMA synchronous=FULL")
        conn.executescript(_SCHEMA)
        return cls(conn, path)

    def close(self) -> None:
        self.conn.close()

    def __enter__(self) -> CampaignStore:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def check_tasks(self, tasks: Iterable[Any]) -> None:
        """Refuse a campaign whose file changed what a finished run of the same key was
        (another limit, fault rate, parameters ...): its results would mix two studies."""
        known = dict(self.conn.execute("SELECT key, settings FROM runs WHERE status IS NOT NULL"))
        changed = [t.key for t in tasks if t.key in known and known[t.key] != t.settings()]
        if changed:
            raise InputError([(Location(str(self.path)), f"{len(changed)} finished runs ({', '.join(changed[:3])}"
                               f"{' ...' if len(changed) > 3 else ''}) were made with other settings than the "
                               "campaign file says now; give the changed campaign another --out directory")])

    def done(self) -> set[str]:
        return {k for (k,) in self.conn.execute("SELECT key FROM runs WHERE status IN ('completed', 'stopped')")}

    def record(self, task: Any, record: dict[str, Any]) -> None:
        """Write run `task`'s record (ita.campaign.runner.run_task) in one transaction."""
        import time

        with self.conn:
            c = self.conn
            key = task.key
            for table in ("results", "diagnoses", "faults"):
                c.execute(f"DELETE FROM {table} WHERE key = ?", (key,))
            c.execute("INSERT OR REPLACE INTO runs VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?)", (
                key, task.part_seed, task.appraiser, task.trial, task.sim_seed, task.settings(), record["status"],
                json.dumps(record.get("summary", {})), json.dumps(record.get("diagnosis_score")),
                record.get("wall_s"), record.get("host"), time.time()))
            c.executemany("INSERT INTO results VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?)", [
                (key, r["spec_id"], r["kind"], r["outcome"], r["value"], r["u"], r["U"], r["low"], r["high"],
                 r["decision"], r["tool"], r["reason"]) for r in record["results"]])
            c.executemany("INSERT INTO diagnoses VALUES (?, ?, ?)",
                          [(key, i, json.dumps(d)) for i, d in enumerate(record.get("diagnoses", []))])
            c.executemany("INSERT INTO faults VALUES (?, ?, ?)",
                          [(key, i, json.dumps(f)) for i, f in enumerate(record.get("injected", []))])

    def record_failure(self, task: Any, message: str) -> None:
        """A run that failed: kept as failed (a restarted campaign runs it again)."""
        with self.conn:
            self.conn.execute("INSERT OR REPLACE INTO runs(key, part_seed, appraiser, trial, sim_seed, settings, "
                              "status, summary) VALUES (?, ?, ?, ?, ?, ?, 'failed', ?)",
                              (task.key, task.part_seed, task.appraiser, task.trial, task.sim_seed, task.settings(),
                               json.dumps({"error": message[-2000:]})))

    # -- reading -------------------------------------------------------------------------
    def runs(self) -> list[dict[str, Any]]:
        cur = self.conn.execute("SELECT key, part_seed, appraiser, trial, sim_seed, status, summary, score, wall_s, "
                                "host FROM runs ORDER BY part_seed, appraiser, trial")
        cols = [d[0] for d in cur.description]
        out = []
        for row in cur:
            r = dict(zip(cols, row))
            r["summary"] = json.loads(r["summary"]) if r["summary"] else {}
            r["score"] = json.loads(r["score"]) if r["score"] else None
            out.append(r)
        return out

    def results(self) -> list[dict[str, Any]]:
        cur = self.conn.execute("SELECT r.key, part_seed, appraiser, trial, spec_id, kind, outcome, value, u, big_u, "
                                "low, high, decision, tool, reason FROM results r JOIN runs USING (key) "
                                "ORDER BY r.key, spec_id")
        cols = [d[0] for d in cur.description]
        return [dict(zip(cols, row)) for row in cur]

    def diagnoses(self) -> list[dict[str, Any]]:
        return [{"key": k, **json.loads(p)} for k, p in self.conn.execute(
            "SELECT key, payload FROM diagnoses ORDER BY key, n")]
