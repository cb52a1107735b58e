"""`ita report RUN -o FILE`: the run's report as one self-contained HTML page or a PDF, or
its AS9102 Form 3 (Characteristic Accountability) as an .xlsx workbook."""

from __future__ import annotations

from pathlib import Path

import click

from ita.cli.common import part_option, reports_errors
from ita.cli.runs import open_archive, resolve_run, runs_dir_option


def run_scene(part_dir: Path | str | None, explicit: Path | None = None):
    """The part scene (mesh, specs, workcell) of a run's part: `explicit` (--part) first,
    else the run's own part directory; None (with a warning) when it cannot be read."""
    from ita.errors import ItaError
    from ita.report.scene import PartScene

    where = explicit if explicit is not None else part_dir
    if where is None:
        return None
    if not Path(where).is_dir():
        click.echo(f"warning: the run's part directory {where} is gone; no part map", err=True)
        return None
    try:
        return PartScene.load(where)
    except (ItaError, OSError, ValueError) as exc:
        click.echo(f"warning: cannot read the part of {where or 'the built-in bulkhead'}: {exc}", err=True)
        return None


@click.command("report")
@click.argument("run")
@click.option("-o", "--output", type=click.Path(path_type=Path, dir_okay=False), required=True,
              help="File to write: .html (one self-contained interactive page, works offline), .pdf "
                   "(printable, the part's verdict on page 1) or .xlsx (AS9102 Rev C Form 3, one row per "
                   "characteristic). Other extensions are refused.")
@click.option("--no-score", is_flag=True, help="Leave out the scoring against the as-built part.")
@click.option("--mkdir", "make_dirs", is_flag=True, help="Create the output's directory if it is missing.")
@part_option
@runs_dir_option
@reports_errors
def report(run: str, output: Path, no_score: bool, make_dirs: bool, part_dir: Path | None,
           runs_dir: Path | None) -> None:
    """Write the report of RUN (an id, a unique prefix, or "last") to FILE (-o).

    The part's verdict (accept only when every spec conforms, reject when any does not,
    otherwise incomplete, with what is missing); the results feature by feature (nominal,
    measured, deviation, tolerance with a bar, U, U over tolerance, decision, reason);
    the part in 3-D coloured by decision or deviation; the Gantt chart of the arm, SLRA
    and gauge streams with WAITs; exceptions and run events; the cycle-time breakdown.
    The cycle time is compared with the 24 h manual method and the 2.4 h goal of 1987
    only for a run of the whole part; a partial run shows its rate and an extrapolation,
    labelled as such.  FILE.xlsx is the AS9102 Rev C Form 3 instead: one row per result
    (number, location, designator, requirement, result with U, tool, NC-<run>-<n> for one
    that does not conform, decision) under Form 1's fields.  For a simulated run of a generated part, a separate section
    scores the results against the as-built part, unless --no-score.  With --part, RUN
    must be a run of that part ("last": its last run).
    """
    from ita.files.atomic import output_path
    from ita.report import FORMATS, build_pdf, build_report, report_format, write_report
    from ita.report.as9102 import EXTENSION

    output_path(output, what="-o", make_dirs=make_dirs)  # refuse before the work, not after
    ext = output.suffix.lower()
    if ext == EXTENSION:
        _form3(run, output, make_dirs, part_dir, runs_dir)
        return
    if ext not in FORMATS:
        from ita.errors import InputError, Location

        raise InputError([(Location(str(output), field="-o"), "a report is written as .html (one interactive "
                           "page), .pdf (printable) or .xlsx (AS9102 Form 3), not "
                           f"{ext or 'a file without an extension'}")])
    fmt = report_format(output)
    with open_archive(runs_dir) as archive:
        run_id = resolve_run(archive, run, part_dir)
        info = archive.run(run_id)
        scene = run_scene(info.part_dir if info.part_dir else None, part_dir)
        values = injected = None
        if not no_score and info.settings.get("simulated", True):
            from ita.scoring import truth as scoring

            source = scoring.run_part_truth(str(part_dir) if part_dir is not None else info.part_dir,
                                            dict(info.settings))
            injected = scoring.injected_faults(archive.path.parent, run_id)
            if scoring.has_true_values(source):
                values = scoring.true_values(source)
            else:
                click.echo("note: the run's part has no as-built values; no scoring section", err=True)
        if fmt == "pdf":
            content: str | bytes = build_pdf(archive, run_id, true_values=values, scene=scene, injected=injected)
        else:
            content = build_report(archive, run_id, true_values=values, scene=scene, injected=injected)
    output = write_report(output, content, make_dirs=make_dirs)
    click.echo(f"{output}: {fmt.upper()} report of run {run_id} ({info.done} results"
               + (", scored" if values is not None else "") + ")")


def _form3(run: str, output: Path, make_dirs: bool, part_dir: Path | None, runs_dir: Path | None) -> None:
    """`ita report RUN -o FILE.xlsx`: the AS9102 Rev C Form 3 workbook, written atomically."""
    from ita.files.atomic import write_atomic
    from ita.report.as9102 import form3_xlsx

    with open_archive(runs_dir) as archive:
        run_id = resolve_run(archive, run, part_dir)
        info = archive.run(run_id)
        content = form3_xlsx(archive, run_id)
    output = write_atomic(output, content, what="-o", make_dirs=make_dirs)
    click.echo(f"{output}: AS9102 Form 3 of run {run_id} ({info.done} characteristics)")
