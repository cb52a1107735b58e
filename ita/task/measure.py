"""One measurement's round trip, the same for the Top Level and `ita measure`.

    outcome = measure_one(session, "HD-OF-017", state, tool="slra_1")
    outcome.value                 # MeasuredValue of the spec (None: not measured, see .reason)
    outcome.others                # the other members of its SLRA view group, from the same frame
    outcome.state                 # where the arm is now and what it holds (plan the next from it)

The Operation Planner plans the measurement with the tool the Sequence Planner chose
(MACROP lookup first) from `state`; the Plan Executive runs the plan on the devices, the
Geometric Reasoner resolving its qualitative poses; the values come back inside the
devices' replies (:func:`ita.devices.measured_values`).  When a step fails (an exception
reply or a time-out) the measurement is not done, the state is taken from the steps
that completed, and the arm is freed if it is stuck.  A measurement the Geometric
Reasoner could not place for that tool cannot be done; nothing is planned for it.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace
from enum import Enum
from typing import TYPE_CHECKING

from ita.devices.data import MeasuredValue, measured_values, scan_frames
from ita.logic.terms import Term, TermValue
from ita.planning import NoPlanError
from ita.planning.state import NOTHING, Place, PoseKind, QualitativePose, WorldState

if TYPE_CHECKING:
    from ita.executive import ExecutionReport
    from ita.planning import OperationPlan
    from ita.sensors.slra_frame import RangeFrame
    from ita.task.session import Session

__all__ = ["MeasureOutcome", "MeasureStatus", "execute_goals", "execute_measurement", "measure_one",
           "placement_problem", "state_after"]


class MeasureStatus(str, Enum):
    """How a measurement's round trip ended."""

    MEASURED = "measured"
    NOT_DONE = "not_done"              # planned and attempted: no plan, a failed step, no value
    CANNOT_BE_DONE = "cannot_be_done"  # not attempted: the MKB has no pose for it with this tool


@dataclass(frozen=True, eq=False)
class MeasureOutcome:
    """The round trip of one measurement.

    value: the spec's MeasuredValue as the devices gave it (with its reason when it failed;
    None when no device got that far); reason: why it was not measured; others:
    values of the other members of its SLRA view group that the plan's frame served (in
    group order, measured or not); plan/report: the operation plan and its execution
    (None when nothing was planned or run); state: the arm's state after; t0/t1:
    simulated start and end; recovered_arm: the arm was jogged free after a failure.
    """

    spec_id: str
    tool: str | None
    status: MeasureStatus
    value: MeasuredValue | None
    reason: str | None
    others: tuple[MeasuredValue, ...]
    plan: OperationPlan | None
    report: ExecutionReport | None
    state: WorldState
    t0: float
    t1: float
    recovered_arm: bool = False

    @property
    def frames(self) -> tuple[RangeFrame, ...]:
        """The range frames the plan took (SLRA measurements)."""
        return () if self.report is None else scan_frames(self.report)


def state_after(plan: OperationPlan, report: ExecutionReport) -> WorldState:
    """The world state after a plan that stopped: the initial state with the results of
    the steps that completed applied (moves, contact, tool pick-ups and put-downs)."""
    state = plan.initial_state
    pose, holding = state.pose, state.holding
    for outcome in report.outcomes:
        r = outcome.result
        if not isinstance(r, Term):
            continue
        try:
            if r.name == "moved" and len(r.args) == 2:
                pose = QualitativePose.from_term(r.args[1])
            elif r.name == "contact" and len(r.args) == 3:
                pose = QualitativePose(PoseKind.CONTACT, Place.from_term(r.args[1]))
            elif r.name == "tool_location" and len(r.args) == 2 and isinstance(r.args[1], Term):
                holding = str(r.args[0]) if r.args[1].name == "on_arm" else None
        except ValueError:
            continue
    return WorldState(state.arm, pose, None if holding == NOTHING else holding)


def placement_problem(session: Session, spec_id: str, tool: str) -> str | None:
    """Why the MKB cannot place `spec_id` for `tool`, or None when it can."""
    tool_class = session.ctx.workcell.tool(tool).tool_class.value
    entry = session.mkb.entry_for(spec_id, tool_class)
    if entry is None:
        return "not in the measurement knowledge base"
    if not entry.ok:
        return f"{entry.status}: {entry.reason}"
    return None


def _dimension(spec_id: str, report: ExecutionReport) -> MeasuredValue | None:
    """The value of a ``dimension(Id, Tool, Val, Sigma)`` result (a device that sends no
    data with its reply)."""
    for res in report.results:
        if isinstance(res, Term) and res.name == "dimension" and res.args[0] == spec_id:
            return MeasuredValue(spec_id, float(res.args[2]), float(res.args[3]))
    return None


def measure_one(session: Session, spec_id: str, state: WorldState, tool: str) -> MeasureOutcome:
    """Plan, execute and read back measurement `spec_id` with `tool` from `state` (see the
    module docstring).  The simulated clock ends at the plan's end."""

    spec = session.specs[spec_id]
    clock = session.clock
    t0 = clock.now
    problem = placement_problem(session, spec_id, tool)
    if problem is not None:
        return MeasureOutcome(spec_id, tool, MeasureStatus.CANNOT_BE_DONE, None, problem, (), None, None,
                              state, t0, t0)
    try:
        plan = session.planner.plan_measurement(spec, state, tool)
    except NoPlanError as exc:
        return MeasureOutcome(spec_id, tool, MeasureStatus.NOT_DONE, None, f"no plan: {exc.reason}", (), None,
                              None, state, t0, t0)
    return execute_measurement(session, spec_id, tool, plan, t0)


def execute_measurement(session: Session, spec_id: str, tool: str, plan: OperationPlan, t0: float | None = None
                        ) -> MeasureOutcome:
    """Run `plan` (a measurement's plan, planned or repaired) from `t0` (default now) and
    read its value back: the second half of :func:`measure_one`."""
    clock = session.clock
    t0 = clock.now if t0 is None else t0
    report = session.executive.execute(plan, start_s=t0)
    if clock.now < report.finished_s:
        clock.advance(report.finished_s - clock.now)
    # the result's end: its last reply, which a trailing command (Vision's processing, on
    # while the arm flies on: ita.executive.run_streams) gives after the plan's end
    t1 = max([clock.now] + [o.finished_s for o in report.outcomes])
    values = measured_values(report)
    others = tuple(v for k, v in values.items() if k != spec_id)
    if not report.ok:
        recovered = session.arm.recover()
        state = state_after(plan, report)
        if recovered and state.pose.kind is PoseKind.CONTACT:   # jogged back off the part: its approach point
            state = replace(state, pose=QualitativePose(PoseKind.APPROACH, state.pose.place))
        return MeasureOutcome(spec_id, tool, MeasureStatus.NOT_DONE, values.get(spec_id),
                              report.failure.reason if report.failure is not None else "failed",
                              others, plan, report, state, t0, t1, recovered)
    value = values.get(spec_id)
    if value is None:
        value = _dimension(spec_id, report)
    if value is None or not value.ok:
        reason = value.reason if value is not None and value.reason else "no value in the replies"
        return MeasureOutcome(spec_id, tool, MeasureStatus.NOT_DONE, value, reason, others, plan, report,
                              plan.final_state, t0, t1)
    return MeasureOutcome(spec_id, tool, MeasureStatus.MEASURED, value, None, others, plan, report,
                          plan.final_state, t0, t1)


def execute_goals(session: Session, goals: Sequence[TermValue], state: WorldState, *, name: str = ""
                  ) -> tuple[OperationPlan | None, ExecutionReport | None, WorldState, str]:
    """Plan `goals` (terms such as ``calibrated(us_probe_1)``) from `state` and run the plan
    now: (plan, report, state after, note).  No plan: (None, None, state, why).  A failed
    step frees the arm if it is stuck."""
    try:
        plan = session.planner.plan_goals(goals, state, name=name)
    except NoPlanError as exc:
        return None, None, state, f"no plan: {exc.reason}"
    clock = session.clock
    report = session.executive.execute(plan, start_s=clock.now)
    if clock.now < report.finished_s:
        clock.advance(report.finished_s - clock.now)
    if report.ok:
        return plan, report, plan.final_state, ""
    session.arm.recover()
    return plan, report, state_after(plan, report), ""
