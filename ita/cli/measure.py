"""`ita measure MEAS_ID`: take one measurement in the simulated workcell and print it.

    ita measure HD-OF-101 [--render scan.png] [--part DIR] [--seed S] [--json]

The arm starts at home with no tool; the measurement takes the same round trip as in a
run (ita.task.measure.measure_one): the tool the sequence plan chose, the Operation
Planner's plan (MACROP lookup first), the Executive on the simulated devices (Path
Planner and controller, gauge, SLRA and Vision), the value back in the devices' replies.
The value, its uncertainty, the nominal, the tolerance and the ISO 14253-1 decision are
printed.  --render writes the range image with Vision's patches and fitted features
(SLRA measurements).  Nothing is recorded in the runs archive.
Exit codes: 0 measured; 1 not measured (the reason is printed); 2 bad input.
"""

from __future__ import annotations

import json
from pathlib import Path

import click

from ita.cli.common import part_option, reports_errors, seed_option


@click.command("measure")
@click.argument("meas_id")
@part_option
@click.option("--render", type=click.Path(path_type=Path, dir_okay=False), default=None,
              help="Write the SLRA range image with patches and fitted features here (PNG).")
@seed_option()
@click.option("--json", "as_json", is_flag=True, help="Print JSON.")
@reports_errors
def measure(meas_id: str, part_dir: Path | None, render: Path | None, seed: int, as_json: bool) -> None:
    """Move the simulated arm with the right tool to MEAS_ID, measure, print the result."""
    from ita.archive import decide
    from ita.archive.model import BOUNDED_BELOW
    from ita.errors import InputError, Location
    from ita.part.store import load_part
    from ita.planning import WorldState
    from ita.sequence.next_step import the_arm
    from ita.specs.io import read_specs
    from ita.task import MeasureStatus, measure_one, open_session

    part = load_part(part_dir)
    if meas_id not in {s.id for s in read_specs(part.specs_path)}:   # before loading the world
        raise InputError([(Location(str(part.specs_path)), f"no measurement {meas_id!r}")])
    session = open_session(part_dir, seed=seed, progress=lambda m: click.echo(f"{m} ...", err=True))
    try:
        spec = session.specs[meas_id]
        tool = session.planned_tool(meas_id)
        out = {"id": meas_id, "kind": spec.kind.value, "nominal": spec.nominal, "lower": spec.lower,
               "upper": spec.upper, "tool": tool}
        value = u = None
        reason: str | None
        if tool is None:
            why = dict(session.plan.cannot).get(meas_id, "no tool for it")
            reason = f"cannot be done: {why}"
        else:
            result = measure_one(session, meas_id, WorldState(arm=the_arm(session.kb)), tool)
            reason = result.reason
            if result.status is MeasureStatus.CANNOT_BE_DONE:
                reason = f"cannot be done: {result.reason}"
            elif result.status is MeasureStatus.MEASURED and result.value is not None:
                value, u = result.value.value, result.value.u
            if result.plan is not None and result.report is not None:
                out.update(steps=len(result.plan.steps), macrop=result.plan.macrop_name,
                           sim_s=round(result.report.makespan, 3))
            frames = result.frames
            if render is not None and frames and result.value is not None:
                from ita.vision.render import render_measurement

                render_measurement(frames[0], spec, session.slra.vctx, result.value.source, render)
                out["render"] = str(render)
            elif render is not None:
                click.echo("note: --render draws SLRA measurements only; nothing drawn", err=True)
        if value is not None and u is not None:
            decision = decide(value, 2.0 * u, spec.low_limit, spec.high_limit,
                              bounded_below=spec.kind.value in BOUNDED_BELOW)
            out.update(value=value, u=u, U=2.0 * u, decision=decision.value)
        else:
            out.update(reason=reason)
    finally:
        session.close()
    if as_json:
        click.echo(json.dumps(out, indent=1))
    elif value is not None and u is not None:
        click.echo(f"{meas_id} ({spec.kind.value}, {out['tool']}): {value:.4f} mm  u {u:.4f}  U {2 * u:.4f} (k=2)")
        click.echo(f"  nominal {spec.nominal:g}  tolerance {spec.lower:+g}/{spec.upper:+g}  "
                   f"limits [{spec.low_limit:g}, {spec.high_limit:g}]  decision {out['decision']}")
        if "render" in out:
            click.echo(f"  range image: {out['render']}")
    else:
        click.echo(f"{meas_id}: not measured: {reason}")
    raise SystemExit(0 if value is not None else 1)
