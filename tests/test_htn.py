"""The HTN planner on HDDL: `ita htn solve`, its plans checked by the independent
verifier (ita/htn/verify.py) on the IPC 2020 instances of ../shared/hddl/, a verifier
that rejects broken plans, bad HDDL as one `error:` line with file and line, and the
engine called in-process through the bridge with an attached procedure answered by
Python."""

from __future__ import annotations

import json
import re
import uuid
from dataclasses import replace
from pathlib import Path
from typing import Any

import pytest
from click.testing import CliRunner

from ita.cli import main
from ita.htn import (
    Decomposition,
    HtnPlan,
    format_ipc,
    parse_ipc,
    solve_hddl,
    verify_plan,
)
from ita.htn.hddl import read_domain, read_problem
from ita.htn.solve import NoPlan
from ita.htn.verify import verify_files
from ita.logic.attached import nondet
from ita.logic.terms import Term, Var

REPO = Path(__file__).resolve().parent.parent
SHARED = REPO.parent / "shared" / "hddl"
#: problem files at least this large are left to the slow suite
LARGE = 4000


def _instances() -> list[Any]:
    if not SHARED.is_dir():
        return [pytest.param(None, None, marks=pytest.mark.skip(reason=f"{SHARED} is absent"))]
    found = []
    for domain in sorted(SHARED.glob("*/domain.hddl")):
        for problem in sorted(domain.parent.glob("*.hddl")):
            if problem.name == "domain.hddl":
                continue
            marks = [pytest.mark.slow] if problem.stat().st_size >= LARGE else []
            found.append(pytest.param(domain, problem, marks=marks, id=f"{domain.parent.name}/{problem.stem}"))
    return found


@pytest.mark.parametrize("domain, problem", _instances())
def test_ipc_instance_solved_and_verified(domain: Path, problem: Path) -> None:
    outcome = solve_hddl(domain, problem, time_limit=60)
    assert outcome.plan is not None, outcome.explain()
    assert verify_files(domain, problem, format_ipc(outcome.plan)) == []


# -- a small domain of our own, for the CLI and the verifier --------------------------

DOMAIN = """(define (domain deliver)
  (:requirements :typing :negative-preconditions :hierarchy :method-preconditions)
  (:types place truck parcel)
  (:predicates (at ?x - truck ?p - place) (road ?a ?b - place) (in ?c - parcel ?t - truck)
               (lies ?c - parcel ?p - place))
  (:task deliver :parameters (?c - parcel ?p - place))
  (:task get_to :parameters (?t - truck ?p - place))
  (:method m_deliver
    :parameters (?c - parcel ?from ?to - place ?t - truck)
    :task (deliver ?c ?to)
    :precondition (lies ?c ?from)
    :ordered-subtasks (and (get_to ?t ?from) (load ?t ?c ?from) (get_to ?t ?to) (unload ?t ?c ?to)))
  (:method m_here
    :parameters (?t - truck ?p - place)
    :task (get_to ?t ?p)
    :precondition (at ?t ?p)
    :ordered-subtasks (and))
  (:method m_drive
    :parameters (?t - truck ?a ?b - place)
    :task (get_to ?t ?b)
    :precondition (and (at ?t ?a) (road ?a ?b))
    :ordered-subtasks (and (drive ?t ?a ?b)))
  (:method m_via
    :parameters (?t - truck ?m ?b - place)
    :task (get_to ?t ?b)
    :ordered-subtasks (and (get_to ?t ?m) (drive ?t ?m ?b)))
  (:action drive :parameters (?t - truck ?a ?b - place)
    :precondition (and (at ?t ?a) (road ?a ?b))
    :effect (and (not (at ?t ?a)) (at ?t ?b)))
  (:action load :parameters (?t - truck ?c - parcel ?p - place)
    :precondition (and (at ?t ?p) (lies ?c ?p))
    :effect (and (not (lies ?c ?p)) (in ?c ?t)))
  (:action unload :parameters (?t - truck ?c - parcel ?p - place)
    :precondition (and (at ?t ?p) (in ?c ?t))
    :effect (and (not (in ?c ?t)) (lies ?c ?p))))
"""

PROBLEM = """(define (problem two) (:domain deliver)
  (:objects a b c - place t1 - truck p1 p2 - parcel)
  (:htn :ordered-subtasks (and (deliver p1 c) (deliver p2 a)))
  (:init (at t1 a) (road a b) (road b a) (road b c) (road c b) (lies p1 b) (lies p2 c))
  (:goal (and (lies p1 c) (lies p2 a))))
"""


@pytest.fixture
def files(tmp_path: Path) -> tuple[Path, Path]:
    d, p = tmp_path / "domain.hddl", tmp_path / "problem.hddl"
    d.write_text(DOMAIN)
    p.write_text(PROBLEM)
    return d, p


def solve(*args: object):
    return CliRunner().invoke(main, ["htn", "solve", *map(str, args)])


@pytest.fixture
def good_plan(files: tuple[Path, Path]) -> HtnPlan:
    outcome = solve_hddl(*files, time_limit=30)
    assert outcome.plan is not None
    return outcome.plan


def test_cli_prints_the_ipc_format(files):
    out = solve(*files, "--verify")
    assert out.exit_code == 0, out.stderr
    lines = out.stdout.splitlines()
    assert lines[0] == "==>" and lines[-2] == "<==" and lines[-1].startswith("; ")
    assert re.fullmatch(r"root \d+ \d+", next(line for line in lines if line.startswith("root")))
    assert "0 drive t1 a b" in lines
    assert any(re.fullmatch(r"\d+ deliver p1 c -> m_deliver( \d+){4}", line) for line in lines)
    assert any(re.fullmatch(r"\d+ get_to t1 c -> m_here", line) for line in lines)  # p2 is where p1 went
    assert any(re.fullmatch(r"\d+ get_to t1 a -> m_via \d+ 6", line) for line in lines)


def test_cli_json(files):
    out = solve(*files, "--json")
    assert out.exit_code == 0, out.stderr
    data = json.loads(out.stdout)
    assert data["status"] == "plan" and data["actions"][0] == {"id": 0, "name": "drive", "args": ["t1", "a", "b"]}
    assert len(data["root"]) == 2


def test_no_plan_is_exit_1(files, tmp_path):
    d, _ = files
    p = tmp_path / "stuck.hddl"
    p.write_text(PROBLEM.replace("(road a b) (road b a)", ""))
    out = solve(d, p, "--time-limit", "2")
    assert out.exit_code == 1
    assert "; no plan: no plan within the time limit (2.0 s)" in out.stderr  # m_via recurses without end


def test_exhausted_is_exit_1(files, tmp_path):
    d = tmp_path / "nonrecursive.hddl"
    d.write_text(DOMAIN.replace("(get_to ?t ?m) (drive ?t ?m ?b)", "(drive ?t ?m ?b)"))
    p = tmp_path / "stuck.hddl"
    p.write_text(PROBLEM.replace("(road a b) (road b a)", ""))
    out = solve(d, p)
    assert out.exit_code == 1 and "search space was exhausted" in out.stderr


@pytest.mark.parametrize("old, new, line, words", [
    ("(:types place truck parcel)", "(:types place truck parcel", 3, "unbalanced parentheses"),
    (":ordered-subtasks (and (get_to ?t ?from)", ":subtasks (and (get_to ?t ?from)", 8,
     "partial order is not supported"),
    ("(and (not (lies ?c ?p)) (in ?c ?t))", "(when (lies ?c ?p) (in ?c ?t))", 32, "conditional effects (when)"),
    ("(road ?a ?b))\n    :effect", "(street ?a ?b))\n    :effect", 28, "street is not declared"),
    (":method-preconditions", ":durative-actions", 2, "requirement :durative-actions is not supported"),
])
def test_bad_hddl_is_one_error_line_with_file_and_line(files, tmp_path, old, new, line, words):
    _, p = files
    bad = tmp_path / "bad.hddl"
    assert old in DOMAIN
    bad.write_text(DOMAIN.replace(old, new, 1))
    out = solve(bad, p)
    assert out.exit_code == 2
    errors = out.stderr.strip().splitlines()
    assert len(errors) == 1 and errors[0].startswith(f"error: {bad}:{line}: "), out.stderr
    assert words in errors[0]


def test_missing_file_is_exit_2(files, tmp_path):
    d, _ = files
    out = solve(d, tmp_path / "nope.hddl")
    assert out.exit_code == 2


# -- the verifier rejects broken plans ------------------------------------------------

@pytest.fixture
def checker(files):
    domain, problem = read_domain(files[0]), read_problem(files[1])
    return lambda plan: verify_plan(domain, problem, plan)


def test_the_good_plan_verifies(good_plan, checker):
    assert checker(good_plan) == []
    assert checker(parse_ipc(format_ipc(good_plan))) == []


def test_rejects_a_dropped_action(good_plan, checker):
    dropped, _ = good_plan.actions[2]
    broken = replace(
        good_plan,
        actions=tuple(a for a in good_plan.actions if a[0] != dropped),
        decompositions=tuple(replace(d, children=tuple(c for c in d.children if c != dropped))
                             for d in good_plan.decompositions))
    assert checker(broken)


def test_rejects_an_action_missing_from_the_tree(good_plan, checker):
    last, _ = good_plan.actions[-1]
    broken = replace(good_plan, decompositions=tuple(
        replace(d, children=tuple(c for c in d.children if c != last)) for d in good_plan.decompositions))
    problems = checker(broken)
    assert problems and ("subtasks" in problems[0] or "never reached" in problems[0])


def test_rejects_a_wrong_method(good_plan, checker):
    first = next(d for d in good_plan.decompositions if d.method == "m_drive")
    broken = replace(good_plan, decompositions=tuple(
        replace(d, method="m_via") if d is first else d for d in good_plan.decompositions))
    assert checker(broken)


def test_rejects_a_method_whose_precondition_fails(good_plan, checker):
    # m_here says "already there": wrong where the truck still has to drive
    target = next(d for d in good_plan.decompositions if d.method == "m_drive")
    actions = tuple(a for a in good_plan.actions if a[0] not in target.children)
    broken = replace(good_plan, actions=actions, decompositions=tuple(
        replace(d, method="m_here", children=()) if d is target else d for d in good_plan.decompositions))
    problems = checker(broken)
    assert problems and "precondition" in problems[0]


def test_rejects_swapped_actions(good_plan, checker):
    actions = list(good_plan.actions)
    actions[0], actions[1] = actions[1], actions[0]
    assert checker(replace(good_plan, actions=tuple(actions)))


def test_rejects_swapped_subtasks(good_plan, checker):
    target = next(d for d in good_plan.decompositions if d.method == "m_deliver")
    children = list(target.children)
    children[1], children[3] = children[3], children[1]
    broken = replace(good_plan, decompositions=tuple(
        replace(d, children=tuple(children)) if d is target else d for d in good_plan.decompositions))
    assert checker(broken)


def test_rejects_swapped_roots(good_plan, checker):
    assert checker(replace(good_plan, roots=tuple(reversed(good_plan.roots))))


def test_rejects_an_unsatisfied_goal(files, good_plan):
    d, p = files
    other = p.parent / "goal.hddl"
    other.write_text(PROBLEM.replace("(lies p2 a))", "(lies p2 b))"))
    assert verify_files(d, other, format_ipc(good_plan)) == ["the goal does not hold in the final state"]


def test_rejects_an_unreached_decomposition_line(good_plan, checker):
    first = good_plan.decompositions[0]
    broken = replace(good_plan, decompositions=good_plan.decompositions + (
        Decomposition(10_000, first.task, first.method, first.children),))
    problems = checker(broken)
    assert problems and "never reached" in problems[0]


def test_ipc_text_round_trip(good_plan):
    assert parse_ipc("noise before\n" + format_ipc(good_plan) + "noise after\n") == good_plan


# -- the engine in-process, through the bridge ------------------------------------------

#: a domain given as Prolog facts: the tool for a job comes from Python (an attached procedure)
_OPERATORS = [
    Term("operator", (Term("pick", (Var("T"),)), [Term("on_rack", (Var("T"),))], [Term("on_rack", (Var("T"),))],
                      [Term("held", (Var("T"),))])),
    Term("operator", (Term("use", (Var("T"), Var("J"))), [Term("held", (Var("T"),))], [], [Term("done", (Var("J"),))])),
]
_METHODS = [
    Term("method", ("by_tool", Term("do", (Var("J"),)),
                    [Term("call", (Term(":", ("py_bridge", Term("attached", ("tool_for", [Var("J")], Var("T"))))),)),
                     Term("not", (Term("broken", (Var("T"),)),))],
                    [Term("pick", (Var("T"),)), Term("use", (Var("T"), Var("J")))])),
]


def test_in_process_plan_with_an_attached_procedure_and_replan(knowledge_base):
    kb = knowledge_base
    module = f"htn_test_{uuid.uuid4().hex}"  # the engine is one per process: a module of our own
    for fact in _OPERATORS + _METHODS:
        kb.call("system", "assertz", Term(":", (module, fact)))
    asked: list[str] = []

    def tool_for(job: str) -> list[str]:
        asked.append(job)
        return {"drill": ["d1", "d2"], "probe": ["p1"]}[job]  # d1 is broken: the planner backtracks

    state = [Term("on_rack", ("d1",)), Term("on_rack", ("d2",)), Term("on_rack", ("p1",)), Term("broken", ("d1",))]
    tasks = [Term("do", ("drill",)), Term("do", ("probe",))]
    with kb.attached({"tool_for": nondet(tool_for)}):
        result = kb.one("htn", "htn_plan", module, state, tasks, [], Var("R"))["R"]
        assert result.name == "plan"
        steps, tree, final = result.args
        actions = [s.args[1] for s in steps]
        assert actions == [Term("pick", ("d2",)), Term("use", ("d2", "drill")), Term("pick", ("p1",)),
                           Term("use", ("p1", "probe"))]
        assert "drill" in asked and "probe" in asked
        calls = [n.args[4] for n in tree.args[1] if n.name == "decomposed"]
        assert calls[0] == [Term(":", ("py_bridge", Term("attached", ("tool_for", ["drill"], "d2"))))]
        # after the first two actions: what remains, planned again from the state then
        remaining = kb.one("htn", "htn_remaining", tree, 2, Var("N"))["N"]
        assert [e.args[1] for e in remaining] == [Term("do", ("probe",))]
        state2 = [Term("on_rack", ("p1",)), Term("held", ("d2",))]
        again = kb.one("htn", "htn_replan", module, state2, remaining, [], Var("R"))["R"]
        assert [s.args[1] for s in again.args[0]] == [Term("pick", ("p1",)), Term("use", ("p1", "probe"))]


def test_no_plan_outcome_says_why():
    from ita.htn.solve import SolveOutcome

    assert "exhausted" in SolveOutcome(None, NoPlan.EXHAUSTED, 0.1).explain()
    assert "5 s" in SolveOutcome(None, NoPlan.TIME_LIMIT, 5.0, 5).explain()
