"""Tour improvement: 2-opt and Or-opt local search, and iterated local search (ILS).

Compiled with numba (BSD-2-Clause licence; ``cache=True``, so the compilation of a few
seconds is paid once per installation, not per call).

The tour is an array ``tour`` of node ids with its inverse ``pos`` (``pos[tour[k]] == k``),
read cyclically.  Every change to it is a reversal of a cyclic range of positions
(:func:`reverse`); the reversals made since the last kick are logged, so a rejected kick
is undone by replaying them in reverse order (a reversal is its own inverse).

Moves (all work for asymmetric costs ``D[i, j] != D[j, i]``; a reversed stretch is
charged its reverse-direction cost):

- 2-opt: remove two edges, reconnect by reversing the path between them.
- Or-opt: move a segment of 1 to 3 nodes elsewhere, in either orientation.
- or3 (segment swap): two adjacent segments of any length trade places (pure 3-opt).
- kick: a double bridge (three consecutive segments ``B C D`` become ``D C B``, every
  segment keeping its direction), cut within a window of positions or, now and then,
  next to a node's nearest neighbours.

Iterated local search keeps a kicked tour while it is within ``slack`` of the best one
(record-to-record acceptance) and returns the best.

Candidate moves are limited to neighbour lists ``neigh`` (``(n, k) int``: each row the
nearest nodes, closest first) and driven by a queue of "active" nodes (the don't-look
bits: a node leaves the queue when no improving move starts from it, and returns when one
of its tour edges changes).
"""

from __future__ import annotations

import numpy as np
from numba import njit

LOG_CAPACITY = 1 << 16  # reversals remembered per kick; past that a kick is kept as is


@njit(cache=True)
def next_random(rng: np.ndarray) -> np.uint64:
    """xorshift64* step; ``rng`` is a ``(1,) uint64`` state (non-zero)."""
    x = rng[0]
    x ^= x >> np.uint64(12)
    x ^= x << np.uint64(25)
    x ^= x >> np.uint64(27)
    rng[0] = x
    return x * np.uint64(2685821657736338717)


@njit(cache=True)
def random_below(rng: np.ndarray, bound: int) -> int:
    """A pseudo-random int in ``[0, bound)``."""
    return int(next_random(rng) >> np.uint64(11)) % bound


@njit(cache=True)
def reverse(tour: np.ndarray, pos: np.ndarray, i: int, j: int, log: np.ndarray, nlog: np.ndarray) -> None:
    """Reverse the cyclic range of positions ``i..j`` (inclusive) and log it."""
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
    k = nlog[0]
    if k < log.shape[0]:
        log[k, 0] = i
        log[k, 1] = j
    nlog[0] = k + 1


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
def try_two_opt(a, D, neigh, tour, pos, sym, eps, queue, qstate, inq, log, nlog):
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
        reverse(tour, pos, pos[bs2], pos[bp1], log, nlog)
    else:
        reverse(tour, pos, pos[bs1], pos[bp2], log, nlog)
    push(bp1, queue, qstate, inq)
    push(bs1, queue, qstate, inq)
    push(bp2, queue, qstate, inq)
    push(bs2, queue, qstate, inq)
    return best


@njit(cache=True)
def move_segment(tour, pos, i, j, x, y, reverse_segment, log, nlog):
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
        reverse(tour, pos, i, px, log, nlog)
        reverse(tour, pos, i, (i + forward_len - 1) % n, log, nlog)
        if not reverse_segment:
            reverse(tour, pos, (i + forward_len) % n, px, log, nlog)
    else:
        py = pos[y]
        reverse(tour, pos, py, j, log, nlog)
        reverse(tour, pos, (py + seg_len) % n, j, log, nlog)
        if not reverse_segment:
            reverse(tour, pos, py, (py + seg_len - 1) % n, log, nlog)


@njit(cache=True)
def try_or_opt(a, D, neigh, tour, pos, sym, eps, queue, qstate, inq, log, nlog):
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
                        move_segment(tour, pos, i, j, x, y, rev, log, nlog)
                        push(p, queue, qstate, inq)
                        push(nx, queue, qstate, inq)
                        push(s1, queue, qstate, inq)
                        push(s2, queue, qstate, inq)
                        push(x, queue, qstate, inq)
                        push(y, queue, qstate, inq)
                        return delta
    return 0.0


@njit(cache=True)
def swap_adjacent(tour, pos, i, len1, len2, log, nlog):
    """Swap the segment of ``len1`` positions starting at ``i`` with the ``len2`` after it."""
    n = tour.shape[0]
    last = (i + len1 + len2 - 1) % n
    reverse(tour, pos, i, last, log, nlog)
    reverse(tour, pos, i, (i + len2 - 1) % n, log, nlog)
    reverse(tour, pos, (i + len2) % n, last, log, nlog)


@njit(cache=True)
def try_or3(a, D, neigh, tour, pos, eps, queue, qstate, inq, log, nlog):
    """Apply the first improving segment swap with a new edge at ``a``; return its delta.

    Tour ``a t2..t3 t4..t5 t6`` becomes ``a t4..t5 t2..t3 t6`` (a pure 3-opt move, "or3":
    no segment changes direction).  ``t4`` is a neighbour of ``a``, ``t5`` of ``t2``.
    """
    n = tour.shape[0]
    t1 = a
    i2 = (pos[t1] + 1) % n
    t2 = tour[i2]
    d12 = D[t1, t2]
    for k in range(neigh.shape[1]):
        t4 = neigh[t1, k]
        g1 = d12 - D[t1, t4]
        if g1 <= eps:
            break
        o4 = (pos[t4] - i2) % n
        if o4 == 0 or o4 >= n - 2:
            continue
        t3 = tour[pos[t4] - 1]
        g1 += D[t3, t4]
        for q in range(neigh.shape[1]):
            t5 = neigh[t2, q]
            g2 = g1 - D[t5, t2]
            if g2 <= eps:
                break
            o5 = (pos[t5] - i2) % n
            if o5 < o4 or o5 >= n - 2:
                continue
            t6 = tour[(pos[t5] + 1) % n]
            delta = D[t3, t6] - D[t5, t6] - g2
            if delta < -eps:
                len_b = o4
                len_c = o5 - o4 + 1
                len_a = n - len_b - len_c
                if len_a >= len_b and len_a >= len_c:
                    swap_adjacent(tour, pos, i2, len_b, len_c, log, nlog)
                elif len_b >= len_c:
                    swap_adjacent(tour, pos, pos[t4], len_c, len_a, log, nlog)
                else:
                    swap_adjacent(tour, pos, pos[t6], len_a, len_b, log, nlog)
                for v in (t1, t2, t3, t4, t5, t6):
                    push(v, queue, qstate, inq)
                return delta
    return 0.0


@njit(cache=True)
def local_search(D, neigh, tour, pos, sym, eps, use_two_opt, use_or_opt, use_or3,
                 queue, qstate, inq, log, nlog):
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
            delta = try_two_opt(a, D, neigh, tour, pos, sym, eps, queue, qstate, inq, log, nlog)
        if delta == 0.0 and use_or_opt:
            delta = try_or_opt(a, D, neigh, tour, pos, sym, eps, queue, qstate, inq, log, nlog)
        if delta == 0.0 and use_or3:
            delta = try_or3(a, D, neigh, tour, pos, eps, queue, qstate, inq, log, nlog)
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


@njit(cache=True)
def double_bridge(D, neigh, tour, pos, rng, window, far_every, queue, qstate, inq, log, nlog):
    """Kick: turn three consecutive segments ``B C D`` into ``D C B``; return the cost change.

    The cuts fall within ``window`` positions after a random node or, one time in
    ``far_every`` (0: never), at the positions of three of its neighbours.  Needs
    ``len(tour) >= 5``.
    """
    n = tour.shape[0]
    p0 = random_below(rng, n)
    o1 = 0
    o2 = 0
    o3 = 0
    if far_every > 0 and random_below(rng, far_every) == 0:  # cut next to three of a node's neighbours
        a = tour[p0]
        k = neigh.shape[1]
        for _ in range(8):
            o1 = (pos[neigh[a, random_below(rng, k)]] - p0) % n
            o2 = (pos[neigh[a, random_below(rng, k)]] - p0) % n
            o3 = (pos[neigh[a, random_below(rng, k)]] - p0) % n
            if o1 != o2 and o1 != o3 and o2 != o3 and max(o1, max(o2, o3)) <= n - 2:
                break
            o1 = 0
    if o1 == 0:
        w = min(window, n - 2)
        o1 = 1 + random_below(rng, w)
        o2 = 1 + random_below(rng, w)
        o3 = 1 + random_below(rng, w)
        while o2 == o1:
            o2 = 1 + random_below(rng, w)
        while o3 == o1 or o3 == o2:
            o3 = 1 + random_below(rng, w)
    if o1 > o2:
        o1, o2 = o2, o1
    if o2 > o3:
        o2, o3 = o3, o2
    if o1 > o2:
        o1, o2 = o2, o1
    a = tour[p0]
    b0 = tour[(p0 + 1) % n]
    b1 = tour[(p0 + o1) % n]
    c0 = tour[(p0 + o1 + 1) % n]
    c1 = tour[(p0 + o2) % n]
    d0 = tour[(p0 + o2 + 1) % n]
    d1 = tour[(p0 + o3) % n]
    e = tour[(p0 + o3 + 1) % n]
    delta = (D[a, d0] + D[d1, c0] + D[c1, b0] + D[b1, e]
             - D[a, b0] - D[b1, c0] - D[c1, d0] - D[d1, e])
    len_d = o3 - o2
    len_c = o2 - o1
    reverse(tour, pos, (p0 + 1) % n, (p0 + o3) % n, log, nlog)
    reverse(tour, pos, (p0 + 1) % n, (p0 + len_d) % n, log, nlog)
    reverse(tour, pos, (p0 + len_d + 1) % n, (p0 + len_d + len_c) % n, log, nlog)
    reverse(tour, pos, (p0 + len_d + len_c + 1) % n, (p0 + o3) % n, log, nlog)
    for v in (a, b0, b1, c0, c1, d0, d1, e):
        push(v, queue, qstate, inq)
    return delta


@njit(cache=True)
def iterated_local_search(D, neigh, tour, pos, sym, eps, cost, kicks, window, far_every, slack, rng,
                          queue, qstate, inq, log, nlog):
    """Run ``kicks`` rounds of kick + local search (record-to-record acceptance).

    A round is kept when the tour stays within ``slack`` of the best tour seen; the best
    tour is returned in ``tour``/``pos``.  ``tour`` must be a local optimum of cost
    ``cost``; returns the final cost.
    """
    n = tour.shape[0]
    if n < 8:
        return cost
    best = cost
    best_tour = tour.copy()
    for _ in range(kicks):
        nlog[0] = 0
        delta = double_bridge(D, neigh, tour, pos, rng, window, far_every, queue, qstate, inq, log, nlog)
        delta += local_search(D, neigh, tour, pos, sym, eps, True, True, True, queue, qstate, inq, log, nlog)
        if cost + delta <= best + slack or nlog[0] > log.shape[0]:
            cost += delta
            if cost < best - eps:
                best = cost
                best_tour[:] = tour
        else:
            for k in range(nlog[0] - 1, -1, -1):
                reverse(tour, pos, log[k, 0], log[k, 1], log, nlog)
    if best < cost:
        tour[:] = best_tour
        for k in range(n):
            pos[tour[k]] = k
    return best
