"""Order points so the arm's travel is short: the Sequence Planner's travelling salesman step.

:func:`solve_tour` takes a cost matrix, ``(n, n) float``, ``cost[i, j]`` being the cost
of going from ``i`` to ``j`` (for the arm: its motion time between the two measurement
poses).  The matrix may be asymmetric; every method charges a reversed stretch of the tour
its reverse-direction cost.  Methods (an explicit registry, :data:`METHODS`):

``classic``
    the seed's method (Golden, Bodin, Doyle and Stewart 1980): convex hull insertion with
    the largest-angle rule, then 2-opt edge exchange, then Or-opt "peephole" moves of
    segments of 1 to 3 points, 2-opt and Or-opt alternating until neither improves.  The
    hull needs coordinates (``coords``, ``(n, 2)``, or ``(n, d)`` projected on their
    best-fit plane); without them it starts from cheapest insertion instead.
``default``
    LKH (Helsgaun's Lin-Kernighan-Helsgaun, through the elkai binding; ita.sequence.lkh)
    on the same matrix, bounded by work (trials by the problem's size) with a fixed seed:
    the same tour on every machine at any load.  Mean gap 0.03 %, worst 0.34 % on the 14
    TSPLIB instances of ``bench/tsp.py`` (within 0.08 % on each of up to 1,300 nodes).
    Asymmetric matrices as LKH's ATSP.
``fast``
    fast-tsp (MIT; ita.sequence.fasttsp): a library's Or-opt and Lin-Kernighan style
    local search on the same matrix, scaled to its 16-bit integers, for a wall-clock
    budget of 1 ms a node (0.05 to 0.9 s) unless ``time_budget`` is given.  Mean gap
    0.02 %, worst 0.3 % on the same instances.  Symmetric matrices directly, asymmetric
    ones through Jonker and Volgenant's transform.  It has no seed and stops at a
    deadline: two solves may differ.

Closed tours and open paths: with ``start`` (and/or ``end``) the result is an open path
that begins at ``start`` (ends at ``end``) and its cost has no closing edge.  This is done
with a dummy node tied at no cost to the path's ends, so both methods solve a closed tour.
``start == end`` asks for a closed tour listed from ``start``.

Tiny problems (at most 7 nodes, counting the dummy) are solved exactly by enumeration.
``classic`` and ``default`` are deterministic (the same order for the same matrix on any
machine); ``fast`` is up to 20 nodes (fast-tsp then solves exactly), above that two solves
may differ (nearly always in equal-cost ways).
"""

from __future__ import annotations

import itertools
import time
from dataclasses import dataclass
from typing import Callable, Sequence

import numpy as np

from ita.sequence import fasttsp, lkh
from ita.sequence.construct import (
    cheapest_insertion,
    convex_hull_insertion,
    neighbour_lists,
)
from ita.sequence.localsearch import activate_all, local_search

EXACT_UP_TO = 7  # nodes (with the dummy) solved by enumeration


@dataclass(frozen=True)
class Tour:
    """An ordering of the nodes ``0..n-1``.

    ``order``: the node ids in visiting order; ``cost``: its cost under the matrix it was
    solved for (with the closing edge back to ``order[0]`` when ``closed``); ``method``:
    the method's name; ``seconds``: wall time spent solving.
    """

    order: tuple[int, ...]
    cost: float
    method: str
    seconds: float
    closed: bool = True


@dataclass(frozen=True)
class OrderingProblem:
    """What a method orders.

    ``D``: ``(n, n) float`` costs, zero diagonal; ``coords``: ``(n, d)`` or ``None``;
    ``start``/``end``: the fixed ends of an open path (both ``None``: a closed tour);
    ``time_budget``: seconds for the fast method, or ``None``.
    """

    D: np.ndarray
    coords: np.ndarray | None
    start: int | None
    end: int | None
    time_budget: float | None


@dataclass(frozen=True)
class SearchSpace:
    """What the classic search works on: a closed-tour problem, perhaps with a dummy node.

    ``D``: ``(m, m) float`` costs (``m = n + 1`` with a dummy at index ``n``);
    ``coords``: ``(n, d)`` or ``None``; ``symmetric``: ``D == D.T``.
    """

    D: np.ndarray
    n: int
    coords: np.ndarray | None
    symmetric: bool
    has_dummy: bool


def tour_cost(cost: np.ndarray, order: Sequence[int] | np.ndarray, closed: bool = True) -> float:
    """Cost of visiting ``order`` under ``cost`` (``(n, n) float``), with the closing edge if ``closed``."""
    idx = np.asarray(order, dtype=np.int64)
    if idx.size < 2:
        return 0.0
    total = float(np.asarray(cost)[idx[:-1], idx[1:]].sum())
    if closed:
        total += float(cost[idx[-1], idx[0]])
    return total


def solve_tour(
    cost: np.ndarray,
    method: str = "default",
    coords: np.ndarray | None = None,
    start: int | None = None,
    end: int | None = None,
    time_budget: float | None = None,
) -> Tour:
    """Order the ``n`` nodes of ``cost`` (``(n, n) float``, maybe asymmetric) into a short tour.

    ``coords``: ``(n, d) float`` positions for the classic method's convex hull (``d >= 2``;
    projected on their best-fit plane when ``d > 2``).  ``start``/``end``: fix the ends
    of an open path (see the module docstring).  ``time_budget``: wall-clock seconds the
    fast method searches for (``None``: 1 ms a node, 0.05 to 0.9 s); the others ignore it
    (their work is bounded by the problem's size).  Raises ``ValueError`` on bad arguments.
    """
    t0 = time.perf_counter()
    if method not in METHODS:
        raise ValueError(f"unknown method {method!r}; choose from {', '.join(METHODS)}")
    D = _checked_matrix(cost)
    n = D.shape[0]
    if coords is not None:
        coords = np.asarray(coords, dtype=np.float64)
        if coords.ndim != 2 or coords.shape[0] != n or coords.shape[1] < 2:
            raise ValueError(f"coords must be ({n}, d) with d >= 2, got shape {coords.shape}")
    for name, node in (("start", start), ("end", end)):
        if node is not None and not 0 <= node < n:
            raise ValueError(f"{name} must be a node in 0..{n - 1}, got {node}")
    if time_budget is not None and time_budget < 0:
        raise ValueError(f"time_budget must be >= 0, got {time_budget}")

    closed = start is None and end is None or (start is not None and start == end)
    problem = OrderingProblem(D, coords, None if closed else start, None if closed else end, time_budget)
    if n + (not closed) <= EXACT_UP_TO:
        order = _exact_order(problem)
    else:
        order = METHODS[method](problem)
    if closed:
        k = order.index(start if start is not None else 0)
        order = order[k:] + order[:k]
    # The methods guarantee these; a failure here is a bug, not bad input.
    assert sorted(order) == list(range(n)), "the order is not a permutation of the nodes"
    assert closed or start is None or order[0] == start, "open path does not begin at start"
    assert closed or end is None or order[-1] == end, "open path does not end at end"
    return Tour(order=tuple(order), cost=tour_cost(D, order, closed), method=method,
                seconds=time.perf_counter() - t0, closed=closed)


def _checked_matrix(cost: np.ndarray) -> np.ndarray:
    """A float64 copy of a square finite matrix with a zero diagonal."""
    D = np.array(cost, dtype=np.float64)
    if D.ndim != 2 or D.shape[0] != D.shape[1]:
        raise ValueError(f"cost must be a square (n, n) matrix, got shape {D.shape}")
    if D.shape[0] == 0:
        raise ValueError("cost has no nodes")
    if not np.all(np.isfinite(D)):
        raise ValueError("cost must be finite")
    np.fill_diagonal(D, 0.0)
    return D


def _search_space(problem: OrderingProblem) -> SearchSpace:
    """Add a dummy node for an open path: free to reach from the path's end, free to leave
    to its start, and so dear elsewhere (more than any tour) that it sits between them."""
    D, coords, start, end = problem.D, problem.coords, problem.start, problem.end
    n = D.shape[0]
    symmetric = bool(np.allclose(D, D.T, rtol=1e-12, atol=0.0))
    if start is None and end is None:
        return SearchSpace(D, n, coords, symmetric, False)
    big = (n + 1) * (float(np.abs(D).max()) + 1.0)
    X = np.zeros((n + 1, n + 1))
    X[:n, :n] = D
    if symmetric:
        ends = [v for v in (start, end) if v is not None]
        X[n, :n] = big
        X[n, ends] = 0.0
        X[:n, n] = X[n, :n]
    else:
        X[n, :n] = 0.0 if start is None else big
        X[:n, n] = 0.0 if end is None else big
        if start is not None:
            X[n, start] = 0.0
        if end is not None:
            X[end, n] = 0.0
    X[n, n] = 0.0
    return SearchSpace(X, n, coords, symmetric, True)


def _read_order(tour: np.ndarray, space: SearchSpace, start: int | None, end: int | None) -> list[int]:
    """Turn a closed tour of the search space into an open path, or a closed tour from node 0."""
    n = space.n
    nodes = [int(v) for v in tour]
    if not space.has_dummy:
        k = nodes.index(0)
        return nodes[k:] + nodes[:k]
    k = nodes.index(n)
    order = nodes[k + 1:] + nodes[:k]
    if space.symmetric and ((start is not None and order[0] != start)
                            or (start is None and order[-1] != end)):
        order.reverse()
    return order


def _exact_order(problem: OrderingProblem) -> list[int]:
    """The optimal order of a tiny problem (``n`` plus the dummy at most ``EXACT_UP_TO``)."""
    space = _search_space(problem)
    return _read_order(_exact(space.D), space, problem.start, problem.end)


def _exact(D: np.ndarray) -> np.ndarray:
    """Optimal closed tour by enumeration (for ``m <= EXACT_UP_TO`` nodes): ``(m,) int``."""
    m = D.shape[0]
    if m <= 2:
        return np.arange(m)
    perms = np.array(list(itertools.permutations(range(1, m))), dtype=np.int64)
    full = np.hstack([np.zeros((len(perms), 1), dtype=np.int64), perms])
    costs = D[full, np.roll(full, -1, axis=1)].sum(axis=1)
    return full[int(np.argmin(costs))]


def _workspace(m: int) -> tuple[np.ndarray, ...]:
    """Queue, queue state and in-queue flags of the local search for ``m`` nodes."""
    return np.zeros(m, np.int64), np.zeros(2, np.int64), np.zeros(m, np.bool_)


def _eps(D: np.ndarray) -> float:
    """Improvements smaller than this are treated as none (rounding noise)."""
    return 1e-9 * max(float(np.abs(D).max()), 1e-300)


def _positions(tour: np.ndarray) -> np.ndarray:
    pos = np.empty_like(tour)
    pos[tour] = np.arange(tour.shape[0])
    return pos


def _with_dummy_inserted(D: np.ndarray, tour: np.ndarray) -> np.ndarray:
    """Put the dummy (last index of ``D``) into the closed ``tour`` where it costs least."""
    d = D.shape[0] - 1
    nxt = np.roll(tour, -1)
    added = D[tour, d] + D[d, nxt] - D[tour, nxt]
    k = int(np.argmin(added))
    return np.concatenate([tour[:k + 1], [d], tour[k + 1:]]).astype(np.int64)


def _insertion_start(space: SearchSpace) -> np.ndarray:
    """Convex hull insertion (cheapest insertion without coordinates), dummy added last: ``(m,) int``."""
    D, n = space.D, space.n
    real = np.ascontiguousarray(D[:n, :n])
    if space.coords is not None:
        tour = convex_hull_insertion(real, space.coords)
    else:
        tour = cheapest_insertion(real)
    if space.has_dummy:
        tour = _with_dummy_inserted(D, tour)
    return tour


def classic_search(space: SearchSpace) -> np.ndarray:
    """Convex hull (or cheapest) insertion, then 2-opt and Or-opt to a local optimum: ``(m,) int``."""
    D = space.D
    tour = np.ascontiguousarray(_insertion_start(space), dtype=np.int64)
    pos = _positions(tour)
    neigh = neighbour_lists(D, D.shape[0] - 1)  # every node: exhaustive neighbourhoods
    queue, qstate, inq = _workspace(D.shape[0])
    eps = _eps(D)
    while True:
        activate_all(tour, queue, qstate, inq)
        local_search(D, neigh, tour, pos, space.symmetric, eps, True, False, queue, qstate, inq)
        activate_all(tour, queue, qstate, inq)
        gain = local_search(D, neigh, tour, pos, space.symmetric, eps, False, True, queue, qstate, inq)
        if gain >= -eps:
            return tour


def classic(problem: OrderingProblem) -> list[int]:
    """The seed's method: convex hull insertion, then 2-opt and Or-opt (Golden et al. 1980)."""
    space = _search_space(problem)
    return _read_order(classic_search(space), space, problem.start, problem.end)


def default(problem: OrderingProblem) -> list[int]:
    """LKH bounded by work with a fixed seed (ita.sequence.lkh): the same tour on every
    machine at any load; the classic search in the never-seen case that its tour breaks
    the reduction."""
    order = lkh.order(problem.D, problem.start, problem.end)
    return list(order) if order is not None else classic(problem)


def fast(problem: OrderingProblem) -> list[int]:
    """fast-tsp on the same matrix (ita.sequence.fasttsp) for a wall-clock budget; the
    classic search in the never-seen case that fast-tsp's tour breaks the reduction to its
    symmetric form."""
    order = fasttsp.order(problem.D, problem.start, problem.end, problem.time_budget)
    return list(order) if order is not None else classic(problem)


METHODS: dict[str, Callable[[OrderingProblem], list[int]]] = {
    "classic": classic,
    "default": default,
    "fast": fast,
}
