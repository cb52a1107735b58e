"""Building, storing and stepping through sequence plans; resequencing when tools break."""

from __future__ import annotations

import json
from dataclasses import replace

import numpy as np
import pytest

from ita.errors import InputError
from ita.sequence.next_step import next_step, peek
from ita.sequence.plan import (
    MOTION_TIME_COST,
    build_plan,
    following,
    planning_context,
    tool_at_start,
    tool_points_world,
)
from ita.sequence.store import (
    PlanNotFound,
    PlanStale,
    apply_tool_marks,
    check_current,
    load_plan,
    load_tool_marks,
    marked,
    plan_from_dict,
    plan_path,
    save_plan,
    save_tool_marks,
    tool_marks_applied,
)


@pytest.fixture(autouse=True)
def private_home(tmp_path, monkeypatch):
    monkeypatch.setenv("ITA_HOME", str(tmp_path / "home"))


@pytest.fixture(scope="module")
def full_ctx(knowledge_base, builtin_part):
    # the geometry alone: not what a stored MKB of the session could not place
    return planning_context(kb=knowledge_base, part=builtin_part, method="classic", use_mkb=False)


@pytest.fixture(scope="module")
def ctx(full_ctx):
    """A small context: the first 6 specs of each kind (54 specs), classic method."""
    per_kind: dict = {}
    for s in full_ctx.specs:
        per_kind.setdefault(s.kind, [])
        if len(per_kind[s.kind]) < 6:
            per_kind[s.kind].append(s)
    specs = tuple(s for group in per_kind.values() for s in group)
    return replace(full_ctx, specs=specs)


@pytest.fixture()
def world(knowledge_base):
    """world(marks): a context manager applying tool marks for a block (reset after)."""
    return lambda marks: tool_marks_applied(knowledge_base, marks)


def _planned(plan):
    return [i for g in plan.groups for i in g.order]


def _all_ids(plan):
    return _planned(plan) + list(plan.done) + [i for i, _ in plan.cannot]


def test_plan_accounts_for_every_measurement(ctx, world):
    with world({}):
        plan = build_plan(ctx)
    ids = [s.id for s in ctx.specs]
    assert sorted(_all_ids(plan)) == sorted(ids)
    # the SLRA the run registers the part with is in hand when it starts to measure: its
    # group first, and only the probe to pick up
    assert [g.tool for g in plan.groups] == ["slra_1", "us_probe_1"] and tool_at_start(ctx.kb) == "slra_1"
    assert plan.tool_changes == 1
    assert not plan.cost_interim and plan.cost_model == MOTION_TIME_COST.name
    assert plan.total_s == pytest.approx(sum(g.cost_s for g in plan.groups) + plan.transfer_s)
    assert plan.transfer_s > 0


def test_group_cost_is_the_closed_tour_from_the_rack(ctx, world):
    with world({}):
        plan = build_plan(ctx)
    g = plan.groups[1]
    spec = ctx.workcell.tool(g.tool)
    specs = [ctx.spec(i) for i in g.order]
    m = ctx.cost_model.tour(ctx.workcell, spec, specs)  # stops in visiting order
    n = len(specs)
    expected = m[0, 1] + sum(m[k, k + 1] for k in range(1, n)) + m[n, 0]
    assert g.cost_s == pytest.approx(expected)


def test_slra_point_is_at_its_standoff(ctx):
    spec = ctx.specs[0]
    us = tool_points_world(ctx.workcell, ctx.workcell.tool("us_probe_1"), [spec])
    slra = tool_points_world(ctx.workcell, ctx.workcell.tool("slra_1"), [spec])
    assert np.linalg.norm(slra - us) == pytest.approx(ctx.workcell.tool("slra_1").standoff_nominal)


def test_held_tool_goes_first_and_saves_a_change(ctx, world):
    with world({"us_probe_1": {"location": "on_arm(t3)"}}):
        plan = build_plan(ctx)
    assert [g.tool for g in plan.groups] == ["us_probe_1", "slra_1"]
    assert plan.tool_changes == 1


def test_plan_with_done_and_broken_tools(ctx, world):
    done = [ctx.specs[0].id, ctx.specs[-1].id]
    with world({"us_probe_1": {"condition": "broken"}, "us_probe_2": {"condition": "broken"}}):
        plan = build_plan(ctx, done=done)
    assert plan.done == tuple(done)
    webs = {s.id for s in ctx.specs if s.kind.value == "web_thickness"} - set(done)
    flanges = {s.id for s in ctx.specs if s.kind.value == "flange_thickness"} - set(done)
    cannot = {i for i, _ in plan.cannot}
    assert webs <= cannot and {r for _, r in plan.cannot} == {"no_working_tool(us_tool)"}
    # a flange wall's thickness falls back to the probe bent 90 degrees (a cap's top it
    # cannot reach: its holder would lie along the part's face)
    assert sorted(g.tool for g in plan.groups) == ["slra_1", "us_probe_90"]
    bent = set(next(g.order for g in plan.groups if g.tool == "us_probe_90"))
    assert "FT-OFL01-W1" in bent and bent | (cannot - webs) == flanges
    assert plan.tool_state["us_probe_1"]["condition"] == "broken"


def test_store_round_trip(ctx, world):
    with world({}):
        plan = build_plan(ctx)
    path = save_plan(plan)
    assert path == plan_path(ctx.part_name) and path.parent.name == "plans"
    assert load_plan(ctx.part_name) == plan
    assert plan_from_dict(json.loads(path.read_text())) == plan
    assert not list(path.parent.glob(".*.tmp"))  # atomic write left no temporary file
    check_current(plan, ctx.specs_digest)
    with pytest.raises(PlanStale):
        check_current(plan, "0" * 64)


def test_missing_and_bad_plans(tmp_path):
    with pytest.raises(PlanNotFound):
        load_plan("nothing-here")
    bad = tmp_path / "bad.json"
    bad.write_text("{\"version\": 1}")
    with pytest.raises(InputError, match="not a sequence plan"):
        load_plan("x", bad)
    bad.write_text("{oops")
    with pytest.raises(InputError, match="not valid JSON"):
        load_plan("x", bad)


def test_tool_marks(knowledge_base):
    marks = marked({}, "us_probe_1", "broken")
    marks = marked(marks, "slra_1", "missing")
    assert marks == {"us_probe_1": {"condition": "broken"}, "slra_1": {"missing": True}}
    assert marked(marks, "slra_1", "found") == {"us_probe_1": {"condition": "broken"}}
    assert marked(marks, "us_probe_1", "ok") == {"slra_1": {"missing": True}}
    with pytest.raises(InputError, match="unknown mark"):
        marked(marks, "slra_1", "melted")
    save_tool_marks(marks)
    assert load_tool_marks() == marks
    with tool_marks_applied(knowledge_base, marks):
        assert not knowledge_base.holds("world", "available", "us_probe_1")
        assert not knowledge_base.holds("world", "available", "slra_1")
        assert knowledge_base.holds("world", "available", "slra_2")
    assert knowledge_base.holds("world", "available", "us_probe_1")  # reset after the block
    with pytest.raises(InputError, match="unknown tool 'drill'"):
        apply_tool_marks(knowledge_base, {"drill": {"condition": "broken"}})


def _step_through(ctx, plan, n):
    steps = []
    for _ in range(n):
        result = next_step(ctx, plan)
        plan = result.plan
        steps.append(result)
    return steps, plan


def test_next_step_follows_the_stored_order(ctx, world):
    with world({}):
        plan = build_plan(ctx)
        expected = [i for _, i in peek(plan, 5)]
        steps, plan = _step_through(ctx, plan, 5)
    assert [r.step.spec_id for r in steps] == expected == _planned(plan)[:5]
    assert not any(r.resequenced for r in steps)
    assert plan.handed_out == tuple(expected)
    assert steps[0].step.tool == "slra_1" and steps[0].step.arm == "t3"
    assert steps[-1].step.remaining == len(_planned(plan)) - 5


def test_an_arm_of_two_follows_its_shares_tours_in_their_order_then_the_rest(ctx, world):
    """A two-arm run's arm takes its share in the order of the allocation's tours (each its
    own tool, arranged for both arms): handed out in that order, with that tool; what the
    tours leave keeps its groups after them."""
    with world({}):
        plan = build_plan(ctx)
        slra, probe = (g.order for g in plan.groups[:2])
        tours = [(plan.groups[1].tool, tuple(reversed(probe[:4]))), (plan.groups[0].tool, (slra[3], slra[0]))]
        followed = following(plan, tours, ctx.workcell, [12.5, 3.0])
        steps, after = _step_through(ctx, followed, 6)
    assert [r.step.spec_id for r in steps] == [*reversed(probe[:4]), slra[3], slra[0]]
    assert [r.step.tool for r in steps] == [plan.groups[1].tool] * 4 + [plan.groups[0].tool] * 2
    assert not any(r.resequenced for r in steps)
    assert [g.cost_s for g in followed.groups[:2]] == [12.5, 3.0]
    # nothing lost, nothing twice; the rest in its groups' order after the tours
    assert sorted(_planned(followed)) == sorted(_planned(plan))
    assert _planned(followed)[6:] == [i for i in _planned(plan) if i not in {*probe[:4], slra[3], slra[0]}]
    assert after.handed_out[:6] == tuple(r.step.spec_id for r in steps)


def test_broken_probe_with_spare_continues_in_the_same_order(ctx, world):
    with world({}):
        plan = build_plan(ctx)
        n_slra = len(plan.groups[0].order)
        _steps, plan = _step_through(ctx, plan, n_slra + 3)  # 3 into the probe's group
    us_order = plan.groups[1].order
    with world({"us_probe_1": {"condition": "broken"}}):
        result = next_step(ctx, plan)
    assert result.resequenced and result.reason == "tool us_probe_1 not available (broken)"
    assert result.step.tool == "us_probe_2" and result.step.spec_id == us_order[3]
    new = result.plan
    assert [g.tool for g in new.groups] == ["us_probe_2"]
    assert new.groups[0].order == us_order[3:]  # kept, not re-solved
    assert set(new.done) == set(plan.handed_out)
    assert new.handed_out == plan.handed_out + (us_order[3],)
    assert new.history[-1].endswith("resequenced: tool us_probe_1 not available (broken)")


def test_broken_tool_without_spare_moves_to_cannot(ctx, world):
    marks = {"us_probe_1": {"condition": "broken"}, "us_probe_2": {"missing": True}}
    with world({}):
        plan = build_plan(ctx)
    # the probe's group comes second: the first step (SLRA) needs no resequencing ...
    with world(marks):
        first = next_step(ctx, plan)
    assert not first.resequenced and first.step.tool == "slra_1"
    # ... until the SLRA's group is done
    with world({}):
        _steps, plan = _step_through(ctx, first.plan, len(plan.groups[0].order) - 1)
    with world(marks):
        result = next_step(ctx, plan)
    assert result.resequenced and result.reason == "tool us_probe_1 not available (broken)"
    # the flange walls' thicknesses fall back to the probe bent 90 degrees; the rest cannot be done
    probe_ids = plan.groups[1].order
    assert [g.tool for g in result.plan.groups] == ["us_probe_90"]
    bent = set(result.plan.groups[0].order)
    assert "FT-OFL01-W1" in bent and result.step.tool == "us_probe_90" and result.step.spec_id in bent
    assert {ctx.spec(i).kind.value for i in bent} == {"flange_thickness"}
    assert {r for _, r in result.plan.cannot} == {"no_working_tool(us_tool)"}
    assert {i for i, _ in result.plan.cannot} == set(probe_ids) - bent
    # the probe comes back: the cannot-be-done measurements are planned again
    with world({}):
        back = next_step(ctx, result.plan)
    assert back.resequenced and back.reason == "a us_tool is available again"
    assert back.step.tool == "us_probe_1" and back.plan.cannot == ()


def test_rib_widths_move_to_the_probe_when_both_slras_break(ctx, world):
    with world({}):
        plan = build_plan(ctx)
    with world({"slra_1": {"condition": "broken"}, "slra_2": {"condition": "broken"}}):
        result = next_step(ctx, plan)
    assert result.resequenced and result.step.tool == "us_probe_1"
    kinds = {ctx.spec(i).kind.value for i in result.plan.groups[0].order}
    assert kinds == {"web_thickness", "flange_thickness", "stiffener_width"}
    assert {r for _, r in result.plan.cannot} == {"no_working_tool(slra_tool)"}


def test_plan_runs_out(ctx, world):
    small = replace(ctx, specs=ctx.specs[:2])
    with world({}):
        plan = build_plan(small)
        steps, plan = _step_through(small, plan, 3)
    assert [r.step is None for r in steps] == [False, False, True]
    assert set(plan.finished()) == {s.id for s in small.specs}


def test_whole_bulkhead_plan(full_ctx, world):
    with world({}):
        plan = build_plan(full_ctx)
    assert len(full_ctx.specs) > 1000
    assert sorted(_all_ids(plan)) == sorted(s.id for s in full_ctx.specs)
    assert plan.cannot == () and plan.tool_changes == 1          # the SLRA is in hand after the registration
    print(f"\nwhole bulkhead plan ({len(full_ctx.specs)} specs, classic): {plan.build_seconds:.2f} s")
