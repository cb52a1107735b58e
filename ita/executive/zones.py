"""Interference zones for two arms on one part: claim before entering, clear after leaving.

The cell's floor is cut into square zones (a grid, :class:`ZoneGrid`, seen from above).
An arm's body lies between its base and its tool: from above, the segment base -> tool
thickened by the arm's half-width and a clearance (:attr:`ZoneGrid.radius`).  An arm at
rest holds the zones that thick segment touches; a move from tool point p to q sweeps
the triangle (base, p, q) (the arm turns about its base axis and stretches or folds),
and holds the zones within ``radius`` of it until the move ends.

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
from typing import Iterable, Sequence

import numpy as np

__all__ = ["ArmJob", "Move", "Schedule", "ZoneEvent", "ZoneGrid", "ZoneTable", "coordinate",
           "min_separation", "segment_distance"]

#: the arm's half-width plus clearance seen from above (m): a T3's forearm and wrist are
#: about 0.2 m across, a tool 0.2 m; with 0.1 m to spare
RADIUS_M = 0.25
#: zone size (m)
CELL_M = 0.1
#: a retreating arm folds its tool back to this distance from its base axis (m)
RETREAT_M = 0.5
#: tool speed of a retreat (m/s): the controller's TCP limit
RETREAT_SPEED = 0.75

Point = tuple[float, float]


def segment_distance(a: np.ndarray, b: np.ndarray, c: np.ndarray, d: np.ndarray) -> float:
    """Least distance between segments ab and cd in the plane."""
    def point_segment(p: np.ndarray, s: np.ndarray, e: np.ndarray) -> float:
        v = e - s
        t = 0.0 if not v.any() else float(np.clip(np.dot(p - s, v) / np.dot(v, v), 0.0, 1.0))
        return float(np.linalg.norm(p - (s + t * v)))

    def cross(o: np.ndarray, p: np.ndarray, q: np.ndarray) -> float:
        return float((p[0] - o[0]) * (q[1] - o[1]) - (p[1] - o[1]) * (q[0] - o[0]))

    d1, d2 = cross(c, d, a), cross(c, d, b)
    d3, d4 = cross(a, b, c), cross(a, b, d)
    if ((d1 > 0) != (d2 > 0)) and ((d3 > 0) != (d4 > 0)) and d1 * d2 < 0 and d3 * d4 < 0:
        return 0.0
    return min(point_segment(a, c, d), point_segment(b, c, d), point_segment(c, a, b), point_segment(d, a, b))


@dataclass(frozen=True)
class ZoneGrid:
    """Square zones of side ``cell`` (m) over the rectangle ``low``..``high`` seen from above;
    zone (i, j) is numbered ``i * ny + j`` (the order claims are listed in)."""

    low: Point
    high: Point
    cell: float = CELL_M
    radius: float = RADIUS_M

    @classmethod
    def around(cls, points: Iterable[Sequence[float]], margin: float = 0.5, cell: float = CELL_M,
               radius: float = RADIUS_M) -> "ZoneGrid":
        """A grid over the points (bases and targets, world x, y) with a margin."""
        xy = np.asarray([(float(p[0]), float(p[1])) for p in points])
        lo, hi = xy.min(axis=0) - margin - radius, xy.max(axis=0) + margin + radius
        return cls((float(lo[0]), float(lo[1])), (float(hi[0]), float(hi[1])), cell, radius)

    @property
    def shape(self) -> tuple[int, int]:
        return (max(1, math.ceil((self.high[0] - self.low[0]) / self.cell)),
                max(1, math.ceil((self.high[1] - self.low[1]) / self.cell)))

    def _centres(self) -> np.ndarray:
        nx, ny = self.shape
        i, j = np.meshgrid(np.arange(nx), np.arange(ny), indexing="ij")
        return np.stack([self.low[0] + (i + 0.5) * self.cell, self.low[1] + (j + 0.5) * self.cell], -1).reshape(-1, 2)

    def near_polygon(self, corners: Sequence[Sequence[float]]) -> frozenset[int]:
        """Zones any point of which lies within ``radius`` of the polygon (a point, a
        segment or a triangle, its corners from above): a zone is taken when its centre
        is within ``radius`` plus its half-diagonal (so never too few)."""
        P = np.asarray(corners, dtype=float)[:, :2]
        c = self._centres()
        reach = self.radius + self.cell * math.sqrt(0.5)
        dist = np.full(len(c), np.inf)
        k = len(P)
        for a in range(k):
            s, e = P[a], P[(a + 1) % k]
            v = e - s
            vv = float(np.dot(v, v))
            t = np.zeros(len(c)) if vv == 0 else np.clip((c - s) @ v / vv, 0.0, 1.0)
            dist = np.minimum(dist, np.linalg.norm(c - (s + t[:, None] * v), axis=1))
        if k == 3:                                    # inside the triangle: distance 0
            sign = [np.sign((P[(a + 1) % 3, 0] - P[a, 0]) * (c[:, 1] - P[a, 1])
                            - (P[(a + 1) % 3, 1] - P[a, 1]) * (c[:, 0] - P[a, 0])) for a in range(3)]
            inside = ((sign[0] >= 0) & (sign[1] >= 0) & (sign[2] >= 0)) | ((sign[0] <= 0) & (sign[1] <= 0) & (sign[2] <= 0))
            dist[inside] = 0.0
        return frozenset(int(z) for z in np.flatnonzero(dist <= reach))

    def at_rest(self, base: Point, tool: Point) -> frozenset[int]:
        """The zones an arm holds at rest with its tool at ``tool``."""
        return self.near_polygon([base, tool])

    def swept(self, base: Point, start: Point, end: Point) -> frozenset[int]:
        """The zones an arm sweeps moving its tool from ``start`` to ``end``."""
        return self.near_polygon([base, start, end])

    def base_zone(self, base: Point, toward: Point, retreat_m: float = RETREAT_M) -> frozenset[int]:
        """The zones an arm retreated toward ``toward`` holds (its base and a stub)."""
        return self.at_rest(base, retreat_point(base, toward, retreat_m))


def retreat_point(base: Point, tool: Point, retreat_m: float = RETREAT_M) -> Point:
    """Where a retreating arm folds its tool back to: on its base ray, ``retreat_m`` out."""
    v = np.asarray(tool, dtype=float) - np.asarray(base, dtype=float)
    n = float(np.linalg.norm(v))
    if n <= retreat_m:
        return (float(tool[0]), float(tool[1]))
    p = np.asarray(base, dtype=float) + v * (retreat_m / n)
    return (float(p[0]), float(p[1]))


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

    def go(name: str, target: Point, move_s: float, dwell_s: float, label: str, kind: str = "grant") -> None:
        job, t0 = by_name[name], clock[name]
        sweep = grid.swept(job.base, tool[name], target)
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
            go(name, move.target, move.move_s, move.dwell_s, move.label)
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
        go(loser, back, dist / RETREAT_SPEED, 0.0, "retreat", kind="retreat")
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
