"""Kinematics of the workcell's arm: forward and inverse kinematics, reach, motion time.

Shared by the Sequence Planner (its cost matrix) and the Path Planner (link tubes for
collision checks, goal configurations).  Pure numpy functions over arrays, vectorised over
configurations and poses; every pose is a 4x4 transform in the world frame (m, z up),
every angle in radians.

    from ita.kinematics import arm_model, ik_tool, measurement_poses, choose_nearest, move_time_matrix
    cell = load_workcell()
    model = arm_model(cell.arm)
    tool = cell.tool("us_probe_1")
    poses = measurement_poses(cell.part, points_mm, normals, tool)     # (n, 12, 4, 4)
    ik = ik_tool(model, poses, tool.tcp.matrix()).flatten_batch()     # (n,) x 12 K slots
    q, found = choose_nearest(model, ik, q_home)                        # (n, 6), (n,)
    cost = move_time_matrix(model, q[found])                           # (m, m) seconds
"""

from ita.kinematics.choice import (
    choose_centred,
    choose_nearest,
    limit_margin,
    reachable,
)
from ita.kinematics.fk import (
    JOINT_LIMIT_TOL,
    ArmModel,
    arm_model,
    axis_rotations,
    flange_poses,
    frame_segments,
    invert_poses,
    link_frames,
    link_segments,
    tcp_poses,
)
from ita.kinematics.ik import (
    IK_STATUS_DESCRIPTIONS,
    IKSolutions,
    IKStatus,
    ik_flange,
    ik_tool,
    slot_count,
)
from ita.kinematics.timing import joint_times, move_time, move_time_matrix
from ita.kinematics.tool_poses import (
    DEFAULT_ROLLS,
    approach_poses,
    flange_of_tool,
    measurement_poses,
    roll_angles,
    surface_frames,
)

__all__ = [
    "DEFAULT_ROLLS",
    "IK_STATUS_DESCRIPTIONS",
    "JOINT_LIMIT_TOL",
    "ArmModel",
    "IKSolutions",
    "IKStatus",
    "approach_poses",
    "arm_model",
    "axis_rotations",
    "choose_centred",
    "choose_nearest",
    "flange_of_tool",
    "flange_poses",
    "frame_segments",
    "ik_flange",
    "ik_tool",
    "invert_poses",
    "joint_times",
    "limit_margin",
    "link_frames",
    "link_segments",
    "measurement_poses",
    "move_time",
    "move_time_matrix",
    "reachable",
    "roll_angles",
    "slot_count",
    "surface_frames",
    "tcp_poses",
]
