"""`ita inspect`, `ita continue`, `ita monitor` as a user calls them."""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest
from click.testing import CliRunner

from ita.cli import main


@pytest.fixture(scope="module")
def finished_run(tmp_path_factory, builtin_part) -> tuple[Path, dict, str]:
    runs = tmp_path_factory.mktemp("runs")
    result = CliRunner().invoke(main, ["inspect", "--limit", "3", "--runs-dir", str(runs), "--json"])
    assert result.exit_code == 0, result.output
    return runs, json.loads(result.stdout), result.stderr


def test_inspect_prints_a_summary_and_progress(finished_run) -> None:
    _, summary, stderr = finished_run
    assert summary["status"] == "completed" and summary["done"] == summary["total"] == 3
    assert sum(summary["counts"].values()) == 3
    assert summary["simulated_cycle_s"] > 0 and summary["wall_s"] > 0
    assert set(summary["breakdown_s"]) >= {"motion", "measuring", "tool_change", "waiting"}
    assert "3/3" in stderr and "run r" in stderr          # the live view (plain lines off a TTY)


def test_a_run_keeps_its_htn_plan_and_the_report_shows_it(finished_run, tmp_path) -> None:
    """The Top Level's plan (the job's HTN decomposition, its figures) is kept with the run,
    as planned when it starts (the System Monitor shows it while the run goes on) and as
    carried out at its end; the report (and so the run page) has a section of it."""
    from ita.archive import Archive, archive_path

    runs, summary, stderr = finished_run
    with Archive.open(archive_path(runs)) as archive:
        trees = archive.events(summary["run_id"], kinds=["task_tree"])
    assert [t.payload["stage"] for t in trees] == ["planned", "carried out"]
    assert all(t.payload["job"] == "inspect_part" for t in trees)
    assert trees[-1].payload["lines"][0] == "inspect_part  <- in_sequence"
    assert summary["planner"]["actions"] >= 3 * 3 and summary["planner"]["plan_s"] > 0
    page = tmp_path / "r.html"
    report = CliRunner().invoke(main, ["report", summary["run_id"], "--runs-dir", str(runs), "-o", str(page)])
    assert report.exit_code == 0, report.output
    assert "The Top Level's plan (HTN)" in page.read_text() and "in_sequence" in page.read_text()


def test_monitor_once_and_refusals(finished_run) -> None:
    runs, summary, _ = finished_run
    run_id = summary["run_id"]
    once = CliRunner().invoke(main, ["monitor", run_id[:10], "--once", "--runs-dir", str(runs)])
    assert once.exit_code == 0 and run_id in once.stdout and "completed" in once.stdout and "3/3" in once.stdout
    stop = CliRunner().invoke(main, ["monitor", run_id, "--stop", "--runs-dir", str(runs)])
    assert stop.exit_code == 2 and "not running" in stop.stderr
    again = CliRunner().invoke(main, ["continue", run_id, "--runs-dir", str(runs)])
    assert again.exit_code == 2 and "nothing to continue" in again.stderr


def test_monitor_sends_interrupt_to_a_running_run(finished_run) -> None:
    from ita.archive import Archive, archive_path

    runs, _, _ = finished_run
    with Archive.open(archive_path(runs)) as archive:
        run_id = archive.create_run("bulkhead", None, total=1)      # a run "in progress" here
    sent = CliRunner().invoke(main, ["monitor", run_id, "--interrupt", "--runs-dir", str(runs)])
    assert sent.exit_code == 0 and "INTERRUPT sent" in sent.stdout
    with Archive.open(archive_path(runs)) as archive:
        request = archive.take_control(run_id)
        assert request is not None and request.command.value == "INTERRUPT"


def test_continue_unknown_run(finished_run) -> None:
    runs, _, _ = finished_run
    result = CliRunner().invoke(main, ["continue", "no-such-run", "--runs-dir", str(runs)])
    assert result.exit_code == 2 and "no run" in result.stderr


def _reinspect(runs: Path, source: str) -> tuple[dict, list]:
    """`ita inspect --task reinspect --from SOURCE`: its JSON summary and the new run's
    results, the run recorded as a reinspection of SOURCE."""
    from ita.archive import Archive, archive_path

    again = CliRunner().invoke(main, ["inspect", "--task", "reinspect", "--from", source, "--runs-dir", str(runs),
                                      "--json"])
    assert again.exit_code == 0, again.output
    summary = json.loads(again.stdout)
    with Archive.open(archive_path(runs)) as archive:
        info = archive.run(summary["run_id"])
        results = archive.results(summary["run_id"])
    assert info.settings["task"] == "reinspect" and info.settings["from"] == source
    return summary, results


def test_reinspect_measures_again_exactly_the_unproven_results_of_a_run(tmp_path, builtin_part) -> None:
    """A run whose results conform, are uncertain, do not conform, were not done or cannot
    be done: `--task reinspect --from RUN` makes a new run of the uncertain, the
    nonconforming and the not done alone, each measured once."""
    from ita.archive import Archive, Outcome, Result, archive_path
    from ita.specs.io import read_specs

    runs = tmp_path / "runs"
    specs = [s for s in read_specs(builtin_part.specs_path) if s.kind.value == "web_thickness"][:6]
    with Archive.open(archive_path(runs)) as archive:
        source = archive.create_run(builtin_part.name, builtin_part.directory, seed=0, total=len(specs))
        a, b, c, d, e, f = specs
        archive.record_result(source, Result.measured(a, a.nominal, 0.001))
        archive.record_result(source, Result.measured(b, b.nominal, 0.001))
        archive.record_result(source, Result.measured(c, c.nominal + c.upper, 0.01))       # uncertain
        archive.record_result(source, Result.measured(d, d.nominal + 3 * d.upper, 0.001))  # does not conform
        archive.record_result(source, Result.unmeasured(e, Outcome.NOT_DONE, "dry couplant"))
        archive.record_result(source, Result.unmeasured(f, Outcome.CANNOT_BE_DONE, "no tool"))
    summary, results = _reinspect(runs, source)
    assert sorted(r.spec_id for r in results) == sorted([c.id, d.id, e.id]) and summary["total"] == 3
    assert all(r.outcome is Outcome.MEASURED for r in results)
    refused = CliRunner().invoke(main, ["inspect", "--task", "reinspect", "--runs-dir", str(runs)])
    assert refused.exit_code == 2 and "--from RUN" in refused.output


def test_reinspect_chooses_more_frames_where_they_lower_the_uncertainty(tmp_path, builtin_part) -> None:
    """Positions left uncertain by their network's frame poses (a term that is new at each
    approach) are measured again from 16 approaches each (kb/tasks.pl better_way/3); a
    diameter whose largest term is the SLRA's calibration (the same in every frame) is
    measured again the same way.  The decomposition kept with the run says so."""
    from ita.archive import Archive, Event, Result, archive_path
    from ita.specs.io import read_specs

    runs = tmp_path / "runs"
    specs = read_specs(builtin_part.specs_path)
    positions = [s for s in specs if s.id.startswith("HP-OF-")][:1]
    diameter = next(s for s in specs if s.id.startswith("HD-OF-"))
    network = "; largest term: network (frame poses and rim fits) (u 0.0787 mm)"
    with Archive.open(archive_path(runs)) as archive:
        source = archive.create_run(builtin_part.name, builtin_part.directory, seed=0, total=2)
        for p in positions:
            archive.record_result(source, Result.measured(p, p.upper - 0.01, 0.08, tool="slra_1",
                                                          reason="U/tolerance 0.31" + network))
        archive.record_result(source, Result.measured(
            diameter, diameter.nominal + diameter.upper, 0.0084, tool="slra_1",
            reason="U/tolerance 0.34; largest term: SLRA calibration (reference workpieces) (u 0.0084 mm)"))
        archive.record_event(source, Event("run_end", "top", 1.0, {"status": "completed"}))
    again = CliRunner().invoke(main, ["inspect", "--task", "reinspect", "--from", source, "--runs-dir", str(runs),
                                      "--json"])
    assert again.exit_code == 0, again.output
    summary = json.loads(again.stdout)
    with Archive.open(archive_path(runs)) as archive:
        run = summary["run_id"]
        tree = "\n".join(archive.events(run, kinds=["task_tree"])[-1].payload["lines"])
        results = {r.spec_id: r for r in archive.results(run)}
    for p in positions:
        assert f"measure_again({p.id}, more_frames(16)" in tree, tree
        seen = re.search(r"seen in (\d+)", results[p.id].reason or "")
        # 16 approaches; a frame whose rim fit the hole's edge defeats sees it not (one in 16, at most two)
        assert seen is not None and int(seen.group(1)) >= 14, results[p.id].reason
    assert f"measure({diameter.id}, slra_1" in tree and f"measure_again({diameter.id}" not in tree
    assert summary["devices"]["slra_frames"] >= 16 + 1


def test_a_fault_met_by_the_recoverys_own_retry_is_diagnosed_too(tmp_path) -> None:
    """slra_2's window dirty, then slra_1's laser failed: the first measurement after 50 s
    fails on slra_1 (HD-TH-B here; the exact one depends on the path planner's timings),
    the handler finds it failed (cleaning does not cure it) and takes the measurement again
    with slra_2, which fails too.  That failure is diagnosed in turn (a dirty window,
    cleaned) and the measurement is made; the first diagnosis says its retry failed."""
    from ita.archive import Archive, archive_path

    runs = tmp_path / "runs"
    out = CliRunner().invoke(main, ["inspect", "--seed", "62", "--limit", "12", "--inject",
                                    "dirty_window@slra_2:after=10", "--inject", "slra_failed@slra_1:after=50",
                                    "--runs-dir", str(runs), "--json"])
    assert out.exit_code == 0, out.output
    summary = json.loads(out.stdout)
    assert summary["counts"].get("not_done", 0) == 0 and summary["done"] == 12
    with Archive.open(archive_path(runs)) as archive:
        diagnoses = [e.payload for e in archive.events(summary["run_id"], kinds=["diagnosis"])]
    assert [d["cause"] for d in diagnoses] == ["slra_failed(slra_1)", "dirty_window(slra_2)"], diagnoses
    assert diagnoses[0]["spec"] == diagnoses[1]["spec"]
    assert diagnoses[0]["recovery"].startswith("the retry failed:")
    assert not diagnoses[1]["recovery"].startswith("the retry failed:")


def test_cell_check_reads_the_block_with_each_probe_and_measures_the_tooling_holes(tmp_path, builtin_part) -> None:
    """`--task cell_check`: a run of the part's tooling holes alone, each probe reading the
    calibration block first, and a report of the cell's state (its artifacts' readings)."""
    from ita.archive import Archive, archive_path
    from ita.part.model import Hole, HoleRole
    from ita.specs.io import read_specs

    tooling = {f.id for f in builtin_part.features if isinstance(f, Hole) and f.role is HoleRole.TOOLING}
    expected = sorted(s.id for s in read_specs(builtin_part.specs_path) if s.feature in tooling)
    runs = tmp_path / "runs"
    result = CliRunner().invoke(main, ["inspect", "--task", "cell_check", "--runs-dir", str(runs), "--json"])
    assert result.exit_code == 0, result.output
    summary = json.loads(result.stdout)
    cell = summary["cell"]
    assert sorted(h["spec"] for h in cell["tooling"]) == expected and summary["total"] == len(expected)
    assert sorted(p["probe"] for p in cell["probes"]) == ["us_probe_1", "us_probe_2", "us_probe_90"]
    assert all(p["ok"] and abs(p["reading_mm"] - p["block_mm"]) < 0.1 for p in cell["probes"])
    assert all(h["centre_off_mm"] is not None and h["centre_off_mm"] < 1.0 for h in cell["tooling"])
    assert cell["state"] == "as certified" or cell["state"].startswith("to look at: ")
    with Archive.open(archive_path(runs)) as archive:
        assert [e.kind for e in archive.events(summary["run_id"], kinds=["cell_check"])] == ["cell_check"]
    refused = CliRunner().invoke(main, ["inspect", "--task", "cell_check", "--limit", "3", "--runs-dir", str(runs)])
    assert refused.exit_code == 2 and "--limit" in refused.output


def test_with_both_slras_broken_the_run_says_what_is_missing(tmp_path, builtin_part) -> None:
    """Both SLRAs marked broken: the tooling holes of a cell check cannot be done, each
    with the reason naming what is missing; the cell's report counts them; the summary
    ends with a note of the results without a value."""
    from ita.archive import Archive, archive_path

    runs = tmp_path / "runs"
    for tool in ("slra_1", "slra_2"):
        assert CliRunner().invoke(main, ["sequence", "tool", "broken", tool]).exit_code == 0
    try:
        out = CliRunner().invoke(main, ["inspect", "--task", "cell_check", "--runs-dir", str(runs)])
    finally:
        for tool in ("slra_1", "slra_2"):
            CliRunner().invoke(main, ["sequence", "tool", "ok", tool])
    assert out.exit_code == 0, out.output
    assert "the cell: to look at:" in out.output and "cannot be done" in out.output
    assert "NOTE: 2 cannot be done" in out.output and ", 0 measured" in out.output
    with Archive.open(archive_path(runs)) as archive:
        results = archive.results(archive.runs()[-1].id)
    assert {r.reason for r in results} == {"no working slra_tool: slra_1 broken, slra_2 broken"}


@pytest.mark.slow
def test_reinspect_measures_again_exactly_what_a_run_left_unproven(tmp_path, builtin_part) -> None:
    """A run with faults injected (an arm drift, found by the cell's checks) on a serial
    whose as-built part has one flange wall 0.4 mm thick (`--shift`) leaves that result
    unproven; `--task reinspect --from RUN` makes a new run of what was left alone, and
    measures each once."""
    from ita.archive import Archive, archive_path
    from ita.part.store import load_part, part_key
    from ita.sequence.store import load_plan
    from ita.toplevel import unproven

    runs = tmp_path / "runs"
    assert CliRunner().invoke(main, ["prepare"]).exit_code == 0
    shifted = load_plan(part_key(load_part(None))).groups[0].order[0]   # the stored plan's first measurement
    first = CliRunner().invoke(main, ["inspect", "--limit", "12", "--faults", "0.3", "--seed", "1", "--alarm-after",
                                      "0", "--inject", "position_drift:after=0", "--serial", "SN-7", "--shift",
                                      f"{shifted}=0.4", "--runs-dir", str(runs), "--json"])
    assert first.exit_code == 0, first.output
    source = json.loads(first.stdout)["run_id"]
    with Archive.open(archive_path(runs)) as archive:
        left = unproven(archive, source)
    assert shifted in left, left
    summary, results = _reinspect(runs, source)
    assert sorted(r.spec_id for r in results) == sorted(left) and summary["total"] == len(left)
    refused = CliRunner().invoke(main, ["inspect", "--task", "reinspect", "--runs-dir", str(runs)])
    assert refused.exit_code == 2 and "--from RUN" in refused.output


def test_serial_and_operator_are_kept_with_the_run_and_listed_with_its_verdict(tmp_path, builtin_part) -> None:
    runs = tmp_path / "runs"
    made = CliRunner().invoke(main, ["inspect", "--limit", "2", "--serial", "SN-0042", "--operator", "A. Tester",
                                     "--runs-dir", str(runs), "--json"])
    assert made.exit_code == 0, made.output
    listed = json.loads(CliRunner().invoke(main, ["runs", "--runs-dir", str(runs), "--json"]).stdout)
    assert [(r["serial"], r["operator"]) for r in listed] == [("SN-0042", "A. Tester")]
    assert listed[0]["verdict"] in ("accept", "reject", "incomplete")
    table = CliRunner().invoke(main, ["runs", "--runs-dir", str(runs)]).stdout
    assert "VERDICT" in table and "SN-0042" in table and "A. Tester" in table
    for bad in ("", "x" * 65, "SN\n1", "SN\x1b[2J"):
        refused = CliRunner().invoke(main, ["inspect", "--limit", "1", "--serial", bad, "--runs-dir", str(runs)])
        assert refused.exit_code == 2 and "printable" in refused.output, repr(bad)
