"""The Exception Handler as the Top Level calls it, on a measurement that failed.

    handle = Handling.of(session, archive, run_id)      # Handling(session, None): failures not handled
    handled = handle(outcome)                           # None: not handled, or no word for the exception

The handler (:mod:`ita.diagnosis`) diagnoses the failure, puts the cell right and takes
the measurement again; fault injection is paused meanwhile (a test or a repair is not a
command the faults of the run are drawn for).  Its ``compare_neighbours`` test reads the
values the run has measured of the nearest measurements of the same kind.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

from ita.devices.injection import paused
from ita.diagnosis import ExceptionHandler

if TYPE_CHECKING:
    from collections.abc import Callable

    from ita.archive import Archive
    from ita.diagnosis.handler import Handled
    from ita.planning.state import WorldState
    from ita.task.measure import MeasureOutcome
    from ita.task.session import Session

__all__ = ["Handling", "MeasuredNeighbours"]


@dataclass(frozen=True)
class MeasuredNeighbours:
    """Values measured in run `run_id` of the `count` measurements of the same kind nearest
    to a spec (nearest first): the Exception Handler's compare_neighbours."""

    session: Session
    archive: Archive
    run_id: str
    count: int = 5

    def __call__(self, spec_id: str) -> list[float]:
        specs = self.session.specs
        me = specs[spec_id]
        found = [(math.dist(specs[r.spec_id].point, me.point), r.value) for r in self.archive.results(self.run_id)
                 if r.value is not None and r.spec_id in specs and r.spec_id != spec_id
                 and specs[r.spec_id].kind is me.kind]
        return [v for _, v in sorted(found)[:self.count]]


@dataclass(frozen=True)
class Handling:
    """Calls `handler` (None: failures are not handled) on a failed measurement of
    `session`, with fault injection paused."""

    session: Session
    handler: ExceptionHandler | None

    @classmethod
    def of(cls, session: Session, archive: Archive, run_id: str,
           prepare_tool: Callable[[str, str, WorldState], WorldState] | None = None) -> Handling:
        """The Exception Handler of run `run_id`, comparing with the run's measured neighbours;
        prepare_tool: before a retry with another tool (a spare probe reads the block)."""
        return cls(session, ExceptionHandler(session, neighbours=MeasuredNeighbours(session, archive, run_id),
                                             prepare_tool=prepare_tool))

    def __call__(self, failed: MeasureOutcome) -> Handled | None:
        if self.handler is None:
            return None
        with paused(self.session.arm.injector):
            return self.handler.handle(failed)
