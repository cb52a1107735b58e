"""What the devices' replies carry, and reading it back out of an execution report.

A gauge MEASURE replies ``VALUE(V)`` with ``data`` one :class:`MeasuredValue`; a Vision
MEASURE replies ``VALUE(V, S)`` (or an exception) with one MeasuredValue per member of
the view group its frame served; a SCAN replies ``IMAGE(G)`` with :class:`ScanData`, the
frames taken.  :func:`measured_values` collects every value of a report, the failing
step's exception reply included (a Vision failure of one member does not lose the
others').
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from typing import TYPE_CHECKING, TypeAlias, Union

from ita.executive.commands import Command, Reply
from ita.logic.terms import Term, TermValue
from ita.sensors.slra_frame import RangeFrame
from ita.sensors.ultrasonic import GaugeException, Reading
from ita.vision.context import VisionException, VisionResult

if TYPE_CHECKING:
    import numpy as np
    from numpy.typing import ArrayLike, NDArray

    from ita.executive import ExecutionReport

__all__ = ["ArmPath", "MeasuredValue", "ScanData", "arm_paths", "measured_values", "scan_frames", "spec_of_message"]

#: samples an ArmPath keeps of a flown trajectory (evenly spaced in time, ends included)
PATH_SAMPLES = 40

#: a device's own record of a measurement: the gauge's reading or exception, Vision's result
#: or exception (None: the device kept none)
Source: TypeAlias = Union[Reading, GaugeException, VisionResult, VisionException, None]


@dataclass(frozen=True)
class MeasuredValue:
    """One measurement's outcome on a device: the value and its standard uncertainty
    (mm), or why there is none (`reason`); `source` is the device's own record (a gauge
    Reading, a VisionResult or VisionException) for reports and pictures."""

    spec_id: str
    value: float | None
    u: float | None
    reason: str | None = None
    source: Source = None

    @property
    def ok(self) -> bool:
        return self.value is not None and self.u is not None and math.isfinite(self.value) \
            and math.isfinite(self.u)


@dataclass(frozen=True, eq=False)
class ScanData:
    """The frames of one SCAN of view group `group` (range frames, first the view's own
    raster, then those of the re-approaches)."""

    group: str
    frames: tuple[RangeFrame, ...]


@dataclass(frozen=True, eq=False)
class ArmPath:
    """The path an arm command flew, for people: times (n,) s from the command's start,
    joints q (n, 6) rad, tool point tcp (n, 3) in the world frame (m), held tool."""

    times: tuple[float, ...]
    q: tuple[tuple[float, ...], ...]
    tcp: tuple[tuple[float, float, float], ...]
    tool: str | None = None

    @classmethod
    def sampled(cls, times: ArrayLike, q: ArrayLike, tcp_of: Callable[[NDArray[np.float64]], ArrayLike],
                tool: str | None, samples: int = PATH_SAMPLES) -> ArmPath:
        """Up to `samples` knots of a trajectory (times (m,), q (m, 6)), evenly in time;
        tcp_of(q (k, 6)) -> (k, 4, 4) world poses of the tool point."""
        import numpy as np

        t = np.asarray(times, dtype=float)
        qs = np.asarray(q, dtype=float)
        if len(t) > samples:
            idx = np.unique(np.searchsorted(t, np.linspace(t[0], t[-1], samples)).clip(0, len(t) - 1))
            t, qs = t[idx], qs[idx]
        xyz = np.asarray(tcp_of(qs))[:, :3, 3]
        return cls(tuple(round(float(v), 4) for v in t), tuple(tuple(round(float(v), 5) for v in row) for row in qs),
                   tuple((round(float(x), 5), round(float(y), 5), round(float(z), 5)) for x, y, z in xyz), tool)


def spec_of_message(message: TermValue) -> str | None:
    """The measurement id a message's qualitative parameters name (``...(meas(Id))``)."""
    def walk(value: TermValue) -> str | None:
        if isinstance(value, Term):
            if value.name == "meas" and len(value.args) == 1:
                return str(value.args[0])
            for a in value.args:
                found = walk(a)
                if found is not None:
                    return found
        return None

    return walk(message)


def _replies(report: ExecutionReport) -> Iterable[tuple[Command, Reply]]:
    for outcome in report.outcomes:
        yield outcome.command, outcome.reply
    if report.failure is not None:
        yield report.failure.command, report.failure.reply


def measured_values(report: ExecutionReport) -> dict[str, MeasuredValue]:
    """Spec id -> its value from the replies of an execution report (in reply order; a
    later reply for the same spec wins)."""
    out: dict[str, MeasuredValue] = {}
    for _command, reply in _replies(report):
        data = reply.data
        if isinstance(data, MeasuredValue):
            out[data.spec_id] = data
        elif isinstance(data, tuple) and data and all(isinstance(d, MeasuredValue) for d in data):
            out.update({d.spec_id: d for d in data})
    return out


def arm_paths(report: ExecutionReport) -> list[tuple[Command, ArmPath]]:
    """The paths the arm flew in an execution report, with their commands, in order."""
    return [(command, reply.data) for command, reply in _replies(report) if isinstance(reply.data, ArmPath)]


def scan_frames(report: ExecutionReport) -> tuple[RangeFrame, ...]:
    """The range frames of every SCAN of an execution report, in order."""
    frames: list[RangeFrame] = []
    for _command, reply in _replies(report):
        if isinstance(reply.data, ScanData):
            frames += reply.data.frames
    return tuple(frames)
