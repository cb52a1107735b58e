"""The Top Level: the sequence-level loop of an inspection run.

    session = open_session(part_dir, seed=1)                 # prepares first if needed
    run_id = start_run(session, archive, limit=12)
    summary = TopLevel(session, archive, run_id, signals).run(on_progress=show)

The loop (seed, "Top Level"): the next measurement from the Sequence Planner
(``next_step``: resources checked, resequencing when a tool is gone); a plan for it from
the Operation Planner with the tool the Sequence Planner chose (MACROP lookup first), from
the world state the previous plan left; its execution by the Plan Executive on the
devices (ita.devices), the Geometric Reasoner resolving the plan's qualitative poses from
the MKB (one round trip: :func:`ita.task.measure.measure_one`); the result to the
archive the moment it exists, with the plan's events, in one transaction.  An exception
reply or a time-out: the measurement is recorded not done with the reason, the world
state is taken from the steps that did complete, the arm is freed if it is stuck, and the
loop goes on.  A measurement the Geometric Reasoner could not place, or that the
Sequence Planner put in its cannot-be-done group, is recorded cannot-be-done.

SLRA view groups: a frame taken for one measurement serves every member of its view
group (the MKB); the members' results are recorded as soon as Vision has them, and the
Sequence Planner's later hand-out of a member already recorded is skipped.  A member the
frame could not measure is not recorded: it is handed out later on its own view (with
the Exception Handler behind it), since a frame made for another is no attempt of its own.

Hole positions by a network (the run's setting ``network``, see
:mod:`ita.toplevel.network`): a fastener hole's position is PENDING once its frame is
measured (its sightings kept in the archive as an event, the plan's events recorded at
once) and decided, with the other positions on its face, when the last of them has been
measured or given up; a run that completes decides every network left.  `ita continue`
reads the pending frames back and does not measure them again.

Heights with their webs' measured thickness (:mod:`ita.toplevel.heights`): a flange or
rib height is referenced to the web face beside it; while a web thickness spec of that
floor is still to be measured in the run, the height is PENDING (an archive event) and
decided when the last of them is done (at the run's end at the latest), with the
measured thickness in place of the web's nominal height.  `ita continue` reads them back.

Between measurements the loop obeys INTERRUPT (leave after the current plan, status
INTERRUPTED) and STOP (raised at once as StopNow, status STOPPED), from Ctrl-C or from
the archive's control table (`ita monitor`).  A run is continued (`ita continue`) by
skipping every spec the archive has a result for: nothing is measured twice, nothing is
lost.
"""

from __future__ import annotations

import time
from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING, Any

import numpy as np

from ita.archive import Decision, Event, Outcome, Result, RunStatus
from ita.archive.timeline import breakdown, intervals, span
from ita.devices.arm import RECOVER_SECONDS
from ita.devices.stations import CAL_STEP_MM
from ita.diagnosis import ExceptionHandler
from ita.logic.terms import Term
from ita.planning.state import WorldState
from ita.sequence.next_step import next_step, the_arm
from ita.task.measure import (
    MeasureOutcome,
    MeasureStatus,
    execute_goals,
    measure_one,
    placement_problem,
)
from ita.toplevel.details import measurement_details
from ita.toplevel.events import archive_events
from ita.toplevel.heights import EVENT_KIND as HEIGHT_EVENT
from ita.toplevel.heights import HEIGHT_KINDS, HeightPending, decide_height, web_specs
from ita.toplevel.network import EVENT_KIND, Pending, decide, network_key
from ita.toplevel.signals import RunSignals, StopNow

if TYPE_CHECKING:
    from ita.archive import Archive
    from ita.sequence.next_step import Step
    from ita.task.session import Session

__all__ = ["Progress", "RunSummary", "TopLevel", "start_run", "why_uncertain"]


def why_uncertain(result: Result, value: Any) -> Result:
    """An uncertain result with why added to its reason: U over the tolerance zone and the
    largest term of the uncertainty budget its device reported (Vision's ``budget``:
    term -> standard uncertainty, mm).  Any other result as it is."""
    if result.decision is not Decision.UNCERTAIN or result.U is None:
        return result
    zone = result.upper - result.lower
    note = f"U/tolerance {result.U / zone:.2f}" if zone > 0 else f"U {result.U:.4f} mm"
    budget = (getattr(getattr(value, "source", None), "diagnostics", None) or {}).get("budget") or {}
    if budget:
        term, size = max(budget.items(), key=lambda kv: kv[1])
        note += f"; largest term: {term} (u {size:.4f} mm)"
    return replace(result, reason=f"{result.reason}; {note}" if result.reason else note)


def start_run(session: Session, archive: Archive, *, limit: int | None = None, run_id: str | None = None,
              settings: dict[str, Any] | None = None) -> str:
    """Register a new run of the session's part in `archive`: the measurements it sets out
    to do are the first `limit` of the sequence plan (all by default), plus those the plan
    cannot do (recorded as such).  run_id: the id to give it (the System Monitor names the
    runs it starts); default a fresh one.  `settings` adds to what the run records (the
    fault injection).  Returns the run id."""
    plan = session.plan
    order = [i for g in plan.groups for i in g.order]
    todo = order[:limit] if limit is not None else order
    if limit is None:
        todo += [i for i, _ in plan.cannot]
    settings = {"simulated": True, "simulated_part": session.simulated, "limit": limit, "part_arg": session.part_arg, "specs": todo,
                "mkb_digest": session.mkb.digest, "sequence_total_s": plan.total_s, **(settings or {})}
    return archive.create_run(session.part.name, session.part.directory, seed=session.seed,
                              settings=settings, total=len(todo), run_id=run_id)


# -- progress and summary -------------------------------------------------------------------

@dataclass(frozen=True)
class Progress:
    """What the live view shows after each measurement."""

    run_id: str
    done: int
    total: int
    group: int | None
    tool: str | None
    spec_id: str | None
    status: str
    sim_s: float
    wall_s: float
    eta_wall_s: float | None
    eta_sim_s: float | None
    exceptions: int
    counts: dict[str, int]


@dataclass
class RunSummary:
    """How a run (or this part of a continued run) ended."""

    run_id: str
    status: str
    done: int
    total: int
    counts: dict[str, int]
    sim_start_s: float
    sim_end_s: float
    wall_s: float
    measured_now: int
    exceptions: int
    frames: int
    breakdown: dict[str, float] = field(default_factory=dict)
    devices: dict[str, float] = field(default_factory=dict)
    continue_hint: str | None = None
    alarm: str = ""             # why the Top Level stopped the run itself (failures in a row)

    @property
    def cycle_s(self) -> float:
        return self.sim_end_s - self.sim_start_s

    def to_dict(self) -> dict[str, Any]:
        return {"run_id": self.run_id, "status": self.status, "done": self.done, "total": self.total,
                "counts": dict(self.counts), "simulated_cycle_s": round(self.sim_end_s, 3),
                "simulated_this_session_s": round(self.cycle_s, 3), "wall_s": round(self.wall_s, 3),
                "wall_s_per_measurement": round(self.wall_s / self.measured_now, 4) if self.measured_now else None,
                "recorded_now": self.measured_now, "exceptions": self.exceptions, "slra_scans": self.frames,
                "breakdown_s": {k: round(v, 2) for k, v in self.breakdown.items()},
                "devices": {k: round(v, 3) for k, v in self.devices.items()},
                "continue": self.continue_hint, "alarm": self.alarm or None}


# -- the loop ---------------------------------------------------------------------------------

#: measurements not done in a row (after the Exception Handler) at which the Top Level stops the
#: run: something systematic is wrong, and going on would only fill the run with "not done"
MAX_FAILURES_IN_A_ROW = 10


class TopLevel:
    """Runs (or continues) one inspection run of `session` recorded in `archive`.

    max_failures_in_a_row: stop the run (status stopped, with an alarm; `ita continue`
    goes on once the cause is put right) after this many measurements in a row end not
    done; 0: never; None: the run's setting "alarm_after" (`ita inspect --alarm-after`),
    else MAX_FAILURES_IN_A_ROW."""

    def __init__(self, session: Session, archive: Any, run_id: str, signals: RunSignals | None = None, *,
                 handle_exceptions: bool = True, max_failures_in_a_row: int | None = None) -> None:
        self.session = session
        if max_failures_in_a_row is None:
            max_failures_in_a_row = archive.run(run_id).settings.get("alarm_after", MAX_FAILURES_IN_A_ROW)
        self.max_failures_in_a_row = int(max_failures_in_a_row)
        self.failures_in_a_row: list[str] = []      # reasons of the last measurements not done, in a row
        self.archive = archive
        self.run_id = run_id
        self.signals = signals or RunSignals(message=None)
        info = archive.run(run_id)
        ids = info.settings.get("specs")
        self.todo: list[str] = list(ids) if ids is not None else list(session.specs)
        self.todo_set = set(self.todo)
        self.done: set[str] = archive.done_spec_ids(run_id)
        self.counts: Counter[str] = Counter(archive.decision_counts(run_id))
        self.exceptions = 0
        self.plan_no = len(self.done)
        self.recorded_now = 0
        self.frames = 0
        self.diagnoses = 0
        self.network = bool(info.settings.get("network", False))
        self.pending: dict[str, Pending] = {}
        self.failed_in_others: dict[str, str] = {}   # view-group members another's frame could not measure
        self.kept: dict[str, tuple[dict | None, tuple]] = {}   # a pending result's details and frames (this process)
        self.networks: dict[str, set[str]] = {}     # network key -> the run's specs it decides
        if self.network:
            features, specs = session.slra.vctx.features, session.specs
            for spec_id in self.todo:
                key = network_key(specs[spec_id], features) if spec_id in specs else None
                if key is not None:
                    self.networks.setdefault(key, set()).add(spec_id)
            for event in archive.events(run_id, kinds=[EVENT_KIND]):
                p = Pending.from_event(event)
                if p.spec_id not in self.done:
                    self.pending[p.spec_id] = p
        self.heights: dict[str, HeightPending] = {}   # heights waiting for their webs' thicknesses
        for event in archive.events(run_id, kinds=[HEIGHT_EVENT]):
            h = HeightPending.from_event(event)
            if h.spec_id not in self.done:
                self.heights[h.spec_id] = h
        self._floors: dict[str, tuple[str, ...]] | None = None
        self.calibrated: set[str] = set()        # probes whose velocity this process set (or tried to)
        self.handler = None
        if handle_exceptions:
            self.handler = ExceptionHandler(session, neighbours=self._neighbours)

    def _neighbours(self, spec_id: str, count: int = 5) -> list[float]:
        """Values measured in this run of the measurements of the same kind nearest to
        `spec_id` (the Exception Handler's compare_neighbours)."""
        import math

        specs = self.session.specs
        me = specs[spec_id]
        found = [(math.dist(specs[r.spec_id].point, me.point), r.value) for r in self.archive.results(self.run_id)
                 if r.value is not None and r.spec_id in specs and r.spec_id != spec_id
                 and specs[r.spec_id].kind is me.kind]
        return [v for _, v in sorted(found)[:count]]

    # -- recording ---------------------------------------------------------------------------
    def _record(self, result: Result, events: list[Event] = (), details: dict | None = None,
                frames: tuple = ()) -> None:
        if self.archive.record_result(self.run_id, result, events=events, details=details, frames=frames):
            self.done.add(result.spec_id)
            label = result.decision.value if result.decision is not None else result.outcome.value
            self.counts[label] += 1
            self.recorded_now += 1
            if result.outcome is Outcome.MEASURED:
                self.failures_in_a_row = []
            elif result.outcome is Outcome.NOT_DONE:
                self.failures_in_a_row.append(f"{result.spec_id}: {result.reason or 'not done'}")

    def _unmeasured(self, spec_id: str, outcome: Outcome, reason: str, *, tool: str | None = None,
                    t0: float | None = None, t1: float | None = None, events: list[Event] = (),
                    details: dict | None = None, frames: tuple = ()) -> None:
        spec = self.session.specs[spec_id]
        self._record(Result.unmeasured(spec, outcome, reason, tool=tool, sim_time_start=t0, sim_time_end=t1),
                     list(events), details, frames)

    # -- the run -----------------------------------------------------------------------------
    def run(self, on_progress: Callable[[Progress], None] | None = None) -> RunSummary:

        s = self.session
        wall0 = time.perf_counter()
        last = self.archive.last_sim_time(self.run_id) or 0.0
        if s.world.clock.now < last:
            s.world.clock.advance(last - s.world.clock.now)
        sim0 = s.world.clock.now
        n_done0 = len(self.done)
        plan = replace(s.plan, handed_out=tuple(i for g in s.plan.groups for i in g.order
                                                  if i in self.done or self._waiting(i)
                                                  or i not in self.todo_set))
        state = WorldState(arm=self._arm_name())
        status = RunStatus.COMPLETED
        alarm = ""
        current: tuple[int | None, str | None, str | None] = (None, None, None)
        try:
            for spec_id, reason in s.plan.cannot:
                if spec_id in self.todo_set and spec_id not in self.done:
                    self._unmeasured(spec_id, Outcome.CANNOT_BE_DONE, reason)
            while True:
                self.signals.poll(self.archive, self.run_id)
                if self.signals.interrupt:
                    status = RunStatus.INTERRUPTED
                    break
                result = next_step(s.ctx, plan)
                plan = result.plan
                if result.resequenced:
                    self.archive.record_event(self.run_id, Event("sequence", "top", s.world.clock.now, {
                        "reason": result.reason, "groups": [{"tool": g.tool, "count": len(g.order)}
                                                            for g in plan.groups]}))
                step = result.step
                if step is None:
                    break
                if step.spec_id in self.done or self._waiting(step.spec_id) or step.spec_id not in self.todo_set:
                    continue
                current = (step.group, step.tool, step.spec_id)
                state = self._measure(step, state)
                self._solve_networks()
                self._settle_heights()
                if on_progress is not None:
                    on_progress(self._progress(current, wall0, sim0, n_done0, "measuring"))
                if self.max_failures_in_a_row and len(self.failures_in_a_row) >= self.max_failures_in_a_row:
                    alarm = (f"{len(self.failures_in_a_row)} measurements in a row not done; the last: "
                             f"{self.failures_in_a_row[-1][:300]}")
                    status = RunStatus.STOPPED
                    break
        except StopNow:
            status = RunStatus.STOPPED
        end_t = max(s.world.clock.now, s.executive.settled())     # the last trailing Vision reply too
        if status is RunStatus.COMPLETED:
            self._solve_networks(final=True)
            self._settle_heights(final=True)
        remaining = [i for i in self.todo if i not in self.done and not self._waiting(i)]
        if status is RunStatus.COMPLETED and remaining:
            for spec_id in remaining:   # the sequence planner no longer hands them out
                if spec_id in self.failed_in_others:
                    self._unmeasured(spec_id, Outcome.NOT_DONE, self.failed_in_others[spec_id])
                else:
                    self._unmeasured(spec_id, Outcome.CANNOT_BE_DONE, "not handed out by the sequence planner")
        kind = {RunStatus.COMPLETED: "run_end", RunStatus.INTERRUPTED: "interrupt",
                RunStatus.STOPPED: "stop"}[status]
        self.archive.set_status(self.run_id, status, event=Event(kind, "top", end_t, {
            "reason": alarm or self.signals.reason or None, "done": len(self.done), "total": len(self.todo)}))
        self.archive.update_totals(self.run_id, specs=len(self.todo), done=len(self.done),
                                   sim_time_s=end_t, counts=dict(self.counts))
        summary = RunSummary(
            self.run_id, status.value, len(self.done), len(self.todo), dict(self.counts), sim0, end_t,
            time.perf_counter() - wall0, self.recorded_now, self.exceptions, self.frames,
            devices={**{f"arm_{k}": v for k, v in s.arm.stats.items()},
                     **{f"slra_{k}": v for k, v in s.slra.stats.items()},
                     "path_planning_wall_s": s.arm.planning_seconds},
            continue_hint=None if status is RunStatus.COMPLETED else f"ita continue {self.run_id}", alarm=alarm)
        summary.breakdown = self.breakdown()
        if on_progress is not None:
            on_progress(self._progress(current, wall0, sim0, n_done0, status.value))
        return summary

    def breakdown(self) -> dict[str, float]:
        """The run's cycle-time breakdown from its recorded events (ita.archive.timeline)."""

        events = self.archive.events(self.run_id)
        start, end = span(events)
        return breakdown(intervals(events, end), start, end)

    def _arm_name(self) -> str:

        return the_arm(self.session.kb)

    def _progress(self, current: tuple, wall0: float, sim0: float, n0: int, status: str) -> Progress:
        s = self.session
        done, total = len(self.done), len(self.todo)
        wall = time.perf_counter() - wall0
        made = done - n0
        left = total - done
        eta_wall = wall / made * left if made else None
        eta_sim = (s.world.clock.now - sim0) / made * left if made else None
        return Progress(self.run_id, done, total, current[0], current[1], current[2], status, s.world.clock.now,
                        wall, eta_wall, eta_sim, self.exceptions, dict(self.counts))

    def _measure(self, step: Step, state: WorldState) -> WorldState:
        """Measure one step (and its view group's other members) and record it; a failure
        goes to the Exception Handler, which diagnoses it, puts the cell right and takes
        the measurement again.  The new state."""
        if step.tool not in self.calibrated and self._is_probe(step.tool) \
                and placement_problem(self.session, step.spec_id, step.tool) is None:
            state = self._calibrate(step.tool, state)
        out = measure_one(self.session, step.spec_id, state, step.tool)
        if out.status is MeasureStatus.CANNOT_BE_DONE:
            self._unmeasured(step.spec_id, Outcome.CANNOT_BE_DONE, out.reason or "", tool=step.tool)
            return out.state
        if out.plan is None:
            self._unmeasured(step.spec_id, Outcome.NOT_DONE, out.reason or "", tool=step.tool, t0=out.t0,
                             t1=out.t1)
            return out.state
        self.plan_no += 1
        events = self._events(out, step.group)
        if any(e.kind == "command" and e.payload.get("name") == "scan" for e in events):
            self.frames += 1
        plan_no = self.plan_no
        failed = out.status is not MeasureStatus.MEASURED and out.report is not None and not out.report.ok
        if failed:
            self.exceptions += 1
            handled = self._handle(out)
            if handled is not None:
                self.diagnoses += 1
                events += self._handled_events(handled)
                others = out.others + handled.outcome.others
                if handled.outcome.report is not None:
                    plan_no = self.plan_no
                out = replace(handled.outcome, others=others)
        extra = measurement_details(self.session, out, plan_no=plan_no, group=step.group)
        mine = extra.details.get(step.spec_id)
        spec = self.session.specs[step.spec_id]
        tool = out.tool or step.tool
        if out.status is MeasureStatus.MEASURED:
            assert out.value is not None
            self.failures_in_a_row = []          # measured, even when its result waits for its network
            if not self._hold(step.spec_id, out.value, tool, out.t0, out.t1, events, mine, extra.frames) and \
                    not self._hold_height(step.spec_id, out.value, tool, out.t0, out.t1, events, mine, extra.frames):
                self._record(why_uncertain(Result.measured(spec, out.value.value, out.value.u, tool=tool,
                                                           sim_time_start=out.t0, sim_time_end=out.t1), out.value),
                             events, mine, extra.frames)
        else:
            self._unmeasured(step.spec_id, Outcome.NOT_DONE, out.reason or "", tool=tool, t0=out.t0,
                             t1=out.t1, events=events, details=mine, frames=extra.frames)
        for other in out.others:   # the rest of the frame's view group
            if other.spec_id in self.done or self._waiting(other.spec_id) or other.spec_id not in self.todo_set:
                continue
            theirs = extra.details.get(other.spec_id)
            if other.ok and (self._hold(other.spec_id, other, tool, out.t0, out.t1, [], theirs)
                             or self._hold_height(other.spec_id, other, tool, out.t0, out.t1, [], theirs,
                                                  why=f"from the frame of {step.spec_id}")):
                continue
            if other.ok:
                self._record(why_uncertain(Result.measured(self.session.specs[other.spec_id], other.value, other.u,
                                                           tool=tool, sim_time_start=out.t0, sim_time_end=out.t1,
                                                           reason=f"from the frame of {step.spec_id}"), other),
                             [], theirs)
            else:     # not recorded: the Sequence Planner hands it out on its own (its own view, the
                # Exception Handler if that fails too); a frame made for another is no attempt of its own
                self.failed_in_others[other.spec_id] = f"{other.reason or 'not done'} (in the frame of {step.spec_id})"
        return out.state

    # -- the gauge's sound velocity on the calibration block ---------------------------------
    def _is_probe(self, tool: str | None) -> bool:
        try:
            return tool is not None and self.session.ctx.workcell.tool(tool).tool_class.ultrasonic
        except KeyError:
            return False

    def _calibrate(self, probe: str, state: WorldState) -> WorldState:
        """Before a probe's first reading in this process: read the calibration block with it
        (plan ``calibrated(Probe)``: pick it up, the block, couplant, one reading), which sets
        the gauge's sound velocity for it (ita.devices.stations).  A calibration that fails
        is logged and the readings keep the data sheet's velocity uncertainty; it is not
        tried again in this process.  The state after."""
        self.calibrated.add(probe)
        t0 = self.session.world.clock.now
        plan, report, state, note = execute_goals(self.session, [Term("calibrated", (probe,))], state,
                                                  name="calibrate")
        events: list[Event] = []
        if report is not None:
            events += self._plan_events(plan, report, None, "calibration", tool=probe)
        ok = report is not None and report.ok
        reading = None
        if ok:
            last = report.outcomes[-1].reply
            reading = float(last.payload.args[0]) if isinstance(last.payload, Term) and last.payload.args else None
        events.append(Event("calibration", "top", self.session.world.clock.now, {
            "probe": probe, "ok": ok, "block_mm": CAL_STEP_MM, "reading_mm": reading, "started": t0,
            "note": note or ("" if ok or report is None else report.failure.reason)}))
        self.archive.record_events(self.run_id, events)
        return state

    # -- hole positions by a network ------------------------------------------------------
    def _hold(self, spec_id: str, value: Any, tool: str | None, t0: float | None, t1: float | None,
              events: list[Event], details: dict | None = None, frames: tuple = ()) -> bool:
        """Keep a measured position pending for its network (its sightings, the plan's
        events, its details and range frames to the archive now, in one transaction: a
        killed run loses none of them); False when the network does not decide it."""
        if not any(spec_id in members for members in self.networks.values()):
            return False
        p = Pending.from_value(spec_id, value, tool, t0, t1)
        if p is None:
            return False
        self.archive.record_pending(self.run_id, spec_id, [*events, p.to_event()], details=details, frames=frames)
        events.clear()
        self.pending[spec_id] = p
        self.kept[spec_id] = (details, tuple(frames))
        return True

    def _waiting(self, spec_id: str) -> bool:
        """Whether the spec's result waits: for its network, or for its webs' thicknesses."""
        return spec_id in self.pending or spec_id in self.heights

    def _hold_height(self, spec_id: str, value: Any, tool: str | None, t0: float | None, t1: float | None,
                     events: list[Event], details: dict | None = None, frames: tuple = (), why: str = "") -> bool:
        """A height referenced to webs whose thickness the run measures (ita.toplevel.heights):
        decided now when those are all done, else kept pending (its events, details and
        frames to the archive now); False when it is no such height."""
        spec = self.session.specs[spec_id]
        if spec.kind not in HEIGHT_KINDS:
            return False
        if self._floors is None:
            self._floors = web_specs([s for s in self.session.ctx.specs if s.id in self.todo_set],
                                     self.session.slra.vctx)
        p = HeightPending.from_value(spec_id, value, tool, t0, t1, self._floors, self.session.slra.vctx)
        if p is None:
            return False
        if why:
            p = replace(p, why=why)
        if any(s not in self.done for s in p.waits_for):
            self.archive.record_pending(self.run_id, spec_id, [*events, p.to_event()], details=details,
                                        frames=frames)
            events.clear()
            self.heights[spec_id] = p
            self.kept[spec_id] = (details, tuple(frames))
            return True
        self._record(why_uncertain(self._height_result(p), None), events, details, frames)
        return True

    def _height_result(self, p: HeightPending) -> Result:
        measured = {}
        for sid in p.waits_for:
            r = self.archive.result(self.run_id, sid)
            if r is not None and r.value is not None and r.u is not None:
                measured[sid] = (float(r.value), float(r.u))
        specs = self.session.specs
        return decide_height(p, specs[p.spec_id], measured, {k: specs[k].point for k in p.waits_for},
                             self.session.slra.vctx.web_tolerance)

    def _settle_heights(self, final: bool = False) -> None:
        """Decide the pending heights whose webs' thicknesses are all done (final: every
        one; a web whose thickness was not measured keeps its nominal)."""
        for spec_id, p in list(self.heights.items()):
            if final or all(s in self.done for s in p.waits_for):
                self.heights.pop(spec_id)
                details, frames = self.kept.pop(spec_id, (None, ()))
                self._record(why_uncertain(self._height_result(p), None), [], details, frames)

    def _solve_networks(self, final: bool = False) -> None:
        """Decide every network whose members are all measured or given up (final: every
        network with a pending member) and record its results."""
        ctx = self.session.slra.vctx
        for key, members in self.networks.items():
            waiting = [self.pending[i] for i in sorted(members) if i in self.pending]
            if not waiting or (not final and any(i not in self.done and i not in self.pending for i in members)):
                continue
            try:
                results, sol = decide(waiting, self.session.specs, ctx.features,
                                      ctx.pose_sigma_m / ctx.placement.scale)
            except (ValueError, RuntimeError, np.linalg.LinAlgError) as exc:   # never lose the frames
                for p in waiting:
                    self.pending.pop(p.spec_id, None)
                    details, frames = self.kept.pop(p.spec_id, (None, ()))
                    self._record(Result.measured(self.session.specs[p.spec_id], p.frame_value, p.frame_u,
                                                 tool=p.tool, sim_time_start=p.t0, sim_time_end=p.t1,
                                                 reason=f"from its own frame: the network was not solved ({exc})"),
                                 [], details, frames)
                continue
            shifts = np.array([f[:2] for f in sol.frames.values()]) if sol.frames else np.zeros((0, 2))
            self.archive.record_event(self.run_id, Event("network", "top", self.session.world.clock.now, {
                "network": key, "frames": len(sol.frames), "holes": len(sol.holes), "left_out": dict(sol.left_out),
                "variance_factor": sol.variance_factor, "redundancy": sol.redundancy,
                "frame_shift_rms_mm": float(np.sqrt(np.mean(shifts ** 2))) if len(shifts) else None}))
            for r in results:
                self.pending.pop(r.spec_id, None)
                details, frames = self.kept.pop(r.spec_id, (None, ()))
                self._record(r, [], details, frames)

    def _handle(self, out: MeasureOutcome) -> Any:
        """The Exception Handler on a failed measurement (fault injection paused meanwhile)."""
        if self.handler is None:
            return None
        injector = getattr(self.session.arm, "injector", None)
        if injector is not None:
            injector.paused = True
        try:
            return self.handler.handle(out)
        finally:
            if injector is not None:
                injector.paused = False

    def _handled_events(self, handled: Any) -> list[Event]:
        """The archive events of a diagnosis: its record (exception, posterior, tests with
        their results and costs, cause, actions, recovery), every plan it ran, the world
        updates."""
        d = handled.diagnosis
        events = [Event("diagnosis", "top", d.t0, {**d.to_dict(), "summary": d.summary})]
        for inner in handled.nested:        # second faults met during the handling, each on its own
            events.append(Event("diagnosis", "top", inner.t0, {**inner.to_dict(), "summary": inner.summary,
                                                               "during": d.exception}))
            events += [Event("world_update", "top", inner.t1, {"update": u, "spec": inner.spec_id})
                       for u in inner.updates]
        for label, plan, report in handled.executed:
            if report is None:
                continue
            events += self._plan_events(plan, report, d.spec_id, label)
        for update in d.updates:
            events.append(Event("world_update", "top", d.t1, {"update": update, "spec": d.spec_id}))
        events.append(Event("recovery", "top", d.t1, {"spec": d.spec_id, "how": d.recovery, "cause": d.cause}))
        return events

    def _plan_events(self, plan: Any, report: Any, spec_id: str | None, purpose: str, **start: Any) -> list[Event]:
        """The archive events of a plan run for something other than a measurement's own
        round trip (a diagnosis' tests and repairs, a calibration): its start with
        `purpose`, the executive's log, its end."""
        self.plan_no += 1
        return [Event("plan_start", "top", report.started_s, {
                    "spec": spec_id, "macrop": plan.macrop_name, "source": plan.source.value,
                    "steps": len(plan.steps), "purpose": purpose, **start}),
                *archive_events(report, self.plan_no),
                Event("plan_end", "top", report.finished_s, {
                    "spec": spec_id, "status": "ok" if report.ok else "failed", "purpose": purpose})]

    def _events(self, out: MeasureOutcome, group: int | None = None) -> list[Event]:
        """The archive events of a measurement's plan: its start, the executive's log, its
        end and a recovery of the arm."""
        assert out.plan is not None and out.report is not None
        plan, report = out.plan, out.report
        events = [Event("plan_start", "top", out.t0, {"spec": out.spec_id, "macrop": plan.macrop_name,
                                                      "source": plan.source.value, "steps": len(plan.steps),
                                                      "group": group, "tool": out.tool})]
        events += archive_events(report, self.plan_no)
        if report.ok:
            events.append(Event("plan_end", "top", out.t1, {"spec": out.spec_id, "status": "ok"}))
            return events
        events.append(Event("plan_end", "top", out.t1, {"spec": out.spec_id, "status": "failed",
                                                        "recovered_arm": out.recovered_arm}))
        if out.recovered_arm:
            events.append(Event("recovery", "arm", out.t1, {"how": "jog back to the last free configuration",
                                                            "duration": RECOVER_SECONDS}))
        return events
