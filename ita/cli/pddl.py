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

from ita.cli.common import reports_errors
from ita.errors import InputError, Location, PrologError

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
@click.option("--time-limit", type=click.FloatRange(min=0.001), default=60.0, show_default=True,
              help="Give up after this many seconds.")
@reports_errors
def solve(domain: Path, problem: Path, time_limit: float) -> None:
    """Solve PROBLEM of DOMAIN and print the plan in the IPC format."""
    from ita.logic.bridge import KnowledgeBase
    from ita.logic.terms import Term, Var

    kb = KnowledgeBase()
    domain, problem = domain.resolve(), problem.resolve()
    start = time.process_time()
    try:
        solution = kb.once("pddl", "solve_pddl", str(domain), str(problem),
                           [Term("time_limit", (float(time_limit),))], Var("R"))
    except PrologError as exc:
        raise InputError(locate(domain, problem, exc.message)) from None
    seconds = time.process_time() - start
    result = solution["R"] if solution else None
    if not isinstance(result, Term) or result.name != "plan":
        reason = result.args[0] if isinstance(result, Term) else "the planner failed"
        from ita.planning.operation import format_term

        click.echo(f"; no plan: {format_term(reason)}, {seconds:.3f} s", err=True)
        sys.exit(NO_PLAN)
    actions = result.args[0]
    for action in actions:
        click.echo(_ipc_line(action))
    click.echo(f"; length {len(actions)}, {seconds:.3f} s")
