"""What went wrong, in the fault knowledge base's words: an exception and its context.

    exc = classify(outcome, held="us_probe_1", tool="us_probe_1")
    exc.exception    # "no_echo"
    exc.context      # (("probe", "us_probe_1"), ("device", "gauge"))

The devices' exception replies (``GAUGE(no_echo)``, ``BUMP(link, obstacle)``,
``VISION(too_few_pixels)``...), the executive's time-outs and unexpected replies become
the exceptions of kb/faults.pl; the context names the tool in hand and the device, which
fill in the causes (``broken_probe(probe)`` -> ``broken_probe(us_probe_1)``).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Protocol

from ita.logic.terms import Term, TermValue
from ita.robot.controller import REFUSED_BY_ZONES
from ita.specs.model import is_ultrasonic

if TYPE_CHECKING:
    from ita.executive import ExecutionReport

__all__ = ["Classified", "classify", "classify_reply"]

#: the gauge's failure -> the exception
_GAUGE = {
    "no_echo": "no_echo", "no_couplant": "no_couplant_film", "doubled": "doubled_thickness",
    "implausible": "implausible_thickness", "misaligned": "misaligned", "no_contact": "no_contact",
    "garbage": "corrupt_reply", "no_probe": "tool_not_seated",
}
#: Vision's failure -> the exception
_VISION = {
    "out_of_view": "out_of_view", "occluded": "too_few_pixels", "too_few_pixels": "too_few_pixels",
    "fit_residual": "fit_residual", "not_measurable": "view_not_measurable", "garbage": "range_image_implausible",
}
#: other exception replies -> the exception
_OTHER = {
    "BUMP": "bump", "NO_PATH": "no_path", "TIMEOUT": "controller_timeout", "REAPPROACH": "bump",
    "REJECTED": "tool_not_seated", "NO_SENSOR": "tool_not_seated", "NO_PROBE": "tool_not_seated",
    "JOINT_LIMIT": "no_path",
}


@dataclass(frozen=True)
class Classified:
    """An exception of kb/faults.pl with its context (``(key, value)`` pairs), and the
    reply it came from (one line)."""

    exception: str
    context: tuple[tuple[str, str], ...]
    reply: str

    def context_terms(self) -> list[Term]:
        """The context as Prolog ``Key=Value`` terms."""
        return [Term("=", (k, v)) for k, v in self.context]


class Reported(Protocol):
    """What :func:`classify` reads: a measurement's round trip (ita.task.measure
    .MeasureOutcome) or any other run with its execution report (None: nothing ran)."""

    @property
    def report(self) -> ExecutionReport | None: ...


def _name_and_arg(payload: TermValue | None) -> tuple[str, str | None]:
    if isinstance(payload, Term):
        arg = payload.args[0] if payload.args else None
        return payload.name, (str(arg) if arg is not None else None)
    return str(payload), None


def classify_reply(kind: str, payload: TermValue | None) -> str | None:
    """The exception of a failure of `kind` (``exception``, ``timeout``,
    ``unexpected_reply``) with reply `payload`; None when kb/faults.pl has none for it."""
    if kind == "timeout":
        return "controller_timeout"
    if kind == "unexpected_reply":
        return "corrupt_reply"
    name, arg = _name_and_arg(payload)
    if arg == "timeout":                      # a motion the controller never answered (REAPPROACH(timeout)...)
        return "controller_timeout"
    if name == "GAUGE":
        return _GAUGE.get(arg or "")
    if name == "VISION":
        return _VISION.get(arg or "")
    return _OTHER.get(name)


def classify(outcome: Reported, *, held: str | None, tool: str | None, slra_class: str = "slra_tool",
             tool_class: str | None = None) -> Classified | None:
    """The exception of a failed measurement's round trip (ita.task.measure
    .MeasureOutcome with a failed report), in the context of the tool in hand `held`
    and the measurement's `tool` (of class `tool_class`); None when it did not fail
    with an exception reply or a time-out, or kb/faults.pl has no word for it, or the zone
    conductor of a two-arm run refused its motion (the other arm stood in the way: the
    measurement stays not done, and the run takes it once more before it ends)."""
    report = getattr(outcome, "report", None)
    if report is None or report.failure is None:
        return None
    failure = report.failure
    if REFUSED_BY_ZONES in (failure.reason or ""):
        return None        # the other arm of a two-arm run stood in the way: no fault of this cell's
    exception = classify_reply(failure.kind.value, failure.reply.payload)
    if exception is None:
        return None
    context: list[tuple[str, str]] = []
    if is_ultrasonic(tool_class) and tool is not None:     # the straight or the bent probe
        context.append(("probe", tool))
    elif held is not None and tool_class is None:
        context.append(("probe", held))
    if tool_class == slra_class and tool is not None:
        context.append(("slra", tool))
    stream = failure.command.stream.device
    if exception == "controller_timeout":     # whichever stream waited, the controller did not answer
        context.append(("device", "controller"))
    elif failure.command.name in ("MEASURE", "COUPLANT") and stream == "path_planner":
        context.append(("device", "gauge"))
    elif stream == "vision":
        context.append(("device", str(failure.command.stream.unit)))
    else:
        context.append(("device", "controller"))
    if tool is not None:
        context.append(("tool", tool))
    return Classified(exception, tuple(context), failure.reason)
