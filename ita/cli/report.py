"""`ita report RUN -o FILE`: the run's report as one self-contained HTML page."""

from __future__ import annotations

from pathlib import Path

import click

from ita.cli.common import reports_errors
from ita.cli.runs import open_archive, runs_dir_option


def _specs(part_dir: str | None) -> list:
    """The specs of the run's part, to place unmeasured specs on the map; [] if unavailable."""
    if not part_dir or not Path(part_dir).is_dir():
        return []
    from ita.errors import ItaError
    from ita.part.store import load_part
    from ita.specs import service

    try:
        return service.load(load_part(Path(part_dir)))
    except (ItaError, OSError) as exc:
        click.echo(f"warning: cannot read the specs of {part_dir}: {exc}", err=True)
        return []


@click.command("report")
@click.argument("run")
@click.option("-o", "--output", type=click.Path(path_type=Path, dir_okay=False), required=True,
              help="HTML file to write.")
@click.option("--no-score", is_flag=True, help="Leave out the scoring against the as-built part.")
@runs_dir_option
@reports_errors
def report(run: str, output: Path, no_score: bool, runs_dir: Path | None) -> None:
    """Write the report of RUN (an id, a unique prefix, or "last") to one HTML page.

    Summary (cycle time against the 24 h manual method and the 2.4 h goal of 1987,
    counts by decision), the part coloured by decision, the tours, a Gantt chart of the
    arm, SLRA and gauge streams, the exceptions and the cycle-time breakdown.  For a
    simulated run of a generated part, a separate section scores the results against
    the as-built part (false accepts and rejects, error histogram), unless --no-score.
    """
    from ita.archive.report import build_report, write_report

    with open_archive(runs_dir) as archive:
        run_id = archive.resolve(run)
        info = archive.run(run_id)
        specs = _specs(info.part_dir)
        values = None
        if not no_score and info.settings.get("simulated", True):
            from ita import scoring

            if scoring.has_true_values(info.part_dir):
                values = scoring.true_values(info.part_dir)
            else:
                click.echo("note: the run's part has no as-built values; no scoring section", err=True)
        text = build_report(archive, run_id, specs=specs, true_values=values)
    write_report(output, text)
    click.echo(f"{output}: report of run {run_id} ({info.done} results"
               + (", scored" if values is not None else "") + ")")
