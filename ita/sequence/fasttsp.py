"""The default ordering: fast-tsp (MIT) on the Sequence Planner's cost matrices.

fast-tsp (a Rust core; Or-opt and Lin-Kernighan style local search, exact Held-Karp up
to :data:`EXACT_NODES` nodes) takes a SYMMETRIC matrix of 16-bit unsigned integers and a
wall-clock budget and returns a closed tour.  :func:`order` puts any problem of
ita.sequence.tour (float costs, maybe asymmetric, maybe an open path) in that form and
reads the answer back:

1. Interchangeable stops are merged: stops with identical rows (and columns) of costs,
   hence zero cost between them (the SLRA takes several measurements from one pose).
   Each merged class is visited at once, in index order, where fast-tsp put its first
   member; exact when the costs obey the triangle inequality.
2. An open path gets a dummy node tied at no cost to its fixed end(s) and at the top
   level to every other node.  Any tour where the dummy is not next to a fixed end has
   an improving 2-opt move as long as that level exceeds every real cost, so the real
   costs keep 65534 of the 65535 levels.
3. An asymmetric matrix goes through Jonker and Volgenant's transform: node i becomes
   the pair (in_i, out_i) joined at no cost, ``out_i - in_j`` costs ``K + c(i, j)`` and
   in-in or out-out pairs the top level (with ``K`` above every real cost, splitting a
   pair does not pay in the usual 2-opt moves; the tour is checked); up to 10 nodes the
   constants are chosen so that fast-tsp's exact solution is exact for the asymmetric
   problem too.  Real costs then get 4096 levels (up to 10 nodes, 1192 to 16384).
4. Costs become integers: a matrix of integers that fits is multiplied by an integer
   (TSPLIB's are solved exactly), any other is scaled so its largest cost takes the top
   level (the bulkhead's motion-time matrices: about 70 us a level).  The tour is costed
   on the float matrix.
5. The tour is read back, checked (a permutation, the pairs and the dummy where they
   belong: :func:`order` returns None otherwise) and put in a canonical form: a closed
   symmetric tour runs towards the smaller of its first node's two neighbours.

Determinism: fast-tsp has no seed, seeds its random numbers from the clock and stops at
a wall-clock deadline, so for more than :data:`EXACT_NODES` nodes two solves of one
matrix may return different tours (nearly always of equal cost: the motion-time
matrices have many exactly equal orders).  Up to :data:`EXACT_NODES` nodes (after
merging, with the dummy or the transform) the answer is exact and repeatable.  A
sequence plan is made once and stored (ita.sequence.store); the runs reuse it.
"""

from __future__ import annotations

import numpy as np

LEVELS = 65535  # fast-tsp's largest distance (16-bit unsigned)
EXACT_NODES = 20  # fast-tsp solves problems of up to this many nodes exactly (Held-Karp)
SECONDS_PER_NODE = 0.001  # budget when none is given: 1 ms a node ...
MIN_SECONDS = 0.05  # ... at least this ...
MAX_SECONDS = 0.9  # ... and at most this (the TSPLIB target is 1 s an instance, overheads included)
ASYM_REAL = 4095  # asymmetric: levels of a real cost ...
ASYM_DUMMY = 8191  # ... of a dummy's barred arc ...
ASYM_JOIN = 8192  # ... and K, added to every arc out_i - in_j


def default_budget(nodes: int) -> float:
    """Seconds fast-tsp is given for a problem of ``nodes`` nodes when no budget is set."""
    return min(MAX_SECONDS, max(MIN_SECONDS, SECONDS_PER_NODE * nodes))


def order(cost: np.ndarray, start: int | None, end: int | None,
          time_budget: float | None = None) -> tuple[int, ...] | None:
    """Order the ``n`` stops of ``cost`` (``(n, n) float``, zero diagonal) with fast-tsp.

    ``start``/``end`` both None: a closed tour (any rotation; a symmetric one in its
    canonical direction); otherwise an open path from ``start`` (if given) to ``end`` (if
    given).  ``time_budget``: fast-tsp's wall-clock seconds (default
    :func:`default_budget` of the solved size).  Returns None when fast-tsp's tour does
    not respect the reduction (never seen; the caller then uses another method).
    """
    import fast_tsp  # slow-ish import, only when ordering

    D = np.asarray(cost, dtype=np.float64)
    symmetric = bool(np.array_equal(D, D.T))
    if not symmetric and np.allclose(D, D.T, rtol=1e-12, atol=0.0):
        symmetric, D = True, np.maximum(D, D.T)  # equal both ways, and so its levels
    classes = merge_interchangeable(D, symmetric, start, end)
    keep = np.array([_leader(c, start, end) for c in classes], dtype=np.int64)
    R = D if len(keep) == D.shape[0] and np.all(keep == np.arange(len(keep))) else D[np.ix_(keep, keep)]
    where = {int(v): k for k, v in enumerate(keep)}
    s = None if start is None else where[start]
    e = None if end is None else where[end]
    reduced = _order_reduced(fast_tsp, R, s, e, symmetric, time_budget)
    if reduced is None:
        return None
    return tuple(v for k in reduced for v in classes[k])


def merge_interchangeable(D: np.ndarray, symmetric: bool, start: int | None,
                          end: int | None) -> list[tuple[int, ...]]:
    """Classes of stops with identical costs to and from every stop, in visiting order.

    Identical rows mean zero cost between the members.  A fixed start leads its class
    and a fixed end closes its own (a class never holds both); classes are listed by
    their smallest member.
    """
    found: dict[bytes | int, list[int]] = {}
    maybe = np.count_nonzero(D == 0, axis=1) > 1  # a twin is at zero cost (besides oneself)
    if maybe.any():
        rows = D[maybe] if symmetric else np.hstack([D[maybe], D.T[maybe]])
        rows = rows + 0.0  # -0.0 -> 0.0, so equal rows have equal bytes
        for i, row in zip(np.flatnonzero(maybe), rows):
            found.setdefault(row.tobytes(), []).append(int(i))
    for i in np.flatnonzero(~maybe):
        found[int(i)] = [int(i)]
    classes: list[tuple[int, ...]] = []
    for members in found.values():
        if start is not None and end is not None and start != end and start in members and end in members:
            members = [v for v in members if v != end]
            classes.append((end,))
        if start is not None and start in members:
            members = [start] + [v for v in members if v != start]
        elif end is not None and end in members:
            members = [v for v in members if v != end] + [end]
        classes.append(tuple(members))
    return sorted(classes, key=min)


def _leader(members: tuple[int, ...], start: int | None, end: int | None) -> int:
    """The stop that stands for a class: the fixed end it holds, else its first."""
    for v in (start, end):
        if v is not None and v in members:
            return v
    return members[0]


def levels(R: np.ndarray, top: int) -> np.ndarray:
    """``R`` (``(m, m) float``) as integers in ``0..top``: ``(m, m) int64``.

    Negative costs are shifted up (every tour and path of the problem has the same number
    of real edges, so a constant does not change the optimum); integer costs that fit
    are multiplied by an integer, so their order is kept exactly; others are scaled so
    the largest takes ``top``.
    """
    X = R
    if X.size and X.min() < 0:
        off = ~np.eye(X.shape[0], dtype=bool)
        X = np.where(off, X - X[off].min(), 0.0)
    high = float(X.max()) if X.size else 0.0
    if high <= 0:
        return np.zeros(X.shape, dtype=np.int64)
    if high <= top and np.array_equal(X, np.rint(X)):
        factor = float(top // int(high))
    else:
        factor = top / high
    out = np.rint(X * factor).astype(np.int64)
    np.fill_diagonal(out, 0)
    return out


def _order_reduced(fast_tsp, R: np.ndarray, s: int | None, e: int | None, symmetric: bool,
                   time_budget: float | None) -> list[int] | None:
    """Order the merged problem: reduced node ids, closed tour or open path s -> e."""
    m = R.shape[0]
    if m == 1:
        return [0]
    if symmetric:
        W, dummy = _symmetric_matrix(R, s, e)
        tour = _solve(fast_tsp, W, time_budget)
        return _read_symmetric(tour, m, dummy, s, e)
    W, dummy = _jonker_volgenant(R, s, e)
    tour = _solve(fast_tsp, W, time_budget)
    return _read_asymmetric(tour, m, dummy, s, e)


def _solve(fast_tsp, W: np.ndarray, time_budget: float | None) -> list[int]:
    """fast-tsp's closed tour of the integer matrix ``W`` (one thread)."""
    if W.shape[0] == 2:
        return [0, 1]
    assert 0 <= W.min() and W.max() <= LEVELS, "levels out of fast-tsp's 16-bit range"
    budget = default_budget(W.shape[0]) if time_budget is None else max(time_budget, 1e-3)
    return [int(v) for v in fast_tsp.find_tour(W.astype(np.uint16), budget, max_threads=1)]


def _symmetric_matrix(R: np.ndarray, s: int | None, e: int | None, top: int = LEVELS) -> tuple[np.ndarray, bool]:
    """The integer matrix (levels up to `top`) of a symmetric problem, with a dummy (last)
    for an open path."""
    m = R.shape[0]
    if s is None and e is None:
        return levels(R, top), False
    W = np.full((m + 1, m + 1), top, dtype=np.int64)
    W[:m, :m] = levels(R, top - 1)
    for v in (s, e):
        if v is not None:
            W[m, v] = W[v, m] = 0
    W[m, m] = 0
    return W, True


def _read_symmetric(tour: list[int], m: int, dummy: bool, s: int | None, e: int | None) -> list[int] | None:
    """The reduced order of a symmetric problem from fast-tsp's tour, or None if broken."""
    if sorted(tour) != list(range(m + dummy)):
        return None
    if not dummy:
        k = tour.index(0)
        tour = tour[k:] + tour[:k]
        if len(tour) > 2 and tour[-1] < tour[1]:
            tour = [tour[0]] + tour[:0:-1]
        return tour
    k = tour.index(m)
    path = tour[k + 1:] + tour[:k]
    if (s is not None and path[0] != s) or (s is None and path[-1] != e):
        path.reverse()
    if (s is not None and path[0] != s) or (e is not None and path[-1] != e):
        return None
    return path


def _jonker_volgenant(R: np.ndarray, s: int | None, e: int | None) -> tuple[np.ndarray, bool]:
    """The symmetric integer matrix of an asymmetric problem (with a dummy for an open path).

    Node ``i`` of the directed problem is ``in_i = i`` and ``out_i = M + i`` (``M`` the
    directed size): ``W[in_i, out_i] = 0``, ``W[out_i, in_j] = K + c(i, j)``, every other
    pair the top level.
    """
    m = R.shape[0]
    dummy = s is not None or e is not None
    M = m + dummy
    if M <= EXACT_NODES // 2:
        # fast-tsp's answer is exact: make every tour that splits a pair, or takes a
        # barred arc, dearer than the best that does not (<= M*K + M*real).  A split tour
        # has at least M + 1 arcs (>= (M + 1)*K) or two top-level pairs (>= 2*LEVELS).
        real = min((2 * LEVELS - M - 1) // (M * M + M), (LEVELS - 1) // (2 * M))  # and K + barred fits
        barred, join = M * real, M * real + 1
    else:
        real, barred, join = ASYM_REAL, ASYM_DUMMY, ASYM_JOIN
    C = np.full((M, M), barred, dtype=np.int64)
    C[:m, :m] = levels(R, real)
    if dummy:  # C[m, j]: dummy -> j (the path's first stop); C[j, m]: j -> dummy (its last)
        C[m, :m] = barred if s is not None else 0
        C[:m, m] = barred if e is not None else 0
        if s is not None:
            C[m, s] = 0
        if e is not None:
            C[e, m] = 0
    np.fill_diagonal(C, 0)
    W = np.full((2 * M, 2 * M), LEVELS, dtype=np.int64)
    W[M:, :M] = join + C  # W[out_i, in_j] = K + C[i, j]
    W[:M, M:] = W[M:, :M].T
    idx = np.arange(M)
    W[idx, M + idx] = W[M + idx, idx] = 0
    W[idx, idx] = W[M + idx, M + idx] = 0
    return W, dummy


def _read_asymmetric(tour: list[int], m: int, dummy: bool, s: int | None, e: int | None) -> list[int] | None:
    """The reduced order of an asymmetric problem from fast-tsp's tour, or None if broken."""
    M = m + dummy
    if sorted(tour) != list(range(2 * M)):
        return None
    k = tour.index(0)
    tour = tour[k:] + tour[:k]
    if tour[1] != M:  # walk in_0 -> out_0 -> in_j -> out_j ...
        tour = [tour[0]] + tour[:0:-1]
    ins, outs = tour[0::2], tour[1::2]
    if any(o != M + i for i, o in zip(ins, outs)):
        return None
    path = list(ins)
    if not dummy:
        return path
    k = path.index(m)
    path = path[k + 1:] + path[:k]
    if (s is not None and path[0] != s) or (e is not None and path[-1] != e):
        return None
    return path
