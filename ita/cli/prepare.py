"""`ita prepare`: the offline preparation of a part for inspection (the main job for now)."""

from __future__ import annotations

import json
import time
from collections.abc import Callable
from pathlib import Path

import click

from typing import TYPE_CHECKING

from ita.cli.common import arm_option, part_option, reports_errors

if TYPE_CHECKING:
    from ita.offline.prepare import PrepareReport


@click.command()
@part_option
@click.option("--json", "as_json", is_flag=True, help="Print the report as JSON.")
@click.option("-q", "--quiet", is_flag=True, help="No progress lines.")
@click.option("--force", is_flag=True, help="Remake the sequence plan and the MKB even when current.")
@arm_option
@click.option("--arms", "arms", type=click.IntRange(1, 2), default=1, show_default=True,
              help="2: prepare the part as each of the cell's two arms works it and store the allocation "
                   "between them, so that `ita inspect --arms 2` starts at once.")
@reports_errors
def prepare(part_dir: Path | None, as_json: bool, quiet: bool, force: bool, arm: str | None, arms: int) -> None:
    """Prepare a part for inspection, offline.

    Builds the part (the built-in bulkhead is generated on first use), validates its
    measurement specs against it, tests the arm's reach for every spec, loads and checks
    the knowledge bases; then makes the sequence plan and the measurement knowledge base
    (MKB: poses, approach points, SLRA views) and warms the MACROP store, so that
    `ita inspect` starts at once; reports what cannot be done and why. Exit code 0 when everything is clean,
    1 when the knowledge bases have problems, 2 when the part or its specs are bad.
    """
    from ita.offline.prepare import prepare as run

    t0 = time.perf_counter()

    def progress(message: str) -> None:
        if not quiet:
            click.echo(f"[{time.perf_counter() - t0:6.1f} s] {message} ...", err=True)

    if arms == 2:
        if arm is not None:
            raise click.UsageError("--arms 2 prepares both arms; --arm names one arm working alone")
        _prepare_two_arms(part_dir, progress, force, as_json)
        return
    report = run(part_dir, progress, force=force, arm=arm)
    if as_json:
        click.echo(json.dumps(report.to_dict(), indent=1))
    else:
        _print_report(report)
    raise SystemExit(0 if report.ok else 1)


def _prepare_two_arms(part_dir: Path | None, progress: Callable[[str], None], force: bool, as_json: bool) -> None:
    from ita.offline.prepare import prepare_two_arms

    reports, allocation, kept = prepare_two_arms(part_dir, progress, force=force)
    ok = allocation is not None
    if as_json:
        click.echo(json.dumps({"arms": [r.to_dict() for r in reports],
                               "allocation": None if allocation is None else allocation.as_dict() | {"kept": kept}},
                              indent=1))
    else:
        for report in reports:
            _print_report(report)
        if allocation is not None:
            click.echo("allocation  " + ", ".join(f"{s.arm} {s.count} measurements ({s.time_s:.0f} s)"
                                                  for s in allocation.shares)
                       + f"; makespan {allocation.makespan_s:.0f} s, one arm {allocation.one_arm_s:.0f} s"
                       + ("; stored, current: kept" if kept else "; stored"))
    raise SystemExit(0 if ok else 1)


def _print_report(report: PrepareReport) -> None:
    p = report.part
    click.echo(f"part        {p.name}  ({p.directory})")
    click.echo(f"size        {p.size[0]:.1f} x {p.size[1]:.1f} x {p.size[2]:.1f} mm, "
               f"{p.triangles} triangles, {'watertight' if p.watertight else 'NOT watertight'}")
    click.echo(f"features    {p.feature_count}: " + ", ".join(f"{k} {n}" for k, n in p.features if n))
    click.echo(f"specs       {p.spec_count} valid: " + ", ".join(f"{k} {n}" for k, n in p.specs if n))
    click.echo(report.reach_text)
    click.echo(f"knowledge   {len(report.kb_files)} Prolog files, {report.kb_predicates} "
               f"documented predicates; check: "
               + ("clean" if not report.kb_problems else f"{len(report.kb_problems)} problems"))
    for problem in report.kb_problems:
        click.echo(f"  {problem}")
    if report.inspection is not None:
        click.echo(report.inspection.text())
    click.echo("time        " + ", ".join(f"{k} {s:.2f} s" for k, s in report.seconds)
               + f"; total {sum(s for _k, s in report.seconds):.1f} s")
