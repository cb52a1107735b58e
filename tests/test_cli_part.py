"""`ita part info | render | build` from the command line."""

from __future__ import annotations

import json

from click.testing import CliRunner

from ita.cli import main


def small_bulkhead_params(text: str) -> str:
    """bulkhead/part.toml's text made a smaller bulkhead: 1600 x 1000 mm, a smaller
    opening, four vertical ribs."""
    for a, b in {"width = 2500.0": "width = 1600.0", "height = 1500.0": "height = 1000.0",
                 "corner_radius = 350.0": "corner_radius = 250.0",
                 "width = 1000.0\nheight = 440.0\ncorner_radius = 150.0": "width = 600.0\nheight = 260.0\n"
                                                                           "corner_radius = 100.0",
                 "x = [-950.0, -650.0, -300.0, 300.0, 650.0, 950.0]": "x = [-550.0, -200.0, 200.0, 550.0]",
                 "y = [-420.0, 0.0, 420.0]": "y = [-280.0, 0.0, 280.0]"}.items():
        assert a in text, a
        text = text.replace(a, b)
    return text


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


def test_part_new_makes_another_bulkhead_with_its_truth(builtin_part, tmp_path):
    """`ita part new DIR --seed S`: another layout and as-built part, the same seed twice the
    same files, a smaller part from a parameter file; a non-empty DIR is refused."""
    from ita.part.store import load_part
    from ita.part.truth import load_truth

    runner = CliRunner()
    a, b = tmp_path / "a", tmp_path / "b"
    for d in (a, b):
        result = runner.invoke(main, ["part", "new", str(d), "--seed", "7"])
        assert result.exit_code == 0, result.output
    assert (a / "specs.csv").read_bytes() == (b / "specs.csv").read_bytes()
    assert (a / "nominal.stl").read_bytes() == (b / "nominal.stl").read_bytes()
    truth_a, truth_builtin = load_truth(a), load_truth(builtin_part.directory)
    assert truth_a.values and truth_a.values != truth_builtin.values
    assert (a / "specs.csv").read_bytes() != builtin_part.specs_path.read_bytes()
    assert load_part(a).directory == a
    # a smaller bulkhead from its own parameter file
    params = (tmp_path / "small.toml")
    from ita.part.bulkhead import default_params_path

    text = default_params_path().read_text(encoding="utf-8")
    params.write_text(small_bulkhead_params(text), encoding="utf-8")
    result = runner.invoke(main, ["part", "new", str(tmp_path / "small"), "--params", str(params), "--seed", "3"])
    assert result.exit_code == 0, result.output
    info = json.loads(runner.invoke(main, ["part", "info", "--json", "--part", str(tmp_path / "small")]).output)
    assert info["size_mm"][:2] == [1600.0, 1000.0] and info["spec_count"] < 1000 and info["unreachable"] == 0
    # parameters the generator's layout does not fit (an opening across the ribs): refused, nothing made
    bad = tmp_path / "bad.toml"
    bad.write_text(text.replace("width = 2500.0", "width = 1600.0").replace("height = 1500.0", "height = 1000.0")
                   .replace("x = [-950.0, -650.0, -300.0, 300.0, 650.0, 950.0]", "x = [-600.0, 600.0]")
                   .replace("y = [-420.0, 0.0, 420.0]", "y = [-300.0, 300.0]"), encoding="utf-8")
    result = runner.invoke(main, ["part", "new", str(tmp_path / "badpart"), "--params", str(bad)])
    assert result.exit_code == 2 and "leave its surface" in result.output and "bad.toml" in result.output
    assert not (tmp_path / "badpart").exists() and not list(tmp_path.glob(".badpart-*"))
    # refused: a directory with something in it, nothing written into it
    (tmp_path / "full").mkdir()
    (tmp_path / "full" / "keep.txt").write_text("mine")
    result = runner.invoke(main, ["part", "new", str(tmp_path / "full")])
    assert result.exit_code == 2 and "not an empty directory" in result.output
    assert [p.name for p in (tmp_path / "full").iterdir()] == ["keep.txt"]
