"""The second level: from a tool-point route to a collision-free joint path.

The route's corners are lifted to joint space (inverse kinematics, the tool's
orientation slerped from the start's to the goal's by arc length, each corner's branch
the quickest to reach from the previous one); the joint path between them is checked at
incremental positions for every link (one batched call of `config_free`).  Where a link
would collide, intermediate subgoals are proposed and evaluated, and the segment replanned
through the best of them, until the whole path is free or the effort bound is spent.

Subgoals, in the order they are proposed for a colliding segment a -> b:
* retreats of the tool point: the segment's middle tool point moved up, toward the arm's
  base and back along the end poses' approach axes, by 0.15 to 0.5 m (IK, nearest branch);
* joint detours: the joint midpoint with the shoulder, elbow or waist turned, and `home`;
* random configurations about the joint midpoint, spreading further each round.
A candidate that frees both halves is taken (the quickest); else one that frees one half,
and the other half is replanned (depth-first, bounded).

Segments are tested by `motion_free` (a `motion.MotionChecker` for sound paths: a segment
it accepts is free at every position, not only at checked ones).  `segments_free` is the
plain sampled test (exact tubes at spaced positions), kept for re-checks at a stated
resolution.

Everything here takes plain callables: `config_free(q (n, 6)) -> bool (n,)`,
`motion_free(a (n, 6), b (n, 6)) -> bool (n,)`.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.spatial.transform import Rotation, Slerp

from ita.kinematics import (
    ArmModel,
    choose_nearest,
    ik_tool,
    link_frames,
    move_time,
    tcp_poses,
)
from ita.path.motion import ConfigChecker, MotionChecker, sweep_bounds

__all__ = ["ConfigChecker", "Effort", "Lifter", "MotionChecker", "lever_arms", "lift_route", "path_free",
           "path_time", "segments_free", "sweep_bounds"]

FloatArray = NDArray[np.float64]
ConfigFree = Callable[[FloatArray], NDArray[np.bool_]]
SegmentsFree = Callable[[FloatArray, FloatArray], NDArray[np.bool_]]
RETREAT_DISTANCES = (0.15, 0.3, 0.5)   # m
DETOUR_STEPS = (0.5, -0.5)             # rad on j1, j2, j3
CHUNK = 8                              # subgoals evaluated per batch, quickest first


def lever_arms(model: ArmModel, tool_length: float = 0.0) -> FloatArray:
    """(6,) m: the farthest any link point (plus a tool reaching tool_length past the
    flange) can be from each joint's axis: the chain's length beyond the joint."""
    frames = link_frames(model, np.zeros(model.dof))[0]
    origins = frames[1:model.dof + 1, :3, 3]
    ends = np.vstack([frames[1:, :3, 3], frames[-1, :3, 3] + frames[-1, :3, 2] * tool_length])
    lever = np.array([np.linalg.norm(ends[i:] - origins[i], axis=1).max() for i in range(model.dof)])
    return lever + float(model.tube_radii.max())


def segments_free(config_free: ConfigFree, a: ArrayLike, b: ArrayLike, lever: FloatArray,
                  resolution: float) -> NDArray[np.bool_]:
    """Bool (n,): whether each joint segment a -> b ((n, 6)) is free at its incremental
    positions (the start configurations are taken as checked): sampled, exact tubes, so
    a pass says nothing about the stretches between samples (`MotionChecker` does).

    lever: (6,) the sweep of a step dq is ||dq * lever||; or sweep bounds (6, t) (see
    `sweep_bounds`): the sweep is the most any tube's axis can move, so `resolution` is a
    true bound on any point's travel between samples.
    Coarse to fine: every segment's n steps (a multiple of 8, n >= ceil(sweep /
    resolution)) are checked at strides 8, 4, 2, 1, each level only for the segments still
    free and only at the positions not checked yet, so a collision is usually found early
    and a free segment costs exactly its n checks."""
    a, b = np.atleast_2d(np.asarray(a, dtype=float)), np.atleast_2d(np.asarray(b, dtype=float))
    lever = np.asarray(lever, dtype=float)
    if lever.ndim == 2:
        sweep = (np.abs(b - a) @ lever).max(axis=1)
    else:
        sweep = np.linalg.norm((b - a) * lever, axis=1)
    steps = 8 * np.maximum(1, np.ceil(sweep / (8.0 * resolution)).astype(np.int64))
    alive = np.ones(len(a), dtype=bool)
    for stride in (8, 4, 2, 1):
        idx = np.flatnonzero(alive)
        if len(idx) == 0:
            break
        count = steps[idx] // stride
        seg = np.repeat(idx, count)
        k = stride * (np.arange(count.sum()) - np.repeat(np.cumsum(count) - count, count) + 1)
        if stride < 8:
            keep = k % (2 * stride) != 0
            seg, k = seg[keep], k[keep]
        s = (k / steps[seg])[:, None]
        bad = ~config_free(a[seg] + s * (b[seg] - a[seg]))
        alive[np.unique(seg[bad])] = False
    return alive


def path_free(config_free: ConfigFree, waypoints: ArrayLike, lever: FloatArray, resolution: float) -> NDArray[np.bool_]:
    """Bool (k - 1,): whether each segment of a joint path (k, 6) is free."""
    w = np.asarray(waypoints, dtype=float)
    if len(w) < 2:
        return np.ones(0, dtype=bool)
    return segments_free(config_free, w[:-1], w[1:], lever, resolution)


def path_time(model: ArmModel, waypoints: ArrayLike) -> float:
    """Sum of the rest-to-rest move times (s) of a joint path's segments."""
    w = np.asarray(waypoints, dtype=float)
    return float(move_time(model, w[:-1], w[1:]).sum()) if len(w) > 1 else 0.0


def lift_route(model: ArmModel, tcp: FloatArray, route: FloatArray, q_start: FloatArray,
               q_goal: FloatArray) -> FloatArray:
    """Joint waypoints (m, 6) from q_start through the route's corners to q_goal.

    Each interior corner of the tool-point route (k, 3) takes the orientation slerped
    between the start's and the goal's tool orientations by arc length and the IK branch
    quickest to reach from the previous waypoint; a corner without a solution is left out.
    """
    if len(route) <= 2:
        return np.vstack([q_start, q_goal])
    ends = tcp_poses(model, np.vstack([q_start, q_goal]), tcp)
    arc = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(route, axis=0), axis=1))])
    frac = arc / arc[-1] if arc[-1] > 0 else np.linspace(0.0, 1.0, len(route))
    rot = Slerp([0.0, 1.0], Rotation.from_matrix(ends[:, :3, :3]))(frac[1:-1]).as_matrix()
    poses = np.tile(np.eye(4), (len(rot), 1, 1))
    poses[:, :3, :3], poses[:, :3, 3] = rot, route[1:-1]
    ik = ik_tool(model, poses, tcp)
    out, prev = [q_start], q_start
    for i in range(len(poses)):
        if not ik.valid[i].any():
            continue
        cost = np.where(ik.valid[i], move_time(model, prev, np.nan_to_num(ik.q[i])), np.inf)
        prev = ik.q[i, int(np.argmin(cost))]
        out.append(prev)
    out.append(q_goal)
    return np.vstack(out)


@dataclass
class Effort:
    """The effort bound of one query: subgoal rounds and seconds; counts what was spent."""

    max_rounds: int = 60
    max_seconds: float = 2.0
    rounds: int = 0
    started: float = field(default_factory=time.perf_counter)

    def spent(self) -> bool:
        """Whether the bound is reached."""
        return self.rounds >= self.max_rounds or time.perf_counter() - self.started > self.max_seconds


@dataclass
class Lifter:
    """Subgoal proposal and evaluation for one arm, tool and validity test.

    tcp: (4, 4) the tool's TCP in the flange frame; config_free / motion_free: the
    configuration and segment tests (a `MotionChecker` for sound paths); home: (6,) a
    safe retract configuration tried as a detour; rng: random subgoals' generator."""

    model: ArmModel
    tcp: FloatArray
    config_free: ConfigFree
    motion_free: SegmentsFree
    home: FloatArray | None = None
    rng: np.random.Generator = field(default_factory=lambda: np.random.default_rng(0))
    random_per_round: int = 24
    max_depth: int = 4
    subgoals_tried: int = 0

    def free_segments(self, a: ArrayLike, b: ArrayLike) -> NDArray[np.bool_]:
        """Bool (n,): segments a -> b free (`motion_free`)."""
        return self.motion_free(np.atleast_2d(a), np.atleast_2d(b))

    def propose(self, a: FloatArray, b: FloatArray, round_index: int) -> FloatArray:
        """Candidate subgoals (n, 6) for the segment a -> b, within the limits."""
        m = self.model
        mid = (a + b) / 2.0
        cands = []
        if round_index == 0:
            ends = tcp_poses(m, np.vstack([a, b]), self.tcp)
            pm = ends[:, :3, 3].mean(axis=0)
            toward = -np.array([pm[0] - m.base[0, 3], pm[1] - m.base[1, 3], 0.0])
            toward /= max(np.linalg.norm(toward), 1e-9)
            dirs = [np.array([0.0, 0.0, 1.0]), toward, -ends[0, :3, 2], -ends[1, :3, 2]]
            rot = Slerp([0.0, 1.0], Rotation.from_matrix(ends[:, :3, :3]))([0.5]).as_matrix()[0]
            poses = []
            for d in dirs:
                for dist in RETREAT_DISTANCES:
                    p = np.eye(4)
                    p[:3, :3], p[:3, 3] = rot, pm + dist * d
                    poses.append(p)
            ik = ik_tool(m, np.asarray(poses), self.tcp)
            q, found = choose_nearest(m, ik, mid)
            cands.append(q[found])
            for j in (0, 1, 2):
                for step in DETOUR_STEPS:
                    c = mid.copy()
                    c[j] += step
                    cands.append(c[None])
            if self.home is not None:
                cands.append(np.asarray(self.home, dtype=float)[None])
        spread = 0.08 * (1 + round_index) * (m.upper - m.lower)
        cands.append(mid + self.rng.normal(size=(self.random_per_round, m.dof)) * spread)
        c = np.vstack(cands)
        c = np.clip(c, m.lower, m.upper)
        return c[self.config_free(c)]

    def connect(self, a: FloatArray, b: FloatArray, effort: Effort, depth: int = 0) -> list[FloatArray] | None:
        """Waypoints after a up to b (b last) of a free joint path, or None within the effort."""
        if self.free_segments(a, b)[0]:
            return [b]
        round_index = 0
        while not effort.spent() and depth < self.max_depth:
            effort.rounds += 1
            c = self.propose(a, b, round_index)
            round_index += 1
            if len(c) == 0:
                continue
            self.subgoals_tried += len(c)
            cost = move_time(self.model, a, c) + move_time(self.model, c, b)
            order = np.argsort(cost, kind="stable")
            c, cost = c[order], cost[order]
            fa = np.zeros(len(c), dtype=bool)
            fb = np.zeros(len(c), dtype=bool)
            for lo in range(0, len(c), CHUNK):
                part = c[lo:lo + CHUNK]
                n = len(part)
                ok = self.free_segments(np.vstack([np.broadcast_to(a, part.shape), part]),
                                        np.vstack([part, np.broadcast_to(b, part.shape)]))
                fa[lo:lo + n], fb[lo:lo + n] = ok[:n], ok[n:]
                both = np.flatnonzero(fa[lo:lo + n] & fb[lo:lo + n])
                if len(both):
                    return [c[lo + both[0]], b]
            # one half free: replan the other half through the best such subgoal
            half = np.flatnonzero(fa | fb)
            for k in half[:2]:
                if fa[k]:
                    rest = self.connect(c[k], b, effort, depth + 1)
                    if rest is not None:
                        return [c[k], *rest]
                else:
                    head = self.connect(a, c[k], effort, depth + 1)
                    if head is not None:
                        return [*head, b]
            if depth > 0:
                return None
        return None

    def repair(self, waypoints: FloatArray, effort: Effort) -> FloatArray | None:
        """The joint path (k, 6) with every colliding segment replanned through subgoals,
        or None if the effort is spent first."""
        w = np.asarray(waypoints, dtype=float)
        free = self.free_segments(w[:-1], w[1:])
        out = [w[0]]
        for i in range(len(w) - 1):
            if free[i]:
                out.append(w[i + 1])
                continue
            piece = self.connect(w[i], w[i + 1], effort)
            if piece is None:
                return None
            out.extend(piece)
        return np.vstack(out)
