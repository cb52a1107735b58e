"""`ita plan MEAS_ID` and `ita macrop list|show|clear`: the Operation Planner.

The learned MACROPs of a part live in ``$ITA_HOME/macrops/<part name>.pl`` (a Prolog
file a user can read), apart from the hand-written ones of kb/macrops.pl.

Exit codes: 0 success; 1 no plan for the measurement; 2 bad input (unknown measurement,
tool or MACROP, a part or knowledge base that does not load).
"""

from __future__ import annotations

import json
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import click

from ita.cli.common import check_job, part_option, reports_errors
from ita.errors import InputError, Location

if TYPE_CHECKING:
    from ita.logic.bridge import KnowledgeBase
    from ita.part.model import Part
    from ita.planning import OperationPlan, OperationPlanner


def _tool_for(part_dir: Path | None, kb: KnowledgeBase, meas_id: str) -> str:
    """The tool the Sequence Planner's rules choose for `meas_id` now; InputError when none can."""
    from ita.sequence.plan import choose_tool, planning_context

    chosen = choose_tool(planning_context(part_dir, kb=kb), meas_id)
    if chosen.tool is None:
        raise InputError([(Location(meas_id), f"no tool can take it: {chosen.reason}")])
    return chosen.tool


def _planner(part_dir: Path | None) -> tuple["OperationPlanner", Part]:
    """The part and an Operation Planner on its MACROP store, its world model the one a run
    starts from (reset, then the tool marks a person set; slow imports here)."""
    from ita.logic.bridge import KnowledgeBase
    from ita.part.store import load_part, part_key
    from ita.planning import OperationPlanner, store_path
    from ita.sequence.store import apply_tool_marks, load_tool_marks

    part = load_part(part_dir)
    kb = KnowledgeBase()
    apply_tool_marks(kb, load_tool_marks())
    return OperationPlanner(kb, store_path(part_key(part))), part


def _table(headers: tuple[str, ...], rows: Sequence[tuple[str, ...]]) -> str:
    widths = [max([len(h)] + [len(r[i]) for r in rows]) for i, h in enumerate(headers)]
    lines = ["  ".join(h.ljust(w) for h, w in zip(headers, widths)).rstrip(),
             "  ".join("-" * w for w in widths)]
    lines += ["  ".join(v.ljust(w) for v, w in zip(row, widths)).rstrip() for row in rows]
    return "\n".join(lines)


def format_plan(plan: "OperationPlan", kind: str, new_macrop: bool | None = None) -> str:
    """The plan as text: what matched (or which MACROP was stored, and whether it is new),
    then a table of steps with their predecessors."""
    if plan.matched:
        head = f"MACROP {plan.macrop_name} matched"
    elif plan.macrop_name and new_macrop:
        head = f"no MACROP matched: planned from scratch, stored as a NEW MACROP {plan.macrop_name}"
    elif plan.macrop_name and new_macrop is False:
        head = f"planned from scratch; its generalization is MACROP {plan.macrop_name}, already stored"
    elif plan.macrop_name:
        head = f"no MACROP matched: planned from scratch, stored as MACROP {plan.macrop_name}"
    else:
        head = "nothing to do: the goal holds already"
    lines = [f"{plan.measurement} ({kind}): {head} ({plan.seconds * 1000:.2f} ms)",
             f"from: {plan.initial_state.pose}, holding {plan.initial_state.holding or 'nothing'}"]
    if plan.steps:
        rows = [(str(s.number), s.text, ", ".join(map(str, s.predecessors)) or "-") for s in plan.steps]
        lines += ["", _table(("step", "action", "after"), rows), ""]
    lines.append(f"then: {plan.final_state.pose}, holding {plan.final_state.holding or 'nothing'}")
    return "\n".join(lines)


@click.command()
@click.argument("meas_id", required=False)
@click.option("--top", is_flag=True, help="Print the HTN decomposition of the Top Level's job for the part instead "
              "(kb/tasks.pl: tasks, methods, the attached procedures asked); nothing is carried out.")
@click.option("--task", "job", default="inspect_part", show_default=True, metavar="NAME",
              help="With --top: the job (`ita tasks` lists them).")
@click.option("--lines", type=click.IntRange(min=1), default=60, show_default=True,
              help="With --top: print at most so many lines of the tree.")
@click.option("--from-scratch", is_flag=True, help="Skip MACROP lookup: plan, generalize and store.")
@click.option("--holding", "holding", default=None, metavar="TOOL",
              help="Start with TOOL in hand (default: an empty hand).")
@click.option("--after", "after", default=None, metavar="MEAS_ID",
              help="Start where the plan of measurement MEAS_ID leaves the arm.")
@click.option("--tool", "tool", default=None, metavar="TOOL",
              help="Measure with TOOL (default: the tool the Sequence Planner's rules choose now).")
@click.option("--json", "as_json", is_flag=True, help="Print the plan as JSON.")
@part_option
@reports_errors
def plan(meas_id: str | None, top: bool, job: str, lines: int, from_scratch: bool, holding: str | None,
         after: str | None, tool: str | None, as_json: bool, part_dir: Path | None) -> None:
    """Plan measurement MEAS_ID with the tool the Sequence Planner chooses: MACROP lookup
    first, else plan from scratch and learn.  With --top, the Top Level's plan of a whole
    job for the part instead: its HTN decomposition."""
    from ita.planning import NoPlanError, WorldState
    from ita.specs.io import read_specs

    if top:
        if meas_id is not None:
            raise click.UsageError("--top plans the whole job: give no MEAS_ID")
        _top(part_dir, job, lines)
        return
    if meas_id is None:
        raise click.UsageError("give MEAS_ID (or --top for the job's plan)")

    planner, part = _planner(part_dir)
    with planner:
        specs = {s.id: s for s in read_specs(part.specs_path)}
        for wanted in (meas_id, after):
            if wanted is not None and wanted not in specs:
                raise InputError([(Location(str(part.specs_path)), f"no measurement {wanted!r}")])
        state = WorldState(holding=holding)
        tool = tool or _tool_for(part_dir, planner.kb, meas_id)
        try:
            if after is not None:
                state = planner.plan_measurement(specs[after], state, _tool_for(part_dir, planner.kb, after)
                                                 ).final_state
            before = {m.name for m in planner.macrops()}
            result = planner.plan_measurement(specs[meas_id], state, tool, from_scratch=from_scratch)
            new_macrop = None if result.matched or not result.macrop_name else result.macrop_name not in before
        except NoPlanError as exc:
            if as_json:
                click.echo(json.dumps({"measurement": meas_id, "source": None, "reason": exc.reason}))
            click.echo(f"error: {exc}", err=True)
            sys.exit(exc.exit_code)
    if as_json:
        data = result.to_dict()
        data["kind"] = specs[meas_id].kind.value
        data["tool"] = tool
        data["new_macrop"] = new_macrop
        click.echo(json.dumps(data, indent=2))
    else:
        click.echo(format_plan(result, specs[meas_id].kind.value, new_macrop))


def _top(part_dir: Path | None, job: str, lines: int) -> None:
    """Print the HTN plan of `job` for the part: a run registered in a temporary archive
    and planned, nothing carried out."""
    import tempfile
    import time

    from ita.archive import Archive
    from ita.task import open_session
    from ita.toplevel import TopLevel, start_run
    from ita.toplevel.agenda import tree_lines

    check_job(job)
    if job == "reinspect":
        raise click.UsageError("reinspect plans from a run: `ita inspect --task reinspect --from RUN` shows it")
    session = open_session(part_dir)
    try:
        with tempfile.TemporaryDirectory(prefix="ita-top-") as tmp, \
                Archive.open(Path(tmp) / "runs.sqlite") as archive:
            run_id = start_run(session, archive, settings={"task": job})
            top = TopLevel(session, archive, run_id)
            t0 = time.perf_counter()
            agenda = top.plan_job()
            took = time.perf_counter() - t0
    finally:
        session.close()
    click.echo(f"job {job}: {len(agenda.steps)} actions, {len(agenda.nodes)} tasks, planned in {took:.2f} s")
    for line in tree_lines(agenda, lines):
        click.echo(line)


@click.group()
def macrop() -> None:
    """List, show and clear the learned MACROPs (generalized plans) of a part."""


@macrop.command("list")
@part_option
@reports_errors
def list_macrops(part_dir: Path | None) -> None:
    """The MACROPs in lookup order, with their hits, and the store's counts."""
    planner, _ = _planner(part_dir)
    with planner:
        infos = planner.macrops()
        counts = planner.counts()
    rows = [(m.name, "learned" if m.learned else "hand-written", str(m.steps), str(m.hits), m.purpose)
            for m in infos]
    click.echo(_table(("name", "origin", "steps", "hits", "purpose"), rows))
    click.echo(f"\n{counts.lookups} lookups: {counts.hits} hits, {counts.misses} misses"
               f"  (store: {planner.path})")


@macrop.command()
@click.argument("name")
@part_option
@reports_errors
def show(name: str, part_dir: Path | None) -> None:
    """Show MACROP NAME (m<N>, or kb:<name> for a hand-written one) like the seed's Figure 4."""
    planner, _ = _planner(part_dir)
    with planner:
        try:
            text = planner.macrop_text(name)
        except (KeyError, ValueError):
            known = ", ".join(m.name for m in planner.macrops())
            raise InputError([(Location(str(planner.path)),
                               f"no MACROP {name!r} (known: {known or 'none'})")]) from None
    click.echo(text, nl=False)


@macrop.command()
@part_option
@reports_errors
def clear(part_dir: Path | None) -> None:
    """Forget the learned MACROPs and the hit and miss counts (hand-written ones stay)."""
    planner, _ = _planner(part_dir)
    with planner:
        forgotten = planner.clear()
    click.echo(f"cleared {forgotten} learned MACROP{'s' if forgotten != 1 else ''} from {planner.path}")
