"""Robot controls: trajectories, execution, bumps, limits, positioning error, faults, tool changes."""

from __future__ import annotations

import numpy as np
import pytest

from ita.kinematics import flange_poses, move_time
from ita.robot import (
    MotionStatus,
    RobotController,
    TimedTrajectory,
    ToolChanger,
    from_waypoints,
)
from ita.robot.waypoints import profile_position, profile_time
from ita.sim.faults import CONTROLLER, Fault, FaultSet
from ita.sim.world import SimWorld

READY = np.array([0.0, 0.057, 0.614, 0.0, 0.114, 1.571])
# found by sampling: joint moves from READY that run into these bodies
INTO_FIXTURE = np.array([0.111, 0.507, -0.435, -0.162, 0.128, 1.7])
INTO_PART = np.array([-0.224, 1.041, -0.483, 0.232, 0.053, 1.808])


@pytest.fixture(scope="module")
def world(builtin_part):
    with SimWorld(part_dir=builtin_part.directory, seed=5, q0=READY) as w:
        yield w


@pytest.fixture()
def ctl(world):
    """A controller on the module's world, which is put back as it was after the test."""
    with world.saved_state():
        world.set_q(READY)
        world.faults = FaultSet()
        yield RobotController(world)
        world.faults = FaultSet()


def test_trajectory_rejects_bad_knots():
    with pytest.raises(ValueError, match="increase"):
        TimedTrajectory(np.array([0.0, 1.0, 1.0]), np.zeros((3, 6)))
    with pytest.raises(ValueError, match="agree"):
        TimedTrajectory(np.array([0.0, 1.0]), np.zeros((3, 6)))
    with pytest.raises(ValueError, match="start at 0"):
        TimedTrajectory(np.array([0.5, 1.0]), np.zeros((2, 6)))


def test_builder_is_synchronised_and_within_limits(world):
    model = world.model
    a, b = READY, READY + np.array([0.6, -0.3, 0.4, 1.0, -0.5, 2.0])
    traj = from_waypoints(model, [a, b], knot_period=0.005)
    np.testing.assert_allclose(traj.start, a)
    np.testing.assert_allclose(traj.end, b)
    assert traj.duration >= float(move_time(model, a, b)) - 1e-9
    speed = np.abs(traj.velocities())
    assert np.all(speed <= model.velocity * (1 + 1e-6))
    accel = np.abs(np.diff(traj.velocities(), axis=0)) / 0.005
    assert np.all(accel <= model.acceleration * 1.01)
    share = (traj.q - a) / (b - a)                          # every joint at the same fraction
    np.testing.assert_allclose(share, share[:, :1].repeat(6, axis=1), atol=1e-9)


def test_single_joint_move_takes_the_kinematics_move_time(world):
    b = READY + np.array([0.0, 0.0, 0.0, 0.0, 0.0, 0.7])
    traj = from_waypoints(world.model, [READY, b])
    assert traj.duration == pytest.approx(float(move_time(world.model, READY, b)))
    total, peak, accel = profile_time(b - READY, world.model.velocity, world.model.acceleration)
    assert total == pytest.approx(traj.duration)
    assert profile_position([0.0, total / 2, total], total, peak, accel) == pytest.approx([0.0, 0.5, 1.0])


def test_execution_takes_the_trajectory_duration(ctl):
    world = ctl.world
    goal = READY + np.array([0.3, -0.1, 0.2, 0.2, -0.2, 0.3])
    traj = from_waypoints(world.model, [READY, goal])
    t0 = world.clock.now
    reply = ctl.execute(traj, command="test move")
    assert reply.ok and reply.command == "test move"
    assert reply.time_s == pytest.approx(traj.duration)
    assert world.clock.now - t0 == pytest.approx(traj.duration)
    tip_error = flange_poses(world.model, world.q)[0, :3, 3] - flange_poses(world.model, goal)[0, :3, 3]
    assert np.linalg.norm(tip_error) < 0.5e-3          # only the positioning error


@pytest.mark.parametrize("goal, obstacle", [(INTO_FIXTURE, "fixture_beam_high"), (INTO_PART, "part")])
def test_driving_into_something_stops_with_a_bump(ctl, goal, obstacle):
    world = ctl.world
    traj = from_waypoints(world.model, [READY, goal])
    reply = ctl.execute(traj)
    assert reply.status is MotionStatus.BUMP and not reply.ok
    assert reply.contact.obstacle == obstacle
    assert reply.contact.moving.startswith("link")
    assert 0.0 < reply.time_s < traj.duration
    assert obstacle in reply.message
    np.testing.assert_allclose(world.q, reply.q)
    assert not np.allclose(world.q, goal, atol=1e-3)       # stopped on the way
    assert world.contacts()                                 # where it touched


def test_allowed_contact_is_not_a_bump(ctl):
    world = ctl.world
    traj = from_waypoints(world.model, [READY, INTO_FIXTURE])
    reply = ctl.execute(traj, allowed=["fixture_beam_high"])
    assert reply.status is MotionStatus.BUMP and reply.contact.obstacle != "fixture_beam_high"
    world.set_q(READY)
    assert ctl.execute(traj, allowed=list(world.bodies)).ok


def test_joint_limits_are_refused_before_moving(ctl):
    world = ctl.world
    bad = READY.copy()
    bad[1] = world.model.upper[1] + 0.05
    t0 = world.clock.now
    reply = ctl.execute(TimedTrajectory(np.array([0.0, 10.0]), np.array([READY, bad])))
    assert reply.status is MotionStatus.JOINT_LIMIT and reply.joint == "j2"
    assert reply.time_s == 0.0 and world.clock.now == t0
    np.testing.assert_allclose(world.q, READY)
    fast = READY + np.array([0.0, 0.0, 0.0, 0.0, 0.0, 1.0])
    reply = ctl.execute(TimedTrajectory(np.array([0.0, 0.1]), np.array([READY, fast])))
    assert reply.status is MotionStatus.JOINT_LIMIT and reply.joint == "j6" and "speed" in reply.message


def test_a_move_onto_a_joint_limit_leaves_the_arm_where_the_next_move_can_start(ctl):
    """The arm settles by its repeatability, but never past a limit: a view whose joint
    solution lies on a limit (IK snaps solutions onto it) does not strand every later
    move with start_out_of_limits."""
    world = ctl.world
    edge = READY.copy()
    edge[0] = world.model.upper[0]                       # j1 on its limit, as IK gives it
    for _ in range(20):                                   # many settle draws: some push outwards
        world.set_q(READY)
        reply = ctl.execute(from_waypoints(world.model, [READY, edge]))
        assert reply.ok, reply.message
        # the Path Planner's start check (within_limits), even with no slack at all
        assert world.model.within_limits(world.q) and world.model.within_limits(world.q, tol=0.0)


def test_trajectory_must_start_at_the_arm(ctl):
    far = READY + 0.2
    reply = ctl.execute(from_waypoints(ctl.world.model, [far, READY]))
    assert reply.status is MotionStatus.REJECTED


def _tcp_errors(ctl, moves):
    world = ctl.world
    target = flange_poses(world.model, READY)[0, :3, 3]
    errors = []
    still = TimedTrajectory(np.array([0.0]), READY[None])
    for _ in range(moves):
        world.set_q(READY)
        assert ctl.execute(still).ok
        errors.append(world.flange_pose()[:3, 3] - target)
    return np.array(errors)


def test_repeatability_error_has_the_stated_spread(ctl):
    errors = _tcp_errors(ctl, 400)
    sigma = ctl.world.cell.arm.repeatability_m / 3.0
    np.testing.assert_allclose(errors.std(axis=0), sigma, rtol=0.15)
    assert np.all(np.abs(errors.mean(axis=0)) < 4 * sigma / np.sqrt(400))
    assert np.max(np.abs(errors)) < 5 * sigma


def test_drift_accumulates_move_after_move(ctl):
    world = ctl.world
    world.faults = FaultSet(drift_per_move_m=1e-4).with_fault(Fault.POSITION_DRIFT, CONTROLLER)
    errors = _tcp_errors(ctl, 30)
    offsets = np.linalg.norm(errors, axis=1)
    assert offsets[-5:].mean() > 2.5e-3                   # about 30 x 0.1 mm
    assert offsets[-5:].mean() > 5 * offsets[:3].mean()
    world.faults = FaultSet()
    assert np.linalg.norm(_tcp_errors(ctl, 3), axis=1).min() > 2.5e-3   # the drift stays until recalibrated


def test_silent_controller_times_out_without_moving(ctl):
    world = ctl.world
    world.faults = FaultSet().with_fault(Fault.CONTROLLER_SILENT)
    traj = from_waypoints(world.model, [READY, READY + 0.1])
    t0 = world.clock.now
    reply = ctl.execute(traj)
    assert reply.status is MotionStatus.TIMEOUT and reply.q is None
    assert reply.time_s == pytest.approx(traj.duration + ctl.reply_timeout_s)
    assert world.clock.now - t0 == pytest.approx(reply.time_s)
    np.testing.assert_allclose(world.q, READY)


def test_tool_pick_up_and_put_down(ctl):
    world = ctl.world
    changer = ToolChanger(ctl)
    t0 = world.clock.now
    reply = changer.pick_up("us_probe_1")
    assert reply.ok, reply
    assert world.held == "us_probe_1"
    assert reply.time_s > changer.latch_time_s and world.clock.now - t0 == pytest.approx(reply.time_s)
    np.testing.assert_allclose(world.tool_pose("us_probe_1"), world.flange_pose(), atol=1e-6)
    lifted = world.q + np.array([0.0, -0.2, 0.0, 0.0, 0.0, 0.0])
    assert ctl.execute(from_waypoints(world.model, [world.q, lifted])).ok
    np.testing.assert_allclose(world.tool_pose("us_probe_1"), world.flange_pose(), atol=1e-6)
    assert changer.pick_up("us_probe_2").status is MotionStatus.REJECTED
    reply = changer.put_down()
    assert reply.ok, reply
    assert world.held is None
    np.testing.assert_allclose(world.tool_pose("us_probe_1"), world.cell.slot_of("us_probe_1").pose.matrix(),
                               atol=1e-6)
    assert changer.put_down().status is MotionStatus.REJECTED
    assert changer.pick_up("no_such_tool").status is MotionStatus.REJECTED


def test_a_step_back_along_the_line_of_sight_keeps_the_tool_s_orientation():
    """joint_translation moves the TCP 80 mm back exactly and does not turn it; the
    position-only least-norm step (joint_offset) turns it by a degree or more there."""
    from ita.kinematics import arm_model
    from ita.kinematics.settle import joint_offset, joint_translation
    from ita.workcell import load_workcell

    wc = load_workcell()
    model, tcp = arm_model(wc.arm), wc.tool("slra_1").tcp.matrix()
    q = np.array([-0.49184, -0.31501, 0.55509, 1.98849, 0.54296, -0.47823])   # a viewing pose of the bulkhead
    start = flange_poses(model, q[None])[0] @ tcp
    step = -0.08 * start[:3, 2] / np.linalg.norm(start[:3, 2])

    def turned_deg(dq):
        end = flange_poses(model, (q + dq)[None])[0] @ tcp
        r = start[:3, :3].T @ end[:3, :3]
        return float(np.degrees(np.arccos(np.clip((np.trace(r) - 1) / 2, -1, 1)))), end[:3, 3] - start[:3, 3]

    angle, moved = turned_deg(joint_translation(model, q, tcp, step))
    assert angle < 1e-4 and np.allclose(moved, step, atol=1e-7)
    assert turned_deg(joint_offset(model, q, tcp, step))[0] > 0.5


@pytest.mark.parametrize("tool, tubes", [(None, True), ("us_probe_90", True), ("slra_1", True),
                                         ("us_probe_90", False), (None, False)])
def test_no_gap_closes_faster_than_the_swept_bound_says(ctl, tool, tubes, monkeypatch):
    """The bound the controller skips checks by: from one control period to the next, the
    arm's (and held tool's) gap to the cell, and the tool's to the arm, change by no more
    than the swept bound grows, on random moves through the cell (gaps measured by
    pybullet up to 0.5 m; a gap is 1-Lipschitz in every point's motion).  tubes=False: an
    arm whose collision shapes the tubes may not enclose (a user's URDF with meshes or
    boxes) is bounded by its links' reach alone."""
    import dataclasses

    from ita.kinematics import link_frames

    world = ctl.world
    if not tubes:
        monkeypatch.setattr(world, "model", dataclasses.replace(world.model, tubes_complete=False))
    if tool is not None:
        world.attach(tool)
    rng = np.random.default_rng(11)
    model = world.model
    worst = 0.0
    for _ in range(6):
        goal = np.clip(READY + rng.uniform(-0.9, 0.9, 6), model.lower, model.upper)
        traj = from_waypoints(model, [READY, goal])
        configs = traj.sample(np.linspace(0.0, traj.duration, 40))
        cell, tool_swept = ctl._swept(configs, link_frames(model, configs))
        gaps = []
        for q in configs:
            world.set_q(q)
            gaps.append(world.contacts_and_gaps(0.0, (), 0.5)[1:])
        gaps = np.array(gaps)
        assert np.all(np.abs(np.diff(gaps[:, 0])) <= np.diff(cell) + 1e-6)
        if tool is None:
            assert np.all(gaps[:, 1] == np.inf)                   # no tool, no gap of it to the arm
        else:
            assert np.all(np.abs(np.diff(gaps[:, 1])) <= np.diff(tool_swept) + 1e-6)
        worst = max(worst, float(np.max(np.abs(np.diff(gaps[:, 0])) / np.maximum(np.diff(cell), 1e-12))))
    assert worst > 0.2          # the bound is not vacuous: some step closes a good part of it


@pytest.mark.parametrize("goal", [INTO_FIXTURE, INTO_PART])
def test_checks_skipped_by_the_swept_bound_find_the_first_contact_of_checking_every_period(ctl, goal, monkeypatch):
    """A move with a probe held into the fixture or the part: the controller's reply (what
    touched what, when, where the arm stopped) is the reply of checking every period."""
    world = ctl.world
    world.attach("us_probe_1")
    start = world.state()
    traj = from_waypoints(world.model, [READY, goal])
    checks = []
    counted = world.contacts_and_gaps

    def counting(*args, **kwargs):
        checks.append(1)
        return counted(*args, **kwargs)

    monkeypatch.setattr(world, "contacts_and_gaps", counting)
    skipped = ctl.execute(traj)
    n_skipped = len(checks)
    world.restore(start)
    monkeypatch.setattr(ctl, "_swept", lambda configs, frames: (np.arange(len(configs)) * 1e9,) * 2)
    every = ctl.execute(traj)
    assert skipped.status is every.status is MotionStatus.BUMP
    assert skipped == every
    assert n_skipped < len(checks) - n_skipped        # far fewer checks than periods


class _FoldingGate:
    """A conductor that tells the arm to fold at its first claim, then refuses."""

    def __init__(self, fold) -> None:
        self.fold, self.claims, self.moves = tuple(fold), [], []

    def claim(self, t, times, q, pinned=False):
        from ita.robot.gate import Grant

        self.claims.append(pinned)
        return Grant("fold", 0.0, self.fold) if len(self.claims) == 1 else Grant("refuse", 0.0, None, "test")

    def moved(self, t, q, flown=None):
        self.moves.append(np.array(q))


def test_an_arm_told_to_fold_where_every_way_back_touches_the_cell_stays_and_asks_again(ctl):
    """Its probe deep in a pocket (here: the arm pressed on the part after a bump), a fold
    would drag it along the part: it stays where it is, says so (the conductor then never
    asks it to fold from there again), and asks for its motion again."""
    world = ctl.world
    assert ctl.execute(from_waypoints(world.model, [READY, INTO_PART])).status is MotionStatus.BUMP
    stuck = np.array(world.q)
    assert world.contacts()
    gate = _FoldingGate(np.array([0.0, -0.236, -1.321, 0.0, 0.0, 0.0]))
    ctl.gate = gate
    try:
        reply = ctl.execute(from_waypoints(world.model, [stuck, READY]))
    finally:
        ctl.gate = None
    assert len(gate.claims) == 2 and not any(gate.claims)
    assert len(gate.moves) == 1 and np.allclose(gate.moves[0], stuck)       # a fold that stopped where it began
    assert reply.status is MotionStatus.REJECTED and "test" in reply.message
    np.testing.assert_allclose(world.q, stuck)                           # never dragged along the part


class _AnsweringGate(_FoldingGate):
    """A conductor that answers every claim with `kind`."""

    def __init__(self, kind: str) -> None:
        super().__init__(np.zeros(6))
        self.kind = kind

    def claim(self, t, times, q, pinned=False):
        from ita.robot.gate import Grant

        self.claims.append(pinned)
        return Grant(self.kind, 2.0, None, "test")


def test_a_person_moves_an_arm_whose_controller_is_down_once_the_space_is_granted(ctl):
    """Its controller failed for good: a person walks it to the target by hand, after the
    conductor's wait, and the conductor is told where it ended; refused, it stays."""
    world = ctl.world
    world.faults = FaultSet().with_fault(Fault.CONTROLLER_SILENT)
    target = np.array([0.0, -0.236, -1.321, 0.0, 0.0, 0.0])
    ctl.gate = _AnsweringGate("refuse")
    try:
        assert not ctl.moved_by_hand(target, 300.0)
        np.testing.assert_allclose(world.q, READY)
        ctl.gate = gate = _AnsweringGate("go")
        t0 = world.clock.now
        assert ctl.moved_by_hand(target, 300.0)
    finally:
        ctl.gate = None
    np.testing.assert_allclose(world.q, target)
    assert world.clock.now == pytest.approx(t0 + 2.0 + 300.0)
    assert len(gate.moves) == 1 and np.allclose(gate.moves[0], target)
