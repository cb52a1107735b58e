"""The results archive: schema, exactly-once results, decisions, control, and SIGKILL."""

from __future__ import annotations

import os
import random
import signal
import sqlite3
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import pytest

from ita.archive import (
    SCHEMA_VERSION,
    Archive,
    ArchiveError,
    ControlCommand,
    Decision,
    Event,
    Outcome,
    Result,
    RunBusy,
    RunStatus,
    SchemaError,
    UnknownRun,
    decide,
)
from ita.archive import store as store_mod

REPO = Path(__file__).resolve().parent.parent


def thickness(spec_id: str, value: float | None = 2.5, u: float = 0.004) -> Result:
    if value is None:
        return Result(spec_id, Outcome.NOT_DONE, 2.5, -0.127, 0.127, reason="no echo")
    return Result(spec_id, Outcome.MEASURED, 2.5, -0.127, 0.127, value=value, u=u)


@pytest.fixture
def archive(tmp_path: Path):
    with Archive.open(tmp_path / "runs" / "archive.sqlite") as a:
        yield a


def dead_pid() -> int:
    p = subprocess.Popen([sys.executable, "-c", "pass"])
    p.wait()
    return p.pid


# ------------------------------------------------------------------------ schema
def test_schema_is_created_versioned_and_kept(tmp_path: Path) -> None:
    path = tmp_path / "a.sqlite"
    with Archive.open(path) as a:
        rid = a.create_run("p", total=3)
    con = sqlite3.connect(path)
    tables = {r[0] for r in con.execute("SELECT name FROM sqlite_master WHERE type='table'")}
    assert {"schema_version", "runs", "results", "events", "control"} <= tables
    assert con.execute("SELECT MAX(version) FROM schema_version").fetchone()[0] == SCHEMA_VERSION
    con.close()
    with Archive.open(path) as a:  # reopening neither migrates again nor loses data
        assert a.run(rid).total == 3
    con = sqlite3.connect(path)
    assert con.execute("SELECT COUNT(*) FROM schema_version").fetchone()[0] == SCHEMA_VERSION
    assert con.execute("PRAGMA journal_mode").fetchone()[0] == "wal"
    con.close()


def test_newer_schema_and_foreign_databases_are_refused(tmp_path: Path) -> None:
    path = tmp_path / "a.sqlite"
    Archive.open(path).close()
    con = sqlite3.connect(path)
    con.execute("INSERT INTO schema_version VALUES (?, 'later')", (SCHEMA_VERSION + 1,))
    con.commit()
    con.close()
    with pytest.raises(SchemaError, match="newer"):
        Archive.open(path)
    other = tmp_path / "other.sqlite"
    con = sqlite3.connect(other)
    con.execute("CREATE TABLE stuff(x)")
    con.commit()
    con.close()
    with pytest.raises(SchemaError, match="not an ITA archive"):
        Archive.open(other)


def test_open_without_create_does_not_create(tmp_path: Path) -> None:
    with pytest.raises(store_mod.NoArchive):
        Archive.open(tmp_path / "none" / "archive.sqlite", create=False)
    assert not (tmp_path / "none").exists()


@pytest.mark.parametrize("durable, level", [(False, 1), (True, 2)])
def test_synchronous_level(tmp_path: Path, durable: bool, level: int) -> None:
    with Archive.open(tmp_path / "a.sqlite", durable=durable) as a:
        assert a._conn.execute("PRAGMA synchronous").fetchone()[0] == level


def test_runs_dir_default_env_and_explicit(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv("ITA_RUNS", raising=False)
    assert store_mod.archive_path().parent == store_mod.ita_home() / "runs"
    monkeypatch.setenv("ITA_RUNS", str(tmp_path / "env"))
    assert store_mod.archive_path() == tmp_path / "env" / "archive.sqlite"
    assert store_mod.archive_path(tmp_path / "x") == tmp_path / "x" / "archive.sqlite"


# ----------------------------------------------------------------------- results
def test_a_spec_is_recorded_once_and_the_first_result_stands(archive: Archive) -> None:
    rid = archive.create_run("p")
    assert archive.record_result(rid, thickness("a", 2.5), [Event("reply", "gauge", 1.0, {"n": 1})])
    # a second result for the same spec: refused as a whole, its events too
    assert not archive.record_result(rid, thickness("a", 2.9), [Event("reply", "gauge", 2.0, {"n": 2})])
    [r] = archive.results(rid)
    assert (r.value, r.decision, r.seq) == (2.5, Decision.CONFORMS, 1)
    assert [e.payload["n"] for e in archive.events(rid, spec_id="a")] == [1]
    assert archive.done_spec_ids(rid) == {"a"}
    # another run may measure the same spec
    other = archive.create_run("p")
    assert archive.record_result(other, thickness("a", 2.6))


def test_a_result_and_its_events_are_written_together_or_not_at_all(archive: Archive,
                                                                     monkeypatch: pytest.MonkeyPatch) -> None:
    rid = archive.create_run("p")
    n_events = len(archive.events(rid))

    def broken(*args, **kwargs):
        raise sqlite3.OperationalError("disk on fire")

    monkeypatch.setattr(archive, "_insert_events", broken)
    with pytest.raises(store_mod.ArchiveError, match="cannot be written \\(disk on fire\\)"):
        archive.record_result(rid, thickness("a"), [Event("reply", "gauge", 1.0)])
    monkeypatch.undo()
    assert archive.results(rid) == [] and len(archive.events(rid)) == n_events
    assert archive.record_result(rid, thickness("a"), [Event("reply", "gauge", 1.0)])


def test_results_round_trip_in_order_with_failed_filter(archive: Archive) -> None:
    rid = archive.create_run("p", total=4)
    archive.record_result(rid, thickness("c", 2.5))                       # conforms
    archive.record_result(rid, thickness("b", 2.9))                       # does not conform
    archive.record_result(rid, thickness("a", 2.5 + 0.127 - 0.004))       # uncertain (U = 0.008)
    archive.record_result(rid, thickness("d", None))                      # not done
    rs = archive.results(rid)
    assert [r.spec_id for r in rs] == ["c", "b", "a", "d"] and [r.seq for r in rs] == [1, 2, 3, 4]
    assert [r.decision for r in rs] == [Decision.CONFORMS, Decision.DOES_NOT_CONFORM, Decision.UNCERTAIN, None]
    assert rs[0].U == pytest.approx(0.008) and rs[3].reason == "no echo"
    assert [r.spec_id for r in archive.results(rid, failed_only=True)] == ["b", "a", "d"]
    assert archive.decision_counts(rid) == {"conforms": 1, "does_not_conform": 1, "uncertain": 1, "not_done": 1}
    info = archive.run(rid)
    assert (info.done, info.total) == (4, 4)


def test_record_into_an_unknown_run_is_an_error(archive: Archive) -> None:
    with pytest.raises(UnknownRun):
        archive.record_result("r-nope", thickness("a"))
    with pytest.raises(UnknownRun):
        archive.record_event("r-nope", Event("command", "arm", 0.0))


def test_events_are_numbered_without_gaps_and_filtered(archive: Archive) -> None:
    rid = archive.create_run("p")  # run_start is event 1
    assert archive.record_event(rid, Event("plan_start", "top", 0.0, {"spec": "a"})) == 2
    assert archive.record_events(rid, [Event("command", "arm", 0.0, {"cmd": 1}),
                                       Event("reply", "arm", 3.0, {"cmd": 1})]) == [3, 4]
    archive.record_result(rid, thickness("a"), [Event("plan_end", "top", 3.0, {"spec": "a"})])
    evs = archive.events(rid)
    assert [e.seq for e in evs] == [1, 2, 3, 4, 5]
    assert [e.kind for e in archive.events(rid, kinds=["reply", "plan_end"])] == ["reply", "plan_end"]
    assert [e.kind for e in archive.events(rid, spec_id="a")] == ["plan_end"]
    assert archive.last_sim_time(rid) == 3.0


# --------------------------------------------------------------------- decisions
@pytest.mark.parametrize("value, expected", [
    (2.25, Decision.CONFORMS),          # low + U: conformance proven, boundary included
    (2.75, Decision.CONFORMS),          # high - U
    (2.5, Decision.CONFORMS),
    (2.2499, Decision.UNCERTAIN),       # just inside the guard band
    (2.0, Decision.UNCERTAIN),          # on the tolerance limit
    (1.75, Decision.UNCERTAIN),         # low - U: nonconformance not proven, boundary excluded
    (1.7499, Decision.DOES_NOT_CONFORM),
    (3.25, Decision.UNCERTAIN),         # high + U
    (3.2501, Decision.DOES_NOT_CONFORM),
])
def test_iso_14253_decision_at_each_boundary(value: float, expected: Decision) -> None:
    assert decide(value, 0.25, 2.0, 3.0) is expected


def test_a_true_position_is_decided_on_its_upper_limit_only() -> None:
    """A position's zone [0, 0.5]: 0 is where the hole should be, not a limit to keep U from."""
    assert decide(0.05, 0.15, 0.0, 0.5) is Decision.UNCERTAIN                     # two-sided: too near 0
    assert decide(0.05, 0.15, 0.0, 0.5, bounded_below=True) is Decision.CONFORMS
    assert decide(0.40, 0.15, 0.0, 0.5, bounded_below=True) is Decision.UNCERTAIN
    assert decide(0.66, 0.15, 0.0, 0.5, bounded_below=True) is Decision.DOES_NOT_CONFORM
    spec = type("Spec", (), {"id": "HP-OF-001", "kind": "hole_position", "point": (0.0, 0.0, 45.0),
                             "nominal": 0.0, "lower": 0.0, "upper": 0.5})()
    assert Result.measured(spec, 0.05, 0.075).decision is Decision.CONFORMS


def test_decision_degenerate_and_bad_inputs() -> None:
    assert decide(2.0, 0.0, 2.0, 3.0) is Decision.CONFORMS          # no uncertainty: limits conform
    assert decide(2.5, 0.5, 2.0, 3.0) is Decision.CONFORMS          # zone shrunk to a point
    assert decide(2.5, 0.6, 2.0, 3.0) is Decision.UNCERTAIN         # U beyond half the band
    assert decide(4.0, 0.6, 2.0, 3.0) is Decision.DOES_NOT_CONFORM
    for args in [(float("nan"), 0.1, 2, 3), (2.5, -0.1, 2, 3), (2.5, 0.1, 3, 2), (2.5, float("inf"), 2, 3)]:
        with pytest.raises(ValueError):
            decide(*args)
    assert Decision.DOES_NOT_CONFORM.label == "does not conform"


def test_result_computes_its_decision_and_checks_its_fields() -> None:
    r = Result("a", Outcome.MEASURED, 2.5, -0.127, 0.127, value=2.62, u=0.004)  # 2.62 > 2.627 - 0.008
    assert r.decision is Decision.UNCERTAIN and r.U == pytest.approx(0.008)
    with pytest.raises(ValueError):
        Result("a", Outcome.MEASURED, 2.5, -0.1, 0.1, value=2.5)               # no uncertainty
    with pytest.raises(ValueError):
        Result("a", Outcome.NOT_DONE, 2.5, -0.1, 0.1, value=2.5, u=0.01)      # value without measuring


# ----------------------------------------------------- runs, resolving, control
def test_resolve_exact_prefix_last_unknown_and_ambiguous(archive: Archive) -> None:
    a = archive.create_run("p", run_id="r20260101-000000-aaaa")
    b = archive.create_run("p", run_id="r20260101-000000-aabb")
    assert archive.resolve(a) == a and archive.resolve("r20260101-000000-aaa") == a
    assert archive.resolve("last") == b
    with pytest.raises(ArchiveError, match="ambiguous"):
        archive.resolve("r20260101-000000-aa")
    with pytest.raises(UnknownRun):
        archive.resolve("x")


def test_new_run_ids_look_like_the_documented_form(archive: Archive) -> None:
    import re

    rid = archive.create_run("p")
    assert re.fullmatch(r"r\d{8}-\d{6}-[0-9a-f]{4}", rid)
    assert archive.run(rid).status is RunStatus.RUNNING and archive.run(rid).pid == os.getpid()


def test_resume_refuses_a_live_run_and_takes_up_a_dead_one(archive: Archive) -> None:
    live = archive.create_run("p")
    with pytest.raises(RunBusy):
        archive.resume_run(live)
    dead = archive.create_run("p", pid=dead_pid())
    archive.record_result(dead, thickness("a"), [Event("reply", "gauge", 7.0)])
    assert archive.run(dead).state_label == "dead"
    archive._conn.execute("INSERT INTO control(run_id, command, issued) VALUES (?, 'STOP', 0)", (dead,))
    info = archive.resume_run(dead)
    assert info.status is RunStatus.RUNNING and info.pid == os.getpid() and info.state_label == "running"
    resume = archive.events(dead, kinds=["resume"])[-1]
    assert resume.sim_time == 7.0 and resume.payload["previous_status"] == "dead"
    assert resume.payload["discarded_control"] == 1 and archive.take_control(dead) is None
    archive.set_status(dead, RunStatus.COMPLETED)
    with pytest.raises(ArchiveError, match="completed"):
        archive.resume_run(dead)


def test_control_commands_reach_the_run_strongest_first(tmp_path: Path) -> None:
    path = tmp_path / "a.sqlite"
    with Archive.open(path) as runner, Archive.open(path) as monitor:
        rid = runner.create_run("p")
        assert runner.take_control(rid) is None
        monitor.issue_control(rid, "interrupt")
        monitor.issue_control(rid, ControlCommand.STOP)
        assert len(monitor.pending_control(rid)) == 2
        req = runner.take_control(rid)
        assert req.command is ControlCommand.STOP and req.taken is not None
        assert runner.take_control(rid) is None and monitor.pending_control(rid) == []
        runner.set_status(rid, RunStatus.STOPPED, event=Event("stop", "top", 12.0))
        with pytest.raises(ArchiveError, match="not running"):
            monitor.issue_control(rid, "STOP")
        assert monitor.run(rid).ended is not None
        assert [e.kind for e in monitor.events(rid, kinds=["stop"])] == ["stop"]


def test_totals_merge(archive: Archive) -> None:
    rid = archive.create_run("p", total=10)
    assert archive.update_totals(rid, cycle_s=12.5) == {"specs": 10, "cycle_s": 12.5}


# ------------------------------------------------------------------ the kill test
CHILD = textwrap.dedent("""
    import sys, time
    from ita.archive import Archive, Event, Outcome, Result, RunStatus

    path, n = sys.argv[1], int(sys.argv[2])
    a = Archive.open(path)
    mine = [r for r in a.runs() if r.part == "kill-test"]
    if mine:
        run_id = mine[0].id
        a.resume_run(run_id)
    else:
        run_id = a.create_run("kill-test", total=n)
    done = a.done_spec_ids(run_id)
    print("ready", len(done), flush=True)
    t = a.last_sim_time(run_id) or 0.0
    for i in range(n):
        sid = f"k{i:04d}"
        if sid in done:
            continue
        a.record_event(run_id, Event("plan_start", "top", t, {"spec": sid}))
        events = [Event("command", "arm", t, {"cmd": 2 * i, "name": "move_to"}),
                  Event("reply", "arm", t + 1, {"cmd": 2 * i, "status": "ok"}),
                  Event("command", "gauge", t + 1, {"cmd": 2 * i + 1, "name": "measure"}),
                  Event("reply", "gauge", t + 2, {"cmd": 2 * i + 1, "status": "ok"}),
                  Event("plan_end", "top", t + 2, {"spec": sid})]
        r = Result(sid, Outcome.MEASURED, 2.5, -0.127, 0.127, value=2.5 + (i % 7) * 0.01, u=0.004,
                   sim_time_start=t, sim_time_end=t + 2)
        if not a.record_result(run_id, r, events):
            print("duplicate", sid, flush=True)
            sys.exit(3)
        t += 2.0
        time.sleep(0.005)  # 300 results take >= 1.5 s: more than the five kills' delays add up to
    a.set_status(run_id, RunStatus.COMPLETED)
    print("done", flush=True)
""")


def test_sigkill_at_random_moments_loses_and_duplicates_no_result(tmp_path: Path) -> None:
    n, kills = 300, 5
    script = tmp_path / "child.py"
    script.write_text(CHILD)
    db = tmp_path / "archive.sqlite"
    env = dict(os.environ, PYTHONPATH=str(REPO) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    rng = random.Random(20261121)

    def start() -> subprocess.Popen:
        p = subprocess.Popen([sys.executable, str(script), str(db), str(n)], stdout=subprocess.PIPE,
                             stderr=subprocess.PIPE, text=True, env=env)
        line = p.stdout.readline()
        assert line.startswith("ready"), (line, p.stderr.read())
        return p

    progress, interrupted = [], 0
    for _ in range(kills):
        p = start()
        time.sleep(rng.uniform(0.02, 0.15))
        os.kill(p.pid, signal.SIGKILL)
        p.wait()
        out = p.stdout.read()
        assert "duplicate" not in out
        interrupted += "done" not in out
        with Archive.open(db) as a:
            progress.append(sum(r.done for r in a.runs()))
    assert interrupted >= 3, "the kills should land in the middle of the run"
    assert progress == sorted(progress), "a kill must not take back committed results"

    p = start()
    out, err = p.communicate(timeout=60)
    assert p.returncode == 0 and "done" in out, err

    with Archive.open(db) as a:
        [run] = a.runs()
        assert run.status is RunStatus.COMPLETED and run.done == n
        results = a.results(run.id)
        assert sorted(r.spec_id for r in results) == [f"k{i:04d}" for i in range(n)]
        assert [r.seq for r in results] == list(range(1, n + 1))
        events = a.events(run.id)
        assert [e.seq for e in events] == list(range(1, len(events) + 1))
        by_spec: dict[str, list[str]] = {}
        for e in events:
            if e.spec_id:
                by_spec.setdefault(e.spec_id, []).append(e.kind)
        for r in results:  # each result has exactly its own events, once
            kinds = by_spec.get(r.spec_id, [])
            assert sorted(kinds) == sorted(["command", "reply", "command", "reply", "plan_end"]), r.spec_id
        assert len(a.events(run.id, kinds=["resume"])) == kills  # every later process took the run up
        starts = {e.payload["spec"] for e in a.events(run.id, kinds=["plan_start"])}
        assert starts == {r.spec_id for r in results}
        assert a.integrity_check() == "ok"
    con = sqlite3.connect(db)
    assert con.execute("SELECT COUNT(*), COUNT(DISTINCT spec_id) FROM results").fetchone() == (n, n)
    con.close()



def test_details_and_frames_are_kept_with_their_result(tmp_path: Path) -> None:
    import numpy as np

    from ita.archive import StoredFrame

    rng = np.random.default_rng(0)
    rng_m = 0.45 + rng.normal(0, 1e-3, (40, 30))
    rng_m[2, 3] = np.nan
    frame = StoredFrame("a", 0, rng_m, rng.random((40, 30)), np.eye(4), (30.0, 24.0), {"group": "g"})
    with Archive.open(tmp_path / "a.sqlite") as a:
        rid = a.create_run("p", total=2)
        assert a.record_result(rid, thickness("a", 2.5), details={"plan": {"steps": [1]}}, frames=[frame])
        # a second result for the same spec changes nothing, its details and frames neither
        assert not a.record_result(rid, thickness("a", 2.6), details={"plan": "other"}, frames=[])
        assert a.details(rid, "a") == {"plan": {"steps": [1]}} and a.details(rid, "b") == {}
        (back,) = a.frames(rid, "a")
        assert back.shape == (40, 30) and back.meta["group"] == "g" and np.isnan(back.range_m[2, 3])
        assert np.nanmax(np.abs(back.range_m - rng_m)) <= 0.6e-4 and a.frame_count(rid) == 1
        assert [r.spec_id for r in a.results(rid, last=1)] == ["a"] and a.result(rid, "a").value == 2.5


def test_a_version_1_archive_is_migrated(tmp_path: Path) -> None:
    from ita.archive.schema import DDL_V1

    path = tmp_path / "old.sqlite"
    con = sqlite3.connect(path, isolation_level=None)
    for statement in DDL_V1.split(";"):
        if statement.strip():
            con.execute(statement)
    con.execute("INSERT INTO schema_version VALUES (1, 'then')")
    con.close()
    with Archive.open(path) as a:
        rid = a.create_run("p", total=1)
        assert a.record_result(rid, thickness("a"), details={"x": 1})
        assert a.details(rid, "a") == {"x": 1}
