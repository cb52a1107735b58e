"""SecondCore: work split by rows with a second thread gives what one call gives."""

from __future__ import annotations

import numpy as np
import pytest

from ita.cores import SecondCore


def _scaled_rows(x, y, k):
    """Per row: x * k + y, and the row's sum (a tuple of arrays, as the kernels return)."""
    out = x * k + y
    return out, out.sum(axis=1)


def test_rows_split_in_halves_come_back_in_order_and_equal_to_one_call():
    core = SecondCore(min_rows=4)
    rng = np.random.default_rng(1)
    x, y = rng.random((101, 3)), rng.random((101, 3))
    calls = []
    submit = core._thread.submit
    core._thread.submit = lambda *a: calls.append(len(a[1])) or submit(*a)
    split = core.in_halves(_scaled_rows, (x, y), 2.5)
    whole = _scaled_rows(x, y, 2.5)
    assert calls == [51]                                        # the second half went to the thread
    assert all(np.array_equal(s, w) for s, w in zip(split, whole))


def test_few_rows_run_whole_in_the_caller():
    core = SecondCore(min_rows=64)
    core._thread.submit = lambda *a: pytest.fail("a small call must not use the thread")
    x = np.arange(30.0).reshape(10, 3)
    out, total = core.in_halves(_scaled_rows, (x, x), 1.0)
    assert np.array_equal(total, 2 * x.sum(axis=1))


def test_a_call_may_set_its_own_least_rows_to_split():
    x = np.arange(30.0).reshape(10, 3)
    eager = SecondCore(min_rows=64)
    calls = []
    submit = eager._thread.submit
    eager._thread.submit = lambda *a: calls.append(len(a[1])) or submit(*a)
    assert np.array_equal(eager.in_halves(_scaled_rows, (x, x), 1.0, min_rows=4)[1], 2 * x.sum(axis=1))
    assert calls == [5]
    lazy = SecondCore(min_rows=4)
    lazy._thread.submit = lambda *a: pytest.fail("below this call's least rows the thread is not used")
    assert np.array_equal(lazy.in_halves(_scaled_rows, (x, x), 1.0, min_rows=64)[1], 2 * x.sum(axis=1))


def test_rows_of_unequal_length_are_refused():
    with pytest.raises(ValueError, match="unequal"):
        SecondCore(min_rows=2).in_halves(_scaled_rows, (np.zeros((4, 3)), np.zeros((5, 3))), 1.0)


def test_work_beside_runs_and_gives_its_result():
    core = SecondCore(min_rows=2)
    assert core.beside(lambda: 6 * 7).result() == 42


def test_a_process_pinned_to_one_core_gets_no_second_thread(monkeypatch):
    import ita.cores as cores

    monkeypatch.setattr(cores.os, "sched_getaffinity", lambda pid: {0}, raising=False)
    core = cores.SecondCore(min_rows=2)
    assert not core.active
    x = np.arange(12.0).reshape(4, 3)
    assert np.array_equal(core.in_halves(_scaled_rows, (x, x), 1.0)[1], 2 * x.sum(axis=1))
    assert core.beside(lambda: "here").result() == "here"


def test_work_the_second_thread_splits_again_runs_there_instead_of_waiting_for_itself():
    core = SecondCore(min_rows=2)
    x = np.arange(30.0).reshape(10, 3)

    def nested():
        inner = core.in_halves(_scaled_rows, (x, x), 1.0)[1]      # from the thread itself
        return inner, core.beside(lambda: 5).result()

    inner, five = core.beside(nested).result(timeout=10)
    assert np.array_equal(inner, 2 * x.sum(axis=1)) and five == 5
