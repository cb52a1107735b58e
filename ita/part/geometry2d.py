"""Plane geometry of the bulkhead layout: rounded rectangles, signed distances, polygons.

Pure numpy functions over arrays (mm, part frame XY).  A rounded rectangle is walked by
arc length `s` from the middle of its bottom edge, counter-clockwise; its polygon has
vertices on the exact curve, so a point sampled on a straight side lies exactly on the
polygon and a point on an arc lies within the chord sag (about 0.03 mm here).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

FloatArray = np.ndarray


@dataclass(frozen=True)
class RoundedRect:
    """An axis-aligned rectangle with rounded corners centred at the origin.

    half_w, half_h: half width (X) and half height (Y), mm; radius: corner radius, mm.
    """

    half_w: float
    half_h: float
    radius: float

    def __post_init__(self) -> None:
        if not 0 < self.radius <= min(self.half_w, self.half_h):
            raise ValueError(f"corner radius {self.radius} must lie in (0, {min(self.half_w, self.half_h)}]")

    def _pieces(self) -> list[tuple[str, float, tuple[float, ...]]]:
        """(type, length, data) of the nine pieces walked from the bottom middle, CCW."""
        a, b, r = self.half_w - self.radius, self.half_h - self.radius, self.radius
        arc = math.pi * r / 2
        return [
            ("line", a, (0.0, -self.half_h, 1.0, 0.0, 0.0, -1.0)),
            ("arc", arc, (a, -b, -math.pi / 2)),
            ("line", 2 * b, (self.half_w, -b, 0.0, 1.0, 1.0, 0.0)),
            ("arc", arc, (a, b, 0.0)),
            ("line", 2 * a, (a, self.half_h, -1.0, 0.0, 0.0, 1.0)),
            ("arc", arc, (-a, b, math.pi / 2)),
            ("line", 2 * b, (-self.half_w, b, 0.0, -1.0, -1.0, 0.0)),
            ("arc", arc, (-a, -b, math.pi)),
            ("line", a, (-a, -self.half_h, 1.0, 0.0, 0.0, -1.0)),
        ]

    @property
    def length(self) -> float:
        """Perimeter, mm."""
        return sum(p[1] for p in self._pieces())

    def breakpoints(self) -> FloatArray:
        """(10,) float: arc lengths where the pieces start and end."""
        return np.concatenate([[0.0], np.cumsum([p[1] for p in self._pieces()])])

    def at(self, s: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray]:
        """Points, outward unit normals and straightness at arc lengths `s`.

        s: (n,) float, taken modulo the perimeter.  Returns (n, 2) points, (n, 2) outward
        normals and (n,) bool, True where the point is on a straight side.
        """
        s = np.mod(np.asarray(s, dtype=float), self.length)
        pts = np.zeros((len(s), 2))
        nrm = np.zeros((len(s), 2))
        straight = np.zeros(len(s), dtype=bool)
        start = 0.0
        for kind, length, data in self._pieces():
            m = (s >= start) & (s <= start + length + 1e-12)
            u = s[m] - start
            if kind == "line":
                x0, y0, tx, ty, nx, ny = data
                pts[m] = np.column_stack([x0 + tx * u, y0 + ty * u])
                nrm[m] = (nx, ny)
                straight[m] = True
            else:
                cx, cy, th0 = data
                th = th0 + u / self.radius
                nrm[m] = np.column_stack([np.cos(th), np.sin(th)])
                pts[m] = np.column_stack([cx, cy]) + self.radius * nrm[m]
                straight[m] = False
            start += length
        return pts, nrm, straight

    def sample_s(self, s0: float, s1: float, step_deg: float = 1.5) -> FloatArray:
        """(k,) float: arc lengths in [s0, s1] for a polygon: ends, piece ends, arc steps."""
        bp = self.breakpoints()
        cuts = [bp]
        arc_len = math.pi * self.radius / 2
        n_arc = max(2, int(math.ceil(90.0 / step_deg)))
        for i, (kind, _, _) in enumerate(self._pieces()):
            if kind == "arc":
                cuts.append(bp[i] + np.linspace(0, arc_len, n_arc + 1))
        grid = np.unique(np.round(np.concatenate(cuts), 9))
        inner = grid[(grid > s0 + 1e-6) & (grid < s1 - 1e-6)]
        return np.concatenate([[s0], inner, [s1]])

    def polygon(self, offset: float = 0.0, step_deg: float = 1.5) -> FloatArray:
        """(n, 2) float: closed CCW polygon (last vertex not repeated), grown by `offset`."""
        s = self.sample_s(0.0, self.length, step_deg)[:-1]
        pts, nrm, _ = self.at(s)
        return pts + offset * nrm

    def sdf(self, p: FloatArray) -> FloatArray:
        """(n,) float: signed distance of (n, 2) points to the curve (negative inside)."""
        q = np.abs(np.asarray(p, dtype=float)) - (
            np.array([self.half_w, self.half_h]) - self.radius
        )
        outside = np.linalg.norm(np.maximum(q, 0.0), axis=1)
        inside = np.minimum(np.max(q, axis=1), 0.0)
        return outside + inside - self.radius


def signed_area(poly: FloatArray) -> float:
    """Signed area of a closed (n, 2) polygon (positive when counter-clockwise)."""
    x, y = poly[:, 0], poly[:, 1]
    return 0.5 * float(np.dot(x, np.roll(y, -1)) - np.dot(np.roll(x, -1), y))


def ccw(poly: FloatArray) -> FloatArray:
    """(n, 2) float: `poly` ordered counter-clockwise."""
    return poly if signed_area(poly) >= 0 else poly[::-1].copy()


def strip_polygon(path: FloatArray, normals: FloatArray, d0: float, d1: float) -> FloatArray:
    """(2n, 2) float: CCW polygon of the band between offsets d0 and d1 along a path.

    path: (n, 2) points; normals: (n, 2) unit normals giving the offset direction.
    """
    a = path + d0 * normals
    b = path + d1 * normals
    return ccw(np.vstack([a, b[::-1]]))


def rect_polygon(start: ArrayLike, end: ArrayLike, width: float, extend: float = 0.0) -> FloatArray:
    """(4, 2) float: CCW rectangle of `width` around the segment start-end, lengthened
    by `extend` at both ends."""
    start, end = np.asarray(start, float), np.asarray(end, float)
    t = (end - start) / np.linalg.norm(end - start)
    n = np.array([-t[1], t[0]])
    a, b = start - extend * t, end + extend * t
    h = width / 2
    return ccw(np.array([a - h * n, b - h * n, b + h * n, a + h * n]))


def circle_polygon(center: FloatArray, radius: float, segments: int) -> FloatArray:
    """(segments, 2) float: CCW regular polygon inscribed in a circle."""
    th = np.linspace(0, 2 * np.pi, segments, endpoint=False)
    return np.column_stack([center[0] + radius * np.cos(th), center[1] + radius * np.sin(th)])


def circle_segments(radius: float, max_sag: float = 0.02, minimum: int = 16) -> int:
    """Vertex count (multiple of 4) of a circle polygon whose chord sag is at most max_sag."""
    if radius <= max_sag:
        return minimum
    n = math.pi / math.acos(1 - max_sag / radius)
    return int(max(minimum, 4 * math.ceil(n / 4)))


def box_clearance(p: FloatArray, box: tuple[float, float, float, float]) -> FloatArray:
    """(n,) float: distance of (n, 2) points inside box (x0, y0, x1, y1) to its sides
    (negative outside)."""
    x0, y0, x1, y1 = box
    return np.min(np.column_stack([p[:, 0] - x0, x1 - p[:, 0], p[:, 1] - y0, y1 - p[:, 1]]), axis=1)


def points_in_polygon(p: FloatArray, poly: FloatArray) -> FloatArray:
    """(n,) bool: whether each of (n, 2) points lies inside the closed (m, 2) polygon
    (crossing-number rule)."""
    x, y = p[:, 0:1], p[:, 1:2]
    a, b = poly, np.roll(poly, -1, axis=0)
    ay, by = a[:, 1][None, :], b[:, 1][None, :]
    crosses = (ay > y) != (by > y)
    with np.errstate(divide="ignore", invalid="ignore"):
        xc = a[:, 0][None, :] + (y - ay) * (b[:, 0] - a[:, 0])[None, :] / (by - ay)
    return (np.count_nonzero(crosses & (x < xc), axis=1) % 2) == 1


def distance_to_polygon(p: FloatArray, poly: FloatArray) -> FloatArray:
    """(n,) float: distance of each of (n, 2) points to the edges of a closed (m, 2) polygon."""
    a, b = poly, np.roll(poly, -1, axis=0)
    ab = b - a
    ap = p[:, None, :] - a[None, :, :]
    t = np.clip(np.einsum("nmk,mk->nm", ap, ab) / np.einsum("mk,mk->m", ab, ab), 0.0, 1.0)
    closest = a[None, :, :] + t[..., None] * ab[None, :, :]
    return np.min(np.linalg.norm(p[:, None, :] - closest, axis=2), axis=1)
