"""The Top Level's record of a plan's execution as archive events.

    events = archive_events(report, plan_no=7)     # ita.archive Events, ready to record

The executive's log of one plan becomes the archive's conventions
(:mod:`ita.archive.timeline`): a command per SEND with its end and category, its reply,
WAIT and CONTINUE per stream, exceptions.  Commands are numbered ``<plan>.<step>``.
"""

from __future__ import annotations

from typing import Any

from ita.archive import Event
from ita.executive import LogKind
from ita.executive.commands import term_text
from ita.logic.terms import Term

__all__ = ["archive_events"]


_CATEGORY = {"MOVE": "motion", "RETRACT": "motion", "CONTACT": "motion", "COUPLANT": "measuring",
             "MEASURE": "measuring", "SCAN": "measuring", "PICKUP": "tool_change", "PUTDOWN": "tool_change"}


def _stream_name(stream: Any, message_name: str | None) -> str:
    if stream is None:
        return "top"
    if stream.device == "vision":
        return "slra"
    if message_name in ("COUPLANT", "MEASURE"):
        return "gauge"
    return "arm"


def archive_events(report: Any, plan_no: int) -> list[Event]:
    """The executive's log of one plan as archive events (ita.archive.timeline's
    conventions): a command per SEND with its end and category, its reply, WAIT and
    CONTINUE per stream, exceptions."""
    names: dict[int, str] = {}
    ends: dict[int, float] = {}
    for e in report.events:
        if e.kind is LogKind.SEND:
            names[e.step] = e.payload.name if isinstance(e.payload, Term) else str(e.payload)
        elif e.kind in (LogKind.REPLY, LogKind.EXCEPTION, LogKind.TIMEOUT, LogKind.CANCELLED) and e.step is not None:
            ends.setdefault(e.step, e.sim_time)
    out: list[Event] = []
    for e in report.events:
        step = e.step
        name = names.get(step) if step is not None else None
        stream = _stream_name(e.stream, name)
        cmd = f"{plan_no}.{step}"
        if e.kind is LogKind.SEND:
            payload = {"cmd": cmd, "name": name.lower(), "category": _CATEGORY.get(name, "other"),
                       "message": term_text(e.payload)}
            if step in ends:
                payload["end"] = ends[step]
            out.append(Event("command", stream, e.sim_time, payload))
        elif e.kind is LogKind.REPLY:
            reply, result = e.payload
            out.append(Event("reply", stream, e.sim_time, {"cmd": cmd, "status": "ok", "reply": term_text(reply),
                                                            "result": term_text(result)}))
        elif e.kind in (LogKind.EXCEPTION, LogKind.TIMEOUT):
            status = "timeout" if e.kind is LogKind.TIMEOUT else "exception"
            out.append(Event("reply", stream, e.sim_time, {"cmd": cmd, "status": status}))
        elif e.kind is LogKind.WAIT:
            out.append(Event("wait", stream, e.sim_time, {"on": [f"{plan_no}.{s}" for s in e.payload], "cmd": cmd}))
        elif e.kind is LogKind.CONTINUE:
            out.append(Event("continue", stream, e.sim_time, {"on": [f"{plan_no}.{s}" for s in e.payload],
                                                              "cmd": cmd}))
        elif e.kind is LogKind.CANCELLED:
            out.append(Event("cancelled", stream, e.sim_time, {"cmd": cmd, "how": str(e.payload)}))
    if report.failure is not None:
        f = report.failure
        out.append(Event("exception", _stream_name(f.command.stream, f.command.name), f.at_s,
                         {"message": f.reason, "kind": f.kind.value, "step": f.step.number,
                          "reply": term_text(f.reply.payload) if f.reply.payload is not None else None}))
    return out
