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
retreats and its makespan), not a run.
"""

from __future__ import annotations

from dataclasses import replace

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
    coordinate,
)
from ita.geometry.configurations import measurement_configurations
from ita.kinematics import arm_model
from ita.sequence.allocate import Allocation, ArmShare
from ita.sequence.cost import rack_configurations, slot_position, tool_points_world
from ita.sequence.plan import PlanningContext

__all__ = ["arm_jobs", "coordinated"]


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
            moves.append(Move(at_slot, ctx.cost_model.transfer(view, held, tool), 0.0, f"pick up {tool}", q_slot))
            held = tool
            specs = [ctx.spec(i) for i in order]
            xy = tool_points_world(view, view.tool(tool), specs)[:, :2]
            q = measurement_configurations(view, model, view.tool(tool), specs).q
            for k, spec_id in enumerate(order):
                moves.append(Move((float(xy[k, 0]), float(xy[k, 1])), legs[k], allocation.dwell_s, spec_id,
                                  tuple(map(float, q[k]))))
            moves.append(Move(at_slot, legs[-1], 0.0, f"back to {tool}'s slot", q_slot))
        if held is not None:
            moves.append(Move(moves[-1].target, ctx.cost_model.transfer(view, held, None), 0.0, f"put down {held}",
                              moves[-1].q))
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
        points = [j.base for j in jobs] + [m.target for j in jobs for m in j.moves]
        grid = ZoneGrid.around(points)
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
