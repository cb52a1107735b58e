"""The real device adapters of the Executive: the simulated arm (through the Path Planner
and the robot controller, with the ultrasonic gauge on its stream) and the SLRA (through
Vision).  Each implements ita.executive.adapters.DeviceAdapter.

    arm = ArmAdapter(world, reasoner, planner_for, specs)       # stream path_planner(t3)
    slra = SlraAdapter(world, scene, reasoner, vision_ctx, specs, rng)   # stream vision(slra_1)
    PlanExecutive(kb, {"path_planner": arm, "vision": slra}, clock=world.clock)

Times.  The robot controller, the tool changer and the gauge advance the world's
simulated clock themselves as they work; the arm adapter reports each command's end as
the clock after it.  The SLRA adapter reports the frames' scan times (and
:data:`VISION_SECONDS` per frame Vision measures) from the `now` it is given, and the
executive advances the clock; only the re-approach moves between the frames of a
multi-frame SCAN advance it themselves (through the robot controller), and the SCAN
ends after them and all its frames.

The arm receives its whole queue at plan start (lookahead).  Consecutive MOVEs of the
queue (no WAIT, no other command between them) are planned together
(``PathPlanner.plan_queue``) and flown as one blended trajectory; each MOVE's reply comes
when the arm passes (nearest) its goal.  RETRACT and CONTACT are straight, slow joint
moves between the approach point and the contact pose (guarded: the controller stops at
a bump); COUPLANT and MEASURE go to the gauge; PICKUP and PUTDOWN to the tool changer.
Replies: normal ones match the operators' reply patterns (``DONE``, ``CONTACT(F)``,
``VALUE(V)``, ``IMAGE(I)``, ``VALUE(V, S)``); a failure is an exception reply whose
payload names it (``NO_PATH(reason)``, ``BUMP(link, obstacle)``, ``GAUGE(no_couplant)``,
``VISION(occluded)``...), never a raised exception.

Measurements beyond the plan's own: the SLRA adapter measures every member of the
frame's view group (the MKB) in the frame it took, and keeps the replies
(:meth:`SlraAdapter.take_results`) for the Top Level to record; the arm adapter keeps
each gauge reading (:meth:`ArmAdapter.take_readings`) since the operator's result
pattern carries no uncertainty for the probe.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from typing import Any

import numpy as np

from ita.executive.commands import Command, Reply, Wait
from ita.geometry.reasoner import GeometricReasoner, Target
from ita.logic.terms import Term

__all__ = ["REAPPROACH_M", "VISION_SECONDS", "ArmAdapter", "SlraAdapter", "spec_of_message"]

#: simulated seconds Vision takes per measurement in a frame (patches, fits)
VISION_SECONDS = 0.15
#: speed scale of the guarded contact move and of the retract (of the joints' limits)
CONTACT_SPEED = 0.5
RETRACT_SPEED = 1.0
#: how far (m) the arm backs off along the line of sight between the frames of a
#: multi-frame SLRA measurement, so that each return is a real approach of the pose
REAPPROACH_M = 0.02
#: the probe's spring rate (N/m), to report the contact force
SPRING_N_PER_M = 2000.0
_SAME_Q = 1e-6


def spec_of_message(message: Any) -> str | None:
    """The measurement id a message's qualitative parameters name (``...(meas(Id))``)."""
    def walk(value: Any) -> str | None:
        if isinstance(value, Term):
            if value.name == "meas" and len(value.args) == 1:
                return str(value.args[0])
            for a in value.args:
                found = walk(a)
                if found is not None:
                    return found
        return None

    return walk(message)


def _exception(name: str, text: str, *args: Any, **details: Any) -> Reply:
    return Reply.exception(Term(name, tuple(args)) if args else name, text, **details)


class ArmAdapter:
    """The arm's stream: Path Planner + robot controller + tool changer + gauge."""

    lookahead = True

    def __init__(self, world: Any, reasoner: GeometricReasoner,
                 planner_for: Callable[[str | None], tuple[Any, Any]],
                 specs: Mapping[str, Any], *, controller: Any = None, gauge: Any = None) -> None:
        from ita.robot import RobotController, ToolChanger
        from ita.sensors.ultrasonic import UltrasonicGauge
        from ita.sim.ultrasonic import UltrasonicSim

        self.world = world
        self.reasoner = reasoner
        self.planner_for = planner_for
        self.specs = specs
        self.controller = controller if controller is not None else RobotController(world)
        self.changer = ToolChanger(self.controller)
        self.gauge = gauge if gauge is not None else UltrasonicGauge(UltrasonicSim(world))
        self._queue: list[Command | Wait] = []
        self._ready: dict[int, Any] = {}        # step -> Completion computed with an earlier one
        self._readings: dict[str, Any] = {}
        self.last_free_q = np.array(world.q)
        self.planning_seconds = 0.0
        self.stats: dict[str, float] = {"moves": 0, "move_s": 0.0, "contact_s": 0.0, "gauge_s": 0.0,
                                         "tool_change_s": 0.0}

    # -- the protocol ------------------------------------------------------------------
    def begin(self, items: Sequence[Command | Wait], now: float) -> None:
        self._queue = list(items)
        self._ready = {}

    def start(self, command: Command, now: float) -> Any:
        from ita.executive.adapters import Completion

        if command.step in self._ready:
            return self._ready.pop(command.step)
        name = command.name
        if name == "MOVE":
            return self._moves(command)
        t0 = self.world.clock.now
        if name in ("RETRACT", "CONTACT"):
            reply = self._straight(command)
            self.stats["contact_s"] += self.world.clock.now - t0
        elif name == "COUPLANT":
            self.gauge.apply_couplant()
            reply = Reply.normal("DONE")
            self.stats["gauge_s"] += self.world.clock.now - t0
        elif name == "MEASURE":
            reply = self._measure(command)
            self.stats["gauge_s"] += self.world.clock.now - t0
        elif name in ("PICKUP", "PUTDOWN"):
            reply = self._tool(command)
            self.stats["tool_change_s"] += self.world.clock.now - t0
        else:
            reply = _exception("UNSUPPORTED", f"the simulated arm cannot {command.text}", name.lower())
        return Completion(max(self.world.clock.now, now), reply)

    def stop(self, now: float) -> None:
        self._ready = {}

    def snapshot(self) -> Mapping[str, Any]:
        return {"q": [round(float(v), 6) for v in self.world.q], "held": self.world.held}

    # -- results beside the replies --------------------------------------------------------
    def take_readings(self) -> dict[str, Any]:
        """The gauge readings (spec id -> Reading) since the last call."""
        out, self._readings = self._readings, {}
        return out

    def recover(self) -> bool:
        """After a failed plan: if the arm is not where the Path Planner can start from (in
        contact, bumped), put it back at the last configuration it left free (an operator's
        jog, taking :attr:`RECOVER_SECONDS`).  Returns whether it moved the arm."""
        planner, tool = self.planner_for(self.world.held)
        q = np.asarray(self.world.q)[None]
        if planner.config_free(q, tool)[0] and planner.context(tool).motion_free.clear(q)[0]:
            return False
        self.world.set_q(self.last_free_q)
        self.world.clock.advance(self.RECOVER_SECONDS)
        return True

    RECOVER_SECONDS = 10.0

    # -- commands ----------------------------------------------------------------------
    def _target(self, term: Any) -> Target:
        target = self.reasoner.resolve(term)
        if not isinstance(target, Target):
            raise KeyError(f"{term!r} is not a pose")
        return target

    def _moves(self, first: Command) -> Any:
        """Plan the run of consecutive MOVEs from `first` together and fly it."""
        from ita.executive.adapters import Completion

        world = self.world
        start_t = world.clock.now
        index = next(i for i, it in enumerate(self._queue) if isinstance(it, Command) and it.step == first.step)
        batch: list[Command] = []
        for item in self._queue[index:]:
            if not (isinstance(item, Command) and item.name == "MOVE"):
                break
            batch.append(item)
        try:
            goals = [np.asarray(self._target(c.args[1]).q, dtype=float) for c in batch]
        except KeyError as exc:
            return Completion(start_t, _exception("NO_POSE", str(exc), str(exc)))
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
        import time as _time

        w0 = _time.perf_counter()
        results, traj = planner.plan_queue(q, [goals[i] for i in keep], tool)
        self.planning_seconds += _time.perf_counter() - w0
        if traj is None:
            bad = results[-1]
            failed = batch[keep[len(results) - 1]]
            text = f"no path for {failed.text}: {bad.message}"
            payload = bad.reason.value if bad.reason is not None else "no_path"
            if failed is batch[0]:
                return Completion(start_t, _exception("NO_PATH", text, payload))
            # the moves before the failing one are not flown either: the first one fails
            return Completion(start_t, _exception("NO_PATH", text, payload))
        ends = _pass_times(traj, [goals[i] for i in keep])
        reply = self.controller.execute(traj, command="move")
        self.stats["moves"] += len(keep)
        self.stats["move_s"] += reply.time_s
        completions: dict[int, Any] = {}
        kept_end = dict(zip(keep, ends))
        t_prev = 0.0
        failed_at = None if reply.ok else reply.time_s
        for i, c in enumerate(batch):
            t_end = kept_end.get(i, t_prev)
            if failed_at is not None and t_end >= failed_at - 1e-9:
                completions[c.step] = Completion(start_t + failed_at, self._motion_failure(reply, c))
                break
            completions[c.step] = Completion(start_t + (traj.duration if i == len(batch) - 1 and reply.ok else t_end),
                                             Reply.normal("DONE"))
            t_prev = t_end
        if reply.ok:
            self.last_free_q = np.array(world.q)
        first_completion = completions.pop(first.step)
        self._ready.update(completions)
        return first_completion

    def _motion_failure(self, reply: Any, command: Command) -> Reply:
        status = reply.status.value
        if reply.contact is not None:
            return _exception("BUMP", f"{command.text}: {reply.message}", reply.contact.moving,
                              reply.contact.obstacle, q=list(reply.q or ()))
        if status == "timeout":
            return Reply.exception(Term("TIMEOUT", (status,)), reply.message)
        return _exception(status.upper(), f"{command.text}: {reply.message}", reply.joint or status)

    def _straight(self, command: Command) -> Reply:
        from ita.robot import from_waypoints

        world = self.world
        try:
            goal = np.asarray(self._target(command.args[1]).q, dtype=float)
        except KeyError as exc:
            return _exception("NO_POSE", str(exc), str(exc))
        before = np.array(world.q)
        speed = CONTACT_SPEED if command.name == "CONTACT" else RETRACT_SPEED
        traj = from_waypoints(world.model, [before, goal], speed_scale=speed)
        reply = self.controller.execute(traj, command=command.name.lower())
        if not reply.ok:
            return self._motion_failure(reply, command)
        if command.name == "CONTACT":
            self.last_free_q = before
            spec = spec_of_message(command.message)
            entry = self.reasoner.mkb.entries.get(spec or "")
            force = round(SPRING_N_PER_M * (entry.press_m if entry is not None else 0.0), 3)
            return Reply.normal(Term("CONTACT", (force,)))
        self.last_free_q = np.array(world.q)
        return Reply.normal("DONE")

    def _measure(self, command: Command) -> Reply:
        from ita.sensors.ultrasonic import GaugeException, check_expected

        spec_id = spec_of_message(command.message)
        spec = self.specs.get(spec_id or "")
        reply = self.gauge.measure()
        if spec is not None:
            reply = check_expected(reply, spec.nominal, max(abs(spec.upper), abs(spec.lower)))
        if isinstance(reply, GaugeException):
            return _exception("GAUGE", f"gauge: {reply.reason.value} ({reply.message})", reply.reason.value)
        if spec_id is not None:
            self._readings[spec_id] = reply
        return Reply.normal(Term("VALUE", (float(reply.thickness_mm),)))

    def _tool(self, command: Command) -> Reply:
        if command.name == "PICKUP":
            reply = self.changer.pick_up(str(command.args[0]))
        else:
            if self.world.held != str(command.args[0]):
                return _exception("REJECTED", f"not holding {command.args[0]}", "not_holding")
            reply = self.changer.put_down()
        if not reply.ok:
            return self._motion_failure(reply, command)
        self.last_free_q = np.array(self.world.q)
        return Reply.normal("DONE")


def _pass_times(traj: Any, goals: Sequence[np.ndarray]) -> list[float]:
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


def _guarded_measure(measure: Callable[..., Any], frame: Any, spec: Any, vctx: Any) -> Any:
    """Vision's reply; an error inside Vision becomes a NOT_MEASURABLE reply naming it
    (a device reports failures, it never raises)."""
    from ita.vision.measure import Reason, VisionException

    try:
        return measure(frame, spec, vctx)
    except Exception as exc:  # noqa: BLE001 - any fault of the vision code is a failed measurement
        return VisionException(spec.id, Reason.NOT_MEASURABLE, f"vision error {type(exc).__name__}: {exc}")


class SlraAdapter:
    """The SLRA's stream: range frames of the view group at the arm's pose, then Vision.

    A view group whose members need several frames (:func:`ita.vision.measure.frames_for`:
    a position whose only datum is the arm's pose) gets them at one SCAN, each after a
    re-approach: the arm backs off :data:`REAPPROACH_M` from the part and comes back to
    the viewing configuration (through the robot controller, so each return settles with
    a new repeatability draw and takes its real time on the simulated clock)."""

    lookahead = False

    def __init__(self, world: Any, scene: Any, reasoner: GeometricReasoner, vision_ctx: Any,
                 specs: Mapping[str, Any], rng: np.random.Generator, *, params: Any = None,
                 wanted: Callable[[str], bool] | None = None, controller: Any = None) -> None:
        from ita.robot import RobotController
        from ita.sim.slra import SlraParams

        self.world = world
        self.scene = scene
        self.reasoner = reasoner
        self.vctx = vision_ctx
        self.specs = specs
        self.rng = rng
        self.params = params if params is not None else SlraParams()
        self.wanted = wanted or (lambda _id: True)
        self.controller = controller if controller is not None else RobotController(world)
        self.frames: dict[str, list[Any]] = {}  # group id -> the frames of its last SCAN
        self._results: dict[str, Any] = {}
        self.last_frame: Any = None
        self.stats: dict[str, float] = {"frames": 0, "scan_s": 0.0, "vision_s": 0.0, "reapproaches": 0,
                                         "reapproach_s": 0.0}

    def begin(self, items: Sequence[Command | Wait], now: float) -> None:
        pass

    def start(self, command: Command, now: float) -> Any:
        from ita.executive.adapters import Completion

        if command.name == "SCAN":
            return self._scan(command, now)
        if command.name == "MEASURE":
            return self._measure(command, now)
        return Completion(now, _exception("UNSUPPORTED", f"the SLRA cannot {command.text}", command.name.lower()))

    def stop(self, now: float) -> None:
        pass

    def snapshot(self) -> Mapping[str, Any]:
        return {"frames": sorted(self.frames)}

    def take_results(self) -> dict[str, Any]:
        """Vision's replies (spec id -> VisionResult | VisionException) since the last call."""
        out, self._results = self._results, {}
        return out

    def _scan(self, command: Command, now: float) -> Any:
        from ita.executive.adapters import Completion
        from ita.sensors.slra_frame import ScanGeometry
        from ita.sim.slra import simulate_frame

        world = self.world
        tool = world.held_tool
        if tool is None or tool.tool_class.value != "slra_tool":
            return Completion(now, _exception("NO_SENSOR", "no SLRA on the flange", "no_sensor"))
        spec_id = spec_of_message(command.message)
        try:
            group = self.reasoner.resolve(command.args[0])
            anchor = self.reasoner.entry(group.anchor)
        except KeyError as exc:
            return Completion(now, _exception("NO_VIEW", str(exc), spec_id or "?"))
        plan = self._frame_plan(group)
        t = max(now, world.clock.now)
        frames: list[Any] = []
        for k in range(plan.count):
            if k:
                moved = self._reapproach(np.asarray(anchor.q, dtype=float), anchor.pose)
                if not moved.ok:
                    return Completion(t + moved.time_s, _exception(
                        "REAPPROACH", f"re-approach {k} of {plan.count - 1} for {group.id}: {moved.message}",
                        moved.status.value))
                t += moved.time_s
                self.stats["reapproaches"] += 1
                self.stats["reapproach_s"] += moved.time_s
            shape = tuple(group.pixels) if k == 0 else plan.shape
            frame = simulate_frame(self.scene, world.tcp_pose(), ScanGeometry(shape, tuple(group.fov_deg)),
                                   self.params, self.rng, reported_pose=np.asarray(anchor.pose), timestamp=t,
                                   sensor=tool.name)
            frames.append(frame)
            t += frame.frame_time
            self.stats["frames"] += 1
            self.stats["scan_s"] += frame.frame_time
        self.frames = {group.id: frames}
        self.last_frame = frames[0]
        return Completion(t, Reply.normal(Term("IMAGE", (group.id,))))

    def _members(self, group: Any, spec_id: str) -> list[str]:
        return [m for m in group.members if m == spec_id or self.wanted(m)]

    def _frame_plan(self, group: Any) -> Any:
        """The frames the group's wanted members need (the most any of them needs)."""
        from ita.vision.measure import frames_for

        plans = [frames_for(self.specs[m], self.vctx) for m in self._members(group, group.anchor) if m in self.specs]
        return max(plans, key=lambda p: p.count) if plans else frames_for(self.specs[group.anchor], self.vctx)

    def _reapproach(self, q_view: np.ndarray, view_pose: Any) -> Any:
        """Back off REAPPROACH_M along the line of sight and return to q_view (6,): the
        controller's reply (its time; the arm settles with a new repeatability draw)."""
        from ita.robot import from_waypoints
        from ita.robot.controller import joint_offset

        world = self.world
        pose = np.asarray(view_pose, dtype=float)
        look = pose[:3, 2] / np.linalg.norm(pose[:3, 2])      # the sensor looks along its z axis
        tcp = world.held_tool.tcp.matrix()
        q_back = q_view + joint_offset(world.model, q_view, tcp, -REAPPROACH_M * look)
        traj = from_waypoints(world.model, [np.asarray(world.q), q_back, q_view], speed_scale=RETRACT_SPEED)
        return self.controller.execute(traj, command="reapproach")

    def _measure(self, command: Command, now: float) -> Any:
        from ita.executive.adapters import Completion
        from ita.vision.measure import frames_for, measure_frames

        spec_id = spec_of_message(command.message) or ""
        group = self.reasoner.mkb.group_of(spec_id)
        frames = self.frames.get(group.id) if group is not None else None
        if not frames:
            return Completion(now, _exception("NO_IMAGE", f"no frame for {spec_id}", spec_id))
        replies, took = {}, 0.0
        for m in self._members(group, spec_id):
            used = frames[:frames_for(self.specs[m], self.vctx).count]
            replies[m] = _guarded_measure(measure_frames, used, self.specs[m], self.vctx)
            took += VISION_SECONDS * len(used)
        self._results.update(replies)
        self.stats["vision_s"] += took
        reply = replies[spec_id]
        if not reply.ok:
            return Completion(now + took, _exception("VISION", f"vision: {reply.reason.value}: {reply.detail}",
                                                     reply.reason.value))
        value, sigma = float(reply.value), float(reply.uncertainty)
        if not (math.isfinite(value) and math.isfinite(sigma)):
            return Completion(now + took, _exception("VISION", "vision: not a number", "garbage"))
        return Completion(now + took, Reply.normal(Term("VALUE", (value, sigma))))
