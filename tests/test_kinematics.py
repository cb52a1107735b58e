"""Tests of ita.kinematics: forward and inverse kinematics, reach, motion time, tool poses."""

from __future__ import annotations

import dataclasses
import math
import warnings

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from ita.kinematics import (
    JOINT_LIMIT_TOL,
    ArmModel,
    IKStatus,
    approach_poses,
    arm_model,
    choose_centred,
    choose_nearest,
    flange_of_tool,
    flange_poses,
    ik_flange,
    ik_tool,
    joint_times,
    limit_margin,
    link_frames,
    link_segments,
    measurement_poses,
    move_time,
    move_time_matrix,
    reachable,
    slot_count,
    surface_frames,
    tcp_poses,
)
from ita.specs.model import MeasurementKind, Tool
from ita.workcell import Workcell, load_workcell, reach_report

THICKNESS_KINDS = {MeasurementKind.WEB_THICKNESS, MeasurementKind.FLANGE_THICKNESS}


@pytest.fixture(scope="module")
def cell() -> Workcell:
    return load_workcell()


@pytest.fixture(scope="module")
def model(cell: Workcell) -> ArmModel:
    return arm_model(cell.arm)


@pytest.fixture(scope="module")
def random_configs(model: ArmModel) -> np.ndarray:
    """1000 configurations (1000, 6) uniform within the joint limits (seeded)."""
    return np.random.default_rng(7).uniform(model.lower, model.upper, (1000, 6))


@pytest.fixture(scope="module")
def specs(builtin_part):
    from ita.specs.io import read_specs

    return read_specs(builtin_part.specs_path)


def _poses_close(a: np.ndarray, b: np.ndarray, tol: float) -> bool:
    return bool(np.abs(np.asarray(a) - np.asarray(b)).max() <= tol)


# --- forward kinematics -------------------------------------------------------------------

def test_fk_matches_pybullet(cell: Workcell, model: ArmModel, random_configs: np.ndarray) -> None:
    """The flange's world pose agrees with pybullet's; pybullet's FK works in single
    precision (its zero-pose quaternion reads 0.70710677), hence the 1e-6 tolerance."""
    pb = pytest.importorskip("pybullet")
    client = pb.connect(pb.DIRECT)
    try:
        body = pb.loadURDF(str(cell.arm.urdf), cell.arm.base.position, cell.arm.base.quaternion,
                           useFixedBase=True, physicsClientId=client)
        names = [pb.getJointInfo(body, i, physicsClientId=client)[12].decode()
                 for i in range(pb.getNumJoints(body, physicsClientId=client))]
        flange = names.index(cell.arm.flange_link)
        qs = random_configs[:200]
        ours = flange_poses(model, qs)
        for q, pose in zip(qs, ours):
            for j, angle in enumerate(q):
                pb.resetJointState(body, j, float(angle), physicsClientId=client)
            state = pb.getLinkState(body, flange, computeForwardKinematics=True, physicsClientId=client)
            rotation = np.array(pb.getMatrixFromQuaternion(state[5])).reshape(3, 3)
            assert np.allclose(state[4], pose[:3, 3], atol=1e-6, rtol=0)
            assert np.allclose(rotation, pose[:3, :3], atol=1e-6, rtol=0)
    finally:
        pb.disconnect(client)


def test_fk_matches_ikpy_in_double_precision(model: ArmModel, cell: Workcell, random_configs: np.ndarray) -> None:
    """An independent double-precision URDF chain (ikpy) agrees to rounding."""
    ikpy_chain = pytest.importorskip("ikpy.chain")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # ikpy warns about the fixed flange joint
        chain = ikpy_chain.Chain.from_urdf_file(str(cell.arm.urdf), base_elements=["base_link"])
    base = cell.arm.base.matrix()
    for q, pose in zip(random_configs[:200], flange_poses(model, random_configs[:200])):
        theirs = base @ chain.forward_kinematics([0.0, *q, 0.0])
        assert _poses_close(theirs, pose, 1e-12)


def test_fk_single_config_and_shapes(model: ArmModel) -> None:
    assert flange_poses(model, np.zeros(6)).shape == (1, 4, 4)
    assert link_frames(model, np.zeros((5, 6))).shape == (5, 8, 4, 4)
    with pytest.raises(ValueError, match=r"\(n, 6\)"):
        flange_poses(model, np.zeros((3, 5)))


def test_zero_pose_matches_the_urdf_description(model: ArmModel, cell: Workcell) -> None:
    """Zero pose: upper arm vertical, forearm along +x; the flange d6 beyond the wrist
    centre, its approach axis (z) along +x."""
    k = cell.arm.kinematics
    pose = flange_poses(model, np.zeros(6))[0]
    base_z = cell.arm.base.position[2]
    assert np.allclose(pose[:3, 3], [k.a1 + k.d4 + k.d6, 0.0, base_z + k.d1 + k.a2], atol=1e-12)
    assert np.allclose(pose[:3, 2], [1.0, 0.0, 0.0], atol=1e-12)


def test_link_tubes_come_from_the_urdf_and_follow_the_links(model: ArmModel) -> None:
    radii = dict(zip([model.link_names[i] for i in model.tube_links], model.tube_radii))
    assert radii["link2"] == pytest.approx(0.13) and radii["link4"] == pytest.approx(0.09)
    assert len(model.tube_radii) == 10
    q = np.random.default_rng(3).uniform(model.lower, model.upper, (50, 6))
    tubes = link_segments(model, q)
    frames = link_frames(model, q)
    assert tubes.shape == (50, 10, 2, 3)
    # the upper arm's capsule runs from the shoulder (j2) to the elbow (j3)
    upper_arm = int(np.flatnonzero([model.link_names[i] == "link2" for i in model.tube_links])[0])
    assert np.allclose(tubes[:, upper_arm, 0], frames[:, 2, :3, 3], atol=1e-12)
    assert np.allclose(tubes[:, upper_arm, 1], frames[:, 3, :3, 3], atol=1e-12)
    # rigid: every tube keeps its URDF length in every configuration
    lengths = np.linalg.norm(tubes[:, :, 1] - tubes[:, :, 0], axis=-1)
    assert np.allclose(lengths, np.linalg.norm(model.tube_ends[:, 1] - model.tube_ends[:, 0], axis=-1))



@pytest.mark.parametrize("change, complete", [
    (None, True),
    (("<cylinder radius=\"0.3\" length=\"0.55\"/>", "<box size=\"0.6 0.6 0.55\"/>"), False),   # link1's
    (("</robot>", "<link name=\"lamp\"><collision><geometry><sphere radius=\"0.1\"/></geometry></collision>"
                  "</link><joint name=\"lamp_mount\" type=\"fixed\"><parent link=\"link3\"/>"
                  "<child link=\"lamp\"/></joint></robot>"), False),                   # off the chain
    (("</robot>", "<link name=\"plinth\"><collision><geometry><box size=\"1 1 0.1\"/></geometry></collision>"
                  "</link><joint name=\"plinth_mount\" type=\"fixed\"><parent link=\"base_link\"/>"
                  "<child link=\"plinth\"/></joint></robot>"), True),                  # does not move
])
def test_tubes_are_complete_only_when_they_enclose_every_moving_collision_shape(cell: Workcell, tmp_path, change,
                                                                               complete) -> None:
    text = cell.arm.urdf.read_text()
    if change is not None:
        assert change[0] in text
        text = text.replace(change[0], change[1])
    urdf = tmp_path / "arm.urdf"
    urdf.write_text(text)
    assert arm_model(dataclasses.replace(cell.arm, urdf=urdf)).tubes_complete is complete


# --- inverse kinematics -------------------------------------------------------------------

def test_ik_round_trip_contains_the_config(model: ArmModel, random_configs: np.ndarray) -> None:
    poses = flange_poses(model, random_configs)
    ik = ik_flange(model, poses)
    assert ik.q.shape == (1000, slot_count(model), 6) and slot_count(model) == 16
    assert ik.found.all()
    error = np.abs(np.nan_to_num(ik.q, nan=9.0) - random_configs[:, None, :]).max(axis=-1)
    assert np.where(ik.valid, error, np.inf).min(axis=-1).max() < 1e-8


def test_ik_every_solution_reproduces_the_pose_within_limits(model: ArmModel, random_configs: np.ndarray) -> None:
    poses = flange_poses(model, random_configs)
    ik = ik_flange(model, poses)
    q = ik.q[ik.valid]
    target = np.broadcast_to(poses[:, None], (*ik.valid.shape, 4, 4))[ik.valid]
    assert _poses_close(flange_poses(model, q), target, 1e-10)
    assert model.within_limits(q).all()
    assert ik.valid.sum(axis=1).min() >= 1


@settings(max_examples=150, deadline=None)
@given(
    st.lists(st.floats(0.0, 1.0), min_size=6, max_size=6),
    st.sampled_from(["free", "wrist_singular", "at_limits", "elbow_straight"]),
)
def test_ik_round_trip_at_special_configs(model: ArmModel, fractions: list[float], case: str) -> None:
    q = model.lower + np.asarray(fractions) * (model.upper - model.lower)
    if case == "wrist_singular":
        q[4] = 0.0
    elif case == "at_limits":
        q = np.where(np.asarray(fractions) < 0.5, model.lower, model.upper)
    elif case == "elbow_straight":
        q[2] = -math.pi / 2
    pose = flange_poses(model, q)[0]
    ik = ik_flange(model, pose)
    assert ik.status(()) is IKStatus.OK
    solutions = ik.solutions(())
    # at singular and at-limit configurations IK keeps micrometre accuracy (the arm's
    # repeatability is 0.25 mm); elsewhere it is exact to 1e-10 (tests above).  A solution
    # up to JOINT_LIMIT_TOL (1e-6 rad) past a limit is clipped onto it, which moves the
    # flange by that angle times its distance from the joint's axis (under 3 m): a shoulder
    # flipped by pi from -45 deg lands 1e-6 rad past +135 deg and 1.03e-6 m off
    assert _poses_close(flange_poses(model, solutions), np.broadcast_to(pose, (len(solutions), 4, 4)),
                        3.0 * JOINT_LIMIT_TOL)
    # j5 = 0: only j4 + j6 is determined; near it (|j5| < 0.01 rad) j4 - j6 is ill-conditioned
    # (an error of 1e-9 in the pose grows by 1 / sin j5), so the sum is what is compared there
    if case == "wrist_singular" or abs(q[4]) < 1e-2:
        def key(c: np.ndarray) -> np.ndarray:
            return np.r_[c[:3], c[4], np.cos(c[3] + c[5]), np.sin(c[3] + c[5])]

        assert min(np.abs(key(s) - key(q)).max() for s in solutions) < 1e-7
    else:  # j4's range is a whole turn (+-3.141593): at its ends compare modulo 2 pi
        error = np.abs(solutions - q)
        error[:, 3] = np.abs((solutions[:, 3] - q[3] + math.pi) % (2 * math.pi) - math.pi)
        assert error.max(axis=1).min() < 1e-6


def test_ik_gives_eight_branches_when_the_limits_allow(model: ArmModel) -> None:
    """With every joint free over one turn, a generic pose has 8 distinct solutions."""
    free = dataclasses.replace(model, lower=np.full(6, -math.pi), upper=np.full(6, math.pi))
    q = np.array([0.4, 0.3, -0.5, 0.7, 0.9, -0.4])
    pose = flange_poses(free, q)[0]
    ik = ik_flange(free, pose)
    solutions = ik.solutions(())
    assert len(solutions) == 8 and slot_count(free) == 8
    assert _poses_close(flange_poses(free, solutions), np.broadcast_to(pose, (8, 4, 4)), 1e-10)
    # the branches: two j1 values (front / back), a flipped wrist in each arm branch
    assert len(np.unique(np.round(solutions[:, 0], 9))) == 2
    assert np.allclose(np.sort(np.abs(solutions[:, 4]))[::2], np.sort(np.abs(solutions[:, 4]))[1::2])


def test_ik_j6_turns_give_alternatives(model: ArmModel) -> None:
    """j6 spans +-270 deg: j6 = 2.0 and 2.0 - 2 pi are both solutions, 0.5 alone is one."""
    q = np.array([0.1, 0.2, -0.2, 0.3, 0.6, 2.0])
    solutions = ik_flange(model, flange_poses(model, q)[0]).solutions(())
    same_arm = solutions[np.all(np.abs(solutions[:, :5] - q[:5]) < 1e-9, axis=1)]
    assert sorted(same_arm[:, 5]) == pytest.approx([2.0 - 2 * math.pi, 2.0])
    q[5] = 0.5
    solutions = ik_flange(model, flange_poses(model, q)[0]).solutions(())
    same_arm = solutions[np.all(np.abs(solutions[:, :5] - q[:5]) < 1e-9, axis=1)]
    assert same_arm[:, 5] == pytest.approx([0.5])


def test_ik_batch_shapes(model: ArmModel, random_configs: np.ndarray) -> None:
    poses = flange_poses(model, random_configs[:24]).reshape(2, 12, 4, 4)
    ik = ik_flange(model, poses)
    assert ik.q.shape == (2, 12, 16, 6) and ik.codes.shape == (2, 12)
    merged = ik.flatten_batch()
    assert merged.q.shape == (2, 192, 6) and merged.found.all()


def test_unreachable_poses_say_why(model: ArmModel) -> None:
    far = np.eye(4)
    far[:3, 3] = (10.0, 0.0, 1.5)
    # wrist centre 1.5 m straight behind the base at shoulder height, tool pointing down
    behind = np.diag([1.0, -1.0, -1.0, 1.0])
    behind[:3, 3] = (-1.5, 0.0, 0.6 + 0.85 - model.kinematics.d6)
    ik = ik_flange(model, np.stack([far, behind]))
    assert ik.statuses() == [IKStatus.OUT_OF_REACH, IKStatus.JOINT_LIMITS]
    assert not ik.found.any() and np.isnan(ik.q[0]).all()
    assert ik.blocking_joints(1) == (0,)  # facing it, only j1 is out of range
    assert ik.blocking_joints(0) == ()
    assert ik.counts() == {IKStatus.OUT_OF_REACH: 1, IKStatus.JOINT_LIMITS: 1}


def test_wrist_margin_reports_the_singularity(model: ArmModel) -> None:
    q = np.array([0.0, 0.3, -0.3, 0.5, 0.01, 0.2])
    pose = flange_poses(model, q)[0]
    assert ik_flange(model, pose).status(()) is IKStatus.OK
    assert ik_flange(model, pose, wrist_margin=0.1).status(()) is IKStatus.WRIST_SINGULARITY


# --- tool poses, reach and choosing a solution -----------------------------------------------

def test_surface_frames_are_right_handed_and_look_into_the_surface() -> None:
    normals = np.array([[-1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.3, -0.4, 0.5]])
    points = np.array([[2.0, 0.0, 1.4], [1.0, 0.5, 1.0], [0.0, 0.0, 0.0]])
    frames = surface_frames(points, normals, np.linspace(0, 2 * np.pi, 7), standoff=0.2)
    rot = frames[..., :3, :3]
    assert np.allclose(rot @ np.swapaxes(rot, -1, -2), np.eye(3), atol=1e-12)
    assert np.allclose(np.linalg.det(rot), 1.0)
    unit = normals / np.linalg.norm(normals, axis=1, keepdims=True)
    assert np.allclose(rot[..., 2], -unit[:, None, :])
    assert np.allclose(frames[..., :3, 3], (points + 0.2 * unit)[:, None, :])
    # roll 0 keeps the tool's y axis as near to world up as it can be
    assert frames[0, 0, 2, 1] == pytest.approx(1.0)


def _spec_arrays(specs, us: bool):
    rows = [s for s in specs if (s.kind in THICKNESS_KINDS) == us]
    return np.array([s.point for s in rows]), np.array([s.normal for s in rows])


def test_bent_probe_puts_its_tip_on_the_point(cell: Workcell, model: ArmModel, specs) -> None:
    tool = cell.tool("us_probe_1")
    assert not tool.is_straight
    points, normals = _spec_arrays(specs, us=True)
    poses = measurement_poses(cell.part, points, normals, tool)
    ik = ik_tool(model, poses, tool.tcp.matrix()).flatten_batch()
    q, found = choose_nearest(model, ik, np.zeros(6))
    assert found.all()
    tip = tcp_poses(model, q, tool.tcp.matrix())
    world_points = cell.part.to_world(points)
    world_normals = cell.part.normals_to_world(normals)
    assert np.allclose(tip[:, :3, 3], world_points, atol=1e-9)
    assert np.allclose(tip[:, :3, 2], -world_normals, atol=1e-9)
    # and the flange is well away from the point: the probe really is bent
    flange = flange_poses(model, q)[:, :3, 3]
    assert np.linalg.norm(flange - world_points, axis=1).min() > 0.25
    assert np.allclose(flange_of_tool(tip, tool), flange_poses(model, q), atol=1e-9)


def test_slra_looks_from_its_nominal_standoff(cell: Workcell, model: ArmModel, specs) -> None:
    tool = cell.tool("slra_1")
    points, normals = _spec_arrays(specs, us=False)
    poses = measurement_poses(cell.part, points[:50], normals[:50], tool, rolls=4)
    assert poses.shape == (50, 4, 4, 4)
    world_points = cell.part.to_world(points[:50])
    distance = np.linalg.norm(poses[..., :3, 3] - world_points[:, None], axis=-1)
    assert np.allclose(distance, tool.standoff_nominal)
    back = approach_poses(poses, 0.05)
    assert np.allclose(np.linalg.norm(back[..., :3, 3] - world_points[:, None], axis=-1), tool.standoff_nominal + 0.05)


def test_bulkhead_specs_are_ik_reachable(cell: Workcell, model: ArmModel, specs) -> None:
    """Count the specs with an IK solution for their tool (collisions ignored); the IK's
    verdict never contradicts the geometric reach test, a necessary condition."""
    is_us = np.array([s.kind in THICKNESS_KINDS for s in specs])
    points = np.array([s.point for s in specs])
    normals = np.array([s.normal for s in specs])
    found = np.zeros(len(specs), dtype=bool)
    for mask, name in ((is_us, "us_probe_1"), (~is_us, "slra_1")):
        tool = cell.tool(name)
        poses = measurement_poses(cell.part, points[mask], normals[mask], tool)
        found[mask] = reachable(model, poses, tool.tcp.matrix()).any(axis=1)
    geometric = reach_report(cell, points, normals, [Tool.ULTRASONIC if u else Tool.SLRA for u in is_us])
    print(f"\nIK-reachable bulkhead specs: {found.sum()} of {len(specs)} "
          f"({is_us.sum()} ultrasonic, {(~is_us).sum()} SLRA)")
    assert not np.any(found & ~geometric.reachable)
    assert found.mean() > 0.95


def test_choose_nearest_and_centred(model: ArmModel, random_configs: np.ndarray) -> None:
    qs = random_configs[:100]
    ik = ik_flange(model, flange_poses(model, qs))
    q, found = choose_nearest(model, ik, qs)
    assert found.all() and np.allclose(q, qs, atol=1e-8)
    centred, _ = choose_centred(model, ik)
    margins = np.where(ik.valid, limit_margin(model, np.nan_to_num(ik.q)), -np.inf)
    assert np.allclose(limit_margin(model, centred), margins.max(axis=1))
    far = np.eye(4)
    far[:3, 3] = (10.0, 0.0, 1.5)
    none_q, none_found = choose_nearest(model, ik_flange(model, far), np.zeros(6))
    assert none_q.shape == (6,) and np.isnan(none_q).all() and not none_found


# --- motion time ---------------------------------------------------------------------------

def test_joint_times_closed_form() -> None:
    v, a = np.array([1.0]), np.array([2.0])
    # short move: triangle, peak speed sqrt(a d) < v
    assert joint_times([0.2], v, a)[0] == pytest.approx(2 * math.sqrt(0.2 / 2.0))
    # long move: trapezoid, d / v + v / a
    assert joint_times([3.0], v, a)[0] == pytest.approx(3.0 + 0.5)
    # continuous where the profiles meet (d = v^2 / a)
    assert joint_times([0.5], v, a)[0] == pytest.approx(1.0)
    assert joint_times([-3.0], v, a)[0] == pytest.approx(3.5)


def test_move_time_is_the_slowest_joint(model: ArmModel) -> None:
    q0 = np.zeros(6)
    q1 = np.array([2.0, 0.05, 0.0, 0.0, 0.0, 0.0])
    v, a = model.velocity[0], model.acceleration[0]
    assert move_time(model, q0, q1) == pytest.approx(2.0 / v + v / a)
    assert move_time(model, q0, q0) == 0.0


def test_cost_matrix(model: ArmModel, random_configs: np.ndarray) -> None:
    qs = random_configs[:200]
    cost = move_time_matrix(model, qs)
    assert cost.shape == (200, 200)
    assert np.allclose(cost, cost.T) and np.all(np.diag(cost) == 0.0)
    assert np.allclose(cost, move_time(model, qs[:, None, :], qs[None, :, :]))
    assert np.all(cost[~np.eye(200, dtype=bool)] > 0.0)
    rect = move_time_matrix(model, qs[:3], qs[3:10])
    assert rect.shape == (3, 7) and np.allclose(rect, cost[:3, 3:10])
    tool_tcp = np.eye(4)
    capped = move_time_matrix(model, qs, tcp=tool_tcp)
    tcp = tcp_poses(model, qs, tool_tcp)[:, :3, 3]
    chord = np.linalg.norm(tcp[:, None] - tcp[None], axis=-1) / model.max_tool_speed
    assert np.allclose(capped, np.maximum(cost, chord)) and np.all(np.diag(capped) == 0.0)
