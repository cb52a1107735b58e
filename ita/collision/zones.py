"""Zones of the cell's floor seen from above, and the arms' bodies in them: the geometry
of two arms' interference zones (the claims are the Plan Executive's: ita.executive.zones).

The floor is cut into square zones (:class:`ZoneGrid`).  An arm's body seen from above is
its links' polyline from its own kinematics (:func:`arm_body`: base, joints, flange, the
tool's point) thickened by the arm's half-width and a clearance (:attr:`ZoneGrid.radius`),
:meth:`ZoneGrid.near_paths`; without a configuration, the segment base -> tool.  At rest it holds the zones that
thick segment touches (:meth:`ZoneGrid.at_rest`); a move from tool point p to q sweeps
the triangle (base, p, q) (the arm turns about its base axis and stretches or folds,
:meth:`ZoneGrid.swept`).  A zone is taken when its centre is within the radius plus its
half-diagonal, so two arms whose zone sets do not meet have no point within the radius
of both: their bodies are at least twice the radius apart.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable, Iterable, Sequence

import numpy as np
from numba import njit

from ita.kinematics import ArmModel, link_frames

__all__ = ["CELL_M", "RADIUS_M", "RETREAT_M", "TOOL_REACH_M", "ZoneGrid", "arm_body", "folded_configuration",
           "path_distance", "retreat_point", "segment_distance"]

#: the arm's half-width plus clearance seen from above (m): a T3's forearm and wrist are
#: about 0.2 m across, a tool 0.2 m; with 0.1 m to spare
RADIUS_M = 0.25
#: zone size (m)
CELL_M = 0.1
#: a retreating arm folds its tool back to this distance from its base axis (m)
RETREAT_M = 0.5

#: how far a held tool reaches beyond the flange along its axis (m): the longest tool point
TOOL_REACH_M = 0.3

Point = tuple[float, float]  # world x, y (m)


def arm_body(model: ArmModel, tool_reach: float = TOOL_REACH_M) -> Callable[[np.ndarray], np.ndarray]:
    """The arm's body seen from above, from its own kinematics: configurations ``(n, 6)``
    -> ``(n, 9, 2)`` world x, y of the base, each link's origin, the flange and a point
    ``tool_reach`` beyond it along the tool axis (a polyline the radius thickens)."""
    def body(q: np.ndarray) -> np.ndarray:
        frames = link_frames(model, np.atleast_2d(q))
        tip = frames[:, -1, :3, 3] + tool_reach * frames[:, -1, :3, 2]
        return np.concatenate([frames[:, :, :2, 3], tip[:, None, :2]], axis=1)

    return body


def folded_configuration(model: ArmModel, lower: Sequence[float], upper: Sequence[float],
                         body: Callable[[np.ndarray], np.ndarray] | None = None,
                         above_m: float = 0.75) -> tuple[np.ndarray, float]:
    """The configuration (base joint 0) that keeps the arm's body nearest its base axis seen
    from above, every link and the tool above ``above_m`` (clear of its pedestal): the
    pose a retreating arm folds to, its base joint kept.  Returns it and how far (m) the
    body then reaches from the base axis.  A search over shoulder, elbow and wrist pitch
    within the joint limits."""
    shape = body if body is not None else arm_body(model)
    g2 = np.linspace(lower[1], upper[1], 31)
    g3 = np.linspace(lower[2], upper[2], 31)
    g5 = np.linspace(lower[4], upper[4], 13)
    Q = np.array([(0.0, a, b, 0.0, d, 0.0) for a in g2 for b in g3 for d in g5])
    frames = link_frames(model, Q)
    tip = frames[:, -1, :3, 3] + TOOL_REACH_M * frames[:, -1, :3, 2]
    heights = np.concatenate([frames[:, 2:, 2, 3], tip[:, None, 2]], axis=1).min(axis=1)
    xy = shape(Q)
    extent = np.linalg.norm(xy - xy[:, :1], axis=2).max(axis=1)
    k = int(np.argmin(np.where(heights > above_m, extent, np.inf)))
    return Q[k], float(extent[k])


def path_distance(point: Sequence[float] | np.ndarray, paths: np.ndarray) -> np.ndarray:
    """``(m,)``: the least distance from ``point`` (x, y) to each polyline of ``paths``
    (``(m, k, 2)``)."""
    P = np.asarray(paths, dtype=float)
    a, b = P[:, :-1], P[:, 1:]
    v = b - a
    vv = np.maximum(np.einsum("mkj,mkj->mk", v, v), 1e-18)
    c = np.asarray(point, dtype=float)[:2]
    t = np.clip(np.einsum("mkj,mkj->mk", c - a, v) / vv, 0.0, 1.0)
    d: np.ndarray = np.linalg.norm(c - (a + t[..., None] * v), axis=2).min(axis=1)
    return d


def segment_distance(a: np.ndarray, b: np.ndarray, c: np.ndarray, d: np.ndarray) -> float:
    """Least distance between segments ab and cd in the plane."""
    def point_segment(p: np.ndarray, s: np.ndarray, e: np.ndarray) -> float:
        v = e - s
        t = 0.0 if not v.any() else float(np.clip(np.dot(p - s, v) / np.dot(v, v), 0.0, 1.0))
        return float(np.linalg.norm(p - (s + t * v)))

    def cross(o: np.ndarray, p: np.ndarray, q: np.ndarray) -> float:
        return float((p[0] - o[0]) * (q[1] - o[1]) - (p[1] - o[1]) * (q[0] - o[0]))

    d1, d2 = cross(c, d, a), cross(c, d, b)
    d3, d4 = cross(a, b, c), cross(a, b, d)
    if ((d1 > 0) != (d2 > 0)) and ((d3 > 0) != (d4 > 0)) and d1 * d2 < 0 and d3 * d4 < 0:
        return 0.0
    return min(point_segment(a, c, d), point_segment(b, c, d), point_segment(c, a, b), point_segment(d, a, b))


@dataclass(frozen=True)
class ZoneGrid:
    """Square zones of side ``cell`` (m) over the rectangle ``low``..``high`` seen from above;
    zone (i, j) is numbered ``i * ny + j`` (the order claims are listed in)."""

    low: Point
    high: Point
    cell: float = CELL_M
    radius: float = RADIUS_M

    @classmethod
    def around(cls, points: Iterable[Sequence[float]], margin: float = 0.5, cell: float = CELL_M,
               radius: float = RADIUS_M) -> "ZoneGrid":
        """A grid over the points (bases and targets, world x, y) with a margin."""
        xy = np.asarray([(float(p[0]), float(p[1])) for p in points])
        lo, hi = xy.min(axis=0) - margin - radius, xy.max(axis=0) + margin + radius
        return cls((float(lo[0]), float(lo[1])), (float(hi[0]), float(hi[1])), cell, radius)

    @property
    def shape(self) -> tuple[int, int]:
        return (max(1, math.ceil((self.high[0] - self.low[0]) / self.cell)),
                max(1, math.ceil((self.high[1] - self.low[1]) / self.cell)))

    def _centres(self) -> np.ndarray:
        nx, ny = self.shape
        i, j = np.meshgrid(np.arange(nx), np.arange(ny), indexing="ij")
        return np.stack([self.low[0] + (i + 0.5) * self.cell, self.low[1] + (j + 0.5) * self.cell], -1).reshape(-1, 2)

    def near_polygon(self, corners: Sequence[Sequence[float]]) -> frozenset[int]:
        """Zones any point of which lies within ``radius`` of the polygon (a point, a
        segment or a triangle, its corners from above): a zone is taken when its centre
        is within ``radius`` plus its half-diagonal (so never too few)."""
        P = np.asarray(corners, dtype=float)[:, :2]
        c = self._centres()
        reach = self.radius + self.cell * math.sqrt(0.5)
        dist = np.full(len(c), np.inf)
        k = len(P)
        for a in range(k):
            s, e = P[a], P[(a + 1) % k]
            v = e - s
            vv = float(np.dot(v, v))
            t = np.zeros(len(c)) if vv == 0 else np.clip((c - s) @ v / vv, 0.0, 1.0)
            dist = np.minimum(dist, np.linalg.norm(c - (s + t[:, None] * v), axis=1))
        if k == 3:                                    # inside the triangle: distance 0
            sign = [np.sign((P[(a + 1) % 3, 0] - P[a, 0]) * (c[:, 1] - P[a, 1])
                            - (P[(a + 1) % 3, 1] - P[a, 1]) * (c[:, 0] - P[a, 0])) for a in range(3)]
            inside = ((sign[0] >= 0) & (sign[1] >= 0) & (sign[2] >= 0)) | ((sign[0] <= 0) & (sign[1] <= 0) & (sign[2] <= 0))
            dist[inside] = 0.0
        return frozenset(int(z) for z in np.flatnonzero(dist <= reach))

    def near_paths(self, paths: np.ndarray, radius: float | None = None) -> frozenset[int]:
        """Zones any point of which lies within ``radius`` (default the grid's) of a segment
        of the polylines ``paths`` (``(m, k, 2)``: m polylines of k points)."""
        P = np.asarray(paths, dtype=np.float64).reshape(-1, np.shape(paths)[-2], 2)
        a = np.ascontiguousarray(P[:, :-1].reshape(-1, 2))
        b = np.ascontiguousarray(P[:, 1:].reshape(-1, 2))
        reach = (self.radius if radius is None else radius) + self.cell * math.sqrt(0.5)
        nx, ny = self.shape
        out = np.zeros(nx * ny, dtype=np.bool_)
        _mark_near(a, b, self.low[0], self.low[1], self.cell, nx, ny, reach, out)
        return frozenset(int(z) for z in np.flatnonzero(out))

    def at_rest(self, base: Point, tool: Point) -> frozenset[int]:
        """The zones an arm holds at rest with its tool at ``tool``."""
        return self.near_polygon([base, tool])

    def swept(self, base: Point, start: Point, end: Point) -> frozenset[int]:
        """The zones an arm sweeps moving its tool from ``start`` to ``end``."""
        return self.near_polygon([base, start, end])



def retreat_point(base: Point, tool: Point, retreat_m: float = RETREAT_M) -> Point:
    """Where a retreating arm folds its tool back to: on its base ray, ``retreat_m`` out."""
    v = np.asarray(tool, dtype=float) - np.asarray(base, dtype=float)
    n = float(np.linalg.norm(v))
    if n <= retreat_m:
        return (float(tool[0]), float(tool[1]))
    p = np.asarray(base, dtype=float) + v * (retreat_m / n)
    return (float(p[0]), float(p[1]))


@njit(cache=True)
def _mark_near(a, b, low_x, low_y, cell, nx, ny, reach, out):  # pragma: no cover - compiled
    """Mark the zones whose centre lies within ``reach`` of a segment a[s] -> b[s]."""
    r2 = reach * reach
    for s in range(a.shape[0]):
        ax, ay, bx, by = a[s, 0], a[s, 1], b[s, 0], b[s, 1]
        i0 = max(0, int(math.floor((min(ax, bx) - reach - low_x) / cell)))
        i1 = min(nx - 1, int(math.floor((max(ax, bx) + reach - low_x) / cell)))
        j0 = max(0, int(math.floor((min(ay, by) - reach - low_y) / cell)))
        j1 = min(ny - 1, int(math.floor((max(ay, by) + reach - low_y) / cell)))
        vx, vy = bx - ax, by - ay
        vv = vx * vx + vy * vy
        for i in range(i0, i1 + 1):
            cx = low_x + (i + 0.5) * cell
            for j in range(j0, j1 + 1):
                cy = low_y + (j + 0.5) * cell
                t = 0.0 if vv == 0.0 else ((cx - ax) * vx + (cy - ay) * vy) / vv
                t = min(1.0, max(0.0, t))
                dx, dy = cx - (ax + t * vx), cy - (ay + t * vy)
                if dx * dx + dy * dy <= r2:
                    out[i * ny + j] = True
