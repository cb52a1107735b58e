"""What the executive needs of a device.

A device adapter stands for one command stream's device: the arm through the Path
Planner (which also runs the ultrasonic gauge), the SLRA through Vision.  The executor
owns simulated time; an adapter only says when a command it starts will end and how::

    class DeviceAdapter(Protocol):
        lookahead: bool                                  # wants its whole queue at plan start
        def begin(self, items, now) -> None              # that queue (commands and WAITs)
        def start(self, command, now) -> Completion      # run one command: when it ends, reply
        def stop(self, now) -> None                      # the plan stopped: halt
        def snapshot(self) -> Mapping[str, JsonValue]    # device state, for the exception handler

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

A reply carries the command's data (``Reply.data``: a reading, frames, Vision's values),
so the execution report holds everything a plan produced.

Commands carry qualitative parameters (``in_contact_point(meas(b))``,
``viewing_pose(meas(b))``); an adapter turns them into numbers with a
:class:`PoseResolver`, the Geometric Reasoner's callback, given to it when it is made.
The devices themselves live in :mod:`ita.devices`; a scripted double for tests in
``tests/doubles.py``.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any, Protocol, runtime_checkable

from ita.executive.commands import Command, Reply, Wait
from ita.logic.json_value import JsonValue
from ita.logic.terms import Term, TermValue

__all__ = [
    "Completion",
    "DeviceAdapter",
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
    parameter for the tool `tool` (the one the arm holds; None: the tool the sequence
    plan chose), e.g. ``in_contact_point(meas(b))`` -> a tool pose or arm configuration,
    ``patches(meas(b))`` -> an SLRA view, ``min_value(meas(b))`` -> a number.  Raises
    KeyError (or a subclass) for a parameter it does not know.

    What comes back depends on the parameter's functor, which a type cannot say: the
    caller, which knows the functor it asks for, reads the answer as that kind (the
    devices declare the shapes they expect: ita.devices.arm, ita.devices.slra)."""

    def resolve(self, term: TermValue, tool: str | None = None) -> Any: ...


@dataclass(frozen=True)
class Completion:
    """When a started command ends (simulated seconds, absolute) and the device's reply;
    `reply` None: the device never answers (the executor times the command out).
    waited_s: how long the device waited before it began (the other arm's zones: a WAIT
    for their release, a fold to give way), which its time-out does not count."""

    at: float
    reply: Reply | None
    waited_s: float = 0.0


@runtime_checkable
class DeviceAdapter(Protocol):
    """One stream's device, as the executor drives it (see the module docstring)."""

    lookahead: bool

    def begin(self, items: Sequence[Command | Wait], now: float) -> None: ...

    def start(self, command: Command, now: float) -> Completion: ...

    def stop(self, now: float) -> None: ...

    def snapshot(self) -> Mapping[str, JsonValue]: ...


def qualitative_parameters(message: TermValue) -> tuple[Term, ...]:
    """The qualitative parameters of a message, outermost first, in argument order."""
    found: list[Term] = []

    def walk(value: TermValue) -> None:
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
