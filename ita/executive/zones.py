"""Interference zones for two arms on one part: claim before entering, clear after leaving.

The zones and the arms' bodies in them are ita.collision.zones (a grid of the floor seen
from above; an arm at rest holds the zones of its thick segment base -> tool, a move the
zones of the triangle it sweeps until the move ends).

Claims are reservations in time (:class:`ZoneTable`): a claim is granted when none of its
zones is held by the other arm in an overlapping interval (request -> grant), otherwise
the arm WAITs until the other's holding ends and asks again (CONTINUE); after a move the
arm keeps only its rest zones (clear).  Two zones sets that do not meet mean no point
lies within ``radius`` of both arms' segments, so granted claims keep the arms' bodies
at least ``2 * radius`` apart from above (checked independently, by geometry, in
:func:`min_separation`).

No deadlock (:func:`coordinate`): a waiting arm holds only the zones of its rest pose.
If each arm waits for the other (the wait-for graph has its one possible cycle), the arm
of lower priority RETREATS: it folds back along its own base ray to ``retreat_m`` from
its base axis, which sweeps only zones it already holds and so is always granted; then
the other arm's claim is asked again.  The arm of higher priority never waits for the
other's rest zones once that one has retreated, provided its targets lie outside the
other's retreat zones (:meth:`ZoneGrid.base_zone`, which the allocation keeps:
ita.sequence.allocate); so it finishes its work and retreats for good, after which the
other is never refused.  Every wait ends, and the schedule ends.

    grid = ZoneGrid.around(bases, targets)
    schedule = coordinate(grid, arms)          # arms: ArmJob per arm, in priority order
    schedule.makespan_s, schedule.busy_s, schedule.waiting_s, schedule.events
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Sequence

import numpy as np

from ita.collision.zones import (
    RADIUS_M,
    Point,
    ZoneGrid,
    retreat_point,
    segment_distance,
)

__all__ = ["RADIUS_M", "RETREAT_SPEED", "ArmJob", "Deadlock", "Move", "Schedule", "ZoneEvent", "ZoneGrid",
           "ZoneTable", "coordinate", "min_separation", "segment_distance"]

#: tool speed of a retreat (m/s): the controller's TCP limit
RETREAT_SPEED = 0.75

@dataclass(frozen=True)
class Move:
    """One step of an arm's work: move its tool to ``target`` (world x, y) in ``move_s``,
    then stay there ``dwell_s`` (measuring, a tool change); ``label`` names it."""

    target: Point
    move_s: float
    dwell_s: float
    label: str = ""


@dataclass(frozen=True)
class ArmJob:
    """An arm's base (world x, y), where its tool starts, and its moves in order."""

    name: str
    base: Point
    start: Point
    moves: tuple[Move, ...]


@dataclass(frozen=True)
class ZoneEvent:
    """request, grant, wait, continue, clear or retreat, of arm ``arm`` at ``t`` (s)."""

    t: float
    arm: str
    kind: str
    label: str = ""
    zones: int = 0


@dataclass
class ZoneTable:
    """Who holds which zones when: each arm's reservations (start, end, zones), end
    ``inf`` for a rest pose held until the arm moves again."""

    holdings: dict[str, list[tuple[float, float, frozenset[int]]]] = field(default_factory=dict)

    def conflict(self, arm: str, start: float, end: float, zones: frozenset[int]) -> tuple[float, str] | None:
        """The earliest end (inf: held until that arm moves) of another arm's reservation
        that meets the claim, and that arm; None when the claim can be granted."""
        worst: tuple[float, str] | None = None
        for other, held in self.holdings.items():
            if other == arm:
                continue
            for s, e, z in held:
                if s < end and start < e and z & zones and (worst is None or e < worst[0]):
                    worst = (e, other)
        return worst

    def reserve(self, arm: str, start: float, end: float, zones: frozenset[int]) -> None:
        self.holdings.setdefault(arm, []).append((start, end, zones))

    def clear_from(self, arm: str, t: float) -> None:
        """The arm's open-ended rest reservation ends at ``t`` (it moves)."""
        held = self.holdings.get(arm, [])
        self.holdings[arm] = [(s, (t if math.isinf(e) else e), z) for s, e, z in held if s < t or not math.isinf(e)]

    def forget_before(self, t: float) -> None:
        for arm, held in self.holdings.items():
            self.holdings[arm] = [h for h in held if h[1] > t]


@dataclass(frozen=True)
class Schedule:
    """The arms' work in time: when each arm's moves start and end, each arm's busy
    (moving, dwelling) and waiting seconds, the zone events, the makespan."""

    arms: tuple[str, ...]
    timeline: dict[str, tuple[tuple[float, float, float, Point, Point, str], ...]]
    busy_s: dict[str, float]
    waiting_s: dict[str, float]
    retreats: dict[str, int]
    events: tuple[ZoneEvent, ...]
    makespan_s: float


class Deadlock(RuntimeError):
    """The coordination could not go on (never expected: see the module docstring)."""


def coordinate(grid: ZoneGrid, jobs: Sequence[ArmJob], max_steps: int = 1_000_000) -> Schedule:
    """Play the arms' moves in simulated time through the zone table: each move's swept
    zones claimed before it starts, the rest zones kept after; a refused claim waits for
    the holder's release; a mutual wait makes the arm later in ``jobs`` retreat.  Raises
    :class:`Deadlock` if no arm can go on (the targets break the allocation's rule)."""
    table = ZoneTable()
    clock = {j.name: 0.0 for j in jobs}
    tool = {j.name: j.start for j in jobs}
    nxt = {j.name: 0 for j in jobs}
    busy = {j.name: 0.0 for j in jobs}
    waiting = {j.name: 0.0 for j in jobs}
    retreats = {j.name: 0 for j in jobs}
    timeline: dict[str, list[tuple[float, float, float, Point, Point, str]]] = {j.name: [] for j in jobs}
    events: list[ZoneEvent] = []
    blocked: dict[str, bool] = {j.name: False for j in jobs}
    by_name = {j.name: j for j in jobs}
    priority = [j.name for j in jobs]
    for j in jobs:
        table.reserve(j.name, 0.0, math.inf, grid.at_rest(j.base, j.start))

    def go(name: str, target: Point, move_s: float, dwell_s: float, label: str, sweep: frozenset[int],
           kind: str = "grant") -> None:
        job, t0 = by_name[name], clock[name]
        table.clear_from(name, t0)
        table.reserve(name, t0, t0 + move_s, sweep)
        table.reserve(name, t0 + move_s, math.inf, grid.at_rest(job.base, target))
        events.append(ZoneEvent(t0, name, kind, label, len(sweep)))
        events.append(ZoneEvent(t0 + move_s, name, "clear", label, len(sweep)))
        timeline[name].append((t0, t0 + move_s, t0 + move_s + dwell_s, tool[name], target, label))
        tool[name] = target
        clock[name] = t0 + move_s + dwell_s
        busy[name] += move_s + dwell_s

    stuck = {j.name: False for j in jobs}          # waits for another arm's rest zones
    for _ in range(max_steps):
        live = [n for n in priority if nxt[n] < len(by_name[n].moves)]
        if not live:
            break
        name = min(live, key=lambda n: (clock[n], priority.index(n)))
        job, t0 = by_name[name], clock[name]
        move = job.moves[nxt[name]]
        sweep = grid.swept(job.base, tool[name], move.target)
        rest = grid.at_rest(job.base, move.target)
        table.forget_before(min(clock[n] for n in live))
        found = table.conflict(name, t0, math.inf, sweep | rest)
        if found is None:                                   # request -> grant
            events.append(ZoneEvent(t0, name, "continue" if blocked[name] else "request", move.label, len(sweep)))
            blocked[name] = stuck[name] = False
            go(name, move.target, move.move_s, move.dwell_s, move.label, sweep)
            nxt[name] += 1
            continue
        if not blocked[name]:
            events.append(ZoneEvent(t0, name, "wait", move.label))
            blocked[name] = True
        until, other = found
        if not math.isinf(until):                           # cleared at a known time: wait for it
            waiting[name] += until - t0
            clock[name] = until
            continue
        other_moves = nxt[other] < len(by_name[other].moves)
        if other_moves and not stuck[other]:                # it moves on at its next step: wait for that
            stuck[name] = True
            later = clock[other] if clock[other] > t0 else t0 + 1e-6
            waiting[name] += later - t0
            clock[name] = later
            continue
        # each waits for the other's rest zones, or the other is done and parked in the way:
        # the one of lower priority (a parked one first) folds back along its own base ray
        loser = other if not other_moves or priority.index(other) > priority.index(name) else name
        back = retreat_point(by_name[loser].base, tool[loser])
        if back == tool[loser]:
            raise Deadlock(f"{name} waits for zones {other} holds with {loser} already retreated: "
                           f"a target lies in the other arm's base zone")
        dist = float(np.hypot(tool[loser][0] - back[0], tool[loser][1] - back[1]))
        clock[loser] = max(clock[loser], t0)
        go(loser, back, dist / RETREAT_SPEED, 0.0, "retreat", grid.swept(by_name[loser].base, tool[loser], back),
           kind="retreat")
        busy[loser] -= dist / RETREAT_SPEED
        waiting[loser] += dist / RETREAT_SPEED
        retreats[loser] += 1
        stuck[loser] = False
    else:
        raise Deadlock(f"no end after {max_steps} steps")
    return Schedule(tuple(priority), {n: tuple(v) for n, v in timeline.items()}, busy, waiting, retreats,
                    tuple(sorted(events, key=lambda e: (e.t, priority.index(e.arm)))), max(clock.values()))


def min_separation(schedule: Schedule, jobs: Sequence[ArmJob], step_s: float = 0.05) -> float:
    """The least distance between two arms' body segments (from above) over the schedule,
    sampled every ``step_s`` with each tool moving straight during a move: the
    independent check that granted claims keep the arms apart."""
    by = {j.name: j for j in jobs}

    def tool_at(name: str, t: float) -> np.ndarray:
        pos = np.asarray(by[name].start, dtype=float)
        for s, e, _end, a, b, _label in schedule.timeline[name]:
            if t < s:
                break
            if t <= e:
                f = 1.0 if e == s else (t - s) / (e - s)
                here: np.ndarray = np.asarray(a, dtype=float) + f * (np.asarray(b, dtype=float) - np.asarray(a, dtype=float))
                return here
            pos = np.asarray(b, dtype=float)
        return pos

    names = [j.name for j in jobs]
    best = math.inf
    for t in np.arange(0.0, schedule.makespan_s + step_s, step_s):
        for i in range(len(names)):
            for k in range(i + 1, len(names)):
                a, b = names[i], names[k]
                d = segment_distance(np.asarray(by[a].base), tool_at(a, t), np.asarray(by[b].base), tool_at(b, t))
                best = min(best, d)
    return best
