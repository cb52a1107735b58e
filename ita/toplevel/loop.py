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
archive the moment it exists, with the plan's events, in one transaction
(:mod:`ita.toplevel.recording`).  An exception reply or a time-out: the Exception Handler
(:mod:`ita.toplevel.handling`) diagnoses it, puts the cell right and measures again; a
measurement still not done is recorded so with the reason, the world state is taken from
the steps that did complete, the arm is freed if it is stuck, and the loop goes on.  A
measurement the Geometric Reasoner could not place, or that the Sequence Planner put in
its cannot-be-done group, is recorded cannot-be-done.  A probe reads the calibration
block before its first reading (:mod:`ita.toplevel.calibration`).

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

Between measurements the loop obeys INTERRUPT (leave after the current plan, status
INTERRUPTED) and STOP (raised at once as StopNow, status STOPPED), from Ctrl-C or from
the archive's control table (`ita monitor`); so many measurements not done in a row
stop it with an alarm.  A run is continued (`ita continue`) by skipping every spec the
archive has a result for: nothing is measured twice, nothing is lost.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import replace
from typing import TYPE_CHECKING

from ita.archive import Outcome, RunStatus
from ita.archive.timeline import breakdown, intervals, span
from ita.planning.state import WorldState
from ita.sequence.next_step import Step, next_step, the_arm
from ita.task.measure import MeasureOutcome, MeasureStatus, measure_one
from ita.toplevel.calibration import ProbeCalibration
from ita.toplevel.details import MeasurementDetails, measurement_details
from ita.toplevel.events import (
    PlanNumbers,
    diagnosis_events,
    measurement_events,
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
from ita.toplevel.signals import RunSignals, StopNow
from ita.toplevel.start import start_run

if TYPE_CHECKING:
    from ita.archive import Archive, Event
    from ita.task.session import Session

__all__ = ["MAX_FAILURES_IN_A_ROW", "Progress", "RunSummary", "TopLevel", "start_run"]


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
        self.handle = Handling.of(session, archive, run_id) if handle_exceptions else Handling(session, None)
        self.failed_in_others: dict[str, str] = {}   # view-group members another's frame could not measure
        self.exceptions = 0
        self.frames = 0
        self.diagnoses = 0

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
        plan = replace(s.plan, handed_out=tuple(i for g in s.plan.groups for i in g.order if self._skipped(i)))
        state = WorldState(arm=the_arm(s.kb))
        status = RunStatus.COMPLETED
        alarm = ""
        current: Step | None = None
        try:
            for spec_id, reason in s.plan.cannot:
                if spec_id in self.todo_set and spec_id not in self.results.done:
                    self.results.unmeasured(spec_id, Outcome.CANNOT_BE_DONE, reason)
            while True:
                self.signals.poll(self.archive, self.run_id)
                if self.signals.interrupt:
                    status = RunStatus.INTERRUPTED
                    break
                result = next_step(s.ctx, plan)
                plan = result.plan
                if result.resequenced:
                    self.archive.record_event(self.run_id, sequence_event(result.reason, plan, s.clock.now))
                step = result.step
                if step is None:
                    break
                if self._skipped(step.spec_id):
                    continue
                current = step
                state = self._measure(step, state)
                self.pending.settle()
                if on_progress is not None:
                    on_progress(self._progress(started, current, "measuring"))
                alarm = self.failures.alarm
                if alarm:
                    status = RunStatus.STOPPED
                    break
        except StopNow:
            status = RunStatus.STOPPED
        end_t = max(s.clock.now, s.executive.settled())     # the last trailing Vision reply too
        if status is RunStatus.COMPLETED:
            self._finish()
        done, total = len(self.results.done), len(self.todo)
        self.archive.set_status(self.run_id, status, event=run_end_event(
            status, end_t, reason=alarm or self.signals.reason or None, done=done, total=total))
        counts = dict(self.results.counts)
        self.archive.update_totals(self.run_id, specs=total, done=done, sim_time_s=end_t, counts=counts)
        summary = RunSummary(
            self.run_id, status.value, done, total, counts, started.sim_s, end_t,
            time.perf_counter() - started.wall_s, self.results.recorded_now, self.exceptions, self.frames,
            breakdown=self.breakdown(),
            devices={**{f"arm_{k}": v for k, v in s.arm.stats.items()},
                     **{f"slra_{k}": v for k, v in s.slra.stats.items()},
                     "path_planning_wall_s": s.arm.planning_seconds},
            continue_hint=None if status is RunStatus.COMPLETED else f"ita continue {self.run_id}", alarm=alarm)
        if on_progress is not None:
            on_progress(self._progress(started, current, status.value))
        return summary

    def _finish(self) -> None:
        """A completed run: decide everything pending; what the Sequence Planner no longer
        hands out is recorded not done (a view group's frame could not measure it) or
        cannot be done."""
        self.pending.settle(final=True)
        for spec_id in [i for i in self.todo if i not in self.results.done and not self.pending.waiting(i)]:
            if spec_id in self.failed_in_others:
                self.results.unmeasured(spec_id, Outcome.NOT_DONE, self.failed_in_others[spec_id])
            else:
                self.results.unmeasured(spec_id, Outcome.CANNOT_BE_DONE, "not handed out by the sequence planner")

    def breakdown(self) -> dict[str, float]:
        """The run's cycle-time breakdown from its recorded events (ita.archive.timeline)."""
        events = self.archive.events(self.run_id)
        start, end = span(events)
        return breakdown(intervals(events, end), start, end)

    def _progress(self, started: Started, step: Step | None, status: str) -> Progress:
        return progress(self.run_id, started, done=len(self.results.done), total=len(self.todo), step=step,
                        status=status, sim_s=self.session.clock.now, exceptions=self.exceptions,
                        counts=self.results.counts)

    # -- one step ------------------------------------------------------------------------------
    def _measure(self, step: Step, state: WorldState) -> WorldState:
        """Measure one step (and its view group's other members) and record it; a failure
        goes to the Exception Handler, which diagnoses it, puts the cell right and takes
        the measurement again.  The new state."""
        state = self.calibration.before(step.spec_id, step.tool, state)
        out = measure_one(self.session, step.spec_id, state, step.tool)
        if out.status is MeasureStatus.CANNOT_BE_DONE:
            self.results.unmeasured(step.spec_id, Outcome.CANNOT_BE_DONE, out.reason or "", tool=step.tool)
            return out.state
        if out.plan is None:
            self.results.unmeasured(step.spec_id, Outcome.NOT_DONE, out.reason or "", tool=step.tool, t0=out.t0,
                                    t1=out.t1)
            return out.state
        plan_no = self.plans.next()
        events = measurement_events(out, step.group, plan_no)
        if any(e.kind == "command" and e.payload.get("name") == "scan" for e in events):
            self.frames += 1
        if out.status is not MeasureStatus.MEASURED and out.report is not None and not out.report.ok:
            self.exceptions += 1
            handled = self.handle(out)
            if handled is not None:
                self.diagnoses += 1
                events += diagnosis_events(handled, self.plans)
                if handled.outcome.report is not None:
                    plan_no = self.plans.last
                out = replace(handled.outcome, others=out.others + handled.outcome.others)
        extra = measurement_details(self.session, out, plan_no=plan_no, group=step.group)
        self._record(step, out, events, extra)
        return out.state

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
