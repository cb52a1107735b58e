"""The Top Level: an inspection run carried out as the plan of a high-level planner.

    session = open_session(part_dir, seed=1)                 # prepares first if needed
    run_id = start_run(session, archive, limit=12)
    summary = TopLevel(session, archive, run_id, signals).run(on_progress=show)

The seed's wish for its hard-coded Top Level, "a high-level planner that can call on
special-purpose functions such as the current sequence planner as tools", is what this
is: the job (kb/tasks.pl, ``inspect_part``) is planned by the HTN planner
(prolog/htn.pl) from the run's state, and the Top Level carries out the plan's
primitive tasks one by one (:mod:`ita.toplevel.agenda`).  The planner asks the Top
Level's tools through attached procedures: the Sequence Planner's next measurement from
a position of the sequence plan (``next_step``: resources checked, resequencing when a
tool is gone), whether a measurement is still to do, whether a probe reads the
calibration block first.  Before each action its preconditions are checked again; an
action whose preconditions no longer hold (a measurement another's frame measured
meanwhile, a record after a failed reading) has its task planned again from there, and
an outcome that makes the rest of the plan wrong (an interrupt, a STOP, the alarm, a
recovery that changed the world model) has everything left planned again.

The primitive tasks: a measurement's round trip (the Operation Planner's plan with the
tool the Sequence Planner chose, MACROP lookup first, from the world state the previous
plan left; its execution by the Plan Executive on the devices, the Geometric Reasoner
resolving the plan's qualitative poses from the MKB: :func:`ita.task.measure.measure_one`);
the Exception Handler on a failure (:mod:`ita.toplevel.handling`: it diagnoses, puts
the cell right and measures again); the result to the archive the moment it exists,
with the plan's events, in one transaction (:mod:`ita.toplevel.recording`); a probe's
reading of the calibration block before its first reading
(:mod:`ita.toplevel.calibration`); pending results settled.  A measurement still not
done is recorded so with the reason, the world state taken from the steps that did
complete.  A measurement the Geometric Reasoner could not place, or that the Sequence
Planner put in its cannot-be-done group, is recorded cannot-be-done.

SLRA view groups: a frame taken for one measurement serves every member of its view
group (the MKB); the members' results are recorded as soon as Vision has them, and the
Sequence Planner's later hand-out of a member already recorded is skipped.  A member the
frame could not measure is not recorded: it is handed out later on its own view (with
the Exception Handler behind it), since a frame made for another is no attempt of its own.

Pending results (:mod:`ita.toplevel.pending`): a fastener hole's position waits for its
face's network (the run's setting ``network``), a flange or rib height for the
thickness of its webs the run still has to measure; each is decided when the last of
what it waits for is done, and a run that completes decides everything left.
`ita continue` reads them back and does not measure them again.

Before each measurement the Top Level reads the control table: INTERRUPT (leave after
the current measurement, status INTERRUPTED) and STOP (raised at once as StopNow,
status STOPPED), from Ctrl-C or from `ita monitor`; so many measurements not done in a
row stop it with an alarm.  Each is a fact of the plan's state, and the job's methods
end the run accordingly.  A run is continued (`ita continue`) by skipping every spec the
archive has a result for: nothing is measured twice, nothing is lost.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Mapping
from dataclasses import replace
from typing import TYPE_CHECKING, Any

from ita.archive import Event, Outcome, RunStatus
from ita.archive.exceptions import EVENT_KINDS as EXCEPTION_EVENTS
from ita.archive.exceptions import ExceptionCounts
from ita.archive.timeline import breakdown, intervals, span
from ita.diagnosis.tests import DISPLACED_MM
from ita.errors import PrologError
from ita.logic.attached import Procedure
from ita.logic.bridge import KnowledgeBase
from ita.logic.json_value import JsonObject, JsonValue
from ita.logic.terms import Term, TermValue, Var
from ita.logic.world import WorldModel
from ita.planning.state import WorldState
from ita.sequence.next_step import Step, next_step, the_arm
from ita.task.measure import MeasureOutcome, MeasureStatus, execute_goals, measure_one
from ita.toplevel.agenda import Action, Agenda, Facts, tree_lines, with_facts
from ita.toplevel.calibration import ProbeCalibration
from ita.toplevel.checks import CellChecks
from ita.toplevel.details import MeasurementDetails, measurement_details
from ita.toplevel.events import (
    PlanNumbers,
    diagnosis_events,
    measurement_events,
    plan_events,
    run_end_event,
    sequence_event,
)
from ita.toplevel.handling import Handling
from ita.toplevel.pending import PendingDecisions
from ita.toplevel.progress import Progress, RunSummary, Started, progress
from ita.toplevel.recording import (
    MAX_FAILURES_IN_A_ROW,
    Attached,
    FailuresInARow,
    Recorder,
    measured_result,
)
from ita.toplevel.registration import PartRegistration, alignment_payload
from ita.toplevel.shared import SharedCell
from ita.toplevel.signals import RunSignals, StopNow
from ita.toplevel.start import start_run

if TYPE_CHECKING:
    from ita.archive import Archive
    from ita.task.align import Alignment
    from ita.task.session import Session

__all__ = ["JOB", "MAX_FAILURES_IN_A_ROW", "Progress", "RunSummary", "TASKS", "TopLevel", "job_tasks", "jobs",
           "start_run"]

#: the knowledge base module of the Top Level's jobs (kb/tasks.pl) and the default job
TASKS = "tasks"
JOB = "inspect_part"
#: plans made again in a row with the same action first, not applicable, before the run fails
MAX_REPLANS_IN_A_ROW = 20
#: the Exception Handler's calls on one measurement: a recovery whose retry fails with a new
#: exception has that one diagnosed too, up to this many in all
MAX_HANDLINGS = 3
#: lines of the plan's decomposition tree kept with a run (the System Monitor and the report show them)
TREE_LINES = 400
#: the exceptions whose not-done measurement is not taken once more at the end: Vision
#: cannot measure the feature in its view at all
_NOT_RETAKEN = ("view_not_measurable",)


def _beyond_the_cell(diagnosis: Mapping[str, Any]) -> bool:
    """Whether a diagnosis (its archive event's payload) left its measurement beyond the
    cell's reach: a cause found that no action puts right, or an exception of
    :data:`_NOT_RETAKEN` (Vision cannot measure the feature in its view at all)."""
    return bool(diagnosis.get("cause")) and not diagnosis.get("actions") or \
        diagnosis.get("exception") in _NOT_RETAKEN
#: the actions that begin a measurement: the control table is read before the first of them
_POLL_BEFORE = frozenset({"note_resequence", "calibrate_probe", "measure", "measure_again"})


def jobs(kb: KnowledgeBase) -> list[tuple[str, str]]:
    """The jobs of kb/tasks.pl: (name, description), in the order written."""
    return [(str(r["N"]), str(r["D"])) for r in kb.call(TASKS, "job", Var("N"), Var("_T"), Var("D"))]


def job_tasks(kb: KnowledgeBase, name: str) -> list[TermValue]:
    """The task network of job `name` (kb/tasks.pl job/3); PrologError when there is none."""
    found = kb.once(TASKS, "job", name, Var("T"), Var("_D"))
    tasks = None if found is None else found["T"]
    if not isinstance(tasks, list):
        raise PrologError(f"{TASKS}:job/3", f"no job {name!r} (ita tasks lists them)")
    return list(tasks)


class TopLevel:
    """Runs (or continues) one inspection run of `session` recorded in `archive`.

    max_failures_in_a_row: stop the run (status stopped, with an alarm; `ita continue`
    goes on once the cause is put right) after this many measurements in a row end not
    done; 0: never; None: the run's setting "alarm_after" (`ita inspect --alarm-after`),
    else MAX_FAILURES_IN_A_ROW."""

    def __init__(self, session: Session, archive: Archive, run_id: str, signals: RunSignals | None = None, *,
                 handle_exceptions: bool = True, max_failures_in_a_row: int | None = None) -> None:
        info = archive.run(run_id)
        if max_failures_in_a_row is None:
            max_failures_in_a_row = int(info.settings.get("alarm_after", MAX_FAILURES_IN_A_ROW))
        self.session = session
        self.archive = archive
        self.run_id = run_id
        self.job = str(info.settings.get("task", JOB))
        self.signals = signals or RunSignals(message=None)
        ids = info.settings.get("specs")
        self.todo: list[str] = list(ids) if ids is not None else list(session.specs)
        self.todo_set = set(self.todo)
        self.failures = FailuresInARow(int(max_failures_in_a_row))
        self.results = Recorder(session, archive, run_id, self.failures)
        self.plans = PlanNumbers(last=len(self.results.done))
        self.pending = PendingDecisions.resume(session, archive, run_id, self.todo, self.results,
                                               network=bool(info.settings.get("network", False)))
        self.calibration = ProbeCalibration(session, archive, run_id, self.plans)
        self.handle = Handling.of(session, archive, run_id, prepare_tool=self.calibration.before) \
            if handle_exceptions else Handling(session, None)
        #: the interim checks of the cell against its reference artifacts (None: the knowledge sets none)
        self.checks = CellChecks.of(session, archive, run_id, self.plans, self.handle)
        self.registration = PartRegistration(session, archive, run_id, self.plans)
        #: what the other arm of a two-arm run hears of the part and the tools, and tells
        self.shared = SharedCell(session)
        self.failed_in_others: dict[str, str] = {}   # view-group members another's frame could not measure
        self.frames = 0
        self.diagnoses = 0
        # the plan's state on the Python side: positions of the sequence plan (the first:
        # the stored plan with what the run has done handed out), the Sequence Planner's
        # answers per position, the arm's state, the measurements between their actions
        self._cursors = [replace(session.plan, handed_out=tuple(i for g in session.plan.groups for i in g.order
                                                                if self._skipped(i)))]
        self._remade: dict[int, str] = {}          # sequence plan position -> why it was remade there
        self._left: dict[int, list[TermValue]] = {}
        self._next: dict[int, TermValue | None] = {}
        self._state = WorldState(arm=the_arm(session.kb), holding=session.held)   # what the arm holds now
        self._outcomes: dict[str, tuple[Step, MeasureOutcome, list[Event], int]] = {}
        self._steps: dict[str, Step] = {}
        self._handlings: dict[str, int] = {}       # spec id -> the Exception Handler's calls on it
        self._retaken = False                       # the not-done results retaken once at the end
        self._status = RunStatus.COMPLETED
        self._alarm = ""
        self._halt = ""                             # why this arm cannot go on (a diagnosis's halt)
        self._current: Step | None = None
        self._on_progress: Callable[[Progress], None] | None = None
        self._started = Started(time.perf_counter(), session.clock.now, len(self.results.done))
        self.agenda = Agenda(session.kb, TASKS)
        self.cell: JsonObject | None = None          # the job cell_check's report
        earlier = info.settings.get("earlier")
        #: a reinspection's earlier results (ita.toplevel.start.earlier_results), by spec id
        self.earlier: dict[str, JsonValue] = dict(earlier) if isinstance(earlier, dict) else {}

    def _planner_figures(self) -> dict[str, float]:
        """The HTN plan's figures: the first plan's wall time, how often it was planned
        again and the median and largest wall time of that (s)."""
        again = sorted(self.agenda.replan_seconds)
        return {"plan_s": self.agenda.plan_seconds, "replans": float(len(again)),
                "replan_median_s": again[len(again) // 2] if again else 0.0,
                "replan_max_s": again[-1] if again else 0.0, "actions": float(len(self.agenda.executed))}

    def _procedures(self) -> dict[str, Procedure]:
        """The attached procedures of kb/tasks.pl, answered by this run."""
        return {"next_measurement": self._next_measurement, "nothing_left": self._nothing_left,
                "to_measure": self._to_measure, "calibration_due": self._calibration_due,
                "probes": self._probes, "earlier": self._earlier, "alternatives": self._alternatives}

    def _given(self) -> Facts:
        """The facts the job's plan starts from: ``reinspecting`` in a reinspection."""
        return with_facts({}, ["reinspecting"] if self.earlier else [])

    def plan_job(self) -> Agenda:
        """The plan of the run's job from where the run stands, nothing carried out
        (`ita plan --top`): its actions and its decomposition tree."""
        with self.session.kb.attached(self._procedures()):
            self.agenda.plan(job_tasks(self.session.kb, self.job), self._given())
        return self.agenda

    def _skipped(self, spec_id: str) -> bool:
        """Whether the loop passes `spec_id` by: recorded, waiting, or not the run's."""
        return spec_id in self.results.done or self.pending.waiting(spec_id) or spec_id not in self.todo_set

    # -- the run -----------------------------------------------------------------------------
    def run(self, on_progress: Callable[[Progress], None] | None = None) -> RunSummary:
        """Measure what the run still has to, in the Sequence Planner's order, until done,
        interrupted, stopped or alarmed; record how it ended.  on_progress: called after
        each measurement and at the end."""
        s = self.session
        last = self.archive.last_sim_time(self.run_id) or 0.0
        if s.clock.now < last:
            s.clock.advance(last - s.clock.now)
        started = Started(time.perf_counter(), s.clock.now, len(self.results.done))
        self._on_progress = on_progress
        self._started = started
        facts = self._given()
        agenda = self.agenda = Agenda(s.kb, TASKS)
        with s.kb.attached(self._procedures()):
            agenda.plan(job_tasks(s.kb, self.job), facts)
            # the plan as made, for the System Monitor while the run goes on (the end adds the
            # plan as carried out)
            self.archive.record_event(self.run_id, Event("task_tree", "top", s.clock.now, {
                "job": self.job, "stage": "planned", "lines": list(tree_lines(agenda, TREE_LINES)),
                "planner": dict(self._planner_figures())}))
            polled = False
            stuck, blocked = 0, None
            while (action := agenda.next()) is not None:
                try:
                    if not polled and action.name in _POLL_BEFORE:
                        polled = True
                        self.signals.poll(self.archive, self.run_id)
                        if self.signals.interrupt:
                            facts = with_facts(facts, ["interrupted"])
                            agenda.replan_rest(facts)
                            continue
                    if not agenda.applicable(action, facts):
                        stuck = stuck + 1 if action.term == blocked else 1
                        blocked = action.term
                        if stuck > MAX_REPLANS_IN_A_ROW:     # the domain plans what it cannot carry out
                            raise PrologError(f"{TASKS}:method/4", f"planned {stuck} times in a row with the "
                                              f"same action first, not applicable: {action.term}")
                        if not agenda.replan_parent(facts):
                            agenda.replan_rest(facts)
                        continue
                    stuck = 0
                    observed, rest_wrong = self._carry_out(action)
                except StopNow:
                    facts = with_facts(facts, ["stopped"])
                    self._status = RunStatus.STOPPED
                    agenda.replan_rest(facts)
                    continue
                facts = with_facts(agenda.done(action, facts), observed)
                if action.name == "settle_pending":
                    polled = False
                if rest_wrong:
                    self._next.clear()          # the Sequence Planner's answers are of the world before
                    agenda.replan_rest(facts)
        end_t = max(s.clock.now, s.executive.settled())     # the last trailing Vision reply too
        self.archive.record_event(self.run_id, Event("task_tree", "top", end_t, {
            "job": self.job, "stage": "carried out", "lines": list(tree_lines(agenda, TREE_LINES)),
            "planner": dict(self._planner_figures())}))
        status, alarm, current = self._status, self._alarm, self._current
        done, total = len(self.results.done), len(self.todo)
        self.archive.set_status(self.run_id, status, event=run_end_event(
            status, end_t, reason=alarm or self.signals.reason or None, done=done, total=total))
        counts = dict(self.results.counts)
        self.archive.update_totals(self.run_id, specs=total, done=done, sim_time_s=end_t, counts=counts)
        summary = RunSummary(
            self.run_id, status.value, done, total, counts, started.sim_s, end_t,
            time.perf_counter() - started.wall_s, self.results.recorded_now,
            ExceptionCounts.from_events(self.archive.events(self.run_id, kinds=EXCEPTION_EVENTS)), self.frames,
            breakdown=self.breakdown(),
            devices={**{f"arm_{k}": v for k, v in s.arm.stats.items()},
                     **{f"slra_{k}": v for k, v in s.slra.stats.items()},
                     "path_planning_wall_s": s.arm.planning_seconds},
            continue_hint=None if status is RunStatus.COMPLETED else f"ita continue {self.run_id}", alarm=alarm,
            cell=self.cell, planner=self._planner_figures(),
            alignment=self.registration.last if s.alignment is None else s.alignment.to_dict())
        if on_progress is not None:
            on_progress(self._progress(started, current, status.value))
        return summary

    def breakdown(self) -> dict[str, float]:
        """The run's cycle-time breakdown from its recorded events (ita.archive.timeline)."""
        events = self.archive.events(self.run_id)
        start, end = span(events)
        return breakdown(intervals(events, end), start, end)

    def _progress(self, started: Started, step: Step | None, status: str) -> Progress:
        return progress(self.run_id, started, done=len(self.results.done), total=len(self.todo), step=step,
                        status=status, sim_s=self.session.clock.now,
                        exceptions=self.archive.count_events(self.run_id, "exception"),
                        counts=self.results.counts)

    def _get_ready(self) -> None:
        """An arm that takes the other arm's registration (a two-arm run) gets its first
        measurement's tool ready meanwhile, as it would right after: it picks the tool up
        and, a probe, reads the calibration block with it.  (Waiting for the
        registration with nothing in hand, it used to make that trip to the rack after,
        when the registering arm goes there to change its tool.)"""
        s = self.session
        if s.peer is None or s.registers:
            return
        found = self._next_measurement(0)
        if not isinstance(found, Term) or not isinstance(found.args[0], Term):
            return
        step = self._steps[str(found.args[0].args[0])]
        if self.calibration.due(step.spec_id, step.tool):
            self._state = self.calibration.calibrate(step.tool, self._state)
        elif s.held != step.tool:
            plan, report, self._state, _ = execute_goals(s, [Term("holding", (self._state.arm, step.tool))],
                                                         self._state, name="get the first tool")
            if plan is not None and report is not None:
                self.archive.record_events(self.run_id, plan_events(plan, report, None, "the first tool",
                                                                    self.plans.next(), tool=step.tool))

    # -- the attached procedures: the Sequence Planner and the run's state, asked by the plan --
    def _next_measurement(self, cursor: TermValue) -> TermValue | None:
        """next(step(Spec, Tool, Group, Resequenced), Next): the Sequence Planner's next
        measurement after position `cursor` of the sequence plan that the run still has
        to do (those it has are handed out and passed by, as the seed's loop did), the
        positions where it remade the plan on the way, and the position after it; None
        (the goal fails) when nothing is left.  Remembered per position until the world
        changes."""
        k = int(str(cursor))
        if k not in self._next:
            plan = self._cursors[k]
            remade: list[TermValue] = []
            answer: TermValue | None = None
            while True:
                result = next_step(self.session.ctx, plan, self._state.arm)
                plan = result.plan
                self._cursors.append(plan)
                here = len(self._cursors) - 1
                if result.resequenced:
                    remade.append(here)
                    self._remade[here] = result.reason or ""
                step = result.step
                if step is None:
                    self._left[k] = remade
                    break
                if self._skipped(step.spec_id):
                    continue
                self._steps[step.spec_id] = step
                answer = Term("next", (Term("step", (step.spec_id, step.tool, step.group, remade)), here))
                break
            self._next[k] = answer
        return self._next[k]

    def _nothing_left(self, cursor: TermValue) -> TermValue | None:
        """The positions where the plan was remade, when nothing is left after `cursor`."""
        if self._next_measurement(cursor) is not None:
            return None
        return list(self._left[int(str(cursor))])

    def _to_measure(self, spec_id: TermValue) -> TermValue | None:
        return None if self._skipped(str(spec_id)) else "true"

    def _calibration_due(self, spec_id: TermValue, tool: TermValue) -> TermValue | None:
        return "true" if self.calibration.due(str(spec_id), str(tool)) else None

    def _earlier(self, spec_id: TermValue) -> TermValue | None:
        """earlier(Decision, ToolType, Kind, Largest, Frames): the earlier run's result of
        `spec_id` in a reinspection (kb/tasks.pl better_way/3); None when there is none."""
        e = self.earlier.get(str(spec_id))
        if not isinstance(e, dict):
            return None
        return Term("earlier", (str(e["decision"]), str(e["tool_type"]), str(e["kind"]), str(e["largest"]),
                                int(str(e["frames"]))))

    def _alternatives(self, spec_id: TermValue) -> TermValue:
        """alt(ToolType, Tool) for each tool of another type than the planned one that the
        MKB placed for `spec_id` and the arm can use now."""
        sid = str(spec_id)
        s = self.session
        entry = s.mkb.entries.get(sid)
        world = WorldModel(s.kb)
        out: list[TermValue] = []
        for alt in s.mkb.alternatives.get(sid, ()):
            if not alt.ok or (entry is not None and alt.tool_class == entry.tool_class):
                continue
            usable = world.usable(self._state.arm, alt.tool_class)
            if usable:
                out.append(Term("alt", (alt.tool_class, usable[0])))
        return out

    def _probes(self) -> TermValue:
        """The cell's ultrasonic probes that are available now."""
        world = WorldModel(self.session.kb)
        return [t for t in world.tools() if self.calibration.is_probe(t) and world.available(t)]

    def _cell_report(self) -> JsonObject:
        """The cell's state from this run's reference artifacts: each probe's reading of
        the calibration block, each tooling hole's result."""
        probes: list[JsonValue] = [dict(e.payload) for e in self.archive.events(self.run_id, kinds=["calibration"])]
        tooling: list[JsonValue] = []
        problems: list[str] = []
        for probe in probes:
            assert isinstance(probe, dict)
            if not probe.get("ok"):
                problems.append(f"{probe.get('probe')} did not read the block")
        for r in self.archive.results(self.run_id):
            decision = r.decision.value if r.decision is not None else r.outcome.value
            circle = self.archive.details(self.run_id, r.spec_id).get("vision", {}).get("circle_mm")
            offset = None
            if circle is not None and r.point is not None:    # the hole's centre against its nominal place
                offset = round(math.hypot(circle["center"][0] - r.point[0], circle["center"][1] - r.point[1]), 4)
            tooling.append({"spec": r.spec_id, "value": r.value, "nominal": r.nominal,
                            "U": None if r.u is None else r.k * r.u, "decision": decision, "centre_off_mm": offset})
            if decision != "conforms":
                problems.append(f"{r.spec_id} {decision.replace('_', ' ')}")
            if offset is not None and offset > DISPLACED_MM:
                problems.append(f"{r.spec_id}'s centre {offset:.2f} mm off its place (part displaced, or the arm)")
        state = "as certified" if not problems else "to look at: " + "; ".join(problems)
        return {"state": state, "probes": probes, "tooling": tooling}

    def _world(self) -> tuple[tuple[str, str, str], ...]:
        """The world model's tools, their conditions and locations (what a recovery changes)."""
        world = WorldModel(self.session.kb)
        return tuple((t, world.condition(t), str(world.location(t))) for t in world.tools())

    # -- the plan's actions -----------------------------------------------------------------------
    def _carry_out(self, action: Action) -> tuple[list[TermValue], bool]:
        """Carry out one primitive task of the plan (kb/tasks.pl); the facts observed (to add
        to the plan's state) and whether the rest of the plan is wrong now."""
        name, args = action.name, [str(a) for a in action.args]
        s = self.session
        if name == "record_unplaceable":
            for spec_id, reason in s.plan.cannot:
                if spec_id in self.todo_set and spec_id not in self.results.done:
                    self.results.unmeasured(spec_id, Outcome.CANNOT_BE_DONE, self._why_not(reason))
        elif name == "note_resequence":
            k = int(args[0])
            self.archive.record_event(self.run_id, sequence_event(self._remade[k], self._cursors[k], s.clock.now))
        elif name == "register_part":
            self._get_ready()
            self._state = self.registration.register(self._state)
            self._reference_from_alignment()
            # a later run of a two-arm session: what the other arm found meanwhile, acted on
            # before any measuring is planned (nothing of the plan to make again)
            heard, _ = self._hear()
            return heard, False
        elif name == "calibrate_probe":
            # once per probe in a process: an arm waiting for the other's registration read
            # the block before the plan's step came (_get_ready)
            if args[0] not in self.calibration.calibrated:
                self._state = self.calibration.calibrate(args[0], self._state)
        elif name == "measure":
            return self._measure(self._steps[args[0]]), False
        elif name == "measure_again":
            return self._measure(self._way(self._steps[args[0]], action.args[1])), False
        elif name == "handle_exception":
            before = self._world()
            again, remeasure = self._handle(args[0])
            after = self._world()
            self._tell_tools(before, after)
            observed: list[TermValue] = [Term("failed", (args[0],))] if again else []
            if remeasure:
                observed.append("remeasuring")
            return observed, after != before or remeasure
        elif name == "check_cell":
            return self._check_cell()
        elif name == "check_if_due":
            observed, heard_wrong = self._hear()
            if observed:
                return observed, True
            if self.checks is not None and self.checks.due(len(self.results.since_check)) is not None:
                _, wrong = self._check_cell()    # found wrong: those since the last check back in the plan
                return [], wrong or heard_wrong
            return [], heard_wrong
        elif name == "requeued":
            pass
        elif name == "retake_not_done":
            return self._retake_not_done()
        elif name == "record":
            self._conclude(args[0])
        elif name == "settle_pending":
            self.pending.settle()
            if self._on_progress is not None:
                self._on_progress(self._progress(self._started, self._current, "measuring"))
            self._alarm = self._halt or self.failures.alarm
            if self._alarm:
                return ["alarm"], True
        elif name == "decide_pending":
            self.pending.settle(final=True)
        elif name == "record_leftovers":
            why_not = dict(self._cursors[-1].cannot)     # the latest sequence plan's reasons
            for spec_id in [i for i in self.todo if i not in self.results.done and not self.pending.waiting(i)]:
                if spec_id in self.failed_in_others:
                    self.results.unmeasured(spec_id, Outcome.NOT_DONE, self.failed_in_others[spec_id])
                else:
                    self.results.unmeasured(spec_id, Outcome.CANNOT_BE_DONE, self._why_not(why_not.get(spec_id)))
        elif name == "report_cell":
            self.cell = self._cell_report()
            self.archive.record_event(self.run_id, Event("cell_check", "top", s.clock.now, self.cell))
        elif name == "end_run":
            self._status = RunStatus(args[0])
        else:
            raise PrologError(f"{TASKS}:operator/4", f"the Top Level has no action {action.term}")
        return [], False

    def _measure(self, step: Step) -> list[TermValue]:
        """Measure one step (and its view group's other members); the facts observed:
        ``failed(Spec)`` when the round trip ended in an exception (the plan then has the
        Exception Handler diagnose it, put the cell right and measure again)."""
        self._current = step
        # a probe whose calibration the other arm's zones refused reads the block first
        self._state = self.calibration.before(step.spec_id, step.tool, self._state)
        out = measure_one(self.session, step.spec_id, self._state, step.tool)
        if out.status is MeasureStatus.CANNOT_BE_DONE or out.plan is None:
            self._outcomes[step.spec_id] = (step, out, [], 0)
            return []
        plan_no = self.plans.next()
        events = measurement_events(out, step.group, plan_no)
        if any(e.kind == "command" and e.payload.get("name") == "scan" for e in events):
            self.frames += 1
        self._outcomes[step.spec_id] = (step, out, events, plan_no)
        if out.status is not MeasureStatus.MEASURED and out.report is not None and not out.report.ok:
            return [Term("failed", (step.spec_id,))]
        return []

    def _why_not(self, reason: str | None) -> str:
        """A leftover's reason in words: what is missing (``no_working_tool(slra_tool)``:
        which tools of that type there are and their state; ``unmeasurable(Why)``: the
        feature the mesh does not show), else that the Sequence Planner never handed it out."""
        if reason is None:
            return "not handed out by the sequence planner"
        if reason.startswith("unmeasurable(") and reason.endswith(")"):
            return "its feature is not on the part's mesh: " + reason[len("unmeasurable("):-1]
        if reason.startswith("no_working_tool(") and reason.endswith(")"):
            tool_type = reason[len("no_working_tool("):-1]
            world = WorldModel(self.session.kb)
            tools = [t for t in world.tools() if world.tool_type(t) == tool_type]
            states = [f"{t} {'missing' if world.missing(t) else world.condition(t)}" for t in tools]
            return f"no working {tool_type}: " + (", ".join(states) if states else "the cell has none")
        return reason

    def _way(self, step: Step, way: TermValue) -> Step:
        """The step to measure, the way a reinspection chose (kb/tasks.pl better_way/3):
        another tool, or more frames asked of the SLRA for it."""
        if isinstance(way, Term) and way.name == "other_sensor":
            tool = str(way.args[0])
            return replace(step, tool=tool, tool_class=WorldModel(self.session.kb).tool_type(tool))
        if isinstance(way, Term) and way.name == "more_frames":
            self.session.slra.frames_asked[step.spec_id] = int(str(way.args[0]))
        return step

    def _handle(self, spec_id: str) -> tuple[bool, bool]:
        """The Exception Handler on the failed measurement of `spec_id`: whether its
        recovery's retry failed with an exception of its own, to be diagnosed in turn (at
        most MAX_HANDLINGS times per measurement), and whether the diagnosis has what was
        measured since the cell's last good check measured again (an arm drift found)."""
        step, out, events, plan_no = self._outcomes[spec_id]
        aligned = self.session.alignment
        handled = self.handle(out)
        self._realigned(aligned)
        again = remeasure = False
        if handled is not None:
            found = [handled.diagnosis, *handled.nested]
            self._halt = self._halt or next((d.halt for d in found if d.halt), "")
            if any(a.startswith("remeasure(") for d in found for a in d.actions):
                remeasure = bool(self._requeue(handled.diagnosis.cause))
            self.diagnoses += 1
            events += diagnosis_events(handled, self.plans)
            if handled.outcome.report is not None:
                plan_no = self.plans.last
            out = replace(handled.outcome, others=out.others + handled.outcome.others)
            self._handlings[spec_id] = self._handlings.get(spec_id, 0) + 1
            again = handled.retry_failed and self._handlings[spec_id] < MAX_HANDLINGS and not self._halt
        self._outcomes[spec_id] = (step, out, events, plan_no)
        return again, remeasure

    def _check_cell(self) -> tuple[list[TermValue], bool]:
        """The interim check of the cell (ita.toplevel.checks): what was recorded since the
        last good one stands when it passes (or cannot be made: its event says why), and is
        measured again when its diagnosis says so; the facts observed and whether the rest
        of the plan is wrong."""
        observed, heard_wrong = self._hear()
        if observed:
            return observed, True
        if self.checks is None or not self.results.since_check:
            return [], heard_wrong
        before = self._world()
        aligned = self.session.alignment
        done = self.checks.check(self._state)
        self._realigned(aligned)
        after = self._world()
        self._tell_tools(before, after)
        self._state = done.state
        if done.handled is not None:
            self.diagnoses += 1
            self._halt = self._halt or done.handled.diagnosis.halt
        if done.remeasure and done.handled is not None:
            self._requeue(done.handled.diagnosis.cause)
            return ["remeasuring"], True
        if done.passed is not False:
            self.results.checked()
        return [], after != before

    def _reference_from_alignment(self) -> None:
        """The interim checks' reference reading of tooling hole B: where the registration
        found it (its first check then compares with it, no reading of its own)."""
        a = self.session.alignment
        if self.checks is None or a is None or self.checks.bench.reference_spec is None:
            return
        self.checks.bench.baseline = a.registered(self.checks.bench.reference_spec)

    def _realigned(self, before: Alignment | None) -> None:
        """After the Exception Handler: the part registered again (a displaced part) is
        recorded, and the checks' reference reading is where it found tooling hole B; the
        other arm of a two-arm run is told (ita.toplevel.shared)."""
        now = self.session.alignment
        if now is not before:
            self.registration.note_change(before, "a recovery: the part found displaced")
            self._reference_from_alignment()
            if now is not None:
                self.shared.tell_registered(now, self.results.checked_s)

    def _tell_tools(self, before: tuple[tuple[str, str, str], ...], after: tuple[tuple[str, str, str], ...]) -> None:
        """The tools' conditions a diagnosis changed, told to the other arm of a two-arm run."""
        was = {t: c for t, c, _ in before}
        self.shared.tell_tools({t: c for t, c, _ in after if was.get(t, c) != c})

    def _hear(self) -> tuple[list[TermValue], bool]:
        """What the other arm of a two-arm run found of the part and the tools
        (ita.toplevel.shared), acted on: its new registration measured in, and what this
        arm recorded since the part may have moved measured again; a registration it asks
        for made and posted to it.  The facts observed (``remeasuring``) and whether the
        rest of the plan is wrong."""
        heard = self.shared.hear()
        if not heard.anything:
            return [], False
        s = self.session
        observed: list[TermValue] = []
        if heard.alignment is not None:
            self.archive.record_event(self.run_id, Event("alignment", "top", s.clock.now, alignment_payload(
                None, s.alignment, "the other arm registered the part again: it was found displaced")))
            self._reference_from_alignment()
        if heard.since_s is not None:
            since = heard.since_s
            ids = [r.spec_id for r in self.archive.results(self.run_id) if r.outcome is Outcome.MEASURED
                   and r.spec_id in self.todo_set and (r.sim_time_end or r.sim_time_start or 0.0) >= since]
            if self._requeue("part_displaced", ids, f"measured since {since:.1f} s, when the other arm last found "
                                                    "the part in place; it found the part displaced: measured again",
                             pending_since=since):
                observed.append("remeasuring")
        if heard.asks and s.peer is not None:
            kept = self.shared.still_good(max(found_s for _k, found_s in heard.asks))
            if kept is not None:            # registered again since the other arm saw it moved
                for key, _ in heard.asks:
                    s.peer.post(s.clock.now, key, kept)
                return observed, True
            good_s = self.results.checked_s
            self._state, found = self.registration.again(self._state, "the other arm found the part displaced")
            for key, _ in heard.asks:
                s.peer.post(s.clock.now, key, found)
            if found is not None:
                self._reference_from_alignment()
                self.shared.tell_registered(found, good_s)
                if self._requeue("part_displaced"):
                    observed.append("remeasuring")
        return observed, heard.changes_plan

    def _retake_not_done(self) -> tuple[list[TermValue], bool]:
        """Measure once more, before the run ends, what it left not done after a fault it
        then put right (a retry that met another fault, a tool that was replaced later);
        not what cannot be put right in the cell or Vision cannot measure in its view
        (:func:`_beyond_the_cell`, from the run's diagnoses in the archive: a continued run
        knows them too).  Once per run."""
        if self._retaken:
            return [], False
        self._retaken = True
        beyond = {str(e.payload.get("spec")) for e in self.archive.events(self.run_id, kinds=["diagnosis"])
                  if _beyond_the_cell(e.payload)}
        ids = [r.spec_id for r in self.archive.results(self.run_id)
               if r.outcome is Outcome.NOT_DONE and r.spec_id in self.todo_set and r.spec_id not in beyond]
        if not ids:
            return [], False
        self._requeue(None, ids, "left not done after a fault the run put right: measured once more before it ends")
        return ["remeasuring"], True

    def _requeue(self, cause: str | None, spec_ids: list[str] | None = None,
                 why: str = "measured since the cell's last good interim check, with the arm or the part off: "
                            "measured again", pending_since: float | None = None) -> list[str]:
        """Take what was recorded since the cell's last good check (or `spec_ids`) out of
        the archive (an event keeps it), and what is held pending since then (or since
        `pending_since`), and put those measurements back in the run's sequence plan (at
        every position): the Sequence Planner hands them out again, first in their groups.
        The spec ids put back."""
        since_check = spec_ids is None
        if pending_since is None and since_check:
            pending_since = self.results.checked_s
        # what waits for its network or its webs, measured since then, goes too (its frames
        # were taken with the arm or the part off as well); the event names it
        released = [] if pending_since is None else self.pending.release(pending_since)
        payload: dict[str, Any] = {"cause": cause, "why": why}
        if released:
            payload["released"] = released
        event = Event("remeasure", "top", self.session.clock.now, payload)
        ids = self.results.supersede(event, spec_ids)
        if released and not ids:
            self.archive.record_event(self.run_id, event)
        spec_ids = [*ids, *released]
        gone = set(spec_ids)
        self._cursors = [replace(p, handed_out=tuple(i for i in p.handed_out if i not in gone))
                         for p in self._cursors]
        self._next.clear()
        for spec_id in spec_ids:
            self._handlings.pop(spec_id, None)
        return spec_ids

    def _conclude(self, spec_id: str) -> None:
        """Record the measurement of `spec_id` as it ended (module docstring)."""
        step, out, events, plan_no = self._outcomes.pop(spec_id)
        self._state = out.state
        if out.status is MeasureStatus.CANNOT_BE_DONE:
            self.results.unmeasured(step.spec_id, Outcome.CANNOT_BE_DONE, out.reason or "", tool=step.tool)
            return
        if out.plan is None:
            self.results.unmeasured(step.spec_id, Outcome.NOT_DONE, out.reason or "", tool=step.tool, t0=out.t0,
                                    t1=out.t1)
            return
        extra = measurement_details(self.session, out, plan_no=plan_no, group=step.group)
        self._record(step, out, events, extra)

    def _record(self, step: Step, out: MeasureOutcome, events: list[Event], extra: MeasurementDetails) -> None:
        """Record the step's result (or hold it pending) and those of its view group's
        other members the frame measured."""
        tool = out.tool or step.tool
        mine = Attached(extra.details.get(step.spec_id), extra.frames)
        if out.status is MeasureStatus.MEASURED:
            assert out.value is not None
            self.failures.measured()          # measured, even when its result waits
            if not self.pending.hold(step.spec_id, out.value, tool, out.t0, out.t1, events, mine):
                self.results.record(measured_result(self.session.specs[step.spec_id], out.value, tool=tool,
                                                    t0=out.t0, t1=out.t1), events, mine)
        else:
            self.results.unmeasured(step.spec_id, Outcome.NOT_DONE, out.reason or "", tool=tool, t0=out.t0,
                                    t1=out.t1, events=events, attached=mine)
        for other in out.others:   # the rest of the frame's view group
            if self._skipped(other.spec_id):
                continue
            why = f"from the frame of {step.spec_id}"
            theirs = Attached(extra.details.get(other.spec_id))
            if other.ok and self.pending.hold(other.spec_id, other, tool, out.t0, out.t1, [], theirs, why=why):
                continue
            if other.ok:
                self.results.record(measured_result(self.session.specs[other.spec_id], other, tool=tool,
                                                    t0=out.t0, t1=out.t1, reason=why), [], theirs)
            else:     # not recorded: the Sequence Planner hands it out on its own (its own view, the
                # Exception Handler if that fails too); a frame made for another is no attempt of its own
                self.failed_in_others[other.spec_id] = f"{other.reason or 'not done'} (in the frame of {step.spec_id})"
