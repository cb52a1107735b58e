"""`ita inspect`, `ita continue`, `ita monitor`: run an inspection, continue one, watch one.

    ita inspect [--part DIR] [--limit N] [--seed S] [--runs-dir DIR] [--json]
                [--faults RATE] [--fault-kinds K,...] [--inject FAULT[@TARGET][:after=S]]
    ita continue RUN [--runs-dir DIR] [--json]
    ita monitor RUN [--stop | --interrupt] [--once] [--interval S] [--runs-dir DIR]

The live view goes to stderr: a progress bar redrawn in place on a terminal, plain lines
otherwise.  Ctrl-C once: INTERRUPT (the current measurement finishes, everything is
saved, and the command to continue is printed); twice: STOP now.  Exit codes: 0 the run
completed; 3 it was interrupted or stopped (continue it with `ita continue RUN`); 2 bad
input.
"""

from __future__ import annotations

import json
import sys
import time
from pathlib import Path
from typing import Any

import click

from ita.cli.common import part_option, reports_errors
from ita.cli.runs import format_duration, runs_dir_option

NOT_FINISHED = 3


class LiveView:
    """Progress on stderr: in place on a TTY, a line every `every` s otherwise."""

    def __init__(self, stream: Any = None, every: float = 5.0) -> None:
        self.stream = stream or sys.stderr
        self.tty = bool(getattr(self.stream, "isatty", lambda: False)())
        self.every = every
        self._last = 0.0

    def note(self, text: str) -> None:
        if self.tty:
            self.stream.write("\r\033[K")
        print(text, file=self.stream, flush=True)

    def __call__(self, p: Any) -> None:
        now = time.monotonic()
        final = p.status != "measuring"
        if not self.tty and not final and now - self._last < self.every:
            return
        self._last = now
        width = 24
        frac = p.done / p.total if p.total else 1.0
        filled = round(frac * width)
        bar = "#" * filled + "-" * (width - filled)
        eta = "?" if p.eta_wall_s is None else format_duration(p.eta_wall_s)
        eta_sim = "?" if p.eta_sim_s is None else format_duration(p.eta_sim_s)
        group = "-" if p.group is None else str(p.group + 1)
        line = (f"[{bar}] {p.done}/{p.total}  group {group} {p.tool or '-'}  {p.spec_id or '-'}  "
                f"sim {format_duration(p.sim_s)}  wall {format_duration(p.wall_s)}  "
                f"left ~{eta} wall, ~{eta_sim} sim  exceptions {p.exceptions}")
        if self.tty:
            self.stream.write("\r\033[K" + line[:200])
            if final:
                self.stream.write("\n")
            self.stream.flush()
        else:
            print(line, file=self.stream, flush=True)


def _summary_text(summary: Any) -> str:
    d = summary.to_dict()
    lines = [f"run {summary.run_id}: {summary.status}, {summary.done}/{summary.total} results",
             "  " + ", ".join(f"{k} {v}" for k, v in sorted(summary.counts.items())),
             f"  simulated cycle time {format_duration(summary.sim_end_s)} ({summary.sim_end_s:.0f} s)"
             f"; wall-clock {summary.wall_s:.1f} s for {summary.measured_now} results"
             + (f" ({d['wall_s_per_measurement'] * 1000:.0f} ms each)" if d["wall_s_per_measurement"] else ""),
             "  breakdown: " + ", ".join(f"{k} {v:.0f} s" for k, v in summary.breakdown.items() if v > 0),
             f"  exceptions {summary.exceptions}; SLRA scans {summary.frames}"]
    if summary.continue_hint:
        lines.append(f"  continue with: {summary.continue_hint}")
    return "\n".join(lines)


def _attach_injector(session: Any, archive: Any, run_id: str) -> None:
    """Switch the run's fault injection on (its settings' "faults"), logging apart."""
    from ita.sim.inject import FaultInjector, InjectionPlan, injected_log

    spec = archive.run(run_id).settings.get("faults")
    if not spec:
        return
    plan = InjectionPlan.parse(spec.get("rate", 0.0), ",".join(spec.get("kinds", [])) or None,
                               spec.get("scripted", []), spec.get("seed", 0))
    injector = FaultInjector(session.world, plan, injected_log(archive.path.parent, run_id), poses=session.reasoner)
    session.arm.injector = session.slra.injector = injector


def _run(session: Any, archive: Any, run_id: str, as_json: bool, view: LiveView) -> None:
    from ita.toplevel import RunSignals, TopLevel

    _attach_injector(session, archive, run_id)
    with RunSignals(message=sys.stderr) as signals:
        summary = TopLevel(session, archive, run_id, signals).run(on_progress=view)
    if as_json:
        click.echo(json.dumps(summary.to_dict(), indent=1))
    else:
        click.echo(_summary_text(summary))
    if summary.status != "completed":
        click.echo(f"to continue: ita continue {run_id}", err=True)
        raise SystemExit(NOT_FINISHED)


@click.command("inspect")
@part_option
@click.option("--limit", type=click.IntRange(min=1), default=None, help="Only the first N measurements of the sequence.")
@click.option("--seed", type=int, default=0, show_default=True, help="Seed of the simulated workcell.")
@runs_dir_option
@click.option("--json", "as_json", is_flag=True, help="Print the summary as JSON at the end.")
@click.option("--faults", "fault_rate", type=float, default=0.0, show_default=True, metavar="RATE",
              help="Inject faults: each command meets one with probability RATE (0..1), drawn from the "
                   "simulator's fault modes; deterministic for a --seed.  Logged apart in the runs "
                   "directory's faults/ (only scoring reads it).")
@click.option("--fault-kinds", default=None, metavar="K,...",
              help="The fault kinds --faults draws from (default all injectable: broken_probe, worn_probe, "
                   "dry_couplant, empty_couplant, sensor_garbage, transient, controller_silent, obstacle, "
                   "dirty_window).")
@click.option("--inject", "scripts", multiple=True, metavar="FAULT[@TARGET][:after=S]",
              help="Script one fault, e.g. broken_probe@us_probe_1:after=120 (simulated seconds); repeatable.")
@reports_errors
def inspect(part_dir: Path | None, limit: int | None, seed: int, runs_dir: Path | None, as_json: bool,
            fault_rate: float, fault_kinds: str | None, scripts: tuple[str, ...]) -> None:
    """Inspect the part (in the simulated workcell): every measurement of the sequence
    plan, planned, executed, measured and recorded in the runs archive as it is made.

    Prepares the part first when needed (sequence plan, MKB, MACROPs).  A measurement
    that fails goes to the Exception Handler (diagnosis by tests in the cell, recovery,
    a second attempt).  Ctrl-C once interrupts after the current measurement; twice stops
    at once.  Exit codes: 0 completed; 3 interrupted or stopped (ita continue RUN); 2 bad
    input.  --seed is the simulator's noise (and the fault injection's draws).
    """
    from ita.archive import Archive, archive_path
    from ita.sim.inject import InjectionPlan
    from ita.toplevel import open_session, start_run

    injection = InjectionPlan.parse(fault_rate, fault_kinds, scripts, seed)   # bad options fail before any work
    view = LiveView()
    session = open_session(part_dir, seed=seed, progress=lambda m: view.note(f"{m} ..."))
    try:
        with Archive.open(archive_path(runs_dir)) as archive:
            run_id = start_run(session, archive, limit=limit,
                               settings={"faults": injection.to_dict()} if injection.active else None)
            view.note(f"run {run_id}: {archive.run(run_id).total} measurements of {session.ctx.part_name} "
                      f"(set up in {session.setup_seconds:.1f} s)")
            _run(session, archive, run_id, as_json, view)
    finally:
        session.close()


@click.command("continue")
@click.argument("run")
@runs_dir_option
@click.option("--json", "as_json", is_flag=True, help="Print the summary as JSON at the end.")
@reports_errors
def continue_(run: str, runs_dir: Path | None, as_json: bool) -> None:
    """Continue RUN (an id, a unique prefix, or "last") after an INTERRUPT, a STOP or a
    killed process: every measurement without a result is done; none is done twice."""
    from ita.archive import Archive, archive_path
    from ita.toplevel import open_session

    view = LiveView()
    with Archive.open(archive_path(runs_dir), create=False) as archive:
        run_id = archive.resolve(run)
        info = archive.run(run_id)
        part_arg = info.settings.get("part_arg")
        archive.resume_run(run_id)
        session = open_session(Path(part_arg) if part_arg else None, seed=info.seed or 0,
                               progress=lambda m: view.note(f"{m} ..."))
        try:
            view.note(f"continuing run {run_id}: {info.done}/{info.total} done")
            _run(session, archive, run_id, as_json, view)
        finally:
            session.close()


def _monitor_line(archive: Any, run_id: str) -> tuple[str, bool]:
    info = archive.run(run_id)
    counts = archive.decision_counts(run_id)
    n_exc = len(archive.events(run_id, kinds=["exception"]))
    line = (f"{time.strftime('%H:%M:%S')}  {run_id}  {info.state_label}  {info.done}/{info.total or '?'}  "
            f"sim {format_duration(info.sim_time)}  " + ", ".join(f"{k} {v}" for k, v in sorted(counts.items()))
            + f"  exceptions {n_exc}")
    running = info.status.value == "running" and info.alive is not False
    return line, running


@click.command("monitor")
@click.argument("run")
@click.option("--stop", "send", flag_value="STOP", default=None, help="Send STOP: halt now.")
@click.option("--interrupt", "send", flag_value="INTERRUPT", help="Send INTERRUPT: halt after the current plan.")
@click.option("--once", is_flag=True, help="Print the summary once and leave.")
@click.option("--interval", type=float, default=2.0, show_default=True, help="Seconds between refreshes.")
@runs_dir_option
@reports_errors
def monitor(run: str, send: str | None, once: bool, interval: float, runs_dir: Path | None) -> None:
    """Watch RUN from another terminal (its summary, refreshed from the archive until it
    ends), or send it STOP or INTERRUPT."""
    from ita.archive import Archive, archive_path

    with Archive.open(archive_path(runs_dir), create=False) as archive:
        run_id = archive.resolve(run)
        if send is not None:
            request = archive.issue_control(run_id, send)
            click.echo(f"{send} sent to run {run_id} (request {request})")
            return
        while True:
            line, running = _monitor_line(archive, run_id)
            click.echo(line)
            if once or not running:
                return
            try:
                time.sleep(interval)
            except KeyboardInterrupt:
                return
