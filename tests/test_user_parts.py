"""Parts the code was not written around, end to end from the command line: a pocketed
plate from its own mesh and specs only (no features.json, no truth), and a smaller
bulkhead from `ita part new` whose features.json is taken away."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner
from user_parts import make_plate

from ita.cli import main
from ita.part.model import Hole, HoleRole
from ita.part.store import load_part, part_key
from ita.specs.io import read_specs
from ita.vision.measure import along_axis


def run(*args: str):
    return CliRunner().invoke(main, list(args), catch_exceptions=False)


@pytest.fixture(scope="module")
def plate(tmp_path_factory) -> Path:
    return make_plate(tmp_path_factory.mktemp("user") / "plate")


def test_the_plate_s_features_are_found_on_its_mesh_in_both_directions(plate):
    part = load_part(plate)
    assert part.unfound == () and not (plate / "features.json").exists()
    holes = {f.id: f for f in part.features if isinstance(f, Hole)}
    assert holes["S1"].axis == (1.0, 0.0, 0.0) and holes["S1"].depth == pytest.approx(10.0, abs=0.01)
    assert holes["W1"].axis == (0.0, 0.0, 1.0) and holes["W1"].depth == pytest.approx(3.0, abs=0.01)
    assert holes["T1"].depth == pytest.approx(12.0, abs=0.01)           # blind: to its bottom, not through
    rib = part.feature("R1")
    assert (rib.width, rib.height) == pytest.approx((4.0, 30.0), abs=1e-3)


def test_a_side_hole_is_measured_in_a_frame_along_its_axis(plate):
    from ita.vision.for_part import vision_context
    from ita.workcell import workcell_for

    part = load_part(plate)
    cell = workcell_for(part.directory, part.mesh.bounds)
    ctx = vision_context(part, cell)
    spec = next(s for s in __import__("ita.specs.io", fromlist=["x"]).read_specs(part.specs_path) if s.id == "HP-S1")
    local_ctx, local_spec, hole = along_axis(ctx, spec, part.feature("S1"))
    assert hole.axis == (0.0, 0.0, 1.0) and local_spec.normal == (0.0, 0.0, 1.0)
    assert hole.center[2] == pytest.approx(200.0) and set(local_ctx.features) == {"S1", "S2"}
    # the same world point in both frames
    p = np.array([[200.0, -60.0, 15.0]])
    world = cell.part.to_world(p)
    assert np.allclose(local_ctx.placement.to_world(np.array([hole.center])), world)


@pytest.mark.slow     # about 2 minutes on a 2-core machine (the default suite inspects a user's mesh part in
                      # tests/test_user_mesh_scaled.py)
def test_the_plate_is_prepared_inspected_and_reported(plate, tmp_path, ita_home):
    """Simulated as designed (no as-built given): scored against the nominal mesh's own values."""
    result = run("prepare", "--part", str(plate))
    assert result.exit_code == 0, result.output
    runs = tmp_path / "runs"
    result = run("inspect", "--part", str(plate), "--runs-dir", str(runs), "--json")
    assert result.exit_code == 0, result.output
    summary = json.loads(result.output[result.output.index("{"):])
    assert summary["status"] == "completed" and summary["done"] == summary["total"] == 24
    result = run("results", "--runs-dir", str(runs), "last", "--json")
    assert result.exit_code == 0, result.output
    rows = json.loads(result.output)["results"]
    by_id = {r["spec_id"]: r for r in rows}
    # every spec is measured, or named as not doable with the reason
    for r in rows:
        assert r["value"] is not None or r["reason"], r
    measured = [r for r in rows if r["value"] is not None]
    assert len(measured) >= 16
    # the side holes (along +X) are measured in their own frame, as the rest
    assert {"WT-1", "SH-R1-1", "SW-R1-1", "HD-S1", "HP-S1", "HD-T1", "ED-T1"} <= {r["spec_id"] for r in measured}
    # simulated against its nominal mesh: the values sit near the nominal (as designed)
    for sid in ("WT-1", "SH-R1-1", "SW-R1-1", "ED-T1"):
        assert abs(by_id[sid]["value"] - by_id[sid]["nominal"]) < 0.05, by_id[sid]
    report = tmp_path / "report.html"
    result = run("report", "--runs-dir", str(runs), "last", "-o", str(report))
    assert result.exit_code == 0, result.output
    assert "nominal mesh" in report.read_text()
    calibration = json.loads((plate / "slra_calibration.json").read_text())      # prepare made it on the master
    assert calibration["part_key"] == part_key(load_part(plate)) and "spec/HD-S1" in calibration["classes"]


def test_stores_are_keyed_by_the_part_s_content(plate, tmp_path):
    copy = tmp_path / "copy"
    shutil.copytree(plate, copy)
    before = part_key(load_part(copy))
    assert before.startswith("copy-") and before[-12:] == part_key(load_part(plate))[-12:]   # same content
    specs = copy / "specs.csv"
    specs.write_text(specs.read_text().replace("pocket floor", "pocket floor (edited)", 1))
    assert part_key(load_part(copy))[-12:] != before[-12:]


def test_a_lone_found_hole_takes_the_pose_for_datum(plate):
    holes = {f.id: f for f in load_part(plate).features if isinstance(f, Hole)}
    assert all(h.role is HoleRole.LIGHTENING for h in holes.values())   # none within a fastener pitch


@pytest.mark.slow     # about 160 s on a 2-core machine: its calibration on the master alone is most of it
def test_an_asbuilt_plate_calibrated_on_its_master_is_scored_without_false_accepts(plate, tmp_path, ita_home):
    from ita.scoring.truth import true_values, truth_source

    part = tmp_path / "asbuilt-plate"
    shutil.copytree(plate, part)
    result = run("part", "asbuilt", "--part", str(part), "--seed", "3", "--out-of-tolerance", "0.25")
    assert result.exit_code == 0, result.output
    statement = json.loads((part / "asbuilt.json").read_text())
    truth = true_values(part)
    assert "asbuilt.stl" in truth_source(part)
    for hid, dev in statement["holes"].items():     # the mesh has what the statement says
        assert truth[f"HD-{hid}"] == pytest.approx((8.0 if hid[0] == "W" else 4.0 if hid[0] == "T" else 6.0)
                                                   + dev["diameter_change_mm"], abs=0.002)
    assert len(statement["pushed_out_of_tolerance"]) == 2
    nominal = {s.id: s.nominal for s in read_specs(part / "specs.csv")}
    moved = {sid: face["offset_mm"] for face in statement["faces"].values() for sid in face["specs"]}
    assert {"WT-1", "WT-3", "SH-R1-1", "SW-R1-1"} <= set(moved)   # the web, the rib's top and side
    for sid in ("WT-1", "WT-3", "SH-R1-1", "SW-R1-1"):
        assert moved[sid] != 0.0 and truth[sid] == pytest.approx(nominal[sid] + moved[sid], abs=1e-4)
    again = run("part", "asbuilt", "--part", str(part), "--seed", "4")
    assert again.exit_code == 2 and "already has an as-built mesh" in again.output
    result = run("part", "calibrate", "--part", str(part), "--repeats", "3")
    assert result.exit_code == 0, result.output
    classes = json.loads((part / "slra_calibration.json").read_text())["classes"]
    assert {"spec/HD-S1", "spec/ED-T1", "spec/SW-R1-1"} <= set(classes)
    runs = tmp_path / "runs"
    result = run("inspect", "--part", str(part), "--runs-dir", str(runs))
    assert result.exit_code == 0, result.output
    rows = json.loads(run("results", "--runs-dir", str(runs), "last", "--json").output)["results"]
    measured = [r for r in rows if r["value"] is not None]
    assert len(measured) >= 16 and all(r["reason"] for r in rows if r["value"] is None)
    for r in measured:
        true = truth[r["spec_id"]]
        conforms = r["low_limit"] <= true <= r["high_limit"]
        assert not (r["decision"] == "conforms" and not conforms), r          # no false accept
        assert not (r["decision"] == "does_not_conform" and conforms), r      # no false reject
    covered = sum(abs(r["value"] - truth[r["spec_id"]]) <= r["U"] for r in measured)
    assert covered >= len(measured) - 2


@pytest.mark.parametrize("specs, message, line", [
    ("", "empty specs file", None),
    (None, "no specs: the file has its header row", 2),
    ("HD-X,hole_diameter,X,0,0,3.0,0,0,1,8.0,-0.076,0.076,A,,,,", "no hole at (0.0, 0.0, 3.0)", 2),
    ("WT-X,web_thickness,P,-150,0,3.0,0,0,-1,3.0,-0.127,0.127,A,,,,", "no face at (-150.0, 0.0, 3.0)", 2),
])
def test_a_bad_user_part_is_refused_before_any_work_naming_file_and_line(plate, tmp_path, specs, message, line):
    from user_parts import HEADER

    part = tmp_path / "bad"
    part.mkdir()
    shutil.copy(plate / "plate.stl", part)
    (part / "specs.csv").write_text("" if specs == "" else HEADER + "\n" + (specs + "\n" if specs else ""))
    for command in (["spec", "validate"], ["prepare"], ["inspect", "--runs-dir", str(tmp_path / "runs")]):
        result = run(*command, "--part", str(part))
        # validate: a spec whose feature is not there is a warning (exit 1), a run marks it cannot be done;
        # a part none of whose specs can be measured is refused
        warning = command == ["spec", "validate"] and line == 2 and "no spec" not in message
        assert result.exit_code == (1 if warning else 2), (command, result.output)
        assert message in result.output and f"specs.csv{':' + str(line) if line else ''}" in result.output
    assert not (tmp_path / "runs").exists() and sorted(p.name for p in part.iterdir()) == ["plate.stl", "specs.csv"]


@pytest.mark.slow
def test_a_smaller_bulkhead_from_its_mesh_and_specs_only(tmp_path, ita_home):
    """`ita part new` with another seed and size, given as a user would: its mesh and specs
    only (no features.json, part.json or truth); an as-built made by `ita part asbuilt`.
    The first 150 measurements of the sequence: none cannot be done, no false accept,
    coverage of U."""
    from test_cli_part import small_bulkhead_params

    from ita.paths import resource_dir
    from ita.scoring.truth import true_values

    params = tmp_path / "small.toml"
    params.write_text(small_bulkhead_params((resource_dir("bulkhead") / "part.toml").read_text()))
    assert run("part", "new", str(tmp_path / "made"), "--params", str(params), "--seed", "5").exit_code == 0
    part = tmp_path / "user"
    part.mkdir()
    for name in ("nominal.stl", "specs.csv"):
        shutil.copy(tmp_path / "made" / name, part / name)
    assert run("part", "asbuilt", "--part", str(part), "--seed", "11").exit_code == 0
    runs = tmp_path / "runs"
    result = run("inspect", "--part", str(part), "--runs-dir", str(runs), "--limit", "150")
    assert result.exit_code == 0, result.output
    rows = json.loads(run("results", "--runs-dir", str(runs), "last", "--json").output)["results"]
    truth = true_values(part)
    # its path planner's model is the mesh's cover: nothing beside a wall or under a cap is blocked
    assert [r["spec_id"] for r in rows if r["decision"] == "cannot_be_done"] == []
    measured = [r for r in rows if r["value"] is not None]
    assert len(measured) >= 140
    for r in measured:
        conforms = r["low_limit"] <= truth[r["spec_id"]] <= r["high_limit"]
        assert not (r["decision"] == "conforms" and not conforms), r
    covered = sum(abs(r["value"] - truth[r["spec_id"]]) <= r["U"] for r in measured) / len(measured)
    assert 0.9 <= covered
