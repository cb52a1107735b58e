"""`ita spc`: statistical process control of one design's characteristics across serials."""

from __future__ import annotations

import json
import math
from pathlib import Path

import click

from ita.cli.common import part_option, reports_errors
from ita.cli.runs import open_archive, runs_dir_option
from ita.specs.model import MeasurementKind

__all__ = ["spc"]


def _num(x: float | None, digits: int = 4) -> str:
    return "-" if x is None or not math.isfinite(x) else f"{x:.{digits}f}"


@click.command("spc")
@part_option
@runs_dir_option
@click.option("--kind", type=click.Choice([k.value for k in MeasurementKind]), default=None,
              help="Only characteristics of this kind.")
@click.option("--q", "q_level", type=click.FloatRange(0.0, 1.0, min_open=True), default=0.05, show_default=True,
              help="Benjamini-Hochberg level: the chance that an in-control set of serials has any "
                   "characteristic flagged is at most this.")
@click.option("--all", "show_all", is_flag=True, help="List every characteristic (default: the flagged ones and "
                                                        "the 20 lowest Cpk).")
@click.option("--json", "as_json", is_flag=True, help="One JSON entry per characteristic: id, n, mean, sd, cp, "
                                                        "cpk, cpk_ci, flags, and the chart's data.")
@reports_errors
def spc(part_dir: Path | None, runs_dir: Path | None, kind: str | None, q_level: float, show_all: bool,
        as_json: bool) -> None:
    """Chart every characteristic of the part's design over its serials (the runs given
    `ita inspect --serial SN`): mean, standard deviation, Cp, Cpk with its 95 % interval,
    the individuals and moving-range chart's limits, and the special causes found (one
    serial unlike the others; a step in the later serials).  The rules' p-values go through
    Benjamini-Hochberg across the characteristics, so that a thousand charts do not flag
    nearly every in-control part as plain 3-sigma rules would.  A serial's latest run
    stands for it; only measured values are charted.
    """
    from ita.part.store import load_part
    from ita.spc import chart_all, design_series

    part = load_part(part_dir)
    with open_archive(runs_dir) as archive:
        serials, series = design_series(archive, part.name, kind)
    charts = chart_all(series, q=q_level)
    flagged = [c for c in charts if c.flags]
    if as_json:
        click.echo(json.dumps({"part": part.name, "serials": [s.serial for s in serials],
                               "runs": [s.run_id for s in serials], "q": q_level,
                               "characteristics": [c.to_dict() for c in charts]}, indent=1))
        return
    if not serials:
        click.echo(f"no runs of {part.name} with a serial number (ita inspect --serial SN)", err=True)
        return
    n = len(serials)
    beyond = sum(1 for c in charts if c.beyond_3_sigma)
    click.echo(f"{part.name}: {n} serials ({serials[0].serial} .. {serials[-1].serial}), {len(charts)} "
               f"characteristics; {len(flagged)} flagged (Benjamini-Hochberg, q = {q_level:g}); "
               f"{beyond} with a point beyond 3 sigma (not flagged on that alone)")
    if n < 5:
        click.echo(f"note: {n} serials: the step rule needs 5, the point rule 4; Cpk's interval is wide", err=True)
    shown = flagged + sorted((c for c in charts if not c.flags and c.cpk is not None),
                             key=lambda c: c.cpk if c.cpk is not None else math.inf)
    if not show_all:
        shown = shown[:len(flagged) + 20]
    header = f"{'CHARACTERISTIC':16s} {'KIND':18s} {'N':>3s} {'MEAN':>10s} {'SD':>8s} {'CP':>6s} {'CPK':>6s} " \
             f"{'CPK 95 %':>15s}  FLAG"
    click.echo(header)
    for c in shown:
        ci = "-" if c.cpk_ci is None else f"{c.cpk_ci[0]:.2f}..{c.cpk_ci[1]:.2f}"
        flag = "; ".join(f"{f.rule} at {','.join(f.serials)} (q {f.q:.2g})" for f in c.flags)
        click.echo(f"{c.series.id:16s} {c.series.kind:18s} {c.n:3d} {_num(c.mean):>10s} {_num(c.sd):>8s} "
                   f"{_num(c.cp, 2):>6s} {_num(c.cpk, 2):>6s} {ci:>15s}  {flag}")
