"""The part registered on its datums (ita.task.align): the simulator seats it off its
nominal placement as a fixture does, or a knock moves it millimetres; registration on
tooling holes B and C by the SLRA finds where it is, within the uncertainty it states."""

from __future__ import annotations

import math

import numpy as np
import pytest

from ita.planning.state import WorldState
from ita.sequence.next_step import the_arm
from ita.sim.fixture import KNOCK, knocked, seated
from ita.sim.inject import InjectionPlan
from ita.task import open_session
from ita.task.align import datum_specs, fit_motion, register_part
from ita.workcell import load_workcell


def test_a_rigid_motion_in_the_plane_is_fitted_from_two_or_more_points() -> None:
    nominal = np.array([[-1085.0, -285.0], [1085.0, 135.0], [0.0, 700.0]])
    theta = math.radians(0.2)
    rot = np.array([[math.cos(theta), -math.sin(theta)], [math.sin(theta), math.cos(theta)]])
    seen = nominal @ rot.T + np.array([0.3, -0.4])
    got, shift, residuals = fit_motion(nominal, seen)
    assert got == pytest.approx(theta, abs=1e-12) and shift == pytest.approx([0.3, -0.4], abs=1e-9)
    assert residuals.max() < 1e-9
    seen[2] += (0.0, 0.05)                                  # one point off: it shows in its residual
    _, _, residuals = fit_motion(nominal, seen)
    assert residuals.argmax() == 2 and residuals[2] > 0.02


def test_a_placement_moved_and_the_motion_read_back() -> None:
    nominal = load_workcell().part
    theta = math.radians(-0.3)
    rot = np.array([[math.cos(theta), -math.sin(theta), 0.0], [math.sin(theta), math.cos(theta), 0.0], [0, 0, 1]])
    moved = nominal.moved(rot, np.array([1.0, -2.0, 0.0]))
    r, shift = moved.offset_from(nominal)
    assert r == pytest.approx(rot, abs=1e-12) and shift == pytest.approx([1.0, -2.0, 0.0], abs=1e-9)
    p = np.array([[100.0, 200.0, 5.0]])
    assert moved.to_world(p) == pytest.approx(nominal.to_world(p @ rot.T + [1.0, -2.0, 0.0]), abs=1e-12)


def test_a_knock_is_millimetres_and_tenths_of_a_degree_a_seating_tenths() -> None:
    nominal = load_workcell().part
    for seed in range(20):
        rng = np.random.default_rng(seed)
        r, shift = seated(nominal, rng).offset_from(nominal)
        assert abs(math.degrees(math.atan2(r[1, 0], r[0, 0]))) <= 0.25 + 1e-9
        r, shift = knocked(nominal, rng).offset_from(nominal)
        assert abs(math.degrees(math.atan2(r[1, 0], r[0, 0]))) <= KNOCK.cut * KNOCK.turn_deg + 1e-9


def test_a_knock_is_scripted_on_the_part_and_nowhere_else() -> None:
    plan = InjectionPlan.parse(0.0, None, ["part_displaced:after=60"], 0)
    plan.check_targets(["us_probe_1"], ["slra_1"])
    wrong = InjectionPlan.parse(0.0, None, ["part_displaced@slra_1:after=60"], 0)
    with pytest.raises(Exception, match="part_displaced@part"):
        wrong.check_targets(["us_probe_1"], ["slra_1"])


def _error_at(session, placement, xy) -> float:
    """Distance (mm) between where `placement` and the simulator put part point xy."""
    p = np.array([[xy[0], xy[1], 2.5]])
    return float(np.linalg.norm(placement.to_world(p) - session.world.part_placement.to_world(p)) * 1000)


def test_the_part_is_registered_where_the_fixture_and_then_a_knock_put_it(builtin_part) -> None:
    """Seated off its place by the fixture's draw, the part is found on tooling holes B and C
    within three of its stated uncertainties at every corner; knocked millimetres away, it
    is found again (the holes located in their frames first), as well."""
    session = open_session(None, seed=5, placement_error=True)
    try:
        assert [h.datum for h, _ in datum_specs(session)] == ["B", "C"]
        state = WorldState(arm=the_arm(session.kb))
        nominal = session.ctx.workcell.part
        corners = [(x, y) for x in (nominal.envelope_min_mm[0], nominal.envelope_max_mm[0])
                   for y in (nominal.envelope_min_mm[1], nominal.envelope_max_mm[1])]
        assert max(_error_at(session, nominal, c) for c in corners) > 0.1      # it is off: a real test
        done = register_part(session, state, "slra_1")
        a = done.alignment
        assert a is not None, done.reason
        for c in corners:
            assert _error_at(session, a.placement, c) <= 3 * math.sqrt(2) * a.u_at(c)
        assert max(a.residuals_mm.values()) < 0.1 and a.seconds > 0
        assert session.reasoner.placement == a.placement and session.slra.vctx.placement == a.placement
        session.world.place_part(knocked(session.world.part_placement, np.random.default_rng(3)))
        assert max(_error_at(session, a.placement, c) for c in corners) > 1.0
        again = register_part(session, done.state, "slra_1")
        b = again.alignment
        assert b is not None, again.reason
        assert again.moved_mm > 1.0
        for c in corners:
            assert _error_at(session, b.placement, c) <= 3 * math.sqrt(2) * b.u_at(c)
    finally:
        session.close()


@pytest.mark.slow
def test_a_part_knocked_mid_run_is_found_registered_again_and_the_run_completes(tmp_path, builtin_part) -> None:
    """`--inject part_displaced:after=200`: the part knocked millimetres off while the SLRA
    measures; the failure that follows is diagnosed part_displaced, the part registered
    again where it lies (no person called), what was measured since the last good check
    measured again (the hole positions held for their networks too), and every
    measurement made."""
    import json

    from click.testing import CliRunner

    from ita.archive import Archive, archive_path
    from ita.cli import main

    res = CliRunner().invoke(main, ["inspect", "--seed", "63", "--limit", "400", "--runs-dir", str(tmp_path),
                                    "--inject", "part_displaced:after=200", "--json"])
    assert res.exit_code == 0, res.output
    summary = json.loads(res.stdout[res.stdout.index("{"):])
    assert summary["measured"] == 400 and summary["status"] == "completed"
    with Archive.open(archive_path(tmp_path), create=False) as archive:
        run_id = archive.resolve("last")
        aligned = [e.payload for e in archive.events(run_id, kinds=["alignment"])]
        assert [a["why"] for a in aligned] == ["the run's start", "a recovery: the part found displaced"]
        assert all(a["registered"] for a in aligned)
        causes = [e.payload.get("cause") for e in archive.events(run_id, kinds=["diagnosis"])]
        assert "part_displaced" in causes
        # the hole positions held for their networks were let go with the rest and measured
        # again: no network mixes frames of the part where it was with frames of where it is
        again = archive.events(run_id, kinds=["remeasure"])
        released = {i for e in again for i in e.payload.get("released") or []}
        frames = archive.events(run_id, kinds=["network_frame"])
        assert released and all(any(f.payload["spec"] == i and f.sim_time > again[0].sim_time for f in frames)
                                for i in released)
        results = {r.spec_id: r for r in archive.results(run_id)}
        assert all("network of" in (results[i].reason or "") for i in released)


def test_a_part_that_could_not_be_registered_says_so_at_the_end_of_its_run(tmp_path, builtin_part, monkeypatch) -> None:
    """Tooling holes not found where the cell can see them: the run goes on at the placement
    it has, and its summary says the part was not registered, and why (`alignment` of the
    JSON summary too); the archive keeps the event."""
    from click.testing import CliRunner

    import ita.toplevel.registration as registration
    from ita.archive import Archive, archive_path
    from ita.cli import main
    from ita.task.align import AlignDone

    def not_found(session, state, tool, **_):
        return AlignDone(None, "TH-B (datum B) not found in its view: the part is further off its place than the "
                               "cell can see", (), state)

    monkeypatch.setattr(registration, "register_part", not_found)
    res = CliRunner().invoke(main, ["inspect", "--limit", "2", "--runs-dir", str(tmp_path), "--placement", "exact"])
    assert res.exit_code == 0, res.output
    assert "the part was NOT registered on its datums: TH-B (datum B) not found" in res.output
    with Archive.open(archive_path(tmp_path), create=False) as archive:
        events = archive.events(archive.resolve("last"), kinds=["alignment"])
    assert [e.payload["registered"] for e in events] == [False] and "not found" in events[0].payload["reason"]
