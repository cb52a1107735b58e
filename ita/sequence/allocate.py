"""Two arms on one part: which arm does which measurement (min-max), and how far that is
from a bound.

The allocation is the high-level planner's decision; this module makes it from the
one-arm sequence plan's groups (which tool class each measurement takes):

1. **What each arm can do.**  A measurement is an arm's when the arm's reach test passes
   (ita.workcell.reach_report with the cell as that arm works it,
   ``Workcell.seen_by``), its MKB places it when it has one (an SLRA view the part does
   not block from that side: the reach test alone does not know), the arm has a
   configuration for it (the cost model's inverse kinematics), it reaches the rack slot of a tool of its class, and its body there, and
   all the way as it folds back, keeps clear of the other arm folded on its base,
   whatever that arm's base joint (ita.collision.zones.Revolved: where the other arm
   retreats to; its zones and the arm's never meet, the rule that keeps the coordination
   free of deadlock).
2. **Tools.**  Each arm has its own tool of a class when the rack holds two (the first
   arm the plan's, the second the other); a class with one tool (the bent probe) is
   shared: all its measurements go to one arm (the one that can do them all, the one
   nearer the tool's rack slot when both can), so a tool is in one hand at a time and
   the arms never queue for it.
3. **Min-max split.**  The measurements both arms can do are ordered by how much nearer
   (seen from above) they are to the first arm's base than to the second's; a split
   point sends those before it to the first arm, the rest to the second.  Each arm's time is its tours
   (the default ordering on the cost model's motion-time matrices, per tool) plus a
   dwell per measurement (by tool class); the split that minimises the larger of the two is found by
   bisection (the first arm's time grows with the split, the second's shrinks), then its
   neighbours are tried.
4. **The bound.**  Every measurement costs at least its dwell plus the cheapest way into
   it by an arm that can do it; the two arms' times add up to at least that sum, so the
   makespan is at least half of it, and at least each arm's share of what only it can do.
   The gap to this bound is reported; it leaves out the arms' tool changes and the
   tours' closing, so it is a loose bound.

    allocation = allocate(ctx, plan)
    allocation.assigned, allocation.makespan_s, allocation.bound_s, allocation.gap_percent
"""

from __future__ import annotations

from collections.abc import Callable, Collection, Mapping, Sequence
from dataclasses import dataclass, field
from types import MappingProxyType

import numpy as np

from ita.collision.zones import (
    ArmBody,
    Revolved,
    ZoneGrid,
    arm_body,
    folded_configuration,
)
from ita.geometry.configurations import measurement_configurations
from ita.geometry.mkb import MeasurementKB
from ita.geometry.reasoner import GeometricReasoner
from ita.kinematics import arm_model
from ita.sequence.cost import rack_configurations, slot_position, tool_points_world
from ita.sequence.plan import PlanningContext, SequencePlan
from ita.sequence.tour import solve_tour
from ita.workcell import ToolSpec, Workcell, reach_report
from ita.workcell.reach import Reach

__all__ = ["DWELL_S", "Allocation", "ArmShare", "allocate", "alone"]

#: seconds an arm spends at a measurement besides moving to it, by tool family (every
#: ultrasonic probe's is us_tool's): a probe
#: squirts couplant (0.4 s), presses on (about 0.4 s), pulses (1.2 s) and lifts off (about
#: 0.4 s); the SLRA scans a view (about 0.55 s, a view to about one measurement in the
#: bulkhead's plan) and measures in the range image (about 0.2 s).  From a two-arm
#: whole-bulkhead run's commands (seed 0); one second for every measurement, as before,
#: under-priced the probe work by more than half and so split it unevenly.
DWELL_S: Mapping[str, float] = MappingProxyType({"us_tool": 2.4, "slra_tool": 0.75})
#: poses sampled on an arm's way from a measurement back to its fold
FOLD_SAMPLES = 9


@dataclass(frozen=True)
class ArmShare:
    """One arm's part of the work: its groups (tool, ordered spec ids, tour seconds), its
    time (tours, dwell and rack) and how many measurements."""

    arm: str
    groups: tuple[tuple[str, tuple[str, ...], float], ...]
    time_s: float
    count: int
    legs: tuple[tuple[float, ...], ...] = ()     # per group: seconds slot -> first, ..., last -> slot
    rack_s: float = 0.0                          # seconds at the rack (tool pick-ups and put-downs)


@dataclass(frozen=True)
class Allocation:
    """The two-arm allocation: each arm's share, the makespan (the larger time), the
    bound, and what neither arm can do (spec id, why)."""

    shares: tuple[ArmShare, ...]
    assigned: Mapping[str, str]
    makespan_s: float
    bound_s: float
    one_arm_s: float
    unassigned: tuple[tuple[str, str], ...]
    split: int
    dwell_s: Mapping[str, float] = field(default_factory=lambda: DWELL_S)
    #: arm -> the measurements it can do (its reach, MKB, tools and configurations clear of
    #: the other arm folded; a shared tool's group its owner's alone): whom work left by
    #: the other arm may be handed to
    able: Mapping[str, frozenset[str]] = field(default_factory=dict)
    #: arm -> the measurements it reaches, its MKB places and it has a tool class for,
    #: wherever the other arm stands: what it may try when the other stands still for good
    #: (a hand-over; its Path Planner and the zones then say whether it can)
    reaches: Mapping[str, frozenset[str]] = field(default_factory=dict)
    #: how the arms' tours run: which way round and in which order, the order of the
    #: shortest coordinated schedule (ita.executive.two_arms.arranged); "" as made here
    arranged: str = ""

    @property
    def gap_percent(self) -> float:
        return 100.0 * (self.makespan_s - self.bound_s) / self.bound_s if self.bound_s > 0 else 0.0

    def as_dict(self) -> dict:
        return {"arms": [{"arm": s.arm, "measurements": s.count, "time_s": round(s.time_s, 1), "rack_s": round(s.rack_s, 1),
                          "groups": [{"tool": t, "count": len(o), "tour_s": round(c, 1)} for t, o, c in s.groups]}
                         for s in self.shares],
                "makespan_s": round(self.makespan_s, 1), "bound_s": round(self.bound_s, 1),
                "gap_percent": round(self.gap_percent, 1), "one_arm_s": round(self.one_arm_s, 1),
                "ratio_to_one_arm": round(self.makespan_s / self.one_arm_s, 3) if self.one_arm_s else None,
                "unassigned": [{"spec": i, "why": w} for i, w in self.unassigned],
                "arranged": self.arranged or "as allocated"}


def _tools(cell: Workcell, plan_tool: str, arm_index: int) -> str | None:
    """The tool of the plan tool's class the arm uses: the first arm the plan's, the second
    the other of its class (None when the class has one tool, which is shared)."""
    same = [t.name for t in cell.tools if t.tool_class is cell.tool(plan_tool).tool_class
            and t.same_shape(cell.tool(plan_tool))]
    if arm_index == 0:
        return plan_tool
    spare = [t for t in same if t != plan_tool]
    return spare[0] if spare else None


def allocate(ctx: PlanningContext, plan: SequencePlan, dwell_s: Mapping[str, float] = DWELL_S,
             mkbs: Mapping[str, MeasurementKB] | None = None) -> Allocation:
    """Split the one-arm `plan`'s measurements between the two arms of ``ctx.workcell``
    (see the module docstring).  mkbs: arm name -> the MKB made for the cell as that arm
    works it (ita.sequence.plan.planning_context's ``arm``): a measurement is an arm's only
    when its MKB places it for the tool's class (an SLRA view the part does not block from
    that side, a probe pose and approach).  ValueError when the cell has one arm."""
    cell = ctx.workcell
    arms = cell.arms()
    if len(arms) != 2:
        raise ValueError(f"the workcell {cell.source} names one arm; a second is a [robot_b] table")
    views = [cell.seen_by(a.name) for a in arms]
    bases = [np.asarray(a.base.position[:2], dtype=float) for a in arms]
    # the tool each arm uses per group, and which measurements it can do
    groups = [(g.tool, list(g.order)) for g in plan.groups if g.order]
    every = [i for _t, ids in groups for i in ids]
    specs = {i: ctx.spec(i) for i in every}
    tool_of = {i: t for t, ids in groups for i in ids}
    points = {}
    for t, ids in groups:
        xyz = tool_points_world(cell, cell.tool(t), [specs[i] for i in ids])
        points.update({i: xyz[k, :2] for k, i in enumerate(ids)})
    grid = ZoneGrid.around([tuple(map(float, p)) for p in [*bases, *points.values()]])
    models = [arm_model(v.arm) for v in views]
    bodies = [arm_body(m, cell.tools) for m in models]
    # the ground each arm folded on its base holds, whatever its base joint: the other's
    # tubes keep clear of it by more than the zones' half-diagonal on each side, so their
    # zones never meet
    folds = [folded_configuration(models[a], arms[a].joints.lower, arms[a].joints.upper, bodies[a])
             for a in range(2)]
    revolved = [Revolved.of(bodies[a], folds[a][0], (float(bases[a][0]), float(bases[a][1])), grid.z_high)
                for a in range(2)]
    gap = grid.apart_m
    can = [dict[str, bool]() for _ in range(2)]
    reaches: list[set[str]] = [set(), set()]
    why: dict[str, str] = {}
    matrices: list[dict[str, tuple[list[str], np.ndarray]]] = [{}, {}]
    for a in range(2):
        for t, ids in groups:
            own = _tools(cell, t, a)
            tool = cell.tool(own if own is not None else t)
            mkb = None if mkbs is None else mkbs.get(arms[a].name)
            ok = _placeable(ctx, views[a], tool, ids, mkb, why)
            if ok and not arms[a].works_with(tool.tool_class.value):
                why.update({i: f"{arms[a].name}: not fitted for {tool.tool_class.value} (its tool_classes)" for i in ok})
                ok = []
            if ok and mkb is not None and tool.tool_class.ultrasonic:
                missed = _stations_missed(ctx, views[a], mkb, tool.name)
                if missed:                      # a probe is calibrated on the block and wetted at the station
                    why.update({i: f"{arms[a].name}: cannot reach the {missed} with {tool.name}" for i in ok})
                    ok = []
            reaches[a].update(ok)
            matrix, kept = _matrix(ctx, views[a], tool.name, ok, bodies[a], folds[a][0], revolved[1 - a], gap)
            matrices[a][t] = (kept, matrix) if matrix is not None else ([], np.zeros((1, 1)))
            for i in ids:
                can[a][i] = i in set(matrices[a][t][0])
                if not can[a][i]:
                    why.setdefault(i, f"{arms[a].name}: {'out of reach' if i not in ok else 'no configuration clear of the other arm'}")
    # shared tools (one of their class): the whole group to one arm
    forced: dict[str, int] = {}
    for t, ids in groups:
        if _tools(cell, t, 1) is None:
            # the arm nearer the tool's slot, when it can do them all (its trips are short
            # and the other arm never reaches in beside its base), else the other
            slot = slot_position(cell, t)[:2]
            near, far = sorted((0, 1), key=lambda a: (float(np.linalg.norm(slot - bases[a])), a))
            owner = near if all(can[near][i] for i in ids) or not all(can[far][i] for i in ids) else far
            forced.update({i: owner for i in ids})
    unassigned = tuple((i, why.get(i, "neither arm")) for i in every
                       if not (can[0][i] or can[1][i]) or (i in forced and not can[forced[i]][i]))
    lost = {i for i, _ in unassigned}
    only = {i: 0 if not can[1][i] else 1 for i in every if i not in lost and (can[0][i] != can[1][i])}
    only.update({i: a for i, a in forced.items() if i not in lost})
    both = [i for i in every if i not in lost and i not in only]
    # nearer the first arm's base than the second's (by how much) first: a split point
    # leaves each arm the measurements on its own side of a hyperbola between the bases
    both.sort(key=lambda i: (float(np.linalg.norm(points[i] - bases[0]) - np.linalg.norm(points[i] - bases[1])), i))

    def shares(k: int) -> tuple[ArmShare, ArmShare]:
        side = dict(only)
        side.update({i: 0 for i in both[:k]})
        side.update({i: 1 for i in both[k:]})
        return _share(arms[0].name, 0, side, groups, matrices[0], dwell_s, views[0], ctx.cost_model.transfer), \
            _share(arms[1].name, 1, side, groups, matrices[1], dwell_s, views[1], ctx.cost_model.transfer)

    lo, hi = 0, len(both)
    cache: dict[int, tuple[ArmShare, ArmShare]] = {}

    def at(k: int) -> tuple[ArmShare, ArmShare]:
        if k not in cache:
            cache[k] = shares(k)
        return cache[k]

    while hi - lo > 1:                                   # first arm's time grows with k
        mid = (lo + hi) // 2
        s0, s1 = at(mid)
        if s0.time_s < s1.time_s:
            lo = mid
        else:
            hi = mid
    best = min((k for k in {lo, hi, max(0, lo - 1), min(len(both), hi + 1)}),
               key=lambda k: (max(s.time_s for s in at(k)), k))
    chosen = at(best)
    assigned = {i: chosen[0].arm for _t, o, _c in chosen[0].groups for i in o}
    assigned.update({i: chosen[1].arm for _t, o, _c in chosen[1].groups for i in o})
    # the bound: half the least total work, and each arm's own
    least = {}
    for i in every:
        if i in lost:
            continue
        costs = []
        for a in range(2):
            if can[a][i]:
                kept, M = matrices[a][tool_of[i]]
                k = kept.index(i) + 1
                costs.append(float(np.min(np.delete(M[:, k], k))))
        least[i] = dwell_s[cell.tool(tool_of[i]).tool_class.family.value] + min(costs)
    bound = max(sum(least.values()) / 2.0,
                *(sum(least[i] for i, a in only.items() if a == arm) for arm in range(2)))
    one = (sum(g.cost_s for g in plan.groups) + plan.transfer_s
           + sum(dwell_s[cell.tool(t).tool_class.family.value] * len(ids) for t, ids in groups))
    able = {arms[a].name: frozenset(i for i in every if i not in lost and can[a][i] and forced.get(i, a) == a)
            for a in range(2)}
    return Allocation(chosen, assigned, max(s.time_s for s in chosen), bound, one, unassigned, best, dwell_s, able,
                      {arms[a].name: frozenset(reaches[a]) for a in range(2)})


def _stations_missed(ctx: PlanningContext, view: Workcell, mkb: MeasurementKB, tool: str) -> str:
    """The stations a probe needs (the calibration block, the couplant station) that the
    arm cannot take with `tool` in hand ("" when it reaches both)."""
    reasoner = GeometricReasoner(mkb, view, ctx.specs)
    missed = []
    for name, said in (("cal_block", "calibration block"), ("couplant_station", "couplant station")):
        try:
            reasoner.station(name, tool)
        except KeyError:
            missed.append(said)
    return " and ".join(missed)


def _placeable(ctx: PlanningContext, view: Workcell, tool: ToolSpec, ids: Sequence[str],
               mkb: MeasurementKB | None, why: dict[str, str]) -> list[str]:
    """Those of ``ids`` the arm of ``view`` reaches with ``tool`` and its MKB (when given)
    places for the tool's class; why not, in ``why``, for the others."""
    report = reach_report(view, np.array([ctx.spec(i).point for i in ids]),
                          np.array([ctx.spec(i).normal for i in ids]), [tool.tool_class.value] * len(ids))
    ok = [i for i, v in zip(ids, report.verdicts) if v is Reach.REACHABLE]
    why.update({i: f"{view.arm.name}: out of reach" for i in ids if i not in set(ok) and i not in why})
    if mkb is None:
        return ok
    placed = {i: mkb.entry_for(i, tool.tool_class.value) for i in ok}
    for i, e in placed.items():
        if e is None or not e.ok:
            why.setdefault(i, f"{view.arm.name}: its MKB does not place it ({'not tried' if e is None else e.status})")
    return [i for i in ok if (e := placed[i]) is not None and e.ok]


def alone(ctx: PlanningContext, plan: SequencePlan, arm: str, spec_ids: Collection[str],
          keep_clear: Callable[[np.ndarray], np.ndarray], dwell_s: Mapping[str, float] = DWELL_S,
          mkbs: Mapping[str, MeasurementKB] | None = None,
          unavailable: Collection[str] = ()) -> tuple[ArmShare, tuple[tuple[str, str], ...]]:
    """One arm of the cell working ``spec_ids`` (of the one-arm ``plan``'s groups) alone,
    the other out of work (down): those it reaches, its MKB places, it has a tool for (its
    own of the class; a tool with no twin unless ``unavailable``) and whose measuring
    configurations ``keep_clear`` (``(n, 6)`` -> ``(n,)`` bool) accepts, as its tours;
    and the rest, each with why."""
    cell = ctx.workcell
    a = [x.name for x in cell.arms()].index(arm)
    view = cell.seen_by(arm)
    model = arm_model(view.arm)
    wanted = set(spec_ids)
    groups = [(g.tool, [i for i in g.order if i in wanted]) for g in plan.groups]
    groups = [(t, ids) for t, ids in groups if ids]
    why: dict[str, str] = {}
    matrices: dict[str, tuple[list[str], np.ndarray]] = {}
    side: dict[str, int] = {}
    for t, ids in groups:
        own = _tools(cell, t, a) or t
        if own in unavailable:
            why.update({i: f"{own}, the one tool of its class, is in the other arm's hand" for i in ids})
            continue
        tool = view.tool(own)
        if not view.arm.works_with(tool.tool_class.value):
            why.update({i: f"{arm}: not fitted for {tool.tool_class.value} (its tool_classes)" for i in ids})
            continue
        ok = _placeable(ctx, view, tool, ids, None if mkbs is None else mkbs.get(arm), why)
        try:
            rack_configurations(view, model, own)
        except ValueError:
            why.update({i: f"{arm}: cannot reach {own}'s rack slot" for i in ok})
            continue
        conf = measurement_configurations(view, model, tool, [ctx.spec(i) for i in ok])
        clear = np.zeros(len(ok), dtype=bool)
        if conf.found.any():
            clear[conf.found] = keep_clear(conf.q[conf.found])
        for i, found, free in zip(ok, conf.found, clear):
            if not found:
                why.setdefault(i, f"{arm}: no configuration")
            elif not free:
                why.setdefault(i, f"{arm}: the other arm, down where it stopped, is in the way")
        kept = [i for i, free in zip(ok, clear) if free]
        matrices[t] = (kept, ctx.cost_model.tour(view, tool, [ctx.spec(i) for i in kept]))
        side.update({i: a for i in kept})
    share = _share(arm, a, side, groups, matrices, dwell_s, view, ctx.cost_model.transfer)
    done = {i for _t, o, _c in share.groups for i in o}
    return share, tuple((i, why.get(i, f"{arm}: cannot")) for _t, ids in groups for i in ids if i not in done)


def _matrix(ctx: PlanningContext, view: Workcell, tool: str, ids: Sequence[str],
            body: ArmBody, fold: np.ndarray, other: Revolved, gap: float) -> tuple[np.ndarray | None, list[str]]:
    """The cost model's matrix (rack slot first) of the measurements the arm has a
    configuration for whose tubes, there and folding back from there to ``fold`` (its base
    joint kept), keep more than ``gap`` (m) beyond their radii from ``other``, the other
    arm folded, and their ids;
    (None, []) when it cannot reach the tool's slot."""
    spec = view.tool(tool)
    model = arm_model(view.arm)
    try:
        rack_configurations(view, model, tool)
    except ValueError:
        return None, []
    conf = measurement_configurations(view, model, spec, [ctx.spec(i) for i in ids])
    apart = np.zeros(len(ids), dtype=bool)
    if conf.found.any():
        q = conf.q[conf.found]
        folded = np.broadcast_to(fold, q.shape).copy()
        folded[:, 0] = q[:, 0]
        # the body there and all the way folding back (base joint kept): its way back is clear too
        clear = np.ones(len(q), dtype=bool)
        for s in np.linspace(0.0, 1.0, FOLD_SAMPLES):
            clear &= other.clear_of(body, q + s * (folded - q), gap)
        apart[conf.found] = clear
    kept = [i for i, ok in zip(ids, apart) if ok]
    return ctx.cost_model.tour(view, spec, [ctx.spec(i) for i in kept]), kept


def _share(arm: str, a: int, side: Mapping[str, int], groups: Sequence[tuple[str, list[str]]],
           matrices: Mapping[str, tuple[list[str], np.ndarray]], dwell_s: Mapping[str, float], view: Workcell,
           transfer: Callable[[Workcell, str | None, str | None], float]) -> ArmShare:
    """The arm's tours (one per tool group it has work in, in the plan's group order), each
    named by the tool the arm uses, with the seconds of each leg and at the rack."""
    out, legs, total, count, rack = [], [], 0.0, 0, 0.0
    held: str | None = None
    for t, ids in groups:
        mine = [i for i in ids if side.get(i) == a]
        if not mine:
            continue
        kept, M = matrices[t]
        pos = {i: k + 1 for k, i in enumerate(kept)}
        idx = [0] + [pos[i] for i in mine]
        tour = solve_tour(M[np.ix_(idx, idx)], start=0, end=0)
        order = tuple(mine[k - 1] for k in tour.order if k != 0)
        stops = [idx[k] for k in tour.order] + [0]
        tool = _tools(view, t, a) or t
        rack += transfer(view, held, tool)
        held = tool
        out.append((tool, order, float(tour.cost)))
        legs.append(tuple(float(M[u, v]) for u, v in zip(stops, stops[1:])))
        total += float(tour.cost) + dwell_s[view.tool(tool).tool_class.family.value] * len(mine)
        count += len(mine)
    if held is not None:
        rack += transfer(view, held, None)
    return ArmShare(arm, tuple(out), total + rack, count, tuple(legs), rack)
