"""What a run counts as an exception: one definition, read from the archive, for every view
that shows a count (the end of `ita inspect`, `ita diagnosis show`, `ita monitor`, the web
pages and the reports).

An **exception** is a plan that ended on a device's EXCEPTION reply or a TIMEOUT: the
archive's ``exception`` event, one per failed plan.  Where it happened is the plan it ended
(the ``plan_start`` before it):

- ``measurement``: a measurement's own plan;
- ``retry``: the second attempt of a recovery (plan repair or replanning);
- ``test``: a diagnostic test's plan (its failure is the test's outcome);
- ``repair``: a repair's plan (a tool change, a cleaning ...);
- ``check``: the cell's own plans (a probe on the calibration block, the interim check,
  the part's registration).

A **diagnosis** is the Exception Handler's account of one exception (the ``diagnosis``
event: the tests, the cause, the recovery).  Measurements' and retries' exceptions are
diagnosed; an exception of a test or a repair is part of the diagnosis that ran it;
a check's is handled by the check (its event says what it found).

    records = exception_records(archive.events(run_id, kinds=EVENT_KINDS))
    counts = ExceptionCounts.of(records)
    counts.text()      # "3 exceptions (2 in measurements, 1 in a diagnostic test); 2 diagnosed"
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from typing import Any

from ita.archive.model import Event

__all__ = ["EVENT_KINDS", "WHERE", "ExceptionCounts", "ExceptionRecord", "exception_records"]

#: the event kinds the count reads
EVENT_KINDS = ("plan_start", "exception", "diagnosis")

#: where an exception can happen, in the order the counts name them, with their words
WHERE = {"measurement": ("in measurements", "in a measurement"),
         "retry": ("in recoveries' second attempts", "in a recovery's second attempt"),
         "test": ("in diagnostic tests", "in a diagnostic test"),
         "repair": ("in repairs", "in a repair"),
         "check": ("in the cell's checks", "in a check of the cell")}

#: a diagnosis begins at its exception's time: within this (s) of it
SAME_TIME_S = 1e-6


def _where(purpose: str | None) -> str:
    """Where an exception of a plan with `purpose` (None: a measurement's own) happened."""
    if purpose is None:
        return "measurement"
    if purpose.startswith("recovery"):
        return "retry"
    if purpose.startswith("test"):
        return "test"
    if purpose.startswith("repair"):
        return "repair"
    return "check"


@dataclass(frozen=True)
class ExceptionRecord:
    """One exception: its event's seq and sim time, the stream and step it ended, the
    device's message and kind (``exception`` or ``timeout``), the measurement it concerned,
    where it happened (:data:`WHERE`) and the plan's purpose, and the diagnosis made of it
    (the ``diagnosis`` event's payload) or, for a test's or a repair's, the one that ran it
    (`within`)."""

    seq: int | None
    at: float | None
    stream: str | None
    message: str
    kind: str
    spec: str | None
    where: str
    purpose: str | None = None
    diagnosis: Mapping[str, Any] | None = None
    within: Mapping[str, Any] | None = None

    @property
    def diagnosed(self) -> bool:
        return self.diagnosis is not None

    def to_dict(self) -> dict[str, Any]:
        d = self.diagnosis or self.within
        return {"seq": self.seq, "sim_time": self.at, "stream": self.stream, "kind": self.kind,
                "message": self.message, "spec": self.spec, "where": self.where, "plan": self.purpose,
                "diagnosed": self.diagnosed,
                "diagnosis": None if d is None else {k: d.get(k) for k in (
                    "exception", "cause", "recovery", "summary", "tests", "posterior", "updates", "remaining",
                    "during") if k in d},
                "diagnosis_of": "this exception" if self.diagnosis is not None else
                                ("the exception whose diagnosis ran it" if self.within is not None else None)}


def exception_records(events: Sequence[Event]) -> list[ExceptionRecord]:
    """The run's exceptions in order, from its events (at least :data:`EVENT_KINDS`, in
    seq order), each with where it happened and its diagnosis."""
    records: list[ExceptionRecord] = []
    purpose: str | None = None
    spec: str | None = None
    handling: Mapping[str, Any] | None = None      # the diagnosis whose plans follow
    diagnoses: list[tuple[Mapping[str, Any], float | None]] = []
    for e in events:
        if e.kind == "plan_start":
            purpose = e.payload.get("purpose")
            spec = e.payload.get("spec") or e.spec_id
            if purpose is None:
                handling = None
        elif e.kind == "exception":
            where = _where(purpose)
            records.append(ExceptionRecord(
                e.seq, e.sim_time, e.stream, str(e.payload.get("message") or ""), str(e.payload.get("kind") or
                                                                                      "exception"),
                spec, where, purpose, within=handling if where in ("test", "repair") else None))
        elif e.kind == "diagnosis":
            diagnoses.append((e.payload, e.sim_time))
            if "during" not in e.payload:
                handling = e.payload
    for d, at in diagnoses:     # a second fault's diagnosis is recorded before the plan it failed in
        _link(records, d, at)
    return records


def _link(records: list[ExceptionRecord], d: Mapping[str, Any], at: float | None) -> None:
    """Put diagnosis `d` (begun at `at`) on the latest undiagnosed exception of its
    measurement that happened by then (a measurement's or a retry's first; else any)."""
    t0 = d.get("t0", at)
    spec = d.get("spec")
    fits = [i for i, r in enumerate(records) if r.diagnosis is None and r.spec == spec
            and (t0 is None or r.at is None or r.at <= float(t0) + SAME_TIME_S)]
    own = [i for i in fits if records[i].where in ("measurement", "retry")]
    if own or fits:
        pick = (own or fits)[-1]
        records[pick] = replace(records[pick], diagnosis=d, within=None)


@dataclass(frozen=True)
class ExceptionCounts:
    """The counts every view shows: exceptions in all, by where (:data:`WHERE`), how many
    were diagnosed, and the diagnoses made (one per diagnosed exception)."""

    total: int = 0
    by_where: Mapping[str, int] = field(default_factory=dict)
    diagnosed: int = 0

    @classmethod
    def of(cls, records: Sequence[ExceptionRecord]) -> ExceptionCounts:
        where = Counter(r.where for r in records)
        return cls(len(records), {w: where[w] for w in WHERE if where[w]}, sum(r.diagnosed for r in records))

    @classmethod
    def from_events(cls, events: Sequence[Event]) -> ExceptionCounts:
        return cls.of(exception_records(events))

    def text(self) -> str:
        """The counts in words: "3 exceptions (2 in measurements, 1 in a diagnostic test); 2 diagnosed"."""
        if not self.total:
            return "0 exceptions"
        parts = [f"{n} {WHERE[w][0] if n > 1 else WHERE[w][1]}" for w, n in self.by_where.items()]
        return (f"{self.total} exception{'s' * (self.total != 1)} ({', '.join(parts)}); "
                f"{self.diagnosed} diagnosed")

    def to_dict(self) -> dict[str, Any]:
        return {"exceptions": self.total, "by_where": dict(self.by_where), "diagnosed": self.diagnosed,
                "text": self.text()}
