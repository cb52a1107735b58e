"""`ita inspect`, `ita continue`, `ita monitor` as a user calls them."""

from __future__ import annotations

import json
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
