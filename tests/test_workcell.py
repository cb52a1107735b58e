"""Tests of ita.workcell: the workcell file, the arm's URDF, frames and the reach test."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest

from ita.errors import InputError
from ita.specs.model import Tool
from ita.workcell import (
    Reach,
    Workcell,
    default_workcell_path,
    frames,
    load_workcell,
    reach_report,
)


@pytest.fixture(scope="module")
def cell() -> Workcell:
    return load_workcell()


@pytest.fixture(scope="module")
def arm_sim(cell: Workcell):
    """A pybullet DIRECT client with the arm loaded at its base pose: (pybullet, client, body)."""
    pb = pytest.importorskip("pybullet")
    client = pb.connect(pb.DIRECT)
    body = pb.loadURDF(str(cell.arm.urdf), cell.arm.base.position, cell.arm.base.quaternion,
                       useFixedBase=True, physicsClientId=client)
    yield pb, client, body
    pb.disconnect(client)


# --- the workcell file --------------------------------------------------------------------

def test_default_workcell_has_the_fixed_names(cell: Workcell) -> None:
    assert cell.arm.name == "t3"
    assert {t.name: t.tool_class for t in cell.tools} == {
        "us_probe_1": Tool.ULTRASONIC, "us_probe_2": Tool.ULTRASONIC, "us_probe_90": Tool.ULTRASONIC_BENT,
        "slra_1": Tool.SLRA, "slra_2": Tool.SLRA,
    }
    assert cell.rack.name == "rack"
    assert {s.name: s.tool for s in cell.rack.slots} == {
        "slot_1": "us_probe_1", "slot_2": "us_probe_2", "slot_3": "slra_1", "slot_4": "slra_2",
        "slot_5": "us_probe_90",
    }
    assert cell.couplant_station.name == "couplant_station"
    assert cell.cal_block.name == "cal_block"
    assert cell.slot_of("slra_2").name == "slot_4"


def test_default_workcell_figures(cell: Workcell) -> None:
    assert cell.arm.payload_kg == 45.0
    assert cell.arm.repeatability_m == pytest.approx(0.00025)
    assert all(t.weight_kg <= cell.arm.payload_kg for t in cell.tools)
    assert cell.tool("us_probe_1").weight_kg == pytest.approx(1.5)
    assert cell.tool("slra_1").weight_kg == pytest.approx(6.0)
    slra = cell.tool("slra_1")
    assert 0.3 <= slra.standoff_min < slra.standoff_nominal < slra.standoff_max <= 0.6
    assert len(cell.arm.joints.acceleration) == 6 and min(cell.arm.joints.acceleration) > 0
    k = cell.arm.kinematics
    # T3-776-like: upper arm 1.12 m, forearm 1.40 m
    assert (k.a2, k.d4) == pytest.approx((1.12, 1.40))


def test_joint_limits_match_the_urdf_in_pybullet(cell: Workcell, arm_sim) -> None:
    pb, client, body = arm_sim
    revolute = [i for i in range(pb.getNumJoints(body, physicsClientId=client))
                if pb.getJointInfo(body, i, physicsClientId=client)[2] == pb.JOINT_REVOLUTE]
    assert len(revolute) == 6
    limits = cell.arm.joints
    for k, i in enumerate(revolute):
        info = pb.getJointInfo(body, i, physicsClientId=client)
        assert info[1].decode() == limits.names[k] == f"j{k + 1}"
        assert info[8] == pytest.approx(limits.lower[k])
        assert info[9] == pytest.approx(limits.upper[k])
        assert info[11] == pytest.approx(limits.velocity[k])
        assert limits.lower[k] < 0.0 < limits.upper[k]


def _flange_pose(pb, client, body, q) -> tuple[np.ndarray, np.ndarray]:
    for i, v in enumerate(q):
        pb.resetJointState(body, i, float(v), physicsClientId=client)
    state = pb.getLinkState(body, 6, computeForwardKinematics=True, physicsClientId=client)
    return np.array(state[4]), np.array(pb.getMatrixFromQuaternion(state[5])).reshape(3, 3)


def test_kinematic_parameters_agree_with_the_urdf(cell: Workcell, arm_sim) -> None:
    pb, client, body = arm_sim
    k = cell.arm.kinematics
    position, rotation = _flange_pose(pb, client, body, np.zeros(6))
    expected = np.asarray(cell.arm.base.position) + [k.a1 + k.d4 + k.d6, 0.0, k.d1 + k.a2]
    assert position == pytest.approx(expected, abs=1e-6)
    assert rotation[:, 2] == pytest.approx([1.0, 0.0, 0.0], abs=1e-6)  # flange z along the forearm
    # spherical wrist: turning j4, j5, j6 does not move the wrist centre
    rng = np.random.default_rng(7)
    centres = []
    for _ in range(5):
        q = np.concatenate([[0.3, 0.2, -0.4], rng.uniform(-1.5, 1.5, 3)])
        position, rotation = _flange_pose(pb, client, body, q)
        centres.append(position - rotation[:, 2] * k.d6)
    assert np.ptp(np.array(centres), axis=0) == pytest.approx(np.zeros(3), abs=1e-6)


# --- frames -------------------------------------------------------------------------------

def test_part_to_world_round_trip_and_orientation(cell: Workcell) -> None:
    rng = np.random.default_rng(3)
    points = rng.uniform([-1250, -750, 0], [1250, 750, 60], size=(50, 3))
    world = cell.part.to_world(points)
    assert cell.part.to_part(world) == pytest.approx(points, abs=1e-9)
    # the inspected side (+Z) faces the robot (at the origin): the normal points to -x
    assert cell.part.normals_to_world(np.array([[0.0, 0.0, 1.0]]))[0] == pytest.approx([-1.0, 0.0, 0.0])
    # mm to m: the part's 2500 mm width is 2.5 m in the world
    span = cell.part.to_world(np.array([[-1250.0, 0.0, 0.0], [1250.0, 0.0, 0.0]]))
    assert np.linalg.norm(span[1] - span[0]) == pytest.approx(2.5)


def test_rotation_conversions_round_trip() -> None:
    rng = np.random.default_rng(5)
    for rpy in rng.uniform(-math.pi, math.pi, size=(20, 3)):
        m = frames.rpy_to_matrix(rpy)
        assert m @ m.T == pytest.approx(np.eye(3), abs=1e-12)
        assert frames.quaternion_to_matrix(frames.matrix_to_quaternion(m)) == pytest.approx(m, abs=1e-9)


# --- the reach test -----------------------------------------------------------------------

def _reach_world(cell: Workcell, points_m, normals_world, tool: str):
    """Reach report for world points (n, 3) and world normals (n, 3)."""
    points_mm = cell.part.to_part(np.asarray(points_m, dtype=float))
    normals = np.asarray(normals_world, dtype=float) @ cell.part.rotation_matrix()
    return reach_report(cell, points_mm, normals, [tool] * len(points_mm))


def test_a_point_at_the_arm_base_is_too_close(cell: Workcell) -> None:
    report = _reach_world(cell, [cell.arm.base.position], [[0.0, 0.0, 1.0]], "slra_tool")
    assert report.verdicts == (Reach.TOO_CLOSE,)
    assert report.n_unreachable == 1 and math.isnan(report.standoffs[0])


def test_a_point_5m_away_is_too_far(cell: Workcell) -> None:
    base = np.asarray(cell.arm.base.position)
    for tool in ("us_tool", "slra_tool"):
        report = _reach_world(cell, [base + [5.0, 0.0, 0.5]], [[-1.0, 0.0, 0.0]], tool)
        assert report.verdicts == (Reach.TOO_FAR,)
    assert "too_far" in report.summary()


def test_a_point_behind_the_base_is_outside_j1(cell: Workcell) -> None:
    # behind the base, facing away from it: j1 would be 180 deg (limits +/-135 deg)
    base = np.asarray(cell.arm.base.position)
    report = _reach_world(cell, [base + [-1.0, 0.0, 0.6]], [[-1.0, 0.0, 0.0]], "us_tool")
    assert report.verdicts == (Reach.OUTSIDE_J1,)


def test_a_surface_facing_away_needs_too_much_wrist_bend(cell: Workcell) -> None:
    # in front of the arm and in range, but the normal points away from the arm: the tool
    # would have to point back at the robot
    base = np.asarray(cell.arm.base.position)
    report = _reach_world(cell, [base + [1.2, 0.0, 0.9]], [[1.0, 0.0, 0.0]], "slra_tool")
    assert report.verdicts == (Reach.WRIST_BEND,)


def test_the_web_of_the_default_layout_is_reachable(cell: Workcell) -> None:
    xs, ys = np.meshgrid(np.linspace(-1250, 1250, 26), np.linspace(-750, 750, 16))
    points = np.column_stack([xs.ravel(), ys.ravel(), np.full(xs.size, 2.5)])
    normals = np.tile([0.0, 0.0, 1.0], (len(points), 1))
    for tool in ("us_tool", "slra_tool"):
        report = reach_report(cell, points, normals, [tool] * len(points))
        assert report.n_reachable >= 0.99 * len(points), report.summary()
    slra = cell.tool("slra_1")
    passed = np.array(report.standoffs)[report.reachable]
    assert np.all((passed >= slra.standoff_min) & (passed <= slra.standoff_max))


def test_the_outer_flange_walls_are_reachable_with_the_bent_probe(cell: Workcell) -> None:
    ys = np.linspace(-700, 700, 15)
    points = np.concatenate([np.column_stack([np.full(15, x), ys, np.full(15, 25.0)]) for x in (-1250, 1250)])
    normals = np.concatenate([np.tile([s, 0.0, 0.0], (15, 1)) for s in (-1.0, 1.0)])
    report = reach_report(cell, points, normals, ["us_tool"] * len(points))
    assert report.n_reachable == len(points), report.summary()


def test_arm_poses_from_forward_kinematics_pass(cell: Workcell, arm_sim) -> None:
    """The test is a necessary condition: a pose the arm reaches never fails an arm check."""
    pb, client, body = arm_sim
    slra = cell.tool("slra_1")
    # only the arm's own checks: one standoff, no margin, no working-height or base limits
    one_standoff = dataclasses.replace(slra, standoff_min=slra.standoff_nominal, standoff_max=slra.standoff_nominal)
    relaxed = dataclasses.replace(
        cell,
        tools=(one_standoff,),
        reach=dataclasses.replace(cell.reach, margin=1.0, base_keepout_radius=0.0, wrist_min_height=-9.0,
                                  wrist_max_height=9.0, tcp_min_height=-9.0),
    )
    rng = np.random.default_rng(11)
    limits = cell.arm.joints
    points, normals = [], []
    for _ in range(300):
        position, rotation = _flange_pose(pb, client, body, rng.uniform(limits.lower, limits.upper))
        points.append(position + rotation[:, 2] * (slra.tcp_length + slra.standoff_nominal))
        normals.append(-rotation[:, 2])
    report = _reach_world(relaxed, points, normals, "slra_tool")
    assert set(report.verdicts) <= {Reach.REACHABLE, Reach.INSIDE_PART}, report.summary()
    assert report.n_reachable > 250


def test_reach_report_counts_and_validates_lengths(cell: Workcell) -> None:
    points = np.array([[0.0, 0.0, 2.5], [0.0, 0.0, 2.5]])
    normals = np.array([[0.0, 0.0, 1.0], [0.0, 0.0, 1.0]])
    report = reach_report(cell, points, normals, ["us_tool", "slra_tool"])
    assert report.counts() == {Reach.REACHABLE: 2}
    assert report.standoffs[0] == 0.0 and report.standoffs[1] == pytest.approx(cell.tool("slra_1").standoff_nominal)
    with pytest.raises(ValueError):
        reach_report(cell, points, normals, ["us_tool"])


def test_the_real_specs_are_reachable(cell: Workcell) -> None:
    """The built-in bulkhead's specs (thicknesses with the probe, the rest with the SLRA)."""
    store = pytest.importorskip("ita.part.store")
    io = pytest.importorskip("ita.specs.io")
    specs = io.read_specs(store.load_part(None).specs_path)
    tools = ["us_tool" if s.kind.value.endswith("thickness") else "slra_tool" for s in specs]
    report = reach_report(cell, np.array([s.point for s in specs]), np.array([s.normal for s in specs]), tools)
    assert report.n_reachable >= 0.99 * len(specs), report.summary()


# --- bad input ----------------------------------------------------------------------------

def _write_variant(tmp_path: Path, old: str, new: str) -> Path:
    text = default_workcell_path().read_text(encoding="utf-8")
    urdf = default_workcell_path().parent / "t3_arm.urdf"
    text = text.replace('urdf = "t3_arm.urdf"', f'urdf = "{urdf.as_posix()}"')
    assert old in text, old
    path = tmp_path / "workcell.toml"
    path.write_text(text.replace(old, new, 1), encoding="utf-8")
    return path


@pytest.mark.parametrize(
    ("old", "new", "field"),
    [
        ("weight_kg = 1.5", "weight_kg = -1.5", "tool[us_probe_1].weight_kg"),
        ("weight_kg = 6.0", "weight_kg = 60.0", "tool[slra_1].weight_kg"),
        ("acceleration = [1.2, 1.0, 1.2, 3.0, 3.0, 4.0]", "acceleration = [1.2, 1.0]", "robot.acceleration"),
        ("x_axis = [0.0, -1.0, 0.0]", "x_axis = [0.0, -2.0, 0.0]", "part.x_axis"),
        ('tool = "slra_2"', 'tool = "slra_9"', "rack.slot[slot_4].tool"),
        ("standoff = [0.30, 0.45, 0.60]", "standoff = [0.60, 0.45, 0.30]", "tool[slra_1].standoff"),
        ("margin = 0.97", "margin = 1.5", "reach.margin"),
        ("repeatability_mm = 0.25", 'repeatability_mm = "tight"', "robot.repeatability_mm"),
        ('name = "t3_b"', 'name = "t3"', "robot_b.name"),
        ("base_position = [1.4, 2.35, 0.6]\n", "", "robot_b.base_position"),
        ("size = [0.8, 0.8, 0.6]", "size = [0.8, -0.8, 0.6]", "robot_b.pedestal.size"),
        ("center = [2.25, 2.1, 0.925]", "center = [2.25, 2.1]", "robot_b.cal_block.center"),
        ('name = "t3_b"\n', 'name = "t3_b"\ntool_classes = ["laser"]\n', "robot_b.tool_classes"),
        ("[robot_b.cal_block]\ncenter = [2.25, 2.1, 0.925]\nsize = [0.15, 0.1, 0.05]\n", "", "robot_b.cal_block"),
    ],
)
def test_bad_values_name_the_field(tmp_path: Path, old: str, new: str, field: str) -> None:
    path = _write_variant(tmp_path, old, new)
    with pytest.raises(InputError) as info:
        load_workcell(path)
    fields = [loc.field for loc, _ in info.value.problems]
    assert field in fields
    assert all(loc.file == str(path) for loc, _ in info.value.problems)
    assert field in str(info.value)


def test_toml_syntax_error_gives_the_line(tmp_path: Path) -> None:
    path = _write_variant(tmp_path, "payload_kg = 45.0", "payload_kg = = 45.0")
    with pytest.raises(InputError) as info:
        load_workcell(path)
    loc = info.value.problems[0][0]
    expected = next(i for i, line in enumerate(path.read_text().splitlines(), 1) if "payload_kg" in line)
    assert loc.line == expected


def test_bad_urdf_limit_names_the_joint(tmp_path: Path) -> None:
    urdf_text = (default_workcell_path().parent / "t3_arm.urdf").read_text(encoding="utf-8")
    marker = '<joint name="j3" type="revolute">'
    head, tail = urdf_text.split(marker)
    tail = tail.replace('lower="', 'lower="x', 1)
    (tmp_path / "arm.urdf").write_text(head + marker + tail, encoding="utf-8")
    text = default_workcell_path().read_text(encoding="utf-8").replace('urdf = "t3_arm.urdf"', 'urdf = "arm.urdf"')
    path = tmp_path / "workcell.toml"
    path.write_text(text, encoding="utf-8")
    with pytest.raises(InputError) as info:
        load_workcell(path)
    assert [(Path(loc.file).name, loc.field) for loc, _ in info.value.problems] == [("arm.urdf", "joint j3.limit.lower")]


def test_missing_file_is_an_input_error(tmp_path: Path) -> None:
    with pytest.raises(InputError):
        load_workcell(tmp_path / "nope.toml")


def test_a_part_s_envelope_comes_from_its_mesh_unless_its_cell_states_one(tmp_path: Path) -> None:
    from ita.workcell import workcell_for

    bounds = np.array([[-200.0, -150.0, 0.0], [200.0, 150.0, 30.0]])
    user = tmp_path / "user"
    user.mkdir()
    # a user part in the built-in cell: never the bulkhead's envelope
    cell = workcell_for(user, bounds)
    assert cell.part.envelope_min_mm == (-200.0, -150.0, 0.0) and cell.part.envelope_max_mm == (200.0, 150.0, 30.0)
    # its own cell without an envelope: the mesh's; with one: as stated
    text = _write_variant(tmp_path, "envelope_max_mm = [1250.0, 750.0, 60.0]", "").read_text()
    (user / "workcell.toml").write_text(text.replace("envelope_min_mm = [-1250.0, -750.0, 0.0]", ""))
    assert workcell_for(user, bounds).part.envelope_max_mm == (200.0, 150.0, 30.0)
    with pytest.raises(InputError, match="no envelope"):
        workcell_for(user)
    (user / "workcell.toml").write_text(_write_variant(tmp_path, "scale = 0.001", "scale = 0.001").read_text())
    assert workcell_for(user, bounds).part.envelope_max_mm == (1250.0, 750.0, 60.0)
    assert workcell_for(None, bounds).part.envelope_max_mm == (1250.0, 750.0, 60.0)   # the built-in part


def test_the_second_arm_is_the_first_seen_from_its_own_base(cell: Workcell) -> None:
    assert [a.name for a in cell.arms()] == ["t3", "t3_b"]
    b = cell.seen_by("t3_b")
    assert b.arm.base.position == (1.4, 2.35, 0.6) and b.pedestal.name == "pedestal_t3_b"
    assert b.second_arm == cell.arm and b.seen_by("t3") == cell.seen_by("t3")
    assert b.arm.joints == cell.arm.joints and b.arm.kinematics == cell.arm.kinematics
    assert cell.second_pedestal not in cell.static_boxes()           # one-arm runs leave it out
    with pytest.raises(KeyError):
        cell.seen_by("t4")


def test_the_second_arm_works_at_its_own_stations(cell: Workcell) -> None:
    """Its couplant station and calibration block are its own (within its reach) in its
    view; like its pedestal, they are outside the first arm's world, and the first arm's
    are outside its own."""
    b = cell.seen_by("t3_b")
    assert cell.second_stations is not None
    assert b.cal_block == cell.second_stations.cal_block and b.couplant_station == cell.second_stations.couplant_station
    assert b.cal_block.pose.position != cell.cal_block.pose.position
    assert b.second_stations is not None and b.second_stations.cal_block == cell.cal_block
    positions = lambda boxes: {x.pose.position for x in boxes}  # noqa: E731
    assert not positions(cell.second_stations.stands + (b.cal_block, b.couplant_station)) & positions(cell.static_boxes())
    assert not positions(cell.stands + (cell.cal_block,)) & positions(b.static_boxes())
    for view in (cell, b):                       # each arm reaches its own stations
        reach = np.linalg.norm(np.subtract(view.cal_block.pose.position[:2], view.arm.base.position[:2]))
        assert reach < 2.0
