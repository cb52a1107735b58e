"""A repeatable ordering: LKH (Helsgaun's Lin-Kernighan-Helsgaun heuristic, through the
elkai binding) bounded by work, not time, with a fixed seed.

fast-tsp (ita.sequence.fasttsp) seeds from the clock and stops at a wall-clock deadline:
two solves of one matrix can differ, and a busy machine finds worse tours.  LKH given a
SEED and a number of trials (MAX_TRIALS) and of ascent iterations for its candidate sets
(INITIAL_PERIOD) does the same work, and so returns the same tour, on any machine at any
load.

    order(cost, start, end)      # as ita.sequence.fasttsp.order: a closed tour or an open path

The problem is put in LKH's form as fast-tsp's is: interchangeable stops merged
(ita.sequence.fasttsp.merge_interchangeable), costs made integers on a fine scale
(:data:`LEVELS`), an asymmetric matrix given as ATSP (LKH's own transformation), an open
path closed through a dummy stop tied at no cost to its fixed end(s) and at a cost above
every tour to the others.  The tour is read back, checked and put in canonical form.
"""

from __future__ import annotations

import numpy as np

from ita.sequence.fasttsp import (
    _leader,
    _read_symmetric,
    _symmetric_matrix,
    levels,
    merge_interchangeable,
)

__all__ = ["ASYMMETRIC_INITIAL_PERIOD", "ASYMMETRIC_MAX_TRIALS", "ASYMMETRIC_TRIAL_WORK", "CANDIDATES", "INITIAL_PERIOD", "LEVELS", "MAX_TRIALS", "MIN_TRIALS", "SEED", "TRIAL_WORK", "order", "trials"]

#: LKH's work: trials (each a Lin-Kernighan descent from a new tour near the best), as
#: many as TRIAL_WORK / nodes, between MIN_TRIALS and MAX_TRIALS (a trial costs about the
#: same at any size here, while the problem's reading and ascent grow with its square) ...
TRIAL_WORK = 60_000
MIN_TRIALS = 40
MAX_TRIALS = 300
#: ... the subgradient ascent's initial period ...
INITIAL_PERIOD = 50
#: ... and the candidate edges: POPMUSIC's (sub-paths of a tour optimised by 3-opt, from
#: the costs alone, as any matrix has them) rather than alpha-nearness's.  Measured on the
#: 14 TSPLIB instances of ../shared/tsplib with seeds 1 to 5 (70 solves, 2026-11-30):
#: alpha-nearness with 45,000 / 40..100 / period 100 averaged 0.035 % above the optimum,
#: worst 0.48 % (rl1304), slowest 0.83 s; POPMUSIC with these 0.009 %, worst 0.14 %,
#: slowest about 1.0 s.  (Seed 1, the one used, is not chosen by them: it was before.)
CANDIDATES = "CANDIDATE_SET_TYPE = POPMUSIC\nPOPMUSIC_INITIAL_TOUR = NO\n"
#: an asymmetric matrix (LKH's ATSP, POPMUSIC not applicable): alpha-nearness candidates
#: with these, as before
ASYMMETRIC_TRIAL_WORK, ASYMMETRIC_MAX_TRIALS, ASYMMETRIC_INITIAL_PERIOD = 45_000, 100, 100
#: its random numbers' seed: the same tour on every machine
SEED = 1
#: integer levels the largest real cost takes: LKH multiplies each by its PRECISION (100)
#: in a C int, and a tour's dummy ties cost twice the largest (kept far below 2**31)
LEVELS = 100_000


def trials(nodes: int, symmetric: bool = True) -> int:
    """LKH's MAX_TRIALS for a problem of ``nodes`` nodes (the work, not the time, bounds it)."""
    work, most = (TRIAL_WORK, MAX_TRIALS) if symmetric else (ASYMMETRIC_TRIAL_WORK, ASYMMETRIC_MAX_TRIALS)
    return max(MIN_TRIALS, min(most, work // max(nodes, 1)))


def order(cost: np.ndarray, start: int | None, end: int | None) -> tuple[int, ...] | None:
    """Order the ``n`` stops of ``cost`` (``(n, n) float``, zero diagonal) with LKH; as
    :func:`ita.sequence.fasttsp.order`.  None when the tour read back does not respect the
    reduction (the caller then uses another method)."""
    D = np.asarray(cost, dtype=np.float64)
    symmetric = bool(np.array_equal(D, D.T))
    classes = merge_interchangeable(D, symmetric, start, end)
    keep = np.array([_leader(c, start, end) for c in classes], dtype=np.int64)
    R = D[np.ix_(keep, keep)]
    where = {int(v): k for k, v in enumerate(keep)}
    s = None if start is None else where[start]
    e = None if end is None else where[end]
    reduced = _order_reduced(R, s, e, symmetric)
    if reduced is None:
        return None
    return tuple(v for k in reduced for v in classes[k])


def _order_reduced(R: np.ndarray, s: int | None, e: int | None, symmetric: bool) -> list[int] | None:
    m = R.shape[0]
    closed = s is None and e is None
    if m <= 3:
        return _small(R, s, e, closed)
    if symmetric:                       # the same matrix and reading back as fast-tsp's, on LKH's scale
        W, dummy = _symmetric_matrix(R, s, e, _top(R))
        tour = _solve(W, True)
        return None if tour is None else _read_symmetric(tour, m, dummy, s, e)
    W = levels(R, _top(R))
    if not closed:                        # a dummy stop m closes the path: m -> s and e -> m at no cost
        big = 2 * int(W.max()) + 1        # above every real cost: a tour with the dummy elsewhere improves
        X = np.full((m + 1, m + 1), big, dtype=np.int64)
        X[:m, :m] = W
        X[m, m] = 0
        X[m, :m] = 0 if s is None else big
        X[:m, m] = 0 if e is None else big
        if s is not None:
            X[m, s] = 0
        if e is not None:
            X[e, m] = 0
        W = X
    tour = _solve(W, False)
    if tour is None:
        return None
    k = tour.index(0 if closed else m)    # LKH's ATSP tour runs in its own direction
    if closed:
        return tour[k:] + tour[:k]
    path = tour[k + 1:] + tour[:k]
    if (s is not None and path[0] != s) or (e is not None and path[-1] != e):
        return None
    return path


def _top(R: np.ndarray) -> int:
    """The level of the largest cost: integer costs as they are (one above them, for an open
    path's barrier), any other scaled to :data:`LEVELS`."""
    high = float(R.max()) if R.size else 0.0
    if R.size and R.min() >= 0 and 0 < high < LEVELS and np.array_equal(R, np.rint(R)):
        return int(high) + 1
    return LEVELS


def _small(R: np.ndarray, s: int | None, e: int | None, closed: bool) -> list[int]:
    """Up to three stops: every order tried."""
    from itertools import permutations

    best, cost = None, np.inf
    for p in permutations(range(R.shape[0])):
        if (s is not None and p[0] != s) or (e is not None and p[-1] != e):
            continue
        c = sum(R[a, b] for a, b in zip(p, p[1:])) + (R[p[-1], p[0]] if closed else 0.0)
        if c < cost:
            best, cost = list(p), c
    assert best is not None
    return best


def _solve(W: np.ndarray, symmetric: bool) -> list[int] | None:
    """LKH's tour of integer matrix ``W`` (0-based, closed), or None when it is no tour."""
    from elkai import (
        _elkai,  # the LKH binding's extension (its package imports nothing else)
    )

    n = W.shape[0]
    period = INITIAL_PERIOD if symmetric else ASYMMETRIC_INITIAL_PERIOD
    params = (f"RUNS = 1\nSEED = {SEED}\nMAX_TRIALS = {trials(n, symmetric)}\nINITIAL_PERIOD = {period}\n"
              f"{CANDIDATES if symmetric else ''}PROBLEM_FILE = :stdin:\n")
    # the matrix as text (elkai's LKH reads only FULL_MATRIX): each level's digits made once
    digits = np.array([str(v) for v in range(int(W.max()) + 1)], dtype=object)
    problem = (f"TYPE : {'TSP' if symmetric else 'ATSP'}\nDIMENSION : {n}\nEDGE_WEIGHT_TYPE : EXPLICIT\n"
               "EDGE_WEIGHT_FORMAT : FULL_MATRIX\nEDGE_WEIGHT_SECTION\n"
               + "\n".join(map(" ".join, digits[W].tolist())) + "\n")
    tour = [int(i) - 1 for i in _elkai.solve_problem(params, problem)]
    if sorted(tour) != list(range(n)):
        return None
    return tour
