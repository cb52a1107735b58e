"""Compiled (numba) kernels of the region tree: scalar shape tests and the tree walks.

The same tests as `shapes` (which is the numpy reference they are checked against), for
one query at a time, so that a walk stops at the first solid region it meets and skips the
children of every region it misses.  Compiled on first use and cached beside the module
(`cache=True`).  The tree is passed as the flat arrays of `tree.RegionTree.arrays()`:

    kind (N,) int8, pos (N, 3), rot (N, 3, 3), half (N, 3), rad (N,), bound (N,) radius of
    a sphere about pos enclosing the region, solid (N,) bool, obj (N,) int32 (owning
    object or -1), active (N,) bool, child_ptr (N + 1,), child_idx (E,), roots (R,)
"""

from __future__ import annotations

import numpy as np
from numba import njit

SPHERE, TUBE, BOX = 0, 1, 2


@njit(cache=True)
def _seg_point_d2(p0, p1, c):
    dx, dy, dz = p1[0] - p0[0], p1[1] - p0[1], p1[2] - p0[2]
    wx, wy, wz = c[0] - p0[0], c[1] - p0[1], c[2] - p0[2]
    dd = dx * dx + dy * dy + dz * dz
    t = 0.0
    if dd > 0.0:
        t = (wx * dx + wy * dy + wz * dz) / dd
        t = min(max(t, 0.0), 1.0)
    ex, ey, ez = wx - t * dx, wy - t * dy, wz - t * dz
    return ex * ex + ey * ey + ez * ez


@njit(cache=True)
def _seg_seg_d2(p0, p1, q0, q1):
    d1 = p1 - p0
    d2 = q1 - q0
    r = p0 - q0
    a = d1[0] * d1[0] + d1[1] * d1[1] + d1[2] * d1[2]
    e = d2[0] * d2[0] + d2[1] * d2[1] + d2[2] * d2[2]
    f = d2[0] * r[0] + d2[1] * r[1] + d2[2] * r[2]
    eps = 1e-300
    if a <= eps and e <= eps:
        s = 0.0
        t = 0.0
    elif a <= eps:
        s = 0.0
        t = min(max(f / e, 0.0), 1.0)
    else:
        c = d1[0] * r[0] + d1[1] * r[1] + d1[2] * r[2]
        if e <= eps:
            t = 0.0
            s = min(max(-c / a, 0.0), 1.0)
        else:
            b = d1[0] * d2[0] + d1[1] * d2[1] + d1[2] * d2[2]
            denom = a * e - b * b
            s = 0.0
            if denom > 1e-12 * a * e:
                s = min(max((b * f - c * e) / denom, 0.0), 1.0)
            t = (b * s + f) / e
            if t < 0.0:
                t = 0.0
                s = min(max(-c / a, 0.0), 1.0)
            elif t > 1.0:
                t = 1.0
                s = min(max((b - c) / a, 0.0), 1.0)
    gx = r[0] + s * d1[0] - t * d2[0]
    gy = r[1] + s * d1[1] - t * d2[1]
    gz = r[2] + s * d1[2] - t * d2[2]
    return gx * gx + gy * gy + gz * gz


@njit(cache=True)
def _point_cyl_d2(x, y, z, c0, u, half, r):
    """Squared distance of the point (x, y, z) from the solid cylinder of radius r whose
    axis runs half either side of c0 along the unit u (0 inside)."""
    wx, wy, wz = x - c0[0], y - c0[1], z - c0[2]
    h = wx * u[0] + wy * u[1] + wz * u[2]
    rho = np.sqrt(max(wx * wx + wy * wy + wz * wz - h * h, 0.0))
    dx = max(abs(h) - half, 0.0)
    dr = max(rho - r, 0.0)
    return dx * dx + dr * dr


@njit(cache=True)
def _seg_cyl_d(p0, p1, q0, q1, r):
    """A lower bound, within 1e-8 m, of the distance of the segment p0 p1 from the solid,
    flat-ended cylinder of radius r on the axis q0 q1 (0 where they meet).

    The distance from a convex set is convex along the segment: a golden-section search
    brackets its least value, and the segment's length times the last bracket's width
    (the most the distance changes across it) is taken off what was found."""
    ux, uy, uz = q1[0] - q0[0], q1[1] - q0[1], q1[2] - q0[2]
    length = np.sqrt(ux * ux + uy * uy + uz * uz)
    u = np.empty(3)
    c0 = np.empty(3)
    if length > 0.0:
        u[0], u[1], u[2] = ux / length, uy / length, uz / length
    else:
        u[0], u[1], u[2] = 1.0, 0.0, 0.0
    for i in range(3):
        c0[i] = 0.5 * (q0[i] + q1[i])
    half = 0.5 * length
    dx, dy, dz = p1[0] - p0[0], p1[1] - p0[1], p1[2] - p0[2]
    span = np.sqrt(dx * dx + dy * dy + dz * dz)
    best = min(_point_cyl_d2(p0[0], p0[1], p0[2], c0, u, half, r),
               _point_cyl_d2(p1[0], p1[1], p1[2], c0, u, half, r))
    if span == 0.0:
        return np.sqrt(best)
    g = 0.6180339887498949
    lo, hi = 0.0, 1.0
    a = hi - g * (hi - lo)
    b = lo + g * (hi - lo)
    fa = _point_cyl_d2(p0[0] + a * dx, p0[1] + a * dy, p0[2] + a * dz, c0, u, half, r)
    fb = _point_cyl_d2(p0[0] + b * dx, p0[1] + b * dy, p0[2] + b * dz, c0, u, half, r)
    while (hi - lo) * span > 1e-9:
        if fa <= fb:
            hi, b, fb = b, a, fa
            a = hi - g * (hi - lo)
            fa = _point_cyl_d2(p0[0] + a * dx, p0[1] + a * dy, p0[2] + a * dz, c0, u, half, r)
        else:
            lo, a, fa = a, b, fb
            b = lo + g * (hi - lo)
            fb = _point_cyl_d2(p0[0] + b * dx, p0[1] + b * dy, p0[2] + b * dz, c0, u, half, r)
        best = min(best, fa, fb)
    return max(np.sqrt(best) - (hi - lo) * span - 1e-9, 0.0)


@njit(cache=True)
def pair_gap(p0, p1, rp, cp, q0, q1, rq, cq):
    """m: a lower bound of the surface distance of two tubes of a self-collision pair
    (<= 0 where they meet).  A tube (p0, p1, rp) with cp > 0 stands for the flat-ended
    cylinder of radius cp on its axis grown by rp - cp (rp: the radius it is checked
    with); with cp == 0 it is its capsule.  When both are cylinders, the thicker is met
    exactly and the other as its capsule (which encloses it)."""
    if cp == 0.0 and cq == 0.0:
        return np.sqrt(_seg_seg_d2(p0, p1, q0, q1)) - rp - rq
    if cp >= cq:
        return _seg_cyl_d(q0, q1, p0, p1, cp) - (rp - cp) - rq
    return _seg_cyl_d(p0, p1, q0, q1, cq) - (rq - cq) - rp


@njit(cache=True)
def _slab(a, d, h0, h1, h2, grow):
    """Whether a + t d, t in [0, 1], meets the box of half extents h + grow (box frame)."""
    t0, t1 = 0.0, 1.0
    for i in range(3):
        h = (h0 if i == 0 else (h1 if i == 1 else h2)) + grow
        if d[i] == 0.0:
            if abs(a[i]) > h:
                return False
        else:
            inv = 1.0 / d[i]
            u = (-h - a[i]) * inv
            v = (h - a[i]) * inv
            if u > v:
                u, v = v, u
            t0 = max(t0, u)
            t1 = min(t1, v)
            if t0 > t1:
                return False
    return True


@njit(cache=True)
def _seg_box_d2(a, d, h, bp):
    """Squared distance of the segment a + t d (box frame) to the box of half extents h.
    bp: workspace (8,).  Convex piecewise quadratic, minimised piece by piece (exact)."""
    bp[0] = 0.0
    bp[1] = 1.0
    k = 2
    for i in range(3):
        if d[i] != 0.0:
            for sgn in (-1.0, 1.0):
                t = (sgn * h[i] - a[i]) / d[i]
                if 0.0 < t < 1.0:
                    bp[k] = t
                    k += 1
    # insertion sort of bp[:k]
    for i in range(1, k):
        v = bp[i]
        j = i - 1
        while j >= 0 and bp[j] > v:
            bp[j + 1] = bp[j]
            j -= 1
        bp[j + 1] = v
    best = np.inf
    for m in range(k - 1):
        t0, t1 = bp[m], bp[m + 1]
        tm = 0.5 * (t0 + t1)
        num, den = 0.0, 0.0
        for i in range(3):
            x = a[i] + tm * d[i]
            if x > h[i]:
                num -= (a[i] - h[i]) * d[i]
                den += d[i] * d[i]
            elif x < -h[i]:
                num -= (a[i] + h[i]) * d[i]
                den += d[i] * d[i]
        ts = t0
        if den > 0.0:
            ts = min(max(num / den, t0), t1)
        g = 0.0
        for i in range(3):
            x = a[i] + tm * d[i]
            if x > h[i]:
                y = a[i] - h[i] + ts * d[i]
                g += y * y
            elif x < -h[i]:
                y = a[i] + h[i] + ts * d[i]
                g += y * y
        best = min(best, g)
    return best


@njit(cache=True)
def overlaps(p0, p1, r, n, kind, pos, rot, half, rad, bound, a, d, bp):
    """Whether the query tube (p0, p1, r) overlaps region n.  a, d (3,), bp (8,): workspace."""
    reach = r + bound[n]
    if _seg_point_d2(p0, p1, pos[n]) > reach * reach:
        return False
    k = kind[n]
    grow = r + rad[n]
    if k == SPHERE:
        return True  # the bounding sphere is the sphere
    if k == TUBE:
        axis = rot[n, :, 0] * half[n, 0]
        return _seg_seg_d2(p0, p1, pos[n] - axis, pos[n] + axis) <= grow * grow
    for i in range(3):
        a[i] = rot[n, 0, i] * (p0[0] - pos[n, 0]) + rot[n, 1, i] * (p0[1] - pos[n, 1]) + rot[n, 2, i] * (p0[2] - pos[n, 2])
        d[i] = rot[n, 0, i] * (p1[0] - p0[0]) + rot[n, 1, i] * (p1[1] - p0[1]) + rot[n, 2, i] * (p1[2] - p0[2])
    h = half[n]
    if not _slab(a, d, h[0], h[1], h[2], grow):
        return False
    if grow == 0.0 or _slab(a, d, h[0], h[1], h[2], 0.0):
        return True
    return _seg_box_d2(a, d, h, bp) <= grow * grow


@njit(cache=True)
def first_hit(p0, p1, r, kind, pos, rot, half, rad, bound, solid, obj, active, child_ptr, child_idx, roots,
              stack, a, d, bp, skip):
    """Index of the first solid region the query tube meets, or -1 (depth-first walk).
    skip (objects,) bool: objects whose regions do not count."""
    sp = 0
    for i in range(roots.shape[0] - 1, -1, -1):
        stack[sp] = roots[i]
        sp += 1
    while sp > 0:
        sp -= 1
        n = stack[sp]
        if not active[n]:
            continue
        if not overlaps(p0, p1, r, n, kind, pos, rot, half, rad, bound, a, d, bp):
            continue
        if solid[n]:
            if obj[n] >= 0 and obj[n] < skip.shape[0] and skip[obj[n]]:
                continue
            return n
        lo, hi = child_ptr[n], child_ptr[n + 1]
        if sp + (hi - lo) > stack.shape[0]:
            return n  # cannot happen for a tree; conservative if it did
        for j in range(hi - 1, lo - 1, -1):
            stack[sp] = child_idx[j]
            sp += 1
    return -1


@njit(cache=True)
def region_distance(p0, p1, r, n, kind, pos, rot, half, rad, bound, a, d, bp):
    """m: surface distance of the tube (p0, p1, r) from region n, <= 0 where they meet.
    a, d (3,), bp (8,): workspace."""
    k = kind[n]
    if k == SPHERE:
        return np.sqrt(_seg_point_d2(p0, p1, pos[n])) - bound[n] - r
    if k == TUBE:
        axis = rot[n, :, 0] * half[n, 0]
        return np.sqrt(_seg_seg_d2(p0, p1, pos[n] - axis, pos[n] + axis)) - rad[n] - r
    for i in range(3):
        a[i] = rot[n, 0, i] * (p0[0] - pos[n, 0]) + rot[n, 1, i] * (p0[1] - pos[n, 1]) + rot[n, 2, i] * (p0[2] - pos[n, 2])
        d[i] = rot[n, 0, i] * (p1[0] - p0[0]) + rot[n, 1, i] * (p1[1] - p0[1]) + rot[n, 2, i] * (p1[2] - p0[2])
    h = half[n]
    if _slab(a, d, h[0], h[1], h[2], 0.0):
        return -rad[n] - r
    return np.sqrt(_seg_box_d2(a, d, h, bp)) - rad[n] - r


@njit(cache=True)
def tube_clearance(p0, p1, r, cap, kind, pos, rot, half, rad, bound, solid, obj, active, child_ptr, child_idx,
                    roots, stack, a, d, bp, skip):
    """m: the tube's surface distance from the nearest solid region (not of the objects
    skip (objects,)), or cap if none is nearer; <= 0 if it meets one.  A region's
    children lie within it (as for `first_hit`), so a region farther than the nearest
    solid found so far is not entered."""
    best = cap
    sp = 0
    for i in range(roots.shape[0] - 1, -1, -1):
        stack[sp] = roots[i]
        sp += 1
    while sp > 0:
        sp -= 1
        n = stack[sp]
        if not active[n]:
            continue
        if solid[n] and obj[n] >= 0 and obj[n] < skip.shape[0] and skip[obj[n]]:
            continue
        if np.sqrt(_seg_point_d2(p0, p1, pos[n])) - bound[n] - r >= best:
            continue
        g = region_distance(p0, p1, r, n, kind, pos, rot, half, rad, bound, a, d, bp)
        if g >= best:
            continue
        if solid[n]:
            best = g
            if best <= 0.0:
                return best
            continue
        lo, hi = child_ptr[n], child_ptr[n + 1]
        if sp + (hi - lo) > stack.shape[0]:
            return -1.0           # cannot happen for a tree; conservative if it did
        for j in range(hi - 1, lo - 1, -1):
            stack[sp] = child_idx[j]
            sp += 1
    return best


@njit(cache=True)
def query_tree(p0, p1, r, kind, pos, rot, half, rad, bound, solid, obj, active, child_ptr, child_idx, roots):
    """Solid region index (n,) int64 first met by each query tube (p0, p1 (n, 3), r (n,)), or -1."""
    n = p0.shape[0]
    out = np.full(n, -1, dtype=np.int64)
    stack = np.empty(child_idx.shape[0] + roots.shape[0] + 1, dtype=np.int64)
    a, d, bp = np.empty(3), np.empty(3), np.empty(8)
    skip = np.zeros(0, dtype=np.bool_)
    for q in range(n):
        out[q] = first_hit(p0[q], p1[q], r[q], kind, pos, rot, half, rad, bound, solid, obj, active,
                           child_ptr, child_idx, roots, stack, a, d, bp, skip)
    return out


@njit(cache=True)
def query_pairs(p0, p1, r, kind, pos, rot, half, rad, bound, nodes):
    """Bool (n, m): brute-force overlap of query tubes with the listed regions (no walk)."""
    n, m = p0.shape[0], nodes.shape[0]
    out = np.zeros((n, m), dtype=np.bool_)
    a, d, bp = np.empty(3), np.empty(3), np.empty(8)
    for q in range(n):
        for j in range(m):
            out[q, j] = overlaps(p0[q], p1[q], r[q], nodes[j], kind, pos, rot, half, rad, bound, a, d, bp)
    return out


@njit(cache=True)
def check_arm(segs, radii, cyl, world, ignore, pairs, kind, pos, rot, half, rad, bound, solid, obj, active, child_ptr,
              child_idx, roots):
    """Per configuration of segs (n, t, 2, 3): (hit (n,) int8, detail (n,) int64).

    hit: 0 free, 1 a tube meets a solid region (detail: that region), 2 two tubes of a
    self-collision pair meet (detail: the pair's index).  World tubes (world[k]) are
    walked through the tree, not counting the objects ignore[k] (t, objects); pairs (p, 2)
    are tube index pairs checked against each other, a tube with cyl[k] > 0 as the
    flat-ended cylinder of that radius (see `pair_gap`).
    """
    n, t = segs.shape[0], segs.shape[1]
    hit = np.zeros(n, dtype=np.int8)
    detail = np.full(n, -1, dtype=np.int64)
    stack = np.empty(child_idx.shape[0] + roots.shape[0] + 1, dtype=np.int64)
    a, d, bp = np.empty(3), np.empty(3), np.empty(8)
    for c in range(n):
        found = False
        for k in range(t):
            if not world[k]:
                continue
            node = first_hit(segs[c, k, 0], segs[c, k, 1], radii[k], kind, pos, rot, half, rad, bound, solid,
                             obj, active, child_ptr, child_idx, roots, stack, a, d, bp, ignore[k])
            if node >= 0:
                hit[c] = 1
                detail[c] = node
                found = True
                break
        if found:
            continue
        for p in range(pairs.shape[0]):
            i, j = pairs[p, 0], pairs[p, 1]
            reach = radii[i] + radii[j]
            if _seg_seg_d2(segs[c, i, 0], segs[c, i, 1], segs[c, j, 0], segs[c, j, 1]) > reach * reach:
                continue        # the capsules enclose the cylinders
            if (cyl[i] == 0.0 and cyl[j] == 0.0) or pair_gap(segs[c, i, 0], segs[c, i, 1], radii[i], cyl[i],
                                                             segs[c, j, 0], segs[c, j, 1], radii[j], cyl[j]) <= 0.0:
                hit[c] = 2
                detail[c] = p
                break
    return hit, detail
