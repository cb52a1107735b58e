"""Fault injection held off while the cell's own work goes on.

    with paused(session.arm.injector):   # the Exception Handler's tests, a check, a registration
        ...
"""

from __future__ import annotations

import contextlib
from collections.abc import Iterator

from ita.sim.inject import FaultInjector

__all__ = ["paused"]


@contextlib.contextmanager
def paused(injector: FaultInjector | None) -> Iterator[None]:
    """No fault injected while inside (the Exception Handler's tests and repairs, the
    cell's checks, the part's registration: they meet the faults already on, no new one)."""
    if injector is None:
        yield
        return
    was = injector.paused
    injector.paused = True
    try:
        yield
    finally:
        injector.paused = was
