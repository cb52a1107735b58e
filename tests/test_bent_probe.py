"""The probe bent 90 degrees (us_probe_90): the four bulkhead flange walls the 45-degree probe
cannot touch (its contact pose collides at every roll and arm branch) are planned for it,
placed by the Geometric Reasoner and measured in a run."""

from __future__ import annotations

import numpy as np
import pytest

from ita.logic.terms import Term

BLOCKED = ("FT-OFL01-W1", "FT-OFL02-W1", "FT-OFL15-W1", "FT-OFL16-W1")


@pytest.fixture(scope="module")
def prepared(builtin_part, knowledge_base):
    """The built-in part's planning context, sequence plan, MKB and preparation report."""
    from ita.offline.prepare import prepare_inspection
    from ita.sequence.plan import planning_context

    ctx = planning_context(None, kb=knowledge_base, part=builtin_part)
    plan, mkb, report = prepare_inspection(ctx, builtin_part, warm=False)
    return ctx, plan, mkb, report


def test_every_measurement_can_be_done_the_blocked_walls_with_the_bent_probe(prepared) -> None:
    _, plan, mkb, report = prepared
    assert report.cannot == ()
    group = next(g for g in plan.groups if g.tool == "us_probe_90")
    assert set(group.order) == set(BLOCKED) and group.tool_class == "us_bent"
    assert dict(group.rules) == {"us_bent_flange_thickness": len(BLOCKED)}
    for spec_id in BLOCKED:
        assert mkb.entries[spec_id].tool == "us_probe_90" and mkb.entries[spec_id].ok
        straight = mkb.entry_for(spec_id, "us_tool")       # the MKB's reason, kept as an alternative
        assert straight is not None and straight.status == "contact_blocked"
    # every other flange thickness stays with the straight probe (one tool change more, no more)
    straight_group = next(g for g in plan.groups if g.tool == "us_probe_1")
    assert sum(1 for i in straight_group.order if i.startswith("FT-")) == 80 - len(BLOCKED)


def test_the_bent_probe_is_perpendicular_pressed_and_approaches_through_free_space(prepared, builtin_part) -> None:
    from ita.path import planners_for

    ctx, _, mkb, _ = prepared
    cell = ctx.workcell
    entries = [mkb.entries[i] for i in BLOCKED]
    planner, tool = planners_for(cell, builtin_part)("us_probe_90")
    assert planner.config_free(np.array([e.q_approach for e in entries]), tool).all()
    for e in entries:
        spec = ctx.spec(e.spec_id)
        point = cell.part.to_world(np.array([spec.point]))[0]
        normal = cell.part.normals_to_world(np.array([spec.normal]))[0]
        normal /= np.linalg.norm(normal)
        assert np.dot(e.pose[:3, 2], -normal) > 0.9999
        assert np.dot(e.pose[:3, 3] - point, -normal) == pytest.approx(e.press_m, abs=1e-6)
        assert np.dot(e.pose_approach[:3, 3] - point, normal) >= tool.approach_distance - 1e-9
        flange_axis = e.pose[:3, :3] @ tool.tcp.rotation().T[:, 2]          # the holder runs across the normal
        assert abs(np.dot(flange_axis, normal)) < 1e-6


def test_a_resequencing_keeps_the_walls_on_the_bent_probe(prepared, knowledge_base) -> None:
    """The MKB's placements ride in the planning context's facts (with_mkb): a plan made
    again, or one measurement's tool chosen again, still sends the walls to the bent probe;
    the geometry alone (no MKB) would not know the straight probe's contact collides."""
    from dataclasses import replace

    from ita.sequence.plan import build_plan, choose_tool, with_mkb

    ctx, _, mkb, _ = prepared
    placed = with_mkb(ctx, mkb)
    again = build_plan(placed)
    assert set(next(g.order for g in again.groups if g.tool == "us_probe_90")) == set(BLOCKED)
    sel = choose_tool(placed, "FT-OFL01-W1")
    assert sel.tool == "us_probe_90"
    assert sel.why == ("rejected(us_flange_thickness, not_placed(us_tool, contact_blocked))",
                       "chosen(us_bent_flange_thickness, primary)")
    bare = replace(ctx, facts=placed.facts.base, _facts_cache={})
    assert choose_tool(bare, "FT-OFL01-W1").tool == "us_probe_1"
    facts = placed.facts(ctx.workcell, [ctx.spec("FT-OFL01-W1")])[0]
    assert Term("placed", ("us_tool", "contact_blocked")) in facts
    assert Term("placed", ("us_bent", "placed")) in facts


def test_a_run_measures_the_four_walls_with_the_bent_probe(builtin_part, tmp_path) -> None:
    from ita.archive import Archive
    from ita.scoring.truth import true_values
    from ita.task import open_session
    from ita.toplevel import RunSignals, TopLevel

    session = open_session(None, seed=3)
    try:
        with Archive.open(tmp_path / "archive.sqlite") as archive:
            run_id = archive.create_run("bulkhead", session.part.directory, seed=3,
                                        settings={"specs": list(BLOCKED)}, total=len(BLOCKED))
            summary = TopLevel(session, archive, run_id, RunSignals(message=None)).run()
            results = archive.results(run_id)
            events = archive.events(run_id)
    finally:
        session.close()
    assert summary.status == "completed"
    assert sorted(r.spec_id for r in results) == sorted(BLOCKED)
    truth = true_values(builtin_part.directory)
    for r in results:
        assert r.outcome.value == "measured" and r.tool == "us_probe_90", (r.spec_id, r.outcome, r.reason)
        assert r.decision is not None and 0.0 < r.u < 0.05
        assert abs(r.value - truth[r.spec_id]) <= r.k * r.u, (r.spec_id, r.value, truth[r.spec_id], r.u)
    picked = [e for e in events if e.kind == "command" and e.payload.get("name") == "pickup"]
    assert picked, "no tool change recorded"
