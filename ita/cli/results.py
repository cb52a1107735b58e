"""`ita results RUN`: the results of a run, feature by feature, with their ISO 14253-1
decisions; as a table, CSV or JSON."""

from __future__ import annotations

import csv
import json
import sys
from datetime import datetime, timezone
from pathlib import Path

import click

from ita.cli.common import part_option, reports_errors
from ita.cli.runs import open_archive, resolve_run, runs_dir_option


def result_dict(r) -> dict:
    """Every column of the per-feature table (ita.report.data.COLUMNS) of a stored result."""
    from ita.report.data import result_row

    return result_row(r)


def _num(x: float | None, digits: int = 4) -> str:
    return "-" if x is None else f"{x:.{digits}f}"


def _signed(x: float | None, digits: int = 4) -> str:
    return "-" if x is None else f"{x:+.{digits}f}"


def _csv_cell(column: str, value: object, rounded: bool) -> object:
    """A CSV cell: empty for None; with `rounded`, a float to four decimals and the
    wall-clock time (Unix seconds) as ISO 8601 in UTC; else the value as it is (every
    digit: Python writes the shortest text that reads back the same float)."""
    if value is None:
        return ""
    if rounded and isinstance(value, float):
        if column == "wall_time":
            return datetime.fromtimestamp(value, tz=timezone.utc).isoformat(timespec="seconds")
        return f"{value:.4f}"
    return value


@click.command("results")
@click.argument("run")
@runs_dir_option
@part_option
@click.option("--json", "as_json", is_flag=True, help="Print JSON (every column) instead of a table.")
@click.option("--csv", "as_csv", is_flag=True, help="Print CSV (every column, a header line first) instead of a table.")
@click.option("--rounded", is_flag=True, help="With --csv: numbers to four decimals and the wall-clock time as "
              "ISO 8601 (UTC), for a spreadsheet; without it --csv keeps every digit and the time in Unix seconds.")
@click.option("--failed", is_flag=True, help="Only results not proven to conform: does not conform, "
              "uncertain, not done, cannot be done.")
@click.option("--qif", "qif_file", type=click.Path(path_type=Path),
              help="Write every result as one QIF 3.0 results document to this file (atomically) instead "
                   "of printing them.")
@reports_errors
def results(run: str, runs_dir: Path | None, part_dir: Path | None, as_json: bool, as_csv: bool,
            rounded: bool, failed: bool, qif_file: Path | None) -> None:
    """List the results of RUN (an id, a unique prefix of one, or "last").

    Per result: kind, tool, nominal, measured value, deviation, tolerance, expanded
    uncertainty U = k u, U over the tolerance band, and the decision: conforms (inside
    the tolerance shrunk by U), does not conform (outside it grown by U), or uncertain
    (in between), as ISO 14253-1 asks, with the reason for every result not proven to
    conform.  Millimetres throughout.  --csv and --json carry every column (also the
    limits, u, k, position in the band, times and the spec's point).  With --part, RUN
    must be a run of that part ("last": its last run).

    --qif FILE writes the run as a QIF 3.0 results document (ISO 23952) for a quality
    system: per result its characteristic (definition with the tolerance, nominal,
    item named by the spec id), feature, device and measurement (value with its
    uncertainty, status PASS, FAIL, INDETERMINATE or NOT_ANALYZED), the overall
    inspection status from the part's verdict, and the run's traceability.  The part's
    specs (of --part, else of the run's part) give the features' directions.
    """
    from ita.report.data import COLUMNS

    if as_json and as_csv:
        raise click.UsageError("--json and --csv exclude each other")
    if rounded and not as_csv:
        raise click.UsageError("--rounded goes with --csv")
    if qif_file is not None:
        if as_json or as_csv or failed:
            raise click.UsageError("--qif writes every result to its file: it excludes --json, --csv and --failed")
        _write_qif(run, runs_dir, part_dir, qif_file)
        return
    with open_archive(runs_dir) as archive:
        run_id = resolve_run(archive, run, part_dir)
        rows = [result_dict(r) for r in archive.results(run_id, failed_only=failed)]
        info = archive.run(run_id)
    if as_json:
        click.echo(json.dumps({"run": run_id, "columns": list(COLUMNS), "results": rows}, indent=2))
        return
    if as_csv:
        out = csv.DictWriter(sys.stdout, fieldnames=list(COLUMNS), lineterminator="\n")
        out.writeheader()
        for row in rows:
            out.writerow({k: _csv_cell(k, v, rounded) for k, v in row.items()})
        return
    click.echo(f"run {run_id}: {info.part}, {info.state_label}, {info.done} of "
               f"{info.total if info.total is not None else '?'} done"
               + (f"; {len(rows)} not proven to conform" if failed else ""))
    if not rows:
        return
    table = [(str(r["seq"]), r["spec_id"], r["kind"] or "-", r["tool"] or "-", _num(r["nominal"]), _num(r["value"]),
              _signed(r["deviation"]), f"{r['lower']:+.4f}/{r['upper']:+.4f}", _num(r["U"]),
              "-" if r["U_over_tolerance"] is None else f"{100 * r['U_over_tolerance']:.0f}%",
              r["decision"].replace("_", " "), r["reason"] or "") for r in rows]
    header = ("#", "SPEC", "KIND", "TOOL", "NOMINAL", "VALUE", "DEVIATION", "TOLERANCE", "U", "U/TOL", "DECISION",
              "REASON")
    widths = [max(len(x) for x in col) for col in zip(header, *table)]
    right = {0, 4, 5, 6, 8, 9}
    for line in (header, *table):
        click.echo("  ".join(c.rjust(w) if i in right else c.ljust(w)
                             for i, (c, w) in enumerate(zip(line, widths))).rstrip())


def _write_qif(run: str, runs_dir: Path | None, part_dir: Path | None, qif_file: Path) -> None:
    from ita.files.atomic import output_path
    from ita.qif.results import export_run

    output_path(qif_file, what="--qif")  # refuse before the work, not after
    with open_archive(runs_dir) as archive:
        run_id = resolve_run(archive, run, part_dir)
        done = export_run(archive, run_id, qif_file, part_dir=part_dir)
    for warning in done.warnings:
        click.echo(f"warning: {warning}", err=True)
    click.echo(f"{done.path}: QIF 3.0 results of run {done.run_id} ({done.results} results, "
               f"inspection status {done.inspection_status})")
