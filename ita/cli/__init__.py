"""The `ita` command line: a click group whose subcommands load lazily.

Each subcommand group lives in its own module of this package and is imported only when
used, so `ita --help` is fast and a heavy dependency is paid for only by the command that
needs it.  The registry below is explicit: add a line to add a command group.
"""

from __future__ import annotations

import contextlib
import difflib
import importlib
import os
import warnings
from collections.abc import Callable
from typing import Any

import click

# name -> "module:attribute" of a click command or group
COMMANDS: dict[str, str] = {
    "kb": "ita.cli.kb:kb",
    "part": "ita.cli.part:part",
    "spec": "ita.cli.spec:spec",
    "prepare": "ita.cli.prepare:prepare",
    "sequence": "ita.cli.sequence:sequence",
    "plan": "ita.cli.plan:plan",
    "macrop": "ita.cli.plan:macrop",
    "pddl": "ita.cli.pddl:pddl",
    "htn": "ita.cli.htn:htn",
    "path": "ita.cli.path:path",
    "runs": "ita.cli.runs:runs",
    "results": "ita.cli.results:results",
    "report": "ita.cli.report:report",
    "inspect": "ita.cli.inspect:inspect",
    "tasks": "ita.cli.inspect:tasks",
    "continue": "ita.cli.inspect:continue_",
    "monitor": "ita.cli.inspect:monitor",
    "measure": "ita.cli.measure:measure",
    "diagnosis": "ita.cli.diagnosis:diagnosis",
    "serve": "ita.cli.serve:serve",
    "campaign": "ita.cli.campaign:campaign",
    "spc": "ita.cli.spc:spc",
}

#: BLAS threads for a command's process unless the user's environment says otherwise.  ITA's
#: matrices are small; a second BLAS thread spins on the second core between calls (about 13 s
#: of a whole run's 80 s of CPU), where the SLRA's ray casting runs half of each frame.
BLAS_THREADS = "1"


class LazyGroup(click.Group):
    """A click group that imports its subcommands on first use."""

    def list_commands(self, ctx: click.Context) -> list[str]:
        return sorted(set(super().list_commands(ctx)) | set(COMMANDS))

    def get_command(self, ctx: click.Context, cmd_name: str) -> click.Command | None:
        if cmd_name in COMMANDS:
            os.environ.setdefault("OPENBLAS_NUM_THREADS", BLAS_THREADS)   # read when numpy loads: before it
            module_name, attr = COMMANDS[cmd_name].split(":")
            return getattr(importlib.import_module(module_name), attr)
        return super().get_command(ctx, cmd_name)

    def make_context(self, info_name: str | None, args: list[str], parent: click.Context | None = None,
                     **extra) -> click.Context:
        """As click's, after refusing arguments that are not UTF-8 text (exit 2)."""
        for i, arg in enumerate(args, 1):
            if "\x00" in arg:
                click.echo(f"error: argument {i} contains a NUL character", err=True)
                raise SystemExit(2)
            try:
                arg.encode("utf-8")
            except UnicodeEncodeError as exc:
                shown = arg.encode("utf-8", "surrogateescape")[:60]
                click.echo(f"error: argument {i} ({shown!r}) is not valid UTF-8 text "
                           f"(byte {arg[exc.start].encode('utf-8', 'surrogateescape')!r} at position {exc.start})",
                           err=True)
                raise SystemExit(2)
        return super().make_context(info_name, args, parent, **extra)

    def invoke(self, ctx: click.Context):
        """As click's; an operating-system or database error that a command did not turn
        into a message is reported with the file it concerns (exit 2), not a traceback."""
        import sqlite3

        try:
            with warnings.catch_warnings():
                warnings.showwarning = _one_line_warnings(warnings.showwarning)
                return super().invoke(ctx)
        except BrokenPipeError:  # the reader went away (`ita ... | head`): stop quietly
            import sys

            with contextlib.suppress(OSError):
                os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
            raise SystemExit(1) from None
        except OSError as exc:
            where = f"{exc.filename}: " if exc.filename else ""
            click.echo(f"error: {where}{exc.strerror or exc}", err=True)
            raise SystemExit(2) from None
        except sqlite3.DatabaseError as exc:
            click.echo(f"error: the run archive cannot be read (damaged or not an ITA archive): {exc}", err=True)
            raise SystemExit(2) from None

    def resolve_command(self, ctx: click.Context, args: list[str]) -> tuple:
        """As click's, with "did you mean ...?" for a mistyped command."""
        name = args[0] if args else ""
        if name and not name.startswith("-") and self.get_command(ctx, name) is None:
            close = difflib.get_close_matches(name, self.list_commands(ctx), n=3, cutoff=0.6)
            hint = f" Did you mean {' or '.join(repr(c) for c in close)}?" if close else ""
            ctx.fail(f"No such command {name!r}.{hint} (ita --help lists them)")
        return super().resolve_command(ctx, args)


def _one_line_warnings(show: Callable[..., None]) -> Callable[..., None]:
    """A warnings.showwarning that shows ITA's own warnings as one line, `warning: ...`,
    and hands any other to `show` (how Python showed them before)."""
    from ita.errors import ItaWarning

    def shown(message: Warning | str, category: type[Warning], filename: str, lineno: int,
              file: Any = None, line: str | None = None) -> None:
        if issubclass(category, ItaWarning):
            click.echo(f"warning: {message}", err=True)
        else:
            show(message, category, filename, lineno, file, line)

    return shown


@click.group(cls=LazyGroup, context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(package_name="ita")
def main() -> None:
    """ITA: plan and run the autonomous dimensional inspection of a machined bulkhead.

    Every command takes --part DIR to work on another part (a directory with a mesh and a
    specs.csv); the built-in bulkhead is the default.
    """
