"""The ultrasonic gauge's commands, on the arm's stream (the probe is on the flange).

    gauge = GaugeCommands(UltrasonicGauge(UltrasonicSim(world)), specs)
    gauge.handlers    # {"COUPLANT": ..., "MEASURE": ...}: command -> Reply

COUPLANT squirts couplant ahead of the probe (``DONE``).  MEASURE takes one reading
(``VALUE(V)``) with the reading as the reply's data (:class:`~ita.devices.data
.MeasuredValue`, its standard uncertainty from the gauge's data sheet).  A bad
measurement is an exception, not a result: a reading about twice the spec's nominal is
refused as ``GAUGE(doubled)`` (a second-echo lock), one further from the nominal than
:data:`IMPLAUSIBLE_TOLERANCES` times its tolerance as ``GAUGE(implausible)`` (the part
and the gauge make it implausible), the reading kept in the reply's data for the
Exception Handler; a gauge exception becomes the exception reply ``GAUGE(reason)``.  The gauge advances the
world's clock itself; the arm device reports each command's end as the clock after it.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping

from ita.devices.data import MeasuredValue, spec_of_message
from ita.executive.commands import Command, Reply
from ita.logic.terms import Term
from ita.sensors.ultrasonic import (
    GaugeException,
    GaugeFailure,
    Reading,
    UltrasonicGauge,
    check_expected,
)
from ita.specs.model import MeasurementSpec

__all__ = ["IMPLAUSIBLE_TOLERANCES", "GaugeCommands"]

#: a reading further than this many tolerances from the nominal is implausible
IMPLAUSIBLE_TOLERANCES = 10.0


class GaugeCommands:
    """COUPLANT and MEASURE of `gauge` (ita.sensors.ultrasonic.UltrasonicGauge); specs:
    spec id -> MeasurementSpec (for the doubled-reading check)."""

    def __init__(self, gauge: UltrasonicGauge, specs: Mapping[str, MeasurementSpec]) -> None:
        self.gauge = gauge
        self.specs = specs

    @property
    def handlers(self) -> dict[str, Callable[[Command], Reply]]:
        return {"COUPLANT": self.couplant, "MEASURE": self.measure}

    def couplant(self, command: Command) -> Reply:
        self.gauge.apply_couplant()
        return Reply.normal("DONE")

    def measure(self, command: Command) -> Reply:
        spec_id = spec_of_message(command.message)
        spec = self.specs.get(spec_id or "")
        raw = self.gauge.measure()
        reply = raw
        if spec is not None and isinstance(raw, Reading):
            tolerance = max(abs(spec.upper), abs(spec.lower))
            reply = check_expected(raw, spec.nominal, tolerance)
            if isinstance(reply, Reading) and abs(raw.thickness_mm - spec.nominal) > IMPLAUSIBLE_TOLERANCES * tolerance:
                reply = GaugeException(GaugeFailure.IMPLAUSIBLE, raw.dwell_s,
                                       f"reads {raw.thickness_mm:.3f} mm, nominal {spec.nominal:.3f} "
                                       f"+/- {tolerance:.3f} mm")
        if isinstance(reply, GaugeException):
            failed = None if spec_id is None else MeasuredValue(spec_id, None, None, f"gauge: {reply.reason.value}",
                                                                raw)
            return Reply.exception(Term("GAUGE", (reply.reason.value,)),
                                   f"gauge: {reply.reason.value} ({reply.message})", data=failed)
        data = None if spec_id is None else MeasuredValue(spec_id, float(reply.thickness_mm), float(reply.u_mm),
                                                          source=reply)
        return Reply.normal(Term("VALUE", (float(reply.thickness_mm),)), data=data)
