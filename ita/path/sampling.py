"""The fallback level: a bidirectional sampling planner (RRT-Connect) in joint space.

When the two levels above (a tool-point route, then subgoals about the joint path) spend
their effort without a free path, the query is not given up: some moves need a large
joint-space swing (another arm branch, the wrist turned over, the arm lifted out of a
pocket and swung round) that no subgoal near the direct joint path leads to.  This level
searches the whole joint space, as Kuffner and LaValle's RRT-Connect (2000):

* two trees, one rooted at the start and one at every goal configuration; each iteration
  samples a configuration uniformly within the joint limits, extends one tree one step
  toward it, then pulls the other tree greedily toward the new node (step after step,
  until it reaches it or is blocked); the trees swap roles every iteration;
* distances are joint differences scaled by each joint's lever arm (`lift.lever_arms`:
  roughly metres of the farthest link point's travel), and a step is at most
  `step` of the scaled joint space's diagonal;
* a node is added only if `config_free` accepts it and `motion_free` (a
  `motion.MotionChecker`) accepts the segment from its parent, so the path found is free
  at every position, not only at sampled ones;
* the random draws come from the given generator only (the planner seeds it per query),
  so a query's answer is reproducible; the effort bound is `max_iterations` (and
  `max_seconds` as a cap of last resort).

The path returned is raw (tree nodes); the planner shortens and times it like any other.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]
ConfigFree = Callable[[FloatArray], NDArray[np.bool_]]
SegmentsFree = Callable[[FloatArray, FloatArray], NDArray[np.bool_]]


@dataclass(frozen=True)
class SamplingResult:
    """path (k, 6) from the start to one of the goals, or None; iterations spent; nodes
    in both trees; seconds spent."""

    path: FloatArray | None
    iterations: int
    nodes: int
    seconds: float


class _Tree:
    """A tree of joint configurations grown by the planner (nodes and parent indices)."""

    def __init__(self, roots: FloatArray, weights: FloatArray) -> None:
        roots = np.atleast_2d(roots)
        self.weights = weights
        self.nodes = np.empty((max(64, 2 * len(roots)), roots.shape[1]))
        self.nodes[:len(roots)] = roots
        self.parents = [-1] * len(roots)
        self.count = len(roots)

    def nearest(self, q: FloatArray) -> tuple[int, float]:
        """Index of the node nearest q (lever-scaled metric) and its distance."""
        d = (((self.nodes[:self.count] - q) * self.weights) ** 2).sum(axis=1)
        i = int(np.argmin(d))
        return i, float(np.sqrt(d[i]))

    def add(self, q: FloatArray, parent: int) -> int:
        """Append q under parent; its index."""
        if self.count == len(self.nodes):
            self.nodes = np.vstack([self.nodes, np.empty_like(self.nodes)])
        self.nodes[self.count] = q
        self.parents.append(parent)
        self.count += 1
        return self.count - 1

    def branch(self, i: int) -> FloatArray:
        """The nodes from i back to its root (i first)."""
        out = []
        while i >= 0:
            out.append(self.nodes[i])
            i = self.parents[i]
        return np.vstack(out)


@dataclass(frozen=True)
class _Space:
    """What the planner needs of the joint space: limits, metric, step and the checks."""

    lower: FloatArray
    upper: FloatArray
    weights: FloatArray
    step: float
    config_free: ConfigFree
    motion_free: SegmentsFree

    def toward(self, tree: _Tree, target: FloatArray) -> tuple[int, FloatArray, bool]:
        """(nearest node, the configuration one step from it toward target, whether that
        is target itself)."""
        near, dist = tree.nearest(target)
        if dist <= self.step:
            return near, target, True
        q = tree.nodes[near] + (target - tree.nodes[near]) * (self.step / dist)
        return near, q, False

    def extend(self, tree: _Tree, target: FloatArray) -> tuple[int, bool]:
        """One step of tree toward target: (new node's index or -1 if blocked, reached)."""
        near, q, reached = self.toward(tree, target)
        if not self.config_free(q[None])[0] or not self.motion_free(tree.nodes[near][None], q[None])[0]:
            return -1, False
        return tree.add(q, near), reached

    def connect(self, tree: _Tree, target: FloatArray, deadline: float) -> int:
        """Steps of tree toward target until it is reached (its node's index) or a step is
        blocked (-1)."""
        while time.perf_counter() < deadline:
            new, reached = self.extend(tree, target)
            if new < 0:
                return -1
            if reached:
                return new
        return -1


def rrt_connect(start: FloatArray, goals: FloatArray, config_free: ConfigFree, motion_free: SegmentsFree,
                lower: FloatArray, upper: FloatArray, lever: FloatArray, rng: np.random.Generator,
                max_iterations: int = 10000, max_seconds: float = 5.0, step: float = 0.1) -> SamplingResult:
    """A free joint path from start (6,) to any of goals (m, 6), both free (see the module
    doc), or None within the effort; step: the longest edge as a fraction of the scaled
    joint space's diagonal."""
    t0 = time.perf_counter()
    deadline = t0 + max_seconds
    lower, upper = np.asarray(lower, dtype=float), np.asarray(upper, dtype=float)
    weights = np.asarray(lever, dtype=float)
    space = _Space(lower, upper, weights, step * float(np.linalg.norm((upper - lower) * weights)),
                   config_free, motion_free)
    trees = [_Tree(np.asarray(start, dtype=float), weights), _Tree(np.asarray(goals, dtype=float), weights)]
    grow = 0                                   # the tree extended toward the sample this iteration
    iterations = 0
    while iterations < max_iterations and time.perf_counter() < deadline:
        iterations += 1
        sample = rng.uniform(lower, upper)
        new, _ = space.extend(trees[grow], sample)
        if new >= 0:
            q = trees[grow].nodes[new]
            met = space.connect(trees[1 - grow], q, deadline)
            if met >= 0:
                ends = (new, met) if grow == 0 else (met, new)
                path = np.vstack([trees[0].branch(ends[0])[::-1], trees[1].branch(ends[1])[1:]])
                return SamplingResult(path, iterations, trees[0].count + trees[1].count, time.perf_counter() - t0)
        grow = 1 - grow
    return SamplingResult(None, iterations, trees[0].count + trees[1].count, time.perf_counter() - t0)
