"""`ita campaign FILE.toml` runs a study of many inspections; `ita campaign report DIR`."""

from __future__ import annotations

import json
from pathlib import Path

import click

from ita.cli.common import reports_errors


class _FileOrCommand(click.Group):
    """`ita campaign FILE.toml ...` is `ita campaign run FILE.toml ...`."""

    def resolve_command(self, ctx: click.Context, args: list[str]
                        ) -> tuple[str | None, click.Command | None, list[str]]:
        if args and args[0] not in self.commands and not args[0].startswith("-"):
            args = ["run", *args]
        return super().resolve_command(ctx, args)


@click.group(cls=_FileOrCommand)
def campaign() -> None:
    """Studies of many inspection runs: `ita campaign FILE.toml` runs one (a gauge R&R
    study, a false-accept rate, a fault campaign), `ita campaign report DIR` gives its
    figures.

    The file (TOML) names the parts (generator seeds: `ita part new`), the appraisers
    (simulator seeds) and trials, the measurements per run, the fault rate and the arms
    that work each run (`arms = 2`: both of the workcell's); see docs/campaigns.md.  Runs go to a local pool (--workers) or to an existing Dask
    cluster (--cluster ADDRESS); each lands in the campaign archive when it ends, and the
    same command started again runs only what is missing."""


@campaign.command("run")
@click.argument("file", type=click.Path(path_type=Path, dir_okay=False))
@click.option("--out", "out_dir", type=click.Path(path_type=Path, file_okay=False), default=None,
              help="The campaign's directory (archive, parts, prepared stores).  Default: FILE's name "
                   "with .campaign beside it.")
@click.option("--workers", type=click.IntRange(1, 256), default=1, show_default=True,
              help="Runs at once on this machine (each a process of its own).")
@click.option("--cluster", default=None, metavar="ADDRESS",
              help="A Dask distributed scheduler (tcp://host:8786) to run on instead of the local pool.")
@reports_errors
def run(file: Path, out_dir: Path | None, workers: int, cluster: str | None) -> None:
    """Run the campaign FILE.toml (the runs its archive does not hold yet)."""
    from ita.campaign.execute import run_campaign
    from ita.campaign.study import load_campaign

    c = load_campaign(file)
    out = out_dir or file.with_suffix(".campaign")
    summary = run_campaign(c, out, workers=workers, cluster=cluster, progress=lambda m: click.echo(m, err=True))
    click.echo(f"campaign {c.name}: {summary['runs']} runs; ran {summary['ran']}, failed {summary['failed']} "
               f"in {summary['wall_s']:.0f} s; archive {out}/campaign.sqlite; figures: ita campaign report {out}")
    if summary["failed"]:
        raise SystemExit(1)


@campaign.command("report")
@click.argument("directory", type=click.Path(path_type=Path, file_okay=False, exists=True))
@click.option("--json", "as_json", is_flag=True, help="Print the figures as JSON.")
@click.option("--plots", type=click.Path(path_type=Path, file_okay=False), default=None,
              help="Write one PNG per kind here (errors by appraiser, the gauge study's deviations).")
@reports_errors
def report(directory: Path, as_json: bool, plots: Path | None) -> None:
    """Per kind: crossed gauge R&R (ANOVA: %GRR, ndc, repeatability, reproducibility), bias
    against the truth, false accepts with the 95 % upper bound of their rate; for fault
    campaigns the measured share and the diagnoses that named the injected cause."""
    from ita.campaign.report import campaign_report, format_report, plot_kinds

    rep = campaign_report(directory)
    if plots is not None:
        for p in plot_kinds(directory, rep, plots):
            click.echo(f"wrote {p}", err=True)
    click.echo(json.dumps(rep, indent=1, default=str) if as_json else format_report(rep))
