"""What a monitor shows of a run now, read from the archive: progress, the current
measurement, the last results, exceptions, times.  `ita monitor` prints it; `ita serve`
streams it to the browser.

    state = live_state(archive, run_id)        # a JSON-ready dict
"""

from __future__ import annotations

import time
from typing import Any

from ita.archive.exceptions import EVENT_KINDS as EXCEPTION_EVENTS
from ita.archive.exceptions import ExceptionCounts
from ita.archive.store import Archive
from ita.report.data import arm_runs, event_row, result_row

LAST_RESULTS = 8


def live_state(archive: Archive, run_id: str, *, last: int = LAST_RESULTS) -> dict[str, Any]:
    """The run's state now.  Keys: run, state (running, interrupted, stopped, completed,
    failed, dead), running (its process lives), done, total, counts, current (group,
    tool, spec of the latest plan), next (the next measurement of the run's order
    without a result), last (rows of the last results), exceptions (the last ten),
    exception_count and exception_counts (ita.archive.exceptions: the one count every view shows), sim_s, wall_s (since the run or its latest resumption started),
    eta_wall_s and eta_sim_s (left, from the pace so far), arms (a run of a two-arm run:
    each arm's run and hand-over run, its state, done, total, current measurement and
    simulated time; [] for one arm), key (changes whenever anything shown does)."""
    info = archive.run(run_id)
    plans = archive.events(run_id, kinds=["plan_start"], last=1)
    current: dict[str, Any] = {}
    if plans:
        p = plans[0].payload
        current = {"spec": p.get("spec") or plans[0].spec_id, "group": p.get("group"), "tool": p.get("tool")}
    rows = [result_row(r) for r in archive.results(run_id, last=last)]
    exceptions = archive.events(run_id, kinds=["exception"])
    exception_counts = ExceptionCounts.from_events(archive.events(run_id, kinds=EXCEPTION_EVENTS))
    starts = archive.events(run_id, kinds=["run_start", "resume"], last=1)
    t_start = starts[0].wall_time if starts else None
    t_start_sim = starts[0].sim_time if starts else None
    done, total = info.done, info.total
    running = info.status.value == "running" and info.alive is not False
    now = time.time()
    ended = None if running else (rows[-1]["wall_time"] if rows else None)
    wall_s = None if t_start is None else max(0.0, (ended or now) - t_start)
    made = archive_count_since(archive, run_id, t_start)
    left = None if total is None else max(total - done, 0)
    eta_wall = wall_s / made * left if wall_s is not None and made and left is not None else None
    sim_span = None if t_start_sim is None or info.sim_time is None else info.sim_time - t_start_sim
    eta_sim = sim_span / made * left if sim_span is not None and made and left is not None else None
    todo = info.settings.get("specs") or []
    have = archive.done_spec_ids(run_id) if todo else set()
    nxt = next((s for s in todo if s not in have and s != current.get("spec")), None) if running else None
    last_seq = archive.events(run_id, last=1)
    arms = [_arm_row(archive, arm, rid) for arm, rid in arm_runs(archive, run_id)]
    key = f"{info.status.value}:{running}:{done}:{last_seq[0].seq if last_seq else 0}:" + \
        ",".join(f"{a['run']}={a['state']}/{a['done']}/{a['current']}" for a in arms)
    return {"run": run_id, "part": info.part, "state": info.state_label, "running": running, "done": done,
            "total": total, "counts": archive.decision_counts(run_id), "current": current, "next": nxt,
            "last": rows, "exceptions": [event_row(e) for e in exceptions[-10:]],
            "exception_count": exception_counts.total,
            "exception_counts": exception_counts.to_dict(), "sim_s": info.sim_time, "wall_s": wall_s,
            "eta_wall_s": eta_wall if running else None, "eta_sim_s": eta_sim if running else None,
            "arms": arms, "key": key}


def _arm_row(archive: Archive, arm: str, run_id: str) -> dict[str, Any]:
    """One arm's run of a two-arm run, now: its state, progress, the measurement it is at."""
    info = archive.run(run_id)
    plans = archive.events(run_id, kinds=["plan_start"], last=1)
    current = (plans[0].payload.get("spec") or plans[0].spec_id) if plans else None
    return {"arm": arm, "run": run_id, "state": info.state_label, "done": info.done, "total": info.total,
            "current": current if info.status.value == "running" else None, "sim_s": info.sim_time,
            "handover": run_id.endswith("-h")}


def archive_count_since(archive: Archive, run_id: str, wall: float | None) -> int:
    """Results recorded since wall-clock time `wall` (all when None)."""
    rows = archive.results(run_id)
    return len(rows) if wall is None else sum(1 for r in rows if r.wall_time >= wall)
