"""Commands, WAITs, CONTINUEs and replies of the Plan Executive, as values.

Each step of a plan becomes one :class:`Command` for one device stream.  The stream, the
message and the expected reply and result come from the operator's Figure 3 fields in
kb/operators.pl (``command_stream``, ``message_pattern``, ``reply_pattern``,
``result_pattern``), fetched for all steps of a plan in one bridge call to
``executive:step_commands/2`` (prolog/executive.pl)::

    commands = plan_commands(kb, plan.steps)
    commands[4].stream     # StreamId('path_planner', 't3')
    commands[4].message    # Term('MEASURE', (Term('min_value', ...), Term('max_value', ...)))
    commands[4].reply      # Term('VALUE', (Var('V0'),))
    commands[4].result_of(Term('VALUE', (2.51,)))   # Term('dimension', ('b', 'us_probe_1', 2.51, 0.0))

Terms are the bridge's Python values (:mod:`ita.logic.terms`): atoms ``str``, numbers,
compounds :class:`~ita.logic.terms.Term`; pattern variables are
:class:`~ita.logic.terms.Var`, shared between a command's reply and result patterns.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from enum import Enum
from types import MappingProxyType
from typing import TYPE_CHECKING

from ita.errors import ItaError
from ita.logic.json_value import JsonValue
from ita.logic.terms import Term, TermValue, Var
from ita.planning.operation import PlanStep, format_term

if TYPE_CHECKING:
    from ita.logic.bridge import KnowledgeBase

__all__ = [
    "DEFAULT_TIMEOUTS",
    "Command",
    "ExecutiveError",
    "Reply",
    "ReplyKind",
    "StreamId",
    "Wait",
    "instantiate",
    "match",
    "plan_commands",
    "term_text",
]

#: Time-out (simulated seconds from the moment a device starts a command) per message
#: name; a message not named here gets DEFAULT_TIMEOUT_S.  Generous against the
#: nominal durations (arm moves of a few seconds, a range image in seconds), so a
#: time-out means a device that does not answer, not a slow one.
DEFAULT_TIMEOUTS: Mapping[str, float] = MappingProxyType({
    "MOVE": 60.0,
    "RETRACT": 30.0,
    "CONTACT": 30.0,
    "COUPLANT": 30.0,
    "MEASURE": 30.0,
    "SCAN": 60.0,
    "PICKUP": 60.0,
    "PUTDOWN": 60.0,
    "CALIBRATE": 120.0,
    "REFILL": 180.0,
    "CALL": 3600.0,         # a person called to the cell (ita.devices.person): minutes of work
})
DEFAULT_TIMEOUT_S = 60.0


class ExecutiveError(ItaError):
    """The executive cannot run a plan at all (a malformed plan, a stream without a device)."""


@dataclass(frozen=True, order=True)
class StreamId:
    """One independently controllable device's command stream, as the operators name it:
    ``command_stream(path_planner, t3)`` is ``StreamId("path_planner", "t3")``."""

    device: str
    unit: str

    @classmethod
    def from_term(cls, value: TermValue) -> StreamId:
        if (isinstance(value, Term) and value.name == "command_stream" and len(value.args) == 2
                and all(isinstance(a, str) for a in value.args)):
            return cls(value.args[0], value.args[1])
        raise ValueError(f"not a command stream: {value!r}")

    def __str__(self) -> str:
        return f"{self.device}({self.unit})"


@dataclass(frozen=True)
class Command:
    """What the executive sends for plan step `step` to `stream`.

    message: the message term, qualitative parameters unresolved (``MOVE(approach_point(
    meas(a)), approach_point(meas(b)))``); reply: the normal reply expected, a pattern
    with :class:`Var`; result: what the step reports, a pattern over the same variables;
    timeout_s: how long the device may take from the moment it starts the command.
    """

    stream: StreamId
    step: int
    message: TermValue
    reply: TermValue
    result: TermValue
    timeout_s: float

    @property
    def name(self) -> str:
        """The message's name, e.g. ``MOVE``."""
        return self.message.name if isinstance(self.message, Term) else str(self.message)

    @property
    def args(self) -> tuple[TermValue, ...]:
        """The message's arguments (empty for an atom message)."""
        return self.message.args if isinstance(self.message, Term) else ()

    @property
    def text(self) -> str:
        return term_text(self.message)

    def result_of(self, payload: TermValue | None) -> TermValue | None:
        """The step's result for the normal reply `payload`; None if `payload` does not
        match the expected reply pattern (no payload matches none: the operators' reply
        patterns are atoms and compounds)."""
        if payload is None:
            return None
        bindings = match(self.reply, payload)
        return None if bindings is None else instantiate(self.result, bindings)


@dataclass(frozen=True)
class Wait:
    """WAIT in `stream` before the command of step `step`, until the steps `waits_for`
    (its predecessors in other streams) have completed."""

    stream: StreamId
    step: int
    waits_for: tuple[int, ...]


class ReplyKind(str, Enum):
    """How a command ended: a normal reply, an exception reply, or no reply in time."""

    NORMAL = "normal"
    EXCEPTION = "exception"
    TIMEOUT = "timeout"


@dataclass(frozen=True)
class Reply:
    """A device's reply to a command.

    payload: the reply term (``DONE``, ``VALUE(2.51)``; for an exception e.g.
    ``BUMP(link_3, bulkhead)``), None for a time-out; text: one line for people;
    details: what the device adds for diagnosis (joint angles, contacts...), values only;
    data: what the command produced beyond the reply term, for whoever reads the
    execution report (a gauge reading, range frames, Vision's values: ita.devices.data;
    the executive does not look into it, whoever reads it checks what it is).
    """

    kind: ReplyKind
    payload: TermValue | None = None
    text: str = ""
    details: Mapping[str, JsonValue] = field(default_factory=lambda: MappingProxyType({}))
    data: object = None

    @classmethod
    def normal(cls, payload: TermValue, text: str = "", *, data: object = None) -> Reply:
        return cls(ReplyKind.NORMAL, payload, text, data=data)

    @classmethod
    def exception(cls, payload: TermValue, text: str = "", *, data: object = None, **details: JsonValue) -> Reply:
        return cls(ReplyKind.EXCEPTION, payload, text, MappingProxyType(dict(details)), data)

    @property
    def ok(self) -> bool:
        return self.kind is ReplyKind.NORMAL


# -- patterns ---------------------------------------------------------------------------


def match(pattern: TermValue, value: TermValue, bindings: Mapping[Var, TermValue] | None = None
          ) -> dict[Var, TermValue] | None:
    """The bindings (extending `bindings`) under which `pattern` equals the ground `value`,
    or None.  A variable met twice must match equal values."""
    found = dict(bindings or {})
    return found if _match(pattern, value, found) else None


def _match(pattern: TermValue, value: TermValue, found: dict[Var, TermValue]) -> bool:
    if isinstance(pattern, Var):
        if pattern in found:
            return _equal(found[pattern], value)
        found[pattern] = value
        return True
    if isinstance(pattern, Term):
        return (isinstance(value, Term) and value.name == pattern.name
                and len(value.args) == len(pattern.args)
                and all(_match(p, v, found) for p, v in zip(pattern.args, value.args)))
    if isinstance(pattern, list):
        return (isinstance(value, (list, tuple)) and len(value) == len(pattern)
                and all(_match(p, v, found) for p, v in zip(pattern, value)))
    return _equal(pattern, value)


def _equal(a: TermValue, b: TermValue) -> bool:
    if isinstance(a, str) or isinstance(b, str):
        return isinstance(a, str) and isinstance(b, str) and a == b
    if isinstance(a, (int, float)) and isinstance(b, (int, float)):
        return a == b or (isinstance(a, float) and isinstance(b, float) and math.isnan(a) and math.isnan(b))
    return bool(a == b)


def instantiate(pattern: TermValue, bindings: Mapping[Var, TermValue]) -> TermValue:
    """`pattern` with its bound variables replaced by their values."""
    if isinstance(pattern, Var):
        return bindings.get(pattern, pattern)
    if isinstance(pattern, Term):
        return Term(pattern.name, tuple(instantiate(a, bindings) for a in pattern.args))
    if isinstance(pattern, list):
        return [instantiate(a, bindings) for a in pattern]
    return pattern


def term_text(value: object) -> str:
    """A term as Prolog writes it, pattern variables by name: ``VALUE(V0)``; any other
    value as :func:`~ita.planning.operation.format_term` gives it."""
    if isinstance(value, Var):
        return value.name
    if isinstance(value, Term):
        return f"{value.name}({', '.join(term_text(a) for a in value.args)})"
    if isinstance(value, list):
        return "[" + ", ".join(term_text(a) for a in value) + "]"
    return format_term(value)


def _unnumber(value: TermValue) -> TermValue:
    """Prolog's numbered variables ``'$VAR'(N)`` as ``Var('VN')``."""
    if isinstance(value, Term):
        if value.name == "$VAR" and len(value.args) == 1 and isinstance(value.args[0], int):
            return Var(f"V{value.args[0]}")
        return Term(value.name, tuple(_unnumber(a) for a in value.args))
    if isinstance(value, list):
        return [_unnumber(a) for a in value]
    return value


# -- from the operators -------------------------------------------------------------------


def step_term(step: PlanStep) -> str | Term:
    """The step's action as a term, e.g. ``Term('move', ('t3', 'home', ...))``."""
    return Term(step.action, step.args) if step.args else step.action


def timeout_for(message_name: str, timeouts: Mapping[str, float] = DEFAULT_TIMEOUTS) -> float:
    """The time-out of a message named `message_name`; ValueError unless positive."""
    seconds = float(timeouts.get(message_name, timeouts.get("*", DEFAULT_TIMEOUT_S)))
    if not seconds > 0.0:
        raise ValueError(f"time-out of {message_name} must be positive, got {seconds}")
    return seconds


def plan_commands(
    kb: KnowledgeBase,
    steps: Sequence[PlanStep],
    timeouts: Mapping[str, float] = DEFAULT_TIMEOUTS,
) -> tuple[Command, ...]:
    """The command of each step of `steps`, in the same order, from one bridge call.

    `timeouts` maps message names to time-outs (key ``"*"``: the default).  Raises
    :class:`~ita.errors.PrologError` for an action that is no operator.
    """
    if not steps:
        return ()
    solution = kb.once("executive", "step_commands", [step_term(s) for s in steps], Var("C"))
    if solution is None:
        raise ExecutiveError("executive:step_commands/2 failed")
    commands = []
    for step, term in zip(steps, solution["C"]):
        stream, message, reply, result = term.args
        message = _unnumber(message)
        commands.append(Command(
            stream=StreamId.from_term(stream),
            step=step.number,
            message=message,
            reply=_unnumber(reply),
            result=_unnumber(result),
            timeout_s=timeout_for(message.name if isinstance(message, Term) else str(message), timeouts),
        ))
    return tuple(commands)
