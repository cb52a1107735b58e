"""The SLRA's stream: range frames of a view group at the arm's pose, then Vision.

    slra = SlraDevice(world, scene, poses, vision_ctx, specs, rng)

- SCAN(patches(meas(Id))): the frames of Id's view group (the MKB), taken from the
  group's anchor pose; replies ``IMAGE(Group)`` with the frames as data
  (:class:`~ita.devices.data.ScanData`).  A group whose members need several frames
  (:func:`ita.vision.scan.frames_for`: a position whose only datum is the arm's
  pose) gets them at one SCAN, each after a re-approach: the arm backs off
  :data:`REAPPROACH_M` from the part and comes back to the viewing configuration
  (through the robot controller, so each return settles with a new repeatability draw
  and takes its real time).  Only as many as the decision needs: after 1, 2, 4, 8 ...
  frames Vision measures those members on the frames so far, and once each is decided
  (ISO 14253-1, conforms or does not conform with its U) no more are taken
  (:meth:`SlraDevice._decided`; Vision's time for it counts).  A reinspection may ask for
  more frames of a spec (``SlraDevice.frames_asked``, kb/tasks.pl ``more_frames(N)``): those
  are all taken, at the group's pixels, and Vision averages them.
- MEASURE(min_value(meas(Id)), ...): Vision on the group's last frames, for every
  member of the group; replies ``VALUE(V, S)`` for Id (or ``VISION(reason)``) with one
  :class:`~ita.devices.data.MeasuredValue` per member as data.

The Exception Handler's tests on this stream:

- CALIBRATE(Tool, cal_block): a small frame of the calibration block's face from above
  (the arm at the block's approach point): ``VALUE(RangeMm, SigmaMm)`` of its plane, or
  ``VISION(too_few_pixels)`` when most returns are lost (a dirty window, a failed laser).
- RESCAN(patches(meas(Id))): the feature once more from a second stand-off
  (:data:`RESCAN_BACK_M` further along the line of sight, and back): Vision's reply for Id.

A dirty window (the DIRTY_WINDOW fault of the tool) loses most returns
(:data:`DIRTY_DROPOUT`) and dims the rest; a failed laser or detector (SLRA_FAILED) loses
every return, and cleaning the window does not bring them back.

Times: a SCAN ends after its frames' scan times (and the re-approaches, which advance
the clock through the controller); Vision takes :data:`VISION_SECONDS` per frame it
measures.  The executive advances the clock to each reply.
"""

from __future__ import annotations

import contextlib
import math
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import replace

import numpy as np
from numpy.typing import ArrayLike

from ita.archive.decision import decide
from ita.archive.model import BOUNDED_BELOW
from ita.devices.arm import RETRACT_SPEED, exception_reply
from ita.devices.data import MeasuredValue, ScanData, spec_of_message
from ita.executive.adapters import Completion, PoseResolver
from ita.executive.commands import Command, Reply, Wait
from ita.geometry.mkb import ViewGroup
from ita.kinematics.fk import flange_poses
from ita.kinematics.settle import joint_translation
from ita.logic.json_value import JsonValue
from ita.logic.terms import Term
from ita.robot import RobotController, from_waypoints
from ita.robot.controller import MotionReply
from ita.sensors.slra_frame import RangeFrame, ScanGeometry
from ita.sim.faults import Fault
from ita.sim.inject import FaultInjector
from ita.sim.slra import SlraParams, SlraScene, simulate_frame
from ita.sim.world import SimWorld
from ita.specs.model import MeasurementSpec
from ita.vision.context import (
    VisionContext,
    VisionException,
    VisionFailure,
    VisionReply,
    VisionResult,
)
from ita.vision.measure import measure_frames
from ita.vision.scan import FramePlan, frames_for
from ita.workcell.model import PartPlacement

__all__ = ["DIRTY_DROPOUT", "REAPPROACH_M", "RESCAN_BACK_M", "VISION_SECONDS", "SlraDevice"]

#: simulated seconds Vision takes per measurement in a frame (patches, fits)
VISION_SECONDS = 0.15
#: how far (m) the arm backs off along the line of sight between the frames of a
#: multi-frame SLRA measurement, so that each return is a real approach of the pose
REAPPROACH_M = 0.02
#: how far (m) beyond the viewing pose a RESCAN looks from (the second stand-off)
RESCAN_BACK_M = 0.08
#: share of the returns a dirty window loses (and how much it dims the others)
DIRTY_DROPOUT = 0.97
DIRTY_DIMMING = 0.3
#: the frame of the calibration block: pixels and window (deg)
CAL_SHAPE = (48, 48)
CAL_FOV_DEG = (3.0, 3.0)
#: a calibration frame is good with at least this share of valid pixels
CAL_MIN_VALID = 0.5


#: Vision's measurement of a spec in frames (ita.vision.measure.measure_frames)
Measure = Callable[[Sequence[RangeFrame], MeasurementSpec, VisionContext], VisionReply]


def _guarded_measure(measure: Measure, frames: Sequence[RangeFrame], spec: MeasurementSpec,
                     vctx: VisionContext) -> VisionReply:
    """Vision's reply; an error inside Vision becomes a NOT_MEASURABLE reply naming it
    (a device reports failures, it never raises)."""

    try:
        return measure(frames, spec, vctx)
    except Exception as exc:  # noqa: BLE001 - any fault of the vision code is a failed measurement
        return VisionException(spec.id, VisionFailure.NOT_MEASURABLE, f"vision error {type(exc).__name__}: {exc}")


def _value(spec_id: str, reply: VisionReply) -> MeasuredValue:
    if isinstance(reply, VisionResult):     # reply.ok
        return MeasuredValue(spec_id, float(reply.value), float(reply.uncertainty), source=reply)
    return MeasuredValue(spec_id, None, None, f"vision: {reply.reason.value}: {reply.detail}", reply)


class SlraDevice:
    """The SLRA's stream (see the module docstring).  wanted: which members of a view
    group to measure besides the one asked for (default all)."""

    lookahead = False

    def __init__(self, world: SimWorld, scene: SlraScene, poses: PoseResolver, vision_ctx: VisionContext,
                 specs: Mapping[str, MeasurementSpec], rng: np.random.Generator, *, params: SlraParams | None = None,
                 wanted: Callable[[str], bool] | None = None, controller: RobotController | None = None) -> None:

        self.world = world
        self._scene = scene
        self.poses = poses
        self.vctx = vision_ctx
        self.specs = specs
        self.rng = rng
        self.params = params if params is not None else SlraParams()
        self.wanted = wanted or (lambda _id: True)
        self.controller = controller if controller is not None else RobotController(world)
        self._frames: dict[str, tuple[RangeFrame, ...]] = {}  # group id -> the frames of its last SCAN
        #: spec id -> frames asked for it beyond its own need (a reinspection's more_frames(N)):
        #: each after its own approach, at the group's pixels, averaged by Vision
        self.frames_asked: dict[str, int] = {}
        self.injector: FaultInjector | None = None     # when faults are injected
        self.stats: dict[str, float] = {"frames": 0, "scan_s": 0.0, "vision_s": 0.0, "reapproaches": 0,
                                         "reapproach_s": 0.0}
        self.handlers: dict[str, Callable[[Command, float], Completion]] = {
            "SCAN": self._scan, "MEASURE": self._measure, "CALIBRATE": self._calibrate, "RESCAN": self._rescan}

    @property
    def scene(self) -> SlraScene:
        """What the beam can hit, with the part where the simulator has it now (a knock
        moves it: the scene is placed again)."""
        if self._scene.placement != self.world.part_placement:
            self._scene = self._scene.placed(self.world.part_placement)
        return self._scene

    @contextlib.contextmanager
    def frames_for_reading(self, spec_id: str, frames: int) -> Iterator[None]:
        """At least `frames` frames of `spec_id` (each after its own approach) while inside:
        a reading of the reference feature or of a datum, not the run's own need."""
        asked = self.frames_asked
        before = asked.get(spec_id)
        asked[spec_id] = max(frames, before or 1)
        try:
            yield
        finally:
            if before is None:
                asked.pop(spec_id, None)
            else:
                asked[spec_id] = before

    def register(self, placement: PartPlacement, u_mm: float = 0.0) -> None:
        """Measure in the part frame of `placement` from now on (the part registered on its
        datums, ita.task.align; `u_mm` its standard uncertainty per axis at the part's
        farthest corner): Vision turns frames into part points through it."""
        self.vctx = replace(self.vctx, placement=placement, registration_u_mm=u_mm)

    # -- the protocol ------------------------------------------------------------------
    def begin(self, items: Sequence[Command | Wait], now: float) -> None:
        pass

    def start(self, command: Command, now: float) -> Completion:
        if self.injector is not None:
            self.injector.before(command, "slra")
        handler = self.handlers.get(command.name)
        if handler is None:
            return Completion(now, exception_reply("UNSUPPORTED", f"the SLRA cannot {command.text}",
                                                   command.name.lower()))
        held_up = self.controller.held_up_s
        done = handler(command, now)
        waited = self.controller.held_up_s - held_up      # the other arm's zones, before it began
        return replace(done, waited_s=waited) if waited > 0 else done

    def stop(self, now: float) -> None:
        pass

    def snapshot(self) -> Mapping[str, JsonValue]:
        return {"frames": sorted(self._frames)}

    # -- commands ----------------------------------------------------------------------
    def _scan(self, command: Command, now: float) -> Completion:

        world = self.world
        tool = world.held_tool
        if tool is None or tool.tool_class.value != "slra_tool":
            return Completion(now, exception_reply("NO_SENSOR", "no SLRA on the flange", "no_sensor"))
        spec_id = spec_of_message(command.message)
        try:
            group = self.poses.resolve(command.args[0], tool.name)
            anchor = self.poses.resolve(Term("viewing_pose", (Term("meas", (group.anchor,)),)), tool.name)
        except KeyError as exc:
            return Completion(now, exception_reply("NO_VIEW", str(exc), spec_id or "?"))
        plan = self._frame_plan(group)
        t = max(now, world.clock.now)
        frames: list[RangeFrame] = []
        # frames asked for (a reinspection's) are all taken; a spec's own need stops once decided
        asked = any(self.frames_asked.get(m, 1) > 1 for m in self._members(group, group.anchor))
        checks = set() if asked else {2 ** i for i in range(plan.count.bit_length())} - {plan.count}
        for k in range(plan.count):
            if k:
                moved = self._reapproach(np.asarray(anchor.q, dtype=float), anchor.pose)
                if not moved.ok:
                    return Completion(t + moved.time_s, exception_reply(
                        "REAPPROACH", f"re-approach {k} of {plan.count - 1} for {group.id}: {moved.message}",
                        moved.status.value))
                t += moved.time_s
                self.stats["reapproaches"] += 1
                self.stats["reapproach_s"] += moved.time_s
            shape = tuple(group.pixels) if k == 0 else plan.shape
            frame = simulate_frame(self.scene, world.tcp_pose(), ScanGeometry(shape, tuple(group.fov_deg)),
                                   self._physics(tool.name), self.rng, reported_pose=np.asarray(anchor.pose),
                                   timestamp=t, sensor=tool.name)
            frames.append(frame)
            t += frame.frame_time
            self.stats["frames"] += 1
            self.stats["scan_s"] += frame.frame_time
            if len(frames) in checks:
                decided, took = self._decided(group, frames)
                t += took
                self.stats["vision_s"] += took
                if decided:
                    self.stats["reapproaches_saved"] = self.stats.get("reapproaches_saved", 0) \
                        + plan.count - len(frames)
                    break
        self._frames = {group.id: tuple(frames)}
        return Completion(t, Reply.normal(Term("IMAGE", (group.id,)), data=ScanData(group.id, tuple(frames))))

    def _physics(self, tool: str) -> SlraParams:
        """The SLRA's physics now: a dirty window loses most returns and dims the rest; a
        failed laser or detector returns nothing."""
        if self.world.faults.has(Fault.SLRA_FAILED, tool):
            return replace(self.params, dropout_rate=1.0)
        if not self.world.faults.has(Fault.DIRTY_WINDOW, tool):
            return self.params
        return replace(self.params, dropout_rate=DIRTY_DROPOUT,
                       reflectance=self.params.reflectance * DIRTY_DIMMING)

    def _calibrate(self, command: Command, now: float) -> Completion:
        world = self.world
        tool = world.held_tool
        if tool is None or tool.tool_class.value != "slra_tool":
            return Completion(now, exception_reply("NO_SENSOR", "no SLRA on the flange", "no_sensor"))
        t = max(now, world.clock.now)
        frame = simulate_frame(self.scene, world.tcp_pose(), ScanGeometry(CAL_SHAPE, CAL_FOV_DEG),
                               self._physics(tool.name), self.rng, timestamp=t, sensor=tool.name)
        t += frame.frame_time + VISION_SECONDS
        valid = np.isfinite(frame.range_m)
        if valid.mean() < CAL_MIN_VALID:
            return Completion(t, Reply.exception(Term("VISION", ("too_few_pixels",)),
                                                 f"calibration block: {valid.mean():.0%} valid pixels"))
        r = frame.range_m[valid] * 1000.0
        return Completion(t, Reply.normal(Term("VALUE", (float(np.median(r)), float(np.std(r)))),
                                          f"calibration block: {valid.mean():.0%} valid pixels"))

    def _rescan(self, command: Command, now: float) -> Completion:
        world = self.world
        tool = world.held_tool
        spec_id = spec_of_message(command.message) or ""
        if tool is None or tool.tool_class.value != "slra_tool":
            return Completion(now, exception_reply("NO_SENSOR", "no SLRA on the flange", "no_sensor"))
        try:
            group = self.poses.resolve(command.args[0], tool.name)
            anchor = self.poses.resolve(Term("viewing_pose", (Term("meas", (group.anchor,)),)), tool.name)
        except KeyError as exc:
            return Completion(now, exception_reply("NO_VIEW", str(exc), spec_id or "?"))
        q_view = np.asarray(anchor.q, dtype=float)
        pose = np.asarray(anchor.pose, dtype=float)
        look = pose[:3, 2] / np.linalg.norm(pose[:3, 2])
        q_back = q_view + joint_translation(world.model, q_view, tool.tcp.matrix(), -RESCAN_BACK_M * look)
        t = max(now, world.clock.now)
        out = self.controller.execute(from_waypoints(world.model, [np.asarray(world.q), q_back],
                                                     speed_scale=RETRACT_SPEED), command="rescan")
        t += out.time_s
        if not out.ok:
            return Completion(t, exception_reply("REAPPROACH", f"second stand-off for {spec_id}: {out.message}",
                                                 out.status.value))
        # the pose the controller reports there: its forward kinematics of the joints it was
        # sent to (the least-norm step back along the line of sight turns the tool a little too)
        back_pose = flange_poses(world.model, q_back[None])[0] @ tool.tcp.matrix()
        fov = tuple(min(f * 1.0, m) for f, m in zip(group.fov_deg, self.vctx.max_fov_deg))
        frame = simulate_frame(self.scene, world.tcp_pose(), ScanGeometry(tuple(group.pixels), fov),
                               self._physics(tool.name), self.rng, reported_pose=back_pose, timestamp=t,
                               sensor=tool.name)
        t += frame.frame_time
        reply = _guarded_measure(measure_frames, [frame], self.specs[spec_id], self.vctx)
        t += VISION_SECONDS
        back = self.controller.execute(from_waypoints(world.model, [np.asarray(world.q), q_view],
                                                      speed_scale=RETRACT_SPEED), command="rescan")
        t += back.time_s
        data = (_value(spec_id, reply),)
        if isinstance(reply, VisionException):     # not reply.ok
            return Completion(t, Reply.exception(Term("VISION", (reply.reason.value,)),
                                                 f"vision from the second stand-off: {reply.reason.value}", data=data))
        return Completion(t, Reply.normal(Term("VALUE", (float(reply.value), float(reply.uncertainty))), data=data))

    def _members(self, group: ViewGroup, spec_id: str) -> list[str]:
        return [m for m in group.members if m == spec_id or self.wanted(m)]

    def _decided(self, group: ViewGroup, frames: Sequence[RangeFrame]) -> tuple[bool, float]:
        """Whether the frames so far decide every member of `group` that asks for several
        (each conforms or does not, with its U), and Vision's time to find out."""
        took = 0.0
        for m in self._members(group, group.anchor):
            spec = self.specs.get(m)
            if spec is None or self._wanted_frames(m) <= 1:
                continue
            reply = _guarded_measure(measure_frames, list(frames), spec, self.vctx)
            took += VISION_SECONDS * len(frames)
            if isinstance(reply, VisionException) or not (math.isfinite(reply.value) and math.isfinite(reply.uncertainty)):
                return False, took
            d = decide(float(reply.value), 2.0 * float(reply.uncertainty), spec.low_limit, spec.high_limit,
                       bounded_below=spec.kind.value in BOUNDED_BELOW)
            if d.value == "uncertain":
                return False, took
        return True, took

    def _wanted_frames(self, spec_id: str) -> int:
        """The frames Vision averages for `spec_id`: its own need, or more when asked."""
        return max(frames_for(self.specs[spec_id], self.vctx).count, self.frames_asked.get(spec_id, 1))

    def _frame_plan(self, group: ViewGroup) -> FramePlan:
        """The frames the group's wanted members need (the most any of them needs or was
        asked for; frames asked beyond a member's own need are at the group's pixels)."""

        members = [m for m in self._members(group, group.anchor) if m in self.specs]
        plans = [frames_for(self.specs[m], self.vctx) for m in members]
        plan = max(plans, key=lambda p: p.count) if plans else frames_for(self.specs[group.anchor], self.vctx)
        asked = max((self.frames_asked.get(m, 1) for m in members), default=1)
        if asked <= plan.count:
            return plan
        return FramePlan(asked, plan.shape if plan.count > 1 else (int(group.pixels[0]), int(group.pixels[1])))

    def _reapproach(self, q_view: np.ndarray, view_pose: ArrayLike) -> MotionReply:
        """Back off REAPPROACH_M along the line of sight and return to q_view (6,): the
        controller's reply (its time; the arm settles with a new repeatability draw)."""

        world = self.world
        pose = np.asarray(view_pose, dtype=float)
        look = pose[:3, 2] / np.linalg.norm(pose[:3, 2])      # the sensor looks along its z axis
        tool = world.held_tool
        assert tool is not None   # a SCAN re-approaches with the SLRA in hand (checked there)
        tcp = tool.tcp.matrix()
        q_back = q_view + joint_translation(world.model, q_view, tcp, -REAPPROACH_M * look)
        traj = from_waypoints(world.model, [np.asarray(world.q), q_back, q_view], speed_scale=RETRACT_SPEED)
        return self.controller.execute(traj, command="reapproach")

    def _measure(self, command: Command, now: float) -> Completion:

        spec_id = spec_of_message(command.message) or ""
        held = self.world.held
        try:
            group = self.poses.resolve(Term("patches", (Term("meas", (spec_id,)),)), held)
        except KeyError:
            group = None
        frames = self._frames.get(group.id) if group is not None else None
        if not frames:
            return Completion(now, exception_reply("NO_IMAGE", f"no frame for {spec_id}", spec_id))
        replies: dict[str, VisionReply] = {}
        took = 0.0
        for m in self._members(group, spec_id):
            used = frames[:self._wanted_frames(m)]
            replies[m] = _guarded_measure(measure_frames, used, self.specs[m], self.vctx)
            took += VISION_SECONDS * len(used)
        self.stats["vision_s"] += took
        data = tuple(_value(m, r) for m, r in replies.items())
        reply = replies[spec_id]
        if isinstance(reply, VisionException):     # not reply.ok
            return Completion(now + took, Reply.exception(
                Term("VISION", (reply.reason.value,)), f"vision: {reply.reason.value}: {reply.detail}", data=data))
        value, sigma = float(reply.value), float(reply.uncertainty)
        if not (math.isfinite(value) and math.isfinite(sigma)):
            return Completion(now + took, Reply.exception(Term("VISION", ("garbage",)), "vision: not a number",
                                                          data=data))
        return Completion(now + took, Reply.normal(Term("VALUE", (value, sigma)), data=data))
