"""`ita pddl solve`: IPC plan output, errors with file:line, exit codes."""

from __future__ import annotations

from pathlib import Path

import pytest
from click.testing import CliRunner

from ita.cli import main
from ita.cli.pddl import unbalanced_line

DOMAIN = """(define (domain hand)
  (:requirements :strips)
  (:predicates (at ?x) (holding ?x) (free))
  (:action pick
    :parameters (?x)
    :precondition (and (at ?x) (free))
    :effect (and (holding ?x) (not (at ?x)) (not (free))))
  (:action drop
    :parameters (?x)
    :precondition (holding ?x)
    :effect (and (at ?x) (free) (not (holding ?x)))))
"""
PROBLEM = """(define (problem two) (:domain hand)
  (:objects a b)
  (:init (at a) (at b) (free))
  (:goal (and (holding b))))
"""


@pytest.fixture
def files(tmp_path: Path):
    d, p = tmp_path / "domain.pddl", tmp_path / "problem.pddl"
    d.write_text(DOMAIN)
    p.write_text(PROBLEM)
    return d, p


def solve(*args):
    return CliRunner().invoke(main, ["pddl", "solve", *map(str, args)])


def test_prints_ipc_plan(files):
    out = solve(*files)
    assert out.exit_code == 0, out.stderr
    lines = out.stdout.splitlines()
    assert lines[0] == "(pick b)" and lines[-1].startswith("; length 1")


def test_no_plan_is_exit_1(files, tmp_path):
    d, _ = files
    p = tmp_path / "impossible.pddl"
    p.write_text(PROBLEM.replace("(holding b)", "(holding b) (holding a)"))
    out = solve(d, p)
    assert out.exit_code == 1 and "; no plan:" in out.stderr


def test_unbalanced_parenthesis_names_file_and_line(files, tmp_path):
    d, p = files
    bad = tmp_path / "bad.pddl"
    bad.write_text(DOMAIN.replace("(:action drop", "(:action drop)\n)"))
    out = solve(bad, p)
    assert out.exit_code == 2
    assert f"{bad}:" in out.stderr and "unbalanced parentheses" in out.stderr


def test_unsupported_requirement_names_its_line(files, tmp_path):
    d, p = files
    bad = tmp_path / "fluents.pddl"
    bad.write_text(DOMAIN.replace(":strips", ":fluents"))
    out = solve(bad, p)
    assert out.exit_code == 2 and f"{bad}:2:" in out.stderr


def test_time_limit_option(files):
    out = solve(*files, "--time-limit", "5")
    assert out.exit_code == 0


def test_unbalanced_line():
    assert unbalanced_line("(a\n (b))\n)") == (3, "unexpected ')'")
    assert unbalanced_line("(a ; )\n (b)") == (1, "'(' is never closed")
    assert unbalanced_line("(a (b))") is None
