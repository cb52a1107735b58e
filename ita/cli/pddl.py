"""`ita pddl solve DOMAIN PROBLEM`: the Task Planner on a STRIPS PDDL problem.

Prints the plan in the IPC plan format, one ``(action arg ...)`` per line, then a
comment line ``; length N, T s``, so any plan validator (VAL, pyperplan) can check it.

Exit codes: 0 a plan was printed; 1 no plan (the reason on stderr: search exhausted,
effort bound, time limit); 2 bad input (a file that does not parse, with file:line
where it can be found).
"""

from __future__ import annotations

import re
import sys
import time
from pathlib import Path

import click

from ita.cli.common import FiniteFloatRange, reports_errors
from ita.errors import InputError, Location

NO_PLAN = 1


def unbalanced_line(text: str) -> tuple[int, str] | None:
    """(line, message) of the first parenthesis that does not balance, or None.

    Comments (``;`` to the end of the line) are skipped, as the PDDL reader does.
    """
    open_lines: list[int] = []
    for number, line in enumerate(text.splitlines(), start=1):
        for char in line.split(";", 1)[0]:
            if char == "(":
                open_lines.append(number)
            elif char == ")":
                if not open_lines:
                    return number, "unexpected ')'"
                open_lines.pop()
    if open_lines:
        return open_lines[-1], "'(' is never closed"
    return None


def token_line(text: str, token: str) -> int:
    """The first line where `token` appears as a word (case-insensitive), else 0."""
    pattern = re.compile(rf"(?<![\w?-]){re.escape(token)}(?![\w-])", re.IGNORECASE)
    for number, line in enumerate(text.splitlines(), start=1):
        if pattern.search(line.split(";", 1)[0]):
            return number
    return 0


def locate(domain: Path, problem: Path, message: str) -> list[tuple[Location, str]]:
    """Where in the two files the reader's error `message` points, as well as can be said."""
    for path in (domain, problem):
        found = unbalanced_line(path.read_text(encoding="utf-8", errors="replace"))
        if found:
            return [(Location(str(path), found[0]), f"unbalanced parentheses: {found[1]}")]
    for path in (domain, problem):
        if str(path) in message:  # e.g. "no (define (domain ...)) in FILE"
            return [(Location(str(path)), message)]
    # the offending symbol is usually the last quoted or plain word of the message
    words = re.findall(r"[`']?([A-Za-z?][\w?:-]*)[`']?", message)
    for word in reversed(words):
        for path in (domain, problem):
            line = token_line(path.read_text(encoding="utf-8", errors="replace"), word)
            if line:
                return [(Location(str(path), line), message)]
    return [(Location(str(domain)), message)]


def _ipc_line(action: object) -> str:
    from ita.logic.terms import Term

    if isinstance(action, Term):
        return "(" + " ".join([action.name, *(str(a) for a in action.args)]) + ")"
    return f"({action})"


@click.group()
def pddl() -> None:
    """Solve STRIPS PDDL problems with the ITA Task Planner."""


@pddl.command()
@click.argument("domain", type=click.Path(exists=True, dir_okay=False, path_type=Path))
@click.argument("problem", type=click.Path(exists=True, dir_okay=False, path_type=Path))
@click.option("--time-limit", type=FiniteFloatRange(min=0.001), default=60.0, show_default=True,
              help="Give up after this many seconds (wall clock, reading and grounding included); "
                   "the solver runs in a process of its own that is stopped then.")
@click.option("--max-depth", type=click.IntRange(min=1), default=60, show_default=True,
              help="Depth bound of the planner's goal stack: a problem whose plan needs a deeper "
                   "stack (e.g. a long chain of steps) reports search_exhausted; raise it.")
@click.option("--max-effort", type=click.IntRange(min=1), default=200_000, show_default=True,
              help="Establishers the planner tries before giving up.")
@reports_errors
def solve(domain: Path, problem: Path, time_limit: float, max_depth: int, max_effort: int) -> None:
    """Solve PROBLEM of DOMAIN and print the plan in the IPC format.

    The problem is checked against its domain first (the domain name, a :goal, the
    predicates declared, :typing for types, STRIPS effects and preconditions).  The
    search is bounded by --max-depth and --max-effort; "no plan" says which bound held.
    """
    domain, problem = domain.resolve(), problem.resolve()
    start = time.monotonic()
    result = _solve_in_child(domain, problem, time_limit, max_depth, max_effort)
    seconds = time.monotonic() - start
    from ita.logic.terms import Term

    if isinstance(result, Term) and result.name == "error":
        raise InputError(locate(domain, problem, str(result.args[0])))
    if not isinstance(result, Term) or result.name != "plan":
        reason = result.args[0] if isinstance(result, Term) else result
        click.echo(f"; no plan: {_no_plan_reason(reason, max_depth, max_effort)}, {seconds:.3f} s", err=True)
        sys.exit(NO_PLAN)
    actions = result.args[0]
    for action in actions:
        click.echo(_ipc_line(action))
    click.echo(f"; length {len(actions)}, {seconds:.3f} s")


def _no_plan_reason(reason: object, max_depth: int, max_effort: int) -> str:
    """The planner's reason for no plan, with the bound that held said in words."""
    from ita.logic.terms import Term
    from ita.planning.operation import format_term

    text = format_term(reason)
    if isinstance(reason, Term) and reason.name == "search_exhausted":
        return (f"{text}: no plan within the search bounds (goal-stack depth {max_depth}, "
                f"--max-depth; {max_effort} establishers, --max-effort); a plan that needs a deeper "
                f"goal stack is not found: raise --max-depth")
    if isinstance(reason, Term) and reason.name == "effort_exhausted":
        return f"{text}: the effort bound ({max_effort} establishers, --max-effort) was reached"
    return text


def _solve_in_child(domain: Path, problem: Path, time_limit: float, max_depth: int, max_effort: int):
    """pddl:solve_cli in a child swipl; the decoded result term.  The child is killed (its
    whole process group) when it outlives the time limit by a second."""
    import os
    import shutil
    import signal
    import subprocess

    from ita.logic.terms import Term, read_term
    from ita.paths import resource_dir

    swipl = shutil.which("swipl")
    if swipl is None:
        raise InputError([(Location("swipl"), "SWI-Prolog (swipl) is not on PATH")])
    command = [swipl, "-q", "-f", "none", "--no-packs", "--no-tty", "-g", "pddl:solve_cli", "-t", "halt(4)",
               str(resource_dir("prolog") / "pddl.pl"), "--", str(domain), str(problem),
               repr(float(time_limit)), str(int(max_depth)), str(int(max_effort))]
    child = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, stdin=subprocess.DEVNULL,
                             start_new_session=True)
    try:
        out, err = child.communicate(timeout=time_limit + 1.0)
    except subprocess.TimeoutExpired:
        os.killpg(child.pid, signal.SIGKILL)
        child.communicate()
        return Term("no_plan", (Term("time_limit_exceeded", (float(time_limit),)),))
    except BaseException:
        os.killpg(child.pid, signal.SIGKILL)
        child.wait()
        raise
    text = out.decode("utf-8", "replace").strip()
    if child.returncode != 0 or not text:
        last = err.decode("utf-8", "replace").strip().splitlines()[-1:] or [f"exit {child.returncode}"]
        raise InputError([(Location(str(problem)), f"the planner stopped without an answer: {last[0][:300]}")])
    try:
        return read_term(text.splitlines()[-1])
    except ValueError as exc:
        raise InputError([(Location(str(problem)), f"cannot read the planner's answer: {exc}")]) from None
