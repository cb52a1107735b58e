"""`ita spec ...` on the built-in bulkhead and on an editable copy of it."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from click.testing import CliRunner

from ita.cli import main
from ita.specs.model import MeasurementKind


def run(*args: str):
    return CliRunner().invoke(main, list(args))


@pytest.fixture
def copy(builtin_part, tmp_path: Path) -> Path:
    """An editable copy of the built-in bulkhead."""
    out = tmp_path / "bulkhead"
    assert run("part", "build", "-o", str(out)).exit_code == 0
    return out


def test_list_json_has_every_kind(builtin_part) -> None:
    result = run("spec", "list", "--json")
    assert result.exit_code == 0
    specs = json.loads(result.stdout)
    assert len(specs) >= 900
    assert {s["kind"] for s in specs} == {k.value for k in MeasurementKind}
    holes = json.loads(run("spec", "list", "--json", "--kind", "hole_diameter").stdout)
    assert holes and all(s["kind"] == "hole_diameter" for s in holes)


def test_show_and_validate_the_builtin_specs(builtin_part) -> None:
    first = json.loads(run("spec", "list", "--json").stdout)[0]
    shown = run("spec", "show", first["id"])
    assert shown.exit_code == 0 and first["id"] in shown.stdout and "tolerance" in shown.stdout
    assert run("spec", "show", "NO-SUCH").exit_code == 2
    result = run("spec", "validate")
    assert result.exit_code == 0 and "ok: 1076 specs valid" in result.stdout


def test_validate_reports_bad_rows_with_their_lines(copy: Path, tmp_path: Path) -> None:
    lines = (copy / "specs.csv").read_text().splitlines()
    rows = [line.split(",") for line in lines[:4]]
    rows[1][1] = "web_girth"                          # kind
    rows[2][10], rows[2][11] = "0.3", "0.1"           # lower, upper
    rows[3][5] = str(float(rows[3][5]) + 10.0)        # z: 10 mm off the surface
    bad = [",".join(r) for r in rows]
    bad_file = tmp_path / "bad.csv"
    bad_file.write_text("\n".join(bad) + "\n")
    result = run("spec", "validate", str(bad_file), "--part", str(copy))
    assert result.exit_code == 2
    assert f"{bad_file}:2 [kind]: unknown kind 'web_girth'" in result.stderr
    assert f"{bad_file}:3 [lower]" in result.stderr
    # the off-surface point is found once the row errors are fixed
    bad[1], bad[2] = lines[1], lines[2]
    bad_file.write_text("\n".join(bad) + "\n")
    result = run("spec", "validate", str(bad_file), "--part", str(copy))
    assert result.exit_code == 2 and f"{bad_file}:4 [x]" in result.stderr
    assert "from the part's surface" in result.stderr


def test_add_edit_remove_export_import_on_a_copy(copy: Path, tmp_path: Path) -> None:
    part = ["--part", str(copy)]
    web = json.loads(run("spec", "list", "--json", "--kind", "web_thickness", *part).stdout)[0]
    point = ",".join(str(c) for c in web["point"])
    normal = ",".join(str(c) for c in web["normal"])
    result = run("spec", "add", "--id", "WT-NEW", "--kind", "web_thickness", "--feature",
                 web["feature"], "--point", point, "--normal", normal, "--nominal", "2.5",
                 "--lower", "-0.127", "--upper", "0.127", "--datum", "A", *part)
    assert result.exit_code == 0, result.output
    assert run("spec", "edit", "WT-NEW", "--nominal", "2.55", *part).exit_code == 0
    shown = json.loads(run("spec", "show", "WT-NEW", "--json", *part).stdout)
    assert shown["nominal"] == 2.55
    out = tmp_path / "one.csv"
    assert run("spec", "export", str(out), "--kind", "web_thickness", *part).exit_code == 0
    assert len(out.read_text().splitlines()) == 1 + 201
    assert run("spec", "remove", "WT-NEW", *part).exit_code == 0
    assert run("spec", "show", "WT-NEW", *part).exit_code == 2
    # importing the export again collides with ids already there: all or nothing
    before = (copy / "specs.csv").read_bytes()
    result = run("spec", "import", str(out), *part)
    assert result.exit_code == 2 and "already exists" in result.stderr
    assert (copy / "specs.csv").read_bytes() == before


@pytest.mark.parametrize(
    "args, words",
    [
        (["edit", "WT-NOPE", "--nominal", "1"], "no spec with id 'WT-NOPE'"),
        (["edit", "{first}", "--lower", "5"], "not below upper"),
        (["edit", "{first}", "--point", "0,0,500"], "from the part's surface"),
        (["edit", "{first}", "--point", "1,2"], "three comma-separated numbers"),
        (["add", "--id", "{first}", "--kind", "web_thickness", "--feature", "P", "--point",
          "0,0,0", "--normal", "0,0,1", "--nominal", "2.5", "--lower", "-0.1", "--upper", "0.1",
          "--datum", "A"], "already exists"),
        (["edit", "{first}", "--kind", "girth"], "unknown kind"),
    ],
)
def test_bad_edits_exit_2_and_write_nothing(copy: Path, args, words) -> None:
    first = json.loads(run("spec", "list", "--json", "--part", str(copy)).stdout)[0]["id"]
    before = (copy / "specs.csv").read_bytes()
    result = run("spec", *[a.format(first=first) for a in args], "--part", str(copy))
    assert result.exit_code == 2, result.output
    assert words in result.output
    assert (copy / "specs.csv").read_bytes() == before
