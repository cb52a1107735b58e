"""The two-arm allocation (ita.sequence.allocate): each measurement to an arm that reaches
it, a tool in one hand, the makespan between its bound and the one-arm time."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from ita.executive.two_arms import coordinated
from ita.executive.zones import configurations_at
from ita.logic.world import WorldModel
from ita.sequence.allocate import DWELL_S, allocate
from ita.sequence.plan import build_plan, planning_context
from ita.sim.arms import TwoArms
from ita.specs.model import Tool
from ita.workcell import reach_report
from ita.workcell.reach import Reach


@pytest.fixture(scope="module")
def allocated(builtin_part):
    ctx = planning_context(None, use_mkb=False)     # the same plan whether a test made the MKB or not
    WorldModel(ctx.kb).reset()                       # and whatever tools an earlier test broke
    ctx = replace(ctx, specs=ctx.specs[::9], _facts_cache={})    # every ninth: the whole part, fewer
    plan = build_plan(ctx)
    return ctx, plan, allocate(ctx, plan)


@pytest.fixture(scope="module")
def played(allocated):
    """The allocation's coordinated schedule (the best of its eight orders) and the moves."""
    ctx, _plan, a = allocated
    schedule, jobs, _how = coordinated(ctx, a)
    return schedule, jobs


def test_each_measurement_goes_to_an_arm_that_reaches_it_with_a_tool_of_its_own(allocated) -> None:
    ctx, plan, a = allocated
    cell = ctx.workcell
    assert {s.arm for s in a.shares} == {"t3", "t3_b"}
    planned = {i for g in plan.groups for i in g.order}
    assert set(a.assigned) | {i for i, _ in a.unassigned} == planned
    assert all(s.count > 0.2 * len(planned) for s in a.shares)               # both arms work
    for share in a.shares:
        view = cell.seen_by(share.arm)
        for tool, order, _cost in share.groups:
            specs = [ctx.spec(i) for i in order]
            report = reach_report(view, np.array([s.point for s in specs]), np.array([s.normal for s in specs]),
                                  [cell.tool(tool).tool_class.value] * len(specs))
            assert all(v is Reach.REACHABLE for v in report.verdicts), (share.arm, tool)
    tools = [{t for t, _o, _c in s.groups} for s in a.shares]
    assert not tools[0] & tools[1]                       # no tool in both hands
    for share in a.shares:                               # only the tools each arm is fitted for
        arm = cell.seen_by(share.arm).arm
        assert all(arm.works_with(cell.tool(t).tool_class.value) for t in tools[a.shares.index(share)])


def test_an_arm_gets_work_of_the_tool_classes_it_is_fitted_for_alone(allocated) -> None:
    """The default cell's second arm probes and scans; fitted for the SLRA alone, it gets
    no probe work, not even by a hand-over."""
    ctx, plan, a = allocated
    second = ctx.workcell.second_arm
    assert second is not None and second.tool_classes is None
    b_tools = {ctx.workcell.tool(t).tool_class for s in a.shares if s.arm == second.name for t, _o, _c in s.groups}
    assert any(t.ultrasonic for t in b_tools) and Tool.SLRA in b_tools
    probe_work = {i for g in plan.groups if ctx.workcell.tool(g.tool).tool_class.ultrasonic for i in g.order}
    scanner = replace(ctx, workcell=replace(ctx.workcell, second_arm=replace(second, tool_classes=("slra_tool",))))
    b = allocate(scanner, plan)
    assert {scanner.workcell.tool(t).tool_class for s in b.shares if s.arm == second.name
            for t, _o, _c in s.groups} == {Tool.SLRA}
    assert probe_work and not b.able[second.name] & probe_work      # not even handed over


def test_every_tool_class_has_a_dwell() -> None:
    assert all(c.family.value in DWELL_S for c in Tool)
    assert DWELL_S[Tool.ULTRASONIC.value] > DWELL_S[Tool.SLRA.value]     # a probe presses, pulses, lifts off


def test_the_makespan_lies_between_its_bound_and_the_one_arm_time(allocated) -> None:
    _ctx, _plan, a = allocated
    assert a.bound_s <= a.makespan_s < a.one_arm_s
    assert a.makespan_s == max(s.time_s for s in a.shares)
    assert a.makespan_s <= 0.7 * a.one_arm_s             # the split is near even


def test_a_measurement_an_arms_mkb_does_not_place_is_never_that_arms(allocated) -> None:
    """The reach test does not know that ribs block an SLRA view from one side; the arm's
    MKB does: what it cannot place goes to the other arm (or to neither, saying why)."""
    from ita.geometry.mkb import MeasurementKB, MkbEntry

    ctx, plan, a = allocated
    cell = ctx.workcell
    second = [i for i, arm in a.assigned.items() if arm == "t3_b"]
    blocked = set(second[::2])
    tool_of = {i: g.tool for g in plan.groups for i in g.order}
    entries = {i: MkbEntry(i, tool_of[i], cell.tool(tool_of[i]).tool_class.value,
                           status="view_blocked" if i in blocked else "ok") for i in tool_of}
    fake = MeasurementKB("p", "d", entries)
    b = allocate(ctx, plan, mkbs={"t3_b": fake})
    assert blocked and not {i for i, arm in b.assigned.items() if arm == "t3_b"} & blocked
    why = dict(b.unassigned)
    for i in blocked:
        assert b.assigned.get(i) == "t3" or "t3_b: its MKB does not place it (view_blocked)" in why[i], i
    assert set(b.assigned) | set(why) == set(a.assigned) | {i for i, _ in a.unassigned}   # none lost


def test_one_arm_cell_is_refused(allocated) -> None:
    ctx, plan, _a = allocated
    one = replace(ctx, workcell=replace(ctx.workcell, second_arm=None, second_pedestal=None))
    with pytest.raises(ValueError, match="one arm"):
        allocate(one, plan)


def test_the_two_arms_moves_through_the_zones_never_touch_in_3d(allocated, played) -> None:
    """The coordinated schedule of the allocation: every measurement made, and pybullet's
    URDF arms at every half second of it never touch (nor come within 10 cm)."""
    ctx, _plan, a = allocated
    schedule, jobs = played
    made = {m.label for j in jobs for m in j.moves}
    assert set(a.assigned) <= made
    assert schedule.makespan_s < a.one_arm_s
    times = np.arange(0.0, schedule.makespan_s, 0.5)
    q = configurations_at(schedule, jobs, times)
    with TwoArms(ctx.workcell) as arms:
        gaps = arms.gaps(q["t3"], q["t3_b"])
    assert gaps.min() > 0.1


@pytest.mark.parametrize(("down", "into"), [("t3_b", 0.05), ("t3_b", 0.4), ("t3", 0.4)])
def test_an_arm_down_mid_plan_hands_its_remaining_work_to_the_other(allocated, played, down: str,
                                                                    into: float) -> None:
    """The downed arm stops where it is; the other finishes its own work and makes the
    downed arm's remaining measurements it can, never touching the stopped arm (3-D);
    every measurement is made before, handed over, or lost with a reason.  (Where the
    downed arm stands decides how much the other can still make: its body bars the part
    of the cell it was working in, and may bar the other's tools in the rack.)"""
    from ita.executive.two_arms import hand_over

    ctx, plan, a = allocated
    schedule, jobs = played
    # down while measuring, that far into the plan (not at the rack)
    at = next(moved for start, moved, _end, _a, _b, label in schedule.timeline[down]
              if start >= into * schedule.makespan_s and label in a.assigned)
    h = hand_over(ctx, plan, a, schedule, jobs, down, at)
    survivor = next(j.name for j in jobs if j.name != down)
    theirs = {i for i, arm in a.assigned.items() if arm == down}
    made_after = {lab for *_t, lab in h.schedule.timeline[survivor] if lab in a.assigned}
    lost = dict(h.lost)
    assert set(h.handed) <= made_after and set(h.handed) <= theirs
    if down == "t3_b":                                    # the first arm reaches the whole part
        assert all("out of reach" not in w for w in lost.values())
    if into < 0.1:                     # down early: the other takes over much of what it left
        left = theirs - set(h.done)
        assert len(h.handed) >= 0.25 * len(left), (len(h.handed), len(left))
    for i in a.assigned:                                  # nothing is dropped silently
        assert i in h.done or i in made_after or (i in lost and lost[i]), i
    assert not set(h.done) & made_after                   # nothing made twice
    assert h.makespan_s > at
    times = np.arange(0.0, h.schedule.makespan_s + 0.5, 0.5)
    q = configurations_at(h.schedule, list(h.jobs), times)
    with TwoArms(ctx.workcell) as arms:
        gaps = arms.gaps(q[jobs[0].name], q[jobs[1].name])
    assert gaps.min() > 0.0                               # the moving arm never touches the stopped one


def test_the_allocation_is_kept_between_runs_and_a_damaged_store_is_made_again(allocated) -> None:
    from ita.sequence.allocation_store import allocation_path, stored_allocation

    ctx, plan, a = allocated
    path = allocation_path(ctx.part_name)
    path.unlink(missing_ok=True)
    first, kept = stored_allocation(ctx, plan)
    assert not kept and first == a and path.exists()
    again, kept = stored_allocation(ctx, plan)
    assert kept and again == first                                  # the same, to the last bit
    path.write_text('{"format": 1, "digest": "x", "shares": [', encoding="utf-8")
    third, kept = stored_allocation(ctx, plan)
    assert not kept and third == first
    other = replace(ctx, specs=ctx.specs[:-1], _facts_cache={})     # another plan: not the stored one
    assert stored_allocation(other, build_plan(other))[1] is False
