"""The Plan Executive/Monitor: executes a plan as one command stream per device.

    from ita.executive import PlanExecutive
    executive = PlanExecutive(kb, {"path_planner": arm, "vision": vision}, clock=world.clock)
    report = executive.execute(plan)     # an OperationPlan, or its PlanSteps
    report.ok, report.results, report.events, report.failure

- :mod:`~ita.executive.commands`: the step's command (stream, message, expected reply
  and result) from the operators of kb/operators.pl, one bridge call per plan; WAIT;
  replies (normal, exception, time-out); pattern matching.
- :mod:`~ita.executive.streams`: the split into streams, WAITs exactly before commands
  with a predecessor on another stream.
- :mod:`~ita.executive.executor`: the deterministic discrete-event run against
  simulated time: CONTINUEs, time-outs, the stop on the first exception, the log.
- :mod:`~ita.executive.adapters`: what a device must offer (and fakes for tests), and
  the Geometric Reasoner's callback for qualitative parameters.
"""

from ita.executive.adapters import (
    Completion,
    DeviceAdapter,
    PoseResolver,
    qualitative_parameters,
)
from ita.executive.commands import (
    DEFAULT_TIMEOUTS,
    Command,
    ExecutiveError,
    Reply,
    ReplyKind,
    StreamId,
    Wait,
    plan_commands,
)
from ita.executive.executor import (
    ExecutionFailure,
    ExecutionReport,
    FailureKind,
    LogEvent,
    LogKind,
    PlanExecutive,
    StepOutcome,
    StreamPosition,
    run_streams,
)
from ita.executive.streams import StreamCommands, StreamPlan, execution_order, split

__all__ = [
    "DEFAULT_TIMEOUTS",
    "Command",
    "Completion",
    "DeviceAdapter",
    "LogEvent",
    "LogKind",
    "ExecutionFailure",
    "ExecutionReport",
    "ExecutiveError",
    "FailureKind",
    "PlanExecutive",
    "PoseResolver",
    "Reply",
    "ReplyKind",
    "StepOutcome",
    "StreamCommands",
    "StreamId",
    "StreamPlan",
    "StreamPosition",
    "Wait",
    "execution_order",
    "plan_commands",
    "qualitative_parameters",
    "run_streams",
    "split",
]
