"""The task level: one measurement's round trip, below the Exception Handler.

    from ita.task import open_session, measure_one
    session = open_session(part_dir, seed=1)       # KBs, part, plan, MKB, simulator, devices
    outcome = measure_one(session, "HD-OF-017", state, tool="slra_1")

The Top Level, `ita measure` and the Exception Handler (its tests, its retries) share it:
:mod:`~ita.task.session` (the loaded system: knowledge bases, part, plans, MKB,
simulator and devices, wired once) and :mod:`~ita.task.measure` (plan with the Operation
Planner, execute with the Plan Executive on the devices, read the values back, the world
state after).
"""

from ita.task.measure import (
    MeasureOutcome,
    MeasureStatus,
    execute_goals,
    execute_measurement,
    measure_one,
    placement_problem,
    state_after,
)
from ita.task.session import Session, open_session

__all__ = [
    "MeasureOutcome",
    "MeasureStatus",
    "Session",
    "execute_goals",
    "execute_measurement",
    "measure_one",
    "open_session",
    "placement_problem",
    "state_after",
]
