"""Splitting a partial-order plan into one command stream per device, with WAITs.

The seed's Executive "splits a plan into separate command streams, one for each
independently controllable sensor or effector" and "inserts WAIT commands before any
command that has a predecessor belonging to another command stream".  :func:`split`
does exactly that:

  - each step's command goes to its stream (the operator's ``command_stream``), the
    commands of one stream in an order consistent with the plan's partial order (the
    plan's own step order where it is one);
  - a :class:`~ita.executive.commands.Wait` naming the predecessors on other streams
    goes right before each command that has such predecessors, and nowhere else.
    Predecessors on the command's own stream need no WAIT: a stream runs its commands
    one after another.

Streams are listed in the order their first step appears in the plan; the executor
breaks ties between simultaneous events in that order.
"""

from __future__ import annotations

import heapq
from collections.abc import Sequence
from dataclasses import dataclass

from ita.executive.commands import Command, ExecutiveError, StreamId, Wait
from ita.planning.operation import PlanStep

__all__ = ["StreamCommands", "StreamPlan", "execution_order", "split"]

Item = Command | Wait


@dataclass(frozen=True)
class StreamCommands:
    """The items (commands and WAITs) of one stream, in the order the stream runs them."""

    stream: StreamId
    items: tuple[Item, ...]

    @property
    def commands(self) -> tuple[Command, ...]:
        return tuple(i for i in self.items if isinstance(i, Command))

    @property
    def waits(self) -> tuple[Wait, ...]:
        return tuple(i for i in self.items if isinstance(i, Wait))

    @property
    def steps(self) -> tuple[int, ...]:
        """The step numbers of the stream's commands, in order."""
        return tuple(c.step for c in self.commands)


@dataclass(frozen=True)
class StreamPlan:
    """A plan split into streams: `steps` (in execution order) and each stream's items."""

    steps: tuple[PlanStep, ...]
    streams: tuple[StreamCommands, ...]

    def stream(self, stream: StreamId) -> StreamCommands:
        for s in self.streams:
            if s.stream == stream:
                return s
        raise KeyError(stream)

    def command(self, step: int) -> Command:
        for s in self.streams:
            for c in s.commands:
                if c.step == step:
                    return c
        raise KeyError(step)

    @property
    def waits(self) -> tuple[Wait, ...]:
        return tuple(w for s in self.streams for w in s.waits)


def execution_order(steps: Sequence[PlanStep]) -> tuple[PlanStep, ...]:
    """`steps` in an order where every step follows its predecessors: the lowest-numbered
    ready step first (so a plan already in execution order keeps it).

    Raises :class:`ExecutiveError` for duplicate step numbers, an unknown predecessor or
    a cycle.
    """
    by_number: dict[int, PlanStep] = {}
    for s in steps:
        if s.number in by_number:
            raise ExecutiveError(f"plan has two steps numbered {s.number}")
        by_number[s.number] = s
    waiting = {n: set(s.predecessors) for n, s in by_number.items()}
    followers: dict[int, list[int]] = {n: [] for n in by_number}
    for n, preds in waiting.items():
        for p in preds:
            if p not in by_number:
                raise ExecutiveError(f"step {n} follows step {p}, which is not in the plan")
            if p == n:
                raise ExecutiveError(f"step {n} follows itself")
            followers[p].append(n)
    ready = [n for n, preds in waiting.items() if not preds]
    heapq.heapify(ready)
    order: list[PlanStep] = []
    while ready:
        n = heapq.heappop(ready)
        order.append(by_number[n])
        for f in followers[n]:
            waiting[f].discard(n)
            if not waiting[f]:
                heapq.heappush(ready, f)
    if len(order) != len(by_number):
        stuck = sorted(n for n in by_number if waiting[n])
        raise ExecutiveError(f"the plan's order has a cycle among steps {stuck}")
    return tuple(order)


def split(steps: Sequence[PlanStep], commands: Sequence[Command]) -> StreamPlan:
    """The streams of the plan `steps` whose commands are `commands` (one per step, any
    order, matched by step number; see :func:`~ita.executive.commands.plan_commands`)."""
    ordered = execution_order(steps)
    by_step = {c.step: c for c in commands}
    if len(by_step) != len(commands) or set(by_step) != {s.number for s in ordered}:
        raise ExecutiveError(
            f"commands for steps {sorted(by_step)} do not match the plan's steps "
            f"{sorted(s.number for s in ordered)}"
        )
    items: dict[StreamId, list[Item]] = {}
    for step in ordered:
        command = by_step[step.number]
        others = tuple(sorted(p for p in set(step.predecessors) if by_step[p].stream != command.stream))
        stream_items = items.setdefault(command.stream, [])
        if others:
            stream_items.append(Wait(command.stream, step.number, others))
        stream_items.append(command)
    return StreamPlan(ordered, tuple(StreamCommands(s, tuple(i)) for s, i in items.items()))
