"""The Path Planner: reasons for failure, free paths, subgoals around obstacles, the
trajectory's limits, smoothing that keeps paths free, problem sets, the CLI."""

from __future__ import annotations

import dataclasses
import json
from itertools import pairwise

import numpy as np
import pytest
from click.testing import CliRunner

from ita.cli import main
from ita.collision import ArmChecker, Regions, RegionTree
from ita.collision.kernels import _seg_seg_d2
from ita.errors import InputError
from ita.kinematics import arm_model, link_segments, move_time, tcp_poses
from ita.path.lift import Effort, Lifter, path_free, segments_free
from ita.path.motion import ConfigChecker, MotionChecker, sweep_bounds
from ita.path.planner import (
    HOME,
    PathFailure,
    PathPlanner,
    PlannerSettings,
    planners_for,
)
from ita.path.problems import (
    Problem,
    generate_problems,
    measurement_targets,
    read_problems,
    run_problems,
    summarize,
    write_problems,
)
from ita.path.smooth import (
    estimate_durations,
    limit_violations,
    lspb,
    reshape_path,
    shortcut,
    subdivide,
    time_parameterize,
    trajectory_free,
)
from ita.path.visibility import build_graph
from ita.specs.io import read_specs
from ita.workcell import load_workcell

TOL = 1e-6


@pytest.fixture(scope="module")
def cell():
    return load_workcell()


@pytest.fixture(scope="module")
def planner_for(cell, builtin_part):
    return planners_for(cell, builtin_part)


@pytest.fixture(scope="module")
def specs(builtin_part):
    return read_specs(builtin_part.specs_path)


@pytest.fixture(scope="module")
def wall_scene(cell):
    """The bare arm on its pedestal with a floor and one beam hanging in front of it, which
    the forearm's direct sweep between two stretched poses runs into."""
    model = arm_model(cell.arm)
    tree = RegionTree()
    tree.add("floor", Regions.boxes([[0.0, 0.0, -0.05]], np.eye(3), [[8.0, 8.0, 0.1]]))
    tree.add("pedestal", Regions.boxes([[0.0, 0.0, 0.3]], np.eye(3), [[0.9, 0.9, 0.6]]))
    tree.add("beam", Regions.boxes([[1.5, 0.0, 2.45]], np.eye(3), [[0.3, 0.4, 0.6]]))
    checker = ArmChecker(tree, model.tube_radii, model.tube_links, mount=["pedestal"])
    planner = PathPlanner(model, tree, checker, PlannerSettings(seed=3))
    start = np.array([-0.9, 0.3, -0.2, 0.0, 0.4, 0.0])
    goal = np.array([0.9, 0.3, -0.2, 0.0, 0.4, 0.0])
    return planner, start, goal


def _colliding(planner, tool, rng):
    q = rng.uniform(planner.model.lower, planner.model.upper, (400, 6))
    return q[~planner.config_free(q, tool)][0]


# ---- reasons for failure ---------------------------------------------------------------
def test_start_outside_the_limits_is_refused(planner_for):
    planner, tool = planner_for("us_probe_1")
    start = np.array(HOME)
    start[0] = 3.0
    r = planner.plan(start, np.array(HOME), tool)
    assert not r.ok and r.reason is PathFailure.START_OUT_OF_LIMITS and r.trajectory is None


def test_start_in_collision_names_what_it_hits(planner_for):
    planner, tool = planner_for("us_probe_1")
    start = _colliding(planner, tool, np.random.default_rng(0))
    r = planner.plan(start, np.array(HOME), tool)
    assert not r.ok and r.reason is PathFailure.START_IN_COLLISION
    assert "hits" in r.message and len(r.waypoints) == 0


def test_a_start_settled_just_into_the_tubes_margin_moves_out_of_it_first(planner_for):
    """An arm that settled off its goal by its repeatability into the collision tubes'
    margin (not in contact) is not stuck there: the path starts at it and steps to a free
    configuration a jiggle away; a start deep in collision is still refused (above)."""
    planner, tool = planner_for("us_probe_1")
    free, hit = np.array(HOME), _colliding(planner, tool, np.random.default_rng(0))
    lo, hi = 0.0, 1.0                     # the boundary on the straight line from free to hit
    while hi - lo > 1e-7:
        mid = (lo + hi) / 2
        lo, hi = (mid, hi) if planner.config_free((free + mid * (hit - free))[None], tool)[0] else (lo, mid)
    start = free + hi * (hit - free)
    assert not planner.config_free(start[None], tool)[0]
    r = planner.plan(start, np.array(HOME), tool)
    assert r.ok, r.message
    assert np.array_equal(r.waypoints[0], start) and planner.config_free(r.waypoints[1:], tool).all()
    assert 0.0 < r.stats["jiggled"] <= 0.002
    assert np.allclose(r.trajectory.q[0], start) and np.allclose(r.trajectory.q[-1], HOME)


def test_goal_out_of_reach_is_unreachable(planner_for):
    planner, tool = planner_for("us_probe_1")
    pose = np.eye(4)
    pose[:3, 3] = [5.0, 0.0, 1.0]
    r = planner.plan(np.array(HOME), pose, tool)
    assert not r.ok and r.reason is PathFailure.GOAL_UNREACHABLE and "out_of_reach" in r.message


def test_goal_outside_the_limits_is_unreachable(planner_for):
    planner, tool = planner_for(None)
    goal = np.array(HOME)
    goal[4] = 3.0
    r = planner.plan(np.array(HOME), goal, tool)
    assert not r.ok and r.reason is PathFailure.GOAL_UNREACHABLE


def test_touching_the_part_is_a_goal_in_collision(planner_for, cell, specs):
    """The probe's tip on the surface: every solution's tool tube meets the part's regions."""
    planner, tool = planner_for("us_probe_1")
    spec = min((s for s in specs if s.kind.value == "web_thickness"), key=lambda s: abs(s.point[0]) + abs(s.point[1]))
    from ita.kinematics import measurement_poses

    on_surface = measurement_poses(cell.part, np.array([spec.point]), np.array([spec.normal]), tool)[0]
    r = planner.plan(np.array(HOME), on_surface, tool)
    assert not r.ok and r.reason is PathFailure.GOAL_IN_COLLISION and "part" in r.message


def test_effort_bound_gives_no_path_within_effort(wall_scene):
    planner, start, goal = wall_scene
    strict = PathPlanner(planner.model, planner.tree, planner.checker,
                         PlannerSettings(max_rounds=0, fallback_iterations=0))
    r = strict.plan(start, goal)
    assert not r.ok and r.reason is PathFailure.NO_PATH_WITHIN_EFFORT and "0 subgoal rounds" in r.message


def test_no_path_at_all_is_no_path_within_effort_after_the_fallback(cell):
    # a wall on the waist's zero meridian: at waist 0 the shoulder's tube always reaches
    # into it, and the waist's limits (+-135 deg) forbid going round the back, so the
    # start's side and the goal's are not connected; both levels and the fallback give up
    model = arm_model(cell.arm)
    tree = RegionTree()
    tree.add("floor", Regions.boxes([[0.0, 0.0, -0.05]], np.eye(3), [[8.0, 8.0, 0.1]]))
    tree.add("pedestal", Regions.boxes([[0.0, 0.0, 0.3]], np.eye(3), [[0.9, 0.9, 0.6]]))
    tree.add("wall", Regions.boxes([[2.66, 0.0, 2.5]], np.eye(3), [[4.68, 0.06, 5.0]]))
    checker = ArmChecker(tree, model.tube_radii, model.tube_links, mount=["pedestal"])
    planner = PathPlanner(model, tree, checker, PlannerSettings(seed=3, max_rounds=10, fallback_iterations=1500))
    start, goal = np.array([-2.2, 0.3, -0.2, 0.0, 0.4, 0.0]), np.array([2.2, 0.3, -0.2, 0.0, 0.4, 0.0])
    assert planner.config_free(np.vstack([start, goal])).all()
    waist_zero = np.random.default_rng(0).uniform(model.lower, model.upper, (200, 6))
    waist_zero[:, 0] = 0.0
    assert not planner.config_free(waist_zero).any()
    r = planner.plan(start, goal)
    assert not r.ok and r.reason is PathFailure.NO_PATH_WITHIN_EFFORT
    assert r.stats["sampled"] == 1500 and "1500 sampling iterations" in r.message


# ---- paths -----------------------------------------------------------------------------
def test_free_path_is_direct_and_ends_at_the_goal(planner_for):
    planner, tool = planner_for("us_probe_1")
    goal = np.array(HOME) + np.array([0.3, 0.1, -0.1, 0.2, 0.1, 0.5])
    r = planner.plan(np.array(HOME), goal, tool)
    assert r.ok and r.reason is None and r.stats["subgoals"] == 0
    np.testing.assert_allclose(r.trajectory.q[0], HOME)
    np.testing.assert_allclose(r.trajectory.q[-1], goal, atol=1e-9)
    assert r.duration > 0 and r.tool_path_length > 0
    # without the final reshaping the free path is the direct joint move; reshaped, it is
    # cut into pieces moved where they make the timed trajectory quicker, every one checked
    direct = PathPlanner(planner.model, planner.tree, planner.checker,
                         dataclasses.replace(planner.settings, reshape_splits=1), planner.tubes)
    d = direct.plan(np.array(HOME), goal, tool)
    assert d.ok and len(d.waypoints) == 2
    ctx = planner.context(tool)
    assert ctx.motion_free(r.waypoints[:-1], r.waypoints[1:]).all()
    assert r.duration <= d.duration


@pytest.mark.parametrize("step", [1e-4, 3e-3, 0.05])
def test_a_short_move_stays_direct_and_as_quick_as_from_rest_to_rest(planner_for, step):
    # the moves of an inspection are mostly this short: a detour is never quicker
    planner, tool = planner_for("slra_1")
    start = np.array(HOME)
    goal = start + step * np.array([1.0, -0.5, 0.5, 1.0, -1.0, 1.0])
    r = planner.plan(start, goal, tool)
    assert r.ok and len(r.waypoints) == 2
    assert r.duration == pytest.approx(lspb(planner.model, r.waypoints).duration, rel=1e-6)


def test_reshape_path_is_free_and_never_slower(planner_for):
    planner, tool = planner_for("us_probe_1")
    ctx = planner.context(tool)
    w = np.vstack([HOME, np.array(HOME) + np.array([0.6, 0.2, -0.2, 0.3, 0.2, 0.8])])
    free = ctx.motion_free
    assert free(w[:1], w[1:]).all()
    out = reshape_path(planner.model, w, free, np.random.default_rng(0), tcp=ctx.tcp)
    again = reshape_path(planner.model, w, free, np.random.default_rng(0), tcp=ctx.tcp)
    np.testing.assert_array_equal(out, again)                       # deterministic
    np.testing.assert_allclose(out[[0, -1]], w)
    assert len(out) == 3 and free(out[:-1], out[1:]).all()
    assert estimate_durations(planner.model, out, ctx.tcp)[0] < estimate_durations(planner.model, w, ctx.tcp)[0]
    assert time_parameterize(planner.model, out, tcp=ctx.tcp).duration < \
        time_parameterize(planner.model, w, tcp=ctx.tcp).duration
    np.testing.assert_allclose(subdivide(w, 3)[[0, 3]], w)
    assert len(subdivide(w, 3)) == 4


@pytest.mark.parametrize("scale", [1e-4, 1e-2, 0.3])
def test_estimated_duration_is_the_timed_one(wall_scene, scale):
    # what shortcutting, reshaping and the goal choice minimise is what the arm flies, from
    # a move too short to reach any joint's speed limit to long multi-segment ones
    model = wall_scene[0].model
    rng = np.random.default_rng(4)
    for k in (2, 3, 5):
        paths = np.cumsum(rng.normal(size=(6, k, 6)) * scale, axis=1)
        timed = [time_parameterize(model, w, tool_speed=np.inf).duration for w in paths]
        np.testing.assert_allclose(estimate_durations(model, paths, tool_speed=np.inf), timed, rtol=1e-3)


def test_path_around_an_obstacle_uses_a_subgoal(wall_scene):
    planner, start, goal = wall_scene
    ctx = planner.context(None)
    assert not segments_free(ctx.config_free, start, goal, ctx.lever, 0.02)[0]   # the beam is in the way
    r = planner.plan(start, goal)
    assert r.ok and r.stats["subgoals"] >= 1 and len(r.waypoints) >= 3
    assert path_free(ctx.config_free, r.waypoints, ctx.lever, 0.005).all()
    assert ctx.motion_free(r.waypoints[:-1], r.waypoints[1:]).all()
    assert trajectory_free(r.trajectory, lambda a, b: segments_free(ctx.config_free, a, b, ctx.lever, 0.005))


P081 = (np.array([-0.155, 1.144, -0.661, -1.042, -0.516, -2.866]),   # seed-7 bench set, problem p081
        np.array([2.122, 0.373, -0.87, -0.317, -1.488, 1.21]))


def test_a_swing_the_subgoals_miss_is_found_by_the_fallback(planner_for):
    # the arm stretched forward into a pocket by the part and the fixture's post, the goal
    # behind it: every straight joint move hits both, and no subgoal about the joint
    # midpoint is reachable from the start; RRT-Connect finds the withdraw-then-swing
    planner, tool = planner_for("us_probe_1")
    start, goal = P081
    two_level = PathPlanner(planner.model, planner.tree, planner.checker,
                            dataclasses.replace(planner.settings, fallback_iterations=0), planner.tubes)
    alone = two_level.plan(start, goal, tool)
    assert not alone.ok and alone.reason is PathFailure.NO_PATH_WITHIN_EFFORT
    r = planner.plan(start, goal, tool)
    assert r.ok and r.stats["sampled"] > 0
    np.testing.assert_allclose(r.waypoints[[0, -1]], [start, goal], atol=1e-12)
    ctx = planner.context(tool)
    assert ctx.motion_free(r.waypoints[:-1], r.waypoints[1:]).all()
    assert trajectory_free(r.trajectory,
                           lambda a, b: segments_free(ctx.config_free, a, b, ctx.motion_free.bounds, 0.001))
    assert limit_violations(planner.model, r.trajectory, ctx.tcp)["tool_speed"] <= 1.0 + 1e-6


def test_the_fallback_is_deterministic_for_a_seed(wall_scene):
    planner, start, goal = wall_scene
    # no subgoal rounds: the sampling fallback alone finds the way round the beam
    runs = [PathPlanner(planner.model, planner.tree, planner.checker,
                        PlannerSettings(seed=seed, max_rounds=0)).plan(start, goal) for seed in (5, 5, 6)]
    assert all(r.ok and r.stats["sampled"] > 0 for r in runs)
    np.testing.assert_array_equal(runs[0].waypoints, runs[1].waypoints)
    ctx = planner.context(None)
    for r in runs:
        assert ctx.motion_free(r.waypoints[:-1], r.waypoints[1:]).all()


def test_pose_goal_takes_the_quickest_free_solution(planner_for, cell, specs):
    planner, tool = planner_for("slra_1")
    goal = measurement_targets(cell, specs[10].point, specs[10].normal, tool)
    q, reason, _ = planner.goal_configs(np.array(HOME), goal, tool)
    assert reason is None and len(q) > 1
    r = planner.plan(np.array(HOME), goal, tool)
    assert r.ok
    reached = tcp_poses(planner.model, r.waypoints[-1], tool.tcp.matrix())[0]
    assert min(np.abs(reached - g).max() for g in goal) < 1e-6


def test_compiled_checker_agrees_with_the_arm_checker(planner_for):
    planner, tool = planner_for("us_probe_1")
    ctx = planner.context(tool)
    q = np.random.default_rng(1).uniform(ctx.model.lower - 0.2, ctx.model.upper + 0.2, (3000, 6))
    expected = ctx.model.within_limits(q) & ~ctx.checker.collides(link_segments(ctx.model, q))
    assert 0.1 < expected.mean() < 0.9
    np.testing.assert_array_equal(ConfigChecker(ctx.model, ctx.checker)(q), expected)


def test_sweep_bounds_bound_every_tube_points_travel(planner_for):
    planner, tool = planner_for("us_probe_1")
    model = planner.context(tool).model
    bounds = sweep_bounds(model)
    rng = np.random.default_rng(2)
    q = rng.uniform(model.lower, model.upper, (500, 6))
    dq = rng.normal(size=(500, 6)) * 0.01
    s = np.linspace(0.0, 1.0, 5)[:, None]
    ends = link_segments(model, (q[:, None] + s[None] * dq[:, None]).reshape(-1, 6)).reshape(500, 5, -1, 2, 3)
    travel = np.linalg.norm(np.diff(ends, axis=1), axis=-1).sum(axis=1).max(axis=-1)    # (500, t) path length
    allowed = np.abs(dq) @ bounds
    assert (travel <= allowed * (1 + 1e-9) + 1e-12).all()
    assert (travel > 0.5 * allowed).any()          # and not loose by far everywhere


def test_motion_check_refuses_what_sparse_samples_miss(cell):
    """A 1 cm cube put where the wrist's tip passes between two positions of a 0.5 m
    sampled check: the samples miss it, the motion check does not."""
    model = arm_model(cell.arm)
    a = np.array(HOME)
    b = a + [1.0, 0.0, 0.0, 0.0, 0.0, 0.0]
    tree = RegionTree()
    tree.add("pedestal", Regions.boxes([[0.0, 0.0, 0.3]], np.eye(3), [[0.9, 0.9, 0.6]]))
    planner = PathPlanner(model, tree, ArmChecker(tree, model.tube_radii, model.tube_links, mount=["pedestal"]))
    ctx = planner.context(None)
    bounds = ctx.motion_free.bounds
    assert ctx.motion_free(a, b)[0]
    steps = 8 * int(np.ceil((np.abs(b - a) @ bounds).max() / (8 * 0.5)))      # the sampled check's positions
    tip = link_segments(model, a + ((steps // 2 + 0.5) / steps) * (b - a))[0, -1]   # the last tube, mid-way
    axis = (tip[1] - tip[0]) / np.linalg.norm(tip[1] - tip[0])
    tree.add("cube", Regions.boxes([tip[1] + axis * (model.tube_radii[-1] + 0.003)], np.eye(3), [[0.01] * 3]))
    planner.invalidate()
    ctx = planner.context(None)
    assert ctx.config_free(np.vstack([a, b])).all()
    assert segments_free(ctx.config_free, a, b, bounds, 0.5)[0]                 # the samples miss the cube
    assert not segments_free(ctx.config_free, a, b, bounds, 0.001)[0]           # it is in the way
    assert not ctx.motion_free(a, b)[0]


@pytest.mark.parametrize("held", [None, "us_probe_1", "slra_1"])
def test_motions_the_check_accepts_are_free_everywhere(planner_for, held):
    """Random motions, short and long, many near obstacles: every one the check accepts is
    free at positions 0.5 mm of any tube's travel apart; and it does refuse some."""
    planner, tool = planner_for(held)
    ctx = planner.context(tool)
    rng = np.random.default_rng(5)
    q = rng.uniform(ctx.model.lower, ctx.model.upper, (2000, 6))
    a = q[ctx.config_free(q)][:200]
    b = a + rng.normal(size=a.shape) * rng.choice([0.05, 0.3, 1.0], size=(len(a), 1))
    accepted = ctx.motion_free(a, b)
    assert 30 < accepted.sum() < len(a)
    assert segments_free(ctx.config_free, a[accepted], b[accepted], ctx.motion_free.bounds, 0.0005).all()


def test_segment_speeds_bound_the_tubes_motion(planner_for):
    """The per-segment speeds (lever arms from the segment's own ends) bound every tube
    end's travel and every self-collision pair's change of distance."""
    planner, tool = planner_for("us_probe_1")
    ctx = planner.context(tool)
    model, mc = ctx.model, ctx.motion_free
    pairs = ctx.checker.pairs
    rng = np.random.default_rng(7)
    s = np.linspace(0.0, 1.0, 201)[:, None]
    tight = 0
    for _ in range(60):
        a = rng.uniform(model.lower, model.upper)
        b = a + rng.normal(size=6) * 0.5
        speed, pair_speed = mc.speeds(a, b)
        ends = link_segments(model, a + s * (b - a))                               # (201, t, 2, 3)
        travel = np.linalg.norm(np.diff(ends, axis=0), axis=-1).max(axis=-1) * 200   # (200, t) per unit s
        assert (travel <= speed * (1 + 1e-9) + 1e-12).all()
        gap = np.array([[np.sqrt(_seg_seg_d2(e[i, 0], e[i, 1], e[j, 0], e[j, 1])) for i, j in pairs] for e in ends])
        assert (np.abs(np.diff(gap, axis=0)) * 200 <= pair_speed * (1 + 1e-9) + 1e-9).all()
        tight += (speed <= np.abs(b - a) @ mc.bounds * (1 + 1e-12)).all() and (speed < np.abs(b - a) @ mc.bounds).any()
    assert tight > 30                        # tighter than the configuration-free bound


def test_a_start_micrometres_from_contact_moves_away(cell):
    """A slab 5 micrometres under the arm's lowest point: the motion lifting the arm is
    accepted (its steps grow with the clearance), the one lowering it is not, and the
    plain 0.5 mm re-check agrees that the accepted one is free."""
    model = arm_model(cell.arm)
    a = np.array([0.0, 0.5, 0.4, 0.0, 0.6, 0.0])
    ends = link_segments(model, a)[0]
    low = np.where(model.tube_links >= 3, ends[..., 2].min(axis=1) - model.tube_radii, np.inf)
    k = int(np.argmin(low))                               # the wrist's lowest tube, in front of the arm
    under = ends[k][np.argmin(ends[k, :, 2])]
    top = float(low[k]) - 5e-6
    tree = RegionTree()
    tree.add("pedestal", Regions.boxes([[0.0, 0.0, 0.3]], np.eye(3), [[0.9, 0.9, 0.6]]))
    tree.add("slab", Regions.boxes([[under[0], under[1], top - 0.05]], np.eye(3), [[0.4, 0.4, 0.1]]))
    planner = PathPlanner(model, tree, ArmChecker(tree, model.tube_radii, model.tube_links, mount=["pedestal"]))
    ctx = planner.context(None)
    assert ctx.config_free(a)[0] and not ctx.motion_free.clear(a)[0]     # free, within the floor of contact
    up, down = a + [0.0, -0.4, 0.0, 0.0, 0.0, 0.0], a + [0.0, 0.1, 0.0, 0.0, 0.0, 0.0]
    assert ctx.motion_free(a, up)[0] and ctx.motion_free(up, a)[0]        # leaving it, and arriving at it
    assert not ctx.motion_free(a, down)[0]
    assert segments_free(ctx.config_free, a, up, ctx.motion_free.bounds, 0.0005)[0]
    r = planner.plan(a, up)
    assert r.ok and trajectory_free(r.trajectory, lambda p, q: segments_free(ctx.config_free, p, q,
                                                                            ctx.motion_free.bounds, 0.0005))


def test_motion_checker_settings_are_checked(planner_for):
    planner, tool = planner_for(None)
    with pytest.raises(ValueError, match="floor"):
        MotionChecker(planner.context(tool).config_free, floor=0.0)


def test_many_segments_checked_in_halves_on_two_cores_get_what_one_check_gets(planner_for):
    """A check of many segments goes half to a second thread (SPLIT_SEGMENTS): each
    segment's verdict and clearance evaluations must be what one check gives it."""
    planner, tool = planner_for(None)
    rng = np.random.default_rng(8)
    q0 = rng.uniform(planner.model.lower, planner.model.upper, (60, 6))
    q1 = q0 + rng.normal(0.0, 0.4, q0.shape)
    verdicts = []
    for split in (True, False):
        checker = MotionChecker(planner.context(tool).config_free)
        assert checker.core.active, "this test needs two cores"
        if not split:
            checker.core._thread = None
        verdicts.append((checker(q0, q1), checker.evaluations))
    (ok_split, evals_split), (ok_whole, evals_whole) = verdicts
    assert 0 < ok_whole.sum() < len(ok_whole)                 # some free, some not: a real check
    assert np.array_equal(ok_split, ok_whole) and evals_split == evals_whole


def test_visibility_route_goes_around_a_box():
    tree = RegionTree()
    tree.add("box", Regions.boxes([[0.0, 0.0, 0.0]], np.eye(3), [[0.4, 0.4, 0.4]]))
    graph = build_graph(tree, radius=0.05, clearance=0.02)
    a, b = np.array([-0.6, 0.0, 0.0]), np.array([0.6, 0.05, 0.0])
    route = graph.route(a, b)
    assert route is not None and len(route) >= 3
    np.testing.assert_allclose(route[[0, -1]], [a, b])
    assert not tree.tubes_hit(route[:-1], route[1:], 0.05).any()
    assert np.linalg.norm(np.diff(route, axis=0), axis=1).sum() < 2.0
    direct = graph.route(a, np.array([-0.6, 0.5, 0.3]))
    assert len(direct) == 2


# ---- smoothing and timing --------------------------------------------------------------
def test_trajectory_stays_within_every_joint_limit(planner_for, wall_scene):
    model = wall_scene[0].model
    rng = np.random.default_rng(4)
    for n in (2, 3, 6):
        w = rng.uniform(model.lower, model.upper, (n, 6)) * 0.5
        w[1:] = w[:1] + np.cumsum(rng.normal(size=(n - 1, 6)) * rng.uniform(0.01, 0.8), axis=0)
        w = np.clip(w, model.lower, model.upper)
        traj = time_parameterize(model, w, period=0.005)
        ratios = limit_violations(model, traj)
        assert ratios["velocity"] <= 1 + TOL and ratios["acceleration"] <= 1 + TOL
        assert ratios["tool_speed"] <= 1 + TOL
        np.testing.assert_allclose(traj.q[[0, -1]], w[[0, -1]], atol=1e-9)
    r = wall_scene[0].plan(wall_scene[1], wall_scene[2])
    ratios = limit_violations(model, r.trajectory)
    assert ratios["velocity"] <= 1 + TOL and ratios["acceleration"] <= 1 + TOL


def test_tool_point_speed_limit_is_kept(wall_scene, planner_for):
    """A long sweep of the waist with the arm stretched: the joints alone would carry the
    tool point far faster than the workcell's limit; the timed knots stay within it."""
    planner, tool = planner_for("us_probe_1")
    model, tcp = planner.model, tool.tcp.matrix()
    w = np.array([[-1.2, 0.4, -0.3, 0.0, 0.5, 0.0], [0.0, 0.5, -0.1, 0.3, 0.4, 0.2], [1.2, 0.4, -0.3, 0.0, 0.5, 0.0]])
    free = time_parameterize(model, w, tcp=tcp, tool_speed=np.inf)
    assert limit_violations(model, free, tcp)["tool_speed"] > 1.5
    for stops in (None, [False, True, False]):
        traj = time_parameterize(model, w, stops, tcp=tcp)
        ratios = limit_violations(model, traj, tcp)
        assert 0.95 < ratios["tool_speed"] <= 1 + TOL
        assert ratios["velocity"] <= 1 + TOL and ratios["acceleration"] <= 1 + TOL
    r = planner.plan(np.array(HOME), w[-1], tool)
    assert r.ok and limit_violations(model, r.trajectory, tcp)["tool_speed"] <= 1 + TOL


def test_the_planner_makes_the_controllers_trajectory(planner_for):
    from ita.robot.waypoints import TimedTrajectory

    planner, _ = planner_for(None)
    w = np.array([HOME, np.array(HOME) + 0.3, np.array(HOME) + [0.6, 0.3, 0.3, 0.3, 0.0, 0.3]])
    traj = planner.time(w, None, stops=[True, True, True])
    assert isinstance(traj, TimedTrajectory)
    assert len(traj.vias) == len(traj.stops) == 3 and traj.stops.all()
    np.testing.assert_allclose(traj.sample(traj.vias), w, atol=1e-9)


def test_blends_are_quicker_than_stops_and_stops_are_at_rest(wall_scene):
    model = wall_scene[0].model
    w = np.array([[0.0] * 6, [0.6, 0.2, 0.0, 0.0, 0.0, 0.0], [0.6, 0.6, 0.3, 0.5, 0.0, 0.0]])
    blended = time_parameterize(model, w)
    stopped = time_parameterize(model, w, stops=[False, True, False])
    assert blended.duration < stopped.duration
    t_via = stopped.vias[1]
    near = np.abs(stopped.times - t_via) < 0.011
    speed = np.abs(np.diff(stopped.q, axis=0) / np.diff(stopped.times)[:, None])
    assert speed[near[:-1]].max() < 0.05
    single = lspb(model, w[:2])                    # one segment: the rest-to-rest minimum
    assert single.duration == pytest.approx(float(move_time(model, w[0], w[1])))


def test_smoothing_never_introduces_a_collision(wall_scene):
    planner, start, goal = wall_scene
    ctx = planner.context(None)
    rng = np.random.default_rng(7)

    def free(a, b):
        return segments_free(ctx.config_free, a, b, ctx.lever, 0.02)

    lifter = Lifter(planner.model, np.eye(4), ctx.config_free, ctx.motion_free, np.array(HOME), rng)
    for trial in range(3):
        raw = lifter.repair(np.vstack([start, goal]), Effort(60, 5.0))
        assert raw is not None
        # a jagged but free path: detours through random free configurations
        extra = []
        for a, b in pairwise(raw):
            c = rng.uniform(planner.model.lower, planner.model.upper, (200, 6)) * 0.3 + (a + b) / 2 * 0.7
            ok = ctx.config_free(c)
            c = c[ok]
            good = c[free(np.broadcast_to(a, c.shape), c) & free(c, np.broadcast_to(b, c.shape))]
            extra.append([a, good[0]] if len(good) else [a])
        jagged = np.vstack([q for pair in extra for q in pair] + [raw[-1]])
        assert free(jagged[:-1], jagged[1:]).all()
        short = shortcut(planner.model, jagged, free)
        assert free(short[:-1], short[1:]).all()
        np.testing.assert_allclose(short[[0, -1]], jagged[[0, -1]])
        traj = time_parameterize(planner.model, short, segments_free=ctx.motion_free)
        assert trajectory_free(traj, free)
        assert trajectory_free(traj, lambda a, b: segments_free(ctx.config_free, a, b, ctx.motion_free.bounds, 0.001))


def test_queue_blends_through_intermediate_goals(planner_for):
    planner, tool = planner_for(None)
    goals = [np.array(HOME) + d for d in ([0.4, 0.1, 0, 0, 0, 0], [0.8, -0.1, 0.1, 0, 0.2, 0], [0.8, 0.2, 0, 0, 0, 0])]
    results, blended = planner.plan_queue(np.array(HOME), goals, tool, lookahead=4)
    _, stopped = planner.plan_queue(np.array(HOME), goals, tool, stops=[True, True, False], lookahead=4)
    assert all(r.ok for r in results)
    assert blended.duration < stopped.duration <= sum(r.duration for r in results) + 1e-9


# ---- problem sets ----------------------------------------------------------------------
def test_problem_set_round_trip_and_run(cell, specs, planner_for, tmp_path):
    problems = generate_problems(cell, specs, 8, 5, planner_for)
    assert len(problems) == 8
    path = tmp_path / "p.json"
    write_problems(path, problems, 5)
    assert read_problems(path) == problems
    rows = run_problems(problems, planner_for)
    summary = summarize(rows)
    assert summary["solved"] == 8 and summary["median_ms"] > 0
    assert all(planner_for(p.tool)[0].config_free(np.array(p.start_q), planner_for(p.tool)[1])[0] for p in problems)


def test_malformed_problem_file_is_an_input_error(tmp_path):
    path = tmp_path / "bad.json"
    path.write_text(json.dumps({"format": "ita-path-problems/1", "problems": [
        {"id": "x", "kind": "random", "tool": None, "start_q": [0, 0, 0]}]}))
    with pytest.raises(InputError, match="problems\\[0\\]"):
        read_problems(path)
    path.write_text("{}")
    with pytest.raises(InputError, match="not a problem set"):
        read_problems(path)
    assert Problem.from_json(Problem("a", "random", None, "", "", (0.0,) * 6, (1.0,) * 6).to_json()).goal.shape == (6,)


# ---- CLI -------------------------------------------------------------------------------
def test_cli_plan_renders_and_reports(builtin_part, tmp_path):
    runner = CliRunner()
    png = tmp_path / "path.png"
    r = runner.invoke(main, ["path", "plan", "home", "rack:slot_3", "--render", str(png)])
    assert r.exit_code == 0, r.output
    assert "slra_1" in r.output and "duration" in r.output
    assert png.stat().st_size > 20_000
    r = runner.invoke(main, ["path", "plan", "home", "no_such_spec"])
    assert r.exit_code == 2
    r = runner.invoke(main, ["path", "plan", "home", "home", "--tool", "none", "--json"])
    assert r.exit_code == 0 and json.loads(r.output)["ok"]


def test_cli_plan_without_a_path_exits_1(builtin_part, specs, cell, planner_for):
    r = CliRunner().invoke(main, ["path", "plan", "home", specs[0].id, "--tool", "none"])
    assert r.exit_code == 2            # a measurement needs a tool
    planner, tool = planner_for("us_probe_1")
    blocked = next(s for s in specs if planner.goal_configs(
        np.array(HOME), measurement_targets(cell, s.point, s.normal, tool), tool)[1] is not None)
    r = CliRunner().invoke(main, ["path", "plan", "home", blocked.id, "--tool", "us_probe_1"])
    assert r.exit_code == 1 and "no path: goal_" in r.output


def test_cli_problems_and_bench(builtin_part, tmp_path):
    runner = CliRunner()
    out = tmp_path / "probs.json"
    r = runner.invoke(main, ["path", "problems", "--n", "4", "--seed", "2", "-o", str(out)])
    assert r.exit_code == 0, r.output
    r = runner.invoke(main, ["path", "bench", str(out), "--json"])
    assert r.exit_code == 0, r.output
    data = json.loads(r.output[r.output.index("{"):])
    assert data["summary"]["problems"] == 4 and data["summary"]["solved"] == 4
