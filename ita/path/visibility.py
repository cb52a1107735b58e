"""The tool point's visibility graph ("visibility lines", Lozano-Perez 1979) and A*.

The first level of the Path Planner moves the end effector as a point among the regions
grown by the tool's size.  The static graph's nodes come from the regions' geometry: every
object's bounding box (in its own frame) offset outward by `radius + clearance`, its 8
corners and 12 edge midpoints (spheres and tubes: points on the axes' tangents).  Nodes
inside a region or beyond the tool's reach are dropped.  An edge joins two nodes whose
segment, swept by a sphere of `radius` (one batched `RegionTree.tubes_hit` call), meets
no solid region.  A query adds its start, its goal and goal-directed nodes (points along
the goal's and the start's approach normals) and searches with A* (Euclidean heuristic,
Euclidean edge lengths).

    graph = build_graph(tree, radius=0.09, clearance=0.05, reach=(centre, 3.0))
    route = graph.route(p_start, p_goal, start_normal=n0, goal_normal=n1)   # (k, 3) or None

Graphs are values: built once per tree state and tool radius and cached by the caller.
"""

from __future__ import annotations

import heapq
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from itertools import product

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ita.collision.shapes import BOX, SPHERE, TUBE
from ita.collision.tree import Regions, RegionTree

FloatArray = NDArray[np.float64]
SegmentsFree = Callable[[FloatArray, FloatArray, float], NDArray[np.bool_]]
APPROACH_STEPS = (0.1, 0.25, 0.45)   # m: goal-directed nodes along a terminal's normal


def box_nodes(centre: ArrayLike, rotation: ArrayLike, half: ArrayLike, offset: float) -> FloatArray:
    """Corners (8) and edge midpoints (12) of a box grown by `offset`: (20, 3) world."""
    signs = np.array([s for s in product((-1.0, 0.0, 1.0), repeat=3) if np.count_nonzero(s) >= 2])
    h = np.asarray(half, dtype=float) + offset
    # a corner sits `offset` out along each axis; an edge midpoint along its two axes
    return np.asarray(centre, dtype=float) + (signs * h) @ np.asarray(rotation, dtype=float).T


def region_nodes(regions: Regions, offset: float) -> FloatArray:
    """Candidate nodes (m, 3) around each region grown by `offset` (see the module doc)."""
    out = []
    for k in range(len(regions)):
        c, rot, half, rad = regions.position[k], regions.rotation[k], regions.half[k], regions.rad[k]
        if regions.kind[k] == BOX:
            out.append(box_nodes(c, rot, half + rad, offset))
        elif regions.kind[k] in (SPHERE, TUBE):
            length = half[0] if regions.kind[k] == TUBE else 0.0
            out.append(box_nodes(c, rot, np.array([length, rad, rad]), offset))
    return np.vstack(out) if out else np.zeros((0, 3))


def object_boxes(tree: RegionTree, names: Sequence[str] | None = None) -> Regions:
    """One box per object of the tree: the bounds of its solid regions in its own frame."""
    boxes = []
    for name in tree.objects if names is None else names:
        rot = tree.pose(name)[:3, :3]
        lo, hi = tree.regions(tree.leaves(name)).bounds_in(rot)
        lo, hi = lo.min(axis=0), hi.max(axis=0)
        boxes.append(Regions.boxes(rot @ ((lo + hi) / 2), rot, hi - lo))
    return Regions.concat(boxes)


def tree_segments_free(tree: RegionTree) -> SegmentsFree:
    """The edge test over a region tree: segments (n, 3), (n, 3) swept by radius -> free (n,)."""
    def free(p0: FloatArray, p1: FloatArray, radius: float) -> NDArray[np.bool_]:
        if len(p0) == 0:
            return np.zeros(0, dtype=bool)
        return ~tree.tubes_hit(p0, p1, radius)
    return free


@dataclass(frozen=True, eq=False)
class VisibilityGraph:
    """Static nodes (m, 3), edge lengths (m, m) (inf: not visible), the tool radius and the
    edge test it was built with."""

    nodes: FloatArray
    lengths: FloatArray
    radius: float
    clearance: float
    segments_free: SegmentsFree

    @property
    def edge_count(self) -> int:
        """Number of (undirected) edges."""
        return int(np.isfinite(self.lengths).sum() - len(self.nodes)) // 2

    def terminal_radius(self, point: FloatArray) -> float:
        """The largest of radius, radius/2, 0 at which `point` itself is free: a start or a
        goal near a surface (an approach pose) still gets edges."""
        for r in (self.radius, self.radius / 2.0, 0.0):
            if self.segments_free(point[None], point[None], r)[0]:
                return r
        return 0.0

    def route(self, start: ArrayLike, goal: ArrayLike, start_normal: ArrayLike | None = None,
              goal_normal: ArrayLike | None = None) -> FloatArray | None:
        """The shortest tool-point route (k, 3), k >= 2, from start to goal through the
        graph, or None when the graph does not connect them.  Normals (3,) add
        goal-directed nodes at APPROACH_STEPS along them (retreat and approach)."""
        s, g = np.asarray(start, dtype=float), np.asarray(goal, dtype=float)
        rs, rg = self.terminal_radius(s), self.terminal_radius(g)
        if self.segments_free(s[None], g[None], min(rs, rg))[0]:
            return np.vstack([s, g])
        extra = [s, g]
        for p, n in ((s, start_normal), (g, goal_normal)):
            if n is not None:
                n = np.asarray(n, dtype=float) / np.linalg.norm(n)
                extra.extend(p + d * n for d in APPROACH_STEPS)
        extra_pts = np.asarray(extra)
        keep: NDArray[np.bool_] | list[bool] = (
            self.segments_free(extra_pts[2:], extra_pts[2:], self.radius) if len(extra_pts) > 2 else [])
        extra_pts = np.vstack([extra_pts[:2], extra_pts[2:][np.asarray(keep, dtype=bool)]])
        radii = np.full(len(extra_pts), self.radius)
        radii[0], radii[1] = rs, rg
        m, e = len(self.nodes), len(extra_pts)
        lengths = np.full((m + e, m + e), np.inf)
        lengths[:m, :m] = self.lengths
        np.fill_diagonal(lengths, 0.0)
        everything = np.vstack([self.nodes, extra_pts])
        ii, jj = np.meshgrid(np.arange(m, m + e), np.arange(m + e), indexing="ij")
        mask = jj < ii
        a, b = ii[mask], jj[mask]
        rad = np.minimum(radii[a - m], np.where(b >= m, radii[np.maximum(b - m, 0)], self.radius))
        ok = np.zeros(len(a), dtype=bool)
        for r in np.unique(rad):
            sel = rad == r
            ok[sel] = self.segments_free(everything[a[sel]], everything[b[sel]], float(r))
        d = np.linalg.norm(everything[a] - everything[b], axis=1)
        lengths[a[ok], b[ok]] = d[ok]
        lengths[b[ok], a[ok]] = d[ok]
        path = astar(everything, lengths, m, m + 1)
        return None if path is None else everything[path]


def build_graph(tree: RegionTree, radius: float, clearance: float = 0.05,
                reach: tuple[ArrayLike, float] | None = None,
                segments_free: SegmentsFree | None = None) -> VisibilityGraph:
    """The static visibility graph of the tree's objects for a tool of `radius` (m).

    reach: (centre (3,), distance): nodes further than distance from centre (the arm's
    shoulder and its reach plus the tool) are dropped.  segments_free: the edge test
    (default: the tree's own `tubes_hit`)."""
    test = segments_free or tree_segments_free(tree)
    nodes = region_nodes(object_boxes(tree), radius + clearance)
    if reach is not None:
        centre, distance = np.asarray(reach[0], dtype=float), float(reach[1])
        nodes = nodes[np.linalg.norm(nodes - centre, axis=1) <= distance]
    if len(nodes):
        nodes = np.unique(np.round(nodes, 6), axis=0)
        nodes = nodes[test(nodes, nodes, radius)]
    m = len(nodes)
    lengths = np.full((m, m), np.inf)
    np.fill_diagonal(lengths, 0.0)
    i, j = np.triu_indices(m, k=1)
    if len(i):
        ok = test(nodes[i], nodes[j], radius)
        d = np.linalg.norm(nodes[i] - nodes[j], axis=1)
        lengths[i[ok], j[ok]] = d[ok]
        lengths[j[ok], i[ok]] = d[ok]
    return VisibilityGraph(nodes, lengths, float(radius), float(clearance), test)


def astar(points: FloatArray, lengths: FloatArray, start: int, goal: int) -> list[int] | None:
    """A* over a dense graph: node indices from start to goal, or None.  Edge costs
    lengths (m, m) (inf: no edge); heuristic the Euclidean distance to the goal."""
    h = np.linalg.norm(points - points[goal], axis=1)
    best = np.full(len(points), np.inf)
    best[start] = 0.0
    parent = np.full(len(points), -1)
    closed = np.zeros(len(points), dtype=bool)
    heap = [(h[start], start)]
    while heap:
        _, u = heapq.heappop(heap)
        if closed[u]:
            continue
        if u == goal:
            path = [u]
            while parent[path[-1]] >= 0:
                path.append(int(parent[path[-1]]))
            return path[::-1]
        closed[u] = True
        row = lengths[u]
        nbr = np.flatnonzero(np.isfinite(row) & ~closed)
        cost = best[u] + row[nbr]
        better = cost < best[nbr]
        for v, c in zip(nbr[better], cost[better]):
            best[v] = c
            parent[v] = u
            heapq.heappush(heap, (c + h[v], int(v)))
    return None
