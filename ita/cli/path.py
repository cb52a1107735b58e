"""`ita path`: the Path Planner's commands.

    ita path problems --n N --seed S -o FILE   write a start/goal problem set (JSON)
    ita path bench FILE [--json]               plan every problem of a set; success,
                                               planning time, tool path, trajectory duration
    ita path plan FROM TO [--tool T] [--render path.png] [--json]
                                               plan one move; FROM and TO are a spec id,
                                               'rack:SLOT' (above that slot) or 'home'

The held tool (--tool) defaults to the tool of a rack slot named in FROM or TO (the move
that brings it back or takes it out), else us_probe_1; 'none' is the bare flange.

Exit codes: 0 a path (plan) or a finished run (problems, bench); 1 no path (its reason is
printed); 2 bad input (an unknown spec, slot or tool, a malformed problem file).
"""

from __future__ import annotations

import json
import sys
from pathlib import Path
from typing import Any

import click

from ita.cli.common import part_option, reports_errors, seed_option

NO_PATH = 1
DEFAULT_TOOL = "us_probe_1"
MAX_PROBLEMS = 100_000  # problems `ita path problems` writes at most (--n)


def _scene(part_dir: Path | None) -> tuple[Any, Any]:
    from ita.part.store import load_part
    from ita.workcell import workcell_for

    part = load_part(part_dir)
    return workcell_for(part.directory, part.mesh.bounds), part


@click.group()
def path() -> None:
    """Path Planner: collision-free timed arm motions, problem sets, benchmarks, pictures."""


@path.command("problems")
@click.option("--n", "count", type=click.IntRange(1, MAX_PROBLEMS), default=200, show_default=True,
              help=f"Problems to write (at most {MAX_PROBLEMS:,}).")
@seed_option(default=1, help="Seed of the random poses.")
@click.option("-o", "--out", type=click.Path(path_type=Path, dir_okay=False), required=True)
@part_option
@reports_errors
def problems_cmd(count: int, seed: int, out: Path, part_dir: Path | None) -> None:
    """Generate a problem set: measurement to measurement, rack and back, random poses."""
    from ita.path.planner import planners_for
    from ita.path.problems import generate_problems, write_problems
    from ita.specs.io import read_specs

    cell, part = _scene(part_dir)
    problems = generate_problems(cell, read_specs(part.specs_path), count, seed, planners_for(cell, part))
    write_problems(out, problems, seed)
    kinds: dict[str, int] = {}
    for p in problems:
        kinds[p.kind] = kinds.get(p.kind, 0) + 1
    click.echo(f"wrote {len(problems)} problems to {out} ({', '.join(f'{k} {v}' for k, v in kinds.items())})")


@path.command("bench")
@click.argument("file", type=click.Path(path_type=Path, exists=True, dir_okay=False))
@click.option("--json", "as_json", is_flag=True, help="Print the summary and rows as JSON.")
@part_option
@reports_errors
def bench_cmd(file: Path, as_json: bool, part_dir: Path | None) -> None:
    """Plan every problem of FILE; print success, planning time, path length, duration."""
    from ita.path.planner import planners_for
    from ita.path.problems import read_problems, run_problems, summarize

    problems = read_problems(file)
    cell, part = _scene(part_dir)
    planner_for = planners_for(cell, part)
    for held in {p.tool for p in problems}:          # static graphs before timing
        planner, tool = planner_for(held)
        planner.graph(tool)
    with click.progressbar(length=len(problems), label="planning", file=sys.stderr) as bar:
        rows = run_problems(problems, planner_for, progress=lambda _: bar.update(1))
    summary = summarize(rows)
    if as_json:
        click.echo(json.dumps({"summary": summary, "rows": rows}, indent=1))
        return
    click.echo(f"problems        {summary['problems']}")
    click.echo(f"solved          {summary['solved']}")
    click.echo(f"planning ms     median {summary['median_ms']:.1f}, 95th percentile {summary['p95_ms']:.1f}")
    if summary["solved"]:
        click.echo(f"tool path m     median {summary['median_tool_path_m']:.2f}")
        click.echo(f"duration s      median {summary['median_duration_s']:.2f}")
    for reason, n in summary["failures"].items():
        click.echo(f"failed          {n} {reason}")


def _endpoint(text: str, cell: Any, part: Any, planner: Any, tool: Any, start: bool) -> tuple[Any, str]:
    """A configuration (start) or a goal (poses or a configuration) for FROM/TO text."""
    import numpy as np

    from ita.path.planner import HOME
    from ita.path.problems import free_solutions, measurement_targets, rack_target
    from ita.specs.io import read_specs

    if text == "home":
        return np.asarray(HOME, dtype=float), "home"
    if text.startswith("rack:"):
        try:
            goal = rack_target(cell, text.split(":", 1)[1], tool)
        except KeyError as exc:
            raise click.BadParameter(str(exc.args[0])) from exc
    else:
        specs = {s.id: s for s in read_specs(part.specs_path)}
        spec = specs.get(text.removeprefix("spec:"))
        if spec is None:
            raise click.BadParameter(f"{text!r} is no spec id, 'rack:SLOT' or 'home'")
        if tool is None:
            raise click.BadParameter("a measurement needs a tool (--tool)")
        goal = measurement_targets(cell, spec.point, spec.normal, tool)
    if not start:
        return goal, text
    ctx = planner.context(tool)
    q = free_solutions(goal, ctx.tcp, planner.model, ctx.config_free)
    if len(q) == 0:
        raise click.BadParameter(f"{text}: no collision-free configuration to start from")
    from ita.kinematics import move_time

    return q[int(np.argmin(move_time(planner.model, np.asarray(HOME), q)))], text


@path.command("plan")
@click.argument("source", metavar="FROM")
@click.argument("target", metavar="TO")
@click.option("--tool", "tool_name", default=None, help="Held tool ('none': the bare flange).")
@click.option("--render", "render_to", type=click.Path(path_type=Path, dir_okay=False), default=None,
              help="Draw the planned path to this PNG file.")
@click.option("--json", "as_json", is_flag=True, help="Print the result as JSON.")
@part_option
@reports_errors
def plan_cmd(source: str, target: str, tool_name: str | None, render_to: Path | None, as_json: bool,
             part_dir: Path | None) -> None:
    """Plan one move FROM -> TO (spec ids, 'rack:SLOT', 'home')."""
    from ita.path.planner import workcell_planner

    cell, part = _scene(part_dir)
    if tool_name is None:
        slots = {s.name: s.tool for s in cell.rack.slots}
        named = [slots.get(t.split(":", 1)[1]) for t in (source, target) if t.startswith("rack:")]
        tool_name = next((t for t in named if t), DEFAULT_TOOL)
    held = None if tool_name == "none" else tool_name
    if held is not None and held not in {t.name for t in cell.tools}:
        raise click.BadParameter(f"unknown tool {held!r}", param_hint="--tool")
    planner, tool = workcell_planner(cell, part, held)
    q0, _ = _endpoint(source, cell, part, planner, tool, start=True)
    goal, _ = _endpoint(target, cell, part, planner, tool, start=False)
    result = planner.plan(q0, goal, tool)
    if as_json:
        click.echo(json.dumps({
            "ok": result.ok, "reason": None if result.reason is None else result.reason.value,
            "message": result.message, "tool": held, "seconds": result.seconds,
            "duration_s": result.duration if result.ok else None,
            "tool_path_m": result.tool_path_length if result.ok else None,
            "waypoints": result.waypoints.tolist(), "route": result.route.tolist(), "stats": result.stats}, indent=1))
    elif result.ok:
        click.echo(f"{source} -> {target} with {held or 'no tool'}: {len(result.waypoints)} waypoints, "
                   f"tool path {result.tool_path_length:.2f} m, duration {result.duration:.2f} s, "
                   f"planned in {result.seconds * 1000:.0f} ms")
    else:
        assert result.reason is not None   # a query without a path says why
        click.echo(f"no path: {result.reason.value}: {result.message}", err=True)
    if render_to is not None and result.ok:
        from ita.path.render import render_path

        render_path(planner, result, tool, render_to,
                    title=f"{source} -> {target} ({held or 'no tool'}): {result.duration:.2f} s")
        if not as_json:
            click.echo(f"wrote {render_to}")
    if not result.ok:
        sys.exit(NO_PATH)
