"""The workcell: the arm `t3`, the part's placement and fixture, the tool rack, the tools,
the couplant station and the calibration block (`bulkhead/workcell.toml`,
`bulkhead/t3_arm.urdf`), and a simple geometric reach test for measurement specs.

    from ita.workcell import load_workcell, reach_report
    cell = load_workcell()                       # the built-in workcell
    report = reach_report(cell, points_mm, normals, tool_classes)
    print(report.summary())
"""

from ita.workcell.load import default_workcell_path, load_workcell, workcell_for
from ita.workcell.model import (
    ArmKinematics,
    ArmSpec,
    Box,
    JointLimits,
    PartPlacement,
    Pose,
    Rack,
    RackSlot,
    ReachParams,
    Stations,
    ToolSpec,
    Workcell,
)
from ita.workcell.reach import Reach, ReachReport, reach_report

__all__ = [
    "ArmKinematics",
    "ArmSpec",
    "Box",
    "JointLimits",
    "PartPlacement",
    "Pose",
    "Rack",
    "RackSlot",
    "Reach",
    "ReachParams",
    "ReachReport",
    "Stations",
    "ToolSpec",
    "Workcell",
    "default_workcell_path",
    "load_workcell",
    "reach_report",
    "workcell_for",
]
