"""The zone conductor of a two-arm run: it grants each arm's motions their space, live.

Each arm's controller (ita.robot.gate) claims every motion before it makes it: the zones
the motion sweeps (its joint trajectory, sampled so no point of the arm moves more than
:data:`STEP_M` between samples, each sample's collision tubes
and its tools', ita.collision.zones) and the zones it holds at rest where the motion
ends.  The conductor keeps who holds what when (:class:`~ita.executive.zones.ZoneTable`,
reservations in simulated time) and answers each claim (:class:`~ita.robot.gate.Grant`):
go after a wait (WAIT until the holder's release, then CONTINUE), fold back first, or
refuse.

**Simulated time, not wall time.**  The arms run in their own processes, each with its
own clock.  A claim made at an arm's time t is decided only when every other arm's clock
is known to be at t or later (it has a claim waiting at a later time, or its last granted
motion ends later, or it is done): the conservative rule of parallel discrete-event
simulation.  So the decisions, the waits and the run's figures do not depend on which
process the machine happens to run faster; ties go to the arm of higher priority (the
cell's first arm first).

**News.**  What one arm's diagnosis found of what both share (ita.toplevel.shared) is told
here and handed to the other arm with the answer to its first claim at that simulated
time or later (or with a fact it takes): in simulated time too.

**No deadlock** (the rules of ita.executive.zones.coordinate, applied live):

- An arm holds, at rest, its body's zones; a motion, the zones it sweeps until it ends.
  (An earlier rule had the arm after the first hold its way back too, so that its fold
  was always granted; those zones are about three times its body's, and the first arm
  then waited for it at most of its claims: a whole two-arm run of the default cell took
  2,055 s of simulated cycle with it, 1,287 s without.)
- No claim is granted into a state where neither arm could fold (each one's way back
  meeting the other's body): such a claim waits as if it met the other's body.  So at
  any time at least one of the two arms can fold.
- A claim that meets another arm's motion waits for that motion's end.  A claim that
  meets another arm's body waits for that arm's next claim; if that arm is of lower
  priority, and its next claim would still leave it in the way, it folds back instead
  (it gives way; when the first arm's body stands on its way back, the first arm folds
  first, once, and the lower arm's claim waits for the first's next claim; when the first
  cannot or has folded already, the lower goes on with its claim instead, and so moves).
  Each arm's Path Planner keeps clear of where the other may stand folded
  (:func:`folded_ground`), so with the other folded, an arm's claims are granted.
- If each waits for the other's body, the one of lower priority folds; when its way
  back meets the other's body (or it is folded already), the other folds first; when
  neither can, the lower arm's claim is refused (below) and the first arm's waits for
  the lower's next claim.  The
  allocation (ita.sequence.allocate) keeps every measuring pose of each arm, and its way
  back to its fold, clear of the other arm folded, so with one arm folded the other can
  go on, or fold itself.
- A case outside these rules (a claim that meets an arm that is done, or neither arm
  able to fold) is refused: the controller replies REJECTED, and the Top Level's
  Exception Handler deals with that measurement (it stays not done, with the reason);
  the conductor never waits for ever.

    conductor = Conductor(zone_grid(cell), conducted_arms(cell))   # the cell's arms, the first first
    replies = conductor.receive("t3", ("claim", t, times, q))   # [(arm, reply), ...] to send
    conductor.summary(), conductor.paths                        # figures; every motion made, in time
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ita.collision.tree import Regions
from ita.collision.zones import ArmBody, Revolved, ZoneGrid, Zones, arm_body, folded_configuration
from ita.executive.zones import ZoneEvent, ZoneTable
from ita.kinematics import arm_model
from ita.path.trajectory import TimedTrajectory
from ita.robot.waypoints import retreat_paths
from ita.workcell import Workcell

__all__ = ["GRID_MARGIN_M", "ConductedArm", "Conductor", "Motion", "conducted_arms", "folded_ground", "standing_ground",
           "zone_grid"]

#: the zones reach this far (m) around the arms' bases: farther than either arm with a tool
GRID_MARGIN_M = 3.5
#: a motion's poses are sampled so no point of the arm moves farther than this between two
#: (m); each sample's tubes are grown by half the farthest move (so the zones cover it all)
STEP_M = 0.1
#: a fold keeps the arm's body within this distance (m) behind its base
FOLD_BEHIND_M = 0.2
#: zone sets kept for poses and motions seen before
CACHE_SIZE = 20_000
#: ways back (their swept tubes) kept: an arm standing still is asked about the same ones
RETREAT_CACHE = 64

FloatArray = NDArray[np.float64]
Reply = tuple[str, float, "tuple[float, ...] | None", str]
#: the ways an arm may retreat from its joints to its folded joints (its controller flies one)
Retreat = Callable[[FloatArray, FloatArray], list[TimedTrajectory]]


@dataclass(frozen=True)
class ConductedArm:
    """An arm the conductor answers for: its name, body (collision tubes and tools'), folded
    configuration (its base joint is kept when it folds), where it starts, and the ways it
    may retreat (``retreat(q_from, q_fold)``: ita.robot.waypoints.retreat_paths; the
    conductor claims them all)."""

    name: str
    body: ArmBody
    fold: tuple[float, ...]
    home: tuple[float, ...]
    retreat: Retreat


@dataclass(frozen=True)
class Motion:
    """A motion granted and made: its start (s, the run's simulated time), its knots'
    times (from the start) and joints."""

    arm: str
    start_s: float
    times: FloatArray
    q: FloatArray
    kind: str = "move"

    @property
    def end_s(self) -> float:
        return self.start_s + float(self.times[-1])


@dataclass
class _Claim:
    asked_s: float          # when the arm asked
    t: float                # when it is now to be decided (later after a wait)
    times: FloatArray
    q: FloatArray
    park: bool = False
    zones: tuple[Zones, Zones] | None = None     # (swept, held after), once computed
    pinned: bool = False    # the arm cannot fold before this motion (its probe pressed on the part)


@dataclass
class _State:
    arm: ConductedArm
    q: FloatArray
    floor: float = 0.0                  # the arm makes no claim before this simulated time
    pending: _Claim | None = None
    stuck_on: str | None = None         # whose rest zones its claim waits for
    done: bool = False
    folded: bool = False
    busy_s: float = 0.0
    folds: int = 0
    refused: int = 0
    claims: int = 0
    last_s: float = 0.0
    refusals: list[str] = field(default_factory=list)
    taking: tuple[str, float] | None = None     # (key, time) of a fact it waits for
    of_work: bool = False                       # only the other arm's work posts it (ita.robot.gate)
    no_fold_at: FloatArray | None = None        # where a fold of it stopped short: it cannot fold from there
    stood_refused: bool = False                 # its last claim was refused, neither arm able to give way,
                                                # and it has not moved since


def conducted_arms(cell: Workcell) -> list[ConductedArm]:
    """The conductor's view of each arm of `cell`, the first first: its body with every tool
    of the cell (whichever it holds), its fold, its home and its straight moves' timing."""
    out = []
    for arm in cell.arms():
        view = cell.seen_by(arm.name)
        model = arm_model(view.arm)
        body = arm_body(model, view.tools)
        # folded forward (never far behind its base: a fence may stand there)
        fold, _ = folded_configuration(model, view.arm.joints.lower, view.arm.joints.upper, body, behind_m=FOLD_BEHIND_M)

        def retreat(a: np.ndarray, b: np.ndarray, model: Any = model) -> list[TimedTrajectory]:
            return retreat_paths(model, a, b)

        out.append(ConductedArm(arm.name, body, tuple(map(float, fold)), tuple(map(float, view.arm.home)), retreat))
    return out


def folded_ground(cell: Workcell, margin: float | None = None) -> Regions:
    """Where each other arm of `cell` (the cell as its working arm sees it) may stand
    folded on its base, whatever its base joint (its fold as the conductor orders it,
    ita.collision.zones.Revolved), grown by `margin` (default: a zone's full diagonal, so
    that a body outside it never shares a zone with the folded arm): upright tubes about
    its base axis, a band of heights each.  The working arm's Path Planner keeps clear of
    it in a two-arm run: with the other arm folded, every motion of this one is then
    granted (the allocation keeps its measuring poses clear of the same ground)."""
    grid = zone_grid(cell)
    gap = grid.apart_m if margin is None else margin
    tubes: list[tuple[tuple[float, float, float], tuple[float, float, float], float]] = []
    for other in conducted_arms(cell):
        if other.name == cell.arm.name:
            continue
        base = next(a for a in cell.arms() if a.name == other.name).base.position
        ground = Revolved.of(other.body, np.asarray(other.fold, dtype=float), (float(base[0]), float(base[1])),
                             grid.z_high)
        tubes += [((ground.axis[0], ground.axis[1], z0), (ground.axis[0], ground.axis[1], z1), r)
                  for z0, z1, r in ground.bands(gap)]
    if not tubes:
        return Regions.empty()
    return Regions.tubes([a for a, _b, _r in tubes], [b for _a, b, _r in tubes], [r for _a, _b, r in tubes])


#: a hand-over's Path Planner keeps this far (m) from the other arm standing for good (the
#: zones, finer than the folded ground's margin, then say whether it may pass)
STANDING_MARGIN_M = 0.05


def standing_ground(cell: Workcell, stands: Mapping[str, Sequence[float]], margin: float = STANDING_MARGIN_M
                    ) -> Regions:
    """The bodies of the other arms of `cell` standing for good at their joints `stands`
    (arm -> joints; a hand-over's: they move no more), each tube grown by `margin`."""
    pieces = []
    for other in conducted_arms(cell):
        if other.name == cell.arm.name or other.name not in stands:
            continue
        ends = other.body.tubes(np.asarray(stands[other.name], dtype=float)[None])[0]      # (T, 2, 3)
        pieces.append(Regions.tubes(ends[:, 0], ends[:, 1], np.asarray(other.body.radii, dtype=float) + margin))
    return Regions.concat(pieces) if pieces else Regions.empty()


def zone_grid(cell: Workcell) -> ZoneGrid:
    """Zones over everything either arm can reach."""
    return ZoneGrid.around([(float(a.base.position[0]), float(a.base.position[1])) for a in cell.arms()],
                           margin=GRID_MARGIN_M)


def _densified(q: FloatArray, per_rad: float) -> FloatArray:
    """The knots ``q`` (k, dof) with each segment cut into ceil(largest joint change x
    per_rad) equal steps (at least one): the knots kept, the points as ``np.linspace``
    places them (k x 1/n, the last exactly the next knot)."""
    a, b = q[:-1], q[1:]
    n = np.maximum(1, np.ceil(np.max(np.abs(b - a), axis=1) * per_rad)).astype(np.int64)
    seg = np.repeat(np.arange(len(n)), n)
    k = np.arange(int(n.sum())) - np.repeat(np.cumsum(n) - n, n) + 1          # 1..n within each segment
    frac = k * (1.0 / n[seg])
    frac[k == n[seg]] = 1.0
    return np.concatenate([q[:1], a[seg] + frac[:, None] * (b - a)[seg]])


class Conductor:
    """Grants the arms' claims in simulated-time order (see the module docstring)."""

    def __init__(self, grid: ZoneGrid, arms: Sequence[ConductedArm]) -> None:
        self.grid = grid
        self.order = [a.name for a in arms]
        self.state = {a.name: _State(a, np.asarray(a.home, dtype=float)) for a in arms}
        self.table = ZoneTable()
        self.events: list[ZoneEvent] = []
        self.paths: list[Motion] = []
        self.posts: dict[str, tuple[float, Any]] = {}          # key -> (time posted, value), the first
        # news told to the other arms: (time told, by whom, value), in the order told; and
        # which of them each arm has heard
        self.news: list[tuple[float, str, Any]] = []
        self.heard: dict[str, set[int]] = {a.name: set() for a in arms}
        self._zones: dict[tuple[str, str, bytes], Zones] = {}
        # an arm's ways back from a pose (knots, their swept tubes and radii), the last few
        self._retreats: dict[tuple[str, bytes], list[tuple[FloatArray, tuple[FloatArray, FloatArray] | None]]] = {}
        self.cpu_s = 0.0                     # the conductor's own time (the caller counts it)
        for a in arms:
            st = self.state[a.name]
            self.table.reserve(a.name, 0.0, math.inf, self._rest(a.name, st.q))

    # -- zones -------------------------------------------------------------------------
    def _cached(self, key: tuple[str, str, bytes], make: Callable[[], Zones]) -> Zones:
        """Zones kept by key (an arm comes back to the same poses: approach, contact, retract)."""
        found = self._zones.get(key)
        if found is None:
            found = make()
            if len(self._zones) >= CACHE_SIZE:
                self._zones.pop(next(iter(self._zones)))
            self._zones[key] = found
        return found

    def _rest(self, name: str, q: FloatArray) -> Zones:
        body = self.state[name].arm.body
        q = np.asarray(q, dtype=float)
        return self._cached((name, "rest", q.tobytes()),
                            lambda: self.grid.near_tubes(body.tubes(q[None]), body.radii))

    def _sweep(self, name: str, times: FloatArray, q: FloatArray) -> Zones:
        """The zones of every pose along the motion (knots linear in between, sampled)."""
        q = np.asarray(q, dtype=float)
        if len(q) < 2:
            return self._rest(name, q[0])
        return self._cached((name, "sweep", q.tobytes()), lambda: self._swept_now(name, q))

    def _swept_now(self, name: str, q: FloatArray) -> Zones:
        return self.grid.near_tubes(*self._swept_tubes(name, q))

    def _swept_tubes(self, name: str, q: FloatArray) -> tuple[FloatArray, FloatArray]:
        """The tubes of every pose along the knots ``q`` (densified) and their radii, grown
        by half the largest step between two poses."""
        body = self.state[name].arm.body
        ends = body.tubes(q)                                              # (k, T, 2, 3)
        far = float(np.max(np.linalg.norm(ends[..., :2] - ends[:1, :1, :1, :2], axis=-1))) + 1.0
        dense = _densified(q, far / STEP_M)
        tubes = body.tubes(dense)
        step = float(np.max(np.linalg.norm(np.diff(tubes, axis=0), axis=-1))) if len(dense) > 1 else 0.0
        return tubes, body.radii + step / 2

    def _folded(self, name: str, q: FloatArray) -> FloatArray:
        fold = np.asarray(self.state[name].arm.fold, dtype=float).copy()
        fold[0] = q[0]                                   # the base joint kept: it folds on its own ray
        return fold

    def _ways_swept(self, name: str, ways: Sequence[TimedTrajectory]) -> Zones:
        """The zones of every way a retreat may take (the arm's controller flies one of them)."""
        zones = 0
        for way in ways:
            zones |= self._sweep(name, way.times, way.q)
        return zones

    def body(self, name: str, q: Sequence[float]) -> Zones:
        """The zones of arm `name`'s body (and tools) at joints `q`."""
        return self._rest(name, np.asarray(q, dtype=float))

    def swept(self, name: str, times: Sequence[float], q: Sequence[Sequence[float]]) -> Zones:
        """The zones a motion of arm `name` (knots' times and joints) sweeps."""
        return self._sweep(name, np.asarray(times, dtype=float), np.asarray(q, dtype=float))

    # -- messages ------------------------------------------------------------------------
    def receive(self, name: str, message: tuple[Any, ...]) -> list[tuple[str, Any]]:
        """Take one message of arm `name` (ita.robot.gate); the replies now due, to whom."""
        st = self.state[name]
        kind = message[0]
        if kind == "claim":
            t, times, q = message[1:4]
            pinned = len(message) > 4 and bool(message[4])
            st.pending = _Claim(float(t), float(t), np.asarray(times, dtype=float), np.asarray(q, dtype=float),
                                pinned=pinned)
            st.floor = float(t)
            st.claims += 1
        elif kind == "park":
            _, t, q = message
            st.q = np.asarray(q, dtype=float)
            st.pending = _Claim(float(t), float(t), np.zeros(1), st.q[None], park=True)
            st.floor = float(t)
        elif kind == "moved":
            t, q = message[1], message[2]
            if len(message) == 5:                   # the way a fold took: recorded as the motion made
                self._flown(name, np.asarray(message[3], dtype=float), np.asarray(message[4], dtype=float))
            self._moved(name, float(t), np.asarray(q, dtype=float))
        elif kind == "clock":                       # it makes no claim before then (ita.robot.gate)
            st.floor = max(st.floor, float(message[1]))
        elif kind == "done":
            self._finish(name, float(message[1]))
        elif kind == "post":
            _, t, key, value = message
            self.posts.setdefault(str(key), (float(t), value))
            st.floor = max(st.floor, float(t))
        elif kind == "tell":                        # news for the other arm (ita.robot.gate)
            _, t, value = message
            self.news.append((float(t), name, value))
            st.floor = max(st.floor, float(t))
        elif kind == "take":
            # while it waits for a fact it stands still (its body's zones) and is never asked
            # to fold (it gave way before it asked: ita.toplevel.registration)
            t = float(message[1])
            st.taking = (str(message[2]), t)
            st.of_work = len(message) > 3 and bool(message[3])
            self.table.clear_from(name, t)
            self.table.reserve(name, t, math.inf, self._rest(name, st.q))
            st.folded = True
            self._unstick(name)                    # who waits for its next claim: none comes before
        else:
            raise ValueError(f"arm {name}: unknown message {kind!r}")
        return self._settle()

    def gone(self, name: str) -> list[tuple[str, Any]]:
        """Arm `name`'s process ended (or broke off): it stays where it is, for good."""
        st = self.state[name]
        if not st.done:
            self._finish(name, st.floor)
        return self._settle()

    def idle(self, name: str) -> list[tuple[str, Any]]:
        """Arm `name` has no work in the run: it folds on its base ray at the start (out of
        the other's way, as its controller's park would) and is done there."""
        st = self.state[name]
        self._try_fold(name, _Claim(0.0, 0.0, np.zeros(1), st.q[None], park=True))
        self._finish(name, st.floor)
        return self._settle()

    def _finish(self, name: str, t: float) -> None:
        st = self.state[name]
        st.done, st.pending, st.floor = True, None, math.inf
        st.last_s = max(st.last_s, t)
        self.table.clear_from(name, t)                # it stands there for good: its body alone
        self.table.reserve(name, t, math.inf, self._rest(name, st.q))
        self.events.append(ZoneEvent(t, name, "done"))
        self._unstick(name)                         # who waited for its next claim: there is none

    def _flown(self, name: str, times: FloatArray, q: FloatArray) -> None:
        """Arm `name`'s last retreat took this way (one of those claimed for it)."""
        for k in range(len(self.paths) - 1, -1, -1):
            m = self.paths[k]
            if m.arm == name:
                if m.kind == "retreat" and len(times) >= 2:
                    self.paths[k] = Motion(name, m.start_s, times, q, "retreat")
                return

    def _moved(self, name: str, t: float, q: FloatArray) -> None:
        st = self.state[name]
        st.floor = max(st.floor, t)
        st.last_s = max(st.last_s, t)
        k = next((k for k in range(len(self.paths) - 1, -1, -1) if self.paths[k].arm == name), None)
        if not np.allclose(q, st.q, atol=1e-9):
            claimed = st.q
            st.q, st.stood_refused = q, False
            if np.max(np.abs(q - claimed)) > 1e-3:     # stopped short of the claim's end (a bump): hold where it is
                self.table.clear_from(name, t)
                self.table.reserve(name, t, math.inf, self._rest(name, q))
                st.folded = bool(np.allclose(self._folded(name, q), q, atol=1e-6))
                if k is not None and self.paths[k].kind == "retreat":
                    st.no_fold_at = q.copy()
        if k is not None and self.paths[k].end_s > t + 1e-9:
            last = self.paths[k]                        # cut the recorded motion where it ended
            keep = last.times <= t - last.start_s
            times = np.append(last.times[keep], t - last.start_s)
            qs = np.vstack([last.q[keep], q[None]])
            if len(times) >= 2 and np.all(np.diff(times) > 0):
                self.paths[k] = Motion(name, last.start_s, times, qs, last.kind)

    # -- deciding --------------------------------------------------------------------------
    def _settle(self) -> list[tuple[str, Any]]:
        out: list[tuple[str, Any]] = []
        for name in self.order:                    # facts waited for: posted, or no one left to post them
            st = self.state[name]
            if st.taking is None:
                continue
            key, t = st.taking
            if key in self.posts:
                at, value = self.posts[key]
                wait = max(0.0, at - t)
                st.taking, st.floor = None, t + wait
                st.folded = bool(np.allclose(self._folded(name, st.q), st.q, atol=1e-6))
                out.append(self._taken(name, (wait, value), at))
            elif all(self.state[o].done or (st.of_work and self.state[o].taking is not None)
                     for o in self.order if o != name):
                st.taking = None
                out.append(self._taken(name, (0.0, None), t))
        for _ in range(10_000):
            ready = [n for n in self.order if self.state[n].pending is not None and self.state[n].stuck_on is None]
            if not ready:
                break
            name = min(ready, key=lambda n: (self.state[n].pending.t, self.order.index(n)))   # type: ignore[union-attr]
            claim = self.state[name].pending
            assert claim is not None
            # another arm may still act before then: wait for news (an arm waiting for this
            # one's next claim does nothing before it)
            if any(self._floor(o) < claim.t for o in self.order if o != name):
                break
            t = claim.t
            out.extend(self._with_news(self._decide(name, claim), t))
        return out

    def _taken(self, name: str, reply: tuple[float, Any], t: float) -> tuple[str, Any]:
        """The answer to arm `name`'s take, with the other arms' news of `t` or before: `t`
        is when the fact was posted (its poster's clock is there at least, and one posted
        here, a hand-over, waits for every arm to ask or end) or, none posted, when no arm
        is left to post it: either way the other arms can tell no more of before then."""
        (_, answered), = self._with_news([(name, reply)], t)
        return name, answered

    def _with_news(self, replies: Sequence[tuple[str, tuple[Any, ...]]], t: float) -> list[tuple[str, Any]]:
        """Each reply with the other arms' news told at `t` or before that its arm has not
        heard yet (one item more, after the answer's own; none: the reply as it was).  Every other arm's clock is at
        `t` or later when a claim of `t` is decided, so all news of then has arrived: what
        an arm hears, and when, does not depend on which process runs faster."""
        out: list[tuple[str, Any]] = []
        for arm, reply in replies:
            fresh = [k for k, (at, by, _v) in enumerate(self.news) if by != arm and at <= t and k not in self.heard[arm]]
            if fresh:
                self.heard[arm].update(fresh)
                out.append((arm, (*reply, tuple((self.news[k][0], self.news[k][2]) for k in fresh))))
            else:
                out.append((arm, reply))
        return out

    def _floor(self, name: str) -> float:
        """The earliest simulated time arm `name` may still act at: its claim's (it waits for
        the answer), never while it waits for another's next claim, else its clock."""
        st = self.state[name]
        if st.stuck_on is not None or st.taking is not None:
            return math.inf
        return st.pending.t if st.pending is not None else st.floor

    def _decide(self, name: str, claim: _Claim) -> list[tuple[str, Reply]]:
        st = self.state[name]
        if claim.park:
            return self._park(name, claim)
        sweep, rest = self._claimed(name, claim)
        want = sweep | rest
        found = self.table.conflict(name, claim.t, math.inf, want)
        if found is None:
            # never into a state where neither arm could fold: as if it met the other's body
            blocked = self._unsafe(name, claim.q[-1])
            if blocked is not None:
                found = (math.inf, blocked)
        if found is None:
            # an arm of higher priority waits for this one's rest zones: if this claim would
            # leave it in the way still, give way (fold) instead
            waiting = [h for h in self.order[:self.order.index(name)] if self.state[h].stuck_on == name]
            if waiting and not st.folded and any(self._wanted(h) & want for h in waiting):
                reply = self._try_fold(name, claim)
                if not isinstance(reply, str):
                    return [(name, reply)]
                # its way back meets the waiting arm's body: that arm folds first when it
                # can (this claim is decided again after), so that this one can fold at its
                # next claim; else it goes on with its claim (it moves, so the other's wait
                # ends) rather than stand in the way
                first = self._fold_first(reply, waiting)
                if first is not None:
                    st.stuck_on = reply          # and this claim waits for that arm's next one
                    return [(reply, first)]
            return [(name, self._grant(name, claim, sweep, rest))]
        until, other = found
        if not math.isinf(until):                        # the other's motion ends then: wait for it
            claim.t = until
            return []
        ost = self.state[other]
        if ost.done:
            return [(name, self._refuse(name, claim, f"{other} is done and stands in the way"))]
        if ost.taking is not None:              # it waits for a fact and makes no claim before
            return [(name, self._refuse(name, claim, f"{other} waits for {ost.taking[0]} and stands in the way"))]
        if ost.stuck_on == name:
            return self._give_way(name, claim, other)
        st.stuck_on = other                              # wait for the other's next claim
        return []

    def _fold_first(self, blocker: str, waiting: Sequence[str]) -> Reply | None:
        """Arm `blocker`, of those `waiting` for a lower arm's body, stands on that arm's way
        back: it folds first, once (not when it is folded already or its claim is pinned);
        None when it does not.  Without this the lower arm went on with its claims, never
        able to fold, and the first waited for its whole share (two probing arms: a tool
        change of the first arm waited 2,500 s)."""
        if blocker not in waiting:
            return None
        bst = self.state[blocker]
        if bst.folded or bst.pending is None or bst.pending.park:
            return None
        reply = self._try_fold(blocker, bst.pending)
        return None if isinstance(reply, str) else reply

    def _way_back_meets(self, name: str, q: FloatArray, zones: Zones) -> bool:
        """Whether arm `name` folding from `q` (every way its controller may take, and folded
        there) meets `zones`: its folded body's zones, then each way's swept tubes tried
        against `zones` alone (ZoneGrid.tubes_meet: the same test as the way's zones, cell
        by cell, without marking them all), the first hit ending it."""
        q = np.asarray(q, dtype=float)
        fold = self._folded(name, q)
        if self._rest(name, fold) & zones:
            return True
        if np.allclose(fold, q, atol=1e-6):
            return False
        key = (name, q.tobytes())
        ways = self._retreats.get(key)
        if ways is None:
            knots = [np.asarray(w.q, dtype=float) for w in self.state[name].arm.retreat(q, fold)]
            ways = [(k, self._swept_tubes(name, k) if len(k) >= 2 else None) for k in knots]
            if len(self._retreats) >= RETREAT_CACHE:
                self._retreats.pop(next(iter(self._retreats)))
            self._retreats[key] = ways
        for wq, tubes in ways:
            if tubes is None:                              # a way of one pose: its body
                if self._rest(name, wq[0]) & zones:
                    return True
                continue
            done = self._zones.get((name, "sweep", wq.tobytes()))      # swept already (a fold it made)
            if done is not None:
                if done & zones:
                    return True
            elif self.grid.tubes_meet(*tubes, zones):
                return True
        return False

    def _unsafe(self, name: str, q: FloatArray) -> str | None:
        """The arm that, with arm `name` at rest at `q`, could not fold and keeps `name`
        from folding too (each one's way back meets the other's body); None when none."""
        mine = self._rest(name, q)
        for o in self.order:
            ost = self.state[o]
            if o == name or ost.done:
                continue
            if self._way_back_meets(o, ost.q, mine) and self._way_back_meets(name, q, self._rest(o, ost.q)):
                return o
        return None

    def _claimed(self, name: str, claim: _Claim) -> tuple[Zones, Zones]:
        """A claim's zones: those its motion sweeps, those it holds after."""
        if claim.zones is None:
            claim.zones = (self._sweep(name, claim.times, claim.q), self._rest(name, claim.q[-1]))
        return claim.zones

    def _wanted(self, name: str) -> Zones:
        st = self.state[name]
        if st.pending is None or st.pending.park:
            return 0
        sweep, rest = self._claimed(name, st.pending)
        return sweep | rest

    def _grant(self, name: str, claim: _Claim, sweep: Zones, rest: Zones) -> Reply:
        st = self.state[name]
        t0, d = claim.t, float(claim.times[-1])
        self.table.clear_from(name, t0)
        self.table.reserve(name, t0, t0 + d, sweep)
        self.table.reserve(name, t0 + d, math.inf, rest)
        wait = t0 - claim.asked_s
        kind = "continue" if wait > 0 else "grant"
        self.events.append(ZoneEvent(claim.asked_s, name, "request", "", sweep.bit_count()))
        if wait > 0:
            self.events.append(ZoneEvent(claim.asked_s, name, "wait"))
        self.events.append(ZoneEvent(t0, name, kind, "", sweep.bit_count()))
        self.events.append(ZoneEvent(t0 + d, name, "clear", "", sweep.bit_count()))
        self.paths.append(Motion(name, t0, claim.times, claim.q))
        st.q, st.pending, st.folded, st.stood_refused = claim.q[-1].copy(), None, False, False
        st.floor = t0 + d
        st.last_s = max(st.last_s, t0 + d)
        st.busy_s += d
        self._unstick(name)
        self._forget()
        return ("go", wait, None, "")

    def _give_way(self, name: str, claim: _Claim, other: str) -> list[tuple[str, Reply]]:
        """Arms `name` and `other` each wait for the other's body: the one of lower priority
        folds (its claim is asked again); when its way back meets the other's body (or it is
        folded already), the other folds first.  When neither can, the claim just made is
        refused; but when it is the first arm's, refused so before and not moved since, the
        lower arm's claim is refused instead (it goes on with its next measurement, and may
        move out of the way) and the first arm's waits for the lower's next claim.  (Refusing
        the claim just made every time had the first arm, standing still, have every claim
        of the rest of its share refused at once: 235 on a small bulkhead; refusing the
        lower's every time made the default bulkhead's cycle 29 s longer on seed 0.)"""
        for folder in sorted((name, other), key=self.order.index, reverse=True):
            fst = self.state[folder]
            if fst.folded or fst.pending is None:
                continue
            reply = self._try_fold(folder, fst.pending)
            if not isinstance(reply, str):
                return [(folder, reply)]
        st, ost = self.state[name], self.state[other]
        if (st.stood_refused and self.order.index(other) > self.order.index(name) and ost.pending is not None
                and not ost.pending.park):
            reply = self._refuse(other, ost.pending, f"{name} stands in the way and neither arm can give way")
            st.stuck_on = other                          # this claim waits for the other's next one
            return [(other, reply)]
        reply = self._refuse(name, claim, f"{other} stands in the way and neither arm can give way")
        st.stood_refused = True
        return [(name, reply)]

    def _try_fold(self, name: str, claim: _Claim, to: FloatArray | None = None) -> Reply | str:
        """Fold `name` back from its pose now, on its own base ray (its claim stays to be
        asked again), after the other arms' motions on its way have ended; or, when another
        arm's body stands on its way back, that arm's name, and its own when it cannot fold
        from where it stands (a fold stopped short there, or its claim is pinned: its probe
        is pressed on the part).  to: back to these joints instead (the same ways,
        ita.robot.waypoints.retreat_paths)."""
        st = self.state[name]
        if to is None and st.no_fold_at is not None and np.allclose(st.no_fold_at, st.q, atol=1e-6):
            return name                                  # it tried from here and stopped short
        if to is None and claim.pinned:
            return name                                  # its probe is on the part: off it first
        fold = self._folded(name, st.q) if to is None else np.asarray(to, dtype=float)
        ways = st.arm.retreat(st.q, fold)
        d = max(float(b.duration) for b in ways)
        sweep = self._ways_swept(name, ways)
        back = ways[0]
        rest = self._rest(name, fold)
        t0 = claim.t
        while (found := self.table.conflict(name, t0, math.inf, sweep | rest)) is not None:
            if math.isinf(found[0]):
                return found[1]
            t0 = found[0]                                # the other's motion there ends then: wait for it
        self.table.clear_from(name, t0)
        self.table.reserve(name, t0, t0 + d, sweep)
        self.table.reserve(name, t0 + d, math.inf, rest)
        self.events.append(ZoneEvent(t0, name, "retreat", "", sweep.bit_count()))
        self.paths.append(Motion(name, t0, np.asarray(back.times), np.asarray(back.q), "retreat"))
        wait = t0 - claim.asked_s
        st.folds += 1
        st.q, st.pending, st.folded, st.stuck_on, st.stood_refused = fold, None, to is None, None, False
        st.floor = t0                    # until it says where the fold ended (a bump stops it short)
        st.last_s = max(st.last_s, t0 + d)
        self._unstick(name)
        return ("fold", wait, tuple(map(float, fold)), "")

    def _park(self, name: str, claim: _Claim) -> list[tuple[str, Reply]]:
        """The arm gives way (its work done, or before it waits for a fact): it folds on its
        own base ray (nothing when it is folded there already; turning its base could take
        it into the cell's fences, which the conductor does not know).  When the other arm's
        body stands on its way back, that arm folds first if it is waiting for an answer,
        else the park waits for its next claim; an arm done or folded there refuses it."""
        st = self.state[name]
        if np.allclose(self._folded(name, st.q), st.q, atol=1e-6):
            st.pending = None
            return [(name, ("go", 0.0, None, ""))]
        reply = self._try_fold(name, claim)
        if not isinstance(reply, str):
            return [(name, reply)]
        ost = self.state[reply]
        if not ost.done and not ost.folded:
            if ost.pending is not None:
                first = self._try_fold(reply, ost.pending)
                if not isinstance(first, str):
                    return [(reply, first)]
            elif ost.stuck_on != name:
                st.stuck_on = reply
                return []
        why = "it cannot fold from where it stands" if reply == name else f"its way back meets {reply}'s body"
        return [(name, self._refuse(name, claim, why))]

    def _refuse(self, name: str, claim: _Claim, why: str) -> Reply:
        st = self.state[name]
        st.pending, st.stuck_on = None, None
        st.refused += 1
        st.refusals.append(f"{claim.asked_s:.1f} s: {why}")
        st.floor = claim.t
        self.events.append(ZoneEvent(claim.t, name, "refuse", why))
        self._unstick(name)
        return ("refuse", claim.t - claim.asked_s, None, why)

    def _unstick(self, name: str) -> None:
        for o in self.order:
            if self.state[o].stuck_on == name:
                self.state[o].stuck_on = None

    def _forget(self) -> None:
        live = [self.state[n].floor for n in self.order if not self.state[n].done]
        if live:
            self.table.forget_before(min(live) - 1.0)

    # -- figures ----------------------------------------------------------------------------
    def summary(self) -> dict[str, object]:
        """Each arm's granted motion seconds, folds ordered, claims and refusals (with the
        first refusals' reasons), its last simulated time; the conductor's own CPU seconds.
        (Each arm's waits are its own clock's: the controllers count them.)"""
        return {"arms": {n: {"motion_s": round(s.busy_s, 3), "folds": s.folds, "claims": s.claims, "refused": s.refused,
                             "refusals": s.refusals[:20], "last_s": round(s.last_s, 3)}
                         for n, s in self.state.items()},
                "events": len(self.events), "conductor_cpu_s": round(self.cpu_s, 2)}
