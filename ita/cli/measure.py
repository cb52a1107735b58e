"""`ita measure MEAS_ID`: take one measurement in the simulated workcell and print it.

    ita measure HD-OF-101 [--render scan.png] [--part DIR] [--seed S] [--json]

The arm starts at home with no tool; the Operation Planner's plan fetches the right tool,
the Executive runs it on the simulated devices (Path Planner and controller, gauge,
SLRA and Vision), and the value, its uncertainty, the nominal, the tolerance and the
ISO 14253-1 decision are printed.  --render writes the range image with Vision's patches
and fitted features (SLRA measurements).  Nothing is recorded in the runs archive.
Exit codes: 0 measured; 1 not measured (the reason is printed); 2 bad input.
"""

from __future__ import annotations

import json
from pathlib import Path

import click

from ita.cli.common import part_option, reports_errors


@click.command("measure")
@click.argument("meas_id")
@part_option
@click.option("--render", type=click.Path(path_type=Path, dir_okay=False), default=None,
              help="Write the SLRA range image with patches and fitted features here (PNG).")
@click.option("--seed", type=int, default=0, show_default=True, help="Seed of the simulated workcell.")
@click.option("--json", "as_json", is_flag=True, help="Print JSON.")
@reports_errors
def measure(meas_id: str, part_dir: Path | None, render: Path | None, seed: int, as_json: bool) -> None:
    """Move the simulated arm with the right tool to MEAS_ID, measure, print the result."""
    from ita.archive import decide
    from ita.errors import InputError, Location
    from ita.planning import NoPlanError, WorldState
    from ita.sequence.next_step import the_arm
    from ita.toplevel import open_session
    from ita.toplevel.loop import TopLevel

    session = open_session(part_dir, seed=seed, progress=lambda m: click.echo(f"{m} ...", err=True))
    try:
        spec = session.specs.get(meas_id)
        if spec is None:
            raise InputError([(Location(str(session.part.specs_path)), f"no measurement {meas_id!r}")])
        entry = session.mkb.entries.get(meas_id)
        out = {"id": meas_id, "kind": spec.kind.value, "nominal": spec.nominal, "lower": spec.lower,
               "upper": spec.upper, "tool": None if entry is None else entry.tool}
        reason = None
        value = u = None
        if entry is None or not entry.ok:
            reason = "cannot be done: " + ("no tool for it" if entry is None else f"{entry.status} ({entry.reason})")
        else:
            try:
                op = session.planner.plan_measurement(spec, WorldState(arm=the_arm(session.kb)))
            except NoPlanError as exc:
                op, reason = None, f"no plan: {exc.reason}"
            if op is not None:
                report = session.executive.execute(op)
                readings = session.arm.take_readings()
                vision = session.slra.take_results()
                if report.ok:
                    value, u = TopLevel._value(meas_id, report, readings, vision)
                else:
                    reason = report.failure.reason
                out.update(steps=len(op.steps), macrop=op.macrop_name, sim_s=round(report.makespan, 3))
                if render is not None and session.slra.last_frame is not None and meas_id in vision:
                    from ita.vision.render import render_measurement

                    render_measurement(session.slra.last_frame, spec, session.slra.vctx, vision[meas_id], render)
                    out["render"] = str(render)
                elif render is not None:
                    click.echo("note: --render draws SLRA measurements only; nothing drawn", err=True)
        if value is not None:
            decision = decide(value, 2.0 * u, spec.low_limit, spec.high_limit)
            out.update(value=value, u=u, U=2.0 * u, decision=decision.value)
        else:
            out.update(reason=reason)
    finally:
        session.close()
    if as_json:
        click.echo(json.dumps(out, indent=1))
    elif value is not None:
        click.echo(f"{meas_id} ({spec.kind.value}, {out['tool']}): {value:.4f} mm  u {u:.4f}  U {2 * u:.4f} (k=2)")
        click.echo(f"  nominal {spec.nominal:g}  tolerance {spec.lower:+g}/{spec.upper:+g}  "
                   f"limits [{spec.low_limit:g}, {spec.high_limit:g}]  decision {out['decision']}")
        if "render" in out:
            click.echo(f"  range image: {out['render']}")
    else:
        click.echo(f"{meas_id}: not measured: {reason}")
    raise SystemExit(0 if value is not None else 1)
