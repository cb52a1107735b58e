"""`ita results RUN`: the results of a run with their ISO 14253-1 decisions."""

from __future__ import annotations

import json
from pathlib import Path

import click

from ita.cli.common import reports_errors
from ita.cli.runs import open_archive, runs_dir_option


def result_dict(r) -> dict:
    """JSON-ready dict of a stored result."""
    return {
        "seq": r.seq, "spec_id": r.spec_id, "kind": r.kind, "outcome": r.outcome.value,
        "value": r.value, "u": r.u, "k": r.k, "U": r.U, "nominal": r.nominal, "lower": r.lower,
        "upper": r.upper, "low_limit": r.low_limit, "high_limit": r.high_limit,
        "decision": None if r.decision is None else r.decision.value, "tool": r.tool, "reason": r.reason,
        "sim_time_start": r.sim_time_start, "sim_time_end": r.sim_time_end, "wall_time": r.wall_time,
        "point": None if r.point is None else list(r.point),
    }


def _num(x: float | None, digits: int = 4) -> str:
    return "-" if x is None else f"{x:.{digits}f}"


@click.command("results")
@click.argument("run")
@runs_dir_option
@click.option("--json", "as_json", is_flag=True, help="Print JSON instead of a table.")
@click.option("--failed", is_flag=True, help="Only results not proven to conform: does not conform, "
              "uncertain, not done, cannot be done.")
@reports_errors
def results(run: str, runs_dir: Path | None, as_json: bool, failed: bool) -> None:
    """List the results of RUN (an id, a unique prefix of one, or "last").

    Per result: value, uncertainty (U = k u), nominal, tolerance and the decision:
    conforms (inside the tolerance shrunk by U), does not conform (outside it grown by
    U), or uncertain (in between), as ISO 14253-1 asks.  Millimetres throughout.
    """
    with open_archive(runs_dir) as archive:
        run_id = archive.resolve(run)
        rows = archive.results(run_id, failed_only=failed)
        info = archive.run(run_id)
    if as_json:
        click.echo(json.dumps({"run": run_id, "results": [result_dict(r) for r in rows]}, indent=2))
        return
    click.echo(f"run {run_id}: {info.part}, {info.state_label}, {info.done} of "
               f"{info.total if info.total is not None else '?'} done"
               + (f"; {len(rows)} not proven to conform" if failed else ""))
    if not rows:
        return
    table = [(str(r.seq), r.spec_id, _num(r.value), _num(r.U), _num(r.nominal),
              f"{r.lower:+.4f}/{r.upper:+.4f}", r.status_label + (f" ({r.reason})" if r.reason and r.value is None
                                                                 else "")) for r in rows]
    header = ("#", "SPEC", "VALUE", "U", "NOMINAL", "TOLERANCE", "DECISION")
    widths = [max(len(x) for x in col) for col in zip(header, *table)]
    right = {0, 2, 3, 4}
    for row in (header, *table):
        click.echo("  ".join(c.rjust(w) if i in right else c.ljust(w)
                             for i, (c, w) in enumerate(zip(row, widths))).rstrip())
