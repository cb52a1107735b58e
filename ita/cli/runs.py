"""`ita runs`: list the runs in the results archive.  Also the archive options shared by
`ita results` and `ita report`."""

from __future__ import annotations

import json
from pathlib import Path

import click

from ita.cli.common import reports_errors

runs_dir_option = click.option(
    "--runs-dir",
    type=click.Path(path_type=Path, file_okay=False),
    default=None,
    help="Directory of the runs archive (default: $ITA_RUNS, else ITA_HOME/runs).",
)


def open_archive(runs_dir: Path | None):
    """The archive in `runs_dir` for reading; NoArchive (exit 2) when there is none."""
    from ita.archive import Archive, archive_path

    return Archive.open(archive_path(runs_dir), create=False)


def resolve_run(archive, ref: str, part_dir: Path | None = None) -> str:
    """The run id `ref` names; with `part_dir` (--part), "last" is the last run of that part
    and a run of another part is refused (ArchiveError, exit 2)."""
    from ita.archive import ArchiveError, UnknownRun

    if part_dir is None:
        return archive.resolve(ref)
    want = Path(part_dir).expanduser().resolve()

    def mine(info) -> bool:
        dirs = [d for d in (info.part_dir, info.settings.get("part_arg")) if d]
        return any(Path(d).resolve() == want for d in dirs)

    if ref.strip() == "last":
        runs = [r for r in archive.runs() if mine(r)]
        if not runs:
            raise UnknownRun(f"no run of the part in {want} in {archive.path}")
        return runs[-1].id
    run_id = archive.resolve(ref)
    info = archive.run(run_id)
    if not mine(info):
        raise ArchiveError(f"run {run_id} is of the part in {info.part_dir or '(unknown)'}, not of {want}")
    return run_id


def format_duration(seconds: float | None) -> str:
    """h:mm:ss, or '-' for None."""
    if seconds is None:
        return "-"
    s = round(seconds)
    return f"{s // 3600}:{s % 3600 // 60:02d}:{s % 60:02d}"


@click.command("runs")
@runs_dir_option
@click.option("--json", "as_json", is_flag=True, help="Print JSON instead of a table.")
@reports_errors
def runs(runs_dir: Path | None, as_json: bool) -> None:
    """List the runs: id, part, status, results measured (with a value) of total, simulated cycle time, start,
    the verdict over the run's measurements (accept: every one conforms; reject: one does
    not; incomplete: otherwise, or not ended), and the serial and operator it was given.

    A run whose process died (killed, crashed) shows as "dead" and can be continued.
    """
    from ita.archive import NoArchive
    from ita.report.data import run_verdict as verdict

    try:
        archive = open_archive(runs_dir)
    except NoArchive as exc:
        if as_json:
            click.echo("[]")
        else:
            click.echo(f"no runs ({exc})", err=True)
        return
    with archive:
        infos = archive.runs()
        # "measured": results with a value (not done and cannot be done are results without one)
        measured = {r.id: r.done - sum(n for k, n in archive.decision_counts(r.id).items()
                                       if k in ("not_done", "cannot_be_done")) for r in infos}
    if as_json:
        click.echo(json.dumps([{
            "id": r.id, "part": r.part, "part_dir": r.part_dir, "seed": r.seed, "status": r.status.value,
            "state": r.state_label, "done": r.done, "measured": measured[r.id], "total": r.total,
            "sim_time": r.sim_time,
            "created": r.created, "ended": r.ended, "settings": r.settings, "totals": r.totals,
            "verdict": verdict(r), "serial": r.settings.get("serial"), "operator": r.settings.get("operator"),
        } for r in infos], indent=2))
        return
    if not infos:
        click.echo("no runs", err=True)
        return
    rows = [(r.id, r.part, r.state_label, f"{measured[r.id]}/{r.total if r.total is not None else '?'}",
             format_duration(r.sim_time), r.created.replace("T", " ").replace("+00:00", "Z"), verdict(r),
             r.settings.get("serial") or "-", r.settings.get("operator") or "-") for r in infos]
    header = ("RUN", "PART", "STATUS", "MEASURED", "SIM TIME", "STARTED (UTC)", "VERDICT", "SERIAL", "OPERATOR")
    widths = [max(len(str(x)) for x in col) for col in zip(header, *rows)]
    for row in (header, *rows):
        click.echo("  ".join(str(c).ljust(w) for c, w in zip(row, widths)).rstrip())
