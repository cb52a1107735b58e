"""`ita inspect --arms 2`: both arms of the cell inspect the part at once.

The high-level planner splits the measurements (ita.sequence.allocate, each arm's MKB
and tools) and arranges each arm's tours in the order of the best coordinated schedule
(ita.executive.two_arms.arranged); each arm then works its share, in that order, as a
run of its own, in a process of its own (its Top Level, Plan Executive, Path Planner,
devices and simulator, as a one-arm run),
with the other arm's own tools out of its reach; every motion of either arm is claimed
from this process's zone conductor first (ita.executive.conductor, over a socket pair:
ita.robot.gate), which grants, delays (WAIT, CONTINUE) or folds the arms in simulated
time.  When both shares are worked (or an arm is down), what each arm's run left goes to
the other arm where the allocation says it can do it (:class:`_HandOver`), in a run of
its own.  At the end the simulator plays both arms' motions together (ita.sim.arms, their
URDF bodies in pybullet) and counts the moments they touch.

    inspect_with_two_arms(part_dir=None, limit=None, seed=0, ...)     # prints the summary
"""

from __future__ import annotations

import json
import math
import os
import signal
import socket
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Sequence
from multiprocessing.connection import Connection, wait
from pathlib import Path
from typing import Any

import click
import numpy as np

from ita.archive import Archive, Event, Outcome, RunStatus, archive_path
from ita.archive.store import new_run_id
from ita.executive.conductor import Conductor, Motion, conducted_arms, zone_grid
from ita.logic.bridge import KnowledgeBase
from ita.offline.prepare import prepared_arms, two_arm_allocation
from ita.part.store import load_part
from ita.sequence.store import apply_tool_marks, load_tool_marks
from ita.sim.arms import TwoArms
from ita.workcell import Workcell

__all__ = ["CONTACT_STEP_S", "arm_arm_contacts", "inspect_with_two_arms", "scripts_of", "shares_of"]

#: the contact check plays both arms' motions together at this step (s)
CONTACT_STEP_S = 0.05
NOT_FINISHED = 3


#: faults of what both arms share: a script of one lands in each arm's simulator alike
SHARED_FAULTS = ("part_displaced",)


def scripts_of(scripts: Sequence[str], arms: Sequence[str]) -> dict[str, list[str]]:
    """Each arm's --inject scripts: ``ARM:FAULT...`` is that arm's alone, ``FAULT...``
    each arm's (a fault of the part, which both arms share, is each arm's: each arm's
    simulator holds a copy of the part, knocked alike).  UsageError for an arm the cell
    does not name, or a shared fault given to one arm."""
    out: dict[str, list[str]] = {a: [] for a in arms}
    for s in scripts:
        head, colon, rest = s.partition(":")
        if colon and "@" not in head and not rest.startswith("after="):
            if head not in arms:
                raise click.UsageError(f"--inject {s}: the cell has no arm {head!r} (its arms: {', '.join(arms)})")
            if rest.partition(":")[0].partition("@")[0] in SHARED_FAULTS:
                raise click.UsageError(f"--inject {s}: both arms share the part; name no arm for a fault of it "
                                       f"(--inject {rest})")
            out[head].append(rest)
        else:
            for a in arms:
                out[a].append(s)
    return out


def shares_of(order: Sequence[str], assigned: dict[str, str], arms: Sequence[str]) -> dict[str, list[str]]:
    """Each arm's measurements, in the plan's order: the allocation's; what it gave
    neither arm goes to the first (its run records why it cannot be made)."""
    out: dict[str, list[str]] = {a: [] for a in arms}
    for spec_id in order:
        out[assigned.get(spec_id, arms[0])].append(spec_id)
    return out


def arm_arm_contacts(cell: Workcell, paths: Sequence[Motion], homes: dict[str, Sequence[float]],
                     step_s: float = CONTACT_STEP_S) -> dict[str, Any]:
    """Both arms' motions played together in pybullet (their URDF bodies), every `step_s`
    of the run's simulated time: the moments they touch, how many moments, the least gap."""
    names = [a.name for a in cell.arms()]
    end = max((m.end_s for m in paths), default=0.0)
    times = np.arange(0.0, end + step_s, step_s)
    q = {n: _configurations(times, [m for m in paths if m.arm == n], np.asarray(homes[n], dtype=float)) for n in names}
    with TwoArms(cell) as arms:
        gaps = arms.gaps(q[names[0]], q[names[1]])
    touching = np.flatnonzero(gaps <= 0.0)
    return {"arm_arm_contacts": int(len(touching)), "moments": int(len(times)),
            "least_gap_m": round(float(gaps.min()), 3) if len(gaps) else None,
            "first_contact_s": round(float(times[touching[0]]), 2) if len(touching) else None}


def _configurations(times: np.ndarray, motions: Sequence[Motion], home: np.ndarray) -> np.ndarray:
    """An arm's joints at `times`: at rest between its motions, along them during."""
    out = np.repeat(home[None], len(times), axis=0)
    for m in sorted(motions, key=lambda m: m.start_s):
        during = (times >= m.start_s) & (times <= m.end_s)
        if np.any(during):
            t = times[during] - m.start_s
            out[during] = np.stack([np.interp(t, m.times, m.q[:, j]) for j in range(m.q.shape[1])], axis=-1)
        out[times > m.end_s] = m.q[-1]
    return out


class _Child:
    """One arm's run in its own process, its output relayed."""

    def __init__(self, arm: str, args: list[str], conn: Connection, child_end: socket.socket) -> None:
        self.arm = arm
        self.conn = conn
        self.proc = subprocess.Popen(args, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                                     pass_fds=(child_end.fileno(),))
        child_end.close()
        self.out: list[str] = []
        self.threads = [threading.Thread(target=self._relay, args=(self.proc.stdout, self.out, None), daemon=True),
                        threading.Thread(target=self._relay, args=(self.proc.stderr, None, arm), daemon=True)]
        for t in self.threads:
            t.start()

    @staticmethod
    def _relay(stream: Any, keep: list[str] | None, prefix: str | None) -> None:
        for line in stream:
            if keep is not None:
                keep.append(line)
            else:
                click.echo(f"[{prefix}] {line.rstrip()}", err=True)

    def summary(self) -> dict[str, Any] | None:
        for t in self.threads:
            t.join(timeout=10)
        text = "".join(self.out)
        start = text.find("{")
        if start < 0:
            return None
        try:
            found = json.loads(text[start:])
        except json.JSONDecodeError:
            return None
        return found if isinstance(found, dict) else None


class _HandOver:
    """What an arm left, handed to the other (the high-level planner's re-allocation).

    Each arm's process, its share worked, folds and asks for its hand-over
    (``take("handover:ARM")``).  Once every arm has asked or its process has ended, the
    measurements each arm's run did not measure (not done, or never reached when its run
    stopped: an arm whose controller failed for good is down) go to the other arm when
    it reaches them with a tool of its own and its own run completed (the allocation's
    `reaches`: the other arm then stands still for good, so it is not held to keep clear
    of where that one might fold; its Path Planner keeps clear of where it stands, the
    zones say the rest), with where the other arm stands; posted at the latest
    of the arms' clocks, so an arm that finished early waits in simulated time until
    then.  One round: what a hand-over leaves stays not done."""

    def __init__(self, conductor: Conductor, runs_dir: Path | None, runs: dict[str, str],
                 reaches: dict[str, frozenset[str]]) -> None:
        self.conductor = conductor
        self.runs_dir = runs_dir
        self.runs = runs
        self.reaches = reaches
        self.asked: dict[str, float] = {}
        self.ended: set[str] = set()
        self.posted = False
        self.given: dict[str, list[str]] = {}
        self.left: dict[str, list[str]] = {}

    def saw(self, arm: str, message: tuple[Any, ...]) -> list[tuple[str, Any]]:
        if message[0] == "take" and message[2] == f"handover:{arm}":
            self.asked[arm] = float(message[1])
        return self._due()

    def gone(self, arm: str) -> list[tuple[str, Any]]:
        self.ended.add(arm)
        return self._due()

    def _due(self) -> list[tuple[str, Any]]:
        if self.posted or not self.asked or any(a not in self.asked and a not in self.ended for a in self.runs):
            return []
        self.posted = True
        t = max([*self.asked.values(), *(self.conductor.state[a].last_s for a in self.ended)])
        left, completed = self._left()
        self.left = left
        out: list[tuple[str, Any]] = []
        for arm in self.asked:
            mine = [i for other in self.runs if other != arm for i in left.get(other, [])
                    if i in self.reaches.get(arm, frozenset())] if completed.get(arm) else []
            self.given[arm] = mine
            # and where each other arm stands for good (its Path Planner plans around that
            # body, not the ground it might fold to: it moves no more)
            stands = {o: [float(v) for v in self.conductor.state[o].q] for o in self.runs if o != arm}
            out += self.conductor.receive(arm, ("post", t, f"handover:{arm}",
                                                {"specs": mine, "stands": stands} if mine else None))
        return out

    def _left(self) -> tuple[dict[str, list[str]], dict[str, bool]]:
        """Each arm's run's measurements not measured (in its order), and whether it completed."""
        left: dict[str, list[str]] = {}
        completed: dict[str, bool] = {}
        with Archive.open(archive_path(self.runs_dir), create=False) as archive:
            known = {r.id for r in archive.runs()}
            for arm, run_id in self.runs.items():
                if run_id not in known:
                    continue
                info = archive.run(run_id)
                measured = {r.spec_id for r in archive.results(run_id) if r.outcome is Outcome.MEASURED}
                left[arm] = [str(i) for i in info.settings.get("specs") or [] if i not in measured]
                completed[arm] = info.status is RunStatus.COMPLETED
        return left, completed


def _serve(conductor: Conductor, children: Sequence[_Child], hand_over: _HandOver) -> None:
    """Answer the arms' claims until both processes have ended."""
    live: dict[Any, _Child] = {c.conn: c for c in children}
    while live:
        for ready in wait(list(live), timeout=1.0):
            child = live[ready]
            try:
                message = child.conn.recv()
            except (EOFError, OSError):
                del live[ready]
                replies = hand_over.gone(child.arm)          # (posted before the conductor lets it go)
                replies += conductor.gone(child.arm)
            else:
                t0 = time.process_time()
                replies = conductor.receive(child.arm, message)
                replies += hand_over.saw(child.arm, message)
                conductor.cpu_s += time.process_time() - t0
                if os.environ.get("ITA_CONDUCTOR_TRACE"):
                    state = {n: (None if st.pending is None else round(st.pending.t, 2), st.stuck_on, round(st.floor, 2))
                             for n, st in conductor.state.items()}
                    click.echo(f"  {child.arm} {message[0]} {message[1]:.2f} -> {replies} {state}", err=True)
            for arm, reply in replies:
                target = next(c for c in children if c.arm == arm)
                try:
                    target.conn.send(reply)
                except (BrokenPipeError, OSError):
                    pass


def inspect_with_two_arms(*, part_dir: Path | None, limit: int | None, seed: int, runs_dir: Path | None,
                          as_json: bool, fault_rate: float, fault_kinds: str | None, scripts: Sequence[str],
                          network: bool, placement: str, operator: str | None, alarm_after: int | None) -> None:
    """`ita inspect --arms 2` (module docstring); exits 3 unless both arms' runs completed."""
    wall0 = time.perf_counter()
    kb = KnowledgeBase()
    apply_tool_marks(kb, load_tool_marks())
    part = load_part(part_dir)

    def note(text: str) -> None:
        click.echo(f"{text} ...", err=True)

    ctx, plan, mkbs = prepared_arms(part_dir, kb, part, progress=note)
    cell = ctx.workcell
    arms = [a.name for a in cell.arms()]
    if len(arms) != 2:
        raise click.UsageError(f"--arms 2: the workcell ({cell.source}) names one arm; a second is a [robot_b] "
                               "table in its workcell.toml")
    note("allocating the measurements between the arms")
    allocation, kept = two_arm_allocation(ctx, plan, mkbs)
    if kept:
        note("the stored allocation is current: kept")
    order = [i for g in plan.groups for i in g.order]
    todo = order[:limit] if limit is not None else order + [i for i, _ in plan.cannot]
    shares = shares_of(todo, dict(allocation.assigned), arms)
    tools = {s.arm: {t for t, _o, _c in s.groups} for s in allocation.shares}
    by_arm = {s.arm: s for s in allocation.shares}
    group = new_run_id()
    runs = {a: f"{group}-{a}" for a in arms}
    note(f"two-arm run {group}: " + ", ".join(f"{a} {len(shares[a])} measurements (run {runs[a]})" for a in arms))

    conductor = Conductor(zone_grid(cell), conducted_arms(cell))
    children: list[_Child] = []
    common = ["--seed", str(seed), "--placement", placement, "--json", "--network" if network else "--no-network"]
    if part_dir is not None:
        common += ["--part", str(part_dir)]
    if runs_dir is not None:
        common += ["--runs-dir", str(runs_dir)]
    if fault_rate:
        common += ["--faults", str(fault_rate)]
    if fault_kinds:
        common += ["--fault-kinds", fault_kinds]
    own_scripts = scripts_of(scripts, arms)
    if operator is not None:
        common += ["--operator", operator]
    if alarm_after is not None:
        common += ["--alarm-after", str(alarm_after)]
    # the first arm with work registers the part; the other measures in its registration
    registrar = next((a for a in arms if shares[a]), arms[0])
    old_int = signal.signal(signal.SIGINT, signal.SIG_IGN)     # Ctrl-C reaches the arms' runs: they stop, this serves on
    try:
        for arm in arms:
            if not shares[arm]:
                continue
            ours, theirs = socket.socketpair()
            conn = Connection(os.dup(ours.fileno()))
            ours.close()
            away = {t: o for o in arms if o != arm for t in sorted(tools[o] - tools[arm])}
            mine = set(shares[arm])             # its share's tours, in the arranged order
            tours = [[t, [i for i in o if i in mine], c] for t, o, c in by_arm[arm].groups]
            conn.send({"specs": shares[arm], "away_tools": away, "group": group,
                       "registers": arm == registrar, "tours": [x for x in tours if x[1]]})
            args = [sys.executable, "-m", "ita.cli", "inspect", "--arm", arm, "--run-id", runs[arm],
                    "--conductor-fd", str(theirs.fileno()), *common]
            for s in own_scripts[arm]:
                args += ["--inject", s]
            children.append(_Child(arm, args, conn, theirs))
        hand_over = _HandOver(conductor, runs_dir, {c.arm: runs[c.arm] for c in children},
                              dict(allocation.reaches))
        for arm in arms:                     # an arm with nothing to do folds out of the way, done
            if not shares[arm]:
                conductor.idle(arm)
        _serve(conductor, children, hand_over)
        codes = {c.arm: c.proc.wait() for c in children}
    finally:
        signal.signal(signal.SIGINT, old_int)
        for c in children:
            if c.proc.poll() is None:
                c.proc.kill()
    summaries = {c.arm: c.summary() for c in children}
    note("playing both arms' motions together in the simulator (contacts)")
    contacts = arm_arm_contacts(cell, conductor.paths, {a.name: a.home for a in conducted_arms(cell)})
    zones = conductor.summary()
    final = _final(runs_dir, [runs[c.arm] for c in children],
                   [h["run_id"] for s in summaries.values() if s and (h := s.get("handover"))])
    # an arm's run that did not complete is made good when all it left was handed over and done
    made_good = {a for a in codes if codes[a] != 0 and hand_over.left.get(a) is not None
                 and all(i in final["measured_ids"] for i in hand_over.left[a])}
    codes = {a: 0 if a in made_good else c for a, c in codes.items()}
    report = _report(group, runs, summaries, codes, zones, contacts, allocation.as_dict(), time.perf_counter() - wall0,
                     final, hand_over.given)
    with Archive.open(archive_path(runs_dir)) as archive:
        for arm, run_id in runs.items():
            if arm in codes:
                end_s = float(report["simulated_cycle_s"] or 0.0)
                archive.record_event(run_id, Event("two_arms", "top", end_s,
                                                   {k: v for k, v in report.items() if k != "runs"}))
                # its zone claims as the conductor granted them (the report's two-arm Gantt chart)
                archive.record_event(run_id, Event("zones", "top", end_s, {"events": [
                    [round(e.t, 3), e.kind, e.zones] for e in conductor.events
                    if e.arm == arm and e.kind != "request"]}))
    if as_json:
        click.echo(json.dumps(report, indent=1))
    else:
        click.echo(_text(report))
    if any(code != 0 for code in codes.values()):
        raise SystemExit(NOT_FINISHED)


def _final(runs_dir: Path | None, main: Sequence[str], handed: Sequence[str]) -> dict[str, Any]:
    """The two-arm run's results as they stand: each spec's result in its arm's run, or in
    a hand-over run when that measured it; counts by decision (or outcome)."""
    todo: list[str] = []
    with Archive.open(archive_path(runs_dir), create=False) as archive:
        known = {r.id for r in archive.runs()}
        for run_id in main:
            if run_id in known:
                todo += [str(i) for i in archive.run(run_id).settings.get("specs") or []]
        last = archive.merged_results(main, handed)
    counts: dict[str, int] = {}
    for r in last.values():
        key = r.decision.value if r.decision is not None else r.outcome.value
        counts[key] = counts.get(key, 0) + 1
    missing = len(set(todo) - set(last))
    if missing:
        counts["not_reached"] = missing
    measured = {i for i, r in last.items() if r.outcome is Outcome.MEASURED}
    return {"counts": counts, "measured": len(measured), "total": len(set(todo)), "measured_ids": measured}


def _report(group: str, runs: dict[str, str], summaries: dict[str, dict[str, Any] | None], codes: dict[str, int],
            zones: dict[str, Any], contacts: dict[str, Any], allocation: dict[str, Any], wall_s: float,
            final: dict[str, Any], given: dict[str, list[str]]) -> dict[str, Any]:
    arms_z = zones["arms"]
    per_arm = {}
    for arm, s in summaries.items():
        z = arms_z.get(arm, {})
        cycle = max(float(s.get("simulated_end_s", 0.0)), float(s["simulated_cycle_s"])) if s else math.nan
        own = (s or {}).get("zones", {})           # the arm's own clock: its waits and folds
        # its waits for the other arm: for space (claims, folds) and for the hand-over
        waited = float(own.get("wait_s", 0.0)) + float(own.get("fold_s", 0.0)) \
            + float((s or {}).get("handover_wait_s", 0.0))
        handed = (s or {}).get("handover")
        # its work's end: its share's run's, or its hand-over run's (as a one-arm run's cycle
        # is counted: to its last measurement and check, not the fold out of the way after)
        ended = float((handed or s)["simulated_cycle_s"]) if s else math.nan
        per_arm[arm] = {"run_id": runs[arm], "status": s["status"] if s else f"exit {codes.get(arm)}",
                        "measured": s["measured"] if s else 0, "total": s["total"] if s else 0,
                        "counts": s["counts"] if s else {}, "simulated_cycle_s": round(cycle, 3),
                        "simulated_work_end_s": round(ended, 3),
                        "busy_s": round(cycle - waited, 3), "waiting_s": round(waited, 3),
                        "folds": int(own.get("folds", 0)), "stayed": bool((s or {}).get("stayed")),
                        "claims": z.get("claims", 0), "refused": int(own.get("refused", 0)),
                        "refusals": z.get("refusals", []),
                        "exceptions": s["exceptions"] if s else None, "wall_s": s["wall_s"] if s else None,
                        "handed_over": len(given.get(arm, [])),
                        "handover": None if not handed else
                        {k: handed.get(k) for k in ("run_id", "status", "measured", "total", "counts", "waited_s")}}
    cycles = [v["simulated_cycle_s"] for v in per_arm.values() if not math.isnan(v["simulated_cycle_s"])]
    worked = [v["simulated_work_end_s"] for v in per_arm.values() if not math.isnan(v["simulated_work_end_s"])]
    return {"group": group, "arms": 2, "status": "completed" if all(c == 0 for c in codes.values()) else "not finished",
            "simulated_cycle_s": round(max(cycles), 3) if cycles else None,
            "simulated_work_end_s": round(max(worked), 3) if worked else None,
            "measured": final["measured"], "total": final["total"], "counts": final["counts"],
            "arm_arm_contacts": contacts["arm_arm_contacts"], "contact_check": contacts,
            "per_arm": per_arm, "allocation": {k: allocation[k] for k in ("makespan_s", "bound_s", "one_arm_s")},
            "conductor_cpu_s": zones.get("conductor_cpu_s"), "wall_s": round(wall_s, 1), "runs": runs,
            "handover_runs": {a: v["handover"]["run_id"] for a, v in per_arm.items() if v["handover"]}}


def _text(report: dict[str, Any]) -> str:
    lines = [f"two-arm run {report['group']}: {report['status']}; simulated cycle "
             f"{report['simulated_cycle_s']} s (the last measurement and check at {report['simulated_work_end_s']} s, "
             f"then the arms folded); {report['measured']} of {report['total']} measured; "
             f"arm-arm contacts {report['arm_arm_contacts']} in {report['contact_check']['moments']} moments "
             f"(least gap {report['contact_check']['least_gap_m']} m); wall {report['wall_s']} s"]
    for arm, a in report["per_arm"].items():
        lines.append(f"  {arm:6s} run {a['run_id']}: {a['status']}, {a['measured']}/{a['total']} measured, "
                     f"cycle {a['simulated_cycle_s']} s, waited {a['waiting_s']} s for the other arm "
                     f"({a['folds']} folds, {a['refused']} claims refused)")
        if a["handover"]:
            h = a["handover"]
            lines.append(f"         and run {h['run_id']}: {h['measured']}/{h['total']} the other arm left, "
                         f"handed over (waited {h['waited_s']} s for it): {h['status']}")
    counts = ", ".join(f"{k} {v}" for k, v in sorted(report["counts"].items()))
    lines.append(f"  decisions: {counts}")
    lines.append("  each arm's results: ita results RUN (the runs above)")
    return "\n".join(lines)
