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

Incremental positions, made sound (`MotionChecker`): along a joint segment a -> b no point
of tube k's axis moves faster than D_k = sum_j |b_j - a_j| R[j, k] metres per unit of the
segment's parameter, R[j, k] bounding tube k's distance from joint j's axis in any
configuration (`sweep_bounds`).  The segment is cut into cells; each cell's centre is
checked with every tube grown by the most its axis can move within half the cell
(h * D_k), so a free cell proves its whole stretch free.  Cells are at most `resolution`
metres of the fastest tube's sweep long; a cell whose grown check fails (but whose centre
is free) is halved, down to `depth` halvings, before the segment is given up.  So a
segment the checker accepts is free at every position, not only at the checked ones.
`segments_free` is the plain sampled test (exact tubes at spaced positions), kept for
re-checks at a stated resolution.

Everything here takes plain callables: `config_free(q (n, 6)) -> bool (n,)`,
`motion_free(a (n, 6), b (n, 6)) -> bool (n,)`.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
from numba import njit
from numpy.typing import ArrayLike, NDArray
from scipy.spatial.transform import Rotation, Slerp

from ita.collision import ArmChecker
from ita.collision.kernels import check_arm
from ita.kinematics import (
    ArmModel,
    choose_nearest,
    ik_tool,
    link_frames,
    move_time,
    tcp_poses,
)

FloatArray = NDArray[np.float64]
ConfigFree = Callable[[FloatArray], NDArray[np.bool_]]
SegmentsFree = Callable[[FloatArray, FloatArray], NDArray[np.bool_]]
RETREAT_DISTANCES = (0.15, 0.3, 0.5)   # m
DETOUR_STEPS = (0.5, -0.5)             # rad on j1, j2, j3
CHUNK = 8                              # subgoals evaluated per batch, quickest first


class ConfigChecker:
    """`config_free` for an ArmModel and its ArmChecker, compiled end to end.

    The same test as ``model.within_limits(q) & ~checker.collides(link_segments(model,
    q))`` (the checker's own compiled kernel over the tree's current arrays), with the
    forward kinematics compiled too, so that one configuration costs microseconds rather
    than the numpy overhead of a batch: what a sampling planner calling it per state needs.
    """

    def __init__(self, model: ArmModel, checker: ArmChecker) -> None:
        if len(checker.radii) != len(model.tube_radii):
            raise ValueError("the checker's tubes are not the model's")
        self.model, self.checker = model, checker
        self._fk = (np.ascontiguousarray(model.base), np.ascontiguousarray(model.origins),
                    np.ascontiguousarray(model.axes), np.ascontiguousarray(model.flange_offset),
                    np.ascontiguousarray(model.tube_links), np.ascontiguousarray(model.tube_ends))
        self._limits = (np.ascontiguousarray(model.lower), np.ascontiguousarray(model.upper))
        self._objects = -1
        self._ignore = np.zeros((0, 0), dtype=np.bool_)

    def ignore(self) -> NDArray[np.bool_]:
        """(t, objects) the mount objects that links 0 and 1 may touch (as ArmChecker)."""
        tree = self.checker.tree
        if tree.object_count != self._objects:
            ignore = np.zeros((len(self.checker.radii), tree.object_count), dtype=np.bool_)
            low = self.checker.tube_links <= 1
            for name in self.checker.mount:
                if name in tree.objects:
                    ignore[low, tree.object_id(name)] = True
            self._ignore, self._objects = ignore, tree.object_count
        return self._ignore

    def __call__(self, q: ArrayLike) -> NDArray[np.bool_]:
        """Bool (n,): configurations q (n, 6) (or (6,)) within the limits and collision-free."""
        q = np.ascontiguousarray(np.atleast_2d(np.asarray(q, dtype=float)))
        c = self.checker
        return _configs_free(q, *self._limits, *self._fk, c.radii, c.world, self.ignore(), c.pairs,
                             *c.tree.arrays())


@njit(cache=True)
def _link_segments(q, base, origins, axes, flange_offset, tube_links, tube_ends, frames, joint, out):
    """Compiled `fk.link_segments` of one configuration q (6,) into out (t, 2, 3);
    frames (dof + 2, 4, 4) and joint (4, 4) are scratch."""
    dof = q.shape[0]
    frames[0] = base
    for j in range(dof):
        kx, ky, kz = axes[j, 0], axes[j, 1], axes[j, 2]
        c, s = np.cos(q[j]), np.sin(q[j])
        v = 1.0 - c
        r00, r01, r02 = c + kx * kx * v, kx * ky * v - kz * s, kx * kz * v + ky * s
        r10, r11, r12 = ky * kx * v + kz * s, c + ky * ky * v, ky * kz * v - kx * s
        r20, r21, r22 = kz * kx * v - ky * s, kz * ky * v + kx * s, c + kz * kz * v
        o = origins[j]
        for r in range(3):
            joint[r, 0] = o[r, 0] * r00 + o[r, 1] * r10 + o[r, 2] * r20
            joint[r, 1] = o[r, 0] * r01 + o[r, 1] * r11 + o[r, 2] * r21
            joint[r, 2] = o[r, 0] * r02 + o[r, 1] * r12 + o[r, 2] * r22
            joint[r, 3] = o[r, 3]
        joint[3, 0], joint[3, 1], joint[3, 2], joint[3, 3] = 0.0, 0.0, 0.0, 1.0
        _mul(frames[j], joint, frames[j + 1])
    _mul(frames[dof], flange_offset, frames[dof + 1])
    for k in range(tube_links.shape[0]):
        f = frames[tube_links[k]]
        for e in range(2):
            for r in range(3):
                out[k, e, r] = (f[r, 0] * tube_ends[k, e, 0] + f[r, 1] * tube_ends[k, e, 1]
                                + f[r, 2] * tube_ends[k, e, 2] + f[r, 3])


@njit(cache=True)
def _mul(a, b, out):
    for r in range(4):
        for k in range(4):
            out[r, k] = a[r, 0] * b[0, k] + a[r, 1] * b[1, k] + a[r, 2] * b[2, k] + a[r, 3] * b[3, k]


@njit(cache=True)
def _configs_free(q, lower, upper, base, origins, axes, flange_offset, tube_links, tube_ends, radii, world,
                  ignore, pairs, kind, pos, rot, half, rad, bound, solid, obj, active, child_ptr, child_idx, roots):
    n, dof = q.shape
    inside = np.ones(n, dtype=np.bool_)
    segs = np.empty((n, tube_links.shape[0], 2, 3))
    frames = np.empty((dof + 2, 4, 4))
    joint = np.empty((4, 4))
    for i in range(n):
        for j in range(dof):
            if q[i, j] < lower[j] - 1e-9 or q[i, j] > upper[j] + 1e-9:
                inside[i] = False
        _link_segments(q[i], base, origins, axes, flange_offset, tube_links, tube_ends, frames, joint, segs[i])
    hit, _ = check_arm(segs, radii, world, ignore, pairs, kind, pos, rot, half, rad, bound, solid, obj,
                       active, child_ptr, child_idx, roots)
    return inside & (hit == 0)


def sweep_bounds(model: ArmModel) -> FloatArray:
    """(dof, t) m/rad: R[j, k] bounds the distance of any point of tube k's axis from joint
    j's axis in every configuration, so no such point moves faster than R[j, k] per radian
    of joint j (0 for joints that do not move the tube's link).

    Exact for a tube on the joint's own child link (its largest distance from the axis);
    otherwise the next joint's (fixed) distance from the axis plus the chain's length from
    that joint's origin to the tube's farthest end."""
    dof = model.dof
    steps = [np.linalg.norm(model.origins[m][:3, 3]) for m in range(dof)]
    steps.append(np.linalg.norm(model.flange_offset[:3, 3]))       # frame dof -> flange
    out = np.zeros((dof, len(model.tube_links)))
    for k, link in enumerate(model.tube_links):
        ends = model.tube_ends[k]
        reach = float(np.linalg.norm(ends, axis=1).max())
        for j in range(min(int(link), dof)):
            axis = model.axes[j]
            if link == j + 1:
                perp = ends - np.outer(ends @ axis, axis)
                out[j, k] = float(np.linalg.norm(perp, axis=1).max())
            else:              # frame j+2's origin is rigid on link j+1; then the chain
                nxt = model.origins[j + 1][:3, 3] if j + 1 < dof else model.flange_offset[:3, 3]
                offset = float(np.linalg.norm(nxt - (nxt @ axis) * axis))
                out[j, k] = offset + float(sum(steps[m] for m in range(j + 2, int(link)))) + reach
    return out


@njit(cache=True)
def _motions_free(a, b, bounds, margin, depth, budget, lower, upper, base, origins, axes, flange_offset, tube_links,
                  tube_ends, radii, world, ignore, pairs, kind, pos, rot, half, rad, bound, solid, obj, active,
                  child_ptr, child_idx, roots):
    """Bool (n,): segments a -> b (n, dof) proven free by grown cells (see `MotionChecker`)."""
    n, dof = a.shape
    t = tube_links.shape[0]
    out = np.zeros(n, dtype=np.bool_)
    segs = np.empty((1, t, 2, 3))
    frames = np.empty((dof + 2, 4, 4))
    joint = np.empty((4, 4))
    q = np.empty(dof)
    speed = np.empty(t)
    grown = np.empty(t)
    centre = np.empty(2 * depth + 4)
    width = np.empty(2 * depth + 4)
    level = np.empty(2 * depth + 4, dtype=np.int64)
    for i in range(n):
        ok = True
        for j in range(dof):
            if (a[i, j] < lower[j] - 1e-9 or a[i, j] > upper[j] + 1e-9
                    or b[i, j] < lower[j] - 1e-9 or b[i, j] > upper[j] + 1e-9):
                ok = False
        if not ok:
            continue
        fastest = 0.0
        for k in range(t):
            speed[k] = 0.0
            for j in range(dof):
                speed[k] += abs(b[i, j] - a[i, j]) * bounds[j, k]
            fastest = max(fastest, speed[k])
        cells = max(1, int(np.ceil(fastest / (2.0 * margin))))
        spare = budget                      # halved cells this segment may still check
        stride = 8
        while stride >= 1 and ok:
            for c in range(0, cells, stride):
                if stride < 8 and c % (2 * stride) == 0:
                    continue
                top = 0
                centre[0], width[0], level[0] = (c + 0.5) / cells, 0.5 / cells, 0
                while top >= 0:
                    s, h, lev = centre[top], width[top], level[top]
                    top -= 1
                    for j in range(dof):
                        q[j] = a[i, j] + s * (b[i, j] - a[i, j])
                    _link_segments(q, base, origins, axes, flange_offset, tube_links, tube_ends, frames, joint,
                                   segs[0])
                    for k in range(t):
                        grown[k] = radii[k] + h * speed[k]
                    hit, _ = check_arm(segs, grown, world, ignore, pairs, kind, pos, rot, half, rad, bound, solid,
                                       obj, active, child_ptr, child_idx, roots)
                    if hit[0] == 0:
                        continue
                    if lev >= depth or spare < 2:
                        ok = False
                        break
                    spare -= 2
                    exact, _ = check_arm(segs, radii, world, ignore, pairs, kind, pos, rot, half, rad, bound,
                                         solid, obj, active, child_ptr, child_idx, roots)
                    if exact[0] != 0:
                        ok = False
                        break
                    for side in (-0.5, 0.5):
                        top += 1
                        centre[top], width[top], level[top] = s + side * h, h / 2.0, lev + 1
                if not ok:
                    break
            stride //= 2
        out[i] = ok
    return out


@njit(cache=True)
def _configs_clear(q, margin, moving, lower, upper, base, origins, axes, flange_offset, tube_links, tube_ends, radii, world,
                   ignore, pairs, kind, pos, rot, half, rad, bound, solid, obj, active, child_ptr, child_idx, roots):
    """Bool (n,): configurations q (n, dof) within the limits and free with every moving
    tube (moving (t,) 1.0, else 0.0) grown by margin."""
    n, dof = q.shape
    t = tube_links.shape[0]
    out = np.zeros(n, dtype=np.bool_)
    segs = np.empty((1, t, 2, 3))
    frames = np.empty((dof + 2, 4, 4))
    joint = np.empty((4, 4))
    grown = radii + margin * moving
    for i in range(n):
        inside = True
        for j in range(dof):
            if q[i, j] < lower[j] - 1e-9 or q[i, j] > upper[j] + 1e-9:
                inside = False
        if not inside:
            continue
        _link_segments(q[i], base, origins, axes, flange_offset, tube_links, tube_ends, frames, joint, segs[0])
        hit, _ = check_arm(segs, grown, world, ignore, pairs, kind, pos, rot, half, rad, bound, solid, obj, active,
                           child_ptr, child_idx, roots)
        out[i] = hit[0] == 0
    return out


class MotionChecker:
    """`motion_free(a (n, 6), b (n, 6)) -> bool (n,)`: joint segments free at every position
    (see the module doc), compiled end to end over a ConfigChecker's arm and tree.

    resolution: m, the longest a cell may be along the fastest tube's sweep (cells are
    checked with tubes grown by up to resolution / 2); depth: halvings of a cell whose
    grown check fails before the segment is refused (the closest approach accepted is
    then resolution / 2 ** (depth + 1)); budget: halved cells checked per segment before
    it is refused (a motion grazing an obstacle over a long stretch would need many)."""

    def __init__(self, config_free: ConfigChecker, resolution: float = 0.02, depth: int = 10,
                 budget: int = 256) -> None:
        if resolution <= 0.0 or depth < 0:
            raise ValueError(f"resolution must be > 0 and depth >= 0, got {resolution}, {depth}")
        self.config_free = config_free
        self.bounds = np.ascontiguousarray(sweep_bounds(config_free.model).astype(float))
        self.resolution, self.depth, self.budget = float(resolution), int(depth), int(budget)
        self.checks = 0

    @property
    def floor(self) -> float:
        """m: the smallest growth a cell is checked with; a motion passing closer to an
        obstacle than this is refused."""
        return self.resolution / 2.0 ** (self.depth + 1)

    def clear(self, q: ArrayLike) -> NDArray[np.bool_]:
        """Bool (n,): configurations q (n, 6) free with every tube a joint moves grown by
        `floor`: those a motion can be proven to start from or end at (a configuration
        closer than that to an obstacle cannot be)."""
        q = np.ascontiguousarray(np.atleast_2d(np.asarray(q, dtype=float)))
        cf = self.config_free
        c = cf.checker
        moving = (self.bounds.sum(axis=0) > 0.0).astype(float)
        return _configs_clear(q, self.floor, moving, *cf._limits, *cf._fk, c.radii, c.world, cf.ignore(), c.pairs,
                              *c.tree.arrays())

    def __call__(self, a: ArrayLike, b: ArrayLike) -> NDArray[np.bool_]:
        """Bool (n,): whether each segment a -> b ((n, 6) or (6,)) is free everywhere."""
        a = np.ascontiguousarray(np.atleast_2d(np.asarray(a, dtype=float)))
        b = np.ascontiguousarray(np.atleast_2d(np.asarray(b, dtype=float)))
        a, b = np.broadcast_arrays(a, b)
        cf = self.config_free
        c = cf.checker
        self.checks += len(a)
        return _motions_free(np.ascontiguousarray(a), np.ascontiguousarray(b), self.bounds,
                             self.resolution / 2.0, self.depth, self.budget, *cf._limits, *cf._fk, c.radii, c.world,
                             cf.ignore(), c.pairs, *c.tree.arrays())


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
