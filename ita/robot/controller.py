"""Robot controls: execute a timed joint trajectory on the simulated arm and reply.

    controller = RobotController(world)                 # world: ita.sim.world.SimWorld
    reply = controller.execute(trajectory)              # a MotionReply, never an exception
    if reply.ok: ... reply.time_s ...
    else: reply.status (BUMP / TIMEOUT / JOINT_LIMIT / REJECTED), reply.contact, reply.joint

The controller runs at a fixed control rate: every period it sets the joints to the
trajectory's configuration at that time (kinematically: the arm follows its commands
exactly while it moves) and checks for unplanned contact of the arm and its tool with
everything else (`SimWorld.contacts`), bodies named in `allowed` excepted.  A contact
stops the arm where it is and the reply is BUMP, naming what touched what and where.

At the end of a move the arm settles with a positioning error: a Gaussian TCP offset of
standard deviation repeatability / 3 per axis (the data sheet's +- figure read as 3
sigma), plus the accumulated drift of the POSITION_DRIFT fault, applied as the smallest
joint change that moves the TCP by that offset.  A controller hit by CONTROLLER_SILENT
does not move and does not answer: the reply is TIMEOUT after the trajectory's duration
plus `reply_timeout_s` (a TRANSIENT fault on the controller: for one command only).  The simulated clock advances by each reply's `time_s`.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass, replace
from enum import Enum

import numpy as np
from numpy.typing import NDArray

from ita.kinematics import JOINT_LIMIT_TOL, frame_segments, link_frames
from ita.kinematics.settle import settled
from ita.robot.gate import Grant, MotionGate
from ita.robot.waypoints import TimedTrajectory, retreat_paths
from ita.sim.faults import CONTROLLER, Fault
from ita.sim.world import Contact, SimWorld, tool_shapes

FloatArray = NDArray[np.float64]
_START_TOLERANCE = 0.01         # rad: how far a trajectory may start from the arm's joints
_SPEED_TOLERANCE = 1e-6         # relative: a speed this little over the limit is rounding


class MotionStatus(str, Enum):
    """How a command ended.  DONE is the normal reply; the others are exception replies."""

    DONE = "done"
    BUMP = "bump"
    TIMEOUT = "timeout"
    JOINT_LIMIT = "joint_limit"
    REJECTED = "rejected"


#: what a REJECTED reply's message starts with when the zone conductor refused the claim
#: (the other arm stands in the way: ita.executive.conductor)
REFUSED_BY_ZONES = "the other arm's zones"

@dataclass(frozen=True)
class MotionReply:
    """The controller's answer to one command.

    time_s: simulated time from the command to the reply; q: joint angles at the reply
    (None after a timeout: nobody knows); contact: what bumped (BUMP); joint: the joint at
    fault (JOINT_LIMIT); message: one line for people.
    """

    status: MotionStatus
    command: str
    time_s: float
    q: tuple[float, ...] | None
    contact: Contact | None = None
    joint: str = ""
    message: str = ""
    waited_s: float = 0.0        # of time_s, before the motion started: the other arm's zones (a wait, a fold)

    @property
    def ok(self) -> bool:
        """Whether this is the normal reply."""
        return self.status is MotionStatus.DONE


#: how far (m) beyond the contact margin a check measures the gap, to skip the control
#: periods that cannot close it
LOOKAHEAD_M = 0.02


class RobotController:
    """The simulated arm's controller (see the module docstring).

    rate_hz: control rate; reply_timeout_s: how long the caller waits beyond a command's
    own duration before calling it a timeout; contact_margin: a gap (m) below which a
    near miss counts as a bump (0: touching).
    """

    def __init__(self, world: SimWorld, *, rate_hz: float = 125.0, reply_timeout_s: float = 5.0,
                 contact_margin: float = 0.0) -> None:
        if rate_hz <= 0.0:
            raise ValueError("rate_hz must be > 0")
        self.world = world
        self.rate_hz = float(rate_hz)
        self.reply_timeout_s = float(reply_timeout_s)
        self.contact_margin = float(contact_margin)
        self._drift_direction = _unit(np.random.default_rng([world.seed, 3]).normal(size=3))
        #: the interlock with another arm's controller (ita.robot.gate): None when alone
        self.gate: MotionGate | None = None
        #: seconds waited for the other arm's zones, folds made to give way, motions refused
        self.zone_stats: dict[str, float] = {"wait_s": 0.0, "folds": 0, "fold_s": 0.0, "refused": 0}
        #: seconds its motions were held up by the other arm before they set off (waits,
        #: folds, the ways back), in all: a device's time-outs do not count them
        self.held_up_s = 0.0

    @property
    def period(self) -> float:
        """Control period (s)."""
        return 1.0 / self.rate_hz

    def execute(self, trajectory: TimedTrajectory, *, allowed: Iterable[str] = (),
                command: str = "move") -> MotionReply:
        """Run `trajectory` from the arm's current joints; the MotionReply says how it went.
        With a gate (another arm in the cell), the motion's space is claimed first: the
        arm waits for the grant, folds back when told to, and a refused claim is REJECTED.
        A controller that does not answer claims nothing either (the command times out)."""
        faults = self.world.faults
        if self.gate is None or faults.has(Fault.TRANSIENT, CONTROLLER) or faults.controller_silent:
            return self._execute(trajectory, allowed=allowed, command=command)
        world, gate = self.world, self.gate
        t0 = world.clock.now
        # a retract starts with the probe pressed on the part: no fold before it (it would drag the probe)
        pinned = command == "retract"
        grant = gate.claim(t0, trajectory.times, trajectory.q, pinned=pinned)
        back: TimedTrajectory | None = None
        allowed = tuple(allowed)
        while grant.kind == "fold" and grant.fold is not None:
            folded = self._fold(grant, allowed)
            if folded is None:       # no way back clear of the cell: it stays, and asks again (the
                grant = gate.claim(world.clock.now, trajectory.times, trajectory.q, pinned=pinned)  # conductor
                continue             # does not tell it to fold from here again)
            if not folded.ok:
                return replace(folded, time_s=world.clock.now - t0, waited_s=world.clock.now - t0)
            # back the way a retreat goes, the other way round: out in front of where it was, then in
            out = self._clear_way(retreat_paths(world.model, trajectory.start, world.q), allowed)
            if out is None:
                return MotionReply(MotionStatus.REJECTED, command, world.clock.now - t0, tuple(map(float, world.q)),
                                   message="folded to give way, it finds no way back clear of the cell",
                                   waited_s=world.clock.now - t0)
            back = TimedTrajectory(out.duration - out.times[::-1], out.q[::-1])
            both = np.concatenate([back.q, trajectory.q[1:]]) if len(trajectory.q) > 1 else back.q
            times = np.concatenate([back.times, back.duration + trajectory.times[1:]])
            grant = gate.claim(world.clock.now, times, both)
        if grant.kind != "go":
            self.zone_stats["refused"] += 1
            return MotionReply(MotionStatus.REJECTED, command, world.clock.now - t0, tuple(map(float, world.q)),
                               message=f"{REFUSED_BY_ZONES}: {grant.why}", waited_s=world.clock.now - t0)
        self._wait(grant.wait_s)
        if back is not None:
            reply = self._execute(back, allowed=allowed, command="return")
            if not reply.ok:
                gate.moved(world.clock.now, world.q)
                return replace(reply, time_s=world.clock.now - t0, waited_s=world.clock.now - t0)
        started = world.clock.now
        self.held_up_s += started - t0
        reply = self._execute(trajectory, allowed=allowed, command=command)
        gate.moved(world.clock.now, world.q)
        return replace(reply, time_s=reply.time_s + started - t0, waited_s=started - t0)

    def give_way(self) -> None:
        """Fold out of the other arm's way (when the conductor says it is not yet), before
        the arm waits for something other than space (nothing without a gate)."""
        if self.gate is None:
            return
        grant = self.gate.park(self.world.clock.now, self.world.q)
        if grant.kind == "fold" and grant.fold is not None:
            self._fold(grant)

    def park(self, give_way: bool = True) -> None:
        """At the end of the arm's work: give way (unless told not to: no arm moves after
        it), then tell the conductor the arm is done."""
        if self.gate is None:
            return
        if give_way:
            self.give_way()
        self.gate.done(self.world.clock.now)

    def claim_jog(self, target: NDArray[np.float64], seconds: float) -> bool:
        """Claim an operator's jog straight to `target` taking `seconds` (True: granted,
        after the wait; always True without a gate)."""
        if self.gate is None:
            return True
        grant = self.gate.claim(self.world.clock.now, np.array([0.0, seconds]), np.stack([self.world.q, target]))
        if grant.kind != "go":
            self.zone_stats["refused"] += 1
            return False
        self._wait(grant.wait_s)
        return True

    def moved_by_hand(self, target: NDArray[np.float64], seconds: float) -> bool:
        """A person moves the arm by hand to ``target`` taking ``seconds`` (its controller
        down for good: nothing it commands moves it), once the other arm's conductor grants
        the space; told to fold instead, the person folds it there the same way.  Whether
        the arm was moved (always, without a gate)."""
        world, gate = self.world, self.gate
        q0 = np.array(world.q)
        times, path = np.array([0.0, seconds]), np.stack([q0, np.asarray(target, dtype=float)])
        if gate is not None:
            grant = gate.claim(world.clock.now, times, path)
            if grant.kind not in ("go", "fold"):
                return False
            world.clock.advance(grant.wait_s)
            if grant.kind == "fold" and grant.fold is not None:      # the conductor's fold: its first way
                way = retreat_paths(world.model, q0, np.asarray(grant.fold))[0]
                times, path = np.asarray(way.times) * (seconds / max(float(way.duration), 1e-9)), np.asarray(way.q)
        world.clock.advance(seconds)
        world.set_q(path[-1])
        if gate is not None:
            gate.moved(world.clock.now, np.array(path[-1]), (times, path))
        return True

    def jogged(self) -> None:
        """After a jog claimed with :meth:`claim_jog`: where the arm is now."""
        if self.gate is not None:
            self.gate.moved(self.world.clock.now, self.world.q)

    def _clear_way(self, ways: list[TimedTrajectory], allowed: tuple[str, ...]) -> TimedTrajectory | None:
        """The first of `ways` the arm can fly without touching the cell (checked every
        control period, the arm put back after); None when none is."""
        world = self.world
        q_now = np.array(world.q)
        try:
            for way in ways:
                steps = max(2, int(np.ceil(way.duration * self.rate_hz)))
                for q in way.sample(np.linspace(0.0, way.duration, steps)):
                    world.set_q(q)
                    if world.contacts(self.contact_margin, allowed):
                        break
                else:
                    return way
        finally:
            world.set_q(q_now)
        return None

    def _wait(self, seconds: float) -> None:
        if seconds > 0:
            self.world.clock.advance(seconds)
            self.zone_stats["wait_s"] += seconds

    def _fold(self, grant: Grant, allowed: tuple[str, ...] = ()) -> MotionReply | None:
        """Fold back as the conductor told (after its wait) and say where the arm ended;
        `allowed`: what the motion it makes way for may touch (a tool just let go).  None
        when every way back would touch the cell (a probe deep in a pocket): it stays, and
        says so (a fold that stopped where it started)."""
        assert self.gate is not None and grant.fold is not None
        self._wait(grant.wait_s)
        t0 = self.world.clock.now
        way = self._clear_way(retreat_paths(self.world.model, self.world.q, np.asarray(grant.fold)), allowed)
        if way is None:
            q = np.array(self.world.q)
            self.gate.moved(t0, q, (np.array([0.0, 1e-3]), np.stack([q, q])))
            return None
        reply = self._execute(way, allowed=allowed, command="retreat")
        self.gate.moved(self.world.clock.now, self.world.q, (way.times, way.q))
        self.zone_stats["folds"] += 1
        self.zone_stats["fold_s"] += self.world.clock.now - t0
        return reply

    def _execute(self, trajectory: TimedTrajectory, *, allowed: Iterable[str] = (),
                 command: str = "move") -> MotionReply:
        world = self.world
        glitch = world.faults.has(Fault.TRANSIENT, CONTROLLER)
        if glitch:                          # a one-off: this command is lost, the next is not
            world.faults = world.faults.without(Fault.TRANSIENT, CONTROLLER)
        if glitch or world.faults.controller_silent:
            wait = trajectory.duration + self.reply_timeout_s
            world.clock.advance(wait)
            return MotionReply(MotionStatus.TIMEOUT, command, wait, None,
                         message=f"no reply from the controller within {wait:.1f} s")
        problem = self._check(trajectory)
        if problem is not None:
            return replace(problem, command=command)
        skip = tuple(allowed)
        start = world.q
        offset = start - trajectory.start          # blend the small start error out linearly
        steps = max(1, int(np.ceil(trajectory.duration * self.rate_hz - 1e-9)))
        times = np.minimum(np.arange(1, steps + 1) * self.period, trajectory.duration)
        fade = 1.0 - times / trajectory.duration if trajectory.duration > 0 else np.zeros(steps)
        configs = trajectory.sample(times) + fade[:, None] * offset
        frames = link_frames(world.model, configs)        # forward kinematics of the whole move at once
        flanges = frames[:, -1]
        # every control period is checked unless no contact is possible there: from one
        # check to the next, no point of the arm or tool moves farther than the swept bound
        # (`_swept`), so the checks skip the periods that cannot close the gaps the last
        # check found (the same first contact as checking them all)
        cell_swept, tool_swept = self._swept(configs, frames)
        margin = self.contact_margin
        i = 0
        while i < steps:
            world.set_q(configs[i], flanges[i])
            hits, cell_gap, tool_gap = world.contacts_and_gaps(margin, skip, margin + LOOKAHEAD_M)
            if hits:
                return self._bump(command, float(times[i]), hits)
            reach = min(int(np.searchsorted(cell_swept, cell_swept[i] + cell_gap - margin)),
                        int(np.searchsorted(tool_swept, tool_swept[i] + tool_gap - margin)))
            i = max(i + 1, reach)
        # the arm settles off its goal by its repeatability, but never past a joint's limit
        world.set_q(settled(world.model, trajectory.end, self._settle_tcp(), self._settle_offset()))
        hits = world.contacts(self.contact_margin, skip)
        if hits:
            return self._bump(command, trajectory.duration, hits)
        world.clock.advance(trajectory.duration)
        return MotionReply(MotionStatus.DONE, command, trajectory.duration, tuple(map(float, world.q)))

    def _swept(self, configs: FloatArray, frames: FloatArray) -> tuple[FloatArray, FloatArray]:
        """Two bounds (n,) m, cumulative from configs[0] along the move's configs (n, 6)
        with link frames (n, 8, 4, 4): how far a point of the arm or the held tool can have
        come towards the cell, and the held tool towards the arm's links.  A step's bound
        is the smaller of two that hold:

        - joint by joint: a joint change dq moves no point of the links after it, or of the
          tool, farther than sum |dq_j| r_j (`_sweep_radii`), in the world or in the frame
          of any link before it;
        - link by link: a link's shapes move by at most its origin's shift plus their reach
          from it (`SimWorld.link_reach`) times |R' - R| (the 2-norm of the change of its
          rotation, 2 sin(angle / 2): its Frobenius norm over the square root of 2), or,
          where the arm's tubes enclose its collision shapes, by the smaller of that and a
          tube's ends' shift plus its radius times the same; the tool by the flange's shift plus its reach times the flange's; between the
          tool and a link, twice the largest.
        """
        world, model = self.world, self.world.model
        reach = self._tool_reach()
        joint_steps = np.abs(np.diff(configs, axis=0)) @ self._sweep_radii(reach)
        if len(configs) < 2:
            return np.zeros(len(configs)), np.zeros(len(configs))
        rotations, origins = frames[:, :, :3, :3], frames[:, :, :3, 3]
        turn = np.linalg.norm(rotations[1:] - rotations[:-1], axis=(-2, -1)) / math.sqrt(2.0)  # 2 sin(angle / 2)
        links = (np.linalg.norm(np.diff(origins, axis=0), axis=-1) + turn * world.link_reach).max(axis=1)
        if model.tubes_complete and len(model.tube_radii):
            ends = frame_segments(model, frames)                                      # (n, t, 2, 3)
            shift = np.linalg.norm(np.diff(ends, axis=0), axis=-1).max(axis=-1)       # (n - 1, t)
            links = np.minimum(links, (shift + turn[:, model.tube_links] * model.tube_radii).max(axis=1))
        tool = np.linalg.norm(np.diff(origins[:, -1], axis=0), axis=-1) + turn[:, -1] * reach
        rigid = np.maximum(links, tool)
        cell_steps, tool_steps = np.minimum(joint_steps, rigid), np.minimum(joint_steps, 2.0 * rigid)
        return np.concatenate([[0.0], np.cumsum(cell_steps)]), np.concatenate([[0.0], np.cumsum(tool_steps)])

    def _tool_reach(self) -> float:
        """How far (m) from the flange's origin the held tool reaches: its body box, its
        collision shapes, its TCP (0 without a tool)."""
        tool = self.world.held_tool
        if tool is None:
            return 0.0
        reach = float(np.linalg.norm(tool.body_center) + 0.5 * np.linalg.norm(tool.body_size)
                      + np.linalg.norm(tool.tcp.position))
        for kind, centre, axis_or_size, radius, length in tool_shapes(tool):
            if kind == "box":
                far = float(np.linalg.norm(centre) + 0.5 * np.linalg.norm(axis_or_size))
            else:
                half = 0.5 * length * np.asarray(axis_or_size)
                far = max(float(np.linalg.norm(centre + half)), float(np.linalg.norm(centre - half))) + radius
            reach = max(reach, far)
        return reach

    def _sweep_radii(self, tool_reach: float) -> FloatArray:
        """Per joint j, an upper bound (m) on how far a point that the joint moves (of the
        links after it, or of the held tool) lies from its axis, which passes through the
        next link's origin: the chain's lengths from there to the point's link, plus how far
        the point lies from its link's origin (`SimWorld.link_reach`, a tube's end and
        radius; the tool's reach `tool_reach` from the flange), and never less than the lengths to the
        flange plus the widest tube.  A joint change dq then moves no point farther than
        sum |dq_j| r_j."""
        model = self.world.model
        lengths = np.append(np.linalg.norm(model.origins[:, :3, 3], axis=1), np.linalg.norm(model.flange_offset[:3, 3]))
        to_link = np.concatenate([[0.0], np.cumsum(lengths)])          # from the base's origin to link l's
        widest = float(np.max(model.tube_radii)) if len(model.tube_radii) else 0.0
        radii = to_link[-1] - to_link[1:-1] + widest + tool_reach     # (dof,): to the flange
        far = np.array(self.world.link_reach, dtype=float)
        if len(model.tube_radii):
            np.maximum.at(far, model.tube_links, np.linalg.norm(model.tube_ends, axis=-1).max(axis=-1) + model.tube_radii)
        for link in range(1, len(far)):
            joints = np.arange(min(link, model.dof))                   # the joints that move link `link`
            radii[joints] = np.maximum(radii[joints], to_link[link] - to_link[joints + 1] + far[link])
        return radii

    def _bump(self, command: str, t: float, hits: list[Contact]) -> MotionReply:
        self.world.clock.advance(t)
        worst = min(hits, key=lambda c: c.distance)
        return MotionReply(MotionStatus.BUMP, command, t, tuple(map(float, self.world.q)), contact=worst,
                     message=f"{worst.moving} touched {worst.obstacle} at {t:.3f} s")

    def _check(self, trajectory: TimedTrajectory) -> MotionReply | None:
        model = self.world.model
        q = self.world.q
        names = model.joint_names
        if trajectory.q.shape[1] != model.dof:
            return MotionReply(MotionStatus.REJECTED, "", 0.0, tuple(q), message="wrong number of joints")
        gap = np.abs(trajectory.start - q)
        if gap.max() > _START_TOLERANCE:
            j = int(np.argmax(gap))
            return MotionReply(MotionStatus.REJECTED, "", 0.0, tuple(q), joint=names[j],
                         message=f"trajectory starts {gap[j]:.4f} rad from the arm at {names[j]}")
        outside = (trajectory.q < model.lower - JOINT_LIMIT_TOL) | (trajectory.q > model.upper + JOINT_LIMIT_TOL)
        if outside.any():
            k, j = map(int, np.argwhere(outside)[0])
            return MotionReply(MotionStatus.JOINT_LIMIT, "", 0.0, tuple(q), joint=names[j],
                         message=f"{names[j]} = {trajectory.q[k, j]:.4f} rad at {trajectory.times[k]:.3f} s "
                                 f"is outside [{model.lower[j]:.4f}, {model.upper[j]:.4f}]")
        if len(trajectory.times) > 1:
            speed = np.abs(trajectory.velocities()).max(axis=0)
            over = speed > model.velocity * (1.0 + _SPEED_TOLERANCE)
            if over.any():
                j = int(np.argmax(speed / model.velocity))
                return MotionReply(MotionStatus.JOINT_LIMIT, "", 0.0, tuple(q), joint=names[j],
                             message=f"{names[j]} speed {speed[j]:.3f} rad/s exceeds {model.velocity[j]:.3f}")
        return None

    def _settle_offset(self) -> FloatArray:
        """The world offset (3,) m the TCP settles off its goal: the repeatability draw plus drift."""
        world = self.world
        if world.faults.has(Fault.POSITION_DRIFT, CONTROLLER):
            world.drift_m = world.drift_m + world.faults.drift_per_move_m * self._drift_direction
        sigma = world.cell.arm.repeatability_m / 3.0
        return world.rng.normal(0.0, sigma, 3) + world.drift_m

    def _settle_tcp(self) -> FloatArray:
        """The held tool's TCP (4, 4) in the flange frame (the flange without a tool)."""
        tool = self.world.held_tool
        return tool.tcp.matrix() if tool is not None else np.eye(4)


def _unit(v: FloatArray) -> FloatArray:
    return v / np.linalg.norm(v)
