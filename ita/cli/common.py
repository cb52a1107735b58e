"""Options and error handling shared by the CLI's commands."""

from __future__ import annotations

import functools
import math
import sys
from pathlib import Path
from typing import Any, Callable, ParamSpec, TypeVar

import click

from ita.errors import ItaError
from ita.seeds import SEED_MAX, SEED_MIN

F = TypeVar("F", bound=Callable[..., Any])
P = ParamSpec("P")
R = TypeVar("R")

part_option = click.option(
    "--part",
    "part_dir",
    type=click.Path(path_type=Path, file_okay=False),
    default=None,
    help="Part directory (a mesh and specs.csv). Default: the built-in bulkhead.",
)

arm_option = click.option(
    "--arm",
    default=None,
    metavar="NAME",
    help="The arm of the cell that works, alone (default: its first; a cell's second arm is its [robot_b] "
         "table). The second has its own sequence plan, MKB and MACROPs, prepared on first use.",
)


def reports_errors(func: Callable[P, R]) -> Callable[P, R]:
    """Turn the project's own errors into a message on stderr and their exit code."""

    @functools.wraps(func)
    def wrapper(*args: P.args, **kwargs: P.kwargs) -> R:
        try:
            return func(*args, **kwargs)
        except ItaError as exc:
            for line in str(exc).splitlines() or [type(exc).__name__]:
                click.echo(f"error: {line}", err=True)
            sys.exit(exc.exit_code)

    return wrapper


class FiniteFloatRange(click.FloatRange):
    """click.FloatRange that also refuses NaN and the infinities (NaN passes every bound
    of a FloatRange, since it compares false with everything)."""

    name = "finite float range"

    def convert(self, value: Any, param: click.Parameter | None, ctx: click.Context | None) -> Any:
        number = super().convert(value, param, ctx)
        if not math.isfinite(number):
            self.fail(f"{number} is not a finite number in the range {self._describe_range()}.", param, ctx)
        return number


#: every --seed takes this range (ita.seeds)
SEED_TYPE = click.IntRange(SEED_MIN, SEED_MAX)


def seed_option(default: int | None = 0, help: str = "Seed of the simulated workcell.",
                required: bool = False) -> Callable[[F], F]:
    """A --seed option: an integer from 0 to 2**63 - 1 (exit 2 with the range otherwise)."""
    return click.option("--seed", type=SEED_TYPE, default=default, required=required,
                        show_default=default is not None and not required, help=help)


def check_job(job: str) -> None:
    """Refuse (usage error, exit 2) a job that kb/tasks.pl does not have, naming those it has."""
    from ita.logic.bridge import KnowledgeBase
    from ita.toplevel import jobs

    known = [name for name, _ in jobs(KnowledgeBase())]
    if job not in known:
        raise click.BadParameter(f"no job {job!r} in kb/tasks.pl (the jobs: {', '.join(known)})",
                                 param_hint="--task")
