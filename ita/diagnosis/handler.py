"""The Exception Handler: diagnose a failed measurement, put the world right, recover.

    handler = ExceptionHandler(session, neighbours=...)
    handled = handler.handle(outcome)            # outcome: a failed MeasureOutcome
    handled.diagnosis                            # exception, posterior, tests, cause, actions
    handled.outcome                              # the measurement after recovery (or not done, and why)
    handled.executed                             # every plan run for it, for the archive

The seed: "The Exception Handler is responsible for diagnosing the cause of the
exception, updating the world model to correspond to the current state of the world,
and generating a recovery plan."  So, in order:

1. the failure becomes an exception of kb/faults.pl with its context (classify);
2. the engine (prolog/diagnosis.pl) gives the posterior over its causes from the stated
   priors and the counts learned across runs, and the first test of the decision tree
   over the tests the cell can make now, each priced with the set-up it needs from the
   arm's state; the test is made in the cell (ita.diagnosis.tests); its outcome narrows
   the causes; again, until one cause is isolated or no test separates the rest;
3. the counts are updated (ita.diagnosis.counts);
4. the world model is updated and the cell put right by the cause's recovery actions,
   as kb/faults.pl recovery/2 names them; the handler knows their kinds, not the
   recoveries: a world-model change (a tool marked, so the Sequence Planner resequences
   to its spare), a goal of kb/operators.pl that the Operation Planner plans from the
   arm's state and the Plan Executive runs on the devices (the cell's refill, purge,
   reset, reseat, recalibrate, clean; a person called to the cell, a device of its own
   whose answer the simulator gives: an obstacle removed, a tool replaced from the
   stores; the run waits), the same actions only when a condition of the world model
   does not hold (no spare left), a value accepted (a bad part, not a bad instrument;
   a second view);
5. the measurement is taken again: with the same tool by *plan repair* (the steps of
   the failed plan that did not run, after a plan for the first one's preconditions:
   ``macrop:repair_plan/6``), else with the tool the rules choose now by *replanning*
   (the Operation Planner from the current state to the original goal, MACROP lookup
   first).  A retry during the tests that measured it ends the matter.  When no tool is
   left, or the cause cannot be put right in the cell, the measurement is not done and
   the diagnosis is its reason.

What the cell's interim check against its reference artifacts finds (tooling hole B not
where the run's reference reading saw it, a probe's block reading that walks off) is no
failed measurement but is diagnosed the same way (:meth:`ExceptionHandler.handle_found`:
steps 1 to 4, nothing to take again); a recovery's ``remeasure(since_check)`` tells the
Top Level to measure again what it measured since its last good check.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from types import SimpleNamespace
from typing import TYPE_CHECKING

from ita.devices.data import MeasuredValue, measured_values
from ita.diagnosis.classify import Classified, classify
from ita.diagnosis.counts import FaultCounts
from ita.diagnosis.knowledge import DiagnosisStep, FaultKnowledge
from ita.diagnosis.tests import Situation, TestBench, TestRun
from ita.logic.json_value import JsonObject
from ita.logic.terms import Term, TermValue, Var
from ita.logic.world import WorldModel
from ita.planning import NoPlanError, OperationPlan
from ita.sensors.ultrasonic import Reading
from ita.sequence.plan import choose_tool
from ita.task.align import register_part, registered_by_peer
from ita.task.measure import (
    MeasureOutcome,
    MeasureStatus,
    execute_measurement,
    placement_problem,
)

if TYPE_CHECKING:
    from ita.executive import ExecutionReport
    from ita.planning.state import WorldState
    from ita.task.session import Session

__all__ = ["Diagnosis", "ExceptionHandler", "Handled"]

#: the most tests one diagnosis makes
MAX_TESTS = 6

#: a plan run for a diagnosis: its label, the plan and its execution report
Executed = list[tuple[str, OperationPlan, "ExecutionReport | None"]]


def term_text(value: TermValue) -> str:
    """A term of the knowledge base as text, ``name(arg, ...)``; a variable (one the
    Operation Planner binds) as ``_``."""
    if isinstance(value, Var):
        return "_"
    if isinstance(value, Term):
        return f"{value.name}({', '.join(term_text(a) for a in value.args)})"
    if isinstance(value, list):
        return "[" + ", ".join(term_text(a) for a in value) + "]"
    return str(value)


def _kind(action: TermValue) -> tuple[str, tuple[TermValue, ...]]:
    """A recovery action's kind and arguments: ``achieve(G)`` -> ("achieve", (G,))."""
    return (action.name, tuple(action.args)) if isinstance(action, Term) else (str(action), ())


@dataclass(frozen=True)
class _PutRight:
    """What a recovery's actions did: the lines of the world updates and repairs, the
    situation after, the measurement a value accepted makes (with the action's text), and
    whether every action was made (a goal that could not be achieved stops the rest)."""

    updates: tuple[str, ...]
    situation: Situation
    accepted: tuple[MeasureOutcome, str] | None = None
    complete: bool = True


@dataclass(frozen=True)
class Diagnosis:
    """What the Exception Handler found and did for one failed measurement."""

    spec_id: str
    exception: str
    context: tuple[tuple[str, str], ...]
    reply: str
    posterior: tuple[tuple[str, float], ...]
    expected_s: float
    tests: tuple[TestRun, ...]
    cause: str | None
    remaining: tuple[tuple[str, float], ...]
    actions: tuple[str, ...]
    updates: tuple[str, ...]
    recovery: str
    t0: float
    t1: float
    since: float = 0.0          # when the plan that failed began (the fault was on at some time since)
    #: why this arm cannot go on measuring ("": it can): the part displaced and no arm able
    #: to register it now (one arm of a two-arm run; its run stops, the other takes its work)
    halt: str = ""

    @property
    def summary(self) -> str:
        """One line: the exception, what the tests found, what was done."""
        found = f"cause {self.cause}" if self.cause else \
            "unresolved: " + ", ".join(c for c, _ in self.remaining) if self.remaining else "no cause"
        tests = "; ".join(f"{t.test} -> {t.outcome}" for t in self.tests) or "no test"
        return f"{self.exception}: {tests}; {found}; {self.recovery}"

    def to_dict(self) -> JsonObject:
        return {"spec": self.spec_id, "exception": self.exception, "context": dict(self.context),
                "reply": self.reply, "posterior": [[c, round(p, 4)] for c, p in self.posterior],
                "expected_s": round(self.expected_s, 2), "tests": [t.to_dict() for t in self.tests],
                "cause": self.cause, "remaining": [[c, round(p, 4)] for c, p in self.remaining],
                "actions": list(self.actions), "updates": list(self.updates), "recovery": self.recovery,
                "t0": self.t0, "t1": self.t1, "since": self.since, **({"halt": self.halt} if self.halt else {})}


#: how a diagnosis's recovery starts when the retry it made failed
RETRY_FAILED = "the retry failed:"


@dataclass(frozen=True, eq=False)
class Handled:
    """The Exception Handler's answer: the diagnosis, the measurement's outcome after it,
    every plan it ran (label, plan, execution report), in order, and the diagnoses of
    second faults met on the way (a controller that stops answering during a test)."""

    diagnosis: Diagnosis
    outcome: MeasureOutcome
    executed: tuple[tuple[str, OperationPlan, ExecutionReport | None], ...] = field(default_factory=tuple)
    nested: tuple[Diagnosis, ...] = ()          # second faults met while handling, each diagnosed on its own

    @property
    def retry_failed(self) -> bool:
        """The recovery's own retry ran and ended in an exception: a new failure, for the
        Exception Handler again (the outcome carries its report)."""
        return self.diagnosis.recovery.startswith(RETRY_FAILED)


class ExceptionHandler:
    """Diagnoses and recovers failed measurements of a session (module docstring).

    neighbours: spec id -> values of its measured neighbours (for compare_neighbours);
    method: the engine's test selection (``auto``, ``optimal``, ``rollout``, ``greedy``,
    ``cheapest``); learn: whether diagnoses add to the stored counts; prepare_tool:
    (spec id, tool, state) -> state, called before a retry takes the measurement with
    another tool than the one that failed (the Top Level has a spare probe read the
    calibration block before its first reading)."""

    def __init__(self, session: Session, *, neighbours: Callable[[str], Sequence[float]] | None = None,
                 method: str = "auto", learn: bool = True,
                 prepare_tool: Callable[[str, str, WorldState], WorldState] | None = None) -> None:
        self.session = session
        self.prepare_tool = prepare_tool
        self.knowledge = FaultKnowledge(session.kb)
        #: in the recovery being made: the other arm of a two-arm run could not register the part
        self._no_registration = False
        #: when the failure (or the check's reading) being handled was seen: the cell was so then
        self._evidence_s = 0.0
        self.method = method
        self.learn = learn
        tests = self.knowledge.tests()
        self.bench = TestBench(session, neighbours, {name: info.seconds for name, info in tests.items()},
                               {name: info.needs for name, info in tests.items()})

    # -- the whole of it --------------------------------------------------------------------
    def handle(self, failed: MeasureOutcome) -> Handled | None:
        """Diagnose and recover a failed measurement (its report failed with an exception
        reply or a time-out); None when it did not fail so, or the knowledge base has no
        word for its exception."""
        s = self.session
        tool = failed.tool
        if tool is None:
            return None
        tool_class = s.ctx.workcell.tool(tool).tool_class.value
        exc = classify(failed, held=s.held, tool=tool, tool_class=tool_class)
        if exc is None:
            return None
        situation = Situation(failed.spec_id, tool, tool_class, exc.exception, failed.state, failed.value,
                              dict(exc.context).get("device", ""))
        executed: Executed = []
        nested: list[Diagnosis] = []
        self._evidence_s = failed.t1
        diagnosis, situation, outcome = self._diagnose_and_act(exc, situation, failed.t1, executed, nested, 0)
        diagnosis = replace(diagnosis, since=failed.t0)
        if outcome is None and diagnosis.cause is not None and not diagnosis.actions:
            diagnosis = replace(diagnosis, recovery=f"not done: {diagnosis.cause} cannot be put right in the cell")
        elif outcome is None:
            outcome, recovery = self._retry(failed, situation, executed)
            if outcome is not None and outcome.report is not None and not outcome.report.ok:
                # the retry met a failure of its own: the recovery did not succeed, say so
                recovery = f"{RETRY_FAILED} {recovery}: {outcome.reason or 'failed'}"
            diagnosis = replace(diagnosis, recovery=recovery, t1=s.clock.now)
        if outcome is None or outcome.status is not MeasureStatus.MEASURED:
            base = outcome if outcome is not None else failed
            reason = f"{failed.reason}; diagnosis: {diagnosis.summary}"
            outcome = replace(base, status=MeasureStatus.NOT_DONE, reason=reason, t0=failed.t0,
                              t1=s.clock.now)
        else:
            outcome = replace(outcome, t0=failed.t0)
        return Handled(diagnosis, outcome, tuple(executed), tuple(nested))

    def handle_found(self, exception: str, found: MeasureOutcome, tool: str, reply: str) -> Handled:
        """Diagnose and put right what an interim check found: `exception` of kb/faults.pl
        (``position_drift_detected``, ``misaligned``), seen in the check's reading `found`
        made with `tool`; `reply` says what was seen.  Nothing is taken again: the
        outcome is the check's reading."""
        s = self.session
        tool_class = s.ctx.workcell.tool(tool).tool_class.value
        key = "slra" if tool_class == "slra_tool" else "probe"
        device = "controller" if exception == "controller_timeout" else tool if key == "slra" else "gauge"
        exc = Classified(exception, ((key, tool), ("device", device), ("tool", tool)), reply)
        situation = Situation(found.spec_id, tool, tool_class, exception, found.state, None, device)
        executed: Executed = []
        nested: list[Diagnosis] = []
        self._evidence_s = found.t1
        diagnosis, situation, _ = self._diagnose_and_act(exc, situation, found.t1, executed, nested, 0)
        put_right = diagnosis.cause is not None and bool(diagnosis.actions) \
            and not any(u.startswith("not achieved") for u in diagnosis.updates)
        diagnosis = replace(diagnosis, since=found.t0,
                            recovery="put right" if put_right else
                            "not put right" if diagnosis.cause is not None else "no cause isolated")
        return Handled(diagnosis, replace(found, state=situation.state, t1=s.clock.now), tuple(executed),
                       tuple(nested))

    def _diagnose_and_act(self, exc: Classified, situation: Situation, t0: float, executed: Executed,
                          nested: list[Diagnosis], depth: int) -> tuple[Diagnosis, Situation, MeasureOutcome | None]:
        """Steps 2 to 4 for one exception: its tests, the counts, the world updates and
        the cell put right; the diagnosis (recovery said only when the tests or an
        accepted reading measured it), the situation after, and the measurement if done."""
        runs, first, last = self._diagnose(exc, situation, executed, nested, depth)
        situation = replace(situation, state=runs[-1].state if runs else situation.state)
        cause = last.choice[1] if last.choice[0] == "isolated" else None
        if self.learn:
            FaultCounts.record(exc.exception, None if cause is None else self.knowledge.cause_name(cause))
        retried = next((r.measured for r in runs if r.measured is not None), None)
        actions: list[TermValue] = []
        updates: tuple[str, ...] = ()
        outcome: MeasureOutcome | None = retried
        halt = ""
        recovery = "the retry during the tests measured it" if retried is not None else ""
        if retried is None and cause is not None:
            actions = self.knowledge.recovery(cause)
            self._no_registration = False
            done = self._put_right(actions, situation, runs, executed, nested, depth)
            updates, situation = done.updates, done.situation
            if self._no_registration and not done.complete:
                halt = ("the part is displaced and the arm that registers it cannot now (done with its "
                        "share, or waiting itself): this arm stops, its work left goes to the other")
            if done.accepted is not None:
                outcome, how = done.accepted
                recovery = f"accepted: {how}"
        diagnosis = Diagnosis(situation.spec_id, exc.exception, exc.context, exc.reply, first.posterior,
                              first.expected_s, tuple(runs), cause, last.remaining,
                              tuple(term_text(a) for a in actions), updates, recovery, t0, self.session.clock.now,
                              halt=halt)
        return diagnosis, situation, outcome

    def _second_fault(self, report: ExecutionReport | None, situation: Situation, depth: int) -> Classified | None:
        """A fault of another device met by a test or a repair (a controller that stops
        answering while a window is being cleaned): its exception, when there is one to
        handle on its own (one level deep), else None."""
        if depth > 0 or report is None or report.failure is None:
            return None
        s = self.session
        probe = SimpleNamespace(report=report)
        exc = classify(probe, held=s.held, tool=situation.tool, tool_class=situation.tool_class)
        if exc is None:
            return None
        device = dict(exc.context).get("device", "")
        if device == situation.device or exc.exception == situation.exception:
            return None
        return exc

    def _handle_second(self, exc: Classified, situation: Situation, since: float, executed: Executed,
                       nested: list[Diagnosis], depth: int) -> Situation:
        """Diagnose and put right a second fault met during the handling (it is recorded
        as a diagnosis of its own); the situation after."""
        inner = replace(situation, exception=exc.exception, device=dict(exc.context).get("device", ""), reading=None)
        diagnosis, inner, _ = self._diagnose_and_act(exc, inner, self.session.clock.now, executed, nested,
                                                     depth + 1)
        recovery = "put right; the handling of the first exception goes on" if diagnosis.cause else \
            "not put right; the handling of the first exception goes on"
        nested.append(replace(diagnosis, recovery=recovery, since=since))
        return replace(situation, state=inner.state)

    # -- 2. the tests -----------------------------------------------------------------------
    def _diagnose(self, exc: Classified, situation: Situation, executed: Executed, nested: list[Diagnosis], depth: int
                  ) -> tuple[list[TestRun], DiagnosisStep, DiagnosisStep]:
        counts = FaultCounts.load().causes
        context = exc.context_terms()
        results: list[tuple[str, str]] = []
        runs: list[TestRun] = []
        tried: set[str] = set()
        first = last = None
        for _ in range(MAX_TESTS + 1):
            tests = []
            for name in self.knowledge.tests():
                if name in tried:
                    continue
                cost = self.bench.cost(name, situation)
                if cost is not None and cost < float("inf"):
                    tests.append((name, cost))
            last = self.knowledge.step(exc.exception, context, counts, results, tests, self.method)
            first = first or last
            if last.choice[0] != "test" or len(runs) >= MAX_TESTS:
                break
            name = last.choice[1]
            tried.add(name)
            run = self.bench.run(name, situation, dict(tests)[name])
            if run.plan is not None:
                executed.append((f"test {name}", run.plan, run.report))
            # a failure the test reads as its outcome (a probe's block reading that walks off) is
            # what the test observes, not a second fault
            read = run.outcome not in ("ok", "not_run", "silent", "bump")
            second = None if read else self._second_fault(run.report, situation, depth)
            if second is not None:          # the test met another fault: put it right, make the test again
                runs.append(replace(run, outcome="interrupted", note=f"by {second.exception}: {run.note}"))
                situation = self._handle_second(second, replace(situation, state=run.state), run.t0, executed,
                                                nested, depth)
                run = self.bench.run(name, situation, dict(tests)[name])
                if run.plan is not None:
                    executed.append((f"test {name} again", run.plan, run.report))
            if run.outcome not in ("ok", "not_run", "silent", "bump") \
                    and self.knowledge.shows_a_fault(name, run.outcome) \
                    and not self.knowledge.predicts_any(name, run.outcome, [c for c, _ in last.remaining], context):
                # the outcome shows another fault (an empty couplant station while the controller
                # is diagnosed): none of these causes; for them the test ran and answered
                run = replace(run, outcome="ok", note=f"{run.note}; {run.outcome}: another fault, not one of these"
                              .lstrip("; "))
            runs.append(replace(run, posterior=last.posterior))       # the node the test was chosen at
            situation = replace(situation, state=run.state)
            if run.outcome != "not_run":
                results.append((name, run.outcome))
            if run.measured is not None:   # the retry measured it: what the results say, no more tests
                last = self.knowledge.step(exc.exception, context, counts, results, [], self.method)
                break
        assert first is not None and last is not None  # the loop asks the engine at least once
        return runs, first, last

    # -- 4. the world and the cell put right --------------------------------------------------
    def _put_right(self, actions: Sequence[TermValue], situation: Situation, runs: list[TestRun], executed: Executed,
                   nested: list[Diagnosis], depth: int) -> _PutRight:
        """Make a recovery's actions in order (kb/faults.pl recovery/2 says what each kind
        means); a goal that cannot be achieved stops the actions after it."""
        updates: list[str] = []
        accepted: tuple[MeasureOutcome, str] | None = None
        for action in actions:
            kind, args = _kind(action)
            if kind == "world":                 # the world model changes
                self.knowledge.update_world(args[0])
                updates.append(f"world: {term_text(args[0])}")
            elif kind == "achieve":             # planned from the arm's state, run on the devices
                line, situation, ok = self._achieve(args[0], situation, executed, nested, depth)
                updates.append(line)
                if not ok:
                    return _PutRight(tuple(updates), situation, accepted, False)
            elif kind == "unless":              # the actions only when the condition does not hold now
                if self.knowledge.holds_now(args[0]):
                    continue
                assert isinstance(args[1], list)  # unless(Condition, Actions): a list of actions
                inner = self._put_right(list(args[1]), situation, runs, executed, nested, depth)
                updates += inner.updates
                situation, accepted = inner.situation, inner.accepted or accepted
                if not inner.complete:
                    return _PutRight(tuple(updates), situation, accepted, False)
            elif kind == "accept":              # a value stands: the failed reading, or a test's
                line, value = self._accept(args[0], situation, runs)
                updates.append(line)
                if value is not None:
                    accepted = (value, term_text(action))
            elif kind == "first_of":            # the first list of actions carried out to its end
                assert args and isinstance(args[0], list)  # first_of(Alternatives): a list of lists
                tried: list[str] = []
                for alternative in args[0]:
                    assert isinstance(alternative, list)
                    if self._no_registration and any(_kind(a)[0] == "register" for a in alternative):
                        # the other arm cannot register the part now: a way that ends in a
                        # registration (a person re-clamping the part first) cannot end
                        tried.append(f"not tried: {'; '.join(term_text(a) for a in alternative)} "
                                     "(no registration to be had)")
                        continue
                    inner = self._put_right(list(alternative), situation, runs, executed, nested, depth)
                    tried += inner.updates
                    situation, accepted = inner.situation, inner.accepted or accepted
                    if inner.complete:
                        break
                else:
                    return _PutRight(tuple(updates + tried), situation, accepted, False)
                updates += tried
            elif kind == "register":            # the part located on its datums again
                line, situation, ok = self._register(situation, executed)
                updates.append(line)
                if not ok:
                    return _PutRight(tuple(updates), situation, accepted, False)
            elif kind == "remeasure":           # the Top Level measures again what is held since its check
                updates.append("the measurements since the cell's last good check to be measured again")
            # retry: nothing to put right; the measurement is taken again (step 5)
        return _PutRight(tuple(updates), situation, accepted)

    def _register(self, situation: Situation, executed: Executed) -> tuple[str, Situation, bool]:
        """Register the part on its datums again with a working SLRA (ita.task.align); the
        line for the record, the situation after, whether it was registered.  One arm of a
        two-arm run that does not register the part asks the other arm to
        (ita.task.align.registered_by_peer): both see the one part."""
        s = self.session
        if s.peer is not None and not s.registers:
            found, waited = registered_by_peer(s, "the other arm found the part displaced", self._evidence_s)
            if found is None:
                self._no_registration = True
                return "not registered: the other arm made no registration (done, or waiting itself)", situation, False
            return (f"registered again by the other arm (waited {waited:.1f} s): {found.line()}", situation, True)
        tool = self.bench.slra_for(situation)
        if tool is None:
            return "not registered: no working slra_tool", situation, False
        done = register_part(self.session, situation.state, tool)
        executed += [(f"register the part: {out.spec_id}", out.plan, out.report) for out in done.outcomes
                     if out.plan is not None]
        situation = replace(situation, state=done.state)
        if done.alignment is None:
            return f"not registered: {done.reason}", situation, False
        self.session.alignment = done.alignment
        return f"registered again (moved {done.moved_mm:.3f} mm): {done.alignment.line()}", situation, True

    def _achieve(self, goal: TermValue, situation: Situation, executed: Executed, nested: list[Diagnosis],
                 depth: int) -> tuple[str, Situation, bool]:
        """Plan `goal` from the arm's state (the Operation Planner, kb/operators.pl) and run
        the plan (the Plan Executive, on whichever devices its steps name: the arm, the SLRA,
        a person); a second fault that stops it is put right on its own and the plan made
        again.  The line for the record, the situation after, and whether it was achieved."""
        label = term_text(goal)
        plan, report, state, note = self.bench.execute_goals([goal], situation.state, name=label)
        if plan is not None:
            executed.append((f"repair {label}", plan, report))
        second = self._second_fault(report, situation, depth)
        if second is not None:          # another fault stopped it: put that right, then again
            assert report is not None   # a second fault is one of a report's
            situation = self._handle_second(second, replace(situation, state=state), report.started_s, executed,
                                            nested, depth)
            plan, report, state, note = self.bench.execute_goals([goal], situation.state, name=label)
            if plan is not None:
                executed.append((f"repair {label} again", plan, report))
        situation = replace(situation, state=state)
        if plan is None or report is None:
            return f"not achieved {label}: {note}", situation, False
        if report.failure is not None:
            return f"not achieved {label}: {note or report.failure.reason}", situation, False
        said = [o.reply.text for o in report.outcomes if o.reply.text]
        steps = ", ".join(st.text for st in plan.steps)
        return f"achieved {label}: {steps}" + (f" ({'; '.join(said)})" if said else ""), situation, True

    def _accept(self, what: TermValue, situation: Situation, runs: list[TestRun]) -> tuple[str, MeasureOutcome | None]:
        """The value an ``accept(What)`` recovery lets stand: the failed reading
        (``reading``), or the value a test made measured (``test(Test)``)."""
        s = self.session
        kind, args = _kind(what)
        if kind == "reading":
            reading = situation.reading
            raw = getattr(reading.source, "thickness_mm", None) if reading is not None else None
            if reading is None or raw is None:
                return "no reading to accept", None
            assert isinstance(reading.source, Reading)  # of the sources, only a gauge Reading has a thickness
            value = MeasuredValue(situation.spec_id, float(raw), float(reading.source.u_mm), source=reading.source)
            return f"reading {raw:.3f} accepted", MeasureOutcome(
                situation.spec_id, situation.tool, MeasureStatus.MEASURED, value, None, (), None, None,
                situation.state, s.clock.now, s.clock.now)
        test = str(args[0]) if kind == "test" and args else term_text(what)
        for run in runs:
            if run.test == test and run.report is not None and run.report.ok:
                found = measured_values(run.report).get(situation.spec_id)
                if found is not None and found.ok:
                    return f"the value of {test} accepted", MeasureOutcome(
                        situation.spec_id, situation.tool, MeasureStatus.MEASURED, found, None, (), run.plan,
                        run.report, run.state, run.t0, run.t1)
        return f"no value of {test} to accept", None

    # -- 5. the measurement again -------------------------------------------------------------
    def _retry(self, failed: MeasureOutcome, situation: Situation, executed: Executed
               ) -> tuple[MeasureOutcome | None, str]:
        """Take the measurement again with the same tool when it is usable, else with the
        tool the rules choose now (none: not done): by plan repair or by replanning, as
        kb/faults.pl recovery_way/3 says from the two plans' lengths."""
        s = self.session
        arm = situation.state.arm
        tool = situation.tool
        if not WorldModel(s.kb).is_usable(arm, situation.tool_class, tool):
            chosen = choose_tool(s.ctx, situation.spec_id)
            if chosen.tool is None:
                return None, f"not done: no tool left ({chosen.reason})"
            tool = chosen.tool
        if tool != situation.tool and self.prepare_tool is not None:
            situation = replace(situation, state=self.prepare_tool(situation.spec_id, tool, situation.state))
        repaired = None
        done: tuple[int, ...] = ()
        if tool == situation.tool and failed.plan is not None and failed.report is not None:
            done = tuple(failed.report.failure.completed) if failed.report.failure is not None else ()
            repaired = s.planner.repair_plan(failed.plan, done, situation.state)
        replanned, why = None, ""
        problem = placement_problem(s, situation.spec_id, tool)
        if problem is not None:
            why = problem
        else:
            try:
                replanned = s.planner.plan_measurement(s.specs[situation.spec_id], situation.state, tool)
            except NoPlanError as exc:
                why = f"no plan: {exc.reason}"
        answer = s.kb.once("faults", "recovery_way", _steps(repaired), _steps(replanned), Var("W"))
        way = str(answer["W"]) if answer else "none"
        if way == "repair" and repaired is not None and failed.plan is not None:
            out = execute_measurement(s, situation.spec_id, tool, repaired)
            executed.append(("recovery: plan repair", repaired, out.report))
            kept = sum(1 for st in failed.plan.steps if st.number not in set(done))
            also = f"; a new plan: {len(replanned.steps)}" if replanned is not None else ""
            return out, f"plan repair ({len(repaired.steps)} steps, {kept} of the failed plan's kept{also})"
        if way == "replan" and replanned is not None:
            out = execute_measurement(s, situation.spec_id, tool, replanned)
            executed.append(("recovery: replanning", replanned, out.report))
            how = "replanning" + (f" with {tool}" if tool != situation.tool else "")
            also = f"; plan repair: {len(repaired.steps)}" if repaired is not None else ""
            return out, f"{how} ({len(replanned.steps)} steps{also})"
        return None, f"not done: no plan to take it again ({why or 'plan repair and replanning both failed'})"


def _steps(plan: OperationPlan | None) -> str | Term:
    """A plan's length as recovery_way/3 takes it."""
    return "none" if plan is None else Term("steps", (len(plan.steps),))
