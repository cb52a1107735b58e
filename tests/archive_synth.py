"""A synthetic run for the archive's tests: what the Top Level and the Executive record.

Not a fixture file: tests/test_report.py and tests/test_cli_archive.py import it; the
process tests import :func:`wait_for_run`.
"""

from __future__ import annotations

import random
from dataclasses import dataclass
from pathlib import Path

from ita.archive import Archive, Event, Outcome, Result, RunStatus


@dataclass(frozen=True)
class FakeSpec:
    """Enough of a MeasurementSpec for the archive and the report."""

    id: str
    kind: str
    point: tuple[float, float, float]
    nominal: float
    lower: float
    upper: float


def fake_specs(n: int) -> list[FakeSpec]:
    """n specs on a 20-wide grid, thickness 2.5 +-0.127 and hole diameters 6.35 +-0.05."""
    out = []
    for i in range(n):
        x, y = 50.0 * (i % 20), 40.0 * (i // 20)
        if i % 3:
            out.append(FakeSpec(f"s{i:04d}", "web_thickness", (x, y, 0.0), 2.5, -0.127, 0.127))
        else:
            out.append(FakeSpec(f"s{i:04d}", "hole_diameter", (x, y, 0.0), 6.35, -0.05, 0.05))
    return out


def true_values(specs: list[FakeSpec], seed: int = 1) -> dict[str, float]:
    """Deterministic 'true' values: most in tolerance, every 17th well out."""
    rng = random.Random(seed)
    values = {}
    for i, s in enumerate(specs):
        half = (s.upper - s.lower) / 2
        values[s.id] = s.nominal + (1.6 * half if i % 17 == 5 else rng.gauss(0, 0.3 * half))
    return values


def record_synthetic_run(archive: Archive, specs: list[FakeSpec], truth: dict[str, float],
                         *, seed: int = 3, part_dir: Path | None = None, status: RunStatus = RunStatus.COMPLETED,
                         upto: int | None = None, settings: dict | None = None) -> str:
    """Record a run of `specs` (the first `upto` of them) the way the run loop will:
    per spec a plan (gauge specs first, then SLRA), arm motion, gauge measurement with WAIT/CONTINUE, tool changes
    between kinds, an exception on every 40th spec (not done)."""
    rng = random.Random(seed)
    specs = sorted(specs, key=lambda s: s.kind != "web_thickness")  # grouped by tool, as sequenced
    run_id = archive.create_run("synthetic", part_dir, seed=seed, total=len(specs),
                                settings={"simulated": True, "sequencer": "test", **(settings or {})})
    t, cmd, tool = 0.0, 0, None
    for i, s in enumerate(specs[:upto]):
        need = "us_tool" if s.kind == "web_thickness" else "slra_tool"
        sensor = "gauge" if need == "us_tool" else "slra"
        t_start = t
        archive.record_event(run_id, Event("plan_start", "top", t, {"spec": s.id}))
        events = []
        if tool != need:
            events.append(Event("tool_change", "arm", t, {"from": tool, "to": need, "duration": 30.0}))
            t += 30.0
            tool = need
        cmd += 1
        move = rng.uniform(2.0, 5.0)
        events.append(Event("command", "arm", t, {"cmd": cmd, "name": "move_to", "category": "motion"}))
        events.append(Event("wait", sensor, t, {"on": f"arm:{cmd}"}))
        t += move
        events.append(Event("reply", "arm", t, {"cmd": cmd, "status": "ok"}))
        events.append(Event("continue", sensor, t, {}))
        if i % 40 == 39:
            events.append(Event("exception", sensor, t, {"message": "no back-wall echo",
                                                         "diagnosis": "no_couplant", "recovery": "gave up"}))
            events.append(Event("plan_end", "top", t, {"spec": s.id, "status": "failed"}))
            archive.record_result(run_id, Result.unmeasured(s, Outcome.NOT_DONE, "no back-wall echo",
                                                            tool=need, sim_time_start=t_start, sim_time_end=t),
                                  events)
            continue
        cmd += 1
        dwell = 2.0 if sensor == "gauge" else 6.0
        events.append(Event("wait", "arm", t, {"on": f"{sensor}:{cmd}"}))
        events.append(Event("command", sensor, t, {"cmd": cmd, "name": "measure", "category": "measuring"}))
        t += dwell
        events.append(Event("reply", sensor, t, {"cmd": cmd, "status": "ok"}))
        events.append(Event("continue", "arm", t, {}))
        events.append(Event("plan_end", "top", t, {"spec": s.id, "status": "ok"}))
        u = 0.004 if sensor == "gauge" else 0.012
        value = truth[s.id] + rng.gauss(0, u)
        archive.record_result(run_id, Result.measured(s, value, u, tool=need, sim_time_start=t_start,
                                                      sim_time_end=t), events)
    archive.set_status(run_id, status)
    return run_id


def record_two_arm_run(archive: Archive, group: str = "r20261130-100000-abcd", part_dir: Path | None = None
                       ) -> dict[str, str]:
    """A two-arm run as `ita inspect --arms 2` records it: each arm's run with its arm and
    the group in its settings, a move kept per result; the first arm's two results made,
    the second arm's one of two.  Arm -> run id."""
    specs = fake_specs(4)
    runs = {}
    for k, arm in enumerate(("t3", "t3_b")):
        rid = archive.create_run("bulkhead", part_dir, settings={"arm": arm, "two_arms": {"group": group, "away_tools": {}}},
                                 total=2, run_id=f"{group}-{arm}")
        for j in range(2 - k):
            spec = specs[2 * k + j]
            path = [[1.0 + 0.01 * i + k, 0.1 * i, 1.5] for i in range(10)]
            archive.record_result(rid, Result.measured(spec, spec.nominal, 0.002, tool=f"slra_{k + 1}"),
                                  details={"arm_paths": [{"tcp": path, "tool": f"slra_{k + 1}", "name": "move",
                                                          "cmd": "1.1"}]})
        archive.record_event(rid, Event("plan_start", "top", 10.0, {"spec": specs[2 * k + 1].id}))
        runs[arm] = rid
    return runs


def wait_for_run(proc, runs: Path, ready, timeout: float = 240.0) -> str | None:
    """The id of the run process `proc` keeps in the archive of `runs`, once
    `ready(archive, run_id)` holds; None if `proc` ends first or `timeout` (s) passes."""
    import time

    from ita.archive import archive_path

    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline and proc.poll() is None:
        time.sleep(0.05)
        if not archive_path(runs).exists():
            continue
        with Archive.open(archive_path(runs)) as archive:
            mine = [r for r in archive.runs() if r.pid == proc.pid]
            if mine and ready(archive, mine[0].id):
                return mine[0].id
    return None
