"""Measurement entry by pointing at the part (`ita spec pick --at X,Y,Z`): what the mesh
shows at the point, the kinds that fit, the nominal measured on the mesh, the feature,
the point and the normal a spec needs; the reason when nothing measurable is there."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from click.testing import CliRunner
from user_parts import RIM_TOP, RIM_WALL, RIM_Y, make_plate, make_rim_plate

from ita.cli import main
from ita.part.pick import propose
from ita.part.store import load_part
from ita.specs.model import MeasurementKind as K


def run(*args: str):
    return CliRunner().invoke(main, list(args), catch_exceptions=False)


@pytest.fixture(scope="module")
def parts(tmp_path_factory) -> dict[str, Path]:
    root = tmp_path_factory.mktemp("pick")
    return {"rim": make_rim_plate(root / "rim"), "plate": make_plate(root / "plate")}


@pytest.mark.parametrize(("part", "at", "kind", "expect"), [
    # a hole, picked on its bore's wall: its centre on the face it opens onto, its diameter on the mesh
    ("rim", (-100.0, 0.0, 2.0), None, (K.HOLE_DIAMETER, "L1", (-120.0, 0.0, 3.0), (0.0, 0.0, 1.0), 40.0)),
    ("rim", (-100.0, 0.0, 2.0), K.HOLE_POSITION, (K.HOLE_POSITION, "L1", (-120.0, 0.0, 3.0), (0.0, 0.0, 1.0), 0.0)),
    # a hole through a side wall (its axis +X), picked on the top of its bore (a face looking down)
    ("plate", (197.0, -60.0, 18.0), None, (K.HOLE_DIAMETER, "S1", (200.0, -60.0, 15.0), (1.0, 0.0, 0.0), 6.0)),
    # a blind hole in a wall's top: the edge distance to the nearest edge, its point on the ligament
    ("plate", (-98.0, -145.0, 25.0), K.EDGE_DISTANCE, (K.EDGE_DISTANCE, "T1", None, (0.0, 0.0, 1.0), 5.0)),
    # a web: its thickness to the back face on datum A
    ("rim", (-100.0, 50.0, 3.0), None, (K.WEB_THICKNESS, None, (-100.0, 50.0, 3.0), (0.0, 0.0, 1.0), 3.0)),
    # the rim's top: a wall with a floor on one side, its height above datum A
    ("rim", (50.0, RIM_Y - 6.0, RIM_TOP), None, (K.FLANGE_HEIGHT, "RIM-N", None, (0.0, 0.0, 1.0), RIM_TOP)),
    # the rim's outer face: the wall's thickness
    ("rim", (50.0, RIM_Y, 15.0), None, (K.FLANGE_THICKNESS, None, (50.0, RIM_Y, 15.0), (0.0, 1.0, 0.0), RIM_WALL)),
    # a rib's top: its height, or its width across
    ("rim", (0.0, 50.0, RIM_TOP), K.STIFFENER_WIDTH, (K.STIFFENER_WIDTH, "R1", (0.0, 50.0, RIM_TOP), (0.0, 0.0, 1.0),
                                                      4.0)),
])
def test_a_pick_proposes_what_the_mesh_shows(parts, part, at, kind, expect) -> None:
    want_kind, feature, point, normal, nominal = expect
    p = propose(load_part(parts[part]), at, kind)
    assert p.kind == want_kind.value, p
    if feature is not None:
        assert p.feature == feature
    if point is not None:
        assert p.point == pytest.approx(point, abs=0.05)
    assert p.normal == pytest.approx(normal, abs=0.01)
    assert p.nominal == pytest.approx(nominal, abs=0.01)


def test_a_new_feature_gets_a_free_id_and_a_pick_that_fits_nothing_says_why(parts) -> None:
    rim = load_part(parts["rim"])
    web = propose(rim, (-100.0, 50.0, 3.0))
    assert web.feature not in {f.id for f in rim.features} | {"P1", "P2"}     # P1, P2: the specs' pockets
    wrong = propose(rim, (-100.0, 50.0, 3.0), K.HOLE_DIAMETER)
    assert wrong.kind is None and "what fits: web_thickness" in wrong.reason
    assert propose(rim, (0.0, 0.0, 100.0)).reason.startswith("nothing of the part within 5 mm")
    assert "faces down" in propose(rim, (-100.0, 50.0, 0.0)).reason                 # datum A, on the fixture


def test_the_command_line_proposes_as_json_and_the_spec_it_proposes_validates(parts, tmp_path) -> None:
    import shutil

    part = tmp_path / "rim"
    shutil.copytree(parts["rim"], part)
    result = run("spec", "pick", "--part", str(part), "--at", "-100,0,2", "--kind", "hole_position", "--json")
    assert result.exit_code == 0, result.output
    got = json.loads(result.output)
    assert {"kind", "feature", "point", "normal", "nominal", "reason"} <= got.keys() and got["reason"] is None
    assert got["reach"]["slra_tool"] == "reachable"                   # the arm's reach, per tool of the cell
    fmt = lambda v: ",".join(f"{x:g}" for x in v)                                              # noqa: E731
    added = run("spec", "add", "--part", str(part), "--id", "HP-NEW", "--kind", got["kind"], "--feature",
                got["feature"], "--point", fmt(got["point"]), "--normal", fmt(got["normal"]), "--nominal",
                str(got["nominal"]), "--lower", "0", "--upper", "0.5", "--datum", "A")
    assert added.exit_code == 0, added.output
    assert run("spec", "validate", "--part", str(part)).exit_code == 0
    nothing = run("spec", "pick", "--part", str(part), "--at", "0,0,100", "--json")
    assert nothing.exit_code == 1 and json.loads(nothing.output)["reason"]
    assert run("spec", "pick", "--part", str(part), "--at", "0,nan,1").exit_code == 2


@pytest.mark.slow     # about a minute: the part's calibration on its master, then the run
def test_three_picked_specs_are_prepared_and_measured(parts, tmp_path, ita_home) -> None:
    """A hole, a web and a rim picked on a part with no specs yet, added with their
    tolerances, then prepared and measured: each of the three has a value."""
    from user_parts import HEADER

    part = tmp_path / "picked"
    part.mkdir()
    for name in ("plate.stl", "workcell.toml"):
        (part / name).write_bytes((parts["rim"] / name).read_bytes())
    (part / "specs.csv").write_text(HEADER + "\n")
    fmt = lambda v: ",".join(f"{x:g}" for x in v)                                              # noqa: E731
    for sid, at, tol in (("HD-1", "-100,0,2", ("-0.1", "0.1")), ("WT-1", "-100,50,3", ("-0.127", "0.127")),
                         ("FH-1", f"50,{RIM_Y - 6},{RIM_TOP}", ("-0.25", "0.25"))):
        got = json.loads(run("spec", "pick", "--part", str(part), "--at", at, "--json").output)
        extra = ["--direction", fmt(got["direction"])] if got["direction"] else []
        added = run("spec", "add", "--part", str(part), "--id", sid, "--kind", got["kind"], "--feature",
                    got["feature"], "--point", fmt(got["point"]), "--normal", fmt(got["normal"]), "--nominal",
                    str(got["nominal"]), "--lower", tol[0], "--upper", tol[1], "--datum", "A", *extra)
        assert added.exit_code == 0, added.output
    assert run("prepare", "--part", str(part)).exit_code == 0
    runs = tmp_path / "runs"
    assert run("inspect", "--part", str(part), "--runs-dir", str(runs)).exit_code == 0
    rows = json.loads(run("results", "--runs-dir", str(runs), "last", "--json").output)["results"]
    assert {r["spec_id"]: r["value"] is not None for r in rows} == {"HD-1": True, "WT-1": True, "FH-1": True}, rows
