"""Work for a second core: compiled kernels and library calls that run without the GIL.

    core = SecondCore(min_rows=8192)
    hits = core.in_halves(kernel, (dirs,), origin)      # kernel(dirs, origin), dirs' rows in two halves
    later = core.beside(lambda: rng.random(n))          # started now; later.result() when needed

ITA's heavy loops (embree's ray casting, numba kernels compiled with nogil, numpy's random
fills) release the GIL, so a second thread runs them on the second core.  A SecondCore is
one such thread, kept for the owner's life (waking a kept thread costs tens of microseconds;
starting one, more).  On one core (the machine's, or the process's affinity) it runs
everything at once, in the caller.
"""

from __future__ import annotations

import os
import threading
from collections.abc import Callable, Sequence
from concurrent.futures import Future, ThreadPoolExecutor
from typing import Any, TypeVar

import numpy as np

T = TypeVar("T")


def usable_cores() -> int:
    """The processors this process may run on (its affinity: a process pinned to one core
    gets no second thread), or the machine's count where the system does not say."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:          # not on Linux
        return os.cpu_count() or 1


class SecondCore:
    """A kept second thread for work split by rows (`in_halves`) or run alongside (`beside`).

    min_rows: below this many rows `in_halves` runs the kernel whole, in the caller (the split
    would cost about what it saves)."""

    def __init__(self, min_rows: int, name: str = "ita-second-core") -> None:
        if min_rows < 2:
            raise ValueError(f"min_rows must be at least 2, got {min_rows}")
        self.min_rows = int(min_rows)
        self._name = f"{name}-{id(self):x}"
        self._thread = ThreadPoolExecutor(1, thread_name_prefix=self._name) if usable_cores() > 1 else None

    def _second(self) -> ThreadPoolExecutor | None:
        """The second thread, or None when work must run in the caller: no second thread, or
        the caller is it (work it queued for itself would wait behind itself for ever)."""
        if self._thread is None or threading.current_thread().name.startswith(self._name + "_"):
            return None
        return self._thread

    @property
    def active(self) -> bool:
        """Whether there is a second thread (False on a one-core machine)."""
        return self._thread is not None

    def beside(self, work: Callable[[], T]) -> Future[T]:
        """work() started on the second thread (done at once, here, where there is none or
        where this is it)."""
        second = self._second()
        if second is not None:
            return second.submit(work)
        done: Future[T] = Future()
        done.set_result(work())
        return done

    def in_halves(self, kernel: Callable[..., tuple], rows: Sequence[np.ndarray], *rest: Any,
                  min_rows: int | None = None) -> tuple:
        """kernel(*rows, *rest): a tuple of arrays with a row for each row of `rows` (arrays
        of n rows each), each computed from that row alone.  With n >= min_rows (this call's,
        or the core's) the rows go in two halves, the second on the second thread; the same
        arrays, bit for bit, as one call."""
        n = len(rows[0])
        if any(len(r) != n for r in rows):
            raise ValueError(f"rows of unequal length: {[len(r) for r in rows]}")
        thread = self._second()
        if n < max(2, self.min_rows if min_rows is None else min_rows) or thread is None:
            return kernel(*rows, *rest)
        half = n // 2
        second = thread.submit(kernel, *(r[half:] for r in rows), *rest)
        first = kernel(*(r[:half] for r in rows), *rest)
        return tuple(np.concatenate(pair) for pair in zip(first, second.result()))
