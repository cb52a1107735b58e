"""The arm's stream: the Path Planner, the robot controller and the tool changer.

    arm = ArmDevice(world, poses, planner_for, extra=GaugeCommands(gauge, specs).handlers)

Commands (the operators' messages) and their handlers:

- MOVE: the arm receives its whole queue at plan start (lookahead); consecutive MOVEs of
  the queue (no WAIT, no other command between them) are planned together
  (``PathPlanner.plan_queue``) and flown as one blended trajectory; each MOVE's reply
  comes when the arm passes (nearest) its goal.
- RETRACT, CONTACT: straight joint moves between the approach point and the contact
  pose at the arm's own acceleration, CONTACT with its speed overridden (CONTACT_SPEED),
  guarded (the controller stops at a bump); CONTACT replies the force of the probe's
  spring (``CONTACT(F)``).
- PICKUP, PUTDOWN: the tool changer.
- `extra` handlers (the gauge's COUPLANT and MEASURE) ride on the same stream.

Times: the robot controller, the tool changer and the gauge advance the world's
simulated clock as they work; each command ends at the clock after it.  Replies match
the operators' reply patterns; a failure is an exception reply naming it
(``NO_PATH(reason)``, ``BUMP(link, obstacle)``, ``NO_POSE(...)``), never a raised
exception.  Poses come from the Geometric Reasoner through ``poses.resolve(term, tool)``
with the tool the arm holds.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import replace

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ita.devices.data import ArmPath
from ita.executive.adapters import Completion, PoseResolver
from ita.executive.commands import Command, Reply, Wait
from ita.kinematics import flange_poses
from ita.kinematics.settle import joint_translation
from ita.logic.json_value import JsonValue
from ita.logic.terms import Term, TermValue
from ita.path.planner import PathPlanner
from ita.path.trajectory import TimedTrajectory
from ita.robot import RobotController, ToolChanger, from_waypoints
from ita.robot.controller import MotionReply
from ita.sim.inject import FaultInjector
from ita.sim.world import SimWorld
from ita.workcell import ToolSpec

__all__ = ["CONTACT_SPEED", "RECOVER_SECONDS", "RETRACT_SPEED", "SPRING_N_PER_M", "ArmDevice", "exception_reply"]

#: speed override of the guarded contact move (of the joints' velocity limits; the drives'
#: acceleration as it is: the probe slows at the arm's own rate into the contact)
CONTACT_SPEED = 0.5
#: how far (m) a recovery backs the tool straight out when its last free configuration is not
BACK_OFF_M = (0.01, 0.02, 0.04, 0.06)
RETRACT_SPEED = 1.0
#: the probe's spring rate (N/m), to report the contact force
SPRING_N_PER_M = 2000.0
#: seconds an operator's jog back to a free configuration takes (ArmDevice.recover)
RECOVER_SECONDS = 10.0
_SAME_Q = 1e-6

Handler = Callable[[Command], "Reply | Completion"]
#: the held tool's name (None: none) -> its Path Planner and the tool
PlannerFor = Callable[[str | None], tuple[PathPlanner, ToolSpec | None]]


def exception_reply(name: str, text: str, *args: TermValue, **details: JsonValue) -> Reply:
    """An exception reply ``NAME(args...)`` (or the atom NAME) with a line for people."""
    return Reply.exception(Term(name, tuple(args)) if args else name, text, **details)


class ArmDevice:
    """The arm's stream (see the module docstring).

    world: the simulated workcell (ita.sim.world.SimWorld); poses: the Geometric
    Reasoner's PoseResolver; planner_for: ``held tool -> (PathPlanner, ToolSpec)``;
    extra: more handlers by message name (the gauge's).
    """

    lookahead = True

    def __init__(self, world: SimWorld, poses: PoseResolver, planner_for: PlannerFor,
                 *, extra: Mapping[str, Handler] | None = None, controller: RobotController | None = None) -> None:

        self.world = world
        self.poses = poses
        self.planner_for = planner_for
        self.controller = controller if controller is not None else RobotController(world)
        self.changer = ToolChanger(self.controller)
        self._queue: list[Command | Wait] = []
        self._ready: dict[int, Completion] = {}        # step -> Completion computed with an earlier one
        self.last_free_q = np.array(world.q)
        self.planning_seconds = 0.0
        self.injector: FaultInjector | None = None     # when faults are injected
        self.stats: dict[str, float] = {"moves": 0, "move_s": 0.0, "contact_s": 0.0, "gauge_s": 0.0,
                                         "tool_change_s": 0.0, "station_s": 0.0}
        own: dict[str, tuple[Handler, str | None]] = {
            "RETRACT": (self._straight, "contact_s"), "CONTACT": (self._straight, "contact_s"),
            "PICKUP": (self._tool, "tool_change_s"), "PUTDOWN": (self._tool, "tool_change_s"),
        }
        self.handlers: dict[str, tuple[Handler, str | None]] = {
            **own, **{name: (h, "gauge_s") for name, h in (extra or {}).items()}}

    def add_handlers(self, handlers: Mapping[str, Handler], stat: str) -> None:
        """More commands on this stream (the stations'), their time counted under `stat`."""
        self.stats.setdefault(stat, 0.0)
        self.handlers.update({name: (h, stat) for name, h in handlers.items()})

    # -- the protocol ------------------------------------------------------------------
    def begin(self, items: Sequence[Command | Wait], now: float) -> None:
        self._queue = list(items)
        self._ready = {}

    def start(self, command: Command, now: float) -> Completion:
        if self.injector is not None:
            self.injector.before(command, "arm")
        if command.step in self._ready:
            return self._ready.pop(command.step)
        held_up = self.controller.held_up_s
        done = self._start(command, now)
        waited = self.controller.held_up_s - held_up      # the other arm's zones, before it began
        return replace(done, waited_s=waited) if waited > 0 else done

    def _start(self, command: Command, now: float) -> Completion:
        if command.name == "MOVE":
            return self._moves(command)
        entry = self.handlers.get(command.name)
        if entry is None:
            return Completion(max(self.world.clock.now, now), exception_reply(
                "UNSUPPORTED", f"the simulated arm cannot {command.text}", command.name.lower()))
        handler, stat = entry
        t0 = self.world.clock.now
        reply = handler(command)
        if stat is not None:
            self.stats[stat] += self.world.clock.now - t0
        return reply if isinstance(reply, Completion) else Completion(max(self.world.clock.now, now), reply)

    def stop(self, now: float) -> None:
        self._ready = {}

    def snapshot(self) -> Mapping[str, JsonValue]:
        return {"q": [round(float(v), 6) for v in self.world.q], "held": self.world.held}

    def recover(self) -> bool:
        """After a failed plan: if the arm is not where the Path Planner can start from (in
        contact, bumped), put it back at the last configuration it left free, or, when that
        one is not free either, back the tool straight out along its axis (an operator's
        jog, taking :data:`RECOVER_SECONDS`).  Returns whether it moved the arm."""
        planner, tool = self.planner_for(self.world.held)

        def free(q: np.ndarray) -> bool:
            q = np.asarray(q, dtype=float)[None]
            return bool(planner.config_free(q, tool)[0] and planner.context(tool).motion_free.clear(q)[0])

        # touching the part where the Path Planner's model has it clear (the part knocked out
        # of where it was registered), the arm is jogged straight back out too: from there
        # every move bumps again at once (another obstacle at the arm is the diagnosis's)
        touching = self._touches(self.world.q)
        if free(self.world.q) and not touching:
            return False
        target = self.last_free_q
        if not free(target) or (touching and self._touches(target)):     # straight back out (the
            # last free one is not: a retract that settled on an edge, or the part moved onto it)
            target = next((c for c in self._backed_off(np.asarray(self.world.q, dtype=float))
                           if free(c) and not self._touches(c)), target)
        if not self.controller.claim_jog(target, RECOVER_SECONDS):     # the other arm's zones: left as it is
            return False
        self.world.set_q(target)
        self.world.clock.advance(RECOVER_SECONDS)
        self.controller.jogged()
        return True

    def park_away(self, fold: Sequence[float], away_from: tuple[float, float]) -> bool:
        """Fly the arm folded (``fold``'s joints, the base joint aside) with its base joint
        turned away from ``away_from`` (world x, y: the other arm's base), or as near that
        as a free path goes (turns of 30 degrees either side tried in turn): a planned path,
        claimed like any motion.  Whether it got there."""
        world = self.world
        base = np.asarray(world.model.base, dtype=float)
        yaw = math.atan2(base[1, 0], base[0, 0])
        away = math.atan2(base[1, 3] - away_from[1], base[0, 3] - away_from[0]) - yaw
        lower, upper = np.asarray(world.model.lower), np.asarray(world.model.upper)
        planner, tool = self.planner_for(world.held)
        for turn in (0.0, 30.0, -30.0, 60.0, -60.0, 90.0, -90.0):
            j1 = math.remainder(away + math.radians(turn), 2.0 * math.pi)
            q = np.asarray(fold, dtype=float).copy()
            q[0] = j1
            if not (lower[0] <= j1 <= upper[0]) or not planner.config_free(q[None], tool)[0]:
                continue
            if np.max(np.abs(q - world.q)) <= _SAME_Q:
                return True
            _results, traj = planner.plan_queue(world.q, [q], tool)
            if traj is None:
                continue
            reply = self.controller.execute(traj, command="move")
            if reply.ok:
                self.last_free_q = np.array(world.q)
            return reply.ok
        return False

    def _touches(self, q: np.ndarray) -> bool:
        """Whether the arm or its tool at ``q`` touches the part (the controller's contact
        check, as after a bump), the arm put back where it was after."""
        world = self.world
        here = np.array(world.q)
        try:
            world.set_q(np.asarray(q, dtype=float))
            return any(c.obstacle == "part" for c in world.contacts(self.controller.contact_margin))
        finally:
            world.set_q(here)

    def _backed_off(self, q: np.ndarray) -> list[np.ndarray]:
        """Configurations with the tool moved straight back along its axis, away from the
        part, by :data:`BACK_OFF_M` steps, keeping its orientation."""

        world = self.world
        tcp = world.held_tool.tcp.matrix() if world.held_tool is not None else np.eye(4)
        pose = np.asarray(world.tcp_pose(q))
        look = pose[:3, 2] / np.linalg.norm(pose[:3, 2])
        return [q + joint_translation(world.model, q, tcp, -d * look) for d in BACK_OFF_M]

    # -- commands ----------------------------------------------------------------------
    def _q(self, term: TermValue) -> np.ndarray:
        """The joint configuration (6,) of a pose term for the held tool; KeyError if none."""
        target = self.poses.resolve(term, self.world.held)
        q = getattr(target, "q", None)
        if q is None:
            raise KeyError(f"{term!r} is not a pose")
        return np.asarray(q, dtype=float)

    def _moves(self, first: Command) -> Completion:
        """Plan the run of consecutive MOVEs from `first` together and fly it."""
        world = self.world
        start_t = world.clock.now
        index = next(i for i, it in enumerate(self._queue) if isinstance(it, Command) and it.step == first.step)
        batch: list[Command] = []
        for item in self._queue[index:]:
            if not (isinstance(item, Command) and item.name == "MOVE"):
                break
            batch.append(item)
        try:
            goals = [self._q(c.args[1]) for c in batch]
        except KeyError as exc:
            return Completion(start_t, exception_reply("NO_POSE", str(exc), str(exc)))
        q = world.q
        keep: list[int] = []                 # the batch's moves that go somewhere
        last = q
        for i, g in enumerate(goals):
            if np.max(np.abs(g - last)) > _SAME_Q:
                keep.append(i)
                last = g
        if not keep:
            for c in batch[1:]:
                self._ready[c.step] = Completion(start_t, Reply.normal("DONE"))
            return Completion(start_t, Reply.normal("DONE"))
        planner, tool = self.planner_for(world.held)
        w0 = time.perf_counter()
        results, traj = planner.plan_queue(q, [goals[i] for i in keep], tool)
        self.planning_seconds += time.perf_counter() - w0
        if traj is None:   # none of the batch is flown: the first MOVE fails, naming the one that could not
            bad = results[-1]
            failed = batch[keep[len(results) - 1]]
            payload = bad.reason.value if bad.reason is not None else "no_path"
            return Completion(start_t, exception_reply("NO_PATH", f"no path for {failed.text}: {bad.message}",
                                                       payload))
        ends = _pass_times(traj, [goals[i] for i in keep])
        flown = self._path(traj)
        reply = self.controller.execute(traj, command="move")
        start_t += reply.waited_s            # the other arm's zones (a wait, a fold) before it set off
        self.stats["moves"] += len(keep)
        self.stats["move_s"] += reply.time_s - reply.waited_s
        completions: dict[int, Completion] = {}
        kept_end = dict(zip(keep, ends))
        t_prev = 0.0
        failed_at = None if reply.ok else reply.time_s - reply.waited_s
        if not reply.ok and reply.q is None:     # a silent controller: the arm did not move at all
            failed_at = 0.0
        for i, c in enumerate(batch):
            t_end = kept_end.get(i, t_prev)
            if failed_at is not None and t_end >= failed_at - 1e-9:
                completions[c.step] = Completion(start_t + reply.time_s - reply.waited_s if reply.q is None else start_t + failed_at,
                                                 self._motion_failure(reply, c))
                break
            completions[c.step] = Completion(start_t + (traj.duration if i == len(batch) - 1 and reply.ok else t_end),
                                             Reply.normal("DONE", data=flown if i == 0 else None))
            t_prev = t_end
        if reply.ok:
            self.last_free_q = np.array(world.q)
        first_completion = completions.pop(first.step)
        self._ready.update(completions)
        return first_completion

    def _path(self, *trajs: TimedTrajectory) -> ArmPath:
        """The trajectories `trajs`, flown one after the other, as the archive keeps them (a
        few dozen knots, the tool point)."""
        times, qs, t0 = [], [], 0.0
        for traj in trajs:
            times.append(np.asarray(traj.times, dtype=float) + t0)
            qs.append(np.asarray(traj.q, dtype=float))
            t0 = float(times[-1][-1])
        return ArmPath.sampled(np.concatenate(times), np.concatenate(qs), self._tcp_poses, self.world.held)

    def _tcp_poses(self, q: ArrayLike) -> NDArray[np.float64]:
        """World poses (k, 4, 4) of the held tool's TCP (the flange without one) at joints q (k, 6)."""
        poses = flange_poses(self.world.model, np.asarray(q, dtype=float))
        tool = self.world.held_tool
        return poses @ tool.tcp.matrix() if tool is not None else poses

    @staticmethod
    def _motion_failure(reply: MotionReply, command: Command) -> Reply:
        status = reply.status.value
        if reply.contact is not None:
            return exception_reply("BUMP", f"{command.text}: {reply.message}", reply.contact.moving,
                                   reply.contact.obstacle, q=list(reply.q or ()))
        if status == "timeout":
            return Reply.exception(Term("TIMEOUT", (status,)), reply.message)
        return exception_reply(status.upper(), f"{command.text}: {reply.message}", reply.joint or status)

    def _straight(self, command: Command) -> Reply:

        world = self.world
        try:
            target = self.poses.resolve(command.args[1], world.held)
            goal = np.asarray(target.q, dtype=float)
        except (KeyError, AttributeError) as exc:
            return exception_reply("NO_POSE", str(exc), str(exc))
        before = np.array(world.q)
        # one straight rest-to-rest move at the arm's own acceleration: CONTACT with its speed
        # overridden to CONTACT_SPEED (the MKB checked the straight move), RETRACT at full speed
        speed = CONTACT_SPEED if command.name == "CONTACT" else RETRACT_SPEED
        trajs = [from_waypoints(world.model, [before, goal], speed_scale=speed, accel_scale=1.0)]
        flown = self._path(*trajs)
        for traj in trajs:
            reply = self.controller.execute(traj, command=command.name.lower())
            if not reply.ok:
                return self._motion_failure(reply, command)
        if command.name == "CONTACT":
            self.last_free_q = before
            force = round(SPRING_N_PER_M * float(getattr(target, "press_m", 0.0)), 3)
            return Reply.normal(Term("CONTACT", (force,)), data=flown)
        self.last_free_q = np.array(world.q)
        return Reply.normal("DONE", data=flown)

    def _tool(self, command: Command) -> Reply:
        if command.name == "PICKUP":
            reply = self.changer.pick_up(str(command.args[0]))
        else:
            if self.world.held != str(command.args[0]):
                return exception_reply("REJECTED", f"not holding {command.args[0]}", "not_holding")
            reply = self.changer.put_down()
        if not reply.ok:
            return self._motion_failure(reply, command)
        self.last_free_q = np.array(self.world.q)
        return Reply.normal("DONE")


def _pass_times(traj: TimedTrajectory, goals: Sequence[np.ndarray]) -> list[float]:
    """When (s) the trajectory passes nearest each goal (6,) in turn (blends pass near,
    not through, intermediate goals); the last goal at the end."""
    q = np.asarray(traj.q)
    t = np.asarray(traj.times)
    out: list[float] = []
    k0 = 0
    for i, g in enumerate(goals):
        if i == len(goals) - 1:
            out.append(float(t[-1]))
            break
        d = np.max(np.abs(q[k0:] - g), axis=1)
        k = k0 + int(np.argmin(d))
        out.append(float(t[k]))
        k0 = k
    return out
