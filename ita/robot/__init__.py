"""Robot controls of the simulated workcell: trajectories, the controller, the tool changer.

    from ita.robot import RobotController, ToolChanger, from_waypoints
    controller = RobotController(world)                     # world: ita.sim.world.SimWorld
    reply = controller.execute(from_waypoints(world.model, [world.q, q_goal]))
    reply = ToolChanger(controller).pick_up("us_probe_1")

Every command answers with a `MotionReply`: DONE with the time taken, or an exception reply
(BUMP, TIMEOUT, JOINT_LIMIT, REJECTED) saying what went wrong; nothing is raised.
"""

from ita.robot.controller import MotionReply, MotionStatus, RobotController
from ita.robot.toolchanger import ToolChanger
from ita.robot.waypoints import TimedTrajectory, from_waypoints

__all__ = [
    "MotionReply",
    "MotionStatus",
    "RobotController",
    "TimedTrajectory",
    "ToolChanger",
    "from_waypoints",
]
