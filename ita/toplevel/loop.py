"""The Top Level: the sequence-level loop of an inspection run.

    session = open_session(part_dir, seed=1)                 # prepares first if needed
    run_id = start_run(session, archive, limit=12)
    summary = TopLevel(session, archive, run_id, signals).run(on_progress=show)

The loop (seed, "Top Level"): the next measurement from the Sequence Planner
(``next_step``: resources checked, resequencing when a tool is gone); a plan for it from
the Operation Planner (MACROP lookup first), from the world state the previous plan left;
its execution by the Plan Executive on the device adapters (ita.toplevel.adapters), the
Geometric Reasoner resolving the plan's qualitative poses from the MKB; the result to the
archive the moment it exists, with the plan's events, in one transaction.  An exception
reply or a time-out: the measurement is recorded not done with the reason, the world
state is taken from the steps that did complete, the arm is freed if it is stuck, and the
loop goes on.  A measurement the Geometric Reasoner could not place, or that the
Sequence Planner put in its cannot-be-done group, is recorded cannot-be-done.

SLRA view groups: a frame taken for one measurement serves every member of its view
group (the MKB); the members' results are recorded as soon as Vision has them, and the
Sequence Planner's later hand-out of a member already recorded is skipped.

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
from pathlib import Path
from typing import Any

import numpy as np

from ita.archive import Event, Outcome, Result, RunStatus
from ita.executive import EventKind as XKind
from ita.executive.commands import term_text
from ita.logic.terms import Term
from ita.planning.state import NOTHING, Place, Pose, PoseKind, WorldState
from ita.toplevel.signals import RunSignals, StopNow

__all__ = ["Progress", "RunSummary", "Session", "TopLevel", "archive_events", "open_session", "start_run",
           "state_after"]


# -- the session: everything a run needs, loaded once ---------------------------------------

@dataclass(eq=False)
class Session:
    """The loaded system: knowledge bases, part, plan, MKB, simulator and devices."""

    kb: Any
    part: Any
    part_arg: str | None          # --part as given (None: the built-in bulkhead)
    ctx: Any                      # ita.sequence.plan.PlanningContext
    plan: Any                     # the prepared SequencePlan
    mkb: Any
    reasoner: Any
    world: Any
    arm: Any
    slra: Any
    executive: Any
    planner: Any                  # OperationPlanner
    seed: int
    setup_seconds: float = 0.0

    @property
    def specs(self) -> dict[str, Any]:
        return {s.id: s for s in self.ctx.specs}

    def close(self) -> None:
        """Save the MACROP store (kept open: SWI-Prolog has one database per process, which
        another session in this process may share) and close the simulator."""
        try:
            self.planner.save()
        finally:
            self.world.close()


def open_session(part_dir: Path | None = None, *, seed: int = 0,
                 progress: Callable[[str], None] = lambda _m: None) -> Session:
    """Load everything a run needs; prepare the part first (sequence plan, MKB, MACROPs)
    when what is stored is missing or stale."""
    from ita.executive import PlanExecutive
    from ita.geometry import GeometricReasoner
    from ita.logic.bridge import KnowledgeBase
    from ita.offline.prepare import prepare_inspection
    from ita.part.store import load_part
    from ita.path import planners_for
    from ita.planning import OperationPlanner, store_path
    from ita.sequence.plan import planning_context
    from ita.sequence.store import apply_tool_marks, load_tool_marks
    from ita.sim.slra import SlraScene
    from ita.sim.world import SimWorld
    from ita.toplevel.adapters import ArmAdapter, SlraAdapter
    from ita.vision.measure import VisionContext

    t0 = time.perf_counter()
    progress("loading the knowledge bases and the part")
    kb = KnowledgeBase()
    apply_tool_marks(kb, load_tool_marks())
    part = load_part(part_dir)
    ctx = planning_context(part_dir, kb=kb, part=part)
    plan, mkb, _ = prepare_inspection(ctx, part, progress=progress, warm=False)
    specs = {s.id: s for s in ctx.specs}
    cell = ctx.workcell
    reasoner = GeometricReasoner(mkb, cell, ctx.specs)
    progress("building the simulated workcell")
    world = SimWorld(cell, part.directory, seed=seed, q0=reasoner.home)
    try:
        planner_for = planners_for(cell, part)
        arm = ArmAdapter(world, reasoner, planner_for, specs)
        slra_tools = [t for t in cell.tools if t.tool_class.value == "slra_tool"]
        vctx = VisionContext.from_part(part, cell, tool=slra_tools[0].name if slra_tools else "slra_1",
                                       specs=list(ctx.specs))
        scene = SlraScene.from_truth(part.directory, cell)
        slra = SlraAdapter(world, scene, reasoner, vctx, specs, np.random.default_rng([seed, 21]))
        executive = PlanExecutive(kb, {"path_planner": arm, "vision": slra}, clock=world.clock)
        op = OperationPlanner(kb, store_path(ctx.part_name))
    except BaseException:
        world.close()
        raise
    return Session(kb, part, None if part_dir is None else str(Path(part_dir).resolve()), ctx, plan, mkb,
                   reasoner, world, arm, slra, executive, op, seed, time.perf_counter() - t0)


def start_run(session: Session, archive: Any, *, limit: int | None = None) -> str:
    """Register a new run of the session's part in `archive`: the measurements it sets out
    to do are the first `limit` of the sequence plan (all by default), plus those the plan
    cannot do (recorded as such).  Returns the run id."""
    plan = session.plan
    order = [i for g in plan.groups for i in g.order]
    todo = order[:limit] if limit is not None else order
    if limit is None:
        todo += [i for i, _ in plan.cannot]
    settings = {"simulated": True, "limit": limit, "part_arg": session.part_arg, "specs": todo,
                "mkb_digest": session.mkb.digest, "sequence_total_s": plan.total_s}
    return archive.create_run(session.ctx.part_name, session.part.directory, seed=session.seed,
                              settings=settings, total=len(todo))


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
                "continue": self.continue_hint}


# -- events ---------------------------------------------------------------------------------

_CATEGORY = {"MOVE": "motion", "RETRACT": "motion", "CONTACT": "motion", "COUPLANT": "measuring",
             "MEASURE": "measuring", "SCAN": "measuring", "PICKUP": "tool_change", "PUTDOWN": "tool_change"}


def _stream_name(stream: Any, message_name: str | None) -> str:
    if stream is None:
        return "top"
    if stream.device == "vision":
        return "slra"
    if message_name in ("COUPLANT", "MEASURE"):
        return "gauge"
    return "arm"


def archive_events(report: Any, plan_no: int) -> list[Event]:
    """The executive's log of one plan as archive events (ita.archive.timeline's
    conventions): a command per SEND with its end and category, its reply, WAIT and
    CONTINUE per stream, exceptions."""
    names: dict[int, str] = {}
    ends: dict[int, float] = {}
    for e in report.events:
        if e.kind is XKind.SEND:
            names[e.step] = e.payload.name if isinstance(e.payload, Term) else str(e.payload)
        elif e.kind in (XKind.REPLY, XKind.EXCEPTION, XKind.TIMEOUT, XKind.CANCELLED) and e.step is not None:
            ends.setdefault(e.step, e.sim_time)
    out: list[Event] = []
    for e in report.events:
        step = e.step
        name = names.get(step) if step is not None else None
        stream = _stream_name(e.stream, name)
        cmd = f"{plan_no}.{step}"
        if e.kind is XKind.SEND:
            payload = {"cmd": cmd, "name": name.lower(), "category": _CATEGORY.get(name, "other"),
                       "message": term_text(e.payload)}
            if step in ends:
                payload["end"] = ends[step]
            out.append(Event("command", stream, e.sim_time, payload))
        elif e.kind is XKind.REPLY:
            reply, result = e.payload
            out.append(Event("reply", stream, e.sim_time, {"cmd": cmd, "status": "ok", "reply": term_text(reply),
                                                            "result": term_text(result)}))
        elif e.kind in (XKind.EXCEPTION, XKind.TIMEOUT):
            status = "timeout" if e.kind is XKind.TIMEOUT else "exception"
            out.append(Event("reply", stream, e.sim_time, {"cmd": cmd, "status": status}))
        elif e.kind is XKind.WAIT:
            out.append(Event("wait", stream, e.sim_time, {"on": [f"{plan_no}.{s}" for s in e.payload], "cmd": cmd}))
        elif e.kind is XKind.CONTINUE:
            out.append(Event("continue", stream, e.sim_time, {"on": [f"{plan_no}.{s}" for s in e.payload],
                                                              "cmd": cmd}))
        elif e.kind is XKind.CANCELLED:
            out.append(Event("cancelled", stream, e.sim_time, {"cmd": cmd, "how": str(e.payload)}))
    if report.failure is not None:
        f = report.failure
        out.append(Event("exception", _stream_name(f.command.stream, f.command.name), f.at_s,
                         {"message": f.reason, "kind": f.kind.value, "step": f.step.number,
                          "reply": term_text(f.reply.payload) if f.reply.payload is not None else None}))
    return out


def state_after(plan: Any, report: Any) -> WorldState:
    """The world state after a plan that stopped: the initial state with the results of
    the steps that completed applied (moves, contact, tool pick-ups and put-downs)."""
    state = plan.initial_state
    pose, holding = state.pose, state.holding
    for outcome in report.outcomes:
        r = outcome.result
        if not isinstance(r, Term):
            continue
        try:
            if r.name == "moved" and len(r.args) == 2:
                pose = Pose.from_term(r.args[1])
            elif r.name == "contact" and len(r.args) == 3:
                pose = Pose(PoseKind.CONTACT, Place.from_term(r.args[1]))
            elif r.name == "tool_location" and len(r.args) == 2 and isinstance(r.args[1], Term):
                holding = str(r.args[0]) if r.args[1].name == "on_arm" else None
        except ValueError:
            continue
    return WorldState(state.arm, pose, None if holding == NOTHING else holding)


# -- the loop ---------------------------------------------------------------------------------

class TopLevel:
    """Runs (or continues) one inspection run of `session` recorded in `archive`."""

    def __init__(self, session: Session, archive: Any, run_id: str, signals: RunSignals | None = None) -> None:
        self.s = session
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

    # -- recording ---------------------------------------------------------------------------
    def _record(self, result: Result, events: list[Event] = ()) -> None:
        if self.archive.record_result(self.run_id, result, events=events):
            self.done.add(result.spec_id)
            label = result.decision.value if result.decision is not None else result.outcome.value
            self.counts[label] += 1
            self.recorded_now += 1

    def _unmeasured(self, spec_id: str, outcome: Outcome, reason: str, *, tool: str | None = None,
                    t0: float | None = None, t1: float | None = None, events: list[Event] = ()) -> None:
        spec = self.s.specs[spec_id]
        self._record(Result.unmeasured(spec, outcome, reason, tool=tool, sim_time_start=t0, sim_time_end=t1),
                     list(events))

    # -- the run -----------------------------------------------------------------------------
    def run(self, on_progress: Callable[[Progress], None] | None = None) -> RunSummary:
        from ita.sequence.next_step import next_step

        s = self.s
        wall0 = time.perf_counter()
        last = self.archive.last_sim_time(self.run_id) or 0.0
        if s.world.clock.now < last:
            s.world.clock.advance(last - s.world.clock.now)
        sim0 = s.world.clock.now
        n_done0 = len(self.done)
        plan = replace(s.plan, handed_out=tuple(i for g in s.plan.groups for i in g.order
                                                  if i in self.done or i not in self.todo_set))
        state = WorldState(arm=self._arm_name())
        status = RunStatus.COMPLETED
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
                if step.spec_id in self.done or step.spec_id not in self.todo_set:
                    continue
                current = (step.group, step.tool, step.spec_id)
                state = self._measure(step, state)
                if on_progress is not None:
                    on_progress(self._progress(current, wall0, sim0, n_done0, "measuring"))
        except StopNow:
            status = RunStatus.STOPPED
        end_t = s.world.clock.now
        remaining = [i for i in self.todo if i not in self.done]
        if status is RunStatus.COMPLETED and remaining:
            for spec_id in remaining:   # the sequence planner no longer hands them out
                self._unmeasured(spec_id, Outcome.CANNOT_BE_DONE, "not handed out by the sequence planner")
        kind = {RunStatus.COMPLETED: "run_end", RunStatus.INTERRUPTED: "interrupt",
                RunStatus.STOPPED: "stop"}[status]
        self.archive.set_status(self.run_id, status, event=Event(kind, "top", end_t, {
            "reason": self.signals.reason or None, "done": len(self.done), "total": len(self.todo)}))
        self.archive.update_totals(self.run_id, specs=len(self.todo), done=len(self.done),
                                   sim_time_s=end_t, counts=dict(self.counts))
        summary = RunSummary(
            self.run_id, status.value, len(self.done), len(self.todo), dict(self.counts), sim0, end_t,
            time.perf_counter() - wall0, self.recorded_now, self.exceptions, self.frames,
            devices={**{f"arm_{k}": v for k, v in s.arm.stats.items()},
                     **{f"slra_{k}": v for k, v in s.slra.stats.items()},
                     "path_planning_wall_s": s.arm.planning_seconds},
            continue_hint=None if status is RunStatus.COMPLETED else f"ita continue {self.run_id}")
        summary.breakdown = self.breakdown()
        if on_progress is not None:
            on_progress(self._progress(current, wall0, sim0, n_done0, status.value))
        return summary

    def breakdown(self) -> dict[str, float]:
        """The run's cycle-time breakdown from its recorded events (ita.archive.timeline)."""
        from ita.archive.timeline import breakdown, intervals, span

        events = self.archive.events(self.run_id)
        start, end = span(events)
        return breakdown(intervals(events, end), start, end)

    def _arm_name(self) -> str:
        from ita.sequence.next_step import the_arm

        return the_arm(self.s.kb)

    def _progress(self, current: tuple, wall0: float, sim0: float, n0: int, status: str) -> Progress:
        s = self.s
        done, total = len(self.done), len(self.todo)
        wall = time.perf_counter() - wall0
        made = done - n0
        left = total - done
        eta_wall = wall / made * left if made else None
        eta_sim = (s.world.clock.now - sim0) / made * left if made else None
        return Progress(self.run_id, done, total, current[0], current[1], current[2], status, s.world.clock.now,
                        wall, eta_wall, eta_sim, self.exceptions, dict(self.counts))

    def _measure(self, step: Any, state: WorldState) -> WorldState:
        """Plan, execute and record one measurement (and its view group's); the new state."""
        from ita.planning import NoPlanError

        s = self.s
        spec_id = step.spec_id
        spec = s.specs[spec_id]
        entry = s.mkb.entries.get(spec_id)
        if entry is None or not entry.ok:
            why = "not in the measurement knowledge base" if entry is None else f"{entry.status}: {entry.reason}"
            self._unmeasured(spec_id, Outcome.CANNOT_BE_DONE, why, tool=step.tool)
            return state
        t0 = s.world.clock.now
        try:
            op = s.planner.plan_measurement(spec, state)
        except NoPlanError as exc:
            self._unmeasured(spec_id, Outcome.NOT_DONE, f"no plan: {exc.reason}", tool=step.tool, t0=t0, t1=t0)
            return state
        self.plan_no += 1
        report = s.executive.execute(op, start_s=t0)
        t1 = max(s.world.clock.now, report.finished_s)
        if s.world.clock.now < t1:
            s.world.clock.advance(t1 - s.world.clock.now)
        events = [Event("plan_start", "top", t0, {"spec": spec_id, "macrop": op.macrop_name,
                                                  "source": op.source.value, "steps": len(op.steps)})]
        events += archive_events(report, self.plan_no)
        readings = s.arm.take_readings()
        vision = s.slra.take_results()
        if any(e.kind == "command" and e.payload.get("name") == "scan" for e in events):
            self.frames += 1
        if report.ok:
            new_state = op.final_state
            value, u = self._value(spec_id, report, readings, vision)
            events.append(Event("plan_end", "top", t1, {"spec": spec_id, "status": "ok"}))
            if value is None:
                self._unmeasured(spec_id, Outcome.NOT_DONE, "no value in the replies", tool=step.tool, t0=t0,
                                 t1=t1, events=events)
            else:
                self._record(Result.measured(spec, value, u, tool=step.tool, sim_time_start=t0, sim_time_end=t1),
                             events)
        else:
            self.exceptions += 1
            new_state = state_after(op, report)
            moved = s.arm.recover()
            events.append(Event("plan_end", "top", t1, {"spec": spec_id, "status": "failed",
                                                        "recovered_arm": moved}))
            if moved:
                events.append(Event("recovery", "arm", t1, {"how": "jog back to the last free configuration",
                                                            "duration": s.arm.RECOVER_SECONDS}))
            self._unmeasured(spec_id, Outcome.NOT_DONE, report.failure.reason, tool=step.tool, t0=t0, t1=t1,
                             events=events)
        for other, reply in vision.items():   # the rest of the frame's view group
            if other == spec_id or other in self.done or other not in self.todo_set:
                continue
            if reply.ok:
                self._record(Result.measured(s.specs[other], reply.value, reply.uncertainty, tool=step.tool,
                                             sim_time_start=t0, sim_time_end=t1,
                                             reason=f"from the frame of {spec_id}"))
            else:
                self._unmeasured(other, Outcome.NOT_DONE, f"vision: {reply.reason.value}: {reply.detail}",
                                 tool=step.tool, t0=t0, t1=t1)
        return new_state

    @staticmethod
    def _value(spec_id: str, report: Any, readings: dict, vision: dict) -> tuple[float | None, float]:
        """The measured value and standard uncertainty of `spec_id` from the plan's results."""
        if spec_id in readings:
            r = readings[spec_id]
            return float(r.thickness_mm), float(r.u_mm)
        if spec_id in vision and vision[spec_id].ok:
            r = vision[spec_id]
            return float(r.value), float(r.uncertainty)
        for res in report.results:
            if isinstance(res, Term) and res.name == "dimension" and res.args[0] == spec_id:
                return float(res.args[2]), float(res.args[3])
        return None, 0.0
