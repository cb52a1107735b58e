"""Starting tours (convex hull insertion of Golden et al. 1980, cheapest insertion) and neighbour lists.

Convex hull insertion (the seed's method) starts from the hull of the points and inserts
the remaining ones one at a time: each outside node ``k`` is given its cheapest place,
the tour edge ``(i, j)`` minimising ``D[i, k] + D[k, j] - D[i, j]``; of these, the node
whose place makes the largest angle ``i-k-j`` is inserted (the largest-angle rule).
Insertion costs come from the cost matrix, angles from the coordinates.

Without coordinates, :func:`cheapest_insertion` starts from the two nodes farthest apart
and inserts the node of least insertion cost each time.

Compiled with numba (BSD-2-Clause).
"""

from __future__ import annotations

import numpy as np
from numba import njit
from scipy.spatial import ConvexHull, QhullError


def planar(coords: np.ndarray) -> np.ndarray:
    """Project ``(n, d) float`` points (``d >= 2``) on their best-fit plane: ``(n, 2) float``.

    Two-dimensional input is returned as is; higher dimensions go through a principal
    component projection (the two directions of largest spread).
    """
    xy = np.asarray(coords, dtype=np.float64)
    if xy.ndim != 2 or xy.shape[1] < 2:
        raise ValueError(f"coords must be (n, d) with d >= 2, got shape {xy.shape}")
    if xy.shape[1] == 2:
        return xy
    centred = xy - xy.mean(axis=0)
    _, _, vt = np.linalg.svd(centred, full_matrices=False)
    return centred @ vt[:2].T


def hull_cycle(xy: np.ndarray) -> np.ndarray:
    """Indices of the convex hull of ``(n, 2)`` points, counter-clockwise: ``(h,) int``.

    Degenerate sets (fewer than three points, all collinear, all equal) give the two
    extreme points along the direction of largest spread (one point if all coincide).
    """
    n = xy.shape[0]
    if n >= 3:
        try:
            return ConvexHull(xy).vertices.astype(np.int64)
        except QhullError:
            pass
    spread = xy - xy.mean(axis=0)
    axis = np.argmax(np.ptp(xy, axis=0)) if n else 0
    lo, hi = int(np.argmin(spread[:, axis])), int(np.argmax(spread[:, axis]))
    return np.array([lo] if lo == hi else [lo, hi], dtype=np.int64)


def farthest_pair(D: np.ndarray) -> np.ndarray:
    """The two nodes with the largest round trip ``D[i, j] + D[j, i]``: ``(2,) int``."""
    both = D + D.T
    i, j = np.unravel_index(int(np.argmax(both)), both.shape)
    if i == j:  # all costs equal: any two nodes
        return np.array([0, 1], dtype=np.int64)
    return np.array([i, j], dtype=np.int64)


@njit(cache=True)
def _best_place(D, succ, first, u):
    """Cheapest tour edge ``(i, succ[i])`` to insert ``u`` into; returns (cost, i)."""
    best = np.inf
    best_i = -1
    i = first
    while True:
        j = succ[i]
        c = D[i, u] + D[u, j] - D[i, j]
        if c < best:
            best = c
            best_i = i
        i = j
        if i == first:
            break
    return best, best_i


@njit(cache=True)
def _cosine(xy, i, k, j):
    """Cosine of the angle at ``k`` between ``k->i`` and ``k->j`` (-1 if degenerate)."""
    ax = xy[i, 0] - xy[k, 0]
    ay = xy[i, 1] - xy[k, 1]
    bx = xy[j, 0] - xy[k, 0]
    by = xy[j, 1] - xy[k, 1]
    na = np.sqrt(ax * ax + ay * ay)
    nb = np.sqrt(bx * bx + by * by)
    if na == 0.0 or nb == 0.0:
        return -1.0
    return (ax * bx + ay * by) / (na * nb)


@njit(cache=True)
def insertion_tour(D, start_cycle, xy, largest_angle):
    """Grow ``start_cycle`` into a tour of all ``n`` nodes by insertion: ``(n,) int``.

    ``largest_angle``: pick by Golden's largest-angle rule (needs ``xy``, ``(n, 2)``),
    else by least insertion cost.
    """
    n = D.shape[0]
    succ = np.full(n, -1, np.int64)
    inside = np.zeros(n, np.bool_)
    m = start_cycle.shape[0]
    for k in range(m):
        succ[start_cycle[k]] = start_cycle[(k + 1) % m]
        inside[start_cycle[k]] = True
    first = start_cycle[0]
    best_cost = np.full(n, np.inf)
    best_at = np.full(n, -1, np.int64)
    for u in range(n):
        if not inside[u]:
            best_cost[u], best_at[u] = _best_place(D, succ, first, u)
    for _ in range(n - m):
        pick = -1
        score = np.inf
        for u in range(n):
            if inside[u]:
                continue
            if largest_angle:
                s = _cosine(xy, best_at[u], u, succ[best_at[u]])
            else:
                s = best_cost[u]
            if s < score or pick < 0 or (s == score and best_cost[u] < best_cost[pick]):
                score = s
                pick = u
        i = best_at[pick]
        j = succ[i]
        succ[i] = pick
        succ[pick] = j
        inside[pick] = True
        for u in range(n):
            if inside[u]:
                continue
            if best_at[u] == i:  # its best edge (i, j) is gone
                best_cost[u], best_at[u] = _best_place(D, succ, first, u)
            else:
                c = D[i, u] + D[u, pick] - D[i, pick]
                if c < best_cost[u]:
                    best_cost[u] = c
                    best_at[u] = i
                c = D[pick, u] + D[u, j] - D[pick, j]
                if c < best_cost[u]:
                    best_cost[u] = c
                    best_at[u] = pick
    tour = np.empty(n, np.int64)
    v = first
    for k in range(n):
        tour[k] = v
        v = succ[v]
    return tour


def convex_hull_insertion(D: np.ndarray, coords: np.ndarray) -> np.ndarray:
    """Golden et al.'s convex hull insertion with the largest-angle rule.

    ``D``: ``(n, n) float`` costs; ``coords``: ``(n, d) float``, projected to a plane when
    ``d > 2``.  Returns the tour ``(n,) int``.
    """
    xy = planar(coords)
    return insertion_tour(D, hull_cycle(xy), xy, True)


def cheapest_insertion(D: np.ndarray) -> np.ndarray:
    """Cheapest insertion from the farthest pair; for costs without coordinates: ``(n,) int``."""
    return insertion_tour(D, farthest_pair(D), np.zeros((D.shape[0], 2)), False)


def neighbour_lists(D: np.ndarray, k: int) -> np.ndarray:
    """The ``k`` cheapest other nodes of each node, closest first: ``(n, k) int``.

    Asymmetric costs are ranked by ``min(D[i, j], D[j, i])``.
    """
    n = D.shape[0]
    k = max(1, min(k, n - 1))
    key = np.minimum(D, D.T).astype(np.float64, copy=True)
    np.fill_diagonal(key, np.inf)
    if k < n - 1:
        part = np.argpartition(key, k - 1, axis=1)[:, :k]
    else:
        part = np.tile(np.arange(n), (n, 1))
        part = part[~np.eye(n, dtype=bool)].reshape(n, n - 1)
    order = np.argsort(np.take_along_axis(key, part, axis=1), axis=1, kind="stable")
    return np.ascontiguousarray(np.take_along_axis(part, order, axis=1), dtype=np.int64)
