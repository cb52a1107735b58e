"""The ITA planner's PDDL plans, checked by an independent STRIPS simulator.

The planner (prolog/pddl.pl, run with ``swipl`` in a subprocess) prints each plan in
the IPC format; this module parses the same PDDL files with the ``pddl`` package (not
the planner's reader), grounds each printed action, and executes the plan: every
precondition must hold before its step and the goal at the end.  The default run covers
quick problems of each domain; ``-m slow`` runs all 36.
"""

from __future__ import annotations

import shutil
import subprocess
from pathlib import Path

import pytest

pddl = pytest.importorskip("pddl")

ROOT = Path(__file__).resolve().parent.parent
PDDL_DIR = ROOT.parent / "shared" / "pddl"
PLANNER = ROOT / "prolog" / "pddl.pl"

pytestmark = [
    pytest.mark.skipif(shutil.which("swipl") is None, reason="needs swipl"),
    pytest.mark.skipif(not PDDL_DIR.is_dir(), reason="needs ../shared/pddl"),
]

QUICK = [
    ("blocks", "probBLOCKS-4-0"),
    ("blocks", "probBLOCKS-5-1"),
    ("blocks", "probBLOCKS-7-1"),
    ("gripper", "prob01"),
    ("gripper", "prob03"),
    ("logistics00", "probLOGISTICS-4-0"),
    ("logistics00", "probLOGISTICS-6-2"),
]


def all_problems() -> list[tuple[str, str]]:
    return [(d, p.stem) for d in ("blocks", "gripper", "logistics00")
            for p in sorted((PDDL_DIR / d).glob("prob*.pddl"))]


def solve(domain: Path, problem: Path, limit: int) -> list[str]:
    """The plan lines the ITA planner prints (empty when it finds none)."""
    query = (f"use_module('{PLANNER}'),"
             f"(solve_and_print('{domain}','{problem}',[time_limit({limit})]) -> halt(0) ; halt(1))")
    done = subprocess.run(["swipl", "-q", "-g", query, "-t", "halt(2)"],
                          capture_output=True, text=True, timeout=limit + 30)
    return [line.strip() for line in done.stdout.splitlines() if line.startswith("(")]


def lowered(path: Path, tmp: Path) -> Path:
    """A lower-case copy of a PDDL file (the `pddl` package is case-sensitive)."""
    copy = tmp / path.name
    copy.write_text(path.read_text().lower())
    return copy


def atom(predicate, binding: dict[str, str] | None = None) -> tuple[str, ...]:
    names = [binding[t.name] if binding is not None and t.name in binding else t.name
             for t in predicate.terms]
    return (predicate.name, *names)


def conjuncts(formula) -> list:
    return list(formula.operands) if hasattr(formula, "operands") else [formula]


def simulate(domain_file: Path, problem_file: Path, lines: list[str]) -> str | None:
    """Execute the plan; None if it is valid, else what went wrong."""
    domain = pddl.parse_domain(domain_file)
    problem = pddl.parse_problem(problem_file)
    actions = {a.name: a for a in domain.actions}
    state = {atom(p) for p in problem.init}
    for n, line in enumerate(lines, 1):
        name, *args = line.strip("()").split()
        action = actions.get(name)
        if action is None or len(args) != len(action.parameters):
            return f"step {n}: unknown action {line}"
        binding = {v.name: a for v, a in zip(action.parameters, args)}
        for pre in conjuncts(action.precondition):
            if atom(pre, binding) not in state:
                return f"step {n}: {line} needs {atom(pre, binding)}"
        effects = conjuncts(action.effect)
        deletes = {atom(e.argument, binding) for e in effects if type(e).__name__ == "Not"}
        adds = {atom(e, binding) for e in effects if type(e).__name__ != "Not"}
        state = (state - deletes) | adds
    missing = [atom(g) for g in conjuncts(problem.goal) if atom(g) not in state]
    return f"goal not reached: {missing}" if missing else None


def check(domain_name: str, problem_name: str, tmp_path: Path, limit: int) -> None:
    domain = PDDL_DIR / domain_name / "domain.pddl"
    problem = PDDL_DIR / domain_name / f"{problem_name}.pddl"
    lines = solve(domain, problem, limit)
    assert lines, f"no plan for {problem_name}"
    error = simulate(lowered(domain, tmp_path), lowered(problem, tmp_path), lines)
    assert error is None, error


@pytest.mark.parametrize(("domain_name", "problem_name"), QUICK)
def test_quick_problems_have_valid_plans(domain_name, problem_name, tmp_path):
    check(domain_name, problem_name, tmp_path, limit=20)


@pytest.mark.slow
@pytest.mark.parametrize(("domain_name", "problem_name"), all_problems())
def test_all_problems_have_valid_plans(domain_name, problem_name, tmp_path):
    check(domain_name, problem_name, tmp_path, limit=60)


def test_simulator_rejects_a_broken_plan(tmp_path):
    domain = lowered(PDDL_DIR / "blocks" / "domain.pddl", tmp_path)
    problem = lowered(PDDL_DIR / "blocks" / "probBLOCKS-4-0.pddl", tmp_path)
    assert simulate(domain, problem, ["(stack a b)"]) is not None
    assert simulate(domain, problem, []) is not None
