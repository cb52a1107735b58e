"""`ita kb`: look into the knowledge bases: query, shell, check, list, why.

Exit codes: 0 success (a query or `why` with a solution, a clean `check`); 1 a goal
with no solution, or `check` found problems; 2 a refused goal (syntax error, unsafe),
a goal stopped by its time, inference, memory or CPU limit, a goal that raised an error,
or a knowledge base that does not load.

`query`, `why` and each goal of `shell` run in a child process behind the operating
system's walls (ita/logic/sandbox.py, ita/logic/confine.py: bubblewrap's namespaces, a
seccomp filter, rlimits); this process never runs a goal a person typed, and refuses to
run one where the walls cannot be raised.
"""

from __future__ import annotations

import json
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Callable, TextIO

import click

from ita.cli.common import FiniteFloatRange, reports_errors
from ita.errors import ItaError

if TYPE_CHECKING:
    from ita.logic.bridge import KnowledgeBase
    from ita.logic.confine import Jail
    from ita.logic.model import ProofNode, QueryResult
    from ita.logic.sandbox import SandboxFiles, SandboxLimits

NO_SOLUTION = 1
SHELL_HELP = """\
Type a Prolog goal, e.g.  type(X, us_tool)  or  available(T), weight(T, W)
Goals run read-only: the sandbox refuses files, processes, halt, messages, threads and
changes to the knowledge bases; each goal runs in a process of its own, confined by the
operating system (no file but Prolog's and the knowledge bases, no network, no other
process), under a time, an inference, a CPU and a memory limit (nothing it does reaches
the next goal).
Ctrl-C stops the current goal, not the shell.
  why GOAL   show the proof tree of GOAL's first solution
  help       this text
  quit       leave the shell (also exit, or end of input)"""


def _limit_options(func: Callable) -> Callable:
    func = click.option("--time-limit", type=FiniteFloatRange(min=0.001), default=10.0,
                        show_default=True,
                        help="Stop the goal after this many seconds of wall clock (its process is "
                             "killed; it also has 1 GiB of memory and no file writes).")(func)
    func = click.option("--inference-limit", type=click.IntRange(min=1), default=10_000_000,
                        show_default=True, help="Stop the goal after this many inferences.")(func)
    return func


def _knowledge_base() -> "KnowledgeBase":
    from ita.logic.bridge import KnowledgeBase  # starts SWI-Prolog: only when needed

    return KnowledgeBase()


@dataclass(frozen=True)
class UserGoals:
    """Runs user goals in the sandbox's child processes (ita.logic.sandbox), behind the
    walls found once (a shell's goals share them)."""

    files: "SandboxFiles"
    limits: "SandboxLimits"
    jail: "Jail"

    @staticmethod
    def make(time_limit: float, inference_limit: int) -> "UserGoals":
        """Raises Unconfinable (an ItaError) where the walls cannot be raised."""
        from ita.logic.sandbox import SandboxFiles, SandboxLimits

        files = SandboxFiles.of()
        return UserGoals(files, SandboxLimits(float(time_limit), int(inference_limit)), files.jail())

    def query(self, goal: str, limit: int) -> "QueryResult":
        from ita.logic import sandbox

        return sandbox.query(goal, self.files, self.limits, limit, echo=_echo_output, jail=self.jail)

    def why(self, goal: str, max_depth: int) -> "ProofNode | None":
        from ita.logic import sandbox

        return sandbox.explain(goal, self.files, self.limits, max_depth, echo=_echo_output, jail=self.jail)


def _echo_output(text: str) -> None:
    """What a goal printed, shown before its answer."""
    click.echo(text, nl=not text.endswith("\n"))


@click.group()
def kb() -> None:
    """Query, check, list and explain the Prolog knowledge bases (prolog/ and kb/)."""


def format_table(headers: tuple[str, ...], rows: tuple[tuple[str, ...], ...]) -> str:
    """Plain-text table with aligned columns and a dashed rule under the header."""
    widths = [max([len(h)] + [len(r[i]) for r in rows]) for i, h in enumerate(headers)]
    lines = ["  ".join(h.ljust(w) for h, w in zip(headers, widths)).rstrip(),
             "  ".join("-" * w for w in widths)]
    lines += ["  ".join(v.ljust(w) for v, w in zip(row, widths)).rstrip() for row in rows]
    return "\n".join(lines)


def format_result(result: "QueryResult") -> str:
    """A query result for people: a table of bindings, or true./false."""
    if not result.rows:
        return "false."
    if not result.variables:
        return "true."
    text = format_table(result.variables, result.rows)
    if result.truncated:
        text += f"\n(more solutions not shown: first {len(result.rows)}; raise --limit)"
    return text


def result_json(result: "QueryResult") -> str:
    """A query result as JSON: variables, rows as objects of printed values, truncated."""
    return json.dumps(
        {
            "goal": result.goal,
            "succeeded": result.succeeded,
            "variables": list(result.variables),
            "rows": [dict(zip(result.variables, row)) for row in result.rows],
            "truncated": result.truncated,
        },
        indent=2,
    )


def format_tree(node: "ProofNode") -> str:
    """A proof tree, one goal per line, children indented under their parent."""
    lines: list[str] = []

    def walk(n: "ProofNode", prefix: str, last: bool, root: bool) -> None:
        where = f" {n.location.file.rsplit('/', 1)[-1]}:{n.location.line}" if n.location else ""
        label = f"{n.goal}    [{n.kind}{where}]"
        lines.append(label if root else f"{prefix}{'`- ' if last else '|- '}{label}")
        child_prefix = "" if root else prefix + ("   " if last else "|  ")
        for i, child in enumerate(n.children):
            walk(child, child_prefix, i == len(n.children) - 1, False)

    top = node.children[0] if len(node.children) == 1 and node.children[0].goal == node.goal else node
    walk(top, "", True, True)
    return "\n".join(lines)


@kb.command()
@click.argument("goal")
@click.option("--json", "as_json", is_flag=True, help="Print the answers as JSON.")
@click.option("--limit", type=click.IntRange(min=1), default=100, show_default=True,
              help="Largest number of solutions to print.")
@_limit_options
@reports_errors
def query(goal: str, as_json: bool, limit: int, time_limit: float, inference_limit: int) -> None:
    """Run GOAL against the knowledge bases and print every solution's bindings.

    GOAL is Prolog text, e.g. 'type(X, us_tool)'.  Exit code 1 when it has no solution.
    """
    result = UserGoals.make(time_limit, inference_limit).query(goal, limit)
    click.echo(result_json(result) if as_json else format_result(result))
    if not result.succeeded:
        sys.exit(NO_SOLUTION)


@kb.command()
@click.argument("goal")
@click.option("--max-depth", type=click.IntRange(min=0), default=30, show_default=True,
              help="Expand knowledge-base predicates this many levels deep.")
@_limit_options
@reports_errors
def why(goal: str, max_depth: int, time_limit: float, inference_limit: int) -> None:
    """Explain GOAL: print the proof tree of its first solution.

    Each line is a goal with how it was proved: a rule or fact of kb/ (with file:line),
    a builtin, a negation, or depth_limit.  Exit code 1 when GOAL has no proof.
    """
    tree = UserGoals.make(time_limit, inference_limit).why(goal, max_depth)
    if tree is None:
        click.echo(f"no proof: {goal} has no solution.")
        sys.exit(NO_SOLUTION)
    click.echo(format_tree(tree))


@kb.command()
@click.option("--kb-dir", type=click.Path(path_type=Path, file_okay=False, exists=True),
              default=None, help="Check this knowledge-base directory instead of kb/.")
@click.option("--prolog-dir", type=click.Path(path_type=Path, file_okay=False, exists=True),
              default=None, help="Check this engine directory instead of prolog/.")
@reports_errors
def check(kb_dir: Path | None, prolog_dir: Path | None) -> None:
    """Load everything and list errors, warnings and calls to undefined predicates.

    Each problem is printed as file:line: severity: message.  Exit code 0 only when
    there is none.
    """
    from ita.logic.bridge import check_sources

    problems = check_sources(prolog_dir, kb_dir)
    for problem in problems:
        click.echo(str(problem))
    if problems:
        click.echo(f"{len(problems)} problem(s)", err=True)
        sys.exit(1)
    click.echo("knowledge bases OK: no errors, warnings or undefined predicates")


@kb.command("list")
@reports_errors
def list_() -> None:
    """List the knowledge-base files and their predicates with the first line of their PlDoc."""
    docs = _knowledge_base().list_predicates()
    width = max((len(f"{d.name}/{d.arity}") for d in docs), default=0)
    current = None
    for doc in docs:
        if doc.file != current:
            click.echo(("" if current is None else "\n") + f"{doc.file} (module {doc.module})")
            current = doc.file
        click.echo(f"  {doc.name + '/' + str(doc.arity):<{width}}  {doc.summary or '(no PlDoc)'}")


@kb.command()
@click.option("--limit", type=click.IntRange(min=1), default=100, show_default=True,
              help="Largest number of solutions to print per goal.")
@_limit_options
@reports_errors
def shell(limit: int, time_limit: float, inference_limit: int) -> None:
    """Interactive query loop with the safety of `ita kb query`, history and help.

    Reads goals from standard input (one per line); type `help` for help.
    """
    goals = UserGoals.make(time_limit, inference_limit)
    _tolerate_bad_bytes(sys.stdin)
    interactive = sys.stdin.isatty()
    history = _start_history() if interactive else None
    if interactive:
        import signal

        # Ctrl-C on the terminal stops a goal even when the shell was started with SIGINT
        # ignored (a background job of a non-interactive shell inherits that)
        signal.signal(signal.SIGINT, signal.default_int_handler)
        click.echo("ITA knowledge-base shell; `help` for help, `quit` to leave.")
    try:
        for line in _read_lines(sys.stdin, interactive):
            if line in ("quit", "exit", "halt."):
                break
            try:
                click.echo(_shell_answer(goals, line, limit))
            except KeyboardInterrupt:  # the goal's process is killed; the shell goes on
                click.echo("interrupted: the goal was stopped (Ctrl-C).")
    finally:
        if history is not None:
            _save_history(history)


def _shell_answer(goals: UserGoals, line: str, limit: int) -> str:
    """The text answer of the shell to one input line."""
    if line == "help":
        return SHELL_HELP
    try:
        if line.startswith("why "):
            tree = goals.why(line[4:], 30)
            return format_tree(tree) if tree else "no proof."
        return format_result(goals.query(line, limit))
    except ItaError as exc:
        return f"error: {exc}"


def _read_lines(stream: TextIO, interactive: bool):
    """Non-empty input lines, stripped, with a trailing full stop removed."""
    while True:
        if interactive:
            try:
                line = input("?- ")
            except EOFError:
                click.echo()
                return
            except KeyboardInterrupt:  # Ctrl-C at the prompt drops the line, like a shell
                click.echo()
                continue
        else:
            line = stream.readline()
            if not line:
                return
        line = line.strip()
        if line.endswith(".") and line != "halt.":
            line = line[:-1].rstrip()
        if line:
            yield line


def _tolerate_bad_bytes(stream: TextIO) -> None:
    """Read bytes that are not UTF-8 as they are (surrogate escapes), so such a line is
    refused with a message by the sandbox instead of ending the shell."""
    reconfigure = getattr(stream, "reconfigure", None)
    if reconfigure is not None:
        try:
            reconfigure(errors="surrogateescape")
        except (ValueError, OSError):
            pass


def _predicate_names() -> list[str]:
    """Names of the predicates defined in the knowledge bases (for tab completion)."""
    import re

    from ita.paths import resource_dir

    names: set[str] = set()
    for path in sorted(resource_dir("kb").glob("*.pl")):
        try:
            text = path.read_text(encoding="utf-8")
        except (OSError, UnicodeDecodeError):
            continue
        names.update(re.findall(r"^([a-z][A-Za-z0-9_]*)(?:\(|\s*:-|\.)", text, re.MULTILINE))
    return sorted(names | {"why", "help", "quit", "exit"})


def _completer(names: list[str]):
    """A readline completer over `names` for the word under the cursor."""
    matches: list[str] = []

    def complete(text: str, state: int) -> str | None:
        nonlocal matches
        if state == 0:
            matches = [n for n in names if n.startswith(text)]
        return matches[state] if state < len(matches) else None

    return complete


def _start_history() -> Path | None:
    """Enable readline history from the ITA home directory; its path, or None."""
    try:
        import readline
    except ImportError:
        return None
    from ita.paths import ita_home

    readline.set_completer(_completer(_predicate_names()))
    readline.set_completer_delims(" \t\n()[],;")
    readline.parse_and_bind("tab: complete")
    path = ita_home() / "kb_shell_history"
    try:
        if path.is_file():
            readline.read_history_file(path)
    except OSError:
        pass
    readline.set_history_length(1000)
    return path


def _save_history(path: Path) -> None:
    import readline

    try:
        readline.write_history_file(path)
    except OSError as exc:  # a read-only ITA_HOME loses the history, not the session
        click.echo(f"warning: cannot save the shell history to {path}: {exc.strerror}", err=True)
