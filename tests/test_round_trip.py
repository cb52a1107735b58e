"""One measurement's round trip: the Sequence Planner's tool reaches the Operation Planner,
the devices' values come back inside their replies, `ita measure` and the Top Level share
`measure_one`."""

from __future__ import annotations

import pytest

from ita.devices import ScanData, measured_values
from ita.planning import WorldState
from ita.task import MeasureStatus, measure_one


@pytest.fixture(scope="module")
def session(builtin_part):
    from ita.task import open_session

    s = open_session(None, seed=5)
    yield s
    s.close()


@pytest.fixture(scope="module")
def arm() -> dict[str, WorldState]:
    """Where the session's arm is, kept from one test's measurement to the next."""
    return {"state": WorldState(arm="t3")}


def measure(session, arm, spec_id: str, tool: str):
    out = measure_one(session, spec_id, arm["state"], tool)
    arm["state"] = out.state
    return out


PROBE_90 = """tcp_position = [0.0, 0.06, 0.25]    # a slim 0.25 m holder, then the probe bent 90 deg
tcp_rpy_deg = [-90.0, 0.0, 0.0]
holder_radius = 0.012
shaft_radius = 0.006
"""


@pytest.fixture(scope="module")
def rib_cell_part(builtin_part, tmp_path_factory):
    """A copy of the bulkhead (its truth too) cut to a few specs, whose cell's probes are
    bent 90 degrees on a slim holder: they can touch a rib's side wall, which the built-in
    cell's 45-degree probes cannot (every such contact collides)."""
    import json
    import re
    import shutil

    from ita.workcell import default_workcell_path

    d = tmp_path_factory.mktemp("parts") / "ribcell"
    shutil.copytree(builtin_part.directory, d)
    meta = json.loads((d / "part.json").read_text())
    (d / "part.json").write_text(json.dumps({**meta, "name": "ribcell"}))
    lines = (d / "specs.csv").read_text().splitlines()
    keep = [lines[0]] + [x for x in lines[1:] if x.split(",")[2] in ("RV08", "P01")][:12]
    (d / "specs.csv").write_text("\n".join(keep) + "\n")
    cell = default_workcell_path().read_text()
    cell = cell.replace('urdf = "t3_arm.urdf"', f'urdf = "{default_workcell_path().parent / "t3_arm.urdf"}"')
    cell = re.sub(r'tcp_position = \[0.0, 0.099, 0.249\].*\ntcp_rpy_deg = \[-45.0, 0.0, 0.0\].*\n', PROBE_90, cell)
    assert cell.count("holder_radius") == 2
    (d / "workcell.toml").write_text(cell)
    return d


def test_both_slras_broken_a_rib_width_is_planned_executed_and_measured_with_the_probe(rib_cell_part) -> None:
    """The regression of the tool passed down: the rules move rib widths to the probe when
    no SLRA works, and the operation level must plan, execute and measure with it (the
    thickness of the rib through its side wall, not its height from the top)."""
    from ita.scoring.truth import true_values
    from ita.sequence.plan import build_plan
    from ita.task import open_session

    session = open_session(rib_cell_part, seed=5)
    kb = session.kb
    try:
        for slra in ("slra_1", "slra_2"):
            kb.once("world", "set_tool_condition", slra, "broken")
        plan = build_plan(session.ctx)
        probe_group = next(g for g in plan.groups if g.tool == "us_probe_1")
        widths = [i for i in probe_group.order if session.specs[i].kind.value == "stiffener_width"]
        assert widths, "the tool rules did not move rib widths to the probe"
        spec_id = widths[0]
        out = measure_one(session, spec_id, WorldState(arm="t3"), probe_group.tool)
    finally:
        kb.once("world", "reset_world")
        session.close()
    assert out.status is MeasureStatus.MEASURED, out.reason
    assert out.plan.steps[-1].action == "us_measure" and out.plan.steps[-1].args[0] == "us_probe_1"
    names = [c.command.name for c in out.report.outcomes]
    assert "CONTACT" in names and "SCAN" not in names
    assert out.value.source.probe == "us_probe_1"
    truth = true_values(rib_cell_part)[spec_id]
    assert abs(out.value.value - truth) <= 2.0 * out.value.u


def test_the_built_in_probe_cannot_touch_a_rib_wall_and_says_so(session, arm) -> None:
    """With the built-in 45-degree probes a rib width by the probe cannot be done (the
    contact collides): never a reading of something else."""
    spec_id = next(i for i, s in session.specs.items() if s.kind.value == "stiffener_width")
    out = measure(session, arm, spec_id, "us_probe_1")
    assert out.status is MeasureStatus.CANNOT_BE_DONE and "contact_blocked" in out.reason


def test_an_slra_measurement_returns_its_frame_and_its_view_group_in_the_replies(session, arm) -> None:
    group = next(g for g in session.mkb.groups.values() if len(g.members) > 1)
    spec_id = group.anchor
    out = measure(session, arm, spec_id, session.planned_tool(spec_id))
    assert out.status is MeasureStatus.MEASURED, out.reason
    scans = [o.reply.data for o in out.report.outcomes if isinstance(o.reply.data, ScanData)]
    assert len(scans) == 1 and scans[0].group == group.id and out.frames == scans[0].frames
    values = measured_values(out.report)
    assert set(values) == set(group.members)
    assert {v.spec_id for v in out.others} == set(group.members) - {spec_id}
    assert values[spec_id].value == out.value.value


def test_a_thickness_reading_comes_back_in_the_measure_reply(session, arm) -> None:
    spec_id = next(i for g in session.plan.groups if g.tool == "us_probe_1" for i in g.order)
    out = measure(session, arm, spec_id, "us_probe_1")
    assert out.status is MeasureStatus.MEASURED, out.reason
    step = [o for o in out.report.outcomes if o.command.name == "MEASURE"][0]
    assert step.reply.data.spec_id == spec_id and step.reply.data.u > 0
    assert step.reply.data.value == out.value.value == step.reply.payload.args[0]


def test_a_tool_the_mkb_cannot_place_the_measurement_for_is_cannot_be_done(session, arm) -> None:
    spec_id = next(i for g in session.plan.groups if g.tool == "us_probe_1" for i in g.order)
    out = measure(session, arm, spec_id, "slra_1")
    assert out.status is MeasureStatus.CANNOT_BE_DONE and out.plan is None
