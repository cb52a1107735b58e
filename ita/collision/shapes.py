"""Distance and overlap primitives of the region shapes, as pure numpy functions.

A region is one of three shapes, each a frame (position (3,), rotation (3, 3)) and sizes:

    SPHERE  radius `rad`                                   (half and axes unused)
    TUBE    segment position +- half[0] * rotation[:, 0], radius `rad` (a capsule)
    BOX     half extents `half` (3,) along the rotation's columns, rounded by `rad`
            (0 for a plain oriented box)

A query is a tube too: a point is a segment of length 0 and radius 0, a segment has
radius 0, an arm link has its own radius.  Every test below is exact (no tolerance
beyond floating point): a query overlaps a region when the distance from the query's
segment to the region's core (centre point, axis segment or box) is at most the sum of the
radii.  `segment_hits_box` is slab clipping (for radius 0); `segment_box_distance` is the
exact distance from a segment to a solid box (a convex piecewise quadratic in the segment
parameter, minimised piece by piece).

All functions broadcast their leading dimensions, so `f(p0[:, None], p1[:, None], c[None])`
gives an (n, m) table.  Units are whatever the caller uses (the tree uses metres).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

SPHERE, TUBE, BOX = 0, 1, 2
SHAPE_NAMES = {SPHERE: "sphere", TUBE: "tube", BOX: "box"}

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]


def _dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.sum(a * b, axis=-1)


def point_segment_distance(p: ArrayLike, a: ArrayLike, b: ArrayLike) -> FloatArray:
    """Distance (...) from points p (..., 3) to segments a-b (..., 3); a == b allowed."""
    p, a, b = (np.asarray(x, dtype=float) for x in (p, a, b))
    d = b - a
    dd = _dot(d, d)
    with np.errstate(invalid="ignore", divide="ignore"):
        t = np.where(dd > 0.0, _dot(p - a, d) / np.where(dd > 0.0, dd, 1.0), 0.0)
    t = np.clip(t, 0.0, 1.0)
    return np.linalg.norm(p - (a + t[..., None] * d), axis=-1)


def segment_segment_distance(p0: ArrayLike, p1: ArrayLike, q0: ArrayLike, q1: ArrayLike) -> FloatArray:
    """Distance (...) between segments p0-p1 and q0-q1 (..., 3); either may be a point.

    Closest points by clamping the parameters (Ericson, Real-Time Collision Detection 5.1.9).
    """
    p0, p1, q0, q1 = (np.asarray(x, dtype=float) for x in (p0, p1, q0, q1))
    d1, d2, r = p1 - p0, q1 - q0, p0 - q0
    a, e, f = _dot(d1, d1), _dot(d2, d2), _dot(d2, r)
    c, b = _dot(d1, r), _dot(d1, d2)
    eps = 1e-300
    a_ok, e_ok = a > eps, e > eps
    a_s, e_s = np.where(a_ok, a, 1.0), np.where(e_ok, e, 1.0)
    denom = a * e - b * b
    s = np.where(denom > 1e-12 * a_s * e_s, np.clip((b * f - c * e) / np.where(denom > 0, denom, 1.0), 0.0, 1.0), 0.0)
    t = (b * s + f) / e_s
    s = np.where(t < 0.0, np.clip(-c / a_s, 0.0, 1.0), np.where(t > 1.0, np.clip((b - c) / a_s, 0.0, 1.0), s))
    t = np.clip(t, 0.0, 1.0)
    # degenerate segments: a point against a segment (or a point)
    s = np.where(a_ok, s, 0.0)
    t = np.where(a_ok, t, np.clip(f / e_s, 0.0, 1.0))
    s = np.where(e_ok, s, np.clip(-c / a_s, 0.0, 1.0))
    t = np.where(e_ok, t, 0.0)
    s = np.where(a_ok | e_ok, s, 0.0)
    gap = (p0 + s[..., None] * d1) - (q0 + t[..., None] * d2)
    return np.linalg.norm(gap, axis=-1)


def _to_box(p0: np.ndarray, p1: np.ndarray, center: np.ndarray, rotation: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Segment start and direction in the box frame: R^T (p0 - c), R^T (p1 - p0)."""
    a = np.einsum("...ji,...j->...i", rotation, p0 - center)
    d = np.einsum("...ji,...j->...i", rotation, p1 - p0)
    return a, d


def segment_hits_box(p0: ArrayLike, p1: ArrayLike, center: ArrayLike, rotation: ArrayLike,
                     half: ArrayLike) -> BoolArray:
    """Bool (...): whether segments p0-p1 (..., 3) meet solid boxes (centre (..., 3),
    rotation (..., 3, 3), half extents (..., 3)).  Slab clipping; exact."""
    p0, p1, center, rotation, half = (np.asarray(x, dtype=float) for x in (p0, p1, center, rotation, half))
    a, d = _to_box(p0, p1, center, rotation)
    with np.errstate(invalid="ignore", divide="ignore"):
        inv = 1.0 / d
        t1, t2 = (-half - a) * inv, (half - a) * inv
    lo, hi = np.minimum(t1, t2), np.maximum(t1, t2)
    parallel = d == 0.0
    inside = np.abs(a) <= half
    lo = np.where(parallel, np.where(inside, -np.inf, np.inf), lo)
    hi = np.where(parallel, np.where(inside, np.inf, -np.inf), hi)
    t0 = np.maximum(np.max(lo, axis=-1), 0.0)
    t1 = np.minimum(np.min(hi, axis=-1), 1.0)
    return t0 <= t1


def segment_box_distance(p0: ArrayLike, p1: ArrayLike, center: ArrayLike, rotation: ArrayLike,
                         half: ArrayLike) -> FloatArray:
    """Distance (...) from segments p0-p1 (..., 3) to solid boxes; 0 when they meet.

    In the box frame the squared distance of the point a + t d is sum_i max(|x_i| - h_i, 0)^2,
    a convex quadratic between the (at most 6) parameters where a coordinate crosses a face
    plane; the minimum of each piece is found in closed form.  Exact.
    """
    p0, p1, center, rotation, half = (np.asarray(x, dtype=float) for x in (p0, p1, center, rotation, half))
    a, d = _to_box(p0, p1, center, rotation)
    h = np.broadcast_to(half, a.shape)
    with np.errstate(invalid="ignore", divide="ignore"):
        cross = np.concatenate([(-h - a) / d, (h - a) / d], axis=-1)
    cross = np.nan_to_num(cross, nan=0.0, posinf=1.0, neginf=0.0)
    ends = np.broadcast_to(np.array([0.0, 1.0]), cross.shape[:-1] + (2,))
    bps = np.sort(np.clip(np.concatenate([ends, cross], axis=-1), 0.0, 1.0), axis=-1)   # (..., 8)
    t0, t1 = bps[..., :-1], bps[..., 1:]                                                # (..., 7)
    a_, d_, h_ = a[..., None, :], d[..., None, :], h[..., None, :]
    x = a_ + ((t0 + t1) / 2)[..., None] * d_
    s = np.where(x > h_, 1.0, np.where(x < -h_, -1.0, 0.0))
    act = s != 0.0
    e = a_ - s * h_
    num = -np.sum(np.where(act, e * d_, 0.0), axis=-1)
    den = np.sum(np.where(act, d_ * d_, 0.0), axis=-1)
    with np.errstate(invalid="ignore", divide="ignore"):
        ts = np.where(den > 0.0, num / np.where(den > 0.0, den, 1.0), t0)
    ts = np.clip(ts, t0, t1)
    g = np.sum(np.where(act, (e + ts[..., None] * d_) ** 2, 0.0), axis=-1)
    return np.sqrt(np.min(g, axis=-1))


def points_in_spheres(points: ArrayLike, center: ArrayLike, radius: ArrayLike) -> BoolArray:
    """Bool (...): whether points (..., 3) lie in spheres (centre (..., 3), radius (...))."""
    p, c = np.asarray(points, dtype=float), np.asarray(center, dtype=float)
    return np.linalg.norm(p - c, axis=-1) <= np.asarray(radius, dtype=float)


def points_in_tubes(points: ArrayLike, a: ArrayLike, b: ArrayLike, radius: ArrayLike) -> BoolArray:
    """Bool (...): whether points (..., 3) lie in tubes with axis a-b (..., 3) and radius (...)."""
    return point_segment_distance(points, a, b) <= np.asarray(radius, dtype=float)


def points_in_boxes(points: ArrayLike, center: ArrayLike, rotation: ArrayLike, half: ArrayLike) -> BoolArray:
    """Bool (...): whether points (..., 3) lie in boxes (centre, rotation (..., 3, 3), half)."""
    p, c = np.asarray(points, dtype=float), np.asarray(center, dtype=float)
    local = np.einsum("...ji,...j->...i", np.asarray(rotation, dtype=float), p - c)
    return np.all(np.abs(local) <= np.asarray(half, dtype=float), axis=-1)


def tube_axes(position: ArrayLike, rotation: ArrayLike, half: ArrayLike) -> tuple[FloatArray, FloatArray]:
    """Axis ends (..., 3), (..., 3) of tubes stored as frame + half length half[..., 0]."""
    pos, rot, hl = np.asarray(position, dtype=float), np.asarray(rotation, dtype=float), np.asarray(half, dtype=float)
    axis = rot[..., :, 0] * hl[..., 0:1]
    return pos - axis, pos + axis


def query_region_distance(p0: ArrayLike, p1: ArrayLike, kind: ArrayLike, position: ArrayLike,
                          rotation: ArrayLike, half: ArrayLike) -> FloatArray:
    """Distance (...) from query segments p0-p1 to the cores of regions (sphere centre, tube
    axis, box), each region given by kind (...), position (..., 3), rotation (..., 3, 3),
    half (..., 3).  Shapes broadcast; every kind is evaluated and the right one kept."""
    p0, p1 = np.asarray(p0, dtype=float), np.asarray(p1, dtype=float)
    kind = np.asarray(kind)
    pos, rot, half = (np.asarray(x, dtype=float) for x in (position, rotation, half))
    ta, tb = tube_axes(pos, rot, half)
    d_sphere = point_segment_distance(pos, p0, p1)
    d_tube = segment_segment_distance(p0, p1, ta, tb)
    d_box = segment_box_distance(p0, p1, pos, rot, half)
    return np.where(kind == SPHERE, d_sphere, np.where(kind == TUBE, d_tube, d_box))


def queries_hit_regions(p0: ArrayLike, p1: ArrayLike, radius: ArrayLike, kind: ArrayLike, position: ArrayLike,
                        rotation: ArrayLike, half: ArrayLike, rad: ArrayLike) -> BoolArray:
    """Bool (n, m): whether query tubes (p0, p1 (n, 3), radius (n,)) overlap regions (m,).

    Brute force over all pairs: the reference the region tree is tested against.
    """
    p0, p1 = np.atleast_2d(np.asarray(p0, dtype=float)), np.atleast_2d(np.asarray(p1, dtype=float))
    r = np.broadcast_to(np.asarray(radius, dtype=float), p0.shape[:1])
    dist = query_region_distance(p0[:, None], p1[:, None], np.asarray(kind)[None], np.asarray(position)[None],
                                 np.asarray(rotation)[None], np.asarray(half)[None])
    return dist <= r[:, None] + np.asarray(rad, dtype=float)[None]
