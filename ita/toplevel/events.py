"""Every archive event the Top Level builds.

    plans = PlanNumbers(last=0)                              # the run's plans are numbered 1, 2, ...
    events = measurement_events(outcome, group=0, plan_no=plans.next())
    events += diagnosis_events(handled, plans)               # each plan it ran takes the next number
    events = archive_events(report, plan_no=7)               # the executive's log of one plan

The executive's log of one plan becomes the archive's conventions
(:mod:`ita.archive.timeline`): a command per SEND with its end and category, its reply,
WAIT and CONTINUE per stream, exceptions.  Commands are numbered ``<plan>.<step>``.
Around it the Top Level puts a plan's start and end (a measurement's own plan, or one run
for something else: a diagnosis' tests and repairs, a probe's calibration), and records
what it decided itself: a diagnosis, a calibration, a network solved, a resequencing, the
run's end.  The pending results' events (``network_frame``, ``height_web``) are their
values' own (:mod:`ita.toplevel.network`, :mod:`ita.toplevel.heights`): they are read back.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from ita.archive import Event, RunStatus
from ita.devices.arm import RECOVER_SECONDS
from ita.devices.stations import CAL_STEP_MM
from ita.executive import LogKind
from ita.executive.commands import term_text
from ita.logic.json_value import JsonObject, JsonValue
from ita.logic.terms import Term

if TYPE_CHECKING:
    from ita.diagnosis.handler import Handled
    from ita.executive import ExecutionReport
    from ita.executive.commands import StreamId
    from ita.planning import OperationPlan
    from ita.sequence.plan import SequencePlan
    from ita.task.measure import MeasureOutcome
    from ita.vision.network import NetworkSolution

__all__ = ["PlanNumbers", "archive_events", "calibration_event", "diagnosis_events", "measurement_events",
           "network_event", "plan_events", "run_end_event", "sequence_event"]


_CATEGORY = {"MOVE": "motion", "RETRACT": "motion", "CONTACT": "motion", "COUPLANT": "measuring",
             "MEASURE": "measuring", "SCAN": "measuring", "PICKUP": "tool_change", "PUTDOWN": "tool_change"}

#: the event that ends a run, by how it ended
_END_KIND = {RunStatus.COMPLETED: "run_end", RunStatus.INTERRUPTED: "interrupt", RunStatus.STOPPED: "stop"}


@dataclass
class PlanNumbers:
    """The numbers of a run's plans (their commands are ``<plan>.<step>``): 1, 2, ... in the
    order they ran, across measurements, diagnoses and calibrations.  last: the number
    given last (a continued run starts from its results' count)."""

    last: int = 0

    def next(self) -> int:
        """The next plan's number."""
        self.last += 1
        return self.last


# -- one plan's executive log ------------------------------------------------------------------

def _stream_name(stream: StreamId | None, message_name: str | None) -> str:
    if stream is None:
        return "top"
    if stream.device == "vision":
        return "slra"
    if message_name in ("COUPLANT", "MEASURE"):
        return "gauge"
    return "arm"


def archive_events(report: ExecutionReport, plan_no: int) -> list[Event]:
    """The executive's log of one plan as archive events (ita.archive.timeline's
    conventions): a command per SEND with its end and category, its reply, WAIT and
    CONTINUE per stream, exceptions."""
    names: dict[int | None, str] = {}
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
            assert name is not None, "a SEND is a step's"
            payload: JsonObject = {"cmd": cmd, "name": name.lower(), "category": _CATEGORY.get(name, "other"),
                                       "message": term_text(e.payload)}
            if step in ends:
                payload["end"] = ends[step]
            out.append(Event("command", stream, e.sim_time, payload))
        elif e.kind is LogKind.REPLY:
            assert isinstance(e.payload, tuple), "a REPLY's payload is (reply, result)"
            reply, result = e.payload
            out.append(Event("reply", stream, e.sim_time, {"cmd": cmd, "status": "ok", "reply": term_text(reply),
                                                            "result": term_text(result)}))
        elif e.kind in (LogKind.EXCEPTION, LogKind.TIMEOUT):
            status = "timeout" if e.kind is LogKind.TIMEOUT else "exception"
            out.append(Event("reply", stream, e.sim_time, {"cmd": cmd, "status": status}))
        elif e.kind is LogKind.WAIT:
            assert isinstance(e.payload, tuple), "a WAIT's payload is the steps waited for"
            out.append(Event("wait", stream, e.sim_time, {"on": [f"{plan_no}.{s}" for s in e.payload], "cmd": cmd}))
        elif e.kind is LogKind.CONTINUE:
            assert isinstance(e.payload, tuple), "a CONTINUE's payload is the steps waited for"
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


# -- plans with their start and end -------------------------------------------------------------

def measurement_events(out: MeasureOutcome, group: int | None, plan_no: int) -> list[Event]:
    """The archive events of a measurement's plan (number `plan_no`): its start, the
    executive's log, its end and a recovery of the arm."""
    assert out.plan is not None and out.report is not None
    plan, report = out.plan, out.report
    events = [Event("plan_start", "top", out.t0, {"spec": out.spec_id, "macrop": plan.macrop_name,
                                                  "source": plan.source.value, "steps": len(plan.steps),
                                                  "group": group, "tool": out.tool})]
    events += archive_events(report, plan_no)
    if report.ok:
        events.append(Event("plan_end", "top", out.t1, {"spec": out.spec_id, "status": "ok"}))
        return events
    events.append(Event("plan_end", "top", out.t1, {"spec": out.spec_id, "status": "failed",
                                                    "recovered_arm": out.recovered_arm}))
    if out.recovered_arm:
        events.append(Event("recovery", "arm", out.t1, {"how": "jog back to the last free configuration",
                                                        "duration": RECOVER_SECONDS}))
    return events


def plan_events(plan: OperationPlan, report: ExecutionReport, spec_id: str | None, purpose: str, plan_no: int,
                **start: JsonValue) -> list[Event]:
    """The archive events of a plan (number `plan_no`) run for something other than a
    measurement's own round trip (a diagnosis' tests and repairs, a calibration): its
    start with `purpose` (and `start`'s entries), the executive's log, its end."""
    return [Event("plan_start", "top", report.started_s, {
                "spec": spec_id, "macrop": plan.macrop_name, "source": plan.source.value,
                "steps": len(plan.steps), "purpose": purpose, **start}),
            *archive_events(report, plan_no),
            Event("plan_end", "top", report.finished_s, {
                "spec": spec_id, "status": "ok" if report.ok else "failed", "purpose": purpose})]


def diagnosis_events(handled: Handled, plans: PlanNumbers) -> list[Event]:
    """The archive events of a diagnosis: its record (exception, posterior, tests with
    their results and costs, cause, actions, recovery), every plan it ran (each numbered
    by `plans`), the world updates."""
    d = handled.diagnosis
    events = [Event("diagnosis", "top", d.t0, {**d.to_dict(), "summary": d.summary})]
    for inner in handled.nested:        # second faults met during the handling, each on its own
        events.append(Event("diagnosis", "top", inner.t0, {**inner.to_dict(), "summary": inner.summary,
                                                           "during": d.exception}))
        events += [Event("world_update", "top", inner.t1, {"update": u, "spec": inner.spec_id})
                   for u in inner.updates]
    for label, plan, report in handled.executed:
        if report is None:
            continue
        events += plan_events(plan, report, d.spec_id, label, plans.next())
    for update in d.updates:
        events.append(Event("world_update", "top", d.t1, {"update": update, "spec": d.spec_id}))
    events.append(Event("recovery", "top", d.t1, {"spec": d.spec_id, "how": d.recovery, "cause": d.cause}))
    return events


# -- what the Top Level decided ------------------------------------------------------------------

def calibration_event(probe: str, *, ok: bool, reading_mm: float | None, started: float, at: float,
                      note: str) -> Event:
    """A probe's calibration on the block (its step CAL_STEP_MM thick): whether it went
    well, the gauge's reading, when it began and ended (`at`), why it did not."""
    return Event("calibration", "top", at, {"probe": probe, "ok": ok, "block_mm": CAL_STEP_MM,
                                            "reading_mm": reading_mm, "started": started, "note": note})


def network_event(key: str, solution: NetworkSolution, at: float) -> Event:
    """A network of hole positions solved: its frames and holes, those left out, the fit's
    variance factor and redundancy, the frames' RMS shift (mm)."""
    shifts = np.array([f[:2] for f in solution.frames.values()]) if solution.frames else np.zeros((0, 2))
    return Event("network", "top", at, {
        "network": key, "frames": len(solution.frames), "holes": len(solution.holes),
        "left_out": dict(solution.left_out), "variance_factor": solution.variance_factor,
        "redundancy": solution.redundancy,
        "frame_shift_rms_mm": float(np.sqrt(np.mean(shifts ** 2))) if len(shifts) else None})


def sequence_event(reason: str | None, plan: SequencePlan, at: float) -> Event:
    """The Sequence Planner resequenced the run: why, and the new tool groups."""
    return Event("sequence", "top", at, {"reason": reason, "groups": [{"tool": g.tool, "count": len(g.order)}
                                                                      for g in plan.groups]})


def run_end_event(status: RunStatus, at: float, *, reason: str | None, done: int, total: int) -> Event:
    """How the run ended (completed, interrupted, stopped), why, and how far it got."""
    return Event(_END_KIND[status], "top", at, {"reason": reason, "done": done, "total": total})
