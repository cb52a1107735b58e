"""The simulated workcell: what it holds, frames, tools, contacts, state save/restore."""

from __future__ import annotations

import numpy as np
import pybullet as p
import pytest

from ita.kinematics import choose_nearest, ik_tool, measurement_poses
from ita.part import truth as truth_mod
from ita.sim.world import PART, SimClock, SimWorld, tool_shapes

READY = np.array([0.0, 0.057, 0.614, 0.0, 0.114, 1.571])   # probe facing the part's middle


@pytest.fixture(scope="module")
def world(builtin_part):
    with SimWorld(part_dir=builtin_part.directory, seed=3, q0=READY) as w:
        yield w


@pytest.fixture()
def fresh(world):
    """The module's world, put back as it was after each test."""
    with world.saved_state():
        yield world


def test_world_holds_arm_part_rack_tools_and_stations(world):
    assert p.getConnectionInfo(world.client)["connectionMethod"] == p.DIRECT
    names = set(world.bodies)
    cell = world.cell
    assert {PART, "rack", "couplant_station", "cal_block"} <= names
    assert {b.name for b in cell.static_boxes()} <= names
    assert {t.name for t in cell.tools} == set(world.tools)
    assert p.getNumJoints(world.arm, physicsClientId=world.client) == 7   # six joints and the flange


def test_part_body_is_the_as_built_mesh_where_the_placement_puts_it(world, builtin_part):
    mesh = truth_mod.load_truth(builtin_part.directory).mesh
    corners = world.cell.part.to_world(np.asarray(mesh.bounds))
    lo, hi = np.array(p.getAABB(world.bodies[PART], physicsClientId=world.client))
    np.testing.assert_allclose(lo, corners.min(axis=0), atol=2e-3)
    np.testing.assert_allclose(hi, corners.max(axis=0), atol=2e-3)
    assert world.asbuilt_mesh.volume == pytest.approx(mesh.volume)


def test_pybullet_flange_agrees_with_the_kinematics(fresh):
    rng = np.random.default_rng(0)
    for q in rng.uniform(fresh.model.lower, fresh.model.upper, (5, 6)):
        fresh.set_q(q)
        np.testing.assert_allclose(fresh.link_pose(fresh.flange_link), fresh.flange_pose(), atol=1e-5)


def test_tools_start_parked_in_their_slots(world):
    for tool in world.cell.tools:
        np.testing.assert_allclose(world.tool_pose(tool.name), world.cell.slot_of(tool.name).pose.matrix(),
                                   atol=1e-6)


def test_held_tool_follows_the_flange_and_returns_to_its_slot(fresh):
    fresh.attach("slra_1")
    q = READY + np.array([0.2, -0.1, 0.1, 0.3, 0.2, -0.4])
    fresh.set_q(q)
    np.testing.assert_allclose(fresh.tool_pose("slra_1"), fresh.flange_pose(), atol=1e-6)
    tcp = fresh.cell.tool("slra_1").tcp.matrix()
    np.testing.assert_allclose(fresh.tcp_pose(), fresh.flange_pose() @ tcp, atol=1e-12)
    with pytest.raises(RuntimeError, match="already holding"):
        fresh.attach("us_probe_1")
    assert fresh.detach() == "slra_1"
    np.testing.assert_allclose(fresh.tool_pose("slra_1"), fresh.cell.slot_of("slra_1").pose.matrix(), atol=1e-6)


def test_saved_state_restores_joints_tool_and_couplant(world):
    before = world.state()
    with world.saved_state():
        world.attach("us_probe_2")
        world.set_q(READY + 0.1)
        world.drift_m = np.array([1e-3, 0.0, 0.0])
        from ita.sim.world import CouplantSpot
        world.add_couplant(CouplantSpot((0.0, 0.0, 2.5), 5.0, 0.0))
    assert world.state() == before
    assert world.held is None
    np.testing.assert_allclose(world.tool_pose("us_probe_2"), world.cell.slot_of("us_probe_2").pose.matrix(),
                               atol=1e-6)


def test_clock_only_runs_forward():
    clock = SimClock()
    assert clock.advance(1.5) == 1.5
    with pytest.raises(ValueError):
        clock.advance(-0.1)


def _probe_on_web(world, press_m):
    """Joints that put us_probe_1's tip on the middle web spec point, pressed press_m."""
    tool = world.cell.tool("us_probe_1")
    poses = measurement_poses(world.cell.part, np.array([[-935.0, 705.0, 2.5]]), np.array([[0.0, 0.0, 1.0]]),
                              tool, standoff=-press_m)
    q, found = choose_nearest(world.model, ik_tool(world.model, poses, tool.tcp.matrix()).flatten_batch(), READY)
    assert found[0]
    return q[0]


def test_probe_tip_may_touch_but_its_shaft_bumps(fresh):
    fresh.attach("us_probe_1")
    fresh.set_q(_probe_on_web(fresh, 0.0015))
    assert fresh.contacts() == []
    fresh.set_q(_probe_on_web(fresh, 0.015))
    hits = fresh.contacts()
    assert hits and {c.obstacle for c in hits} == {PART} and {c.moving for c in hits} == {"us_probe_1"}
    assert fresh.contacts(ignore=[PART]) == []


def test_contact_probe_shapes_stop_short_of_the_tip(world):
    tool = world.cell.tool("us_probe_1")
    tip = np.asarray(tool.tcp.position)
    kind, centre, axis, radius, length = tool_shapes(tool)[-1]
    assert kind == "capsule"
    reach = centre + axis * (length / 2 + radius)
    assert np.linalg.norm(tip - reach) == pytest.approx(0.008, abs=1e-9)
    assert tool_shapes(world.cell.tool("slra_1"))[0][0] == "box"


def test_close_disconnects(builtin_part):
    world = SimWorld(part_dir=builtin_part.directory)
    with world:
        client = world.client
        assert p.isConnected(client)
    assert not p.isConnected(client)
    world.close()  # idempotent


def test_a_link_s_reach_covers_every_point_of_its_collision_shapes(fresh):
    """SimWorld.link_reach (what the controller's swept bound turns each link by) is no
    less than the distance from the link's origin to any surface point of its shapes:
    rays shot at each link's origin from 400 directions, at three poses, find its surface."""
    from ita.kinematics import link_frames

    world = fresh
    index = {name: k for k, name in enumerate(world.model.link_names)}
    rng = np.random.default_rng(2)
    u = rng.normal(size=(400, 3))
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    found = np.zeros(len(index))
    for q in (np.zeros(6), np.array([0.4, -0.3, 0.5, 1.0, -0.8, 0.6]), np.array([-1.0, 0.6, -0.4, -1.2, 1.1, 2.0])):
        world.set_q(q)
        frames = link_frames(world.model, q)[0]
        for j in world._arm_links:
            k = index[world.link_names[j]]
            origin = frames[k, :3, 3]
            hits = p.rayTestBatch((origin + 3.0 * u).tolist(), np.tile(origin, (len(u), 1)).tolist(),
                                  physicsClientId=world.client)
            on_link = [h[3] for h in hits if h[0] == world.arm and h[1] == j]
            if on_link:
                found[k] = max(found[k], float(np.linalg.norm(np.array(on_link) - origin, axis=1).max()))
    assert found[1:7].min() > 0.05                             # every moving link was hit
    assert np.all(world.link_reach >= found - 1e-6)
