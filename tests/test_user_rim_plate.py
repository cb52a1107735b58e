"""A plate whose rim is a wall without a cap (12 mm thick, 30 mm high), from its own mesh and
specs only: its heights are found as walls with the floor beside them (no width spec), its
wall thicknesses the 45-degree probe cannot touch go to the bent probe, and the whole part
is prepared and measured."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from click.testing import CliRunner
from user_parts import RIM_TOP, RIM_WALL, RIM_X, RIM_Y, make_rim_plate

from ita.cli import main
from ita.part.model import FlangeSegment
from ita.part.store import load_part
from ita.specs.model import MeasurementKind as K


def run(*args: str):
    return CliRunner().invoke(main, list(args), catch_exceptions=False)


@pytest.fixture(scope="module")
def rim_plate(tmp_path_factory) -> Path:
    return make_rim_plate(tmp_path_factory.mktemp("user") / "rim")


def test_a_rim_wall_is_found_from_its_height_specs_alone(rim_plate):
    part = load_part(rim_plate)
    assert part.unfound == ()
    rims = {f.id: f for f in part.features if isinstance(f, FlangeSegment)}
    assert sorted(rims) == ["RIM-E", "RIM-N", "RIM-S", "RIM-W"]
    north = rims["RIM-N"]
    assert north.cap_width == pytest.approx(RIM_WALL, abs=1e-3) and north.height == pytest.approx(RIM_TOP)
    assert north.normals[0] == pytest.approx((0.0, -1.0))               # from its outer face toward the floor
    assert north.path[0][1] == pytest.approx(RIM_Y, abs=1e-3)           # the path is the outer face
    assert north.cap_thickness == pytest.approx(RIM_TOP - 3.0, abs=0.01)   # down to the web
    # both height specs of the wall lie on it (one straight run from corner to corner)
    for s in (s for s in part_specs(rim_plate) if s.feature == "RIM-N" and s.kind is K.FLANGE_HEIGHT):
        assert north.from_wall(s.point) == pytest.approx(RIM_WALL / 2, abs=1e-3)
    assert abs(rims["RIM-E"].path[0][0] - RIM_X) < 1e-3


def part_specs(directory: Path):
    from ita.specs.io import read_specs

    return read_specs(directory / "specs.csv")


def test_one_feature_round_a_corner_is_one_run_and_walls_that_differ_are_named(rim_plate, tmp_path):
    """Two rim walls under one feature id are one run round the corner, each spec on its
    own wall; a wall of another section under the same id is named, with what to do."""
    moved = tmp_path / "rim"
    moved.mkdir()
    for name in ("plate.stl", "workcell.toml"):
        (moved / name).write_bytes((rim_plate / name).read_bytes())
    text = (rim_plate / "specs.csv").read_text()
    (moved / "specs.csv").write_text(text.replace(",RIM-E,", ",RIM-N,"))
    part = load_part(moved)
    assert part.unfound == ()
    run_ = part.feature("RIM-N")
    for s in (s for s in part_specs(moved) if s.feature == "RIM-N" and s.kind is K.FLANGE_HEIGHT):
        assert run_.from_wall(s.point) == pytest.approx(RIM_WALL / 2, abs=1e-3)
    rows = [r for r in text.splitlines() if ",stiffener_width," not in r]      # the rib's heights as the rim's
    (moved / "specs.csv").write_text("\n".join(rows).replace(",R1,", ",RIM-N,").replace("stiffener_height",
                                                                                      "flange_height") + "\n")
    unfound = load_part(moved).unfound
    assert unfound and all("its walls differ" in n.reason and "its own feature id" in n.reason for n in unfound)


@pytest.mark.slow     # about 90 s on a 2-core machine (its calibration on the master is most of it)
def test_the_rim_plate_is_prepared_with_every_spec_and_measured(rim_plate, tmp_path, ita_home):
    result = run("prepare", "--part", str(rim_plate))
    assert result.exit_code == 0, result.output
    assert "0 measurements cannot be done" in result.output
    runs = tmp_path / "runs"
    result = run("inspect", "--part", str(rim_plate), "--runs-dir", str(runs))
    assert result.exit_code == 0, result.output
    rows = json.loads(run("results", "--runs-dir", str(runs), "last", "--json").output)["results"]
    measured = [r for r in rows if r["value"] is not None]
    assert len(measured) >= 0.95 * len(rows) and all(r["value"] is not None or r["reason"] for r in rows)
    tools = {r["spec_id"]: r["tool"] for r in measured}
    assert {tools[f"FH-{s}{k}"] for s in "NSEW" for k in (1, 2)} == {"slra_1"}
    assert "us_probe_90" in {tools[f"FT-{s}{k}"] for s in "NSEW" for k in (1, 2)}     # where the 45-degree one cannot


def test_a_spec_whose_feature_is_not_there_cannot_be_done_and_the_rest_is_planned(rim_plate, tmp_path):
    """Not the whole part refused: `ita spec validate` warns (exit 1) naming the spec, and
    the Sequence Planner's tool rules make that one spec cannot be done with the reason."""
    from ita.sequence.plan import build_plan, planning_context

    part = tmp_path / "rim"
    part.mkdir()
    for name in ("plate.stl", "workcell.toml", "specs.csv"):
        (part / name).write_bytes((rim_plate / name).read_bytes())
    with (part / "specs.csv").open("a") as f:
        f.write("HD-X,hole_diameter,X,-150,-100,3.0,0,0,1,8.0,-0.076,0.076,A,,,,no hole here\n")
    result = CliRunner().invoke(main, ["spec", "validate", "--part", str(part)])
    assert result.exit_code == 1 and "HD-X: feature 'X' not found" in result.output, result.output
    plan = build_plan(planning_context(part, use_mkb=False))
    cannot = dict(plan.cannot)
    assert list(cannot) == ["HD-X"] and cannot["HD-X"].startswith("unmeasurable(no hole at (-150.0, -100.0, 3.0)")
    assert sum(len(g.order) for g in plan.groups) == 28
