"""The Operation Planner facade: pinned plans per measurement kind, lookup, the store."""

from __future__ import annotations

import pytest

from ita.logic.terms import Term
from ita.planning import (
    NoPlanError,
    OperationPlanner,
    Place,
    PlanSource,
    PoseKind,
    QualitativePose,
    WorldState,
    store_path,
)
from ita.specs.model import MeasurementKind, MeasurementSpec

US_KINDS = [MeasurementKind.WEB_THICKNESS, MeasurementKind.FLANGE_THICKNESS]
SLRA_KINDS = [k for k in MeasurementKind if k not in US_KINDS]


def meas(i: str) -> Term:
    return Term("meas", (i,))


def rack(slot: str) -> Term:
    return Term("rack", (slot,))


def spec(mid: str, kind: MeasurementKind) -> MeasurementSpec:
    return MeasurementSpec(mid, kind, "f1", (0.0, 0.0, 0.0), (0.0, 0.0, 1.0), 2.5, -0.1, 0.1)


def tool(kind: MeasurementKind) -> str:
    """The tool the Sequence Planner chooses for a kind with every tool working."""
    return "us_probe_1" if kind in US_KINDS else "slra_1"


AT_A = QualitativePose(PoseKind.CONTACT, Place.meas("a"))
EMPTY = WorldState()
PROBE_AT_A = WorldState(pose=AT_A, holding="us_probe_1")
SLRA_AT_A = WorldState(pose=AT_A, holding="slra_1")

# (state, tool type) -> the expected actions for measurement b
US_IN_HAND = [("move_retract", ("t3", "a")), ("move", ("t3", meas("a"), meas("b"))),
              ("apply_couplant", ("t3", "b")), ("move_contact", ("t3", "b")),
              ("us_measure", ("us_probe_1", "t3", "b"))]
US_FROM_RACK = [("move", ("t3", "home", rack("slot_1"))), ("pick_up", ("t3", "us_probe_1", "slot_1")),
                ("move", ("t3", rack("slot_1"), meas("b"))), ("apply_couplant", ("t3", "b")),
                ("move_contact", ("t3", "b")), ("us_measure", ("us_probe_1", "t3", "b"))]
SLRA_IN_HAND = [("move_retract", ("t3", "a")), ("move", ("t3", meas("a"), meas("b"))),
                ("move_view", ("t3", "b")), ("slra_scan", ("slra_1", "t3", "b")),
                ("slra_measure", ("slra_1", "t3", "b"))]
SLRA_FROM_RACK = [("move", ("t3", "home", rack("slot_3"))), ("pick_up", ("t3", "slra_1", "slot_3")),
                  ("move", ("t3", rack("slot_3"), meas("b"))), ("move_view", ("t3", "b")),
                  ("slra_scan", ("slra_1", "t3", "b")), ("slra_measure", ("slra_1", "t3", "b"))]
SLRA_AFTER_US = [("move_retract", ("t3", "a")), ("move", ("t3", meas("a"), rack("slot_1"))),
                 ("put_down", ("t3", "us_probe_1", "slot_1")),
                 ("move", ("t3", rack("slot_1"), rack("slot_3"))),
                 ("pick_up", ("t3", "slra_1", "slot_3")), ("move", ("t3", rack("slot_3"), meas("b"))),
                 ("move_view", ("t3", "b")), ("slra_scan", ("slra_1", "t3", "b")),
                 ("slra_measure", ("slra_1", "t3", "b"))]

CASES = (
    [(k, PROBE_AT_A, US_IN_HAND) for k in US_KINDS]
    + [(k, EMPTY, US_FROM_RACK) for k in US_KINDS]
    + [(k, SLRA_AT_A, SLRA_IN_HAND) for k in SLRA_KINDS]
    + [(k, EMPTY, SLRA_FROM_RACK) for k in SLRA_KINDS]
    + [(k, PROBE_AT_A, SLRA_AFTER_US) for k in SLRA_KINDS]
)


@pytest.fixture(scope="module")
def kb():
    from ita.logic.bridge import KnowledgeBase

    return KnowledgeBase()


@pytest.fixture
def planner(kb, tmp_path):
    with OperationPlanner(kb, tmp_path / "macrops" / "part.pl") as p:
        yield p


def actions(plan) -> list[tuple[str, tuple]]:
    return [(s.action, s.args) for s in plan.steps]


@pytest.mark.parametrize("kind,state,expected", CASES,
                         ids=[f"{k.value}-{s.holding or 'empty'}" for k, s, _ in CASES])
def test_plan_per_kind_scratch_then_macrop(planner, kind, state, expected):
    first = planner.plan_measurement(spec("b", kind), state, tool(kind))
    again = planner.plan_measurement(spec("b", kind), state, tool(kind))
    from_scratch = planner.plan_measurement(spec("b", kind), state, tool(kind), from_scratch=True)
    assert actions(first) == expected
    assert actions(again) == expected
    assert actions(from_scratch) == expected
    assert again.source is PlanSource.MACROP and again.matched
    assert from_scratch.source is PlanSource.SCRATCH


def test_figure_4_case_uses_the_hand_written_macrop(planner):
    plan = planner.plan_measurement(spec("b", MeasurementKind.WEB_THICKNESS), PROBE_AT_A, "us_probe_1")
    assert plan.source is PlanSource.MACROP and plan.macrop_name == "kb:measured"
    assert [s.predecessors for s in plan.steps] == [(), (1,), (2,), (3,), (4,)]


def test_first_plan_from_rack_is_learned_then_reused_for_another_point(planner):
    first = planner.plan_measurement(spec("b", MeasurementKind.HOLE_DIAMETER), EMPTY, "slra_1")
    other = planner.plan_measurement(spec("c", MeasurementKind.EDGE_DISTANCE), EMPTY, "slra_1")
    assert first.source is PlanSource.SCRATCH and first.macrop_name == "m1"
    assert other.source is PlanSource.MACROP and other.macrop_name == "m1"
    assert other.steps[-1].args == ("slra_1", "t3", "c")
    assert planner.counts().lookups == 2 and planner.counts().hits == 1


def test_goal_constraint_keeps_an_ultrasonic_macrop_from_an_slra_measurement(planner):
    planner.plan_measurement(spec("b", MeasurementKind.WEB_THICKNESS), EMPTY, "us_probe_1")
    slra = planner.plan_measurement(spec("c", MeasurementKind.HOLE_POSITION), EMPTY, "slra_1")
    assert slra.source is PlanSource.SCRATCH
    assert slra.steps[1].args[1] == "slra_1"


def test_final_state_chains_measurements(planner):
    first = planner.plan_measurement(spec("b", MeasurementKind.WEB_THICKNESS), EMPTY, "us_probe_1")
    assert first.final_state == WorldState(pose=QualitativePose(PoseKind.CONTACT, Place.meas("b")),
                                           holding="us_probe_1")
    second = planner.plan_measurement(spec("c", MeasurementKind.HOLE_DIAMETER), first.final_state, "slra_1")
    assert second.final_state == WorldState(pose=QualitativePose(PoseKind.VIEWING, Place.meas("c")), holding="slra_1")
    assert ("put_down", ("t3", "us_probe_1", "slot_1")) in actions(second)


def test_store_persists_with_counts_between_planners(kb, tmp_path):
    path = tmp_path / "store.pl"
    with OperationPlanner(kb, path) as p:
        p.plan_measurement(spec("b", MeasurementKind.STIFFENER_HEIGHT), EMPTY, "slra_1")
        p.plan_measurement(spec("c", MeasurementKind.STIFFENER_WIDTH), EMPTY, "slra_1")
    text = path.read_text()
    assert "store_counts(2, 1, 1)" in text and "macrop(1," in text
    with OperationPlanner(kb, path) as p:
        plan = p.plan_measurement(spec("d", MeasurementKind.FLANGE_WIDTH), EMPTY, "slra_1")
        assert plan.source is PlanSource.MACROP and plan.macrop_name == "m1"
        assert p.counts().lookups == 3
        learned = [m for m in p.macrops() if m.learned]
        assert [(m.name, m.steps, m.hits) for m in learned] == [("m1", 6, 2)]


def test_clear_forgets_learned_macrops(planner):
    planner.plan_measurement(spec("b", MeasurementKind.WEB_THICKNESS), EMPTY, "us_probe_1")
    assert planner.clear() == 1
    assert [m.name for m in planner.macrops()] == ["kb:measured"]
    plan = planner.plan_measurement(spec("c", MeasurementKind.WEB_THICKNESS), EMPTY, "us_probe_1")
    assert plan.source is PlanSource.SCRATCH and plan.macrop_name == "m1"


def test_macrop_text_reads_like_figure_4(planner):
    planner.plan_measurement(spec("b", MeasurementKind.WEB_THICKNESS), EMPTY, "us_probe_1")
    text = planner.macrop_text("m1")
    for keyword in ("purpose(", "preconditions(", "adders(", "unary_constraints(",
                    "n_ary_constraints(", "resources(", "plan("):
        assert keyword in text
    with pytest.raises(KeyError):
        planner.macrop_text("m9")
    with pytest.raises(ValueError):
        planner.macrop_text("nonsense")


def test_no_plan_when_every_tool_of_the_kind_is_broken(kb, planner):
    kb.once("world", "set_tool_condition", "us_probe_1", "broken")
    kb.once("world", "set_tool_condition", "us_probe_2", "broken")
    try:
        with pytest.raises(NoPlanError) as info:
            planner.plan_measurement(spec("b", MeasurementKind.WEB_THICKNESS), EMPTY, "us_probe_1")
        assert info.value.exit_code == 1
    finally:
        kb.once("world", "reset_world")


def test_the_sequence_planners_tool_is_the_one_planned(kb, planner):
    """With probe 1 broken the Sequence Planner hands out its spare: the plan uses it."""
    kb.once("world", "set_tool_condition", "us_probe_1", "broken")
    try:
        plan = planner.plan_measurement(spec("b", MeasurementKind.WEB_THICKNESS), EMPTY, "us_probe_2")
        with pytest.raises(NoPlanError):
            planner.plan_measurement(spec("c", MeasurementKind.WEB_THICKNESS), EMPTY, "us_probe_1")
    finally:
        kb.once("world", "reset_world")
    assert plan.steps[-1].args[0] == "us_probe_2"
    assert ("pick_up", ("t3", "us_probe_2", "slot_2")) in actions(plan)


def test_a_rib_width_given_the_probe_is_planned_with_the_probe(planner):
    plan = planner.plan_measurement(spec("b", MeasurementKind.STIFFENER_WIDTH), EMPTY, "us_probe_1")
    assert actions(plan) == US_FROM_RACK


def test_a_tool_that_cannot_take_the_kind_is_refused(planner):
    from ita.errors import PrologError

    with pytest.raises(PrologError, match="tool_for"):
        planner.plan_measurement(spec("b", MeasurementKind.HOLE_DIAMETER), EMPTY, "us_probe_1")


def test_store_path_is_under_ita_home(monkeypatch, tmp_path):
    monkeypatch.setenv("ITA_HOME", str(tmp_path))
    assert store_path("bulkhead") == tmp_path / "macrops" / "bulkhead.pl"
    assert store_path("a/b").parent == tmp_path / "macrops"
