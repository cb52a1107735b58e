"""The ultrasonic probes' calibration on the block, before each probe's first reading.

    calibration = ProbeCalibration(session, archive, run_id, plans)
    state = calibration.before(step.spec_id, step.tool, state)     # reads the block when it is due

Before a probe's first reading in this process the Top Level reads the calibration block
with it (plan ``calibrated(Probe)``: pick it up, the block, couplant, one reading), which
sets the gauge's sound velocity for it (:mod:`ita.devices.stations`).  It is due only
when the measurement can be placed for the probe (one that cannot is never read).  A
calibration that fails is logged and the readings keep the data sheet's velocity
uncertainty; it is not tried again in this process, unless the other arm of a two-arm
run stood in the way (its zones refused a motion): then it stays due, and is tried again
before the probe's next reading, up to :data:`ZONE_TRIES` times.  The plan's events and a
``calibration`` event go to the archive.
"""

from __future__ import annotations

from collections import Counter
from typing import TYPE_CHECKING

from ita.archive import Event
from ita.robot.controller import REFUSED_BY_ZONES
from ita.logic.terms import Term
from ita.task.measure import execute_goals, placement_problem
from ita.toplevel.events import PlanNumbers, calibration_event, plan_events

if TYPE_CHECKING:
    from ita.archive import Archive
    from ita.executive import ExecutionReport
    from ita.planning import OperationPlan
    from ita.planning.state import WorldState
    from ita.task.session import Session

__all__ = ["ZONE_TRIES", "ProbeCalibration"]

#: tries of a probe's calibration the other arm's zones may refuse before it is given up
ZONE_TRIES = 3


class ProbeCalibration:
    """The probes of run `run_id` calibrated (or tried) by this process; its plans take
    their numbers from `plans`."""

    def __init__(self, session: Session, archive: Archive, run_id: str, plans: PlanNumbers) -> None:
        self.session = session
        self.archive = archive
        self.run_id = run_id
        self.plans = plans
        self.calibrated: set[str] = set()          # read the block, or failed for good
        self._refused: Counter[str] = Counter()    # probe -> tries the other arm's zones refused

    def is_probe(self, tool: str | None) -> bool:
        """Whether `tool` is an ultrasonic probe of the work cell."""
        try:
            return tool is not None and self.session.ctx.workcell.tool(tool).tool_class.ultrasonic
        except KeyError:
            return False

    def due(self, spec_id: str, tool: str) -> bool:
        """Whether measuring `spec_id` with `tool` must wait for its calibration: a probe not
        calibrated yet, with the measurement placed for it."""
        return tool not in self.calibrated and self.is_probe(tool) \
            and placement_problem(self.session, spec_id, tool) is None

    def before(self, spec_id: str, tool: str, state: WorldState) -> WorldState:
        """Calibrate `tool` when measuring `spec_id` with it is due to (:meth:`due`); the
        state after."""
        return self.calibrate(tool, state) if self.due(spec_id, tool) else state

    def calibrate(self, probe: str, state: WorldState) -> WorldState:
        """Read the calibration block with `probe` (module docstring); the state after."""
        self.calibrated.add(probe)
        clock = self.session.clock
        t0 = clock.now
        plan: OperationPlan | None
        report: ExecutionReport | None
        plan, report, state, note = execute_goals(self.session, [Term("calibrated", (probe,))], state,
                                                  name="calibrate")
        events: list[Event] = []
        if plan is not None and report is not None:
            events += plan_events(plan, report, None, "calibration", self.plans.next(), tool=probe)
        ok = report is not None and report.ok
        reading = None
        if report is not None and report.ok:
            last = report.outcomes[-1].reply
            reading = float(last.payload.args[0]) if isinstance(last.payload, Term) and last.payload.args else None
        failure = report.failure if report is not None else None
        if failure is not None and REFUSED_BY_ZONES in (failure.reason or ""):
            self._refused[probe] += 1
            if self._refused[probe] < ZONE_TRIES:
                self.calibrated.discard(probe)      # due still: tried again before its next reading
        events.append(calibration_event(probe, ok=ok, reading_mm=reading, started=t0, at=clock.now,
                                        note=note or ("" if failure is None else failure.reason)))
        self.archive.record_events(self.run_id, events)
        return state
