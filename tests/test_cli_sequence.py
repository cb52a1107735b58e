"""`ita sequence`: make, show, step through and resequence a plan, mark tools, explain."""

from __future__ import annotations

import json

import pytest
from click.testing import CliRunner

from ita.cli import main


@pytest.fixture()
def ita(knowledge_base, builtin_part, tmp_path, monkeypatch):
    """Invoke `ita sequence ...` in-process with a private ITA_HOME, on the built-in part."""
    monkeypatch.setenv("ITA_HOME", str(tmp_path / "home"))
    runner = CliRunner()
    part = ["--part", str(builtin_part.directory)]

    def invoke(*args: str):
        return runner.invoke(main, ["sequence", *args[:1], *part, *args[1:]] if args and args[0] in
                             ("next", "show", "why") else ["sequence", *args])

    invoke.part = part
    yield invoke
    knowledge_base.once("world", "reset_world")  # the commands apply the stored tool marks


def test_sequence_prints_groups_and_stores_the_plan(ita, tmp_path):
    result = ita(*ita.part, "--method", "classic", "--render", str(tmp_path / "seq.png"))
    assert result.exit_code == 0, result.output
    out = result.output
    assert "1. slra_1" in out and "2. us_probe_1" in out
    assert "tool changes: 1" in out and "total:" in out and "seconds of arm motion" in out
    assert "estimate" not in out
    # stored under the part's name and a digest of its content
    assert [p.name[:9] for p in (tmp_path / "home" / "plans").glob("*.json")] == ["bulkhead-"]
    assert (tmp_path / "seq.png").stat().st_size > 10_000


def test_sequence_json(ita):
    result = ita(*ita.part, "--method", "classic", "--json")
    assert result.exit_code == 0, result.output
    data = json.loads(result.output)
    assert data["measurements"] > 1000 and data["cannot"]["count"] == 0
    assert [g["tool"] for g in data["groups"]] == ["slra_1", "us_probe_1"]
    assert data["total_s"] == pytest.approx(sum(g["cost_s"] for g in data["groups"]) + data["transfer_s"],
                                            abs=0.01)
    assert data["cost_interim"] is False and data["cost_model"] == "arm_motion_time"
    assert "joint-space move times" in data["cost_includes"]


def test_next_resequences_after_a_tool_breaks(ita):
    assert ita(*ita.part, "--method", "classic").exit_code == 0
    first = ita("next", "--json", "-n", "2")
    assert first.exit_code == 0, first.output
    steps = [json.loads(line) for line in first.output.splitlines()]
    assert [s["tool"] for s in steps] == ["slra_1", "slra_1"]

    marked = ita("tool", "broken", "slra_1")
    assert marked.exit_code == 0 and "NOT available" in marked.output
    after = ita("next")
    assert after.exit_code == 0, after.output
    assert "resequenced: tool slra_1 not available (broken)" in after.output
    assert "with slra_2" in after.output

    shown = ita("show", "--json")
    plan = json.loads(shown.output)
    assert len(plan["handed_out"]) == 3 and plan["groups"][0]["tool"] == "slra_2"
    assert plan["tool_state"]["slra_1"]["condition"] == "broken"

    # a rebuilt plan keeps the progress, --restart forgets it
    again = ita(*ita.part, "--method", "classic", "--json")
    assert json.loads(again.output)["done"] == 3
    fresh = ita(*ita.part, "--method", "classic", "--json", "--restart")
    assert json.loads(fresh.output)["done"] == 0


def test_tool_marks_list_and_errors(ita):
    listed = ita("tool", "list")
    assert listed.exit_code == 0
    assert listed.output.count("available") == 5 and "NOT" not in listed.output
    assert ita("tool", "missing", "us_probe_2").exit_code == 0
    assert "missing" in ita("tool", "list").output
    assert ita("tool", "ok", "us_probe_2").exit_code == 0
    assert "NOT" not in ita("tool", "list").output
    bad = ita("tool", "broken", "drill")
    assert bad.exit_code == 2 and "unknown tool 'drill'" in bad.output
    assert ita("tool", "broken").exit_code == 2


def test_next_without_a_plan(ita):
    result = ita("next")
    assert result.exit_code == 2 and "run `ita sequence` first" in result.output


def test_why(ita):
    ok = ita("why", "SW-RV01-1", "--tree")
    assert ok.exit_code == 0, ok.output
    assert "tool: slra_1 (slra_tool) by rule slra_rib_width" in ok.output
    assert "ita kb why 'select_tool(stiffener_width, stiffener," in ok.output
    assert "tool_of_type(slra_tool, slra_1, primary)" in ok.output
    ita("tool", "broken", "us_probe_1")
    ita("tool", "broken", "us_probe_2")
    no = ita("why", "WT-P01-1")
    assert no.exit_code == 1 and "cannot be done: no_working_tool(us_tool)" in no.output
    assert ita("why", "nope").exit_code == 2
