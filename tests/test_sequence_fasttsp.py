"""The fast-tsp adapter: integer levels, merged stops, budgets, reductions read back."""

from __future__ import annotations

import numpy as np
import pytest

from ita.sequence.fasttsp import (
    LEVELS,
    MAX_SECONDS,
    MIN_SECONDS,
    default_budget,
    levels,
    merge_interchangeable,
    order,
)


def test_integer_costs_keep_their_order_exactly():
    R = np.array([[0, 7, 300], [7, 0, 12], [300, 12, 0]], dtype=float)
    W = levels(R, LEVELS)
    factor = LEVELS // 300
    assert np.array_equal(W, R.astype(np.int64) * factor)


def test_float_costs_use_the_whole_range():
    R = np.array([[0, 0.25, 4.3], [0.25, 0, 1.0], [4.3, 1.0, 0]])
    W = levels(R, LEVELS)
    assert W.max() == LEVELS and W.dtype == np.int64
    assert np.allclose(W / LEVELS * 4.3, R, atol=4.3 / LEVELS)


def test_negative_costs_are_shifted_and_zero_costs_stay_zero():
    W = levels(np.array([[0, -2.0, 1.0], [-2.0, 0, 3.0], [1.0, 3.0, 0]]), 100)
    assert W.min() == 0 and W[0, 1] == 0 and np.all(np.diag(W) == 0)
    assert np.array_equal(levels(np.zeros((4, 4)), 100), np.zeros((4, 4)))


def test_interchangeable_stops_form_classes_with_the_fixed_ends_in_place():
    xy = np.array([[0, 0], [5, 0], [0, 0], [5, 0], [9, 9], [5, 0]], dtype=float)
    D = np.linalg.norm(xy[:, None] - xy[None], axis=2)
    assert merge_interchangeable(D, True, None, None) == [(0, 2), (1, 3, 5), (4,)]
    assert merge_interchangeable(D, True, 3, None) == [(0, 2), (3, 1, 5), (4,)]
    assert merge_interchangeable(D, True, None, 3) == [(0, 2), (1, 5, 3), (4,)]
    # a class never holds both fixed ends of a path
    assert merge_interchangeable(D, True, 3, 5) == [(0, 2), (3, 1), (4,), (5,)]


def test_asymmetric_stops_must_match_both_ways_to_merge():
    D = np.array([[0, 0, 4], [0, 0, 4], [4, 5, 0]], dtype=float)  # 2 -> 1 dearer than 2 -> 0
    assert merge_interchangeable(D, False, None, None) == [(0,), (1,), (2,)]
    D[2, 1] = 4
    assert merge_interchangeable(D, False, None, None) == [(0, 1), (2,)]


@pytest.mark.parametrize("nodes", [1, 30, 400, 1000, 100_000])
def test_default_budget_grows_with_the_size_within_bounds(nodes):
    b = default_budget(nodes)
    assert MIN_SECONDS <= b <= MAX_SECONDS
    assert b == pytest.approx(min(MAX_SECONDS, max(MIN_SECONDS, nodes / 1000)))


@pytest.mark.parametrize("symmetric", [True, False])
def test_order_reads_every_reduction_back(symmetric):
    rng = np.random.default_rng(3)
    xy = rng.uniform(0, 100, size=(45, 2))
    D = np.linalg.norm(xy[:, None] - xy[None], axis=2)
    if not symmetric:
        D = D + rng.uniform(0, 10, size=D.shape)
        np.fill_diagonal(D, 0)
    for start, end in ((None, None), (0, None), (None, 7), (0, 7)):
        got = order(D, start, end, time_budget=0.05)
        assert got is not None and sorted(got) == list(range(45))
        assert start is None or got[0] == start
        assert end is None or got[-1] == end


def test_tiny_problems():
    assert order(np.zeros((1, 1)), None, None) == (0,)
    assert order(np.array([[0, 1.0], [1.0, 0]]), None, None) == (0, 1)
    assert order(np.array([[0, 1.0], [2.0, 0]]), 1, None) == (1, 0)
