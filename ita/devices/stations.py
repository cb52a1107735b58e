"""The cell's stations and its supervisor, on the arm's stream: the Exception Handler's
tests and repairs that are not a measurement.

    stations = StationCommands(world, poses, controller, gauge_sim)
    stations.handlers     # message name -> command -> Reply

- CALIBRATE(Tool, cal_block): the probe in hand reads the calibration block (a stepped
  gauge block; its :data:`CAL_STEP_MM` step, certified to :data:`CAL_BLOCK_U_MM`):
  straight down onto its face from the approach point, couplant, one reading, straight
  back up; replies ``VALUE(V)`` or the gauge's exception ``GAUGE(reason)``.  A reading
  close enough to the block sets the gauge's sound velocity for that probe
  (ita.sensors.ultrasonic.velocity_calibration).
- LEVEL(couplant_station): the reservoir's level, ``LEVEL(Percent)``.
- REFILL(couplant_station): refill the reservoir (the EMPTY_COUPLANT fault goes);
  ``LEVEL(100)``.
- PURGE(Tool): purge the dispenser of the probe in hand (DRY_COUPLANT goes).
- CLEAN(Tool): wipe the window of the SLRA in hand (DIRTY_WINDOW goes).
- QUERY(controller): re-home the arm and query the controller: ``READY``, or no reply
  at all from a silent controller (the executive times it out).
- RESET(controller): power-cycle the controller (CONTROLLER_SILENT goes; CONTROLLER_FAILED,
  a controller failed for good, stays).
- RESEAT(Device): reseat the sensor's cable (SENSOR_GARBAGE goes).
- RECALIBRATE(cal_block): touch off the arm on the block (its drift is zeroed, and stops).

Each takes its stated time (:data:`SECONDS`) on the simulated clock.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from ita.devices.arm import CONTACT_SPEED, exception_reply
from ita.devices.data import MeasuredValue
from ita.executive.adapters import Completion, PoseResolver
from ita.executive.commands import Command, Reply
from ita.logic.terms import Term
from ita.robot import from_waypoints
from ita.robot.controller import RobotController
from ita.sensors.ultrasonic import (
    GaugeException,
    GaugeSpec,
    UltrasonicGauge,
    interpret,
    velocity_calibration,
)
from ita.sim.faults import CONTROLLER, GAUGE, STATION, Fault
from ita.sim.ultrasonic import UltrasonicSim
from ita.sim.world import SimWorld

__all__ = ["CAL_BLOCK_U_MM", "CAL_STEP_MM", "SECONDS", "StationCommands"]

#: the thickness (mm) of the calibration block's step the probe reads
CAL_STEP_MM = 10.0

#: the standard uncertainty (mm) of that step's thickness on its certificate
CAL_BLOCK_U_MM = 0.0005

#: simulated seconds of the station operations (the motion to the station is planned apart)
SECONDS = {
    "LEVEL": 3.0,
    "REFILL": 60.0,
    "PURGE": 15.0,
    "CLEAN": 20.0,
    "QUERY": 2.0,
    "RESET": 30.0,
    "RESEAT": 20.0,
    "RECALIBRATE": 45.0,
}


class StationCommands:
    """The station and supervisor commands of the arm's stream (see the module docstring).

    world: the simulated workcell; poses: the Geometric Reasoner (``station`` poses);
    controller: the robot controller; gauge_sim: the simulated gauge (its
    ``pulse_reference``, ``dispense``, ``station_level``); gauge: the gauge facade
    (ita.sensors.ultrasonic.UltrasonicGauge) whose velocity a block reading sets (None:
    readings of the block set nothing)."""

    def __init__(self, world: SimWorld, poses: PoseResolver, controller: RobotController, gauge_sim: UltrasonicSim,
                 spec: GaugeSpec = GaugeSpec(), gauge: UltrasonicGauge | None = None) -> None:
        self.world = world
        self.poses = poses
        self.controller = controller
        self.gauge_sim = gauge_sim
        self.spec = spec
        self.gauge = gauge

    @property
    def handlers(self) -> dict[str, Callable[[Command], Reply | Completion]]:
        return {"CALIBRATE": self.calibrate, "LEVEL": self.level, "REFILL": self.refill, "PURGE": self.purge,
                "CLEAN": self.clean, "QUERY": self.query, "RESET": self.reset, "RESEAT": self.reseat,
                "RECALIBRATE": self.recalibrate}

    def _wait(self, name: str) -> None:
        self.world.clock.advance(SECONDS[name])

    def _silent(self) -> bool:

        return self.world.faults.controller_silent

    def calibrate(self, command: Command) -> Reply | Completion:
        world = self.world
        tool = world.held_tool
        if tool is None or not tool.tool_class.ultrasonic:
            return exception_reply("NO_PROBE", "no ultrasonic probe on the flange", "no_probe")
        try:
            contact = self.poses.station("cal_block", tool.name, contact=True)   # type: ignore[attr-defined]
        except KeyError as exc:
            return exception_reply("NO_POSE", str(exc), "cal_block")
        above = np.array(world.q)
        self.gauge_sim.dispense()
        down = self.controller.execute(from_waypoints(world.model, [above, contact.q], speed_scale=CONTACT_SPEED),
                                       command="calibrate", allowed=("cal_block",))
        if not down.ok:
            return exception_reply(down.status.value.upper(), f"{command.text}: {down.message}", down.status.value)
        thickness_mm = CAL_STEP_MM
        reply = interpret(self.gauge_sim.pulse_reference(thickness_mm), self.spec)
        up = self.controller.execute(from_waypoints(world.model, [np.array(world.q), above],
                                                    speed_scale=CONTACT_SPEED), command="calibrate",
                                     allowed=("cal_block",))
        if not up.ok:
            return exception_reply(up.status.value.upper(), f"{command.text}: {up.message}", up.status.value)
        if isinstance(reply, GaugeException):
            return Reply.exception(Term("GAUGE", (reply.reason.value,)), f"gauge on the calibration block: "
                                   f"{reply.reason.value}")
        calibration = velocity_calibration(reply, thickness_mm, CAL_BLOCK_U_MM, self.spec, world.clock.now)
        if calibration is not None and self.gauge is not None:
            self.gauge.calibrate(calibration)
        data = MeasuredValue("cal_block", float(reply.thickness_mm), float(reply.u_mm), source=reply)
        note = "" if calibration is None else f"; velocity set for {tool.name}: x{calibration.factor:.5f}"
        return Reply.normal(Term("VALUE", (float(reply.thickness_mm),)), f"block {thickness_mm:.3f} mm{note}",
                            data=data)

    def level(self, command: Command) -> Reply | Completion:
        if self._silent():
            return Completion(self.world.clock.now, None)
        self._wait("LEVEL")
        return Reply.normal(Term("LEVEL", (float(self.gauge_sim.station_level()),)))

    def refill(self, command: Command) -> Reply | Completion:

        self._wait("REFILL")
        self.world.faults = self.world.faults.without(Fault.EMPTY_COUPLANT, STATION)
        return Reply.normal(Term("LEVEL", (100.0,)))

    def purge(self, command: Command) -> Reply | Completion:
        self._wait("PURGE")
        self.world.faults = self.world.faults.without(Fault.DRY_COUPLANT, str(command.args[0]))
        return Reply.normal("DONE")

    def clean(self, command: Command) -> Reply | Completion:
        self._wait("CLEAN")
        self.world.faults = self.world.faults.without(Fault.DIRTY_WINDOW, str(command.args[0]))
        return Reply.normal("DONE")

    def query(self, command: Command) -> Reply | Completion:
        if self._silent():
            return Completion(self.world.clock.now, None)         # the executive times it out
        home = np.asarray(self.poses.resolve(Term("approach_point", ("home",)), self.world.held).q, dtype=float)
        if np.max(np.abs(np.asarray(self.world.q) - home)) > 1e-6:
            moved = self.controller.execute(from_waypoints(self.world.model, [np.asarray(self.world.q), home]),
                                            command="rehome")
            if not moved.ok:
                return exception_reply(moved.status.value.upper(), moved.message, moved.status.value)
        self._wait("QUERY")
        return Reply.normal("READY")

    def reset(self, command: Command) -> Reply | Completion:

        self._wait("RESET")
        self.world.faults = self.world.faults.without(Fault.CONTROLLER_SILENT, CONTROLLER)
        return Reply.normal("DONE")

    def reseat(self, command: Command) -> Reply | Completion:

        self._wait("RESEAT")
        device = str(command.args[0])
        self.world.faults = self.world.faults.without(Fault.SENSOR_GARBAGE, GAUGE if device == "gauge" else device)
        return Reply.normal("DONE")

    def recalibrate(self, command: Command) -> Reply | Completion:
        self._wait("RECALIBRATE")
        self.world.drift_m = np.zeros(3)
        self.world.faults = self.world.faults.without(Fault.POSITION_DRIFT, CONTROLLER)
        return Reply.normal("DONE")
