"""The Geometric Reasoner and the Measurement Knowledge Base."""

from __future__ import annotations

import numpy as np
import pytest

from ita.geometry import (
    GeometricReasoner,
    Target,
    load_mkb,
    save_mkb,
    view_groups,
)
from ita.kinematics import arm_model, tcp_poses
from ita.logic.terms import Term


@pytest.fixture(scope="module")
def prepared(builtin_part, knowledge_base):
    """The built-in part's planning context, sequence plan and MKB (made once)."""
    from ita.offline.prepare import prepare_inspection
    from ita.sequence.plan import planning_context

    ctx = planning_context(None, kb=knowledge_base, part=builtin_part)
    plan, mkb, report = prepare_inspection(ctx, builtin_part, warm=False)
    return ctx, plan, mkb, report


def _meas(kind: str, spec_id: str) -> Term:
    return Term(kind, (Term("meas", (spec_id,)),))


def test_every_measurement_has_an_entry_or_a_reason(prepared) -> None:
    _, plan, mkb, report = prepared
    assert set(mkb.entries) == {i for g in plan.groups for i in g.order}
    counts = mkb.counts()
    assert counts["ok"] >= 0.9 * len(mkb.entries)
    for e in mkb.problems():
        assert e.reason and e.q is None
    assert len(report.cannot) == len(plan.cannot) + len(mkb.problems())


def test_configurations_reproduce_the_tool_poses(prepared) -> None:
    ctx, _, mkb, _ = prepared
    model = arm_model(ctx.workcell.arm)
    for e in [e for e in mkb.entries.values() if e.ok][::7]:
        tcp = ctx.workcell.tool(e.tool).tcp.matrix()
        got = tcp_poses(model, np.vstack([e.q, e.q_approach]), tcp)
        np.testing.assert_allclose(got[0], e.pose, atol=1e-6)
        np.testing.assert_allclose(got[1], e.pose_approach, atol=1e-6)
        assert model.within_limits(e.q) and model.within_limits(e.q_approach)


def test_probe_is_perpendicular_pressed_and_approach_points_are_free(prepared, builtin_part) -> None:
    from ita.path import planners_for

    ctx, _, mkb, _ = prepared
    cell = ctx.workcell
    probe = [e for e in mkb.entries.values() if e.ok and e.tool_class == "us_tool"]
    assert len(probe) > 250
    planner, tool = planners_for(cell, builtin_part)(probe[0].tool)
    q_approach = np.array([e.q_approach for e in probe])
    assert planner.config_free(q_approach, tool).all()
    for e in probe[::9]:
        spec = ctx.spec(e.spec_id)
        point = cell.part.to_world(np.array([spec.point]))[0]
        normal = cell.part.normals_to_world(np.array([spec.normal]))[0]
        normal /= np.linalg.norm(normal)
        assert np.dot(e.pose[:3, 2], -normal) > 0.9999                       # along the normal, into the part
        depth = np.dot(e.pose[:3, 3] - point, -normal)
        assert depth == pytest.approx(e.press_m, abs=1e-6)                    # tip pressed in
        off = np.dot(e.pose_approach[:3, 3] - point, normal)
        assert off >= cell.tool(e.tool).approach_distance - 1e-9              # off the surface, in free space


def test_slra_view_groups_share_one_frame(prepared, builtin_part) -> None:
    ctx, _, mkb, report = prepared
    slra = [e for e in mkb.entries.values() if e.ok and e.group is not None]
    assert mkb.frames_needed() < len(slra)
    assert report.frames == mkb.frames_needed()
    for g in mkb.groups.values():
        assert g.anchor in g.members
        assert len({ctx.spec(m).feature for m in g.members}) == 1
        for m in g.members:
            e = mkb.entry(m)
            assert e.group == g.id
            np.testing.assert_allclose(e.pose, mkb.entry(g.anchor).pose)
    # a flange's height and width at one point share a frame; no member is seen with a
    # window much wider than its own (a fastener's diameter does not share the wide frame
    # its position needs: its pixels would be three times coarser)
    from ita.geometry import GROUP_GROWTH
    from ita.vision.for_part import vision_context
    from ita.vision.scan import scan_for

    kinds = {tuple(sorted(ctx.spec(m).kind.value for m in g.members)) for g in mkb.groups.values()}
    assert ("flange_height", "flange_width") in kinds
    vctx = vision_context(builtin_part, ctx.workcell, specs=list(ctx.specs))
    def width_mm(fov_deg: float, standoff_m: float) -> float:
        return 2000.0 * standoff_m * np.tan(np.radians(fov_deg) / 2)

    for g in mkb.groups.values():
        if len(g.members) > 1:
            own = min(width_mm(scan_for(ctx.spec(m), vctx).fov_deg[0], vctx.standoff_m) for m in g.members)
            assert width_mm(g.fov_deg[0], mkb.entry(g.anchor).standoff_m) <= GROUP_GROWTH * own * 1.001


def test_view_group_pixels_are_the_most_a_member_asks_for(prepared, builtin_part) -> None:
    """Every group's frame has, per axis, the most pixels any member's `scan_for` asks for;
    the bulkhead's small fastener holes (5 mm) get finer position frames than ctx.shape."""
    from ita.geometry.build import group_pixels
    from ita.vision.for_part import vision_context
    from ita.vision.scan import scan_for

    assert group_pixels([(256, 256), (384, 256), (128, 512)]) == (384, 512)
    ctx, _, mkb, _ = prepared
    vctx = vision_context(builtin_part, ctx.workcell, specs=list(ctx.specs))
    finer = 0
    for g in mkb.groups.values():
        asked = [scan_for(ctx.spec(m), vctx).shape for m in g.members]
        assert tuple(g.pixels) == (max(a[0] for a in asked), max(a[1] for a in asked)), g.id
        for m in g.members:
            assert mkb.entry(m).pixels == g.pixels
        finer += min(g.pixels) > min(vctx.shape)
    assert finer > 0


def test_view_group_rule() -> None:
    from ita.specs.model import MeasurementKind, MeasurementSpec

    def spec(i, x, feature="f"):
        return MeasurementSpec(id=i, kind=MeasurementKind.FLANGE_WIDTH, feature=feature, point=(x, 0.0, 0.0),
                               normal=(0.0, 0.0, 1.0), nominal=1.0, lower=-0.1, upper=0.1)

    specs = [spec("a", 0.0), spec("b", 2.0), spec("c", 30.0), spec("d", 0.0, "g")]
    groups = view_groups(specs, {"a": 40.0, "b": 40.0, "c": 40.0, "d": 40.0}, max_window_mm=200.0)
    members = sorted(sorted(m) for _, m, _ in groups)
    assert members == [["a", "b"], ["c"], ["d"]]


def test_shared_frame_measures_every_member(prepared, builtin_part) -> None:
    """A sample of view groups: one simulated frame at the anchor's pose, Vision measures
    every member in it, within its stated uncertainty of the as-built value."""
    from ita.part.truth import load_truth
    from ita.sensors.slra_frame import ScanGeometry
    from ita.sim.slra import SlraParams, SlraScene, simulate_frame
    from ita.vision.for_part import vision_context
    from ita.vision.measure import measure

    ctx, _, mkb, _ = prepared
    cell = ctx.workcell
    scene = SlraScene.from_truth(builtin_part.directory, cell)
    vctx = vision_context(builtin_part, cell, specs=list(ctx.specs))
    truth = load_truth(builtin_part.directory).values
    rng = np.random.default_rng(3)
    shared = [g for g in mkb.groups.values() if len(g.members) > 1]
    kinds_seen = set()
    for g in shared[::11][:8]:
        anchor = mkb.entry(g.anchor)
        frame = simulate_frame(scene, anchor.pose, ScanGeometry(g.pixels, g.fov_deg), SlraParams(), rng)
        for m in g.members:
            reply = measure(frame, ctx.spec(m), vctx)
            assert reply.ok, (m, reply)
            assert abs(reply.value - truth[m]) <= 3 * reply.expanded + 1e-3, (m, reply.value, truth[m])
            kinds_seen.add(ctx.spec(m).kind.value)
    assert len(kinds_seen) >= 2


def test_resolver_turns_plan_terms_into_numbers(prepared) -> None:
    ctx, _, mkb, _ = prepared
    reasoner = GeometricReasoner(mkb, ctx.workcell, ctx.specs)
    probe = next(e for e in mkb.entries.values() if e.ok and e.tool_class == "us_tool")
    slra = next(e for e in mkb.entries.values() if e.ok and e.group is not None)
    contact = reasoner.resolve(_meas("in_contact_point", probe.spec_id))
    assert isinstance(contact, Target) and np.allclose(contact.q, probe.q)
    assert np.allclose(reasoner.resolve(_meas("approach_point", probe.spec_id)).q, probe.q_approach)
    assert np.allclose(reasoner.resolve(_meas("viewing_pose", slra.spec_id)).q, slra.q)
    assert reasoner.resolve(_meas("patches", slra.spec_id)).id == slra.group
    spec = ctx.spec(probe.spec_id)
    assert reasoner.resolve(_meas("min_value", probe.spec_id)) == spec.low_limit
    assert reasoner.resolve(_meas("max_value", probe.spec_id)) == spec.high_limit
    assert reasoner.resolve(_meas("goal_point", probe.spec_id)).shape == (3,)
    assert reasoner.resolve(Term("approach_point", ("home",))).q.shape == (6,)
    slot = ctx.workcell.slot_of(probe.tool).name
    assert reasoner.resolve(Term("approach_point", (Term("rack", (slot,)),))).q.shape == (6,)
    with pytest.raises(KeyError):
        reasoner.resolve(_meas("approach_point", "NO-SUCH-SPEC"))
    with pytest.raises(KeyError):
        reasoner.resolve(Term("approach_point", ("nowhere",)))
    bad = next((e for e in mkb.entries.values() if not e.ok), None)
    if bad is not None:
        with pytest.raises(KeyError):
            reasoner.resolve(_meas("approach_point", bad.spec_id))


def test_a_station_pose_is_one_the_cell_s_check_finds_free(prepared) -> None:
    """With the cell's check of configurations (the path planner's, in a run), the pose
    over a station is the quickest of the free ones, not the quickest of all: here a
    check that refuses the quickest gets another; one that refuses all, the quickest."""
    ctx, _, mkb, _ = prepared
    reasoner = GeometricReasoner(mkb, ctx.workcell, ctx.specs)
    quickest = reasoner.station("cal_block", "us_probe_1").q
    reasoner.check_with(lambda q, tool: ~np.all(np.isclose(q, quickest), axis=1))
    other = reasoner.station("cal_block", "us_probe_1").q
    assert not np.allclose(other, quickest)
    assert np.allclose(reasoner.station("cal_block", "us_probe_1", contact=True).q[:3], other[:3], atol=0.2)
    reasoner.check_with(lambda q, tool: np.zeros(len(q), dtype=bool))
    assert np.allclose(reasoner.station("cal_block", "us_probe_1").q, quickest)


def test_an_slra_pose_moved_with_the_registered_part_that_meets_the_cell_is_the_mkb_s(prepared) -> None:
    """On a registered part the poses move with it; an SLRA pose that then meets the cell
    (the MKB's was at its edge) is the MKB's own, when that one is free."""
    from dataclasses import replace

    ctx, _, mkb, _ = prepared
    reasoner = GeometricReasoner(mkb, ctx.workcell, ctx.specs)
    e = next(e for e in mkb.entries.values() if e.ok and e.group is not None)
    x, y, z = ctx.workcell.part.translation
    reasoner.register(replace(ctx.workcell.part, translation=(x + 0.0005, y, z)))
    moved = reasoner.resolve(_meas("viewing_pose", e.spec_id))
    assert not np.allclose(moved.q, e.q)
    reasoner.check_with(lambda q, tool: np.all(np.isclose(q, e.q), axis=1))     # the MKB's alone is free
    kept = reasoner.resolve(_meas("viewing_pose", e.spec_id))
    assert np.allclose(kept.q, e.q) and np.allclose(kept.pose, e.pose)
    reasoner.check_with(lambda q, tool: np.ones(len(q), dtype=bool))           # all free: it moves
    assert np.allclose(reasoner.resolve(_meas("viewing_pose", e.spec_id)).q, moved.q)


def test_a_probe_pose_moved_with_the_registered_part_that_meets_the_cell_rolls_about_the_probe(prepared) -> None:
    """A probe's approach moved with the registered part that meets the cell (or the arm
    itself) is turned about the probe's axis, with its contact pose by the same roll: the
    tip touches the same spot, square to the surface, and the approach is free."""
    from dataclasses import replace

    ctx, _, mkb, _ = prepared
    e = next(e for e in mkb.entries.values()
             if e.ok and e.q_approach is not None and ctx.workcell.tool(e.tool).tool_class.ultrasonic)
    reasoner = GeometricReasoner(mkb, ctx.workcell, ctx.specs)
    x, y, z = ctx.workcell.part.translation
    reasoner.register(replace(ctx.workcell.part, translation=(x + 0.0005, y, z)))
    approach = reasoner.resolve(_meas("approach_point", e.spec_id))
    contact = reasoner.resolve(_meas("in_contact_point", e.spec_id))
    reasoner.check_with(lambda q, tool: ~np.all(np.isclose(q, approach.q), axis=1))   # the moved approach is not free
    rolled = reasoner.resolve(_meas("approach_point", e.spec_id))
    touch = reasoner.resolve(_meas("in_contact_point", e.spec_id))
    assert not np.allclose(rolled.q, approach.q)
    for before, after in ((approach, rolled), (contact, touch)):
        assert np.allclose(after.pose[:3, 3], before.pose[:3, 3], atol=1e-9)          # the same spot
        assert np.allclose(after.pose[:3, 2], before.pose[:3, 2], atol=1e-9)          # the same axis
        angle = np.degrees(np.arccos(np.clip(after.pose[:3, 0] @ before.pose[:3, 0], -1.0, 1.0)))
        assert 4.0 < angle < 46.0
    assert np.allclose(touch.pose[:3, :3], rolled.pose[:3, :3] @ approach.pose[:3, :3].T @ contact.pose[:3, :3],
                       atol=1e-9)                                                     # one roll for both
    assert touch.press_m == contact.press_m


def test_mkb_is_stored_keyed_by_digest(prepared, tmp_path) -> None:
    _, _, mkb, _ = prepared
    path = save_mkb(mkb, tmp_path / "m.json")
    again = load_mkb(mkb.part, mkb.digest, path)
    assert again is not None and set(again.entries) == set(mkb.entries)
    e = next(iter(mkb.entries.values()))
    assert np.allclose(again.entry(e.spec_id).pose, e.pose) if e.ok else True
    assert again.groups == mkb.groups
    assert load_mkb(mkb.part, "another digest", path) is None
    (tmp_path / "broken.json").write_text("{not json")
    assert load_mkb(mkb.part, None, tmp_path / "broken.json") is None


def test_tilted_approach_directions_keep_their_angle_off_the_normal():
    """The probe's fallback approach directions are unit vectors exactly the tilt off each
    normal, spread about it; tilt 0 is the normal itself."""
    import math

    from ita.geometry.build import TILT_AZIMUTHS, _tilted

    normals = np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, -0.6, 0.8]])
    assert np.array_equal(_tilted(normals, 0.0)[0], normals)
    dirs = np.stack(_tilted(normals, 20.0))                           # (azimuths, n, 3)
    assert dirs.shape == (TILT_AZIMUTHS, 3, 3)
    assert np.allclose(np.linalg.norm(dirs, axis=-1), 1.0)
    assert np.allclose(np.einsum("anj,nj->an", dirs, normals), math.cos(math.radians(20.0)))
    assert np.allclose(dirs.mean(axis=0) / math.cos(math.radians(20.0)), normals)
