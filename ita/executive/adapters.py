"""What the executive needs of a device, and fake devices for tests.

A device adapter stands for one command stream's device: the arm through the Path
Planner (which also runs the ultrasonic gauge), the SLRA through Vision.  The executor
owns simulated time; an adapter only says when a command it starts will end and how::

    class DeviceAdapter(Protocol):
        lookahead: bool                                  # wants its whole queue at plan start
        def begin(self, items, now) -> None              # that queue (commands and WAITs)
        def start(self, command, now) -> Completion      # run one command: when it ends, reply
        def stop(self, now) -> None                      # the plan stopped: halt
        def snapshot(self) -> Mapping[str, Any]          # device state, for the exception handler

A lookahead device learns its queue in ``begin``; ``start(command)`` then means "go on
with this command of your queue": the executive calls it for the first command at plan
start, for each next one when the one before has replied, and for a command after a
WAIT when it sends the CONTINUE.  A device without lookahead sees each command first
in ``start``.

``start`` may do all of its device's work at once (a simulation computes the end of a
move when it begins); it reports ``Completion(at, reply)`` with ``at >= now``, or a
``reply`` of None when the device will never answer (a silent controller).  The
executor turns a completion later than the command's time-out into a TIMEOUT.  An
adapter reports a device's failure as an exception reply (``Reply.exception``), never
by raising.  Adapters should not move a shared clock themselves: the executor
advances it to each event (a clock already ahead is left alone).

Commands carry qualitative parameters (``in_contact_point(meas(b))``,
``viewing_pose(meas(b))``); an adapter turns them into numbers with a
:class:`PoseResolver`, the Geometric Reasoner's callback, given to it when it is made.
"""

from __future__ import annotations

import math
import random
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any, Protocol, runtime_checkable

from ita.executive.commands import Command, Reply, Wait, instantiate
from ita.logic.terms import Term, Var

__all__ = [
    "Completion",
    "DeviceAdapter",
    "FakeDevice",
    "PoseResolver",
    "qualitative_parameters",
]

#: The functors of the operators' qualitative parameters, which the Geometric Reasoner
#: turns into numbers: poses of the tool point and the values a measurement expects.
QUALITATIVE = frozenset({
    "approach_point", "in_contact_point", "viewing_pose", "goal_point",
    "patches", "min_value", "max_value",
})


@runtime_checkable
class PoseResolver(Protocol):
    """The Geometric Reasoner's callback: the quantitative value of a qualitative
    parameter, e.g. ``in_contact_point(meas(b))`` -> a tool pose or arm configuration,
    ``patches(meas(b))`` -> an SLRA patch layout, ``min_value(meas(b))`` -> a number.
    Raises KeyError (or a subclass) for a parameter it does not know."""

    def resolve(self, term: Any) -> Any: ...


@dataclass(frozen=True)
class Completion:
    """When a started command ends (simulated seconds, absolute) and the device's reply;
    `reply` None: the device never answers (the executor times the command out)."""

    at: float
    reply: Reply | None


@runtime_checkable
class DeviceAdapter(Protocol):
    """One stream's device, as the executor drives it (see the module docstring)."""

    lookahead: bool

    def begin(self, items: Sequence[Command | Wait], now: float) -> None: ...

    def start(self, command: Command, now: float) -> Completion: ...

    def stop(self, now: float) -> None: ...

    def snapshot(self) -> Mapping[str, Any]: ...


def qualitative_parameters(message: Any) -> tuple[Term, ...]:
    """The qualitative parameters of a message, outermost first, in argument order."""
    found: list[Term] = []

    def walk(value: Any) -> None:
        if isinstance(value, Term):
            if value.name in QUALITATIVE:
                found.append(value)
            else:
                for a in value.args:
                    walk(a)

    if isinstance(message, Term):
        for arg in message.args:
            walk(arg)
    return tuple(found)


class FakeDevice:
    """A scripted device for tests: configurable durations, exceptions and silence.

    durations: seconds per message name (``{"MOVE": 2.0}``) or per step number (which
    wins); default_s for the rest.  jitter_s: each duration is stretched by a uniform
    0..jitter_s drawn from ``random.Random(seed)``, so runs with one seed are the same.
    values: the value bound to every variable of a normal reply, per message name (the
    reply is the command's reply pattern with them), default 0.0.  replies: a normal
    reply's payload verbatim, per step number or message name (to send one that does
    not match the pattern).  exceptions: step ->
    exception payload, replied instead of the normal reply at the end of the command.
    silent: steps the device never answers.  resolver: a :class:`PoseResolver` asked
    for each qualitative parameter of each command started.

    Records what it was told: `queued` (now, items) per begin, `started` (now, step),
    `stopped` (now), `resolved` (step, term, value).
    """

    def __init__(
        self,
        *,
        lookahead: bool = False,
        durations: Mapping[str | int, float] | None = None,
        default_s: float = 1.0,
        jitter_s: float = 0.0,
        seed: int = 0,
        values: Mapping[str, Any] | None = None,
        replies: Mapping[str | int, Any] | None = None,
        exceptions: Mapping[int, Any] | None = None,
        silent: Sequence[int] = (),
        resolver: PoseResolver | None = None,
    ) -> None:
        self.lookahead = lookahead
        self.durations = dict(durations or {})
        self.default_s = default_s
        self.jitter_s = jitter_s
        self.values = dict(values or {})
        self.replies = dict(replies or {})
        self.exceptions = dict(exceptions or {})
        self.silent = frozenset(silent)
        self.resolver = resolver
        self._random = random.Random(seed)
        self.queued: list[tuple[float, tuple[Command | Wait, ...]]] = []
        self.started: list[tuple[float, int]] = []
        self.stopped: list[float] = []
        self.resolved: list[tuple[int, Term, Any]] = []
        self._done: list[int] = []

    def begin(self, items: Sequence[Command | Wait], now: float) -> None:
        self.queued.append((now, tuple(items)))

    def start(self, command: Command, now: float) -> Completion:
        self.started.append((now, command.step))
        if self.resolver is not None:
            for term in qualitative_parameters(command.message):
                self.resolved.append((command.step, term, self.resolver.resolve(term)))
        duration = self.durations.get(command.step, self.durations.get(command.name, self.default_s))
        if self.jitter_s:
            duration += self._random.uniform(0.0, self.jitter_s)
        if command.step in self.silent:
            return Completion(math.inf, None)
        if command.step in self.exceptions:
            payload = self.exceptions[command.step]
            return Completion(now + duration, Reply.exception(payload, f"fake exception {payload}"))
        self._done.append(command.step)
        if command.step in self.replies or command.name in self.replies:
            payload = self.replies.get(command.step, self.replies.get(command.name))
        else:
            value = self.values.get(command.name, 0.0)
            payload = instantiate(command.reply, dict.fromkeys(_variables(command.reply), value))
        return Completion(now + duration, Reply.normal(payload))

    def stop(self, now: float) -> None:
        self.stopped.append(now)

    def snapshot(self) -> Mapping[str, Any]:
        return {"done": tuple(self._done)}


def _variables(pattern: Any) -> set[Var]:
    """The variables of a pattern."""
    if isinstance(pattern, Var):
        return {pattern}
    if isinstance(pattern, (Term, list)):
        items = pattern.args if isinstance(pattern, Term) else pattern
        return set().union(*(_variables(a) for a in items)) if items else set()
    return set()
