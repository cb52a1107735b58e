"""`ita sequence`: the Sequence Planner's commands.

    ita sequence [--method classic|default|fast] [--json] [--render seq.png] [--restart]
        partition the part's measurements by tool (kb/tools.pl), order each group, store
        the plan (ita_home()/plans/<part>.json) and print the groups, costs, tool changes
    ita sequence show [--json]        print the stored plan
    ita sequence next [-n N] [--json] hand out the next measurement(s) of the stored plan,
                                      resequencing when a tool is not available
    ita sequence tool list            the tools and their marks in the world model
    ita sequence tool broken|worn|missing|found|ok TOOL
                                      mark a tool by hand (kept in ita_home()/world/tools.json)
    ita sequence why SPEC_ID [--tree] which tool takes SPEC_ID and why
    ita sequence tsp FILE             check the ordering code on a TSPLIB file

Exit codes: 0 success; 1 `next` found nothing left to hand out, `why` a measurement that
cannot be done; 2 bad input, no stored plan, a stale plan, a knowledge base that does not
load.
"""

from __future__ import annotations

import json
import math
import sys
import time
from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

import click

from ita.cli.common import FiniteFloatRange, part_option, reports_errors

if TYPE_CHECKING:
    from ita.sequence.plan import PlanningContext, SequencePlan

NOTHING_LEFT = 1
MARK_CHOICES = ("list", "ok", "broken", "worn", "missing", "found")


def _context(part_dir: Path | None, method: str = "default") -> PlanningContext:
    """The planning context with the stored tool marks applied to the world model."""
    from ita.logic.bridge import KnowledgeBase  # starts SWI-Prolog: only when needed
    from ita.sequence.plan import planning_context
    from ita.sequence.store import apply_tool_marks, load_tool_marks

    kb = KnowledgeBase()
    apply_tool_marks(kb, load_tool_marks())
    return planning_context(part_dir, kb=kb, method=method)


def _unit(plan: SequencePlan) -> str:
    return "s (estimate)" if plan.cost_interim else "s"


def cost_includes(plan: SequencePlan) -> str:
    """What the plan's seconds include: its cost model's description."""
    from ita.sequence.cost import COST_MODELS

    model = COST_MODELS.get(plan.cost_model)
    return model.description if model else f"unknown cost model {plan.cost_model!r}"


def plan_summary(plan: SequencePlan) -> dict[str, Any]:
    """The figures of a plan for people and scripts (no orders)."""
    from collections import Counter

    return {
        "part": plan.part, "method": plan.method, "cost_model": plan.cost_model,
        "cost_interim": plan.cost_interim, "cost_includes": cost_includes(plan),
        "measurements": plan.measurement_count,
        "groups": [{"tool": g.tool, "tool_class": g.tool_class, "count": len(g.order),
                    "cost_s": round(g.cost_s, 3), "rules": dict(g.rules)} for g in plan.groups],
        "done": len(plan.finished()),
        "cannot": {"count": len(plan.cannot), "reasons": dict(Counter(r for _, r in plan.cannot).most_common())},
        "tool_changes": plan.tool_changes, "transfer_s": round(plan.transfer_s, 3),
        "total_s": round(plan.total_s, 3), "build_seconds": round(plan.build_seconds, 3),
        "handed_out": len(plan.handed_out), "remaining": len(plan.pending()),
        "tool_state": {k: dict(v) for k, v in plan.tool_state.items()},
    }


def format_plan(plan: SequencePlan) -> str:
    """A plan for people: the groups with counts and tour costs, the tool changes, the total."""
    unit = _unit(plan)
    lines = [f"sequence plan of {plan.part}: {plan.measurement_count} measurements, method {plan.method}"]
    width = max([len(g.tool) for g in plan.groups] + [14])
    lines.append(f"  {'group':<{width + 3}} {'class':<10} {'count':>6} {'tour ' + unit:>18}")
    for k, g in enumerate(plan.groups):
        lines.append(f"  {k + 1}. {g.tool:<{width}} {g.tool_class:<10} {len(g.order):>6} {g.cost_s:>18.1f}")
    lines.append(f"  {'done':<{width + 3}} {'':<10} {len(plan.finished()):>6}")
    lines.append(f"  {'cannot be done':<{width + 3}} {'':<10} {len(plan.cannot):>6}")
    reasons: dict[str, int] = {}
    for _, r in plan.cannot:
        reasons[r] = reasons.get(r, 0) + 1
    for reason, count in sorted(reasons.items(), key=lambda kv: -kv[1]):
        lines.append(f"      {count:>5}  {reason}")
    at_rack = "between rack slots" if plan.cost_interim else "at the rack (pick-ups, put-downs, slot to slot)"
    lines.append(f"tool changes: {plan.tool_changes}   {at_rack}: {plan.transfer_s:.1f} {unit}")
    lines.append(f"total: {plan.total_s:.1f} {unit}")
    if plan.cost_interim:
        lines.append(f"  (cost model {plan.cost_model}: straight-line tool-point distance at the arm's top "
                     "tool speed, a lower bound; not the arm's motion time)")
    else:
        import textwrap

        lines.append(textwrap.fill(f"(cost model {plan.cost_model}: {cost_includes(plan)})", width=92,
                                   initial_indent="  ", subsequent_indent="   "))
    if plan.handed_out:
        lines.append(f"progress: {len(plan.handed_out)} handed out, {len(plan.pending())} to go")
    broken = {t: s for t, s in plan.tool_state.items()
              if s.get("condition") != "ok" or s.get("location") == "missing"}
    if broken:
        lines.append("tools not available: " + ", ".join(
            f"{t} ({s.get('condition')}, {s.get('location')})" for t, s in sorted(broken.items())))
    return "\n".join(lines)


@click.group(invoke_without_command=True)
@part_option
@click.option("--method", type=click.Choice(["classic", "default", "fast"]), default="default",
              show_default=True,
              help="Tour method per tool group: classic (the seed's convex hull + 2-opt + Or-opt), "
                   "default (LKH bounded by work with a fixed seed: the same plan on every machine) or "
                   "fast (the fast-tsp library; clock-seeded, deadline-bound: plans may differ).")
@click.option("--json", "as_json", is_flag=True, help="Print the plan's figures as JSON.")
@click.option("--render", "render_path", type=click.Path(path_type=Path, dir_okay=False), default=None,
              help="Also draw the tours over the part into this PNG file.")
@click.option("--restart", is_flag=True,
              help="Forget the progress of the stored plan (by default its done measurements stay done).")
@click.pass_context
@reports_errors
def sequence(ctx: click.Context, part_dir: Path | None, method: str, as_json: bool,
             render_path: Path | None, restart: bool) -> None:
    """Make and store the sequence plan of the part (the Sequence Planner).

    Partitions the measurements by tool with the rules of kb/tools.pl (the world model's
    tool marks decide which tools are available), orders each tool's group into a tour
    from and back to its rack slot, orders the groups (one visit to the rack per tool),
    stores the plan for `ita sequence next` and prints the groups, the tour cost of each,
    the tool changes and the total.
    """
    if ctx.invoked_subcommand is not None:
        return
    from ita.sequence.plan import build_plan
    from ita.sequence.store import PlanNotFound, load_plan, save_plan

    t0 = time.perf_counter()
    context = _context(part_dir, method)
    done: tuple[str, ...] = ()
    if not restart:
        try:
            stored = load_plan(context.part_name)
        except PlanNotFound:
            stored = None
        if stored is not None and stored.specs_digest == context.specs_digest:
            done = stored.finished()
    plan = build_plan(context, done=done)
    path = save_plan(plan)
    if render_path is not None:
        from ita.part.store import load_part
        from ita.sequence.render import render_plan

        render_plan(load_part(part_dir), {s.id: s for s in context.specs}, plan, render_path)
    seconds = time.perf_counter() - t0
    if as_json:
        click.echo(json.dumps({**plan_summary(plan), "plan_file": str(path),
                               "command_seconds": round(seconds, 3)}, indent=1))
        return
    click.echo(format_plan(plan))
    click.echo(f"planned in {plan.build_seconds:.2f} s ({seconds:.2f} s with loading); stored in {path}")
    if render_path is not None:
        click.echo(f"wrote {render_path}")


@sequence.command()
@part_option
@click.option("--json", "as_json", is_flag=True, help="Print the whole stored plan (with orders) as JSON.")
@reports_errors
def show(part_dir: Path | None, as_json: bool) -> None:
    """Print the stored sequence plan of the part."""
    from ita.part.store import load_part, part_key
    from ita.sequence.store import load_plan, plan_to_dict

    plan = load_plan(part_key(load_part(part_dir)))
    if as_json:
        click.echo(json.dumps(plan_to_dict(plan), indent=1))
        return
    click.echo(format_plan(plan))
    for k, g in enumerate(plan.groups):
        head = ", ".join(g.order[:8]) + (", ..." if len(g.order) > 8 else "")
        click.echo(f"  {k + 1}. {g.tool}: {head}")
    from ita.offline.prepare import cannot_lines, stored_cannot

    cannot = stored_cannot(plan, plan.part)
    click.echo(f"cannot be done: {len(cannot)} (the tool rules' cannot-be-done group and the measurements the "
               "MKB could not place, as `ita prepare` says)" + (":" if cannot else ""))
    for line in cannot_lines(cannot):
        click.echo(line)


def _down(_ctx: click.Context, _param: click.Parameter, value: str | None) -> tuple[str, float] | None:
    """ARM@SECONDS -> (arm, seconds)."""
    if value is None:
        return None
    arm, at, seconds = value.partition("@")
    try:
        t = float(seconds)
    except ValueError:
        t = math.nan
    if not arm or not at or not math.isfinite(t) or t < 0:
        raise click.BadParameter(f"{value!r}: give ARM@SECONDS, e.g. t3_b@300", param_hint="--down")
    return arm, t


@sequence.command()
@part_option
@click.option("--json", "as_json", is_flag=True, help="Print the allocation as JSON.")
@click.option("--down", default=None, metavar="ARM@SECONDS", callback=_down,
              help="Also re-allocate as if ARM stopped for good SECONDS into the coordinated plan: the other "
                   "arm takes over what the stopped one had not made and it can make.")
@reports_errors
def allocate(part_dir: Path | None, as_json: bool, down: tuple[str, float] | None) -> None:
    """Split the part's measurements between the workcell's two arms (its [robot_b]).

    Prepares the part as each arm works it first (its sequence plan and MKB, reused when
    current).  Each measurement goes to an arm that reaches it, whose MKB places it, with a
    tool of its class (a tool with no twin to one arm), its body clear of the other arm
    folded on its base; the split
    between the arms' bases that makes the larger arm time least.  Prints each arm's share and time (planned motion, the rack and
    a dwell per measurement by tool class), the makespan, a lower bound and the one-arm time; then the
    two arms' moves played through the interference zones (claims, waits, retreats): the
    coordinated makespan and each arm's busy and waiting seconds, and both arms checked for
    contact in 3-D.  With --down, the hand-over: what was made by then, what the other arm
    takes over, what is lost and why, the new makespan.  A plan, not a run (the run is
    `ita inspect --arms 2`).
    """
    import numpy as np

    from ita.executive.two_arms import coordinated
    from ita.executive.zones import configurations_at
    from ita.logic.bridge import KnowledgeBase
    from ita.offline.prepare import prepared_arms
    from ita.part.store import load_part
    from ita.sequence.allocate import allocate as split
    from ita.sequence.plan import planning_context
    from ita.sequence.store import apply_tool_marks, load_tool_marks
    from ita.sim.arms import TwoArms

    kb = KnowledgeBase()
    apply_tool_marks(kb, load_tool_marks())
    part = load_part(part_dir)
    arm_names = [a.name for a in planning_context(part_dir, kb=kb, part=part, use_mkb=False).workcell.arms()]
    if len(arm_names) != 2:
        raise click.UsageError("the workcell names one arm; a second is a [robot_b] table in its workcell.toml")
    if down is not None and down[0] not in arm_names:
        raise click.BadParameter(f"no arm {down[0]!r} (the cell's arms: {', '.join(arm_names)})", param_hint="--down")
    ctx, plan, mkbs = prepared_arms(part_dir, kb, part, progress=lambda m: click.echo(f"{m} ...", err=True))
    click.echo("allocating the measurements between the arms ...", err=True)
    result = split(ctx, plan, mkbs=mkbs)
    click.echo("playing the arms' moves through the interference zones (eight orders) ...", err=True)
    schedule, jobs, how = coordinated(ctx, result)
    click.echo("checking the two arms for contact in 3-D, every half second ...", err=True)
    times = np.arange(0.0, schedule.makespan_s + 0.5, 0.5)
    q = configurations_at(schedule, jobs, times)
    with TwoArms(ctx.workcell) as arms:
        gaps = arms.gaps(q[jobs[0].name], q[jobs[1].name])
    handover = None
    if down is not None:
        from ita.executive.two_arms import hand_over

        click.echo(f"re-allocating with {down[0]} down at {down[1]:.1f} s ...", err=True)
        handover = hand_over(ctx, plan, result, schedule, jobs, down[0], down[1], mkbs)
    report = result.as_dict()
    if handover is not None:
        report["down"] = {"arm": handover.down, "at_s": handover.at_s, "made_before": len(handover.done),
                          "handed_over": len(handover.handed),
                          "lost": [{"spec": i, "why": w} for i, w in handover.lost],
                          "makespan_s": round(handover.makespan_s, 1)}
    report["coordinated"] = {
        "makespan_s": round(schedule.makespan_s, 1), "variant": how,
        "ratio_to_one_arm": round(schedule.makespan_s / result.one_arm_s, 3),
        "busy_s": {k: round(v, 1) for k, v in schedule.busy_s.items()},
        "waiting_s": {k: round(v, 1) for k, v in schedule.waiting_s.items()},
        "retreats": schedule.retreats, "zone_events": len(schedule.events),
        "arm_arm_contacts": int(np.count_nonzero(gaps <= 0.0)), "moments": len(times),
        "least_gap_m": round(float(gaps.min()), 3)}
    if as_json:
        click.echo(json.dumps(report, indent=1))
        return
    for share in result.shares:
        tools = ", ".join(f"{t} {len(o)} ({c:.0f} s of motion)" for t, o, c in share.groups)
        click.echo(f"{share.arm:8s} {share.count:5d} measurements, {share.time_s:7.1f} s: {tools}; "
                   f"{share.rack_s:.0f} s at the rack")
    click.echo(f"makespan {result.makespan_s:.1f} s; lower bound {result.bound_s:.1f} s (gap "
               f"{result.gap_percent:.1f} %); one arm {result.one_arm_s:.1f} s "
               f"(ratio {result.makespan_s / result.one_arm_s:.3f})")
    if result.unassigned:
        click.echo(f"neither arm: {len(result.unassigned)}: "
                   + ", ".join(f"{i} ({w})" for i, w in result.unassigned[:10]))
    c = report["coordinated"]
    click.echo(f"through the interference zones: makespan {schedule.makespan_s:.1f} s "
               f"(ratio {c['ratio_to_one_arm']:.3f} to one arm; {how}: the order `ita inspect --arms 2` follows)")
    for arm in schedule.arms:
        click.echo(f"  {arm:8s} busy {schedule.busy_s[arm]:7.1f} s, waiting {schedule.waiting_s[arm]:6.1f} s, "
                   f"{schedule.retreats[arm]} retreat(s)")
    click.echo(f"  {c['arm_arm_contacts']} arm-arm contacts in {len(times)} moments (both arms in pybullet), least "
               f"gap {c['least_gap_m']:.2f} m; {len(schedule.events)} zone events")
    if handover is not None:
        click.echo(f"{handover.down} down at {handover.at_s:.1f} s: {len(handover.done)} made by then, "
                   f"{len(handover.handed)} of its own handed over, {len(handover.lost)} lost; makespan "
                   f"{handover.makespan_s:.1f} s")
        for i, w in handover.lost[:10]:
            click.echo(f"  lost {i}: {w}")


@sequence.command("next")
@part_option
@click.option("-n", "--count", type=click.IntRange(min=1), default=1, show_default=True,
              help="Hand out this many measurements.")
@click.option("--json", "as_json", is_flag=True, help="Print the steps as JSON lines.")
@reports_errors
def next_(part_dir: Path | None, count: int, as_json: bool) -> None:
    """Hand out the next measurement of the stored plan (checking its tool and the arm).

    When the tool is not available the remaining measurements are resequenced (a spare
    takes over; without one they move to cannot-be-done) and the plan is stored anew.
    Exit code 1 when nothing is left to hand out.
    """
    from ita.sequence.next_step import next_step
    from ita.sequence.store import check_current, load_plan, save_plan

    context = _context(part_dir)
    plan = load_plan(context.part_name)
    check_current(plan, context.specs_digest)
    context = replace(context, method=plan.method)  # resequence as the plan was made
    handed = 0
    for _ in range(count):
        result = next_step(context, plan)
        plan = result.plan
        if result.resequenced:
            msg = f"resequenced: {result.reason}"
            click.echo(json.dumps({"resequenced": result.reason}) if as_json else msg)
            if not as_json:
                click.echo(format_plan(plan))
        if result.step is None:
            break
        handed += 1
        s = result.step
        if as_json:
            click.echo(json.dumps({"id": s.spec_id, "kind": s.kind, "tool": s.tool, "tool_class": s.tool_class,
                                   "arm": s.arm, "group": s.group + 1, "position": s.position,
                                   "remaining": s.remaining}))
        else:
            click.echo(f"next: {s.spec_id}  ({s.kind}) with {s.tool} on {s.arm}; group {s.group + 1} "
                       f"#{s.position}; {s.remaining} to go")
    save_plan(plan)
    if handed < count:
        if not as_json:
            click.echo(f"nothing left to hand out ({len(plan.finished())} done, "
                       f"{len(plan.cannot)} cannot be done)")
        sys.exit(NOTHING_LEFT)


@sequence.command()
@click.argument("action", type=click.Choice(MARK_CHOICES))
@click.argument("tool", required=False)
@reports_errors
def tool(action: str, tool: str | None) -> None:
    """Mark a tool in the world model by hand, or list the tools (ACTION list).

    ACTION: broken or worn (its condition), missing (not in its slot), found (back in
    its slot), ok (working and in its slot).  The marks are kept in
    ita_home()/world/tools.json and apply to every later `ita sequence` command; the
    next `ita sequence next` resequences when the plan's tool is no longer available.
    """
    from ita.errors import InputError, Location
    from ita.files.atomic import locked
    from ita.logic.bridge import KnowledgeBase
    from ita.sequence.plan import tool_state
    from ita.sequence.store import (
        MARKS,
        apply_tool_marks,
        load_tool_marks,
        marked,
        save_tool_marks,
        tool_marks_path,
    )

    kb = KnowledgeBase()
    if action != "list":
        if not tool:
            raise InputError([(Location("<command line>"), f"`tool {action}` needs a TOOL")])
        with locked(tool_marks_path()):  # two markings at once lose neither
            marks = marked(load_tool_marks(), tool, action)
            apply_tool_marks(kb, marks)  # validates the tool name before anything is stored
            path = save_tool_marks(marks)
        click.echo(f"{tool}: {action} ({MARKS[action]}); marks in {path}")
    else:
        marks = load_tool_marks()
        apply_tool_marks(kb, marks)
    from ita.logic.world import WorldModel

    world = WorldModel(kb)
    for name, state in tool_state(kb).items():
        click.echo(f"  {name:<12} {world.tool_type(name):<10} {state['condition']:<7} "
                   f"{state['location']:<18} {'available' if world.available(name) else 'NOT available'}")


@sequence.command()
@click.argument("spec_id")
@part_option
@click.option("--tree", is_flag=True, help="Also print the proof tree of the choice (as `ita kb why`).")
@reports_errors
def why(spec_id: str, part_dir: Path | None, tree: bool) -> None:
    """Explain which tool takes measurement SPEC_ID and why (the rules of kb/tools.pl).

    Prints the rule chosen or the reason it cannot be done, the rules that lost, and the
    goal to give `ita kb why` for the full proof.  Exit code 1 when it cannot be done.
    """
    from ita.cli.kb import format_tree
    from ita.errors import InputError, Location
    from ita.sequence.partition import UNKNOWN_FEATURE, select_tools, term_text

    context = _context(part_dir)
    try:
        spec = context.spec(spec_id)
    except KeyError:
        raise InputError([(Location("<command line>", field="spec_id"),
                           f"no measurement {spec_id!r} in part {context.part_name!r}")]) from None
    index = context.specs.index(spec)
    facts = context.spec_facts()[index]
    selection = select_tools(context.kb, [spec], context.feature_kinds, [facts])[0]
    feature_kind = context.feature_kinds.get(spec.feature, UNKNOWN_FEATURE)
    goal = (f"select_tool({spec.kind.value}, {feature_kind}, {term_text(list(facts))}, Choice, Why)")
    click.echo(f"{spec.id}: {spec.kind.value} on {feature_kind} {spec.feature}")
    click.echo(f"facts: {term_text(list(facts))}")
    if selection.tool:
        click.echo(f"tool: {selection.tool} ({selection.tool_class}) by rule {selection.rule}")
    else:
        click.echo(f"cannot be done: {selection.reason}")
    for step in selection.why:
        click.echo(f"  {step}")
    click.echo(f"proof: ita kb why '{goal}'  (with the same tool marks)")
    if tree:
        proof = context.kb.explain(goal)
        if proof is not None:
            click.echo(format_tree(proof))
    if not selection.tool:
        sys.exit(1)


@sequence.command("tsp")
@click.argument("file", type=click.Path(path_type=Path, dir_okay=False))
@click.option("--method", type=click.Choice(["classic", "default", "fast"]), default="default",
              show_default=True,
              help="classic: the seed's convex hull insertion + 2-opt + Or-opt; "
                   "default: LKH bounded by work with a fixed seed (the same tour everywhere), "
                   "within about 0.1 % of the optimum; "
                   "fast: the fast-tsp library for a wall-clock budget.")
@click.option("--time-budget", type=FiniteFloatRange(min=0), default=None,
              help="Wall-clock seconds for the fast method to search (default: 1 ms a node, "
                   "0.05 to 0.9 s).  Above 20 nodes its tours may differ from run to run.")
@click.option("--json", "as_json", is_flag=True, help="Print a JSON object instead of text.")
@reports_errors
def tsp(file: Path, method: str, time_budget: float | None, as_json: bool) -> None:
    """Solve the TSPLIB EUC_2D file FILE with the sequence planner's ordering code.

    Prints the tour as TSPLIB node ids (1-based) in visiting order and its length, so a
    tour can be checked against a published optimum.  At most 5,000 nodes (the distance
    matrix is dense) and coordinates up to 1e9 in size.  Exit code 2 on a bad file.
    """
    from ita.sequence.tour import solve_tour
    from ita.sequence.tsplib import read_tsplib

    problem = read_tsplib(file)
    tour = solve_tour(problem.matrix(), method=method, coords=problem.coords, time_budget=time_budget)
    ids = [v + 1 for v in tour.order]
    length = round(tour.cost)
    if as_json:
        click.echo(json.dumps({"name": problem.name, "dimension": problem.dimension, "method": method,
                               "length": length, "seconds": round(tour.seconds, 3), "tour": ids}))
        return
    click.echo(f"{problem.name or file.name}: {problem.dimension} nodes, method {method}")
    click.echo(f"length: {length}")
    click.echo(f"seconds: {tour.seconds:.3f}")
    click.echo("tour: " + " ".join(map(str, ids)))
