"""Fault injection: the simulator's faults switched on during a run, at random or scripted.

    plan = InjectionPlan.parse(rate=0.05, kinds="broken_probe,dirty_window",
                               scripts=["broken_probe@us_probe_1:after=120"], seed=7)
    injector = FaultInjector(world, plan, log=runs_dir / "faults" / f"{run_id}.jsonl")
    injector.before(command, held)        # the devices call it as they start each command

Random: before each command, with probability `rate`, one fault drawn from the kinds that
can hit that command's device (the gauge for COUPLANT and MEASURE on the arm's stream,
the controller for the arm's motions, the SLRA in hand for SCAN), deterministic for a
given seed.  Scripted: ``fault[@target][:after=SECONDS]`` switches a fault on at the
first command at or after that simulated time where it can land (target: a tool, or the
device's default: a probe's fault waits until a probe is in hand, an obstacle until there
is room for it); a target the simulator cannot hit with the fault is refused before the
run starts (:meth:`InjectionPlan.check_targets`, :func:`valid_targets`).
A fault stays on until the Exception Handler's recovery takes it out (or, a TRANSIENT,
until the command it hits).  Faults are injected into the run's measuring, not into the
Exception Handler's own tests and repairs (`paused` while it works).  Every fault injected is written to the log, apart from the
archive, like the as-built truth: only scoring reads it; so is the first command at which
an injected fault is found gone (``{"cleared": fault, ...}``).

Not injected at random: POSITION_DRIFT (a step of the arm's calibration that no device
reports, so that only a check against a reference would find it), SENSOR_GARBAGE of an
SLRA, TILTED_PROBE, PART_DISPLACED (``part_displaced:after=600`` knocks the part on its
fixture: millimetres and tenths of a degree, the same knock in every copy of the part of a
two-arm run) and SLRA_FAILED (scripted only: ``tilted_probe:after=60`` tilts the
probe in hand; ``slra_failed@slra_1:after=300`` fails slra_1's laser for good, and with
``slra_failed@slra_2`` later both SLRAs are broken) and CONTROLLER_FAILED
(``controller_failed:after=600``: the arm's controller fails for good, the arm is down;
in a two-arm run its work left is handed to the other arm).
"""

from __future__ import annotations

import json
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ita.errors import InputError, Location
from ita.sim.faults import CONTROLLER, GAUGE, PART, STATION, Fault
from ita.sim.fixture import knocked

__all__ = ["INJECTABLE", "InjectionPlan", "FaultInjector", "Scripted", "injected_log", "valid_targets"]

#: the kinds a random injection may draw, by the device a command reaches
INJECTABLE = {
    "gauge": ("broken_probe", "worn_probe", "dry_couplant", "empty_couplant", "sensor_garbage", "transient"),
    "controller": ("controller_silent", "transient", "obstacle"),
    "slra": ("dirty_window",),
}
#: the cause of kb/faults.pl each injected fault is (for scoring the diagnoses)
CAUSE_OF = {
    "broken_probe": "broken_probe", "worn_probe": "worn_probe", "dry_couplant": "dry_couplant",
    "empty_couplant": "empty_couplant_station", "sensor_garbage": "sensor_cable_fault",
    "transient": "transient_glitch", "controller_silent": "controller_not_answering",
    "controller_failed": "controller_not_answering", "obstacle": "obstacle",
    "dirty_window": "dirty_window", "position_drift": "arm_drift", "tilted_probe": "tilted_probe",
    "slra_failed": "slra_failed", "part_displaced": "part_displaced",
}
_SCRIPT = re.compile(r"^(?P<fault>[a-z_]+)(@(?P<target>[A-Za-z0-9_.-]+))?(:after=(?P<after>[0-9.]+))?$")
_GAUGE_COMMANDS = ("COUPLANT", "MEASURE")
#: scripted faults of the world, not of a device: they land while the injection is paused too
_WORLD_FAULTS = ("part_displaced",)
#: an injected obstacle keeps at least this gap (m) from the arm and its tool where they are
OBSTACLE_CLEARANCE_M = 0.03


@dataclass(frozen=True)
class Scripted:
    """One scripted fault: `fault` on `target` ('' = the device's own) from `after_s`."""

    fault: str
    target: str
    after_s: float


@dataclass(frozen=True)
class InjectionPlan:
    """What to inject: `rate` per command, drawn from `kinds`; `scripted` faults; `seed`."""

    rate: float = 0.0
    kinds: tuple[str, ...] = tuple(sorted({k for ks in INJECTABLE.values() for k in ks}))
    scripted: tuple[Scripted, ...] = ()
    seed: int = 0

    @property
    def active(self) -> bool:
        return self.rate > 0.0 or bool(self.scripted)

    @classmethod
    def parse(cls, rate: float = 0.0, kinds: str | None = None, scripts: tuple[str, ...] | list[str] = (),
              seed: int = 0) -> InjectionPlan:
        """From the command line's --faults, --fault-kinds and --inject; InputError naming
        the bad one."""
        problems = []
        if not (0.0 <= rate <= 1.0):
            problems.append((Location("--faults"), f"a rate between 0 and 1, got {rate}"))
        known = {k for ks in INJECTABLE.values() for k in ks}
        chosen = tuple(sorted(known))
        if kinds:
            chosen = tuple(k.strip() for k in kinds.split(",") if k.strip())
            bad = [k for k in chosen if k not in known]
            if bad:
                problems.append((Location("--fault-kinds"), f"unknown fault kind(s) {', '.join(bad)}; "
                                 f"known: {', '.join(sorted(known))}"))
        scripted = []
        for text in scripts:
            m = _SCRIPT.match(text.strip())
            if m is None or m["fault"] not in {f.value for f in Fault}:
                problems.append((Location("--inject", field=text), "expected fault[@target][:after=SECONDS] with a "
                                 f"fault of {', '.join(f.value for f in Fault)}"))
                continue
            scripted.append(Scripted(m["fault"], m["target"] or "", float(m["after"] or 0.0)))
        if problems:
            raise InputError(problems)
        return cls(float(rate), chosen, tuple(scripted), int(seed))

    def check_targets(self, probes: list[str], slras: list[str]) -> None:
        """InputError (naming --inject and listing what each fault may target in this cell)
        for a scripted fault whose target the simulator cannot hit with it: a fault of a probe
        on a tool that is no probe, a dirty window on a tool that is no SLRA, a gauge's or a
        controller's fault on anything else."""
        valid = valid_targets(probes, slras)
        bad = [s for s in self.scripted if s.target and s.target not in (valid.get(s.fault) or (s.target,))]
        if bad:
            pairs = "; ".join(f"{f}@{'|'.join(t)}" for f, t in sorted(valid.items()) if t)
            raise InputError([(Location("--inject", field=f"{s.fault}@{s.target}"),
                               f"the simulator cannot inject {s.fault} into {s.target}; valid: {pairs}")
                              for s in bad])

    def to_dict(self) -> dict[str, Any]:
        return {"rate": self.rate, "kinds": list(self.kinds), "seed": self.seed,
                "scripted": [f"{s.fault}{'@' + s.target if s.target else ''}:after={s.after_s:g}"
                             for s in self.scripted]}


def valid_targets(probes: list[str], slras: list[str]) -> dict[str, tuple[str, ...] | None]:
    """What each fault may be scripted on (None: any name, an obstacle's)."""
    return {"broken_probe": tuple(probes), "worn_probe": tuple(probes), "dry_couplant": tuple(probes),
            "tilted_probe": tuple(probes), "dirty_window": tuple(slras), "slra_failed": tuple(slras),
            "empty_couplant": (STATION,),
            "sensor_garbage": (GAUGE,), "transient": (GAUGE, CONTROLLER), "controller_silent": (CONTROLLER,),
            "controller_failed": (CONTROLLER,), "position_drift": (CONTROLLER,), "part_displaced": (PART,), "obstacle": None}


def injected_log(runs_dir: Path, run_id: str) -> Path:
    """Where a run's injected faults are logged (only scoring reads it)."""
    return Path(runs_dir) / "faults" / f"{run_id}.jsonl"


class FaultInjector:
    """Switches faults on in `world` before commands (see the module docstring)."""

    def __init__(self, world: Any, plan: InjectionPlan, log: Path | None = None, *, poses: Any = None) -> None:
        self.world = world
        self.plan = plan
        self.log = log
        self.poses = poses
        self.rng = np.random.default_rng([plan.seed, 77])
        self._pending = list(plan.scripted)
        self.count = 0
        self.knocks = 0         # knocks of the part landed (each drawn from its own seed)
        self.paused = False     # the Exception Handler's own tests and repairs meet no new fault
        self._on: list[tuple[str, str]] = []     # injected and not yet taken out

    def carry_on(self, earlier: FaultInjector) -> None:
        """Go on from `earlier`, the injector of an earlier run of the same session (one arm
        of a two-arm run measuring its hand-over): the scripted faults that landed then do
        not land again, and a knock of the part is the next one."""
        self._pending = [s for s in self._pending if s in earlier._pending]
        self.knocks = earlier.knocks

    def before(self, command: Any, device: str) -> None:
        """Maybe inject before `command` reaches `device` (``arm`` or ``slra``)."""
        if not self.plan.active:
            return
        self._note_cleared()
        kind = "slra" if device == "slra" else ("gauge" if command.name in _GAUGE_COMMANDS else "controller")
        now = self.world.clock.now
        for s in list(self._pending):
            # a knock of the part comes when it comes, the Exception Handler's or the
            # registration's own work or not (in a two-arm run the other arm works then)
            if self.paused and s.fault not in _WORLD_FAULTS:
                continue
            if s.after_s <= now:
                # a scripted fault that cannot land on this command (its probe not in hand, no
                # room for the obstacle) waits for the next command where it can
                if self._switch_on(s.fault, s.target or self._default_target(s.fault, kind), command):
                    self._pending.remove(s)
        if self.paused or self.plan.rate <= 0.0:
            return
        if self.rng.random() >= self.plan.rate:
            return
        options = [k for k in INJECTABLE[kind] if k in self.plan.kinds]
        if not options:
            return
        fault = options[int(self.rng.integers(len(options)))]
        target = self._default_target(fault, kind)
        if target is None or self.world.faults.has(fault, target):
            return
        self._switch_on(fault, target, command)

    def _default_target(self, fault: str, kind: str) -> str | None:
        held = self.world.held
        if fault in ("broken_probe", "worn_probe", "dry_couplant", "tilted_probe"):
            tool = self.world.held_tool
            return held if tool is not None and tool.tool_class.ultrasonic else None
        if fault in ("dirty_window", "slra_failed"):
            tool = self.world.held_tool
            return held if tool is not None and tool.tool_class.value == "slra_tool" else None
        if fault == "empty_couplant":
            return STATION
        if fault == "sensor_garbage":
            return GAUGE
        if fault == "transient":
            return GAUGE if kind == "gauge" else CONTROLLER
        if fault in ("controller_silent", "controller_failed", "position_drift"):
            return CONTROLLER
        if fault == "part_displaced":
            return PART
        if fault == "obstacle":
            return f"obstacle_{self.count + 1}"
        return ""

    def _switch_on(self, fault: str, target: str | None, command: Any) -> bool:
        """Switch `fault` on on `target` before `command`; False when it cannot land there."""
        if target is None:
            return False
        if fault == "obstacle" and not self._place_obstacle(target, command):
            return False
        if fault == "position_drift":
            self.world.drift_m = self.world.drift_m + self.rng.normal(0.0, 1.0, 3) / np.sqrt(3) * 2e-3
        if fault == "part_displaced" and not self._knock_part():
            return False
        self.world.faults = self.world.faults.with_fault(fault, target)
        self.count += 1
        self._on.append((fault, target))
        self._write({"sim_time": round(self.world.clock.now, 3), "fault": fault, "target": target,
                     "cause": CAUSE_OF.get(fault, fault), "command": command.text})
        return True

    def _note_cleared(self) -> None:
        """Log the injected faults no longer on (put right by a recovery, or a transient
        spent on the command it hit), so that scoring knows which were there when."""
        for fault, target in list(self._on):
            gone = not self.world.faults.has(fault, target) if fault != "obstacle" \
                else target not in self.world.obstacles
            if gone:
                self._on.remove((fault, target))
                self._write({"sim_time": round(self.world.clock.now, 3), "cleared": fault, "target": target})

    def _write(self, record: dict[str, Any]) -> None:
        if self.log is None:
            return
        self.log.parent.mkdir(parents=True, exist_ok=True)
        with open(self.log, "a", encoding="utf-8") as out:
            out.write(json.dumps(record) + "\n")

    def _knock_part(self) -> bool:
        """Knock the part off its place on the fixture (ita.sim.fixture.knocked); not while
        the arm or its tool is within OBSTACLE_CLEARANCE_M of it (the part would be knocked
        into them: a knock lands when the arm is clear of the part)."""
        world = self.world
        if any(c.obstacle == "part" for c in world.contacts(OBSTACLE_CLEARANCE_M)):
            return False
        before = world.part_placement
        # drawn from the run's seed and the knock's number, not the stream of random faults:
        # in a two-arm run each arm's simulator holds a copy of the one part, and a knock
        # moves both copies alike (each as its own arm is clear of the part)
        world.place_part(knocked(before, np.random.default_rng([self.plan.seed, 78, self.knocks])))
        if any(c.obstacle == "part" for c in world.contacts(OBSTACLE_CLEARANCE_M)):
            world.place_part(before)
            return False
        self.knocks += 1
        return True

    def _place_obstacle(self, name: str, command: Any) -> bool:
        """A box where a MOVE is going (the arm bumps it on the way in); none where the arm
        already is or nearly is (a batch of moves flown at its first command is there
        already; a box a hair from the stopped arm would block every move from there,
        its diagnosis tests included, which is not a fault the cell could meet)."""
        if command.name != "MOVE" or self.poses is None or len(command.args) < 2:
            return False
        try:
            target = self.poses.resolve(command.args[1], self.world.held)
        except KeyError:
            return False
        q = np.asarray(getattr(target, "q", None), dtype=float)
        if q.shape != (6,):
            return False
        pose = self.world.tcp_pose(q)
        self.world.add_obstacle(name, pose[:3, 3], (0.12, 0.12, 0.12))
        if any(c.obstacle == name for c in self.world.contacts(OBSTACLE_CLEARANCE_M)):   # not ahead of the arm
            self.world.remove_obstacle(name)
            return False
        return True
