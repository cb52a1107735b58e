"""`ita htn solve DOMAIN PROBLEM`: the HTN planner on total-order HDDL (IPC 2020).

Prints the plan in the IPC 2020 format (``==>``, the actions numbered, ``root``, one
decomposition line per compound task, ``<==``) and a comment line ``; N actions, T s``;
``--json`` prints the same as one JSON object.

Exit codes: 0 a plan was printed; 1 no plan within the limits (the reason on stderr:
the search space exhausted, the time or node limit); 2 bad input (one ``error:`` line
with file and line); 3 with --verify, a plan that the verifier rejects (a bug).
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import click

from ita.cli.common import FiniteFloatRange, reports_errors

NO_PLAN = 1
PLAN_INVALID = 3


@click.group()
def htn() -> None:
    """Hierarchical (HTN) planning on HDDL problems."""


@htn.command()
@click.argument("domain", type=click.Path(exists=True, dir_okay=False, path_type=Path))
@click.argument("problem", type=click.Path(exists=True, dir_okay=False, path_type=Path))
@click.option("--time-limit", type=FiniteFloatRange(min=0.001), default=60.0, show_default=True,
              help="Give up after this many seconds (wall clock, reading included); the planner runs "
                   "in a process of its own that is stopped then.")
@click.option("--max-nodes", type=click.IntRange(min=1), default=None,
              help="Give up after entering this many search nodes (default: no limit).")
@click.option("--json", "as_json", is_flag=True, help="Print the plan (or why there is none) as JSON.")
@click.option("--verify", is_flag=True, help="Check the plan with the independent verifier before printing it.")
@reports_errors
def solve(domain: Path, problem: Path, time_limit: float, max_nodes: int | None, as_json: bool,
          verify: bool) -> None:
    """Solve PROBLEM of DOMAIN (total-order HDDL) and print the plan in the IPC 2020 format.

    Supported: typing (with either), negative, equality, quantified and disjunctive
    preconditions, method preconditions, ordered subtasks or a total :ordering, a
    state goal.  Refused with file and line: conditional or quantified effects,
    partial order, numbers and costs.
    """
    from ita.htn import format_ipc, solve_hddl
    from ita.htn.verify import verify_files

    outcome = solve_hddl(domain.resolve(), problem.resolve(), time_limit, max_nodes)
    if outcome.plan is None:
        if as_json:
            click.echo(json.dumps({"status": "no_plan", "reason": outcome.no_plan.value if outcome.no_plan else None,
                                   "message": outcome.explain(), "seconds": round(outcome.seconds, 3)}))
        click.echo(f"; no plan: {outcome.explain()}, {outcome.seconds:.3f} s", err=True)
        sys.exit(NO_PLAN)
    text = format_ipc(outcome.plan)
    if verify:
        problems = verify_files(domain, problem, text)
        if problems:
            click.echo(f"error: the planner's plan does not verify: {problems[0]}", err=True)
            sys.exit(PLAN_INVALID)
    if as_json:
        click.echo(json.dumps({"status": "plan", "seconds": round(outcome.seconds, 3), **outcome.plan.to_dict()}))
        return
    click.echo(text, nl=False)
    click.echo(f"; {len(outcome.plan.actions)} actions, {outcome.seconds:.3f} s")
