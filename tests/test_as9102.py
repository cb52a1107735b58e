"""`ita report RUN -o FILE.xlsx`: the AS9102 Rev C Form 3 workbook (issue 32)."""

from __future__ import annotations

from pathlib import Path

import openpyxl
import pytest
from archive_synth import FakeSpec
from click.testing import CliRunner

from ita.archive import Archive, Outcome, Result, RunStatus
from ita.cli import main
from ita.report.as9102 import (
    FORM3_COLUMNS,
    ORGANIZATION,
    UNCERTAIN_NOTE,
    requirement,
    tooling,
)

SPECS = [FakeSpec("WT-1", "web_thickness", (10.0, 20.0, 3.0), 3.0, -0.127, 0.127),
         FakeSpec("=HD-2", "hole_diameter", (55.5, 0.0, -1.25), 6.35, -0.05, 0.05),
         FakeSpec("WT-3", "web_thickness", (100.0, 40.0, 3.0), 3.0, -0.127, 0.127),
         FakeSpec("WT-4", "web_thickness", (150.0, 40.0, 3.0), 3.0, -0.127, 0.127),
         FakeSpec("HD-5", "hole_diameter", (200.0, 40.0, 3.0), 6.35, -0.05, 0.05)]


def run(*args: str):
    return CliRunner().invoke(main, list(args))


@pytest.fixture
def runs(tmp_path: Path) -> tuple[Path, str]:
    d = tmp_path / "runs"
    with Archive.open(d / "archive.sqlite") as a:
        rid = a.create_run("bulkhead-7", None, seed=1, total=len(SPECS),
                           settings={"simulated": True, "serial": "SN-0042"})
        a.record_result(rid, Result.measured(SPECS[0], 3.01, 0.004, tool="us_probe_1"))          # conforms
        a.record_result(rid, Result.measured(SPECS[1], 6.50, 0.01, tool="slra_1"))              # does not conform
        a.record_result(rid, Result.measured(SPECS[2], 3.125, 0.004, tool="us_probe_1"))        # uncertain
        a.record_result(rid, Result.unmeasured(SPECS[3], Outcome.NOT_DONE, "no back-wall echo", tool="us_probe_1"))
        a.record_result(rid, Result.unmeasured(SPECS[4], Outcome.CANNOT_BE_DONE, "hole not visible"))
        a.set_status(rid, RunStatus.COMPLETED)
    return d, rid


def test_form3_workbook_one_row_per_result(runs: tuple[Path, str], tmp_path: Path) -> None:
    d, rid = runs
    out = tmp_path / "fai.xlsx"
    res = run("report", rid[:8], "-o", str(out), "--runs-dir", str(d))
    assert res.exit_code == 0, res.output
    assert "Form 3" in res.output
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".fai.xlsx")]  # no temporary left
    ws = openpyxl.load_workbook(out).active
    cells = [[c for c in row] for row in ws.iter_rows(values_only=True)]
    fields = {row[0]: row[1] for row in cells[1:9] if row[0]}
    assert fields["1. Part Number"] == fields["2. Part Name"] == "bulkhead-7"
    assert fields["3. Serial Number"] == "SN-0042"
    assert fields["4. FAIR Number"] == rid
    assert fields["Organization Name"] == ORGANIZATION
    assert fields["Date"] and len(fields["Date"]) == 10
    assert fields["Part verdict"].startswith("reject")
    top = next(i for i, row in enumerate(cells) if row[0] == FORM3_COLUMNS[0])
    assert tuple(cells[top][:len(FORM3_COLUMNS)]) == FORM3_COLUMNS
    rows = [r for r in cells[top + 1:] if r[0] is not None]
    assert len(rows) == len(SPECS)
    assert [r[0] for r in rows] == [1, 2, 3, 4, 5]
    ok, nc, unsure, not_done, cannot = rows
    assert ok[1] == "10.000, 20.000, 3.000" and ok[2] == "WT-1 (web thickness)"
    assert ok[3] == "3.000 +0.127/-0.127 mm" and ok[4].startswith("3.0100 mm, U = 0.0080 mm")
    assert ok[5] == "ITA ultrasonic probe us_probe_1" and not ok[6] and ok[7] == "conforms"
    assert nc[2] == "=HD-2 (hole diameter)"  # text, not a formula
    assert nc[5] == "ITA laser range sensor slra_1"
    assert nc[6] == f"NC-{rid}-1" and nc[7] == "does not conform"
    assert unsure[6] == UNCERTAIN_NOTE and unsure[7] == "uncertain"
    assert not_done[4] == "not done: no back-wall echo" and not not_done[6]
    assert cannot[4] == "cannot be done: hole not visible" and cannot[5] is None


def test_bad_extension_and_path_write_nothing(runs: tuple[Path, str], tmp_path: Path) -> None:
    d, rid = runs
    res = run("report", rid, "-o", str(tmp_path / "x.txt"), "--runs-dir", str(d))
    assert res.exit_code == 2 and ".xlsx" in res.output and ".html" in res.output
    assert [line for line in res.output.splitlines() if line.startswith("error:")]
    assert not (tmp_path / "x.txt").exists()
    res = run("report", rid, "-o", str(tmp_path / "missing" / "fai.xlsx"), "--runs-dir", str(d))
    assert res.exit_code == 2 and res.output.startswith("error:")
    assert not (tmp_path / "missing").exists()
    res = run("report", "nosuchrun", "-o", str(tmp_path / "fai.xlsx"), "--runs-dir", str(d))
    assert res.exit_code != 0 and not (tmp_path / "fai.xlsx").exists()


def test_cells() -> None:
    assert requirement({"nominal": 3.0, "upper": 0.127, "lower": -0.127}) == "3.000 +0.127/-0.127 mm"
    assert tooling("us_tool") == "ITA ultrasonic probe us_tool"
    assert tooling("slra_tool") == "ITA laser range sensor slra_tool"
    assert tooling(None) == ""
