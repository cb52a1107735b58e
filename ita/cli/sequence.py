"""`ita sequence`: the Sequence Planner's commands (for now `tsp`, to check the ordering code)."""

from __future__ import annotations

import json
from pathlib import Path

import click

from ita.cli.common import reports_errors


@click.group()
def sequence() -> None:
    """Order measurements so the arm's travel is short (the Sequence Planner)."""


@sequence.command("tsp")
@click.argument("file", type=click.Path(path_type=Path, dir_okay=False))
@click.option("--method", type=click.Choice(["classic", "default"]), default="default", show_default=True,
              help="classic: the seed's convex hull insertion + 2-opt + Or-opt; "
                   "default: iterated local search, within about 1 % of the optimum.")
@click.option("--time-budget", type=click.FloatRange(min=0), default=None,
              help="Seconds for the default method to search (default: a fixed amount of search "
                   "growing with the size, about 1 s at 1000 nodes; deterministic).")
@click.option("--seed", type=int, default=0, show_default=True, help="Random seed.")
@click.option("--json", "as_json", is_flag=True, help="Print a JSON object instead of text.")
@reports_errors
def tsp(file: Path, method: str, time_budget: float | None, seed: int, as_json: bool) -> None:
    """Solve the TSPLIB EUC_2D file FILE with the sequence planner's ordering code.

    Prints the tour as TSPLIB node ids (1-based) in visiting order and its length, so a
    tour can be checked against a published optimum.  Exit code 2 on a bad file.
    """
    from ita.sequence.tour import solve_tour
    from ita.sequence.tsplib import read_tsplib

    problem = read_tsplib(file)
    tour = solve_tour(problem.matrix(), method=method, coords=problem.coords,
                      time_budget=time_budget, seed=seed)
    ids = [v + 1 for v in tour.order]
    length = int(round(tour.cost))
    if as_json:
        click.echo(json.dumps({"name": problem.name, "dimension": problem.dimension, "method": method,
                               "length": length, "seconds": round(tour.seconds, 3), "tour": ids}))
        return
    click.echo(f"{problem.name or file.name}: {problem.dimension} nodes, method {method}")
    click.echo(f"length: {length}")
    click.echo(f"seconds: {tour.seconds:.3f}")
    click.echo("tour: " + " ".join(map(str, ids)))
