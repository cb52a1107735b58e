"""Options and error handling shared by the CLI's commands."""

from __future__ import annotations

import functools
import sys
from pathlib import Path
from typing import Any, Callable, TypeVar

import click

from ita.errors import ItaError

F = TypeVar("F", bound=Callable[..., Any])

part_option = click.option(
    "--part",
    "part_dir",
    type=click.Path(path_type=Path, file_okay=False),
    default=None,
    help="Part directory (a mesh and specs.csv). Default: the built-in bulkhead.",
)


def reports_errors(func: F) -> F:
    """Turn the project's own errors into a message on stderr and their exit code."""

    @functools.wraps(func)
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        try:
            return func(*args, **kwargs)
        except ItaError as exc:
            for line in str(exc).splitlines() or [type(exc).__name__]:
                click.echo(f"error: {line}", err=True)
            sys.exit(exc.exit_code)

    return wrapper  # type: ignore[return-value]
