"""`ita inspect`, `ita continue`, `ita monitor`: run an inspection, continue one, watch one.

    ita inspect [--part DIR] [--limit N] [--seed S] [--runs-dir DIR] [--json]
                [--faults RATE] [--fault-kinds K,...] [--inject FAULT[@TARGET][:after=S]]
    ita continue RUN [--runs-dir DIR] [--json]
    ita monitor RUN [--stop | --interrupt] [--once] [--interval S] [--runs-dir DIR]

The live view goes to stderr: a progress line redrawn in place on a terminal (cut to the
terminal's width), plain lines otherwise.  Ctrl-C once: INTERRUPT (the current
measurement finishes, everything is saved, and the command to continue is printed);
twice: STOP now.  Exit codes: 0 the run completed; 3 it was interrupted or stopped
(continue it with `ita continue RUN`); 2 bad input.
"""

from __future__ import annotations

import contextlib
import json
import shutil
import sys
import time
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import click

from ita.archive import Event
from ita.cli.common import (
    FiniteFloatRange,
    arm_option,
    check_job,
    part_option,
    reports_errors,
    seed_option,
)
from ita.cli.runs import format_duration, runs_dir_option

NOT_FINISHED = 3


class LiveView:
    """Progress on stderr: in place on a TTY, a line every `every` s otherwise."""

    def __init__(self, stream: Any = None, every: float = 5.0) -> None:
        self.stream = stream or sys.stderr
        self.tty = bool(getattr(self.stream, "isatty", lambda: False)())
        self.every = every
        self._last = 0.0

    def columns(self) -> int:
        """The terminal's width (80 when it cannot be told)."""
        try:
            import os

            return os.get_terminal_size(self.stream.fileno()).columns
        except (OSError, AttributeError, ValueError):
            return shutil.get_terminal_size((80, 24)).columns

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
        line = progress_line(p, self.columns() if self.tty else 200)
        if self.tty:
            self.stream.write("\r\033[K" + line)
            if final:
                self.stream.write("\n")
            self.stream.flush()
        else:
            print(line, file=self.stream, flush=True)


def progress_line(p: Any, columns: int) -> str:
    """One progress line that fits in `columns` characters (less one, so that a terminal
    never wraps it): the longest of a few forms that fits, cut as a last resort."""
    frac = p.done / p.total if p.total else 1.0
    eta = "?" if p.eta_wall_s is None else format_duration(p.eta_wall_s)
    eta_sim = "?" if p.eta_sim_s is None else format_duration(p.eta_sim_s)
    group = "-" if p.group is None else str(p.group + 1)

    def bar(width: int) -> str:
        filled = round(frac * width)
        return "[" + "#" * filled + "-" * (width - filled) + "]"

    forms = [
        f"{bar(24)} {p.done}/{p.total}  group {group} {p.tool or '-'}  {p.spec_id or '-'}  "
        f"sim {format_duration(p.sim_s)}  wall {format_duration(p.wall_s)}  "
        f"left ~{eta} wall, ~{eta_sim} sim  exceptions {p.exceptions}",
        f"{bar(16)} {p.done}/{p.total} g{group} {p.tool or '-'} {p.spec_id or '-'} "
        f"sim {format_duration(p.sim_s)} left ~{eta} exc {p.exceptions}",
        f"{bar(10)} {p.done}/{p.total} {p.spec_id or '-'} left ~{eta}",
        f"{p.done}/{p.total} {p.spec_id or '-'}",
    ]
    room = max(columns - 1, 10)
    return next((f for f in forms if len(f) <= room), forms[-1][:room])


def _label(ctx: click.Context, param: click.Parameter, value: str | None) -> str | None:
    """A serial number or a name: 1 to 64 printable characters, no line breaks or controls."""
    from ita.labels import label_problem

    if value is None:
        return None
    problem = label_problem(value)
    if problem:
        raise click.BadParameter(problem)
    return value.strip()


def _summary_text(summary: Any) -> str:
    d = summary.to_dict()
    unmeasured = {k: summary.counts.get(k, 0) for k in ("not_done", "cannot_be_done")}
    measured = summary.done - sum(unmeasured.values())
    lines = [f"run {summary.run_id}: {summary.status}, {summary.done}/{summary.total} results, {measured} measured"
             + (f"\n  ALARM, the run stopped itself: {summary.alarm}" if summary.alarm else ""),
             "  " + ", ".join(f"{k} {v}" for k, v in sorted(summary.counts.items())),
             f"  simulated cycle time {format_duration(summary.sim_end_s)} ({summary.sim_end_s:.0f} s)"
             f"; wall-clock {summary.wall_s:.1f} s for {summary.measured_now} results"
             + (f" ({d['wall_s_per_measurement'] * 1000:.0f} ms each)" if d["wall_s_per_measurement"] else ""),
             "  breakdown: " + ", ".join(f"{k} {v:.0f} s" for k, v in summary.breakdown.items() if v > 0),
             f"  {summary.exceptions.text()}; SLRA scans {summary.frames}"]
    aligned = summary.alignment
    if aligned is not None:
        lines.append(f"  {aligned['line']}" if aligned.get("registered") else
                     f"  the part was NOT registered on its datums: {aligned.get('reason', '')}")
    if summary.planner:
        f = summary.planner
        lines.append(f"  top level: {f['actions']:.0f} actions of an HTN plan made in {f['plan_s']:.2f} s; "
                     f"planned again {f['replans']:.0f} times (median {f['replan_median_s'] * 1000:.1f} ms, "
                     f"largest {f['replan_max_s'] * 1000:.0f} ms)")
    if summary.cell is not None:
        cell = summary.cell
        lines.append(f"  the cell: {cell['state']}")
        for probe in cell["probes"]:
            reading = "no reading" if probe["reading_mm"] is None else f"reads {probe['reading_mm']:.4f} mm"
            lines.append(f"    {probe['probe']}: calibration block {probe['block_mm']} mm, {reading}"
                         f" ({'ok' if probe['ok'] else 'failed: ' + probe['note']})")
        for hole in cell["tooling"]:
            value = "not measured" if hole["value"] is None else \
                f"{hole['value']:.4f} (nominal {hole['nominal']:.4f}, U {hole['U']:.4f})"
            off = "" if hole["centre_off_mm"] is None else f", centre {hole['centre_off_mm']:.3f} mm off nominal"
            lines.append(f"    {hole['spec']}: {value}, {hole['decision']}{off}")
    if any(unmeasured.values()):
        said = " and ".join(f"{n} {k.replace('_', ' ')}" for k, n in unmeasured.items() if n)
        lines.append(f"  NOTE: {said}: `ita results {summary.run_id} --failed` lists them with their reasons")
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
    before = session.arm.injector
    if before is not None:      # a later run of the session (a hand-over): what landed before does not again
        injector.carry_on(before)
    session.arm.injector = session.slra.injector = injector


#: seconds a person takes to move an arm whose controller is down out of the other arm's
#: way (lock the cell's gate, release the brakes, walk the arm to its fold)
PERSON_MOVES_ARM_S = 300.0


def _moved_by_a_person(session: Any) -> bool:
    """One arm of two whose controller is down for good: a person moves it by hand to its
    fold on its base ray, out of the other arm's way, once the conductor grants the space
    (RobotController.moved_by_hand); else it stays where it stopped."""
    import numpy as np

    fold = np.asarray(_fold_of(session.ctx.workcell), dtype=float)
    fold[0] = float(session.world.q[0])
    return bool(session.arm.controller.moved_by_hand(fold, PERSON_MOVES_ARM_S))


def _fold_of(cell: Any) -> tuple[float, ...]:
    """The joints the cell's working arm folds to (the zone conductor's: ConductedArm.fold)."""
    from ita.executive.conductor import conducted_arms  # start-up: only a two-arm run's arm needs it

    return next(a.fold for a in conducted_arms(cell) if a.name == cell.arm.name)


def _park_away(session: Any) -> bool:
    """One arm of two, its share worked: fold turned away from the other arm's base."""
    cell = session.ctx.workcell
    if cell.second_arm is None:
        return False
    other = cell.second_arm.base.position
    return bool(session.arm.park_away(_fold_of(cell), (float(other[0]), float(other[1]))))


def _run(session: Any, archive: Any, run_id: str, as_json: bool, view: LiveView, parked: bool = False,
         settings: dict[str, Any] | None = None) -> None:
    """Run `run_id` and print its summary; exit 3 unless it completed.  parked: one arm of a
    two-arm run: at the end it folds out of the other's way, then waits until both arms'
    shares are worked and does what the other arm left that it can (its hand-over: a run
    of its own, `RUN-h`, with `settings`), then says it is done."""
    from ita.executive.conductor import standing_ground
    from ita.task.align import plan_around
    from ita.toplevel import RunSignals, TopLevel, start_run

    _attach_injector(session, archive, run_id)
    with RunSignals(message=sys.stderr) as signals:
        summary = TopLevel(session, archive, run_id, signals).run(on_progress=view)
    extra: dict[str, Any] = {}
    finished = summary.status == "completed"
    if parked:           # one arm of two: out of the other's way (folded, turned away from it), its zones given up
        controller = session.arm.controller
        # the last arm at work, its whole share made, when the other has folded for good
        # (told before this arm's last claim): no arm moves after it, so it stays where its
        # last check left it, as a one-arm run's arm does; else it folds and says so
        stays = (finished and summary.to_dict()["measured"] == summary.total and controller.gate is not None
                 and controller.gate.told("parked") is not None)
        away = False            # flown folded, turned away from the other arm
        if not stays:
            if session.world.faults.controller_silent:
                moved = _moved_by_a_person(session)
                archive.record_event(run_id, Event("world_update", "top", session.clock.now, {"update": (
                    "a person moved the arm out of the other's way by hand (its controller is down)" if moved
                    else "the arm's controller is down and the other arm's zones kept a person from moving it")}))
            elif _park_away(session):
                away = True
            else:
                controller.give_way()
            if controller.gate is not None:
                controller.gate.tell(session.clock.now, {"kind": "parked"})
        extra["simulated_parked_s"] = round(session.clock.now, 3)
        wait, handed = controller.gate.take(session.clock.now, f"handover:{session.ctx.workcell.arm.name}")
        session.clock.advance(wait)
        extra["handover_wait_s"] = round(wait, 3)
        if finished and isinstance(handed, dict) and handed.get("specs"):
            plan_around(session, standing_ground(session.ctx.workcell, handed.get("stands") or {}))
            hid = start_run(session, archive, run_id=f"{run_id}-h", specs=[str(i) for i in handed["specs"]],
                            settings=dict(settings or {}) | {"handed_over_after_s": round(wait, 3)})
            view.note(f"run {hid}: {archive.run(hid).total} measurements the other arm left (its hand-over)")
            _attach_injector(session, archive, hid)
            with RunSignals(message=sys.stderr) as signals:
                more = TopLevel(session, archive, hid, signals).run(on_progress=view)
            away = False                     # it worked again: it gives way below, unless it stays
            extra["handover"] = more.to_dict() | {"run_id": hid, "waited_s": round(wait, 3)}
            finished = finished and more.status == "completed"
        controller.park(give_way=not (stays or away))    # where it stands now, no one moves after it
        extra["stayed"] = stays
        stats = [controller.zone_stats, session.slra.controller.zone_stats]
        extra["zones"] = {k: round(sum(float(s[k]) for s in stats), 3) for k in stats[0]}
        extra["simulated_end_s"] = round(session.clock.now, 3)
    if as_json:
        click.echo(json.dumps(summary.to_dict() | extra, indent=1))
    else:
        click.echo(_summary_text(summary))
    if not finished:
        raise SystemExit(NOT_FINISHED)     # the summary said how to continue


def _unprefixed(script: str) -> str:
    """An --inject script without its arm (``t3_b:controller_failed:after=600``: that
    arm's alone, in a two-arm run)."""
    head, colon, rest = script.partition(":")
    return rest if colon and "@" not in head and not rest.startswith("after=") else script


@dataclass(frozen=True)
class _Conducted:
    """This run as one arm of a two-arm run: its share, the tools it leaves to the other
    arm, the two-arm run's name, and the gate to the zone conductor."""

    specs: tuple[str, ...]
    away_tools: dict[str, str]          # tool -> the other arm it is kept for
    group: str
    gate: Any
    registers: bool = True              # this arm registers the part (the other takes its registration)
    tours: tuple[tuple[str, tuple[str, ...], float], ...] = ()    # its share's tours (tool, spec ids, s)


def _follow(session: Any, tours: Sequence[tuple[str, tuple[str, ...], float]]) -> None:
    """An arm's run of a two-arm run takes its share in the order of the allocation's
    tours (tool, spec ids, seconds), arranged for both arms (ita.executive.two_arms)."""
    from ita.sequence.plan import following

    if tours:
        session.plan = following(session.plan, [(t, ids) for t, ids, _c in tours], session.ctx.workcell,
                                 [c for _t, _i, c in tours])


def _conducted(fd: int) -> _Conducted:
    """Read a two-arm run's set-up from its conductor over the inherited socket `fd`."""
    import os
    import stat
    from multiprocessing.connection import Connection

    from ita.robot.gate import RemoteGate

    try:
        is_socket = stat.S_ISSOCK(os.fstat(fd).st_mode)
    except OSError as exc:
        raise click.BadParameter(f"file descriptor {fd}: {exc.strerror}", param_hint="--conductor-fd") from None
    if not is_socket:
        raise click.BadParameter(f"file descriptor {fd} is not a socket", param_hint="--conductor-fd")
    conn = Connection(fd)
    setup = conn.recv()
    return _Conducted(tuple(setup["specs"]), {str(k): str(v) for k, v in setup["away_tools"].items()},
                      str(setup["group"]), RemoteGate(conn), bool(setup.get("registers", True)),
                      tuple((str(t), tuple(map(str, ids)), float(c)) for t, ids, c in setup.get("tours", ())))


@contextlib.contextmanager
def _closing(session: Any) -> Iterator[Any]:
    """Close `session` (saving its MACROP store) at the end.  When the body failed, its
    error is the one told: a failure to save after it (the same full disk) does not hide it."""
    try:
        yield session
    except BaseException:
        with contextlib.suppress(Exception):
            session.close()
        raise
    session.close()


@click.command("inspect")
@part_option
@click.option("--limit", type=click.IntRange(min=1), default=None, help="Only the first N measurements of the sequence.")
@seed_option()
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
              help="Script one fault, e.g. broken_probe@us_probe_1:after=120 (simulated seconds); repeatable.  "
              "Besides the kinds above: position_drift, tilted_probe, slra_failed@SLRA (a laser or detector "
              "failure that cleaning does not cure), part_displaced (the part knocked on its fixture), "
              "controller_failed (the arm's controller fails for good: the arm is down).  A target the simulator "
              "cannot hit is refused with the valid pairs.  With --arms 2, ARM:FAULT... hits that arm alone "
              "(e.g. t3_b:controller_failed:after=600), FAULT... each arm.")
@click.option("--run-id", default=None, help="The id to give the new run (the System Monitor names the runs "
              "it starts); default a fresh one.")
@click.option("--alarm-after", type=click.IntRange(min=0), default=None, metavar="N",
              help="[default: 10] Stop the run with an alarm (exit 3) when N measurements in a row end not done "
              "even after the Exception Handler: something systematic is wrong; put it right and `ita "
              "continue` the run.  0: never.")
@click.option("--network/--no-network", default=True, show_default=True,
              help="Decide the fastener holes' positions by a network adjustment of the SLRA frames of each "
                   "face (pending until the face's last position frame), instead of each on its own frame.")
@click.option("--task", "job", default="inspect_part", show_default=True, metavar="NAME",
              help="The job to run: a job of kb/tasks.pl, planned by the HTN planner (`ita tasks` lists them).")
@click.option("--serial", default=None, metavar="SN", callback=_label,
              help="The serial number of the part inspected (kept with the run; `ita runs` shows it).  In "
                   "simulation a generated design's serial is its own as-built part, drawn from the serial "
                   "with the process's spread and no gross errors (ita spc charts the serials).")
@click.option("--shift", "shift_texts", multiple=True, metavar="SPEC=DELTA",
              help="With --serial: a special cause in that serial's as-built part, the feature dimension "
                   "SPEC measures moved by DELTA mm (repeatable); for checking SPC.")
@click.option("--operator", default=None, metavar="NAME", callback=_label,
              help="Who runs the inspection (kept with the run; `ita runs` shows it).")
@click.option("--from", "from_run", default=None, metavar="RUN",
              help="With --task reinspect: the run whose unproven results (uncertain, does not conform, not "
                   "done) to measure again; the new run holds those alone.")
@click.option("--placement", type=click.Choice(["fixture", "exact"]), default="fixture", show_default=True,
              help="Where the simulator seats the part: 'fixture', off its nominal placement by a draw of the "
                   "fixture's error (a few tenths of a millimetre and of a degree, from --seed), as a real "
                   "cell does; 'exact', at its nominal placement.  Either way the run registers the part on "
                   "its datums (tooling holes B and C) before it measures.")
@arm_option
@click.option("--arms", "arms", type=click.IntRange(1, 2), default=1, show_default=True,
              help="How many of the cell's arms work the part: 2, both at once (the workcell needs a second "
                   "arm, its [robot_b] table): the measurements split between them, each arm's motions "
                   "claiming their space from the other's (interference zones), each arm a run of its own.")
@click.option("--conductor-fd", "conductor_fd", type=int, default=None, hidden=True,
              help="(internal) the socket of a two-arm run's zone conductor: this run is one arm's.")
@reports_errors
def inspect(part_dir: Path | None, limit: int | None, seed: int, runs_dir: Path | None, as_json: bool,
            fault_rate: float, fault_kinds: str | None, scripts: tuple[str, ...], run_id: str | None,
            alarm_after: int | None, network: bool, job: str, serial: str | None, operator: str | None,
            shift_texts: tuple[str, ...], from_run: str | None, placement: str, arm: str | None,
            arms: int = 1, conductor_fd: int | None = None) -> None:
    """Inspect the part (in the simulated workcell): every measurement of the sequence
    plan, planned, executed, measured and recorded in the runs archive as it is made.

    Prepares the part first when needed (sequence plan, MKB, MACROPs).  A measurement
    that fails goes to the Exception Handler (diagnosis by tests in the cell, recovery,
    a second attempt).  Ctrl-C once interrupts after the current measurement; twice stops
    at once.  `ita monitor RUN` or `ita serve` watch it from elsewhere.  --seed is the
    simulator's noise (and the fault injection's draws).

    \b
    Exit codes:
      0  the run completed
      3  the run was stopped or interrupted (Ctrl-C, STOP or INTERRUPT from the
         System Monitor, or the alarm of --alarm-after): everything measured is
         saved; continue it with `ita continue RUN`
      2  bad input (part, specs, options)
    """
    from ita.archive import Archive, archive_path
    from ita.sim.inject import InjectionPlan
    from ita.task import open_session
    from ita.toplevel import earlier_results, start_run, tooling_specs, unproven

    # bad options fail before any work (with --arms 2 a script may name its arm: ARM:FAULT...)
    injection = InjectionPlan.parse(fault_rate, fault_kinds, [_unprefixed(s) for s in scripts] if arms == 2 else scripts,
                                    seed)
    if arms == 2:
        from ita.cli.arms import inspect_with_two_arms

        if arm is not None or job != "inspect_part" or from_run is not None or serial is not None:
            raise click.UsageError("--arms 2 inspects the part (the job inspect_part) with both arms: it does not "
                                   "go with --arm, --task, --from or --serial")
        inspect_with_two_arms(part_dir=part_dir, limit=limit, seed=seed, runs_dir=runs_dir, as_json=as_json,
                              fault_rate=fault_rate, fault_kinds=fault_kinds, scripts=scripts,
                              network=network, placement=placement, operator=operator, alarm_after=alarm_after)
        return
    conducted = None if conductor_fd is None else _conducted(conductor_fd)
    view = LiveView()
    check_job(job)
    from ita.part.serials import parse_shift

    shifts = dict(parse_shift(t) for t in shift_texts)
    if shifts and serial is None:
        raise click.UsageError("--shift goes with --serial: it shifts that serial's as-built part")
    if job == "cell_check" and limit is not None:
        raise click.UsageError("--limit does not go with --task cell_check: it measures the tooling holes")
    if (job == "reinspect") != (from_run is not None):
        raise click.UsageError("--from RUN goes with --task reinspect, and reinspect needs it")
    specs: list[str] | None = None
    source: str | None = None
    if from_run is not None:
        with Archive.open(archive_path(runs_dir), create=False) as old:
            source = old.resolve(from_run)
            specs = unproven(old, source)
            source_part = old.run(source).part
        if not specs:
            click.echo(f"run {source}: every result is proven to conform; nothing to measure again")
            return
    if conducted is not None:
        specs = list(conducted.specs)
    session = open_session(part_dir, seed=seed, progress=lambda m: view.note(f"{m} ..."), serial=serial,
                           shifts=shifts, placement_error=placement == "fixture", arm=arm,
                           away_tools=conducted.away_tools if conducted is not None else None,
                           others_folded=conducted is not None)
    if conducted is not None:
        session.arm.controller.gate = session.slra.controller.gate = session.peer = conducted.gate
        session.clock.on_advance = conducted.gate.clock
        session.registers = conducted.registers
        _follow(session, conducted.tours)
    with _closing(session):
        tools = session.ctx.workcell.tools
        injection.check_targets([t.name for t in tools if t.tool_class.ultrasonic],
                                [t.name for t in tools if t.tool_class.value == "slra_tool"])
        if job == "cell_check":
            specs = tooling_specs(session)
            if not specs:
                raise click.UsageError(f"part {session.part.name} has no tooling holes to check the cell on")
        if source is not None and session.part.name != source_part:
            raise click.UsageError(f"run {source} inspected part {source_part}, not {session.part.name} "
                                   "(give its part with --part)")
        with Archive.open(archive_path(runs_dir)) as archive:
            settings: dict[str, Any] = {"network": network, "task": job, "placement": placement}
            if arm is not None:
                settings["arm"] = session.ctx.workcell.arm.name
            if source is not None:
                settings["from"] = source
                settings["earlier"] = earlier_results(archive, source, session)
            settings.update({k: v for k, v in (("serial", serial), ("operator", operator)) if v is not None})
            if session.asbuilt_dir is not None:
                settings["asbuilt"] = session.asbuilt_dir
            if shifts:
                settings["shifts"] = dict(shifts)
            if alarm_after is not None:
                settings["alarm_after"] = alarm_after
            if conducted is not None:
                settings["two_arms"] = {"group": conducted.group, "away_tools": dict(conducted.away_tools),
                                        "tours": [[t, list(ids), c] for t, ids, c in conducted.tours]}
            if injection.active:
                settings["faults"] = injection.to_dict()
            run_id = start_run(session, archive, limit=limit, run_id=run_id, settings=settings, specs=specs)
            view.note(f"run {run_id}: {archive.run(run_id).total} measurements of {session.part.name} "
                      f"(set up in {session.setup_seconds:.1f} s)")
            _run(session, archive, run_id, as_json, view, parked=conducted is not None, settings=settings)


@click.command("continue")
@click.argument("run")
@runs_dir_option
@click.option("--json", "as_json", is_flag=True, help="Print the summary as JSON at the end.")
@reports_errors
def continue_(run: str, runs_dir: Path | None, as_json: bool) -> None:
    """Continue RUN (an id, a unique prefix, or "last") after an INTERRUPT, a STOP or a
    killed process: every measurement without a result is done; none is done twice.

    Exit codes as `ita inspect`: 0 completed, 3 stopped or interrupted again, 2 bad input.
    """
    from ita.archive import Archive, archive_path
    from ita.task import open_session

    view = LiveView()
    with Archive.open(archive_path(runs_dir), create=False) as archive:
        run_id = archive.resolve(run)
        info = archive.run(run_id)
        part_arg = info.settings.get("part_arg")
        archive.resume_run(run_id)
        serial, shifts = info.settings.get("serial"), info.settings.get("shifts")
        session = open_session(Path(part_arg) if part_arg else None, seed=info.seed or 0,
                               progress=lambda m: view.note(f"{m} ..."),
                               serial=None if info.settings.get("asbuilt") is None else str(serial),
                               shifts={str(k): float(str(v)) for k, v in shifts.items()}
                               if isinstance(shifts, dict) else None,
                               placement_error=info.settings.get("placement") == "fixture",
                               arm=None if info.settings.get("arm") is None else str(info.settings["arm"]))
        two_arms = info.settings.get("two_arms")
        if isinstance(two_arms, dict):          # an arm's run of a two-arm run: its share's tours
            _follow(session, tuple((str(t), tuple(map(str, ids)), float(c)) for t, ids, c in two_arms.get("tours", ())))
        with _closing(session):
            view.note(f"continuing run {run_id}: {info.done}/{info.total} done")
            _run(session, archive, run_id, as_json, view)


def monitor_text(state: dict, columns: int = 100) -> list[str]:
    """The monitor's screen for a live state (ita.report.live): a header, the current
    measurement, each arm's run of a two-arm run, the last results; every line cut to
    `columns` - 1."""
    cur = state.get("current") or {}
    group = cur.get("group")
    counts = ", ".join(f"{k.replace('_', ' ')} {v}" for k, v in sorted(state["counts"].items())) or "no results yet"
    lines = [f"{state['run']}  {state['state']}  {state['done']}/{state['total'] or '?'}  "
             f"sim {format_duration(state['sim_s'])}  wall {format_duration(state['wall_s'])}"
             + (f"  left ~{format_duration(state['eta_wall_s'])}" if state.get("eta_wall_s") is not None else ""),
             f"  {counts}; {state['exception_counts']['text']}",
             f"  current: group {'-' if group is None else group + 1}, tool {cur.get('tool') or '-'}, "
             f"measurement {cur.get('spec') or '-'}" + (f"; next {state['next']}" if state.get("next") else "")]
    for a in state.get("arms") or []:               # a run of a two-arm run: both arms' runs
        lines.append(f"  arm {a['arm']}{' (hand-over)' if a['handover'] else ''}: run {a['run']} {a['state']}, "
                     f"{a['done']}/{a['total'] or '?'}, sim {format_duration(a['sim_s'])}"
                     + (f", at {a['current']}" if a.get("current") else ""))
    if state["last"]:
        lines.append("  last results:")
        for r in state["last"][-5:]:
            value = "-" if r["value"] is None else f"{r['value']:.4f}"
            lines.append(f"    {r['seq']:>4}  {r['spec_id']:<12} {value:>10}  {r['decision'].replace('_', ' ')}"
                         + (f"  ({r['reason']})" if r["reason"] and r["decision"] != "conforms" else ""))
    room = max(columns - 1, 20)
    return [line[:room] for line in lines]


@click.command("monitor")
@click.argument("run")
@click.option("--stop", "send", flag_value="STOP", default=None, help="Send STOP: halt now.")
@click.option("--interrupt", "send", flag_value="INTERRUPT", help="Send INTERRUPT: halt after the current plan.")
@click.option("--once", is_flag=True, help="Print the summary once and leave.")
@click.option("--interval", type=FiniteFloatRange(0.05, 3600.0), default=2.0, show_default=True,
              help="Seconds between refreshes (0.05 to 3600).")
@runs_dir_option
@reports_errors
def monitor(run: str, send: str | None, once: bool, interval: float, runs_dir: Path | None) -> None:
    """Watch RUN from another terminal, or send it STOP or INTERRUPT.

    Shows progress, the current measurement (group, tool, id), the last results and the
    exceptions, redrawn in place on a terminal until the run ends (off a terminal: a new
    block only when something changed).  `ita serve` shows the same in a browser.
    """
    from ita.archive import Archive, archive_path
    from ita.report.live import live_state

    out = sys.stdout
    tty = out.isatty() and not once
    with Archive.open(archive_path(runs_dir), create=False) as archive:
        run_id = archive.resolve(run)
        if send is not None:
            request = archive.issue_control(run_id, send)
            click.echo(f"{send} sent to run {run_id} (request {request})")
            return
        shown: list[str] = []
        last_key = None
        while True:
            state = live_state(archive, run_id)
            if tty:
                lines = monitor_text(state, shutil.get_terminal_size((100, 24)).columns)
                # redraw in place: back up over the previous screen, clear it, write the new one
                out.write((f"\033[{len(shown)}F" if shown else "") + "\033[J" + "\n".join(lines) + "\n")
                out.flush()
                shown = lines
            elif state["key"] != last_key:        # off a terminal: a new block only when something changed
                click.echo("\n".join([time.strftime("%H:%M:%S")] + monitor_text(state, 200)))
                last_key = state["key"]
            if once or not state["running"]:
                return
            try:
                time.sleep(interval)
            except KeyboardInterrupt:
                return


@click.command("tasks")
@reports_errors
def tasks() -> None:
    """List the jobs the Top Level can run (`ita inspect --task NAME`): the jobs of
    kb/tasks.pl, each a task network the HTN planner decomposes (docs/architecture.md,
    "Top Level", says how to add one)."""
    from ita.logic.bridge import KnowledgeBase
    from ita.toplevel import jobs

    for name, description in jobs(KnowledgeBase()):
        click.echo(f"{name:<16} {description}")
