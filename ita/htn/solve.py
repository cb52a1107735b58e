"""Total-order HDDL solved by the HTN engine (prolog/hddl.pl, prolog/htn.pl) in a child
``swipl``, which is killed (its whole process group) when it outlives the time limit.

The child reads both files, plans and writes one line: the plan and its decomposition
tree, the reason there is none, or ``error(File, Line, Message)`` for bad input, which
becomes an :class:`~ita.errors.InputError` naming file and line.
"""

from __future__ import annotations

import os
import shutil
import signal
import subprocess
import time
from dataclasses import dataclass
from enum import Enum
from pathlib import Path

from ita.errors import InputError, Location
from ita.htn.plan import Atom, Decomposition, HtnPlan
from ita.logic.terms import Term, TermValue, read_term
from ita.paths import resource_dir

#: the task the HDDL reader adds above a problem network that has :parameters
_TOP = "__top"
#: seconds the child may outlive its own time limit before it is killed
_GRACE = 1.0


class NoPlan(Enum):
    """Why the engine returned no plan."""

    EXHAUSTED = "exhausted"
    TIME_LIMIT = "time_limit"
    NODE_LIMIT = "node_limit"


@dataclass(frozen=True)
class SolveOutcome:
    """A plan, or why there is none; `seconds` the wall time of the child process
    (reading the files, planning and writing the answer)."""

    plan: HtnPlan | None
    no_plan: NoPlan | None
    seconds: float
    limit: float | int | None = None

    def explain(self) -> str:
        """Why there is no plan, in words."""
        if self.no_plan is NoPlan.EXHAUSTED:
            return "no plan exists: the search space was exhausted"
        if self.no_plan is NoPlan.TIME_LIMIT:
            return f"no plan within the time limit ({self.limit} s)"
        if self.no_plan is NoPlan.NODE_LIMIT:
            return f"no plan within the node limit ({self.limit} search nodes)"
        return "a plan was found"


def solve_hddl(domain: Path, problem: Path, time_limit: float = 60.0, max_nodes: int | None = None) -> SolveOutcome:
    """Solve the HDDL problem with the HTN engine in a child swipl.

    Raises :class:`~ita.errors.InputError` for a file that does not parse or uses an
    unsupported feature (file and line in the message), or when swipl is missing.
    """
    swipl = shutil.which("swipl")
    if swipl is None:
        raise InputError([(Location("swipl"), "SWI-Prolog (swipl) is not on PATH")])
    command = [swipl, "-q", "-f", "none", "--no-packs", "--no-tty", "-g", "hddl:solve_cli", "-t", "halt(4)",
               str(resource_dir("prolog") / "hddl.pl"), "--", str(domain), str(problem),
               repr(float(time_limit)), "inf" if max_nodes is None else str(int(max_nodes))]
    start = time.monotonic()
    child = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, stdin=subprocess.DEVNULL,
                             start_new_session=True)
    try:
        out, err = child.communicate(timeout=time_limit + _GRACE)
    except subprocess.TimeoutExpired:
        os.killpg(child.pid, signal.SIGKILL)
        child.communicate()
        return SolveOutcome(None, NoPlan.TIME_LIMIT, time.monotonic() - start, time_limit)
    except BaseException:
        os.killpg(child.pid, signal.SIGKILL)
        child.wait()
        raise
    seconds = time.monotonic() - start
    text = out.decode("utf-8", "replace").strip()
    if child.returncode != 0 or not text:
        last = err.decode("utf-8", "replace").strip().splitlines()[-1:] or [f"exit {child.returncode}"]
        raise InputError([(Location(str(problem)), f"the planner stopped without an answer: {last[0][:300]}")])
    try:
        answer = read_term(text.splitlines()[-1])
    except ValueError as exc:
        raise InputError([(Location(str(problem)), f"cannot read the planner's answer: {exc}")]) from None
    return outcome(answer, seconds, time_limit, max_nodes)


def outcome(answer: TermValue, seconds: float, time_limit: float, max_nodes: int | None) -> SolveOutcome:
    """The outcome of the child's answer term."""
    if not isinstance(answer, Term):
        raise InputError([(Location("swipl"), f"unexpected answer from the planner: {answer!r}")])
    if answer.name == "error":
        file, line, message = answer.args
        raise InputError([(Location(str(file), int(line)), str(message))])
    if answer.name == "no_plan":
        reason = answer.args[0]
        name = reason.name if isinstance(reason, Term) else str(reason)
        kind = NoPlan(name)
        limit = time_limit if kind is NoPlan.TIME_LIMIT else max_nodes
        return SolveOutcome(None, kind, seconds, limit)
    if answer.name == "plan":
        steps, tree, _ = answer.args
        return SolveOutcome(plan_of(steps, tree), None, seconds)
    raise InputError([(Location("swipl"), f"unexpected answer from the planner: {answer.name}")])


def atom_of(term: TermValue) -> Atom:
    """(name, arg, ...) of a ground task or action term."""
    if isinstance(term, Term):
        return (term.name, *(_symbol(a) for a in term.args))
    return (_symbol(term),)


def _symbol(value: TermValue) -> str:
    if isinstance(value, (str, int, float)):
        return str(value)
    if isinstance(value, Term):  # an (either ...) type never reaches a plan; say it plainly if it does
        return f"{value.name}({','.join(_symbol(a) for a in value.args)})"
    raise InputError([(Location("swipl"), f"a plan holds an unbound or odd value: {value!r}")])


def plan_of(steps: TermValue, tree: TermValue) -> HtnPlan:
    """The HtnPlan of the engine's steps (Id-Action) and tree(Roots, Nodes), renumbered
    for the IPC format: actions 0.. in order, compound tasks after them."""
    assert isinstance(steps, list) and isinstance(tree, Term)
    actions = tuple((int(s.args[0]), atom_of(s.args[1])) for s in steps)
    roots_term, nodes = tree.args
    roots = [int(r) for r in roots_term]
    decompositions: list[Decomposition] = []
    for node in nodes:
        if node.name == "decomposed":
            ident, task, method, children, _calls = node.args
            name = method.name if isinstance(method, Term) else str(method)
            decompositions.append(Decomposition(int(ident), atom_of(task), name, tuple(int(c) for c in children)))
    if len(roots) == 1 and decompositions and decompositions[0].id == roots[0] and decompositions[0].task == (_TOP,):
        roots = list(decompositions[0].children)
        decompositions = decompositions[1:]
    return HtnPlan(actions, tuple(roots), tuple(decompositions)).renumbered()
