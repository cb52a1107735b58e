"""`ita plan` and `ita macrop` on the built-in bulkhead (store under a temporary ITA_HOME)."""

from __future__ import annotations

import json

import pytest
from click.testing import CliRunner

from ita.cli import main


@pytest.fixture(scope="module")
def ids(builtin_part):
    from ita.specs.io import read_specs

    specs = read_specs(builtin_part.specs_path)
    us = [s.id for s in specs if s.kind.value == "web_thickness"]
    slra = [s.id for s in specs if s.kind.value == "hole_diameter"]
    return us, slra


@pytest.fixture
def run(builtin_part):
    def invoke(*args: str):
        return CliRunner().invoke(main, list(args), catch_exceptions=False)

    invoke("macrop", "clear")
    return invoke


def test_plan_learns_then_matches(run, ids):
    us, _ = ids
    first = run("plan", us[0])
    assert first.exit_code == 0
    assert "no MACROP matched" in first.stdout and "us_measure(us_probe_1, t3" in first.stdout
    second = run("plan", us[1])
    assert second.exit_code == 0 and "MACROP m1 matched" in second.stdout


def test_plan_json_has_steps_and_predecessors(run, ids):
    _, slra = ids
    out = run("plan", slra[0], "--json", "--holding", "us_probe_1")
    assert out.exit_code == 0
    data = json.loads(out.stdout)
    assert data["kind"] == "hole_diameter" and data["source"] == "scratch" and not data["matched"]
    assert [s["action"] for s in data["steps"]][:3] == ["move", "put_down", "move"]
    assert all(p < s["number"] for s in data["steps"] for p in s["predecessors"])
    assert data["final_state"]["holding"] == "slra_1"


def test_from_scratch_and_after(run, ids):
    us, _ = ids
    run("plan", us[0])
    out = run("plan", us[1], "--after", us[0], "--from-scratch")
    assert out.exit_code == 0 and "planned from scratch" in out.stdout
    assert f"move_retract(t3, {us[0]})" in out.stdout


def test_unknown_measurement_is_exit_2(run):
    out = run("plan", "NO-SUCH-ID")
    assert out.exit_code == 2 and "no measurement 'NO-SUCH-ID'" in out.stderr


def test_macrop_list_show_clear(run, ids):
    us, _ = ids
    run("plan", us[0])
    run("plan", us[1])
    listed = run("macrop", "list")
    assert listed.exit_code == 0
    assert "m1" in listed.stdout and "kb:measured" in listed.stdout
    assert "2 lookups: 1 hits, 1 misses" in listed.stdout
    shown = run("macrop", "show", "m1")
    assert shown.exit_code == 0 and "preconditions([" in shown.stdout and "plan([" in shown.stdout
    assert run("macrop", "show", "m7").exit_code == 2
    cleared = run("macrop", "clear")
    assert "cleared 1 learned MACROP" in cleared.stdout
    assert "m1" not in run("macrop", "list").stdout


def test_plan_top_prints_the_jobs_decomposition_and_carries_nothing_out(run, tmp_path):
    """`ita plan --top`: the Top Level's plan of the whole default job for the built-in
    part, its tasks with the methods that decomposed them and what the Sequence Planner
    was asked; no run is recorded in the user's archive."""
    result = run("plan", "--top", "--lines", "30")
    assert result.exit_code == 0, result.output
    lines = result.output.splitlines()
    assert lines[0].startswith("job inspect_part: ") and " actions, " in lines[0]
    assert lines[1] == "inspect_part  <- in_sequence" and lines[2:4] == ["  register_part", "  record_unplaceable"]
    assert "asked: next_measurement(0, step(" in lines[4] and "<- round_trip" in result.output
    assert lines[-1].startswith("... ") and lines[-1].endswith(" more tasks") and len(lines) == 32
    wrong = run("plan", "--top", "X-1")
    assert wrong.exit_code == 2 and "give no MEAS_ID" in wrong.output
