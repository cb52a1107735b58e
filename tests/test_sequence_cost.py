"""The Sequence Planner's cost: arm motion time between measurement configurations, tool changes."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from ita.geometry.configurations import POSE_OK, measurement_configurations
from ita.kinematics import arm_model, move_time, tcp_poses
from ita.logic.terms import Term
from ita.sequence.cost import (
    COST_MODELS,
    COUPLING_S,
    INTERIM_COST,
    MOTION_TIME_COST,
    flange_move_seconds,
    motion_time_tour,
    pose_facts,
    rack_configurations,
    rack_seconds,
    tool_points_world,
)
from ita.sequence.partition import partition_specs
from ita.sequence.plan import build_plan, planning_context
from ita.sequence.store import tool_marks_applied
from ita.specs.model import MeasurementKind


@pytest.fixture(autouse=True)
def private_home(tmp_path, monkeypatch):
    monkeypatch.setenv("ITA_HOME", str(tmp_path / "home"))


@pytest.fixture(scope="module")
def ctx(knowledge_base, builtin_part):
    """The first 6 specs of each kind (54 specs), classic method, the default cost model."""
    full = planning_context(kb=knowledge_base, part=builtin_part, method="classic", use_mkb=False)
    per_kind: dict = {}
    for s in full.specs:
        if len(per_kind.setdefault(s.kind, [])) < 6:
            per_kind[s.kind].append(s)
    return replace(full, specs=tuple(s for group in per_kind.values() for s in group))


@pytest.fixture(scope="module")
def model(ctx):
    return arm_model(ctx.workcell.arm)


def _specs(ctx, *kinds):
    return [s for s in ctx.specs if s.kind.value in kinds]


@pytest.fixture(scope="module")
def probe_case(ctx, model):
    """(tool, specs, configurations, matrix) of the probe on thickness and rib-width specs."""
    tool = ctx.workcell.tool("us_probe_1")
    specs = _specs(ctx, "web_thickness", "flange_thickness", "stiffener_width")
    return tool, specs, measurement_configurations(ctx.workcell, model, tool, specs), \
        motion_time_tour(ctx.workcell, tool, specs)


def test_default_cost_model_is_the_arm_motion_time(ctx):
    assert ctx.cost_model is MOTION_TIME_COST and not MOTION_TIME_COST.interim
    assert COST_MODELS == {"arm_motion_time": MOTION_TIME_COST, "euclidean_tcp_interim": INTERIM_COST}
    assert INTERIM_COST.interim


def test_tour_matrix_shape_diagonal_symmetry(probe_case):
    _tool, specs, _conf, m = probe_case
    assert m.shape == (len(specs) + 1, len(specs) + 1)
    assert np.all(np.diag(m) == 0.0)
    assert np.allclose(m, m.T, rtol=0, atol=1e-12)  # joint times and the TCP chord are symmetric
    off = m[~np.eye(len(m), dtype=bool)]
    assert np.all(np.isfinite(off)) and off.min() > 0.0


def test_entries_are_the_move_time_between_the_chosen_configurations(ctx, model, probe_case):
    tool, specs, conf, m = probe_case
    q_slot, _ = rack_configurations(ctx.workcell, model, tool.name)
    stops = np.vstack([q_slot, conf.q])
    tcp = tcp_poses(model, stops, tool.tcp.matrix())[:, :3, 3]
    for i, j in [(0, 1), (1, 0), (0, len(specs)), (1, 2), (3, 7), (5, len(specs))]:
        joint = float(move_time(model, stops[i], stops[j]))
        chord = float(np.linalg.norm(tcp[i] - tcp[j])) / model.max_tool_speed
        assert m[i, j] == pytest.approx(max(joint, chord), rel=1e-9)
        assert m[i, j] >= joint - 1e-12
    # stop 0 is the tool coupled in its rack slot: the flange at the slot's pose
    slot = ctx.workcell.slot_of(tool.name).pose.matrix()
    from ita.kinematics import flange_poses

    assert np.allclose(flange_poses(model, q_slot[None])[0], slot, atol=1e-9)


def test_chosen_configurations_put_the_tool_on_the_measurement(ctx, model, probe_case):
    tool, specs, conf, _m = probe_case
    assert conf.found.all() and all(s == POSE_OK for s in conf.status)
    assert model.within_limits(conf.q).all()
    tips = tcp_poses(model, conf.q, tool.tcp.matrix())
    thickness = [k for k, s in enumerate(specs) if s.kind is not MeasurementKind.STIFFENER_WIDTH]
    expected = tool_points_world(ctx.workcell, tool, [specs[k] for k in thickness])
    assert np.allclose(tips[thickness, :3, 3], expected, atol=1e-9)
    normals = ctx.workcell.part.normals_to_world(np.array([specs[k].normal for k in thickness], dtype=float))
    assert np.allclose(tips[thickness, :3, 2], -normals, atol=1e-9)  # looking into the surface
    # a rib's width: the probe touches a side wall, looking along the measuring direction
    rib = [k for k, s in enumerate(specs) if s.kind is MeasurementKind.STIFFENER_WIDTH]
    assert rib
    for k in rib:
        axis = ctx.workcell.part.normals_to_world(np.array([specs[k].direction], dtype=float))[0]
        assert abs(float(tips[k, :3, 2] @ axis)) == pytest.approx(1.0, abs=1e-9)
    # one branch for the whole group, near the reference configuration
    assert conf.in_branch.all()


def test_slra_keeps_its_nominal_standoff_when_it_can(ctx, model):
    tool = ctx.workcell.tool("slra_1")
    specs = _specs(ctx, "hole_diameter", "flange_height")
    conf = measurement_configurations(ctx.workcell, model, tool, specs)
    tcp = tcp_poses(model, conf.q, tool.tcp.matrix())[:, :3, 3]
    assert np.allclose(tcp, tool_points_world(ctx.workcell, tool, specs), atol=1e-9)


def test_rack_seconds_add_up(ctx, model):
    cell = ctx.workcell
    pick = rack_seconds(cell, None, "us_probe_1")
    put = rack_seconds(cell, "slra_1", None)
    _, above_a = rack_configurations(cell, model, "slra_1")
    _, above_b = rack_configurations(cell, model, "us_probe_1")
    between = flange_move_seconds(model, above_a, above_b)
    assert pick > COUPLING_S and put > COUPLING_S and between > 0
    assert rack_seconds(cell, "slra_1", "us_probe_1") == pytest.approx(put + between + pick)
    assert rack_seconds(cell, None, None) == 0.0


def test_plan_total_includes_the_tool_changes(ctx, knowledge_base):
    t = MOTION_TIME_COST.transfer
    with tool_marks_applied(knowledge_base, {}):
        plan = build_plan(ctx)
    a, b = [g.tool for g in plan.groups]
    # the SLRA the part is registered with is in hand at the start: its group first, no pick-up
    assert (a, plan.tool_changes) == ("slra_1", 1)
    assert plan.transfer_s == pytest.approx(t(ctx.workcell, a, b) + t(ctx.workcell, b, None))
    assert plan.total_s == pytest.approx(sum(g.cost_s for g in plan.groups) + plan.transfer_s)
    assert plan.transfer_s > 3 * COUPLING_S  # a put-down, a pick-up and a put-down
    # held: the first pick-up is saved
    with tool_marks_applied(knowledge_base, {"us_probe_1": {"location": "on_arm(t3)"}}):
        held = build_plan(ctx)
    assert [g.tool for g in held.groups] == ["us_probe_1", "slra_1"] and held.tool_changes == 1
    assert held.transfer_s == pytest.approx(t(ctx.workcell, "us_probe_1", "slra_1")
                                            + t(ctx.workcell, "slra_1", None))


def test_interim_model_is_still_available_and_labelled(ctx, knowledge_base):
    with tool_marks_applied(knowledge_base, {}):
        plan = build_plan(replace(ctx, cost_model=INTERIM_COST))
    assert plan.cost_interim and plan.cost_model == INTERIM_COST.name and plan.total_s > 0


def _far(spec):
    """The spec moved 3 m up the part (world z): no arm configuration reaches it."""
    x, y, z = spec.point
    return replace(spec, id=spec.id + "-far", point=(x, y + 3000.0, z))


def test_pose_facts_give_the_ik_verdict(ctx):
    near = _specs(ctx, "web_thickness")[0]
    facts = pose_facts(ctx.workcell, [near, _far(near)])
    assert Term("pose", ("us_tool", POSE_OK)) in facts[0] and Term("pose", ("slra_tool", POSE_OK)) in facts[0]
    verdicts = {f.args[0]: f.args[1] for f in facts[1] if f.name == "pose"}
    assert verdicts == {"us_tool": "out_of_reach", "us_bent": "out_of_reach", "slra_tool": "out_of_reach"}
    assert len(facts[1]) == 6  # the reach facts stay, one per tool class


def test_no_pose_goes_to_cannot_be_done(ctx, knowledge_base):
    """A reach test too optimistic to refute a spec: the IK's pose fact sends it to cannot."""
    near = _specs(ctx, "web_thickness")[0]
    specs = [near, _far(near)]

    def optimistic(workcell, specs):
        return [[f for f in row if f.name != "reach"] + [Term("reach", ("us_tool", "reachable")),
                                                          Term("reach", ("slra_tool", "reachable"))]
                for row in pose_facts(workcell, specs)]

    with tool_marks_applied(knowledge_base, {}):
        part = partition_specs(knowledge_base, specs, ctx.feature_kinds, optimistic(ctx.workcell, specs))
    assert part.cannot == ((specs[1].id, "no_pose(us_tool, out_of_reach)"),)
    assert [g.spec_ids for g in part.groups] == [(near.id,)]
    with pytest.raises(ValueError, match="no arm configuration for 1 measurement"):
        motion_time_tour(ctx.workcell, ctx.workcell.tool("us_probe_1"), specs)
