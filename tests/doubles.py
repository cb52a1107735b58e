"""Test doubles of the executive's devices."""

from __future__ import annotations

import math
import random
from collections.abc import Mapping, Sequence
from typing import Any

from ita.executive.adapters import Completion, PoseResolver, qualitative_parameters
from ita.executive.commands import Command, Reply, Wait, instantiate
from ita.logic.terms import Term, Var


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
    for each qualitative parameter of each command started.  held_up: step -> seconds
    the device waits (the other arm's zones) before it begins, within its duration.

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
        held_up: Mapping[int, float] | None = None,
    ) -> None:
        self.held_up = dict(held_up or {})
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
        return Completion(now + duration, Reply.normal(payload), self.held_up.get(command.step, 0.0))

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
