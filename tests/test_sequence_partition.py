"""Partitioning the bulkhead's measurements by tool (kb/tools.pl through the bridge)."""

from __future__ import annotations

from collections import Counter

import numpy as np
import pytest

from ita.geometry.configurations import contact_poses
from ita.logic.terms import Term
from ita.sequence.partition import (
    feature_kinds_of,
    partition_specs,
    reach_facts,
    select_tools,
    term_text,
)
from ita.sequence.store import tool_marks_applied
from ita.specs.model import MeasurementKind, MeasurementSpec

EXPECTED = {  # kind -> (tool with every tool working, rule)
    MeasurementKind.WEB_THICKNESS: ("us_probe_1", "us_web_thickness"),
    MeasurementKind.FLANGE_THICKNESS: ("us_probe_1", "us_flange_thickness"),
    MeasurementKind.HOLE_DIAMETER: ("slra_1", "slra_hole_diameter"),
    MeasurementKind.HOLE_POSITION: ("slra_1", "slra_hole_position"),
    MeasurementKind.EDGE_DISTANCE: ("slra_1", "slra_edge_distance"),
    MeasurementKind.FLANGE_HEIGHT: ("slra_1", "slra_flange_height"),
    MeasurementKind.FLANGE_WIDTH: ("slra_1", "slra_flange_width"),
    MeasurementKind.STIFFENER_HEIGHT: ("slra_1", "slra_rib_height"),
    MeasurementKind.STIFFENER_WIDTH: ("slra_1", "slra_rib_width"),
}
THICKNESS = {MeasurementKind.WEB_THICKNESS, MeasurementKind.FLANGE_THICKNESS}


@pytest.fixture(scope="module")
def bulkhead_specs(builtin_part):
    from ita.specs.io import read_specs

    return tuple(read_specs(builtin_part.specs_path))


@pytest.fixture(scope="module")
def feature_kinds(builtin_part):
    return feature_kinds_of(builtin_part.features)


@pytest.fixture(scope="module")
def facts(bulkhead_specs):
    from ita.workcell import load_workcell

    return reach_facts(load_workcell(), bulkhead_specs)


@pytest.fixture()
def partition(knowledge_base, bulkhead_specs, feature_kinds, facts):
    """partition(marks=None, done=()) -> Partition of the whole bulkhead with those tool marks."""

    def run(marks=None, done=()):
        with tool_marks_applied(knowledge_base, marks or {}):
            return partition_specs(knowledge_base, bulkhead_specs, feature_kinds, facts, done=done)

    return run


def _kinds(specs, ids):
    by_id = {s.id: s.kind for s in specs}
    return Counter(by_id[i] for i in ids)


def test_bulkhead_is_reachable_for_the_tools_it_needs(facts, bulkhead_specs):
    assert len(facts) == len(bulkhead_specs)
    for f, spec in zip(facts, bulkhead_specs):
        verdict = {t.args[0]: term_text(t) for t in f}
        assert set(verdict) == {"us_tool", "us_bent", "slra_tool"}
        assert verdict["us_tool"] == "reach(us_tool, reachable)", spec.id
        if spec.kind not in THICKNESS:  # some flange walls face away from the SLRA's stand-off
            assert verdict["slra_tool"] == "reach(slra_tool, reachable)", spec.id
        if spec.kind is MeasurementKind.FLANGE_THICKNESS and spec.normal[2] == 0.0:   # a wall
            assert verdict["us_bent"] == "reach(us_bent, reachable)", spec.id


def test_tool_selection_for_every_kind(partition, bulkhead_specs):
    result = partition()
    assert result.cannot == () and result.done == ()
    assert {s.kind for s in bulkhead_specs} == set(EXPECTED)
    for spec in bulkhead_specs:
        sel = result.selections[spec.id]
        assert (sel.tool, sel.rule) == EXPECTED[spec.kind], spec.id
    assert [g.tool for g in result.groups] == ["slra_1", "us_probe_1"]
    us = result.group_of("us_probe_1")
    assert set(_kinds(bulkhead_specs, us.spec_ids)) == THICKNESS
    assert sum(len(g.spec_ids) for g in result.groups) == len(bulkhead_specs)


def test_broken_probe_with_spare(partition):
    before = partition()
    after = partition({"us_probe_1": {"condition": "broken"}})
    assert [g.tool for g in after.groups] == ["slra_1", "us_probe_2"]
    assert after.group_of("us_probe_2").spec_ids == before.group_of("us_probe_1").spec_ids
    assert after.cannot == ()
    why = after.selections[after.group_of("us_probe_2").spec_ids[0]].why
    assert why == ("chosen(us_web_thickness, spare_for(us_probe_1))",)


def test_broken_probe_without_spare(partition, bulkhead_specs):
    result = partition({"us_probe_1": {"condition": "broken"}, "us_probe_2": {"missing": True}})
    # the flanges' thicknesses the probe bent 90 degrees reaches fall back to it
    assert [g.tool for g in result.groups] == ["slra_1", "us_probe_90"]
    bent = result.group_of("us_probe_90")
    assert set(_kinds(bulkhead_specs, bent.spec_ids)) == {MeasurementKind.FLANGE_THICKNESS}
    assert dict(bent.rules) == {"us_bent_flange_thickness": len(bent.spec_ids)}
    n_thick = sum(s.kind in THICKNESS for s in bulkhead_specs)
    assert len(result.cannot) == n_thick - len(bent.spec_ids)
    assert result.cannot_counts() == {"no_working_tool(us_tool)": n_thick - len(bent.spec_ids)}
    assert set(_kinds(bulkhead_specs, [i for i, _ in result.cannot])) == THICKNESS


def test_no_slra_moves_rib_widths_to_the_probe(partition, bulkhead_specs):
    result = partition({"slra_1": {"condition": "worn"}, "slra_2": {"condition": "broken"}})
    us = result.group_of("us_probe_1")
    kinds = _kinds(bulkhead_specs, us.spec_ids)
    assert set(kinds) == THICKNESS | {MeasurementKind.STIFFENER_WIDTH}
    assert dict(us.rules)["us_rib_width"] == kinds[MeasurementKind.STIFFENER_WIDTH]
    rib = next(i for i in us.spec_ids if i.startswith("SW-"))
    assert result.selections[rib].why == ("rejected(slra_rib_width, no_working_tool(slra_tool))",
                                          "chosen(us_rib_width, primary)")
    assert set(result.cannot_counts()) == {"no_working_tool(slra_tool)"}


def test_done_group(partition, bulkhead_specs):
    done = [bulkhead_specs[0].id, bulkhead_specs[500].id, "not-a-spec"]
    result = partition(done=done)
    assert result.done == (bulkhead_specs[0].id, bulkhead_specs[500].id)
    planned = {i for g in result.groups for i in g.spec_ids}
    assert not planned & set(done)
    assert len(planned) == len(bulkhead_specs) - 2


def _spec(spec_id, kind, feature="F1", direction=None, nominal=3.0):
    return MeasurementSpec(id=spec_id, kind=kind, feature=feature, point=(0.0, 0.0, 30.0),
                           normal=(0.0, 0.0, 1.0), nominal=nominal, lower=-0.1, upper=0.1,
                           direction=direction)


def test_unreachable_measurement_cannot_be_done(knowledge_base):
    specs = [_spec("a", MeasurementKind.WEB_THICKNESS), _spec("b", MeasurementKind.HOLE_DIAMETER)]
    facts = [[Term("reach", ("us_tool", "too_far"))], [Term("reach", ("slra_tool", "inside_part"))]]
    with tool_marks_applied(knowledge_base, {}):
        result = partition_specs(knowledge_base, specs, {"F1": "pocket"}, facts)
    assert result.groups == ()
    assert result.cannot == (("a", "unreachable(us_tool, too_far)"), ("b", "no_rule(hole_diameter, pocket)"))


def test_unknown_feature_uses_the_kind_alone(knowledge_base):
    specs = [_spec("a", MeasurementKind.FLANGE_THICKNESS, feature="nowhere")]
    with tool_marks_applied(knowledge_base, {}):
        (sel,) = select_tools(knowledge_base, specs, {}, [[]])
    assert (sel.tool, sel.rule) == ("us_probe_1", "us_flange_thickness")


def test_rib_width_probe_touches_the_side_walls():
    spec = _spec("w", MeasurementKind.STIFFENER_WIDTH, direction=(1.0, 0.0, 0.0), nominal=4.0)
    other = _spec("t", MeasurementKind.WEB_THICKNESS)
    pa, na, pb, nb = contact_poses([spec, other])
    assert np.allclose(pa[0], (-2.0, 0.0, 22.0)) and np.allclose(na[0], (-1.0, 0.0, 0.0))
    assert np.allclose(pb[0], (2.0, 0.0, 22.0)) and np.allclose(nb[0], (1.0, 0.0, 0.0))
    assert np.allclose(pa[1], other.point) and np.allclose(nb[1], other.normal)


def test_facts_and_specs_must_match(knowledge_base):
    with pytest.raises(ValueError, match="fact lists"):
        partition_specs(knowledge_base, [_spec("a", MeasurementKind.WEB_THICKNESS)], {}, [])


def test_term_text():
    assert term_text(Term("no_working_tool", ("us_tool",))) == "no_working_tool(us_tool)"
    assert term_text([Term("reach", ("us_tool", "too_far")), "x"]) == "[reach(us_tool, too_far), x]"
