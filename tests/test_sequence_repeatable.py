"""The default ordering (ita.sequence.lkh: LKH bounded by work, with a fixed seed): the
same tour every time for the same matrix, closed or open, symmetric or not, its fixed
ends where they are asked, as short as fast-tsp's; and two plans of one part the same."""

from __future__ import annotations

import numpy as np
import pytest

from ita.sequence.tour import solve_tour


@pytest.mark.parametrize(("n", "symmetric", "start", "end"), [
    (60, True, None, None), (60, True, 0, 0), (60, True, 3, 17), (60, True, 5, None), (60, True, None, 8),
    (50, False, None, None), (50, False, 0, 9), (50, False, None, 4), (50, False, 6, None)])
def test_the_same_tour_every_time_with_its_ends_and_near_fast_tsp(n, symmetric, start, end) -> None:
    rng = np.random.default_rng(n + 7 * (start or 0) + 3 * (end or 0))
    p = rng.uniform(0.0, 100.0, (n, 2))
    cost = np.linalg.norm(p[:, None] - p[None], axis=2)
    if not symmetric:
        cost = cost + rng.uniform(0.0, 5.0, (n, n))
        np.fill_diagonal(cost, 0.0)
    a = solve_tour(cost, method="default", start=start, end=end)
    b = solve_tour(cost, method="default", start=start, end=end)
    assert a.order == b.order and sorted(a.order) == list(range(n))
    if start is not None:
        assert a.order[0] == start
    if end is not None and end != start:
        assert a.order[-1] == end
    fast = solve_tour(cost, method="fast", start=start, end=end)
    assert a.cost <= fast.cost * 1.01


def test_interchangeable_stops_are_visited_together() -> None:
    """Stops with identical costs (several measurements from one pose) go in one visit."""
    rng = np.random.default_rng(2)
    p = rng.uniform(0.0, 100.0, (30, 2))
    p = np.vstack([p, p[:5]])                   # five stops twice
    cost = np.linalg.norm(p[:, None] - p[None], axis=2)
    tour = solve_tour(cost, method="default").order
    pos = {v: k for k, v in enumerate(tour)}
    assert all(abs(pos[i] - pos[30 + i]) == 1 for i in range(5))
