"""The cell checks itself: interim checks against its reference artifacts.

    checks = CellChecks.of(session, archive, run_id, plans, handling)   # None: the knowledge sets none
    why = checks.due(since=12)                # None, or what came due (kb/tasks.pl interim_check/1)
    done = checks.check(state)                # CheckDone: passed, found (a diagnosis), or not made

"Reasoning can do little to replace perception when it comes to determining the state of
an environment" (the seed).  An arm that drifts from its calibration or a part that
moves on its fixture raises no exception of its own: a frame taken meanwhile measures
sizes well and puts positions where they are not.  So the Top Level checks the cell
against its reference artifacts with the tool in hand (kb/tasks.pl check_with/3): with an
SLRA, tooling hole B's centre from several frames against where the run's reference
reading saw it (the first check with an SLRA in hand makes that reading: the SLRA is
checked as soon as it is first in hand); with a probe, its reading of the calibration
block.  What a check finds goes to the Exception Handler as the exception check_with/3
names (``position_drift_detected``, ``misaligned``): the diagnosis tells a drifted arm
from a moved part or a crooked probe and puts it right; a recovery with
``remeasure(since_check)`` has what was recorded since the last good check taken out of
the archive (:meth:`ita.toplevel.recording.Recorder.supersede`, an event keeps it) and
measured again.

Cadence (kb/tasks.pl interim_check/1): so many simulated seconds or so many results
since the last good check; and at the run's end (its job's close_run).  Every check is an
``interim_check`` event with what it measured.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

from ita.archive import Event
from ita.devices.injection import paused
from ita.diagnosis.tests import Situation
from ita.logic.terms import Term, Var
from ita.task.measure import MeasureOutcome, MeasureStatus
from ita.toplevel.events import PlanNumbers, diagnosis_events, plan_events

if TYPE_CHECKING:
    from collections.abc import Callable

    from ita.archive import Archive
    from ita.diagnosis.handler import ExceptionHandler, Handled
    from ita.diagnosis.tests import TestBench
    from ita.planning.state import WorldState
    from ita.task.session import Session
    from ita.toplevel.handling import Handling

__all__ = ["CellChecks", "CheckDone"]

#: the knowledge base module of the interim checks' cadence and tests
TASKS = "tasks"
#: the exception of kb/faults.pl a probe check's other outcomes show (the fault of the tool in hand)
_SEEN = {"no_couplant": "no_couplant_film", "doubled": "doubled_thickness", "no_echo": "no_echo",
         "garbage": "corrupt_reply", "silent": "controller_timeout"}


@dataclass(frozen=True)
class CheckDone:
    """An interim check made: `passed` (True: the cell is as its reference reading saw it;
    False: it found something, `handled` is its diagnosis; None: it could not be made),
    the test and its outcome, a note, the arm's state after."""

    passed: bool | None
    test: str
    outcome: str
    note: str
    state: WorldState
    handled: Handled | None = None

    @property
    def remeasure(self) -> bool:
        """Whether its diagnosis's recovery has what was measured since the last good
        check measured again."""
        if self.handled is None:
            return False
        found = [self.handled.diagnosis, *self.handled.nested]
        return any(a.startswith("remeasure(") for d in found for a in d.actions)


class CellChecks:
    """The interim checks of run `run_id` (module doc): `every` is the cadence
    (``seconds``/``measurements`` -> how many), `tests` the check per tool type (test,
    the exception what it finds raises)."""

    def __init__(self, session: Session, archive: Archive, run_id: str, plans: PlanNumbers, handling: Handling,
                 every: dict[str, float], tests: dict[str, tuple[str, str]]) -> None:
        self.session = session
        self.archive = archive
        self.run_id = run_id
        self.plans = plans
        self.handling = handling
        self.every = every
        self.tests = tests
        self.last_s = session.clock.now
        self.count = 0

    @classmethod
    def of(cls, session: Session, archive: Archive, run_id: str, plans: PlanNumbers,
           handling: Handling) -> CellChecks | None:
        """The run's checks as kb/tasks.pl sets them; None when it sets none or the run
        has no Exception Handler (whose test bench makes them)."""
        kb = session.kb
        every: dict[str, float] = {}
        for row in kb.call(TASKS, "interim_check", Var("E")):
            e = row["E"]
            if isinstance(e, Term) and e.name in ("seconds", "measurements") and e.args:
                every[e.name] = float(str(e.args[0]))
        tests = {str(r["T"]): (str(r["Test"]), str(r["F"])) for r in kb.call(TASKS, "check_with", Var("T"),
                                                                               Var("Test"), Var("F"))}
        if not every or handling.handler is None:
            return None
        return cls(session, archive, run_id, plans, handling, every, tests)

    @property
    def bench(self) -> TestBench:
        assert self.handling.handler is not None   # of(): a run without a handler has no checks
        return self.handling.handler.bench

    def _tool_type(self) -> str | None:
        held = self.session.held
        if held is None:
            return None
        tool_class = self.session.ctx.workcell.tool(held).tool_class
        return "us_tool" if tool_class.ultrasonic else tool_class.value

    def due(self, since: int) -> Term | None:
        """What makes a check due now with `since` results recorded since the last good one
        (None: none is)."""
        if since == 0:
            return None
        if self._tool_type() == "slra_tool" and self.bench.baseline is None:
            return Term("first_reference", ("slra_tool",))
        waited = self.session.clock.now - self.last_s
        if "seconds" in self.every and waited >= self.every["seconds"]:
            return Term("seconds", (round(waited),))
        if "measurements" in self.every and since >= self.every["measurements"]:
            return Term("measurements", (since,))
        return None

    def check(self, state: WorldState) -> CheckDone:
        """Check the cell with the tool in hand (module doc); an ``interim_check`` event."""
        s = self.session
        t0 = s.clock.now
        tool = s.held
        kind = self._tool_type()
        test, found = self.tests.get(kind or "", ("", ""))
        self.count += 1
        with paused(s.arm.injector):     # like the Exception Handler's tests, a check meets no new fault
            if tool is None or not test:
                done = CheckDone(None, test or "none", "not_run", f"no check with {tool or 'nothing'} in hand",
                                 state)
            elif test == "measure_reference_feature":
                done = self._reference(tool, found, state)
            else:
                done = self._bench_test(test, tool, found, state)
        if done.passed is not None:
            self.last_s = s.clock.now
        self.archive.record_event(self.run_id, Event("interim_check", "top", s.clock.now, {
            "t0": t0, "tool": tool, "test": done.test, "outcome": done.outcome, "passed": done.passed,
            "note": done.note, "cause": None if done.handled is None else done.handled.diagnosis.cause}))
        return done

    def _reference(self, tool: str, found: str, state: WorldState) -> CheckDone:
        bench = self.bench
        spec_id = bench.reference_spec
        if spec_id is None:
            return CheckDone(None, "measure_reference_feature", "not_run", "the part has no reference feature", state)
        out = bench.reference_reading(spec_id, state, tool)
        self._events(out, "interim check")
        centre = bench.reference_centre(out)
        if centre is None and out.report is not None and out.report.failure is not None:
            # the reference itself failed (a drifted arm's window misses it): diagnosed like any failure
            handled = self._paused(lambda h: h.handle(out))
            if handled is not None:
                self.archive.record_events(self.run_id, diagnosis_events(handled, self.plans))
                return CheckDone(False, "measure_reference_feature", "failed", out.reason or "", handled.outcome.state,
                                 handled)
        if centre is None:
            return CheckDone(None, "measure_reference_feature", "unclear", out.reason or "not measured", out.state)
        outcome, note = bench.reference_outcome(out)
        if outcome == "ok":
            if bench.baseline is None:
                bench.baseline = centre
                note = f"the reference reading: {spec_id}'s centre at ({centre[0]:.3f}, {centre[1]:.3f}) mm"
            return CheckDone(True, "measure_reference_feature", outcome, note, out.state)
        return self._found(found, out, tool, "measure_reference_feature", outcome, note)

    def _bench_test(self, test: str, tool: str, found: str, state: WorldState) -> CheckDone:
        s = self.session
        tool_class = s.ctx.workcell.tool(tool).tool_class.value
        situation = Situation("", tool, tool_class, "", state)
        run = self.bench.run(test, situation)
        if run.plan is not None and run.report is not None:
            self.archive.record_events(self.run_id, plan_events(run.plan, run.report, None, "interim check",
                                                                self.plans.next(), tool=tool))
        if run.outcome == "ok":
            return CheckDone(True, test, "ok", run.note, run.state)
        # what the check found: a drift (check_with/3), or a fault of the tool in hand met on the
        # way (a dry dispenser, a worn probe): each is diagnosed as the exception it would be
        exception = found if run.outcome in ("misaligned", "displaced") else _SEEN.get(run.outcome)
        if exception is None:
            return CheckDone(None, test, run.outcome, run.note, run.state)
        out = MeasureOutcome("", tool, MeasureStatus.NOT_DONE, None, run.note, (), run.plan, run.report,
                             run.state, run.t0, run.t1)
        return self._found(exception, out, tool, test, run.outcome, run.note)

    def _found(self, exception: str, out: MeasureOutcome, tool: str, test: str, outcome: str,
               note: str) -> CheckDone:
        """The Exception Handler on what the check found."""
        handled = self._paused(lambda h: h.handle_found(exception, out, tool,
                                                        f"interim check {test}: {outcome} ({note})"))
        assert handled is not None   # handle_found always answers
        self.archive.record_events(self.run_id, diagnosis_events(handled, self.plans))
        return CheckDone(False, test, outcome, note, handled.outcome.state, handled)

    def _paused(self, call: Callable[[ExceptionHandler], Handled | None]) -> Handled | None:
        """`call` on the Exception Handler with fault injection paused (its tests and
        repairs meet no new fault)."""
        handler = self.handling.handler
        assert handler is not None   # of(): a run without a handler has no checks
        with paused(self.session.arm.injector):
            return call(handler)

    def _events(self, out: MeasureOutcome, label: str) -> None:
        if out.plan is not None and out.report is not None:
            self.archive.record_events(self.run_id, plan_events(out.plan, out.report, None, label,
                                                                self.plans.next(), tool=out.tool))
