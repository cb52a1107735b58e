"""`ita part info | render | build` from the command line."""

from __future__ import annotations

import json

from click.testing import CliRunner

from ita.cli import main


def test_info_prints_size_and_counts(builtin_part):
    result = CliRunner().invoke(main, ["part", "info"])
    assert result.exit_code == 0, result.output
    assert "2500.0 x 1500.0" in result.output
    assert "web_thickness" in result.output and "pocket" in result.output
    assert "reach: 1076 of 1076 specs pass the geometric test, 0 outside reach" in result.output


def test_info_json(builtin_part):
    result = CliRunner().invoke(main, ["part", "info", "--json"])
    data = json.loads(result.output)
    assert data["spec_count"] >= 900 and data["watertight"]
    assert data["specs"]["hole_position"] > 0 and data["features"]["hole"] > 0
    assert data["unreachable"] == 0 and data["reach"] == {"reachable": data["spec_count"]}


def test_render_writes_png(builtin_part, tmp_path):
    out = tmp_path / "part.png"
    result = CliRunner().invoke(main, ["part", "render", "-o", str(out)])
    assert result.exit_code == 0, result.output
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and out.stat().st_size > 50_000


def test_build_then_info_on_the_copy(builtin_part, tmp_path):
    runner = CliRunner()
    result = runner.invoke(main, ["part", "build", "-o", str(tmp_path / "copy")])
    assert result.exit_code == 0, result.output
    result = runner.invoke(main, ["part", "info", "--json", "--part", str(tmp_path / "copy")])
    assert json.loads(result.output)["directory"] == str(tmp_path / "copy")


def test_bad_part_dir_exits_2_naming_it(tmp_path):
    result = CliRunner().invoke(main, ["part", "info", "--part", str(tmp_path)])
    assert result.exit_code == 2
    assert "no mesh" in result.output and str(tmp_path) in result.output


def test_info_counts_specs_out_of_reach_with_the_reason(tmp_path):
    import trimesh

    part = tmp_path / "far"
    part.mkdir()
    trimesh.creation.box(extents=(8000.0, 100.0, 2.5)).export(part / "plate.stl")
    (part / "specs.csv").write_text(
        "id,kind,feature,x,y,z,nx,ny,nz,nominal,lower,upper,datum\n"
        "NEAR,web_thickness,P,0,0,1.25,0,0,1,2.5,-0.1,0.1,A\n"
        "FAR,web_thickness,P,3990,0,1.25,0,0,1,2.5,-0.1,0.1,A\n"
        "FAR2,hole_diameter,H,-3990,0,1.25,0,0,1,6.0,-0.1,0.1,A\n"
    )
    result = CliRunner().invoke(main, ["part", "info", "--json", "--part", str(part)])
    assert result.exit_code == 0, result.output
    data = json.loads(result.output)
    assert data["unreachable"] == 2 and data["reach"] == {"reachable": 1, "too_far": 2}
