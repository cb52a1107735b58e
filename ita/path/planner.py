"""The Path Planner: reachable goal, tool-point route, collision-free joint path, trajectory.

    planner = PathPlanner(model, tree, checker)          # ArmModel, RegionTree, ArmChecker
    result = planner.plan(q_start, goal, tool)           # goal: q (6,), a tool pose (4, 4)
    if result.ok:                                        #   or candidate poses (k, 4, 4)
        result.trajectory.times, result.trajectory.q     # what the controller runs
    else:
        result.reason, result.message                    # why not

A query (seed, Path Planner): verify that the goal is reachable (inverse kinematics within
the limits, then collision-free; the candidates ordered by motion time from the start);
plan the tool point among the regions grown by the tool's size (`visibility`); lift that
route to joint space and check every link at incremental positions, replanning colliding
stretches through intermediate subgoals (`lift`) within an effort bound; shorten the
path, then cut it into pieces reshaped for the least estimated duration (`smooth.reshape_path`,
every new segment checked); time it with blended corners within the joint limits (`smooth`),
keeping the reshaped path only if its trajectory is the quicker.

Should the two levels spend their effort bound without a free path (a move that needs a
large joint-space swing: another arm branch, the wrist turned over, the arm swung out and
round), a bidirectional sampling planner searches the whole joint space toward every free
goal solution (`sampling.rrt_connect`: RRT-Connect on the same `config_free` and sound
`motion_free`, the lever-arm-scaled metric, the query's seed) within its own bound of
iterations; its path is shortened, reshaped and timed like any other.  Only when that
fails too is the answer `NO_PATH_WITHIN_EFFORT`.

The held tool is one more collision tube on the flange (`tool_tube`), checked against the
world and against the arm's links but its own wrist; the tree must not hold the held
tool's parked copy (`workcell_planner` builds such a tree).  The planner reads the tree
through `ArmChecker` and `RegionTree.tubes_hit` only: it takes no simulator.
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from enum import Enum
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ita.collision import (
    ArmChecker,
    ArmTubes,
    Regions,
    RegionTree,
    arm_tubes,
    build_tree,
    self_pairs,
    tool_tube,
)
from ita.kinematics import (
    ArmModel,
    arm_model,
    ik_tool,
    link_segments,
    tcp_poses,
)
from ita.path.lift import Effort, Lifter, lever_arms, lift_route
from ita.path.motion import ConfigChecker, MotionChecker
from ita.path.sampling import rrt_connect
from ita.path.smooth import (
    estimate_durations,
    reshape_path,
    shortcut,
    time_parameterize,
)
from ita.path.trajectory import TimedTrajectory
from ita.path.visibility import VisibilityGraph, build_graph
from ita.workcell.model import HOME_Q, ToolSpec, Workcell

FloatArray = NDArray[np.float64]
HOME = HOME_Q   # the workcell model's default home: arm folded back, wrist down, clear of the cell


class PathFailure(str, Enum):
    """Why a query has no path; the value is the spelling in reports."""

    GOAL_UNREACHABLE = "goal_unreachable"
    START_OUT_OF_LIMITS = "start_out_of_limits"
    START_IN_COLLISION = "start_in_collision"
    GOAL_IN_COLLISION = "goal_in_collision"
    NO_PATH_WITHIN_EFFORT = "no_path_within_effort"


#: how far (rad per joint) a start configuration found in collision is jiggled to a free one,
#: in growing steps: an arm settled by its repeatability (0.25 mm at the tool point, about
#: 1e-4 rad) into the tubes' margin gets out within the first steps; a real collision does not
JIGGLE_STEPS_RAD = (0.0002, 0.0005, 0.001, 0.002)
#: configurations sampled per step
JIGGLE_SAMPLES = 64


@dataclass(frozen=True)
class PlannerSettings:
    """Figures of the planner.

    clearance: m beyond the tool's radius for visibility nodes; motion_floor: m, the
    closest approach to contact a motion may make away from its ends, motion_budget:
    clearance evaluations per segment (see `motion.MotionChecker`: every accepted motion
    is free at every position); max_rounds / max_seconds: the effort bound (subgoal
    rounds, seconds per query); goal_candidates: IK solutions of the goal tried,
    quickest (by estimated duration) first; detour_rounds / detour_gain: when the quickest goal solution is
    blocked but a slower one is free, subgoal rounds spent on the quicker one if its
    direct time is under detour_gain of the free path's; shortcut_rounds: corner-pulling
    passes;
    refine_rounds: random local descent rounds on each remaining corner (or on the
    reshaped path's waypoints);
    reshape_splits: pieces each segment is cut into before the final descent on the
    estimated duration (`smooth.reshape_path`, kept where the timed trajectory is quicker;
    1: none, the corners refined instead);
    fallback_iterations / fallback_seconds / fallback_step: the sampling fallback's effort
    bound (RRT-Connect iterations, seconds as a last-resort cap; 0 iterations: no
    fallback) and its longest edge (fraction of the scaled joint space's diagonal);
    knot_period: s between trajectory knots; blend: corners blended (else rest at every
    via); seed: random subgoals and samples (each query starts from it: a query's answer
    does not depend on the queries before it)."""

    clearance: float = 0.05
    motion_floor: float = 1e-5
    motion_budget: int = 400
    max_rounds: int = 60
    max_seconds: float = 2.0
    goal_candidates: int = 6
    detour_rounds: int = 2
    detour_gain: float = 0.85
    shortcut_rounds: int = 2
    refine_rounds: int = 6
    reshape_splits: int = 2
    fallback_iterations: int = 10000
    fallback_seconds: float = 5.0
    fallback_step: float = 0.1
    knot_period: float = 0.01
    blend: bool = True
    seed: int = 0
    home: tuple[float, ...] = HOME


@dataclass(frozen=True, eq=False)
class PathResult:
    """The answer to one query.

    ok: a path was found; reason: why not (None when ok); message: one line for people.
    waypoints (k, 6): the joint path (start first, goal last); route (r, 3): the tool
    point's visibility route; tool_path (m, 3): the TCP along the trajectory's knots;
    trajectory: the timed motion; seconds: planning time (all of it); stats: counts."""

    ok: bool
    reason: PathFailure | None
    message: str
    waypoints: FloatArray
    route: FloatArray
    tool_path: FloatArray
    trajectory: TimedTrajectory | None
    seconds: float
    stats: dict[str, Any] = field(default_factory=dict)

    @property
    def duration(self) -> float:
        """Trajectory duration (s), nan without a path."""
        return self.trajectory.duration if self.trajectory is not None else float("nan")

    @property
    def tool_path_length(self) -> float:
        """Length (m) of the tool point's path, nan without a path."""
        if not self.ok:
            return float("nan")
        return float(np.linalg.norm(np.diff(self.tool_path, axis=0), axis=1).sum())


def arm_with_tool(model: ArmModel, tool: ToolSpec | None) -> ArmModel:
    """The model with the held tool's enclosing tube appended on the flange link."""
    if tool is None:
        return model
    ends, radius = tool_tube(tool)
    return dataclasses.replace(
        model,
        tube_links=np.append(model.tube_links, model.dof + 1),
        tube_ends=np.concatenate([model.tube_ends, ends[None]]),
        tube_radii=np.append(model.tube_radii, radius),
    )


def checker_for(model: ArmModel, tree: RegionTree, mount: Sequence[str] = ()) -> ArmChecker:
    """An ArmChecker for `model`'s tubes; a tool tube on the flange is not checked against
    the wrist link it is bolted next to."""
    links = model.tube_links
    exclude = [(model.dof - 1, model.dof + 1)] if (links == model.dof + 1).any() else []
    return ArmChecker(tree, model.tube_radii, links, pairs=self_pairs(links, exclude=exclude), mount=mount)


@dataclass
class _ToolContext:
    model: ArmModel
    checker: ArmChecker
    tcp: FloatArray
    radius: float
    lever: FloatArray
    config_free: ConfigChecker
    motion_free: MotionChecker
    graph: VisibilityGraph | None = None


class PathPlanner:
    """Plans collision-free, timed arm motions in one workcell state (see module doc).

    model: the bare arm; tree: the region tree (without the held tool); checker: the
    arm's checker over that tree (its `mount` is kept for tool variants)."""

    def __init__(self, model: ArmModel, tree: RegionTree, checker: ArmChecker,
                 settings: PlannerSettings | None = None, tubes: ArmTubes | None = None) -> None:
        self.model = model
        self.tree = tree
        self.checker = checker
        self.settings = settings or PlannerSettings()
        # the arm's tight tubes (`ita.collision.arm_tubes`); a held tool then gets tubes of
        # its real shape.  Without them a tool is one enclosing tube (`arm_with_tool`).
        self.tubes = tubes
        self._contexts: dict[str | None, _ToolContext] = {}

    # ---- per tool --------------------------------------------------------------------
    def context(self, tool: ToolSpec | None) -> _ToolContext:
        """Model, checker, TCP and visibility graph for a held tool (cached by name)."""
        key = None if tool is None else tool.name
        if key not in self._contexts:
            if tool is not None and tool.name in self.tree.objects:
                raise ValueError(f"the held tool {tool.name!r} is still in the region tree as parked")
            if tool is None:
                model, checker = self.model, self.checker
            elif self.tubes is not None:
                held = self.tubes.with_tool(tool, self.model.dof + 1)
                model, checker = held.apply(self.model), held.checker(self.tree, self.checker.mount)
            else:
                model = arm_with_tool(self.model, tool)
                checker = checker_for(model, self.tree, self.checker.mount)
            tcp = np.eye(4) if tool is None else tool.tcp.matrix()
            radius = float(self.model.tube_radii[-1]) if tool is None else tool_tube(tool)[1]
            reach = 0.0 if tool is None else float(np.linalg.norm(tool.tcp.position))
            config_free = ConfigChecker(model, checker)
            motion_free = MotionChecker(config_free, self.settings.motion_floor, self.settings.motion_budget)
            self._contexts[key] = _ToolContext(model, checker, tcp, radius, lever_arms(self.model, reach + radius),
                                               config_free, motion_free)
        return self._contexts[key]

    def graph(self, tool: ToolSpec | None) -> VisibilityGraph:
        """The static visibility graph for the tool's size (built on first use)."""
        ctx = self.context(tool)
        if ctx.graph is None:
            k = self.model.kinematics
            shoulder = self.model.base[:3, 3] + np.array([0.0, 0.0, k.d1])
            reach = k.a1 + k.a2 + k.d4 + k.d6 + float(np.linalg.norm(ctx.tcp[:3, 3])) + ctx.radius
            ctx.graph = build_graph(self.tree, ctx.radius, self.settings.clearance, reach=(shoulder, reach))
        return ctx.graph

    def invalidate(self) -> None:
        """Forget cached graphs and checkers (after the tree changed shape)."""
        self._contexts.clear()

    def config_free(self, q: ArrayLike, tool: ToolSpec | None = None) -> NDArray[np.bool_]:
        """Bool (n,): configurations (n, 6) within the limits and free of collision."""
        return self.context(tool).config_free(q)

    # ---- queries ---------------------------------------------------------------------
    def goal_configs(self, q_start: FloatArray, goal: ArrayLike, tool: ToolSpec | None
                     ) -> tuple[FloatArray, PathFailure | None, str]:
        """Free goal configurations (m, 6), quickest from q_start (estimated blended
        duration) first, those within the motion check's floor of contact (reachable
        only by moving straight out of it: `MotionChecker.clear`) last;
        or a reason."""
        ctx = self.context(tool)
        g = np.asarray(goal, dtype=float)
        if g.shape == (self.model.dof,):
            if not self.model.within_limits(g):
                return np.zeros((0, 6)), PathFailure.GOAL_UNREACHABLE, "the goal configuration is outside the joint limits"
            if not ctx.config_free(g)[0]:
                return np.zeros((0, 6)), PathFailure.GOAL_IN_COLLISION, f"the goal configuration hits {self._culprit(g, ctx)}"
            return g[None], None, ""
        if g.shape[-2:] != (4, 4):
            raise ValueError(f"goal must be a configuration (6,) or tool poses (..., 4, 4), got {g.shape}")
        ik = ik_tool(self.model, g.reshape(-1, 4, 4), ctx.tcp)
        q = ik.q[ik.valid]
        if len(q) == 0:
            status = ik.flatten_batch().status(()) if ik.shape else ik.status(())
            return np.zeros((0, 6)), PathFailure.GOAL_UNREACHABLE, f"no joint solution within the limits ({status.value})"
        free = ctx.config_free(q)
        if not free.any():
            return np.zeros((0, 6)), PathFailure.GOAL_IN_COLLISION, f"every joint solution of the goal hits something: {self._culprits(q, ctx)}"
        q = q[free]
        direct = estimate_durations(self.model, np.stack([np.broadcast_to(q_start, q.shape), q], axis=1), ctx.tcp)
        # solutions within micrometres of contact last
        touching = ~ctx.motion_free.clear(q)
        q = q[np.lexsort((direct, touching))]
        _, first = np.unique(np.round(q, 9), axis=0, return_index=True)
        return q[np.sort(first)], None, ""

    def plan(self, q_start: ArrayLike, goal: ArrayLike, tool: ToolSpec | None = None) -> PathResult:
        """Plan one move from q_start (6,) to a goal configuration (6,), tool pose (4, 4) or
        candidate tool poses (k, 4, 4) of the held tool (None: the bare flange)."""
        t0 = time.perf_counter()
        s = self.settings
        ctx = self.context(tool)
        start = np.asarray(q_start, dtype=float).reshape(self.model.dof)
        if not self.model.within_limits(start):
            return self._fail(PathFailure.START_OUT_OF_LIMITS, "the start configuration is outside the joint limits", t0)
        if not ctx.config_free(start)[0]:
            # the arm settled off its last goal (its repeatability) into the tubes' margin:
            # start from a free configuration a jiggle away, the step there first
            near = self._free_near(start, ctx)
            if near is None:
                return self._fail(PathFailure.START_IN_COLLISION,
                                  f"the start configuration hits {self._culprit(start, ctx)}", t0)
            out = self.plan(near, goal, tool)
            if not out.ok or out.trajectory is None:
                return out
            way = np.vstack([start, out.waypoints])
            timed = self.time(way, tool)
            return dataclasses.replace(out, waypoints=way, trajectory=timed,
                                       tool_path=tcp_poses(self.model, timed.q, ctx.tcp)[:, :3, 3],
                                       message=f"{out.message} (from a free configuration a jiggle away)",
                                       seconds=time.perf_counter() - t0,
                                       stats=dict(out.stats, jiggled=float(np.max(np.abs(near - start)))))
        goals, reason, message = self.goal_configs(start, goal, tool)
        if reason is not None:
            return self._fail(reason, message, t0)
        everywhere, goals = goals, goals[: s.goal_candidates]
        graph = self.graph(tool)
        ends = tcp_poses(self.model, np.vstack([start, goals[0]]), ctx.tcp)
        route = graph.route(ends[0, :3, 3], ends[1, :3, 3], -ends[0, :3, 2], -ends[1, :3, 2])
        if route is None:
            route = ends[:, :3, 3]
        lifter = Lifter(self.model, ctx.tcp, ctx.config_free, ctx.motion_free,
                        np.asarray(s.home, dtype=float), np.random.default_rng(s.seed))
        effort = Effort(s.max_rounds, s.max_seconds)
        stats: dict[str, Any] = {"route_corners": len(route) - 2, "goal_candidates": len(goals), "subgoals": 0,
                                 "sampled": 0}
        path = self._two_level(start, goals, route, lifter, effort, ctx, stats)
        stats.update(rounds=effort.rounds, subgoals_tried=lifter.subgoals_tried, graph_nodes=len(graph.nodes))
        if path is None:
            path = self._sample(start, everywhere, ctx, stats)
        if path is None:
            return self._fail(PathFailure.NO_PATH_WITHIN_EFFORT,
                              f"no collision-free path within {effort.rounds} subgoal rounds and "
                              f"{stats['sampled']} sampling iterations ({time.perf_counter() - effort.started:.2f} s)",
                              t0, route, stats)
        path, traj = self._shorten(path, lifter, ctx, tool)
        tool_path = tcp_poses(self.model, traj.q, ctx.tcp)[:, :3, 3]
        stats["waypoints"] = len(path)
        return PathResult(True, None, f"{len(path)} waypoints, {traj.duration:.2f} s", path, route, tool_path, traj,
                          time.perf_counter() - t0, stats)

    def time(self, waypoints: ArrayLike, tool: ToolSpec | None = None, stops: ArrayLike | None = None
             ) -> TimedTrajectory:
        """The blended trajectory of a joint path (blends only where free, the tool point
        within the TCP speed limit; see `smooth`)."""
        ctx = self.context(tool)
        w = np.asarray(waypoints, dtype=float)
        if not self.settings.blend:
            stops = np.ones(len(w), dtype=bool)
        return time_parameterize(self.model, w, stops, ctx.motion_free, ctx.tcp, period=self.settings.knot_period)

    def plan_queue(self, q_start: ArrayLike, goals: Sequence[ArrayLike], tool: ToolSpec | None = None,
                   stops: Sequence[bool] | None = None, lookahead: int = 4
                   ) -> tuple[list[PathResult], TimedTrajectory | None]:
        """Plan consecutive moves (the Executive's lookahead queue) and time them together:
        up to `lookahead` moves are blended through their intermediate goals, except goals
        flagged in `stops` (a measurement) and where a blend would collide; the arm rests
        at the end of each window.  Returns each move's result and the whole trajectory
        (None if a move failed)."""
        results, q = [], np.asarray(q_start, dtype=float)
        for g in goals:
            r = self.plan(q, g, tool)
            results.append(r)
            if not r.ok:
                return results, None
            q = r.waypoints[-1]
        flags = [False] * len(goals) if stops is None else list(stops)
        path, rest = [results[0].waypoints[0]], [True]
        for i, r in enumerate(results):
            path.extend(r.waypoints[1:])
            rest.extend([False] * (len(r.waypoints) - 2))
            rest.append(bool(flags[i]) or (i + 1) % max(lookahead, 1) == 0)
        return results, self.time(np.vstack(path), tool, np.array(rest))

    # ---- helpers ---------------------------------------------------------------------
    def _free_near(self, q: FloatArray, ctx: _ToolContext) -> FloatArray | None:
        """A free configuration within a jiggle of ``q`` (each joint at most
        :data:`JIGGLE_RAD` from it, within the limits), the nearest of those sampled with the
        query's seed; None when none is (what MoveIt's FixStartStateCollision does: an arm
        settled by its repeatability into the collision tubes' margin, not in contact)."""
        rng = np.random.default_rng(self.settings.seed)
        lower, upper = np.asarray(self.model.lower, dtype=float), np.asarray(self.model.upper, dtype=float)
        for radius in JIGGLE_STEPS_RAD:
            cand = np.clip(q + rng.uniform(-radius, radius, size=(JIGGLE_SAMPLES, len(q))), lower, upper)
            free = ctx.config_free(cand)
            if free.any():
                cand = cand[free]
                return np.asarray(cand[int(np.argmin(np.max(np.abs(cand - q), axis=1)))], dtype=float)
        return None

    def _two_level(self, start: FloatArray, goals: FloatArray, route: FloatArray, lifter: Lifter, effort: Effort,
                   ctx: _ToolContext, stats: dict[str, Any]) -> FloatArray | None:
        """The two levels: the direct joint move to each goal candidate and the lifted
        route, the quickest free one taken (a quicker blocked one given a detour or two);
        else colliding stretches replanned through subgoals within the effort bound."""
        s = self.settings
        options = [np.vstack([start, q]) for q in goals]
        if len(route) > 2:
            options.append(lift_route(self.model, ctx.tcp, route, start, goals[0]))
        times = [self._estimate(w, ctx) for w in options]
        path, order = None, np.argsort(times, kind="stable")
        for rank, k in enumerate(order):                # the quickest free option wins
            if lifter.free_segments(options[k][:-1], options[k][1:]).all():
                path = options[k]
                break
        if path is not None and rank > 0:
            # a quicker goal solution may still be worth a subgoal or two
            for k in order[:min(rank, 2)]:
                if times[k] >= s.detour_gain * self._estimate(path, ctx):
                    break
                detour = lifter.repair(options[k], Effort(s.detour_rounds, s.max_seconds))
                if detour is not None and self._estimate(detour, ctx) < self._estimate(path, ctx):
                    path = detour
                    stats["subgoals"] = len(detour) - len(options[k])
        if path is None:
            # replan colliding stretches through subgoals, the quickest option first
            for k in order:
                path = lifter.repair(options[k], effort)
                if path is not None:
                    stats["subgoals"] = len(path) - len(options[k])
                    break
                if effort.spent():
                    break
        return path

    def _sample(self, start: FloatArray, goals: FloatArray, ctx: _ToolContext, stats: dict[str, Any]
                ) -> FloatArray | None:
        """The fallback: a free joint path to any of the free goal solutions by
        `sampling.rrt_connect` within its own effort bound, or None (0 iterations: none)."""
        s = self.settings
        if s.fallback_iterations <= 0:
            return None
        found = rrt_connect(start, goals, ctx.config_free, ctx.motion_free, self.model.lower, self.model.upper,
                            ctx.lever, np.random.default_rng(s.seed), s.fallback_iterations, s.fallback_seconds,
                            s.fallback_step)
        stats.update(sampled=found.iterations, sampled_nodes=found.nodes, sampled_seconds=found.seconds)
        return found.path

    def _shorten(self, path: FloatArray, lifter: Lifter, ctx: _ToolContext, tool: ToolSpec | None
                 ) -> tuple[FloatArray, TimedTrajectory]:
        """The free path shortened (`smooth.shortcut`), then reshaped (`smooth.reshape_path`)
        where that gives a quicker timed trajectory, and its trajectory."""
        s = self.settings
        reshape = s.reshape_splits > 1
        path = shortcut(self.model, path, lifter.free_segments, s.shortcut_rounds, None if reshape else lifter.rng,
                        s.refine_rounds, tcp=ctx.tcp)
        traj = self.time(path, tool)
        if not reshape:
            return path, traj
        quick = reshape_path(self.model, path, lifter.free_segments, np.random.default_rng(s.seed),
                             s.refine_rounds, tcp=ctx.tcp, splits=s.reshape_splits)
        if len(quick) == len(path):                  # not reshaped: no quicker by the estimate
            return path, traj
        timed = self.time(quick, tool)
        return (quick, timed) if timed.duration < traj.duration else (path, traj)

    def _estimate(self, waypoints: FloatArray, ctx: _ToolContext) -> float:
        """Estimated blended duration (s) of a joint path (`smooth.estimate_durations`)."""
        return float(estimate_durations(self.model, waypoints, ctx.tcp)[0])

    def _culprit(self, q: FloatArray, ctx: _ToolContext) -> str:
        if not self.model.within_limits(q):
            return "a joint limit"
        hits = ctx.checker.check(link_segments(ctx.model, q))
        if hits.status[0] == 2:
            a, b = hits.pair[0]
            names = ctx.model.link_names
            link = [names[ctx.model.tube_links[t]] if ctx.model.tube_links[t] <= self.model.dof else "the tool"
                    for t in (a, b)]
            return f"itself ({link[0]} and {link[1]})"
        return str(hits.obj[0])

    def _culprits(self, q: FloatArray, ctx: _ToolContext) -> str:
        """What the configurations q (n, 6) hit, most often first: 'part (10), itself (2)'."""
        counts: dict[str, int] = {}
        for row in q:
            name = self._culprit(row, ctx)
            name = "itself" if name.startswith("itself") else name
            counts[name] = counts.get(name, 0) + 1
        return ", ".join(f"{k} ({v})" for k, v in sorted(counts.items(), key=lambda kv: -kv[1]))

    @staticmethod
    def _fail(reason: PathFailure, message: str, t0: float, route: FloatArray | None = None,
              stats: dict | None = None) -> PathResult:
        empty = np.zeros((0, 6))
        return PathResult(False, reason, message, empty, np.zeros((0, 3)) if route is None else route,
                          np.zeros((0, 3)), None, time.perf_counter() - t0, stats or {})


#: the region tree's object for ground the planner keeps clear of besides the cell's (in
#: a two-arm run, the other arm's: a goal there "hits the other arm")
KEEP_CLEAR = "the other arm"


def planners_for(cell: Workcell, part: Any | None, settings: PlannerSettings | None = None,
                 keep_clear: Regions | None = None) -> Callable[[str | None], tuple[PathPlanner, ToolSpec | None]]:
    """A cached `held tool name -> (PathPlanner, ToolSpec)` for one workcell and part
    (keep_clear: as :func:`workcell_planner`)."""
    cache: dict[str | None, tuple[PathPlanner, ToolSpec | None]] = {}

    def planner_for(held: str | None) -> tuple[PathPlanner, ToolSpec | None]:
        if held not in cache:
            cache[held] = workcell_planner(cell, part, held, settings, keep_clear)
        return cache[held]

    return planner_for


def workcell_planner(cell: Workcell, part: Any | None, held: str | None = None,
                     settings: PlannerSettings | None = None,
                     keep_clear: Regions | None = None) -> tuple[PathPlanner, ToolSpec | None]:
    """A planner over the workcell and part with tool `held` in the gripper (its parked
    copy taken out of the tree), and that tool.  keep_clear: regions the arm keeps out of
    besides the cell (in a two-arm run, where the other arm may stand folded:
    ita.executive.conductor.folded_ground)."""
    tree = build_tree(cell, part)
    if keep_clear is not None and len(keep_clear):
        tree.add(KEEP_CLEAR, keep_clear)
    tool = None
    if held is not None:
        tool = cell.tool(held)
        if held in tree.objects:
            tree.remove(held)
    bare = arm_model(cell.arm)
    tubes = arm_tubes(cell.arm.urdf, bare.link_names)
    model = tubes.apply(bare)
    checker = tubes.checker(tree, mount=[cell.pedestal.name])
    if settings is None:
        settings = PlannerSettings(home=tuple(cell.arm.home))
    return PathPlanner(model, tree, checker, settings, tubes), tool
