"""A user's package mesh in other units, scaled to millimetres, inspected and reported (a
file of its own so that the two workers share the user-part tests: each takes a minute
or two)."""

from __future__ import annotations

import json

from click.testing import CliRunner

from ita.cli import main


def run(*args: str):
    return CliRunner().invoke(main, list(args), catch_exceptions=False)


def test_a_package_mesh_scaled_to_millimetres_is_inspected_and_reported(tmp_path, ita_home):
    from user_parts import make_scaled_mesh_part

    from ita.scoring.truth import true_values

    part = make_scaled_mesh_part(tmp_path / "box")
    runs = tmp_path / "runs"
    result = run("inspect", "--part", str(part), "--runs-dir", str(runs))
    assert result.exit_code == 0, result.output
    rows = json.loads(run("results", "--runs-dir", str(runs), "last", "--json").output)["results"]
    assert len(rows) == 7 and all(r["value"] is not None or r["reason"] for r in rows)
    by_id = {r["spec_id"]: r for r in rows}
    assert by_id["WT-F1"]["decision"] == "cannot_be_done"          # 385 mm down the box: out of reach
    truth = true_values(part)
    widths = [r for r in rows if r["kind"] == "stiffener_width"]
    assert len(widths) == 4 and all(r["decision"] == "conforms" for r in widths)
    assert sum(abs(r["value"] - truth[r["spec_id"]]) <= r["U"] for r in widths) >= 3
    report = tmp_path / "box.html"
    assert run("report", "--runs-dir", str(runs), "last", "-o", str(report)).exit_code == 0
    assert "Scoring against" in report.read_text()
