"""Interference zones for two arms on one part: claim before entering, clear after leaving.

The zones and the arms' bodies in them are ita.collision.zones: cubic zones of the cell's
space; with a body model (an arm's collision tubes and its tools' from its kinematics) and
the moves' configurations, an arm at rest holds the zones of its tubes, a move the zones
of every pose along it (:class:`Footprints`); without, the columns of the segment base ->
tool seen from above and of the triangle a move sweeps.

Claims are reservations in time (:class:`ZoneTable`): a claim is granted when none of its
zones is held by the other arm in an overlapping interval (request -> grant), otherwise
the arm WAITs until the other's holding ends and asks again (CONTINUE); after a move the
arm keeps only its rest zones (clear).  Zone sets that do not meet keep the arms' tubes
at least ``MARGIN_M`` apart in 3-D (without body models, the segments ``2 * radius``
apart from above: :func:`min_separation`); the simulator's arms check it in 3-D
(ita.sim.arms).  A move may be made straight in joint space or by way of a stop (the arm
folded and turned, or its wrist first or last): the first way whose claim is granted is
taken.

No deadlock (:func:`coordinate`), the arms in priority order:

- A waiting arm holds only its rest zones.  An arm after the first also holds, at rest,
  its way back: the zones of folding from there (base joint kept) and of the folded
  arm.  So its retreat, a fold along its own base ray, is always granted.
- An arm that waits for another's rest zones waits for that arm's next step; an arm of
  lower priority for whose rest zones a higher one waits gives way at its next step: it
  retreats.  An arm of lower priority never parks where the next move of a higher one
  goes (it waits for that move instead).
- If each waits for the other, or the other is done and parked in the way, one retreats
  (the one of lower priority, or the parked one, first).  Then the first arm's claims are
  refused only by the folded arms' zones, which its targets keep clear of (the
  allocation's rule, ita.sequence.allocate), so it finishes; then the next; every wait
  ends.  A case outside those rules (a target in the other's base zone, a way back that
  meets a zone held before it was claimed) raises :class:`Deadlock` at once, never waits
  for ever.

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
    ArmBody,
    Point,
    ZoneGrid,
    Zones,
    retreat_point,
    segment_distance,
)

__all__ = ["RADIUS_M", "RETREAT_SPEED", "ArmJob", "Deadlock", "configurations_at", "Move", "Schedule", "ZoneEvent", "ZoneGrid",
           "ZoneTable", "coordinate", "min_separation", "segment_distance"]

#: tool speed of a retreat (m/s): the controller's TCP limit
RETREAT_SPEED = 0.75
#: the least time of a retreat (s): folding the arm is a joint move, however near
RETREAT_MIN_S = 1.0
#: a sampled move's link points move at most this far between samples (m)
SAMPLE_M = 0.05

@dataclass(frozen=True)
class Move:
    """One step of an arm's work: move its tool to ``target`` (world x, y) in ``move_s``,
    then stay there ``dwell_s`` (measuring, a tool change); ``label`` names it; ``q``
    the configuration it takes there (for a check of the bodies in 3-D); ``tool_change``:
    it takes or puts down a tool, so when a downed arm bars it, the moves up to the next
    tool change (made with that tool) are barred with it."""

    target: Point
    move_s: float
    dwell_s: float
    label: str = ""
    q: tuple[float, ...] = ()        # the arm's configuration there (rad), when known
    via: tuple[float, ...] = ()      # a configuration to pass through, tried before the other ways
    tool_change: bool = False


@dataclass(frozen=True)
class ArmJob:
    """An arm's base (world x, y), where its tool starts, and its moves in order."""

    name: str
    base: Point
    start: Point
    moves: tuple[Move, ...]
    body: ArmBody | None = None                              # its tubes and its polyline from above
    home: tuple[float, ...] = ()                             # its configuration at the start
    fold: tuple[float, ...] = ()                             # where a retreat folds it (base joint kept)
    down: bool = False                                       # stopped for good where it is: never moves


class Footprints:
    """The zones an arm holds: with its body model and the moves' configurations, those of
    its links' polyline at rest and of every pose along a move (joint-space straight
    line, sampled so no link point moves more than :data:`SAMPLE_M` between samples, the
    radius grown by half that); without, the segment base -> tool and the triangle a
    move sweeps.  Sweeps are kept: the same move costs one computation."""

    def __init__(self, grid: ZoneGrid) -> None:
        self.grid = grid
        self._sweeps: dict[tuple[str, bytes, bytes], Zones] = {}

    def rest(self, job: ArmJob, xy: Point, q: np.ndarray | None) -> Zones:
        if job.body is None or q is None:
            return self.grid.at_rest(job.base, xy)
        return self.grid.near_tubes(job.body.tubes(q[None]), job.body.radii)

    def sweep(self, job: ArmJob, xy0: Point, q0: np.ndarray | None, xy1: Point, q1: np.ndarray | None) -> Zones:
        if job.body is None or q0 is None or q1 is None:
            return self.grid.swept(job.base, xy0, xy1)
        a, b = sorted((q0.tobytes(), q1.tobytes()))
        key = (job.name, a, b)
        if key not in self._sweeps:
            ends = job.body.tubes(np.stack([q0, q1]))                            # (2, T, 2, 3)
            far = float(np.max(np.linalg.norm(ends[..., :2] - np.asarray(job.base), axis=-1)))   # farthest point
            n = max(2, math.ceil(float(np.max(np.abs(q1 - q0))) * (far + 1.0) / SAMPLE_M) + 1)
            tubes = job.body.tubes(q0 + np.linspace(0.0, 1.0, n)[:, None] * (q1 - q0))
            step = float(np.max(np.linalg.norm(np.diff(tubes, axis=0), axis=-1))) if n > 1 else 0.0
            self._sweeps[key] = self.grid.near_tubes(tubes, job.body.radii + step / 2)
        return self._sweeps[key]


@dataclass(frozen=True)
class ZoneEvent:
    """request, grant, wait, continue, clear, retreat or skip (a move a downed arm bars),
    of arm ``arm`` at ``t`` (s)."""

    t: float
    arm: str
    kind: str
    label: str = ""
    zones: int = 0


@dataclass
class ZoneTable:
    """Who holds which zones when: each arm's reservations (start, end, zones), end
    ``inf`` for a rest pose held until the arm moves again."""

    holdings: dict[str, list[tuple[float, float, Zones]]] = field(default_factory=dict)

    def conflict(self, arm: str, start: float, end: float, zones: Zones) -> tuple[float, str] | None:
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

    def reserve(self, arm: str, start: float, end: float, zones: Zones) -> None:
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
    vias: dict[str, dict[int, tuple[float, ...]]] = field(default_factory=dict)   # arm -> step -> via configuration
    skipped: dict[str, tuple[str, ...]] = field(default_factory=dict)   # arm -> moves a downed arm's body barred


class Deadlock(RuntimeError):
    """The coordination could not go on (never expected: see the module docstring)."""


def coordinate(grid: ZoneGrid, jobs: Sequence[ArmJob], max_steps: int = 1_000_000,
               feet: Footprints | None = None) -> Schedule:
    """Play the arms' moves in simulated time through the zone table: each move's swept
    zones claimed before it starts, the rest zones kept after; a refused claim waits for
    the holder's release; a mutual wait makes the arm later in ``jobs`` retreat.  Raises
    :class:`Deadlock` if no arm can go on (the targets break the allocation's rule).
    feet: the zones of moves already computed on ``grid`` (kept between calls)."""
    table = ZoneTable()
    if feet is None or feet.grid != grid:
        feet = Footprints(grid)
    clock = {j.name: 0.0 for j in jobs}
    tool = {j.name: j.start for j in jobs}
    conf: dict[str, np.ndarray | None] = {j.name: (np.asarray(j.home, dtype=float) if j.home else None) for j in jobs}
    nxt = {j.name: 0 for j in jobs}
    busy = {j.name: 0.0 for j in jobs}
    waiting = {j.name: 0.0 for j in jobs}
    retreats = {j.name: 0 for j in jobs}
    timeline: dict[str, list[tuple[float, float, float, Point, Point, str]]] = {j.name: [] for j in jobs}
    events: list[ZoneEvent] = []
    blocked: dict[str, bool] = {j.name: False for j in jobs}
    by_name = {j.name: j for j in jobs}
    priority = [j.name for j in jobs]

    def go(name: str, target: Point, q: np.ndarray | None, move_s: float, dwell_s: float, label: str,
           sweep: Zones, rest: Zones, kind: str = "grant") -> None:
        t0 = clock[name]
        table.clear_from(name, t0)
        table.reserve(name, t0, t0 + move_s, sweep)
        table.reserve(name, t0 + move_s, math.inf, rest)
        events.append(ZoneEvent(t0, name, kind, label, sweep.bit_count()))
        events.append(ZoneEvent(t0 + move_s, name, "clear", label, sweep.bit_count()))
        timeline[name].append((t0, t0 + move_s, t0 + move_s + dwell_s, tool[name], target, label))
        tool[name], conf[name] = target, q
        clock[name] = t0 + move_s + dwell_s
        busy[name] += move_s + dwell_s

    def moved_q(move: Move) -> np.ndarray | None:
        return np.asarray(move.q, dtype=float) if move.q else None

    def fold_of(arm: str, t0: float) -> tuple[Point, np.ndarray | None, Zones, Zones] | None:
        """Where `arm` folds back to from now on, if that claim can be granted: its fold
        (base joint kept) with a body model, else along its base ray; None if it is
        folded already or the fold meets the other's zones."""
        job, q_now = by_name[arm], conf[arm]
        if job.down:
            return None
        if job.body is not None and q_now is not None and job.fold:
            q_back: np.ndarray | None = np.asarray(job.fold, dtype=float).copy()
            assert q_back is not None
            q_back[0] = q_now[0]                            # the base joint kept: the arm stays on its ray
            tip = job.body(q_back[None])[0, -1]
            back = (float(tip[0]), float(tip[1]))
            if np.allclose(q_back, q_now):
                return None
        else:
            q_back, back = None, retreat_point(job.base, tool[arm])
            if back == tool[arm]:
                return None
        start = max(clock[arm], t0)
        sweep = feet.sweep(job, tool[arm], q_now, back, q_back)
        rest = feet.rest(job, back, q_back)
        if table.conflict(arm, start, math.inf, sweep | rest) is not None:
            return None
        return back, q_back, sweep, rest

    stuck: dict[str, str | None] = {j.name: None for j in jobs}     # whose rest zones it waits for
    folded = {j.name: False for j in jobs}                            # retreated since its last move
    vias: dict[str, dict[int, tuple[float, ...]]] = {j.name: {} for j in jobs}
    skipped: dict[str, list[str]] = {j.name: [] for j in jobs}

    def retreat(arm: str, t0: float) -> bool:
        """Fold `arm` back now if that claim can be granted (see fold_of)."""
        found = fold_of(arm, t0)
        if found is None:
            return False
        back, q_back, sweep, rest = found
        clock[arm] = max(clock[arm], t0)
        dist = float(np.hypot(tool[arm][0] - back[0], tool[arm][1] - back[1]))
        seconds = max(dist / RETREAT_SPEED, RETREAT_MIN_S)
        go(arm, back, q_back, seconds, 0.0, "retreat", sweep, rest, kind="retreat")
        busy[arm] -= seconds
        waiting[arm] += seconds
        retreats[arm] += 1
        folded[arm] = True
        return True

    def held_at(name: str, xy: Point, q: np.ndarray | None) -> Zones:
        """The zones an arm holds at rest there: its body's, and for an arm that may have to
        give way (not the first), its way back too: the fold from there (base joint kept)
        and the folded arm.  With its way back held, a retreat is always granted."""
        job = by_name[name]
        rest = feet.rest(job, xy, q)
        if name == priority[0] or job.down:
            return rest
        if job.body is not None and q is not None and job.fold:
            q_back = np.asarray(job.fold, dtype=float).copy()
            q_back[0] = q[0]
            tip = job.body(q_back[None])[0, -1]
            back = (float(tip[0]), float(tip[1]))
            return rest | feet.sweep(job, xy, q, back, q_back) | feet.rest(job, back, q_back)
        return rest | feet.rest(job, retreat_point(job.base, xy), None)

    def claims(name: str, move: Move) -> list[tuple[Zones, Zones, float, np.ndarray | None]]:
        """The ways to make a move, each as the zones it sweeps and holds after, its seconds
        and the configuration it passes through (None: straight in joint space).  With a
        body model: straight (not for a folded arm), then by way of the arm folded and
        turned to the target's base joint, of the target's arm with the wrist as it is,
        and of the arm as it is with the target's wrist; a way with a stop costs the
        seconds of a retreat more (an estimate: the stop's own motion time is not
        modelled)."""
        job, q0, q1 = by_name[name], conf[name], moved_q(move)
        rest = held_at(name, move.target, q1)
        Way = tuple[Zones, Zones, float, np.ndarray | None]
        straight: Way = (feet.sweep(job, tool[name], q0, move.target, q1), rest, move.move_s, None)
        if q0 is None or q1 is None or job.body is None:
            return [straight]
        ways: list[Way] = [] if folded[name] else [straight]
        turned = np.asarray(job.fold, dtype=float).copy() if job.fold else q0.copy()
        turned[0] = q1[0]
        stops = [turned, np.concatenate([q1[:3], q0[3:]]), np.concatenate([q0[:3], q1[3:]])]
        if move.via:
            stops.insert(0, np.asarray(move.via, dtype=float))
            ways = []
        for via in stops:
            tip = job.body(via[None])[0, -1]
            mid = (float(tip[0]), float(tip[1]))
            sweep = feet.sweep(job, tool[name], q0, mid, via) | feet.sweep(job, mid, via, move.target, q1)
            ways.append((sweep, rest, move.move_s + RETREAT_MIN_S, via))
        return ways if not folded[name] and not move.via else ways + [straight]

    for j in jobs:
        table.reserve(j.name, 0.0, math.inf, held_at(j.name, j.start, conf[j.name]))
    for _ in range(max_steps):
        live = [n for n in priority if nxt[n] < len(by_name[n].moves)]
        if not live:
            break
        name = min(live, key=lambda n: (clock[n], priority.index(n)))
        job, t0 = by_name[name], clock[name]
        table.forget_before(min(clock[n] for n in live))
        # an arm of higher priority waits for this one's rest zones: this one gives way
        if any(stuck[h] == name for h in priority[:priority.index(name)]) and not folded[name]:
            if retreat(name, t0):
                continue
        move = job.moves[nxt[name]]
        # the next moves of the arms of higher priority: no way may leave this arm in them
        ahead: Zones = 0
        for h in priority[:priority.index(name)]:
            if nxt[h] < len(by_name[h].moves):
                h_sweep, h_rest, _s, _v = claims(h, by_name[h].moves[nxt[h]])[0]
                ahead = ahead | h_sweep | h_rest
        found: tuple[float, str] | None = None
        in_way = False
        for k, (sweep, rest, seconds, via) in enumerate(claims(name, move)):
            conflict = table.conflict(name, t0, math.inf, sweep | rest)
            if conflict is None and rest & ahead:
                in_way = True
                continue
            if conflict is None:
                found = None
                break
            if k == 0:
                found = conflict                          # what the first way waits for
        else:
            if in_way and found is None:                  # every free way parks it where a higher one goes next
                h = next(h for h in priority[:priority.index(name)] if nxt[h] < len(by_name[h].moves))
                found = (math.inf, h)
        if found is None:                                   # request -> grant
            events.append(ZoneEvent(t0, name, "continue" if blocked[name] else "request", move.label, sweep.bit_count()))
            blocked[name], stuck[name], folded[name] = False, None, False
            if via is not None:
                vias[name][len(timeline[name])] = tuple(map(float, via))
            go(name, move.target, moved_q(move), seconds, move.dwell_s, move.label, sweep, rest)
            busy[name] -= seconds - move.move_s                 # the turn while folded is a retreat's cost
            waiting[name] += seconds - move.move_s
            nxt[name] += 1
            continue
        if not blocked[name]:
            events.append(ZoneEvent(t0, name, "wait", move.label))
            blocked[name] = True
        until, other = found
        if math.isinf(until) and by_name[other].down:       # a downed arm's body in the way for good
            barred = [move]
            while move.tool_change and nxt[name] + len(barred) < len(job.moves) \
                    and not job.moves[nxt[name] + len(barred)].tool_change:
                barred.append(job.moves[nxt[name] + len(barred)])     # made with the tool it could not take
            for m in barred:
                events.append(ZoneEvent(t0, name, "skip", m.label))
                skipped[name].append(m.label)
            blocked[name] = False
            nxt[name] += len(barred)
            continue
        if not math.isinf(until):                           # cleared at a known time: wait for it
            waiting[name] += until - t0
            clock[name] = until
            continue
        other_moves = nxt[other] < len(by_name[other].moves)
        mine_first = priority.index(name) < priority.index(other)
        if other_moves and stuck[other] != name:
            # it moves on (or, of lower priority, gives way) at its next step: wait for that
            stuck[name] = other
            later = clock[other] if clock[other] > t0 else t0 + 1e-6
            waiting[name] += later - t0
            clock[name] = later
            continue
        # each waits for the other's rest zones, or the other is done, or folded, in the way:
        # one folds back (the other, when it is done or of lower priority, first)
        order = (other, name) if (not other_moves or mine_first) else (name, other)
        if not any(retreat(arm, t0) for arm in order):
            raise Deadlock(f"{name} waits for zones {other} holds, and neither can fold back clear of the "
                           f"other (a target in the other arm's base zone, or zones where neither can give way)")
        stuck[order[0]] = stuck[order[1]] = None
    else:
        raise Deadlock(f"no end after {max_steps} steps")
    return Schedule(tuple(priority), {n: tuple(v) for n, v in timeline.items()}, busy, waiting, retreats,
                    tuple(sorted(events, key=lambda e: (e.t, priority.index(e.arm)))), max(clock.values()), vias,
                    {n: tuple(v) for n, v in skipped.items()})


def configurations_at(schedule: Schedule, jobs: Sequence[ArmJob], times: np.ndarray) -> dict[str, np.ndarray]:
    """Each arm's configuration (``(len(times), 6)`` rad) at the given times of the
    schedule: its home before its first move, at rest where its last move ended, moving
    straight in joint space during a move; a retreat folds it (its ``fold``, the base
    joint kept, as the zones assume)."""
    out = {}
    for job in jobs:
        steps = []                                 # (start, end, q_from, q_to)
        q_prev = np.asarray(job.home, dtype=float)
        k = 0
        vias = schedule.vias.get(job.name, {})
        for n, (s, e, _end, _a, _b, label) in enumerate(schedule.timeline[job.name]):
            if label == "retreat":
                q_to = np.asarray(job.fold, dtype=float).copy()
                q_to[0] = q_prev[0]
            else:
                while job.moves[k].label != label:  # a move a downed arm barred is not in the timeline
                    k += 1
                q_to = np.asarray(job.moves[k].q, dtype=float)
                k += 1
            if n in vias:                          # by way of a stop: half the time to it, half from it
                via = np.asarray(vias[n], dtype=float)
                steps.append((s, (s + e) / 2, q_prev, via))
                steps.append(((s + e) / 2, e, via, q_to))
            else:
                steps.append((s, e, q_prev, q_to))
            q_prev = q_to
        q = np.empty((len(times), len(job.home)))
        starts = np.array([st[0] for st in steps])
        for n, t in enumerate(times):
            i = int(np.searchsorted(starts, t, side="right")) - 1
            if i < 0:
                q[n] = job.home
                continue
            s, e, a, b = steps[i]
            f = 1.0 if t >= e or e <= s else (t - s) / (e - s)
            q[n] = a + f * (b - a)
        out[job.name] = q
    return out


def min_separation(schedule: Schedule, jobs: Sequence[ArmJob], step_s: float = 0.05) -> float:
    """The least distance between two arms' bodies seen from above over the schedule,
    sampled every ``step_s``: their links' polylines where the jobs have a body model and
    configurations (:func:`configurations_at`), else the segments base -> tool with each
    tool moving straight.  The check, by geometry alone, of what the claims promise."""
    times = np.arange(0.0, schedule.makespan_s + step_s, step_s)
    paths = {}
    for job in jobs:
        if job.body is not None and job.home and all(m.q for m in job.moves):
            paths[job.name] = job.body(configurations_at(schedule, [job], times)[job.name])
        else:
            tools = np.array([_tool_at(schedule, job, t) for t in times])
            paths[job.name] = np.stack([np.broadcast_to(np.asarray(job.base, dtype=float), tools.shape), tools], axis=1)
    names = [j.name for j in jobs]
    best = math.inf
    for i in range(len(names)):
        for k in range(i + 1, len(names)):
            A, B = paths[names[i]], paths[names[k]]
            for n in range(len(times)):
                for u in range(A.shape[1] - 1):
                    for v in range(B.shape[1] - 1):
                        best = min(best, segment_distance(A[n, u], A[n, u + 1], B[n, v], B[n, v + 1]))
    return best


def _tool_at(schedule: Schedule, job: ArmJob, t: float) -> np.ndarray:
    """The tool's point (x, y) at ``t``, moving straight during a move."""
    pos = np.asarray(job.start, dtype=float)
    for s, e, _end, a, b, _label in schedule.timeline[job.name]:
        if t < s:
            break
        if t <= e:
            f = 1.0 if e == s else (t - s) / (e - s)
            here: np.ndarray = np.asarray(a, dtype=float) + f * (np.asarray(b, dtype=float) - np.asarray(a, dtype=float))
            return here
        pos = np.asarray(b, dtype=float)
    return pos
