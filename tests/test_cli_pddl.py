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


@pytest.mark.parametrize("domain_edit,problem_edit,where,what", [
    (None, ("(:domain hand)", "(:domain other)"), "problem", "wrong domain"),
    (None, ("(:goal (and (holding b)))", ""), "problem", "no :goal"),
    (None, ("(:init (at a)", "(:init (on a)"), "problem", "not declared in :predicates: on"),
    (("(holding ?x) (not", "(holding ?x ?x) (not"), None, "domain", "holding has 2 arguments"),
    (("(?x)\n    :precondition (and", "(?x - ball)\n    :precondition (and"), None, "domain", "need the :typing"),
    (("(and (holding ?x) (not (at ?x)) (not (free)))", "(when (free) (holding ?x))"), None, "domain",
     "conditional or quantified effects"),
    (("(and (at ?x) (free))", "(or (at ?x) (free))"), None, "domain", "only conjunctions"),
])
def test_problem_checked_against_domain_and_requirements(tmp_path, domain_edit, problem_edit, where, what):
    d, p = tmp_path / "domain.pddl", tmp_path / "problem.pddl"
    d.write_text(DOMAIN.replace(*domain_edit) if domain_edit else DOMAIN)
    p.write_text(PROBLEM.replace(*problem_edit) if problem_edit else PROBLEM)
    out = solve(d, p)
    assert out.exit_code == 2, out.output
    assert what in out.stderr and str(d if where == "domain" else p) in out.stderr


CHAIN = """(define (domain chain)
  (:requirements :strips)
  (:predicates (at ?x) (link ?x ?y))
  (:action move :parameters (?x ?y)
    :precondition (and (at ?x) (link ?x ?y))
    :effect (and (at ?y) (not (at ?x)))))
"""


def _chain(tmp_path, n: int):
    d, p = tmp_path / "chain.pddl", tmp_path / f"chain{n}.pddl"
    d.write_text(CHAIN)
    links = " ".join(f"(link n{i} n{i + 1})" for i in range(n))
    objects = " ".join(f"n{i}" for i in range(n + 1))
    p.write_text(f"(define (problem c) (:domain chain) (:objects {objects}) "
                 f"(:init (at n0) {links}) (:goal (at n{n})))")
    return d, p


def test_depth_bound_is_disclosed_and_can_be_raised(tmp_path):
    d, p = _chain(tmp_path, 100)
    out = solve(d, p)
    assert out.exit_code == 1 and "goal-stack depth 60" in out.stderr and "--max-depth" in out.stderr
    out = solve(d, p, "--max-depth", "300")
    assert out.exit_code == 0 and out.stdout.splitlines()[-1].startswith("; length 100")


def test_time_limit_holds_on_a_large_problem(tmp_path):
    import time

    d, p = _chain(tmp_path, 3000)
    started = time.monotonic()
    out = solve(d, p, "--time-limit", "2", "--max-depth", "10000")
    assert out.exit_code == 1 and "time_limit_exceeded" in out.stderr
    assert time.monotonic() - started < 2 + 2
