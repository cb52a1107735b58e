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
from collections.abc import Iterable
from dataclasses import dataclass
from typing import Any

from ita.executive.commands import Command, Reply

__all__ = ["MeasuredValue", "ScanData", "measured_values", "scan_frames", "spec_of_message"]


@dataclass(frozen=True)
class MeasuredValue:
    """One measurement's outcome on a device: the value and its standard uncertainty
    (mm), or why there is none (`reason`); `source` is the device's own record (a gauge
    Reading, a VisionResult or VisionException) for reports and pictures."""

    spec_id: str
    value: float | None
    u: float | None
    reason: str | None = None
    source: Any = None

    @property
    def ok(self) -> bool:
        return self.value is not None and self.u is not None and math.isfinite(self.value) \
            and math.isfinite(self.u)


@dataclass(frozen=True, eq=False)
class ScanData:
    """The frames of one SCAN of view group `group` (range frames, first the view's own
    raster, then those of the re-approaches)."""

    group: str
    frames: tuple[Any, ...]


def spec_of_message(message: Any) -> str | None:
    """The measurement id a message's qualitative parameters name (``...(meas(Id))``)."""
    from ita.logic.terms import Term

    def walk(value: Any) -> str | None:
        if isinstance(value, Term):
            if value.name == "meas" and len(value.args) == 1:
                return str(value.args[0])
            for a in value.args:
                found = walk(a)
                if found is not None:
                    return found
        return None

    return walk(message)


def _replies(report: Any) -> Iterable[tuple[Command, Reply]]:
    for outcome in report.outcomes:
        yield outcome.command, outcome.reply
    if report.failure is not None:
        yield report.failure.command, report.failure.reply


def measured_values(report: Any) -> dict[str, MeasuredValue]:
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


def scan_frames(report: Any) -> tuple[Any, ...]:
    """The range frames of every SCAN of an execution report, in order."""
    frames: list[Any] = []
    for _command, reply in _replies(report):
        if isinstance(reply.data, ScanData):
            frames += reply.data.frames
    return tuple(frames)
