"""A two-arm allocation as each arm's moves, played through the interference zones.

Each arm's share (ita.sequence.allocate) becomes its stream of moves (:class:`ArmJob`):
for each of its tool groups, to the tool's rack slot (the seconds at the rack to put the
last tool down and pick this one up), along its tour (a leg's seconds of arm motion, then
the dwell at the measurement), back to the slot; at the end the last tool put down.  The
tool's point seen from above is where the arm's body reaches (ita.collision.zones).
:func:`coordinated` plays the streams through the zone table (ita.executive.zones): the
arm named first in the cell has priority; of the eight ways to run the same allocation
(each arm's tours either way round, the second arm's tool groups in either order) the
one with the shortest makespan is kept.  The result is a plan's schedule (its waits, its
retreats and its makespan), not a run; :func:`arranged` gives the allocation in that
order, which the arms' runs follow (`ita inspect --arms 2`: in the whole-bulkhead run
of seed 0 the best order cut the cycle from about 916 s, each arm following its
one-arm plan's order, to about 828 s).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace

import numpy as np

from ita.collision.zones import ZoneGrid, arm_body, folded_configuration
from ita.executive.zones import (
    RETREAT_MIN_S,
    RETREAT_SPEED,
    ArmJob,
    Deadlock,
    Footprints,
    Move,
    Schedule,
    configurations_at,
    coordinate,
)
from ita.geometry.configurations import measurement_configurations
from ita.geometry.mkb import MeasurementKB
from ita.kinematics import arm_model
from ita.sequence.allocate import Allocation, ArmShare, alone
from ita.sequence.cost import rack_configurations, slot_position, tool_points_world
from ita.sequence.plan import PlanningContext, SequencePlan

__all__ = ["Handover", "arm_jobs", "arranged", "coordinated", "hand_over"]


def arm_jobs(ctx: PlanningContext, allocation: Allocation) -> list[ArmJob]:
    """Each arm's moves, the cell's first arm first (it has priority)."""
    jobs: list[ArmJob] = []
    for share in allocation.shares:
        view = ctx.workcell.seen_by(share.arm)
        base = (float(view.arm.base.position[0]), float(view.arm.base.position[1]))
        model = arm_model(view.arm)
        body = arm_body(model, view.tools)
        home = np.asarray(view.arm.home, dtype=float)
        fold, _reach = folded_configuration(model, view.arm.joints.lower, view.arm.joints.upper, body)
        tip = body(home[None])[0, -1]
        start = (float(tip[0]), float(tip[1]))
        moves: list[Move] = []
        held: str | None = None
        for (tool, order, _cost), legs in zip(share.groups, share.legs):
            slot = slot_position(view, tool)
            at_slot = (float(slot[0]), float(slot[1]))
            q_slot = tuple(map(float, rack_configurations(view, model, tool)[0]))
            moves.append(Move(at_slot, ctx.cost_model.transfer(view, held, tool), 0.0, f"pick up {tool}", q_slot,
                              tool_change=True))
            held = tool
            specs = [ctx.spec(i) for i in order]
            xy = tool_points_world(view, view.tool(tool), specs)[:, :2]
            q = measurement_configurations(view, model, view.tool(tool), specs).q
            dwell = allocation.dwell_s[view.tool(tool).tool_class.family.value]
            for k, spec_id in enumerate(order):
                moves.append(Move((float(xy[k, 0]), float(xy[k, 1])), legs[k], dwell, spec_id,
                                  tuple(map(float, q[k]))))
            moves.append(Move(at_slot, legs[-1], 0.0, f"back to {tool}'s slot", q_slot))
        if held is not None:
            moves.append(Move(moves[-1].target, ctx.cost_model.transfer(view, held, None), 0.0, f"put down {held}",
                              moves[-1].q, tool_change=True))
            # done: the arm folds on its base, out of the other's way (a move like any other;
            # the first arm by way of its home, turned away from the other, the others on
            # their own base ray: their way back is theirs)
            parked = fold.copy()
            parked[0] = home[0] if not jobs else moves[-1].q[0]
            tip = body(parked[None])[0, -1]
            away = float(np.hypot(tip[0] - moves[-1].target[0], tip[1] - moves[-1].target[1]))
            moves.append(Move((float(tip[0]), float(tip[1])), max(away / RETREAT_SPEED, RETREAT_MIN_S), 0.0, "park",
                              tuple(map(float, parked)), tuple(map(float, home)) if not jobs else ()))
        jobs.append(ArmJob(share.arm, base, start, tuple(moves), body, tuple(map(float, home)),
                           tuple(map(float, fold))))
    return jobs


def coordinated(ctx: PlanningContext, allocation: Allocation) -> tuple[Schedule, list[ArmJob], str]:
    """The allocation's best schedule through the interference zones, the arms' moves, and
    which variant it is: each arm's tours run either way round and the second arm's tool
    groups in either order (the arms then meet less at the split and at the rack); the
    shortest makespan of those that can be coordinated wins, the first on ties.
    :class:`Deadlock` when none can."""
    best: tuple[Schedule, list[ArmJob], str] | None = None
    stuck: list[str] = []
    feet: Footprints | None = None             # the same moves' zones, for every order
    for name, variant in _variants(allocation):
        jobs = arm_jobs(ctx, variant)
        grid = _grid(jobs)
        feet = feet if feet is not None and feet.grid == grid else Footprints(grid)
        try:
            schedule = coordinate(grid, jobs, feet=feet)
        except Deadlock as e:                 # this order of the work cannot be coordinated
            stuck.append(f"{name}: {e}")
            continue
        if best is None or schedule.makespan_s < best[0].makespan_s:
            best = (schedule, jobs, name)
    if best is None:
        raise Deadlock("no order of the allocation's work could be coordinated: " + "; ".join(stuck))
    return best


def arranged(ctx: PlanningContext, allocation: Allocation) -> Allocation:
    """The allocation with each arm's tours in the order of its best coordinated schedule
    (:func:`coordinated`; ``arranged`` names it): the order the arms' runs then follow.
    The allocation as it is when none can be coordinated (its runs' zones then sort it out)."""
    try:
        _schedule, _jobs, how = coordinated(ctx, allocation)
    except Deadlock:
        return allocation
    return replace(dict(_variants(allocation))[how], arranged=how)


def _grid(jobs: Sequence[ArmJob]) -> ZoneGrid:
    """The zones around the arms' bases and every target of their moves."""
    return ZoneGrid.around([j.base for j in jobs] + [m.target for j in jobs for m in j.moves])


def _variants(allocation: Allocation) -> list[tuple[str, Allocation]]:
    def turned(share: ArmShare, reverse_tours: bool, reverse_groups: bool) -> ArmShare:
        groups, legs = list(share.groups), list(share.legs)
        if reverse_tours:             # a closed tour the other way round: its legs reversed
            groups = [(t, tuple(reversed(o)), c) for t, o, c in groups]
            legs = [tuple(reversed(g)) for g in legs]
        if reverse_groups:
            groups, legs = groups[::-1], legs[::-1]
        return replace(share, groups=tuple(groups), legs=tuple(legs))

    out = []
    for groups_b in (False, True):
        for tours_a in (False, True):
            for tours_b in (False, True):
                first, second = allocation.shares
                name = (f"{first.arm} tours {'reversed' if tours_a else 'as planned'}, "
                        f"{second.arm} tours {'reversed' if tours_b else 'as planned'}"
                        f"{', its tool groups in reverse order' if groups_b else ''}")
                out.append((name, replace(allocation, shares=(turned(first, tours_a, False),
                                                              turned(second, tours_b, groups_b)))))
    return out


@dataclass(frozen=True)
class Handover:
    """An arm down for good at ``at_s`` of a coordinated plan, and what the other does then:
    ``done`` the measurements made by then (the other's current one finished, at
    ``resume_s``), ``handed`` the downed arm's still to do that the other now makes,
    ``lost`` those nobody can make now (with why), the other's new ``schedule`` from
    ``resume_s`` (the downed arm frozen where it stopped, ``q_down``) and the makespan."""

    down: str
    at_s: float
    resume_s: float
    done: tuple[str, ...]
    handed: tuple[str, ...]
    lost: tuple[tuple[str, str], ...]
    schedule: Schedule
    jobs: tuple[ArmJob, ...]
    q_down: tuple[float, ...]

    @property
    def makespan_s(self) -> float:
        return self.resume_s + self.schedule.makespan_s


def hand_over(ctx: PlanningContext, plan: SequencePlan, allocation: Allocation, schedule: Schedule,
              jobs: Sequence[ArmJob], down: str, at_s: float,
              mkbs: Mapping[str, MeasurementKB] | None = None) -> Handover:
    """Re-allocate when arm ``down`` stops for good at ``at_s`` of ``schedule`` (its
    controller failed): it stays where it is, holding what it held; the other finishes
    the move it is making, then makes the rest of its own work and what the downed arm
    had not made that it can (ita.sequence.allocate.alone: its reach, its MKB, its own
    tools, a twinless tool unless in the downed hand, its body clear of the downed arm's
    zones), going on with the tool it holds when it has work for it, then from its rack
    (else the tool it holds put back first), played through the zones with the downed arm
    frozen (a move its body bars is skipped, and lost; a tool change it bars, with the
    moves made with that tool)."""
    names = [j.name for j in jobs]
    if down not in names:
        raise ValueError(f"no arm {down!r} in the plan (its arms: {', '.join(names)})")
    other = next(n for n in names if n != down)
    by = {j.name: j for j in jobs}
    assigned = set(allocation.assigned)
    # the survivor finishes its current step
    resume = at_s
    for start, _moved, end, _a, _b, _label in schedule.timeline[other]:
        if start <= at_s < end:
            resume = end
    done = [lab for n, until in ((down, at_s), (other, resume))
            for _s, _m, end, _a, _b, lab in schedule.timeline[n] if end <= until and lab in assigned]
    held = held_by(schedule, down, at_s)
    q = configurations_at(schedule, jobs, np.array([at_s, resume]))
    q_down, q_other = q[down][0], q[other][1]
    # the survivor's work now, its body clear of the downed arm's zones
    grid = _grid(jobs)
    body_down, body_other = by[down].body, by[other].body
    if body_down is None or body_other is None:
        raise ValueError("a hand-over needs both arms' body models")
    frozen = grid.near_tubes(body_down.tubes(q_down[None]), body_down.radii)

    def keep_clear(Q: np.ndarray) -> np.ndarray:
        return np.array([not grid.near_tubes(body_other.tubes(x[None]), body_other.radii) & frozen for x in Q])

    done_set = set(done)
    todo = [i for i in allocation.assigned if i not in done_set]
    share, lost = alone(ctx, plan, other, todo, keep_clear, allocation.dwell_s, mkbs,
                        unavailable=() if held is None else (held,))
    in_hand = held_by(schedule, other, resume)
    keep = [k for k, (t, _o, _c) in enumerate(share.groups) if t == in_hand][:1]
    if keep:                                        # the work with the tool in its hand first
        ks = keep + [k for k in range(len(share.groups)) if k not in keep]
        share = replace(share, groups=tuple(share.groups[k] for k in ks), legs=tuple(share.legs[k] for k in ks))
    empty = replace(next(s for s in allocation.shares if s.arm == down), groups=(), legs=(), count=0, time_s=0.0)
    shares = tuple(share if s.arm == other else empty for s in allocation.shares)
    again = {j.name: j for j in arm_jobs(ctx, replace(allocation, shares=shares))}
    view = ctx.workcell.seen_by(other)
    tip = body_other(q_other[None])[0, -1]
    mine = again[other]
    if mine.moves and in_hand is not None:
        first = mine.moves[0]
        if keep:     # it goes on with the tool it holds, straight to its first point (at the TCP's top speed)
            to = mine.moves[1]
            mine = replace(mine, moves=(replace(to, move_s=max(to.move_s, float(
                np.hypot(tip[0] - to.target[0], tip[1] - to.target[1])) / RETREAT_SPEED)), *mine.moves[2:]))
        else:        # its tool back to the rack first (at the TCP's top speed)
            back = float(np.hypot(tip[0] - first.target[0], tip[1] - first.target[1])) / RETREAT_SPEED
            tool = first.label[len("pick up "):]
            mine = replace(mine, moves=(replace(first, move_s=back + ctx.cost_model.transfer(view, in_hand, tool)),
                                        *mine.moves[1:]))
    mine = replace(mine, start=(float(tip[0]), float(tip[1])), home=tuple(map(float, q_other)))
    tip_down = body_down(q_down[None])[0, -1]
    stopped = replace(by[down], start=(float(tip_down[0]), float(tip_down[1])), moves=(),
                      home=tuple(map(float, q_down)), fold=(), down=True)
    order = tuple(mine if j.name == other else stopped for j in jobs)
    after = coordinate(grid, order)
    barred = set(after.skipped.get(other, ()))
    made = {i for _t, o, _c in share.groups for i in o} - barred
    lost = lost + tuple((i, f"{down}, down where it stopped, bars the way there") for i in sorted(barred & assigned))
    handed = tuple(i for i in todo if i in made and allocation.assigned[i] == down)
    return Handover(down, at_s, resume, tuple(done), handed, lost, after, order, tuple(map(float, q_down)))


def held_by(schedule: Schedule, arm: str, t: float) -> str | None:
    """The tool ``arm`` holds at ``t`` of ``schedule`` (its moves' labels say)."""
    held: str | None = None
    for _s, moved, _e, _a, _b, lab in schedule.timeline[arm]:
        if moved <= t and lab.startswith("pick up "):
            held = lab[len("pick up "):]
        if moved <= t and lab.startswith("put down "):
            held = None
    return held
