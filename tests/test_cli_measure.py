"""`ita measure MEAS_ID`: one measurement in the simulated workcell."""

from __future__ import annotations

import json
from pathlib import Path

from click.testing import CliRunner

from ita.cli import main


def test_measure_an_slra_spec_and_render_it(builtin_part, tmp_path: Path) -> None:
    png = tmp_path / "scan.png"
    result = CliRunner().invoke(main, ["measure", "HD-OF-101", "--render", str(png), "--json"])
    assert result.exit_code == 0, result.output
    out = json.loads(result.stdout)
    assert out["tool"] == "slra_1" and out["kind"] == "hole_diameter"
    assert abs(out["value"] - out["nominal"]) < 0.5 and 0 < out["u"] < 0.05
    assert out["decision"] in ("conforms", "does_not_conform", "uncertain")
    assert png.is_file() and png.read_bytes()[:4] == b"\x89PNG"


def test_measure_a_thickness_with_the_probe(builtin_part) -> None:
    result = CliRunner().invoke(main, ["measure", "WT-P01-1"])
    assert result.exit_code == 0, result.output
    assert "us_probe_1" in result.stdout and "nominal 2.5" in result.stdout and "decision" in result.stdout


def test_measure_unknown_id(builtin_part) -> None:
    result = CliRunner().invoke(main, ["measure", "NO-SUCH"])
    assert result.exit_code == 2 and "no measurement 'NO-SUCH'" in result.stderr
