"""The devices behind the Plan Executive's command streams, over the simulated workcell.

    arm = ArmDevice(world, poses, planner_for, gauge=GaugeCommands(gauge, specs))  # path_planner(t3)
    slra = SlraDevice(world, scene, poses, vision_ctx, specs, rng)                 # vision(slra_1)
    person = PersonDevice(SimPerson(world), world.clock)                           # person(technician)
    PlanExecutive(kb, {"path_planner": arm, "vision": slra, "person": person}, clock=world.clock)

Each device is a table from a command's message name to the handler that runs it, behind
the executive's :class:`~ita.executive.adapters.DeviceAdapter` protocol, and sees the
Geometric Reasoner only through the executive's narrow
:class:`~ita.executive.adapters.PoseResolver` (``resolve(term, tool)``).  A device's
reply carries its data (:mod:`ita.devices.data`): a gauge reading, the frames of a
scan, Vision's values for every member of a view group, so that nothing leaves a device
by a side channel.

- :mod:`~ita.devices.arm`: MOVE (the Path Planner, consecutive MOVEs planned together
  and flown as one blended trajectory), RETRACT and CONTACT (straight, guarded), PICKUP
  and PUTDOWN (the tool changer); the gauge's commands ride on its stream.
- :mod:`~ita.devices.gauge`: COUPLANT and MEASURE of the ultrasonic gauge.
- :mod:`~ita.devices.slra`: SCAN (range frames of a view group, re-approaches between
  the frames a position needs) and MEASURE (Vision).
- :mod:`~ita.devices.stations`: the calibration block, the couplant station and the
  cell's supervisor, on the arm's stream.
- :mod:`~ita.devices.person`: CALL(Job), a person called to the cell (obstacles removed,
  the part re-clamped, a tool replaced, a probe straightened), answered by the
  simulator (ita.sim.person); the run waits.
"""

from ita.devices.arm import ArmDevice
from ita.devices.data import MeasuredValue, ScanData, measured_values, scan_frames
from ita.devices.gauge import GaugeCommands
from ita.devices.person import PersonDevice
from ita.devices.slra import SlraDevice

__all__ = ["ArmDevice", "GaugeCommands", "MeasuredValue", "PersonDevice", "ScanData", "SlraDevice",
           "measured_values", "scan_frames"]
