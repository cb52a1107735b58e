"""Tour improvement for the classic method: 2-opt and Or-opt local search.

Compiled with numba (BSD-2-Clause licence; ``cache=True``, so the compilation of a few
seconds is paid once per installation, not per call).

The tour is an array ``tour`` of node ids with its inverse ``pos`` (``pos[tour[k]] == k``),
read cyclically.  Every change to it is a reversal of a cyclic range of positions
(:func:`reverse`).

Moves (all work for asymmetric costs ``D[i, j] != D[j, i]``; a reversed stretch is
charged its reverse-direction cost):

- 2-opt: remove two edges, reconnect by reversing the path between them.
- Or-opt: move a segment of 1 to 3 nodes elsewhere, in either orientation.

Candidate moves are limited to neighbour lists ``neigh`` (``(n, k) int``: each row the
nearest nodes, closest first) and driven by a queue of "active" nodes (the don't-look
bits: a node leaves the queue when no improving move starts from it, and returns when one
of its tour edges changes).
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True)
def reverse(tour: np.ndarray, pos: np.ndarray, i: int, j: int) -> None:
    """Reverse the cyclic range of positions ``i..j`` (inclusive)."""
    n = tour.shape[0]
    length = (j - i) % n + 1
    a = i
    b = j
    for _ in range(length // 2):
        ta = tour[a]
        tb = tour[b]
        tour[a] = tb
        pos[tb] = a
        tour[b] = ta
        pos[ta] = b
        a += 1
        if a == n:
            a = 0
        b -= 1
        if b < 0:
            b = n - 1


@njit(cache=True)
def push(x: int, queue: np.ndarray, qstate: np.ndarray, inq: np.ndarray) -> None:
    """Mark node ``x`` active (append it to the circular queue unless already there)."""
    if not inq[x]:
        n = queue.shape[0]
        queue[(qstate[0] + qstate[1]) % n] = x
        qstate[1] += 1
        inq[x] = True


@njit(cache=True)
def path_reversal_change(D: np.ndarray, tour: np.ndarray, i: int, j: int) -> float:
    """Cost change of traversing positions ``i..j`` backwards (0 for symmetric ``D``)."""
    n = tour.shape[0]
    total = 0.0
    a = i
    for _ in range((j - i) % n):
        b = a + 1
        if b == n:
            b = 0
        total += D[tour[b], tour[a]] - D[tour[a], tour[b]]
        a = b
    return total


@njit(cache=True)
def try_two_opt(a, D, neigh, tour, pos, sym, eps, queue, qstate, inq):
    """Apply the best improving 2-opt move with a new edge at ``a``; return its delta (0 if none)."""
    n = tour.shape[0]
    best = -eps
    bp1 = -1
    bs1 = -1
    bp2 = -1
    bs2 = -1
    for direction in range(2):
        if direction == 0:
            p1 = a
            s1 = tour[(pos[a] + 1) % n]
        else:
            s1 = a
            p1 = tour[pos[a] - 1]
        removed = D[p1, s1]
        for k in range(neigh.shape[1]):
            c = neigh[a, k]
            g1 = removed - D[a, c]
            if g1 <= eps:
                break
            if direction == 0:
                p2 = c
                s2 = tour[(pos[c] + 1) % n]
            else:
                s2 = c
                p2 = tour[pos[c] - 1]
            if p2 == s1 or s2 == p1:
                continue
            delta = D[p1, p2] + D[s1, s2] - removed - D[p2, s2]
            if not sym:
                if delta >= best:
                    continue
                delta += path_reversal_change(D, tour, pos[s1], pos[p2])
            if delta < best:
                best = delta
                bp1 = p1
                bs1 = s1
                bp2 = p2
                bs2 = s2
    if bp1 < 0:
        return 0.0
    if sym and 2 * ((pos[bp2] - pos[bs1]) % n + 1) > n:
        reverse(tour, pos, pos[bs2], pos[bp1])
    else:
        reverse(tour, pos, pos[bs1], pos[bp2])
    push(bp1, queue, qstate, inq)
    push(bs1, queue, qstate, inq)
    push(bp2, queue, qstate, inq)
    push(bs2, queue, qstate, inq)
    return best


@njit(cache=True)
def move_segment(tour, pos, i, j, x, y, reverse_segment):
    """Move the segment at positions ``i..j`` between adjacent nodes ``x -> y``.

    With ``reverse_segment`` the result reads ``x, tour[j], ..., tour[i], y``, else
    ``x, tour[i], ..., tour[j], y``.  Done with three reversals over the shorter side.
    """
    n = tour.shape[0]
    seg_len = (j - i) % n + 1
    forward_len = (pos[x] - j) % n  # nodes from after the segment up to x
    backward_len = (i - pos[y]) % n  # nodes from y up to before the segment
    if forward_len <= backward_len:
        px = pos[x]
        reverse(tour, pos, i, px)
        reverse(tour, pos, i, (i + forward_len - 1) % n)
        if not reverse_segment:
            reverse(tour, pos, (i + forward_len) % n, px)
    else:
        py = pos[y]
        reverse(tour, pos, py, j)
        reverse(tour, pos, (py + seg_len) % n, j)
        if not reverse_segment:
            reverse(tour, pos, py, (py + seg_len - 1) % n)


@njit(cache=True)
def try_or_opt(a, D, neigh, tour, pos, sym, eps, queue, qstate, inq):
    """Apply the first improving Or-opt move of a 1-3 node segment ending at ``a``; return its delta."""
    n = tour.shape[0]
    for seg_len in range(1, 4):
        if seg_len > n - 3:
            break
        for direction in range(2):
            if direction == 0:  # segment starts at a
                i = pos[a]
                j = (i + seg_len - 1) % n
            else:  # segment ends at a
                j = pos[a]
                i = (j - seg_len + 1) % n
            s1 = tour[i]
            s2 = tour[j]
            p = tour[i - 1]
            nx = tour[(j + 1) % n]
            gain = D[p, s1] + D[s2, nx] - D[p, nx]
            if gain <= eps:
                continue
            internal = 0.0
            if not sym and seg_len > 1:
                internal = path_reversal_change(D, tour, i, j)
            for k in range(neigh.shape[1]):
                c = neigh[a, k]
                if D[a, c] >= gain:
                    break
                if (pos[c] - i) % n < seg_len:
                    continue
                for side in range(2):
                    # side 0: c precedes a (edge c -> a); side 1: a precedes c (a -> c)
                    if side == 0:
                        x = c
                        y = tour[(pos[c] + 1) % n]
                    else:
                        y = c
                        x = tour[pos[c] - 1]
                    if (pos[x] - i) % n < seg_len or (pos[y] - i) % n < seg_len:
                        continue
                    # a next to x means a is the segment's first node after x
                    rev = (side == 0) != (direction == 0)
                    if rev:
                        added = D[x, s2] + D[s1, y] - D[x, y] + internal
                    else:
                        added = D[x, s1] + D[s2, y] - D[x, y]
                    delta = added - gain
                    if delta < -eps:
                        move_segment(tour, pos, i, j, x, y, rev)
                        push(p, queue, qstate, inq)
                        push(nx, queue, qstate, inq)
                        push(s1, queue, qstate, inq)
                        push(s2, queue, qstate, inq)
                        push(x, queue, qstate, inq)
                        push(y, queue, qstate, inq)
                        return delta
    return 0.0


@njit(cache=True)
def local_search(D, neigh, tour, pos, sym, eps, use_two_opt, use_or_opt, queue, qstate, inq):
    """Improve ``tour`` in place until no active node has an improving move; return the cost change."""
    n = tour.shape[0]
    total = 0.0
    while qstate[1] > 0:
        a = queue[qstate[0]]
        qstate[0] = (qstate[0] + 1) % n
        qstate[1] -= 1
        inq[a] = False
        delta = 0.0
        if use_two_opt:
            delta = try_two_opt(a, D, neigh, tour, pos, sym, eps, queue, qstate, inq)
        if delta == 0.0 and use_or_opt:
            delta = try_or_opt(a, D, neigh, tour, pos, sym, eps, queue, qstate, inq)
        if delta != 0.0:
            total += delta
            push(a, queue, qstate, inq)
    return total


@njit(cache=True)
def activate_all(tour, queue, qstate, inq):
    """Put every node in the queue (in tour order)."""
    n = tour.shape[0]
    qstate[0] = 0
    qstate[1] = n
    for k in range(n):
        queue[k] = tour[k]
        inq[tour[k]] = True
