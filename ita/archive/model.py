"""Values the archive stores and returns: results, events, runs, control commands.

Units: values, uncertainties and tolerances in millimetres; sim_time in simulated
seconds since the start of the run (monotonic across a continued run); wall_time in Unix
seconds (UTC).
"""

from __future__ import annotations

import math
import os
import socket
from collections.abc import Mapping
from dataclasses import dataclass, field
from enum import Enum
from typing import Any

from ita.archive.decision import Decision, decide

#: kinds whose low limit is the quantity's natural bound (decided on their high limit only)
BOUNDED_BELOW = frozenset({"hole_position"})


class Outcome(str, Enum):
    """What became of a measurement.  The value is the spelling in the archive."""

    MEASURED = "measured"
    NOT_DONE = "not_done"              # attempted, gave up (exception not recovered)
    CANNOT_BE_DONE = "cannot_be_done"  # not attempted: no tool, unreachable, ...


class RunStatus(str, Enum):
    """Life of a run.  A run whose process died keeps RUNNING; see RunInfo.alive."""

    RUNNING = "running"
    INTERRUPTED = "interrupted"  # INTERRUPT obeyed after the current plan; can be continued
    STOPPED = "stopped"          # STOP obeyed at once; can be continued
    COMPLETED = "completed"
    FAILED = "failed"


class EventKind(str, Enum):
    """Kinds of events the run loop and the Executive record (others are allowed)."""

    PLAN_START = "plan_start"        # top: a measurement's plan begins; payload {spec, plan?, macrop?}
    PLAN_END = "plan_end"            # top: it ends; payload {spec, status}
    COMMAND = "command"              # arm/slra/gauge: {cmd, name, category?, end?|duration?, ...}
    REPLY = "reply"                  # arm/slra/gauge: {cmd, status, ...}; sim_time = command end
    WAIT = "wait"                    # a stream waits: {on?, end?|duration?}; ends at its CONTINUE
    CONTINUE = "continue"            # the stream proceeds
    EXCEPTION = "exception"          # {message, spec?, diagnosis?, recovery?}
    RECOVERY = "recovery"            # {plan, ...}
    TOOL_CHANGE = "tool_change"      # arm: {from, to, duration?|end?}
    SEQUENCE = "sequence"            # top: the sequence plan {groups: [{tool, order: [ids]}]}
    INTERRUPT = "interrupt"
    STOP = "stop"
    RESUME = "resume"
    RUN_START = "run_start"
    RUN_END = "run_end"


class Stream(str, Enum):
    """The command streams of the Executive, and `top` for the sequence level."""

    ARM = "arm"
    SLRA = "slra"
    GAUGE = "gauge"
    TOP = "top"


class ControlCommand(str, Enum):
    """Commands the System Monitor sends a running Top Level."""

    STOP = "STOP"            # halt all activity immediately
    INTERRUPT = "INTERRUPT"  # halt after the current plan completes


@dataclass(frozen=True)
class Result:
    """The result of one measurement spec, as the Top Level hands it to the archive.

    nominal/lower/upper: the spec's nominal and signed tolerance deviations (mm);
    value: measured value (mm), None unless MEASURED; u: its standard uncertainty (mm);
    k: coverage factor (U = k u); decision: computed from value, U and the limits when
    not given; tool: the tool used; reason: why not measured (or a note); kind and point
    (x, y, z mm, part frame) are copied from the spec so the archive is self-describing.
    """

    spec_id: str
    outcome: Outcome
    nominal: float
    lower: float
    upper: float
    value: float | None = None
    u: float | None = None
    k: float = 2.0
    decision: Decision | None = None
    tool: str | None = None
    reason: str | None = None
    sim_time_start: float | None = None
    sim_time_end: float | None = None
    kind: str | None = None
    point: tuple[float, float, float] | None = None

    def __post_init__(self) -> None:
        object.__setattr__(self, "outcome", Outcome(self.outcome))
        if self.outcome is Outcome.MEASURED:
            if self.value is None or self.u is None:
                raise ValueError(f"{self.spec_id}: a measured result needs a value and an uncertainty")
            if not (math.isfinite(self.value) and math.isfinite(self.u) and self.u >= 0):
                raise ValueError(f"{self.spec_id}: value {self.value} / uncertainty {self.u} not valid")
            if self.decision is None:
                object.__setattr__(self, "decision", decide(self.value, self.k * self.u, self.low_limit, self.high_limit,
                                                           bounded_below=self.kind in BOUNDED_BELOW))
        elif self.value is not None or self.decision is not None:
            raise ValueError(f"{self.spec_id}: an unmeasured result has no value and no decision")
        if self.decision is not None:
            object.__setattr__(self, "decision", Decision(self.decision))

    @property
    def U(self) -> float | None:
        """Expanded uncertainty k u (mm), None when not measured."""
        return None if self.u is None else self.k * self.u

    @property
    def low_limit(self) -> float:
        return self.nominal + self.lower

    @property
    def high_limit(self) -> float:
        return self.nominal + self.upper

    @classmethod
    def measured(cls, spec: Any, value: float, u: float, *, k: float = 2.0, tool: str | None = None,
                 sim_time_start: float | None = None, sim_time_end: float | None = None,
                 reason: str | None = None) -> Result:
        """A measured result of `spec` (a MeasurementSpec); the decision is computed."""
        return cls(spec.id, Outcome.MEASURED, spec.nominal, spec.lower, spec.upper, float(value), float(u), k,
                   tool=tool, reason=reason, sim_time_start=sim_time_start, sim_time_end=sim_time_end,
                   **_spec_extras(spec))

    @classmethod
    def unmeasured(cls, spec: Any, outcome: Outcome, reason: str, *, tool: str | None = None,
                   sim_time_start: float | None = None, sim_time_end: float | None = None) -> Result:
        """A NOT_DONE or CANNOT_BE_DONE result of `spec`, with the reason."""
        if Outcome(outcome) is Outcome.MEASURED:
            raise ValueError("use Result.measured for a measured result")
        return cls(spec.id, Outcome(outcome), spec.nominal, spec.lower, spec.upper, tool=tool, reason=reason,
                   sim_time_start=sim_time_start, sim_time_end=sim_time_end, **_spec_extras(spec))


def _spec_extras(spec: Any) -> dict[str, Any]:
    kind = getattr(spec, "kind", None)
    point = getattr(spec, "point", None)
    return {"kind": getattr(kind, "value", kind),
            "point": None if point is None else tuple(float(c) for c in point)}


@dataclass(frozen=True)
class StoredResult(Result):
    """A result read back from the archive: with its run, order and wall-clock time."""

    run_id: str = ""
    seq: int = 0
    wall_time: float = 0.0

    @property
    def failed(self) -> bool:
        """Not proven to conform: does not conform, uncertain, or not measured."""
        return self.decision is not Decision.CONFORMS

    @property
    def status_label(self) -> str:
        """The decision, or the outcome when there is none ("not done")."""
        return self.decision.label if self.decision is not None else self.outcome.value.replace("_", " ")


@dataclass(frozen=True)
class Event:
    """Something that happened in a run.  seq and wall_time are set by the archive.

    stream: "arm", "slra", "gauge" or "top" (others allowed); spec_id: the measurement
    it belongs to, when any (set automatically for events recorded with a result).
    """

    kind: str
    stream: str | None = None
    sim_time: float | None = None
    payload: Mapping[str, Any] = field(default_factory=dict)
    spec_id: str | None = None
    seq: int | None = None
    wall_time: float | None = None

    def __post_init__(self) -> None:
        object.__setattr__(self, "kind", getattr(self.kind, "value", self.kind))
        object.__setattr__(self, "stream", getattr(self.stream, "value", self.stream))
        if not isinstance(self.kind, str) or not self.kind:
            raise ValueError(f"event kind must be a non-empty string, got {self.kind!r}")


@dataclass(frozen=True)
class RunInfo:
    """A run as listed: identity, status, progress.

    done: results recorded; total: specs the run set out to do (None when unknown);
    sim_time: latest simulated time seen; counts: results per decision or outcome label.
    """

    id: str
    part: str
    part_dir: str | None
    seed: int | None
    created: str
    status: RunStatus
    pid: int | None
    host: str | None
    settings: dict[str, Any]
    totals: dict[str, Any]
    ended: str | None
    done: int
    sim_time: float | None

    @property
    def total(self) -> int | None:
        t = self.totals.get("specs")
        return int(t) if t is not None else None

    @property
    def alive(self) -> bool | None:
        """For a RUNNING run: whether its process still lives (None when it ran on another
        host, so this one cannot tell).  False means the process died (killed, crashed)
        and the run can be continued.  Not RUNNING: False."""
        if self.status is not RunStatus.RUNNING:
            return False
        if self.pid is None or self.host != socket.gethostname():
            return None
        try:
            os.kill(self.pid, 0)
        except ProcessLookupError:
            return False
        except PermissionError:
            return True
        return True

    @property
    def state_label(self) -> str:
        """The status as a person should read it: a RUNNING run whose process died is "dead"."""
        if self.status is RunStatus.RUNNING and self.alive is False:
            return "dead"
        return self.status.value


@dataclass(frozen=True)
class ControlRequest:
    """A STOP or INTERRUPT issued by the System Monitor to a run."""

    id: int
    run_id: str
    command: ControlCommand
    issued: float
    taken: float | None
