"""Faults of the simulated workcell, switched on by tests and (later) by fault injection.

A `FaultSet` is a value: `FaultSet().with_fault(Fault.BROKEN_PROBE, "us_probe_1")` is a
new set; the world holds the current one (`SimWorld.faults`) and the simulated devices
read it on every command.  A fault has a target, the name of the tool (or device) it
hits; the empty target hits every one.

    BROKEN_PROBE       the probe's element is dead: no echo at all
    WORN_PROBE         a worn probe face: weak echo, the gauge locks on the second
                       back-wall echo and reads double
    DRY_COUPLANT       the dispenser gives nothing (empty or dried): no coupling
    CONTROLLER_SILENT  the robot controller stops answering: commands time out
    CONTROLLER_FAILED  the robot controller has failed for good: commands time out, and
                       a reset does not bring it back (the arm is down; scripted only)
    SENSOR_GARBAGE     the gauge's replies are corrupt (out-of-domain values)
    POSITION_DRIFT     the arm's position drifts a little further with every move
    EMPTY_COUPLANT     the couplant station's reservoir is empty: no dispenser gives any
                       (target: the station)
    DIRTY_WINDOW       the SLRA's window is dirty: most returns are lost (target: the SLRA)
    SLRA_FAILED        the SLRA's laser or detector has failed: no returns at all, and
                       cleaning does not bring them back (target: the SLRA; a new unit
                       from the stores does)
    OBSTACLE           something stands in the cell that the collision model does not know
                       (target: its name; the world holds its box, `SimWorld.obstacles`)
    TRANSIENT          one command of the target device fails once (a glitch): the device
                       that meets it clears it (`FaultSet.without`)
    TILTED_PROBE       the probe sits crooked in its holder (knocked): its face meets the
                       part and the calibration block tilted, the echo walks off (target:
                       the probe)
    PART_DISPLACED     the part knocked on its fixture: it sits millimetres and tenths of
                       a degree off where it was (ita.sim.fixture.knocked; target: the
                       part); a person clamping it again takes the fault out

A repair (ita.devices: refill, purge, reset, reseat, recalibrate, clean; a person called
to the cell, ita.sim.person: obstacles removed, a tool replaced, a probe straightened)
takes the fault out of the world's set.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from enum import Enum

#: the fault targets that are no tool: the robot controller, the gauge box, the couplant station
CONTROLLER = "controller"
#: the target of a knock on the part
PART = "part"
GAUGE = "us_gauge"
STATION = "couplant_station"


class Fault(str, Enum):
    """A fault that can be switched on.  The value is the spelling in files and Prolog."""

    BROKEN_PROBE = "broken_probe"
    WORN_PROBE = "worn_probe"
    DRY_COUPLANT = "dry_couplant"
    CONTROLLER_SILENT = "controller_silent"
    CONTROLLER_FAILED = "controller_failed"
    SENSOR_GARBAGE = "sensor_garbage"
    POSITION_DRIFT = "position_drift"
    EMPTY_COUPLANT = "empty_couplant"
    DIRTY_WINDOW = "dirty_window"
    SLRA_FAILED = "slra_failed"
    OBSTACLE = "obstacle"
    TRANSIENT = "transient"
    TILTED_PROBE = "tilted_probe"
    PART_DISPLACED = "part_displaced"


@dataclass(frozen=True)
class FaultSet:
    """The faults switched on: (fault, target) pairs; target '' hits every tool/device.

    drift_per_move_m: how far (m) the TCP drifts, in one fixed direction, with every
    move while POSITION_DRIFT is on.
    """

    active: frozenset[tuple[Fault, str]] = frozenset()
    drift_per_move_m: float = 5e-5

    def with_fault(self, fault: Fault | str, target: str = "") -> FaultSet:
        """This set plus `fault` on `target` ('' = everything)."""
        return replace(self, active=self.active | {(Fault(fault), target)})

    def without(self, fault: Fault | str, target: str | None = None) -> FaultSet:
        """This set minus `fault` on `target` (None: on every target)."""
        f = Fault(fault)
        return replace(self, active=frozenset(
            (g, t) for g, t in self.active if not (g is f and (target is None or t == target))))

    def has(self, fault: Fault | str, target: str = "") -> bool:
        """Whether `fault` hits `target`: switched on for it or for everything."""
        f = Fault(fault)
        return (f, "") in self.active or (target != "" and (f, target) in self.active)

    @property
    def controller_silent(self) -> bool:
        """Whether the robot controller does not answer (silent for now, or failed for good)."""
        return self.has(Fault.CONTROLLER_SILENT, CONTROLLER) or self.has(Fault.CONTROLLER_FAILED, CONTROLLER)

    def __bool__(self) -> bool:
        return bool(self.active)

    def names(self) -> list[str]:
        """'fault' or 'fault@target' of each active fault, sorted (for logs and reports)."""
        return sorted(f.value + (f"@{t}" if t else "") for f, t in self.active)
