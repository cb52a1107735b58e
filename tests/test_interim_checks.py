"""The cell checks itself (issue 34, point 3): an arm drift raises no exception of its own;
the cell finds it against its reference artifacts (the calibration block, tooling hole B),
names it, recalibrates the arm and measures again what it measured since its last good
check, and the archive keeps what it took out."""

from __future__ import annotations

import json
from collections import Counter
from pathlib import Path

from click.testing import CliRunner

from ita.archive import Archive, Event, Result, archive_path
from ita.cli import main


def test_a_superseded_result_leaves_the_archive_with_a_record_and_can_be_measured_again(tmp_path: Path,
                                                                                         builtin_part) -> None:
    from ita.specs.io import read_specs

    spec = read_specs(builtin_part.specs_path)[0]
    with Archive.open(archive_path(tmp_path)) as archive:
        run_id = archive.create_run("bulkhead", builtin_part.directory, seed=1, total=1)
        assert archive.record_result(run_id, Result.measured(spec, spec.nominal + 0.01, 0.002, tool="us_probe_1"))
        gone = archive.supersede(run_id, [spec.id, "NO-SUCH"], Event("remeasure", "top", 5.0, {"cause": "arm_drift"}))
        assert gone == [spec.id] and archive.result(run_id, spec.id) is None
        kept = archive.events(run_id, kinds=["remeasure"])[0].payload
        assert kept["cause"] == "arm_drift" and kept["superseded"][0]["spec"] == spec.id
        assert abs(kept["superseded"][0]["value"] - (spec.nominal + 0.01)) < 1e-9
        assert archive.record_result(run_id, Result.measured(spec, spec.nominal, 0.002, tool="us_probe_2"))
        assert archive.result(run_id, spec.id).tool == "us_probe_2"
        assert archive.integrity_check() == "ok"


def test_an_arm_drift_is_found_named_and_what_was_measured_since_the_last_check_measured_again(
        tmp_path: Path, builtin_part) -> None:
    """The arm drifts from 70 s on, after the part's registration (no device reports it);
    the SLRA's views then miss their features: the diagnosis names arm_drift; the arm is
    touched off on the calibration block, the results since the last good check are taken
    out and measured again; the run completes with every measurement made once in its
    final results and close to the truth."""
    from ita.scoring.truth import true_values

    runs = tmp_path / "runs"
    out = CliRunner().invoke(main, ["inspect", "--seed", "63", "--limit", "80", "--inject",
                                    "position_drift:after=70", "--runs-dir", str(runs), "--json"])
    assert out.exit_code == 0, out.output
    summary = json.loads(out.stdout)
    assert summary["status"] == "completed" and summary["measured"] == 80, summary
    truth = true_values(builtin_part.directory)
    with Archive.open(archive_path(runs), create=False) as archive:
        run_id = summary["run_id"]
        causes = [e.payload.get("cause") for e in archive.events(run_id, kinds=["diagnosis"])]
        again = archive.events(run_id, kinds=["remeasure"])
        results = archive.results(run_id)
        checks = archive.events(run_id, kinds=["interim_check"])
    assert "arm_drift" in causes, causes
    assert len(again) == 1 and again[0].payload["cause"] == "arm_drift"
    superseded = [g["spec"] for g in again[0].payload["superseded"]]
    assert superseded, "nothing was measured again"
    assert Counter(r.spec_id for r in results) == Counter(set(r.spec_id for r in results)) and len(results) == 80
    by_id = {r.spec_id: r for r in results}
    assert all(by_id[s].sim_time_start >= again[0].sim_time for s in superseded)      # measured after it
    assert checks and checks[-1].payload["passed"] is True                        # the last check passed
    far = [(r.spec_id, r.value - truth[r.spec_id], r.U) for r in results if abs(r.value - truth[r.spec_id]) > 2 * r.U]
    assert not far, far

