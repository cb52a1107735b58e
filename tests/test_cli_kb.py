"""`ita kb`: query, shell, check, list, why, as a user sees them."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from click.testing import CliRunner

from ita.cli import main

REPO = Path(__file__).resolve().parent.parent


@pytest.fixture()
def ita(knowledge_base, tmp_path, monkeypatch):
    """Invoke `ita` in-process; returns the click Result."""
    monkeypatch.setenv("ITA_HOME", str(tmp_path / "home"))
    runner = CliRunner()

    def invoke(*args: str, stdin: str | None = None):
        return runner.invoke(main, list(args), input=stdin)

    return invoke


def test_query_prints_aligned_table(ita):
    result = ita("kb", "query", "type(X, us_tool), weight(X, W)")
    assert result.exit_code == 0, result.output
    lines = result.output.splitlines()
    assert lines[0].split() == ["X", "W"]
    assert lines[2].split() == ["us_probe_1", "1.5"]
    assert lines[3].split() == ["us_probe_2", "1.5"]
    # the W column starts at the same place on every line
    assert lines[0].index("W") == lines[2].index("1.5") == lines[3].index("1.5")


def test_query_json_and_limit(ita):
    result = ita("kb", "query", "type(X, Y)", "--json", "--limit", "2")
    assert result.exit_code == 0, result.output
    data = json.loads(result.output)
    assert data["variables"] == ["X", "Y"]
    assert data["rows"] == [{"X": "t3", "Y": "arm"}, {"X": "us_probe_1", "Y": "us_tool"}]
    assert data["truncated"] is True


def test_query_true_and_false(ita):
    assert ita("kb", "query", "available(us_probe_1)").output.strip() == "true."
    result = ita("kb", "query", "type(X, hammer)")
    assert result.exit_code == 1 and result.output.strip() == "false."


@pytest.mark.parametrize(
    "goal",
    ["shell(ls)", "assertz(world:foo)", "halt", "open(f, write, S)", "consult(f)"],
)
def test_query_refuses_unsafe_goal_with_exit_2(ita, goal):
    result = ita("kb", "query", goal)
    assert result.exit_code == 2
    (line,) = [l for l in result.output.splitlines() if l.strip()]
    assert line.startswith("error: refused:")


def test_query_stops_looping_goal_at_the_limit(ita):
    result = ita("kb", "query", "repeat, fail", "--inference-limit", "50000")
    assert result.exit_code == 2
    assert "inference limit" in result.output and "loop" in result.output


def test_query_from_another_directory(run_python):
    proc = run_python(str(REPO / "cli.py"), "kb", "query", "type(X, us_tool)")
    assert proc.returncode == 0, proc.stderr
    assert "us_probe_1" in proc.stdout and "us_probe_2" in proc.stdout


def test_why_prints_indented_proof_tree(ita):
    result = ita("kb", "why", "available(us_probe_1)")
    assert result.exit_code == 0, result.output
    lines = result.output.splitlines()
    assert lines[0].startswith("available(us_probe_1)") and "world.pl:" in lines[0]
    assert any(l.startswith("|- tool_condition(us_probe_1, ok)") for l in lines)
    assert any(l.startswith("|  ") and "type(us_probe_1, us_tool)" in l for l in lines)


def test_why_without_proof_exits_1(ita):
    result = ita("kb", "why", "available(hammer)")
    assert result.exit_code == 1 and "no proof" in result.output


def test_check_is_clean_on_the_real_knowledge_base(ita):
    result = ita("kb", "check")
    assert result.exit_code == 0, result.output
    assert "OK" in result.output


def test_check_reports_broken_file_with_file_line(run_python, broken_kb):
    proc = run_python(str(REPO / "cli.py"), "kb", "check", "--kb-dir", str(broken_kb))
    assert proc.returncode == 1
    assert f"{broken_kb / 'broken_kb.pl'}:3:11: error:" in proc.stdout


def test_check_reports_warnings_and_undefined(run_python, tmp_path):
    kb_dir = tmp_path / "kb2"
    kb_dir.mkdir()
    (kb_dir / "sloppy_kb.pl").write_text(
        ":- module(sloppy_kb, [p/1]).\n"
        "p(X) :- q(Y).\n"
        "q(1).\n"
        "p(2) :- nowhere(3).\n",
        encoding="utf-8",
    )
    proc = run_python(str(REPO / "cli.py"), "kb", "check", "--kb-dir", str(kb_dir))
    assert proc.returncode == 1
    path = kb_dir / "sloppy_kb.pl"
    assert f"{path}:2: warning: Singleton variables" in proc.stdout
    assert f"{path}:4: warning:" in proc.stdout and "discontiguous" in proc.stdout.lower()
    assert "nowhere/1" in proc.stdout and f"{path}:4: error:" in proc.stdout


def test_list_shows_world_predicates_with_pldoc(ita):
    result = ita("kb", "list")
    assert result.exit_code == 0, result.output
    assert "world.pl (module world)" in result.output
    line = next(l for l in result.output.splitlines() if l.strip().startswith("available/1"))
    assert "condition is `ok`" in line


def test_shell_reads_goals_from_stdin(ita):
    stdin = "help\ntype(X, arm).\nshell(ls)\nwhy available(slra_2)\nquit\ntype(X, arm)\n"
    result = ita("kb", "shell", stdin=stdin)
    assert result.exit_code == 0, result.output
    out = result.output
    assert "read-only" in out  # help
    assert "t3" in out
    assert "error: refused: shell/1" in out
    assert "available(slra_2)" in out and "[rule world.pl:" in out
    assert out.count("t3") == 1  # nothing after quit ran


def test_every_kb_command_has_help(ita):
    for command in ("query", "shell", "check", "list", "why"):
        result = ita("kb", command, "--help")
        assert result.exit_code == 0 and len(result.output.splitlines()) > 3


def test_shell_completes_predicate_names():
    from ita.cli.kb import _completer, _predicate_names

    names = _predicate_names()
    assert {"available", "tool_condition", "type"} <= set(names)
    complete = _completer(names)
    assert complete("avail", 0) == "available" and complete("avail", 1) is None
