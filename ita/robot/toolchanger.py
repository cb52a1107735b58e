"""The tool changer: pick a tool up from its rack slot, put it back, with the time it takes.

A rack slot's pose is the parked tool's flange frame; the flange approaches it along its
own z axis (from above: the tools hang in their cradles tip down).  Picking up is

    joints now -> above the slot (approach_height back along the slot's z: the rack's
    approach_m unless given) -> the slot
    -> latch (latch_time_s) -> back above the slot, now carrying the tool

and putting down the same with unlatch.  The moves are joint-space trajectories built by
`trajectory.from_waypoints` and executed by the RobotController; the first one starts
wherever the arm is, so the caller (the path planner, later) should bring the arm near
the rack first.  Each call returns one MotionReply whose time_s is the whole operation's; an
exception reply from a move is passed on with the time spent so far.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from ita.kinematics import choose_nearest, ik_flange
from ita.robot.controller import MotionReply, MotionStatus, RobotController
from ita.robot.waypoints import from_waypoints


class ToolChanger:
    """Tool changes on `controller`'s arm (its world holds the tools)."""

    def __init__(self, controller: RobotController, *, approach_height: float | None = None,
                 latch_time_s: float = 1.5, speed_scale: float = 0.5) -> None:
        self.controller = controller
        self.world = controller.world
        self.approach_height = float(self.world.cell.rack.approach_m if approach_height is None else approach_height)
        self.latch_time_s = float(latch_time_s)
        self.speed_scale = float(speed_scale)

    def pick_up(self, tool: str) -> MotionReply:
        """Fetch `tool` from its slot; on DONE the world holds it."""
        command = f"pick_up {tool}"
        world = self.world
        if world.held is not None:
            return self._refuse(command, f"already holding {world.held}")
        try:
            slot = world.cell.slot_of(tool)
        except KeyError:
            return self._refuse(command, f"no rack slot holds {tool!r}")
        return self._change(command, slot.pose.matrix(), tool, attach=True)

    def put_down(self) -> MotionReply:
        """Return the held tool to its slot; on DONE the arm holds nothing."""
        world = self.world
        if world.held is None:
            return self._refuse("put_down", "no tool is held")
        tool = world.held
        return self._change(f"put_down {tool}", world.cell.slot_of(tool).pose.matrix(), tool, attach=False)

    def _change(self, command: str, slot_pose: np.ndarray, tool: str, attach: bool) -> MotionReply:
        world, model = self.world, self.world.model
        above = slot_pose.copy()
        above[:3, 3] -= self.approach_height * slot_pose[:3, 2]
        q_above, ok_above = choose_nearest(model, ik_flange(model, above[None]), world.q[None])
        if not ok_above[0]:
            return self._refuse(command, "the slot's approach pose is out of reach")
        q_slot, ok_slot = choose_nearest(model, ik_flange(model, slot_pose[None]), q_above)
        if not ok_slot[0]:
            return self._refuse(command, "the slot is out of reach")
        spent = 0.0
        down = from_waypoints(model, [world.q, q_above[0], q_slot[0]], speed_scale=self.speed_scale)
        reply = self.controller.execute(down, allowed=(tool,) if attach else (), command=command)
        spent += reply.time_s
        if not reply.ok:
            return replace(reply, time_s=spent)
        world.clock.advance(self.latch_time_s)
        spent += self.latch_time_s
        if attach:
            world.attach(tool)
        else:
            world.detach()
        up = from_waypoints(model, [world.q, q_above[0]], speed_scale=self.speed_scale)
        reply = self.controller.execute(up, allowed=() if attach else (tool,), command=command)
        spent += reply.time_s
        return replace(reply, time_s=spent)

    def _refuse(self, command: str, message: str) -> MotionReply:
        return MotionReply(MotionStatus.REJECTED, command, 0.0, tuple(map(float, self.world.q)), message=message)
