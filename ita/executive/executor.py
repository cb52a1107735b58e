"""The Plan Executive/Monitor: runs a plan's command streams against simulated time.

A deterministic discrete-event executor.  At plan start every lookahead device (the
arm, through the Path Planner) receives its stream's whole list, WAITs included, so
that it can smooth across commands; the other devices get their commands one by one.
Then, at the current simulated time, every idle stream moves on:

  - at a WAIT it blocks (event WAIT) until the steps the WAIT names have completed;
    then the executive sends the CONTINUE (event CONTINUE) and the stream goes on;
  - at a command it sends it (event SEND): the device's adapter says when the command
    will end and with which reply.  A reply later than the command's time-out, or
    none at all, becomes a TIMEOUT at start + time-out.

The clock then jumps to the next reply or time-out (simultaneous ones are taken
together, streams in plan order).  A normal reply that matches the operator's reply
pattern completes its step (event REPLY, with the step's result); an exception reply,
a reply that does not match (an exception too) or a time-out stops the plan: the
commands running on other streams are aborted, the rest are cancelled (events
CANCELLED), and an :class:`ExecutionFailure` gathers what the Exception Handler needs.

Nothing here is random, and ties are broken by stream and step order, so a run is a
function of the plan and of what the adapters answer: the same seed, the same log.
"""

from __future__ import annotations

import heapq
import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field, replace
from enum import Enum
from typing import TYPE_CHECKING, Protocol, TypeAlias, Union

from ita.executive.adapters import DeviceAdapter
from ita.executive.commands import (
    DEFAULT_TIMEOUTS,
    Command,
    ExecutiveError,
    Reply,
    ReplyKind,
    StreamId,
    Wait,
    plan_commands,
    term_text,
)
from ita.executive.streams import StreamCommands, StreamPlan, split
from ita.logic.json_value import JsonObject, JsonValue
from ita.logic.terms import Term, TermValue, Var
from ita.planning.operation import OperationPlan, PlanStep

if TYPE_CHECKING:
    from ita.logic.bridge import KnowledgeBase

__all__ = [
    "LogEvent",
    "LogKind",
    "ExecutionFailure",
    "ExecutionReport",
    "FailureKind",
    "PlanExecutive",
    "StepOutcome",
    "StreamPosition",
    "run_streams",
]


class Clock(Protocol):
    """A simulated clock (ita.sim.world.SimClock): it only moves forward."""

    @property
    def now(self) -> float: ...

    def advance(self, seconds: float) -> float: ...


class LogKind(str, Enum):
    """What happened.  Payloads: QUEUED the stream's items' step numbers; SEND the
    message; WAIT and CONTINUE the steps waited for; REPLY (reply payload, result);
    EXCEPTION the reply payload (or (payload, expected pattern) for a reply that does
    not match); TIMEOUT the time-out in seconds; CANCELLED ``aborted`` (was running)
    or ``not sent``; PLAN_START the number of steps; PLAN_STOPPED the reason."""

    PLAN_START = "plan_start"
    QUEUED = "queued"
    SEND = "send"
    WAIT = "wait"
    CONTINUE = "continue"
    REPLY = "reply"
    EXCEPTION = "exception"
    TIMEOUT = "timeout"
    CANCELLED = "cancelled"
    PLAN_DONE = "plan_done"
    PLAN_STOPPED = "plan_stopped"


#: what a log event carries (see LogKind): a term, step numbers, seconds, a reason, or a
#: (reply payload, result or expected pattern) pair
LogPayload: TypeAlias = Union[TermValue, tuple[TermValue | None, TermValue], None]


@dataclass(frozen=True)
class LogEvent:
    """One entry of the executive's log; `stream` and `step` None for plan events."""

    sim_time: float
    kind: LogKind
    stream: StreamId | None = None
    step: int | None = None
    payload: LogPayload = None

    def to_dict(self) -> JsonObject:
        """The event as JSON-ready values (terms as Prolog text)."""
        return {
            "sim_time": self.sim_time,
            "kind": self.kind.value,
            "stream": None if self.stream is None else str(self.stream),
            "step": self.step,
            "payload": _plain(self.payload),
        }


class FailureKind(str, Enum):
    """Why a plan stopped."""

    EXCEPTION = "exception"                # the device replied an exception
    UNEXPECTED_REPLY = "unexpected_reply"  # a normal reply that does not match the operator's pattern
    TIMEOUT = "timeout"                    # no reply within the command's time-out


@dataclass(frozen=True)
class StepOutcome:
    """A completed step: its command, when it ran, the device's reply and the result."""

    step: int
    command: Command
    started_s: float
    finished_s: float
    reply: Reply
    result: TermValue


@dataclass(frozen=True)
class StreamPosition:
    """Where a stream stood when the plan stopped: steps done, the step running (None if
    idle), the WAIT it was blocked at (the steps waited for), the steps not sent."""

    stream: StreamId
    done: tuple[int, ...]
    running: int | None
    blocked_on: tuple[int, ...]
    pending: tuple[int, ...]


@dataclass(frozen=True)
class ExecutionFailure:
    """Everything about a stopped plan that the Exception Handler needs.

    plan: the plan as given (an OperationPlan, or its steps); step, command, reply: the
    failing step, its command and the reply (kind TIMEOUT, payload None, for a time-out);
    streams: each stream's position; world: each stream's device snapshot at the stop
    (``str(stream) -> adapter.snapshot()``); completed: steps done; cancelled: steps
    aborted or never sent; events: the whole log, up to the stop.
    """

    kind: FailureKind
    at_s: float
    plan: OperationPlan | Sequence[PlanStep]
    step: PlanStep
    command: Command
    reply: Reply
    streams: tuple[StreamPosition, ...]
    world: Mapping[str, Mapping[str, JsonValue]]
    completed: tuple[int, ...]
    cancelled: tuple[int, ...]
    events: tuple[LogEvent, ...]

    @property
    def reason(self) -> str:
        """One line: what failed, where and how (for the run's record)."""
        where = f"step {self.step.number} {self.step.text} ({self.command.text} on {self.command.stream})"
        if self.kind is FailureKind.TIMEOUT:
            return f"time-out: {where}: no reply within {self.command.timeout_s:g} s"
        if self.kind is FailureKind.UNEXPECTED_REPLY:
            return (f"unexpected reply: {where}: {term_text(self.reply.payload)}, "
                    f"expected {term_text(self.command.reply)}")
        text = f" ({self.reply.text})" if self.reply.text else ""
        return f"exception: {where}: {term_text(self.reply.payload)}{text}"

    def to_dict(self) -> JsonObject:
        return {
            "kind": self.kind.value,
            "reason": self.reason,
            "at_s": self.at_s,
            "step": self.step.number,
            "action": self.step.text,
            "stream": str(self.command.stream),
            "message": term_text(self.command.message),
            "reply": _plain(self.reply),
            "completed": list(self.completed),
            "cancelled": list(self.cancelled),
            "streams": [_plain(p) for p in self.streams],
            "world": _plain(self.world),
        }


@dataclass(frozen=True)
class ExecutionReport:
    """How a plan ran: the completed steps, the log, and the failure if it stopped."""

    plan: OperationPlan | Sequence[PlanStep]
    started_s: float
    finished_s: float
    outcomes: tuple[StepOutcome, ...]
    events: tuple[LogEvent, ...]
    failure: ExecutionFailure | None = None

    @property
    def ok(self) -> bool:
        """Whether every step completed with a normal reply."""
        return self.failure is None

    @property
    def makespan(self) -> float:
        """Simulated seconds from plan start to the last reply (or the stop)."""
        return self.finished_s - self.started_s

    @property
    def results(self) -> tuple[TermValue, ...]:
        """The results of the completed steps, in the order they completed."""
        return tuple(o.result for o in self.outcomes)


# -- the executor ----------------------------------------------------------------------


@dataclass
class _Stream:
    """A stream's progress during a run (mutable, private to one run)."""

    index: int                      # position in the plan's stream order (tie-break)
    commands: StreamCommands
    adapter: DeviceAdapter
    next_item: int = 0
    running: Command | None = None
    busy: bool = False              # still running a trailing command of the plan before
    started_s: float = 0.0
    blocked: Wait | None = None
    done: list[int] = field(default_factory=list)

    @property
    def items(self) -> tuple[Command | Wait, ...]:
        return self.commands.items

    @property
    def finished(self) -> bool:
        return self.running is None and not self.busy and self.next_item >= len(self.items)

    def position(self) -> StreamPosition:
        pending = tuple(i.step for i in self.items[self.next_item:] if isinstance(i, Command))
        return StreamPosition(
            self.commands.stream, tuple(self.done),
            None if self.running is None else self.running.step,
            self.blocked.waits_for if self.blocked else (), pending,
        )


# a reply (None: a time-out) due; no command: a stream's trailing command of the plan before ends
_Pending = tuple[float, int, int, Command | None, Reply | None]
_Failed = tuple[FailureKind, _Stream, Command, Reply]      # why, where, what, the reply
_Log = Callable[..., None]


def _adapter_for(adapters: Mapping[StreamId | str, DeviceAdapter], stream: StreamId) -> DeviceAdapter:
    for key in (stream, str(stream), stream.device):
        if key in adapters:
            return adapters[key]
    raise ExecutiveError(f"no device adapter for stream {stream}")


def run_streams(
    streams: StreamPlan,
    adapters: Mapping[StreamId | str, DeviceAdapter],
    *,
    plan: OperationPlan | Sequence[PlanStep] | None = None,
    start_s: float | None = None,
    clock: Clock | None = None,
    busy_until: dict[str, float] | None = None,
) -> ExecutionReport:
    """Run the streams of a split plan on their devices.

    adapters: by StreamId, by its text (``path_planner(t3)``) or by device name
    (``path_planner``), tried in that order.  start_s: simulated start time (default the
    clock's time, else 0).  clock: advanced to each event (never back; a clock already
    past an event is left alone).  plan: what the failure reports as the plan (default
    the steps).  Raises :class:`ExecutiveError` if a stream has no adapter.

    busy_until: stream text -> simulated time it is busy until, carried from plan to plan
    (updated here).  With it, a stream sends nothing before its time, and trailing
    commands (the last of a stream without lookahead, which no WAIT waits for) do not hold
    the plan: once they are all that runs, each answered normally within its time-out,
    their steps are done with those replies, the plan ends, and their streams stay busy
    until its reply's time (when the plan stops before, it stops as ever).  Vision
    processing a frame while the arm flies to the next view, as the seed's separate
    streams allow.
    """
    runs = [_Stream(i, s, _adapter_for(adapters, s.stream)) for i, s in enumerate(streams.streams)]
    steps = {s.number: s for s in streams.steps}
    now = float(start_s if start_s is not None else (clock.now if clock is not None else 0.0))
    started = now
    events: list[LogEvent] = []
    outcomes: list[StepOutcome] = []
    completed: set[int] = set()
    pending: list[_Pending] = []  # heap of (time, stream index, step, command, reply or None)
    failure_info: _Failed | None = None

    def log(kind: LogKind, run: _Stream | None = None, step: int | None = None, payload: LogPayload = None) -> None:
        events.append(LogEvent(now, kind, None if run is None else run.commands.stream, step, payload))

    log(LogKind.PLAN_START, payload=len(steps))
    for run in runs:
        if run.adapter.lookahead:
            run.adapter.begin(run.items, now)
            log(LogKind.QUEUED, run, payload=run.commands.steps)
    trailing: set[int] = set()
    if busy_until is not None:
        waited = {n for r in runs for item in r.items if isinstance(item, Wait) for n in item.waits_for}
        for run in runs:
            free_at = busy_until.get(str(run.commands.stream), -math.inf)
            if free_at > now:                       # still busy with the last plan's trailing command
                run.busy = True
                heapq.heappush(pending, (free_at, run.index, -1, None, None))
            commands = [i for i in run.items if isinstance(i, Command)]
            if commands and not run.adapter.lookahead and commands[-1].step not in waited:
                trailing.add(commands[-1].step)

    def settle_trailing() -> bool:
        """When only trailing commands are left running, each answered normally in time: take
        their replies as their steps' and end the plan now; whether it did (see the docstring)."""
        if busy_until is None or not pending:
            return False
        live = [(at, index, step, command, reply) for at, index, step, command, reply in pending
                if command is not None]
        if not live or any(p[2] not in trailing or p[4] is None or p[4].kind is not ReplyKind.NORMAL
                           or p[3].result_of(p[4].payload) is None for p in live):
            return False
        if any(r.next_item < len(r.items) or (r.running is not None and r.running.step not in trailing) for r in runs):
            return False
        for at, index, step, command, reply in sorted(live):
            assert reply is not None  # every live one was answered (checked above)
            run = runs[index]
            result = command.result_of(reply.payload)
            assert result is not None  # every live one matched its reply pattern (checked above)
            events.append(LogEvent(at, LogKind.REPLY, run.commands.stream, step, (reply.payload, result)))
            outcomes.append(StepOutcome(step, command, run.started_s, at, reply, result))
            completed.add(step)
            run.done.append(step)
            run.running = None
            busy_until[str(run.commands.stream)] = at
        for run in runs:
            run.busy = False
        pending.clear()
        return True

    while True:
        for run in runs:
            _advance(run, now, completed, pending, log)
        if not pending or settle_trailing():
            break
        now = pending[0][0]
        if clock is not None and clock.now < now:
            clock.advance(now - clock.now)
        while pending and pending[0][0] == now:  # simultaneous replies are all taken
            _, index, _, command, reply = heapq.heappop(pending)
            if command is None:                  # the stream's trailing command of a plan before is over
                runs[index].busy = False
                continue
            found = _receive(runs[index], command, reply, now, completed, outcomes, log)
            failure_info = failure_info or found  # the first failure, in stream order, stops the plan
        if failure_info is not None:
            break

    if failure_info is None:
        stuck = [r for r in runs if not r.finished]
        if stuck:  # cannot happen for a split plan; a guard against malformed StreamPlans
            raise ExecutiveError(f"streams {[str(r.commands.stream) for r in stuck]} blocked for ever")
        log(LogKind.PLAN_DONE)
        return ExecutionReport(plan if plan is not None else streams.steps, started, now,
                               tuple(outcomes), tuple(events))

    kind, failed, command, reply = failure_info
    positions = tuple(r.position() for r in runs)  # before cancelling: where each stood
    cancelled: list[int] = []
    for run in runs:
        run.adapter.stop(now)
        run.busy = False
        if run.running is not None and run is not failed:
            log(LogKind.CANCELLED, run, run.running.step, "aborted")
            cancelled.append(run.running.step)
        for item in run.items[run.next_item:]:
            if isinstance(item, Command):
                log(LogKind.CANCELLED, run, item.step, "not sent")
                cancelled.append(item.step)
    world = {str(r.commands.stream): r.adapter.snapshot() for r in runs}
    failure_stub = ExecutionFailure(
        kind, now, plan if plan is not None else streams.steps, steps[command.step], command, reply,
        positions, world, tuple(sorted(completed)), tuple(sorted(cancelled)), (),
    )
    log(LogKind.PLAN_STOPPED, payload=failure_stub.reason)
    failure = replace(failure_stub, events=tuple(events))
    return ExecutionReport(failure.plan, started, now, tuple(outcomes), tuple(events), failure)


def _advance(run: _Stream, now: float, completed: set[int], pending: list[_Pending], log: _Log) -> None:
    """Let an idle stream go on at `now`: through satisfied WAITs, up to the next command
    sent or the first unsatisfied WAIT."""
    while run.running is None and not run.busy and run.next_item < len(run.items):
        item = run.items[run.next_item]
        if isinstance(item, Wait):
            if run.blocked is not item:
                run.blocked = item
                log(LogKind.WAIT, run, item.step, item.waits_for)
            if not completed.issuperset(item.waits_for):
                return
            log(LogKind.CONTINUE, run, item.step, item.waits_for)
            run.blocked = None
            run.next_item += 1
            continue
        log(LogKind.SEND, run, item.step, item.message)
        completion = run.adapter.start(item, now)
        if completion.at < now:
            raise ExecutiveError(f"{run.commands.stream}: step {item.step} ends at {completion.at} "
                                 f"before it started at {now}")
        deadline = now + completion.waited_s + item.timeout_s      # from when the device began
        if completion.reply is None or completion.at > deadline:
            heapq.heappush(pending, (deadline, run.index, item.step, item, None))
        else:
            heapq.heappush(pending, (completion.at, run.index, item.step, item, completion.reply))
        run.running, run.started_s = item, now
        run.next_item += 1


def _receive(run: _Stream, command: Command, reply: Reply | None, now: float, completed: set[int],
             outcomes: list[StepOutcome], log: _Log) -> _Failed | None:
    """Take a stream's reply (None: its time-out); the failure if the plan must stop."""
    if reply is None:
        log(LogKind.TIMEOUT, run, command.step, command.timeout_s)
        reply = Reply(ReplyKind.TIMEOUT, None, f"no reply within {command.timeout_s:g} s")
        return FailureKind.TIMEOUT, run, command, reply
    if reply.kind is ReplyKind.TIMEOUT:  # the device's own time-out (a silent controller)
        log(LogKind.TIMEOUT, run, command.step, reply.payload)
        return FailureKind.TIMEOUT, run, command, reply
    if reply.kind is ReplyKind.EXCEPTION:
        log(LogKind.EXCEPTION, run, command.step, reply.payload)
        return FailureKind.EXCEPTION, run, command, reply
    result = command.result_of(reply.payload)
    if result is None:
        log(LogKind.EXCEPTION, run, command.step, (reply.payload, command.reply))
        return FailureKind.UNEXPECTED_REPLY, run, command, reply
    log(LogKind.REPLY, run, command.step, (reply.payload, result))
    outcomes.append(StepOutcome(command.step, command, run.started_s, now, reply, result))
    completed.add(command.step)
    run.done.append(command.step)
    run.running = None
    return None


# -- the facade ------------------------------------------------------------------------


class PlanExecutive:
    """Executes operation plans on devices: one bridge call for the plan's commands,
    the split into streams, the run.

        executive = PlanExecutive(kb, {"path_planner": arm, "vision": vision}, clock=world.clock)
        report = executive.execute(plan)            # plan: OperationPlan or PlanSteps
        if not report.ok: record_not_done(report.failure.reason)

    adapters: as for :func:`run_streams`; timeouts: message name -> seconds (see
    :data:`~ita.executive.commands.DEFAULT_TIMEOUTS`).  busy_until: each stream's end of
    its last trailing command, carried from plan to plan (`overlap` False: none, every plan
    waits for all its replies).
    """

    def __init__(
        self,
        kb: KnowledgeBase,
        adapters: Mapping[StreamId | str, DeviceAdapter],
        *,
        timeouts: Mapping[str, float] = DEFAULT_TIMEOUTS,
        clock: Clock | None = None,
        overlap: bool = True,
    ) -> None:
        self.kb = kb
        self.adapters = adapters
        self.timeouts = timeouts
        self.clock = clock
        self.overlap = overlap
        self.busy_until: dict[str, float] = {}

    def prepare(self, plan: OperationPlan | Sequence[PlanStep]) -> StreamPlan:
        """The plan's streams, WAITs inserted (one bridge call)."""
        steps = _steps(plan)
        return split(steps, plan_commands(self.kb, steps, self.timeouts))

    def execute(self, plan: OperationPlan | Sequence[PlanStep], *, start_s: float | None = None) -> ExecutionReport:
        """Run `plan`; the report holds its results, its log and, if it stopped, the failure."""
        return run_streams(self.prepare(plan), self.adapters, plan=plan, start_s=start_s, clock=self.clock,
                           busy_until=self.busy_until if self.overlap else None)

    def settled(self) -> float:
        """When the last trailing command of any stream ends (-inf: none): a run ends then."""
        return max(self.busy_until.values(), default=-math.inf)


def _steps(plan: OperationPlan | Sequence[PlanStep]) -> tuple[PlanStep, ...]:
    return tuple(plan.steps) if isinstance(plan, OperationPlan) else tuple(plan)


def _plain(value: object) -> JsonValue:
    """`value` (whatever a log or a failure holds) as JSON-ready values: terms as Prolog
    text, dataclasses as dicts, anything unknown as its repr."""
    if isinstance(value, (Term, Var)):
        return term_text(value)
    if isinstance(value, Enum):
        plain: JsonValue = value.value      # the enums of a log are str enums
        return plain
    if isinstance(value, StreamId):
        return str(value)
    if isinstance(value, (StreamPosition, Reply)):   # a reply's data (frames...) is not for logs
        return {k: _plain(v) for k, v in value.__dict__.items() if k != "data"}
    if isinstance(value, Mapping):
        return {str(k): _plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple, set, frozenset)):
        return [_plain(v) for v in value]
    if value is None or isinstance(value, (str, int, float, bool)):
        return value
    return repr(value)
