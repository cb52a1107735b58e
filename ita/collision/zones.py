"""Zones of the cell's space, and the arms' bodies in them: the geometry of two arms'
interference zones (the claims are the Plan Executive's: ita.executive.zones).

The space over the floor is cut into cubic zones (:class:`ZoneGrid`, side ``cell``, from
the floor up to ``z_high``).  An arm's body (:class:`ArmBody`) is its collision tubes from
its own kinematics and URDF (ita.kinematics.link_segments) and the held tools' tubes
(ita.collision.arm.tool_tubes, tool_tube) on its flange, each grown by half of :data:`MARGIN_M`
(:meth:`ZoneGrid.near_tubes`).  A zone is taken when its centre is within a tube's
radius plus the zone's half-diagonal, so when two arms' zone sets do not meet no point
lies within the grown radius of both: their tubes are at least MARGIN_M apart, in 3-D.
A body point outside the grid is taken at the grid's nearest point (distances only
shrink: never too few zones).

Without a body model (an arm known only by its base and tool point) a body is the
segment base -> tool seen from above, thickened by :attr:`ZoneGrid.radius`, and holds
every zone of the columns it touches (:meth:`ZoneGrid.at_rest`); a move from tool point
p to q sweeps the triangle (base, p, q) (:meth:`ZoneGrid.swept`).

The seen-from-above polyline (``body(q)``: base, joints, flange, the tool's point) remains
for where a tool is and how far an arm reaches from its base axis.  :class:`Revolved` is
the ground an arm folded on its base holds whatever its base joint (its tubes turned
about its base axis): the allocation keeps the other arm's bodies clear of it
(ita.sequence.allocate).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable, Iterable, Sequence

import numpy as np
from numba import njit

from ita.collision.arm import tool_tube, tool_tubes
from ita.kinematics import ArmModel, frame_segments, link_frames
from ita.workcell.model import ToolSpec

__all__ = ["CELL_M", "MARGIN_M", "RADIUS_M", "RETREAT_M", "TOOL_REACH_M", "Z_HIGH_M", "ArmBody", "Revolved",
           "ZoneGrid", "Zones", "arm_body", "folded_configuration", "retreat_point", "segment_distance"]

#: without a body model, the arm's half-width plus clearance seen from above (m): a T3's
#: forearm and wrist are about 0.2 m across, a tool 0.2 m; with 0.1 m to spare
RADIUS_M = 0.25
#: with body models, the least gap kept between two arms' collision tubes (m)
MARGIN_M = 0.05
#: zone size (m)
CELL_M = 0.1
#: the zones' top (m above the floor)
Z_HIGH_M = 4.0
#: the step of a :class:`Revolved` field and of the points sampled along a tube (m)
FIELD_STEP_M = 0.02
#: a retreating arm folds its tool back to this distance from its base axis (m)
RETREAT_M = 0.5

#: how far a held tool reaches beyond the flange along its axis (m): the longest tool point
TOOL_REACH_M = 0.3

Point = tuple[float, float]  # world x, y (m)
#: a set of zones: bit ``z`` set for zone ``z`` (a Python int: unions, meets and tests are
#: a few machine words each, however many zones)
Zones = int


def _bits(mask: np.ndarray) -> Zones:
    return int.from_bytes(np.packbits(np.asarray(mask, dtype=np.bool_), bitorder="little").tobytes(), "little")


@dataclass(frozen=True, eq=False)
class ArmBody:
    """An arm's body: ``body(q)`` the polyline seen from above (configurations ``(n, 6)``
    -> ``(n, 9, 2)`` world x, y of the base, each link's origin, the flange and a point
    ``tool_reach`` beyond it along the tool axis); ``tubes(q)`` its collision tubes and
    the held tools' (``(n, T, 2, 3)`` world segment ends) and ``radii`` ``(T,)`` theirs
    grown by half the margin."""

    model: ArmModel
    tool_ends: np.ndarray              # (k, 2, 3) the tools' tubes in the flange frame
    tool_radii: np.ndarray             # (k,)
    margin: float = MARGIN_M
    tool_reach: float = TOOL_REACH_M

    def __call__(self, q: np.ndarray) -> np.ndarray:
        frames = link_frames(self.model, np.atleast_2d(q))
        tip = frames[:, -1, :3, 3] + self.tool_reach * frames[:, -1, :3, 2]
        return np.concatenate([frames[:, :, :2, 3], tip[:, None, :2]], axis=1)

    @property
    def radii(self) -> np.ndarray:
        return np.concatenate([np.asarray(self.model.tube_radii, dtype=float), self.tool_radii]) + self.margin / 2

    def tubes(self, q: np.ndarray) -> np.ndarray:
        frames = link_frames(self.model, np.atleast_2d(q))
        flange = frames[:, -1]
        # (matmul, not einsum: the same products, several times faster on these small axes)
        held = np.matmul(self.tool_ends, np.swapaxes(flange[:, None, :3, :3], -1, -2)) + flange[:, None, None, :3, 3]
        return np.concatenate([frame_segments(self.model, frames), held], axis=1)


def arm_body(model: ArmModel, tools: Sequence[ToolSpec] = (), margin: float = MARGIN_M,
             tool_reach: float = TOOL_REACH_M) -> ArmBody:
    """The arm's body from its own kinematics and collision tubes, holding any of
    ``tools`` (all at once, whichever it holds is inside: a contact probe's holder and
    shaft, another tool's one tube enclosing its body box; twins once; none: a tube of
    radius 0.1 m out to ``tool_reach`` along the flange axis)."""
    ends: list[np.ndarray] = []
    radii: list[float] = []
    for tool in tools:
        shapes = zip(*tool_tubes(tool)) if tool.probe_shape() is not None else [tool_tube(tool)]
        for e, r in shapes:
            if not any(np.allclose(e, f) and float(r) == g for f, g in zip(ends, radii)):
                ends.append(np.asarray(e, dtype=float))
                radii.append(float(r))
    if not ends:
        ends, radii = [np.array([[0.0, 0.0, 0.0], [0.0, 0.0, tool_reach]])], [0.1]
    return ArmBody(model, np.asarray(ends, dtype=float), np.asarray(radii, dtype=float), margin, tool_reach)


@dataclass(frozen=True)
class Revolved:
    """The ground an arm folded on its base holds, whatever its base joint: its tubes turned
    about its base axis.  ``field[i, j]`` is, at distance ``i * step`` from the axis and
    height ``j * step``, the least distance to a tube's surface (the distance to a turned
    tube is the distance in that half-plane to its axis points, less its radius);
    :meth:`clearance` of points, a lower bound (less the field's half-diagonal)."""

    axis: Point
    step: float
    field: np.ndarray

    @classmethod
    def of(cls, body: ArmBody, fold: np.ndarray, base: Point, z_high: float = Z_HIGH_M,
           step: float = FIELD_STEP_M) -> "Revolved":
        tubes = body.tubes(np.asarray(fold, dtype=float)[None])[0]      # (T, 2, 3)
        pts, rad = _along(tubes, body.radii, step / 2)                  # the sampling's slack: step / 4
        rho = np.hypot(pts[:, 0] - base[0], pts[:, 1] - base[1])
        reach = float(np.max(rho + rad)) + 1.5
        R = np.arange(0.0, reach + step, step)
        Z = np.arange(0.0, z_high + step, step)
        field = np.full((len(R), len(Z)), np.inf)
        for k in range(0, len(pts), 64):
            d = np.hypot(R[:, None, None] - rho[None, None, k:k + 64], Z[None, :, None] - pts[None, None, k:k + 64, 2])
            field = np.minimum(field, (d - rad[None, None, k:k + 64]).min(axis=2))
        return cls((float(base[0]), float(base[1])), step, field - step / 4)

    def clearance(self, points: np.ndarray) -> np.ndarray:
        """``(m,)``: at least how far each point ``(m, 3)`` is from the folded arm's tubes."""
        P = np.asarray(points, dtype=float).reshape(-1, 3)
        rho = np.hypot(P[:, 0] - self.axis[0], P[:, 1] - self.axis[1])
        i = np.rint(rho / self.step).astype(np.int64)
        j = np.clip(np.rint(P[:, 2] / self.step).astype(np.int64), 0, self.field.shape[1] - 1)
        far = i >= self.field.shape[0]
        out = np.where(far, np.inf, self.field[np.minimum(i, self.field.shape[0] - 1), j])
        # out of the field's heights: the nearest row is a bound only less the height beyond it
        beyond = np.maximum(0.0, np.maximum(-P[:, 2], P[:, 2] - (self.field.shape[1] - 1) * self.step))
        return np.asarray(out - self.step * math.sqrt(0.5) - beyond)

    def bands(self, margin: float, band_m: float = 0.2) -> list[tuple[float, float, float]]:
        """The ground as upright cylinders about the axis, one per height band of ``band_m``:
        ``(z_low, z_high, radius)``, each holding every point of its band whose
        :meth:`clearance` is ``margin`` or less (bands holding none left out)."""
        rows_per = max(1, int(round(band_m / self.step)))
        near = (self.field - self.step * math.sqrt(0.5)) <= margin            # (R, Z)
        out = []
        for j0 in range(0, near.shape[1], rows_per):
            inside = np.nonzero(near[:, j0:j0 + rows_per].any(axis=1))[0]
            if len(inside):
                z0 = max(0.0, (j0 - 0.5) * self.step)
                z1 = (min(j0 + rows_per, near.shape[1]) - 0.5) * self.step
                out.append((z0, z1, float(inside.max() + 1) * self.step))
        return out

    def clear_of(self, body: ArmBody, q: np.ndarray, gap: float) -> np.ndarray:
        """``(n,)``: whether the arm ``body`` at each configuration ``(n, 6)`` keeps every
        tube more than ``gap`` beyond its radius from the folded arm."""
        pts, rad = _along(body.tubes(np.atleast_2d(q)), body.radii, self.step / 2)     # (n, P, 3), (P,)
        n, P = pts.shape[:2]
        room = self.clearance(pts.reshape(-1, 3)).reshape(n, P) - self.step / 4      # between the samples
        return np.asarray(np.all(room > rad[None, :] + gap, axis=1))


def _along(tubes: np.ndarray, radii: np.ndarray, spacing: float) -> tuple[np.ndarray, np.ndarray]:
    """Points along each tube's axis (``(n, T, 2, 3)``, or ``(T, 2, 3)`` for one pose) at
    most ``spacing`` apart (a tube's length is its own at every pose: rigid), and each
    point's tube radius: ``(n, P, 3)`` (or ``(P, 3)``) and ``(P,)``."""
    one = tubes.ndim == 3
    X = tubes[None] if one else tubes
    length = np.linalg.norm(X[0, :, 1] - X[0, :, 0], axis=1)
    counts = np.maximum(2, np.ceil(length / spacing).astype(np.int64) + 1)
    t = np.concatenate([np.linspace(0.0, 1.0, c) for c in counts])
    which = np.repeat(np.arange(X.shape[1]), counts)
    pts = X[:, which, 0] + t[None, :, None] * (X[:, which, 1] - X[:, which, 0])
    return (pts[0] if one else pts), np.asarray(radii, dtype=float)[which]


def folded_configuration(model: ArmModel, lower: Sequence[float], upper: Sequence[float],
                         body: Callable[[np.ndarray], np.ndarray] | None = None,
                         above_m: float = 0.75, behind_m: float | None = None) -> tuple[np.ndarray, float]:
    """The configuration (base joint 0) that keeps the arm's body nearest its base axis seen
    from above, every link and the tool above ``above_m`` (clear of its pedestal): the
    pose a retreating arm folds to, its base joint kept.  Returns it and how far (m) the
    body then reaches from the base axis.  A search over shoulder, elbow and wrist pitch
    within the joint limits.  behind_m: when given, only folds whose body stays within
    that distance behind the base (against the way the base joint points, seen from
    above): an arm standing near a fence folds forward, away from it."""
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
    fit = heights > above_m
    if behind_m is not None:
        forward = np.asarray(model.base, dtype=float)[:2, 0]          # the base joint at 0 points along x
        ahead = ((xy - xy[:, :1]) @ (forward / np.linalg.norm(forward))).min(axis=1)
        fit &= ahead >= -behind_m
    k = int(np.argmin(np.where(fit, extent, np.inf)))
    return Q[k], float(extent[k])


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
    """Cubic zones of side ``cell`` (m) over the rectangle ``low``..``high`` seen from above,
    from the floor up to ``z_high``; zone (i, j, k) is numbered ``(i * ny + j) * nz + k``
    (the order claims are listed in)."""

    low: Point
    high: Point
    cell: float = CELL_M
    radius: float = RADIUS_M
    z_high: float = Z_HIGH_M

    @classmethod
    def around(cls, points: Iterable[Sequence[float]], margin: float = 0.5, cell: float = CELL_M,
               radius: float = RADIUS_M, z_high: float = Z_HIGH_M) -> "ZoneGrid":
        """A grid over the points (bases and targets, world x, y) with a margin."""
        xy = np.asarray([(float(p[0]), float(p[1])) for p in points])
        lo, hi = xy.min(axis=0) - margin - radius, xy.max(axis=0) + margin + radius
        return cls((float(lo[0]), float(lo[1])), (float(hi[0]), float(hi[1])), cell, radius, z_high)

    @property
    def shape(self) -> tuple[int, int]:
        """Zones along x and y (seen from above)."""
        return (max(1, math.ceil((self.high[0] - self.low[0]) / self.cell)),
                max(1, math.ceil((self.high[1] - self.low[1]) / self.cell)))

    @property
    def apart_m(self) -> float:
        """Tubes farther apart than this (m, a zone's full diagonal) never share a zone."""
        return 2.0 * self.cell * math.sqrt(0.75)

    @property
    def levels(self) -> int:
        """Zones up from the floor."""
        return max(1, math.ceil(self.z_high / self.cell))

    def _columns(self, mask: np.ndarray) -> Zones:
        """Every zone of the columns (seen from above) ``mask`` marks."""
        return _bits(np.repeat(np.asarray(mask, dtype=np.bool_), self.levels))

    def near_tubes(self, tubes: np.ndarray, radii: np.ndarray) -> Zones:
        """Zones any point of which lies within its tube's radius of a tube (``(..., T, 2,
        3)`` world segment ends, ``radii`` ``(T,)``), in 3-D."""
        X = np.asarray(tubes, dtype=np.float64)
        T = X.shape[-3]
        ends = X.reshape(-1, 2, 3)
        a = np.ascontiguousarray(ends[:, 0])
        b = np.ascontiguousarray(ends[:, 1])
        reach = np.ascontiguousarray(np.tile(np.asarray(radii, dtype=np.float64), len(ends) // T)) \
            + self.cell * math.sqrt(0.75)
        nx, ny = self.shape
        out = np.zeros(nx * ny * self.levels, dtype=np.bool_)
        _mark_tubes(a, b, self.low[0], self.low[1], self.high[0], self.high[1], self.cell, nx, ny, self.levels,
                    self.z_high, reach, out)
        return _bits(out)

    def tubes_meet(self, tubes: np.ndarray, radii: np.ndarray, zones: Zones) -> bool:
        """Whether ``near_tubes(tubes, radii) & zones`` (the same test, cell by cell) without
        marking every zone near the tubes: only the cells of `zones` are tried, a segment
        far from all of them is passed over, and the first hit ends it."""
        if not zones:
            return False
        X = np.asarray(tubes, dtype=np.float64)
        T = X.shape[-3]
        ends = X.reshape(-1, 2, 3)
        nx, ny = self.shape
        n = nx * ny * self.levels
        raw = np.frombuffer(zones.to_bytes((n + 7) // 8, "little"), dtype=np.uint8)
        mask = np.unpackbits(raw, bitorder="little")[:n].astype(np.bool_)
        where = np.flatnonzero(mask)
        i, rest = np.divmod(where, ny * self.levels)
        j, k = np.divmod(rest, self.levels)
        box = np.array([i.min(), i.max(), j.min(), j.max(), k.min(), k.max()], dtype=np.int64)
        reach = np.ascontiguousarray(np.tile(np.asarray(radii, dtype=np.float64), len(ends) // T)) \
            + self.cell * math.sqrt(0.75)
        return bool(_tubes_meet(np.ascontiguousarray(ends[:, 0]), np.ascontiguousarray(ends[:, 1]), self.low[0],
                                self.low[1], self.high[0], self.high[1], self.cell, nx, ny, self.levels, self.z_high,
                                reach, mask, box))

    def _centres(self) -> np.ndarray:
        nx, ny = self.shape
        i, j = np.meshgrid(np.arange(nx), np.arange(ny), indexing="ij")
        return np.stack([self.low[0] + (i + 0.5) * self.cell, self.low[1] + (j + 0.5) * self.cell], -1).reshape(-1, 2)

    def near_polygon(self, corners: Sequence[Sequence[float]]) -> Zones:
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
        return self._columns(dist <= reach)

    def at_rest(self, base: Point, tool: Point) -> Zones:
        """The zones an arm holds at rest with its tool at ``tool``."""
        return self.near_polygon([base, tool])

    def swept(self, base: Point, start: Point, end: Point) -> Zones:
        """The zones an arm sweeps moving its tool from ``start`` to ``end``."""
        return self.near_polygon([base, start, end])



@njit(cache=True)
def _tubes_meet(a, b, low_x, low_y, high_x, high_y, cell, nx, ny, nz, z_high, reach, mask, box):  # pragma: no cover
    """Whether a zone of ``mask`` (within ``box``: its cells' index ranges) has its centre
    within ``reach[s]`` of a segment a[s] -> b[s]: _mark_tubes's test on those cells alone."""
    for s in range(a.shape[0]):
        r = reach[s]
        r2 = r * r
        ax, ay, az, bx, by, bz, i0, i1, j0, j1, k0, k1 = _segment_cells(a, b, s, low_x, low_y, high_x, high_y, cell,
                                                                        nx, ny, nz, z_high, r)
        i0, i1, j0, j1, k0, k1 = max(i0, box[0]), min(i1, box[1]), max(j0, box[2]), min(j1, box[3]), \
            max(k0, box[4]), min(k1, box[5])
        if i0 > i1 or j0 > j1 or k0 > k1:
            continue
        vx, vy, vz = bx - ax, by - ay, bz - az
        vv = vx * vx + vy * vy + vz * vz
        for i in range(i0, i1 + 1):
            cx = low_x + (i + 0.5) * cell
            for j in range(j0, j1 + 1):
                cy = low_y + (j + 0.5) * cell
                base = (i * ny + j) * nz
                for k in range(k0, k1 + 1):
                    if not mask[base + k]:
                        continue
                    if _near(cx, cy, (k + 0.5) * cell, ax, ay, az, vx, vy, vz, vv, r2):
                        return True
    return False


def retreat_point(base: Point, tool: Point, retreat_m: float = RETREAT_M) -> Point:
    """Where a retreating arm folds its tool back to: on its base ray, ``retreat_m`` out."""
    v = np.asarray(tool, dtype=float) - np.asarray(base, dtype=float)
    n = float(np.linalg.norm(v))
    if n <= retreat_m:
        return (float(tool[0]), float(tool[1]))
    p = np.asarray(base, dtype=float) + v * (retreat_m / n)
    return (float(p[0]), float(p[1]))


@njit(cache=True)
def _near(cx, cy, cz, ax, ay, az, vx, vy, vz, vv, r2):  # pragma: no cover
    """Whether the point (cx, cy, cz) is within sqrt(r2) of the segment from a along v."""
    t = 0.0 if vv == 0.0 else ((cx - ax) * vx + (cy - ay) * vy + (cz - az) * vz) / vv
    t = min(1.0, max(0.0, t))
    dx, dy, dz = cx - (ax + t * vx), cy - (ay + t * vy), cz - (az + t * vz)
    return dx * dx + dy * dy + dz * dz <= r2


@njit(cache=True)
def _segment_cells(a, b, s, low_x, low_y, high_x, high_y, cell, nx, ny, nz, z_high, r):  # pragma: no cover
    """Segment a[s] -> b[s] with its ends brought into the grid's box (distances only
    shrink), and the index ranges of the cells within ``r`` of it along each axis."""
    ax = min(max(a[s, 0], low_x), high_x)
    ay = min(max(a[s, 1], low_y), high_y)
    az = min(max(a[s, 2], 0.0), z_high)
    bx = min(max(b[s, 0], low_x), high_x)
    by = min(max(b[s, 1], low_y), high_y)
    bz = min(max(b[s, 2], 0.0), z_high)
    i0 = max(0, int(math.floor((min(ax, bx) - r - low_x) / cell)))
    i1 = min(nx - 1, int(math.floor((max(ax, bx) + r - low_x) / cell)))
    j0 = max(0, int(math.floor((min(ay, by) - r - low_y) / cell)))
    j1 = min(ny - 1, int(math.floor((max(ay, by) + r - low_y) / cell)))
    k0 = max(0, int(math.floor((min(az, bz) - r) / cell)))
    k1 = min(nz - 1, int(math.floor((max(az, bz) + r) / cell)))
    return ax, ay, az, bx, by, bz, i0, i1, j0, j1, k0, k1


@njit(cache=True)
def _mark_tubes(a, b, low_x, low_y, high_x, high_y, cell, nx, ny, nz, z_high, reach, out):  # pragma: no cover
    """Mark the zones whose centre lies within ``reach[s]`` of a segment a[s] -> b[s] in
    3-D, the segment's ends first brought into the grid's box (distances only shrink)."""
    for s in range(a.shape[0]):
        r = reach[s]
        r2 = r * r
        ax, ay, az, bx, by, bz, i0, i1, j0, j1, k0, k1 = _segment_cells(a, b, s, low_x, low_y, high_x, high_y, cell,
                                                                        nx, ny, nz, z_high, r)
        vx, vy, vz = bx - ax, by - ay, bz - az
        vv = vx * vx + vy * vy + vz * vz
        hh = vx * vx + vy * vy
        rw = r * (1.0 + 1e-9) + 1e-12          # the columns' bound, a hair wide of the test's
        for i in range(i0, i1 + 1):
            cx = low_x + (i + 0.5) * cell
            for j in range(j0, j1 + 1):
                cy = low_y + (j + 0.5) * cell
                # the part of the segment within r of this column seen from above: t in
                # [t0, t1]; only heights within r of it there can be within r in 3-D
                px, py = ax - cx, ay - cy
                cc = px * px + py * py - rw * rw
                if hh == 0.0:
                    if cc > 0.0:
                        continue
                    t0, t1 = 0.0, 1.0
                else:
                    bb = px * vx + py * vy
                    disc = bb * bb - hh * cc
                    if disc < 0.0:
                        continue
                    sq = math.sqrt(disc)
                    t0 = max(0.0, (-bb - sq) / hh)
                    t1 = min(1.0, (-bb + sq) / hh)
                    if t0 > t1:
                        continue
                za, zb = az + t0 * vz, az + t1 * vz
                kk0 = max(k0, int(math.floor((min(za, zb) - rw) / cell - 0.5)))
                kk1 = min(k1, int(math.ceil((max(za, zb) + rw) / cell - 0.5)))
                base = (i * ny + j) * nz
                for k in range(kk0, kk1 + 1):
                    if out[base + k]:
                        continue
                    if _near(cx, cy, (k + 0.5) * cell, ax, ay, az, vx, vy, vz, vv, r2):
                        out[base + k] = True
