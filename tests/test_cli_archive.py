"""`ita runs`, `ita results` and `ita report` on archives made for the test."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest
from archive_synth import fake_specs, record_synthetic_run, true_values
from click.testing import CliRunner

from ita.archive import Archive, RunStatus, archive_path
from ita.cli import main


def run(*args: str, env: dict | None = None):
    return CliRunner().invoke(main, list(args), env=env)


@pytest.fixture
def runs_dir(tmp_path: Path) -> Path:
    """A runs directory with two synthetic runs: a completed one and an interrupted one."""
    d = tmp_path / "runs"
    specs = fake_specs(60)
    with Archive.open(d / "archive.sqlite") as a:
        record_synthetic_run(a, specs, true_values(specs), status=RunStatus.COMPLETED)
        record_synthetic_run(a, specs, true_values(specs), upto=25, status=RunStatus.INTERRUPTED)
    return d


def ids(runs_dir: Path) -> list[str]:
    with Archive.open(runs_dir / "archive.sqlite") as a:
        return [r.id for r in a.runs()]


def test_runs_lists_every_run(runs_dir: Path) -> None:
    res = run("runs", "--runs-dir", str(runs_dir))
    assert res.exit_code == 0, res.output
    first, second = ids(runs_dir)
    lines = res.stdout.splitlines()
    assert lines[0].split()[:4] == ["RUN", "PART", "STATUS", "MEASURED"]
    with Archive.open(archive_path(runs_dir)) as a:        # MEASURED: results with a value
        measured = [sum(1 for r in a.results(rid) if r.value is not None) for rid in (first, second)]
    assert measured[0] < 60                                # the synthetic run has results without a value
    assert first in lines[1] and "completed" in lines[1] and f"{measured[0]}/60" in lines[1]
    assert second in lines[2] and "interrupted" in lines[2] and f"{measured[1]}/60" in lines[2]
    data = json.loads(run("runs", "--runs-dir", str(runs_dir), "--json").stdout)
    assert [r["id"] for r in data] == [first, second] and data[1]["sim_time"] > 0
    assert [r["measured"] for r in data] == measured and data[0]["done"] == 60


def test_runs_dir_from_environment_and_empty(runs_dir: Path, tmp_path: Path) -> None:
    res = run("runs", env={"ITA_RUNS": str(runs_dir)})
    assert res.exit_code == 0 and ids(runs_dir)[0] in res.stdout
    empty = run("runs", "--runs-dir", str(tmp_path / "nothing"))
    assert empty.exit_code == 0 and "no runs" in empty.output
    assert not (tmp_path / "nothing").exists()


def test_a_dead_run_shows_as_dead(tmp_path: Path) -> None:
    p = subprocess.Popen([sys.executable, "-c", "pass"])
    p.wait()
    with Archive.open(tmp_path / "archive.sqlite") as a:
        a.create_run("p", pid=p.pid, total=3)
    res = run("runs", "--runs-dir", str(tmp_path))
    assert res.exit_code == 0 and "dead" in res.stdout and "0/3" in res.stdout


def test_results_table_json_and_failed(runs_dir: Path) -> None:
    first, second = ids(runs_dir)
    prefix = first[:-1] if not second.startswith(first[:-1]) else first
    res = run("results", prefix, "--runs-dir", str(runs_dir))
    assert res.exit_code == 0, res.output
    assert res.stdout.splitlines()[1].split() == ["#", "SPEC", "KIND", "TOOL", "NOMINAL", "VALUE", "DEVIATION",
                                                  "TOLERANCE", "U", "U/TOL", "DECISION", "REASON"]
    assert len(res.stdout.splitlines()) == 2 + 60 and "does not conform" in res.stdout
    data = json.loads(run("results", first, "--runs-dir", str(runs_dir), "--json").stdout)
    assert data["run"] == first and len(data["results"]) == 60
    r0 = data["results"][0]
    assert {"value", "u", "U", "nominal", "lower", "upper", "decision"} <= set(r0)
    failed = json.loads(run("results", first, "--runs-dir", str(runs_dir), "--json", "--failed").stdout)
    decisions = {r["decision"] for r in failed["results"]}
    assert failed["results"] and "conforms" not in decisions
    assert len(failed["results"]) == sum(1 for r in data["results"] if r["decision"] != "conforms")
    last = json.loads(run("results", "last", "--runs-dir", str(runs_dir), "--json").stdout)
    assert len(last["results"]) == 25


def test_results_csv_has_every_column(runs_dir: Path) -> None:
    import csv
    import io

    from ita.report.data import COLUMNS

    first, _ = ids(runs_dir)
    res = run("results", first, "--runs-dir", str(runs_dir), "--csv")
    assert res.exit_code == 0, res.output
    rows = list(csv.DictReader(io.StringIO(res.stdout)))
    assert tuple(rows[0]) == COLUMNS and len(rows) == 60
    assert all(r["reason"] for r in rows if r["decision"] != "conforms")
    both = run("results", first, "--runs-dir", str(runs_dir), "--csv", "--json")
    assert both.exit_code == 2


def test_results_csv_keeps_every_digit_and_rounded_reads_in_a_spreadsheet(runs_dir: Path) -> None:
    import csv
    import io
    import re
    from datetime import datetime

    first, _ = ids(runs_dir)
    full = {r["spec_id"]: r for r in csv.DictReader(io.StringIO(run("results", first, "--runs-dir", str(runs_dir),
                                                                     "--csv").stdout))}
    data = {r["spec_id"]: r for r in json.loads(run("results", first, "--runs-dir", str(runs_dir),
                                                     "--json").stdout)["results"]}
    for spec_id, row in full.items():       # every digit: the CSV's text reads back the archive's float
        for column in ("value", "deviation", "U", "wall_time"):
            if data[spec_id][column] is not None:
                assert float(row[column]) == data[spec_id][column]
    rounded = run("results", first, "--runs-dir", str(runs_dir), "--csv", "--rounded")
    assert rounded.exit_code == 0, rounded.output
    rows = list(csv.DictReader(io.StringIO(rounded.stdout)))
    assert len(rows) == len(full)
    for row in rows:
        for column in ("nominal", "value", "deviation", "U", "x", "y", "z"):
            assert row[column] == "" or re.fullmatch(r"-?\d+\.\d{4}", row[column]), (column, row[column])
        if row["wall_time"]:
            assert datetime.fromisoformat(row["wall_time"]).utcoffset().total_seconds() == 0
    alone = run("results", first, "--runs-dir", str(runs_dir), "--rounded")
    assert alone.exit_code == 2 and "--rounded goes with --csv" in alone.output


def test_part_option_selects_the_runs_of_a_part(runs_dir: Path, tmp_path: Path) -> None:
    other = tmp_path / "otherpart"
    other.mkdir()
    res = run("results", "last", "--part", str(other), "--runs-dir", str(runs_dir))
    assert res.exit_code == 2 and "no run of the part" in res.output
    res = run("report", "last", "-o", str(tmp_path / "r.html"), "--part", str(other), "--runs-dir", str(runs_dir))
    assert res.exit_code == 2 and not (tmp_path / "r.html").exists()


def test_report_refuses_other_extensions_and_writes_nothing(runs_dir: Path, tmp_path: Path) -> None:
    res = run("report", "last", "-o", str(tmp_path / "r.txt"), "--runs-dir", str(runs_dir))
    assert res.exit_code == 2 and ".html" in res.output and ".pdf" in res.output
    assert not (tmp_path / "r.txt").exists()
    res = run("report", "last", "-o", str(tmp_path / "r.pdf"), "--runs-dir", str(runs_dir))
    assert res.exit_code == 0, res.output
    assert (tmp_path / "r.pdf").read_bytes()[:5] == b"%PDF-"


def test_unknown_and_ambiguous_runs_exit_2(runs_dir: Path) -> None:
    res = run("results", "nope", "--runs-dir", str(runs_dir))
    assert res.exit_code == 2 and "no run 'nope'" in res.output
    res = run("results", "r", "--runs-dir", str(runs_dir))
    assert res.exit_code == 2 and "ambiguous" in res.output
    res = run("report", "nope", "-o", "x.html", "--runs-dir", str(runs_dir))
    assert res.exit_code == 2


def test_report_of_a_run_of_the_builtin_part_is_scored(builtin_part, tmp_path: Path) -> None:
    from ita.part import specfile
    from ita.scoring import truth as scoring

    specs = specfile.load(builtin_part)[:40]
    truth = scoring.true_values(builtin_part.directory)
    runs = tmp_path / "runs"
    with Archive.open(runs / "archive.sqlite") as a:
        record_synthetic_run(a, specs, truth, part_dir=builtin_part.directory)
    out = tmp_path / "report.html"
    res = run("report", "last", "-o", str(out), "--runs-dir", str(runs))
    assert res.exit_code == 0, res.output
    page = out.read_text(encoding="utf-8")
    assert "scored" in res.stdout and '"id":"scoring"' in page and "40 of " in page
    assert '"type":"mesh3d"' in page                       # the part's mesh in the 3-D view
    res = run("report", "last", "-o", str(out), "--no-score", "--runs-dir", str(runs))
    assert res.exit_code == 0 and '"id":"scoring"' not in out.read_text(encoding="utf-8")
