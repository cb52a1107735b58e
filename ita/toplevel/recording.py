"""Recording a run's results: each to the archive the moment it exists, once.

    failures = FailuresInARow(limit=10)
    results = Recorder(session, archive, run_id, failures)    # knows what the run has recorded
    results.record(measured_result(spec, value, tool="slra_1", t0=t0, t1=t1), events, Attached(details, frames))
    results.unmeasured("WT-P01-1", Outcome.NOT_DONE, "no path", tool="us_probe_1")
    if failures.alarm: ...                                     # stop the run: something systematic is wrong

A result goes to the archive with its plan's events, its details and its range frames
in one transaction (:meth:`ita.archive.Archive.record_result`); one the archive already
has is not recorded again.  An uncertain result says why in its reason (U over its
tolerance zone and the largest term of its uncertainty budget: :func:`why_uncertain`).
Measurements not done in a row (after the Exception Handler) count towards an alarm.

Checked by the cell.  The results recorded since the last good interim check of the
cell against its reference artifacts (kb/tasks.pl interim_check/1) are `since_check`; a
check that passes clears the list (:meth:`Recorder.checked`); one that finds the arm
drifted or the part moved takes them out of the archive (:meth:`Recorder.supersede`, an
event keeps them) and the Top Level measures them again.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING

from ita.archive import Decision, Event, Outcome, Result, StoredFrame
from ita.devices.data import MeasuredValue
from ita.logic.json_value import JsonValue
from ita.robot.controller import REFUSED_BY_ZONES

if TYPE_CHECKING:
    from ita.archive import Archive
    from ita.specs.model import MeasurementSpec
    from ita.task.session import Session

__all__ = ["MAX_FAILURES_IN_A_ROW", "NOTHING_ATTACHED", "Attached", "FailuresInARow", "Recorder",
           "measured_result", "why_uncertain"]

#: measurements not done in a row (after the Exception Handler) at which the Top Level stops the
#: run: something systematic is wrong, and going on would only fill the run with "not done"
MAX_FAILURES_IN_A_ROW = 10


@dataclass(frozen=True)
class Attached:
    """What the archive keeps beside a result: its details (:mod:`ita.toplevel.details`)
    and its plan's stored range frames."""

    details: Mapping[str, JsonValue] | None = None
    frames: tuple[StoredFrame, ...] = ()


#: a result with nothing beside it
NOTHING_ATTACHED = Attached()


def why_uncertain(result: Result, value: MeasuredValue | None) -> Result:
    """An uncertain result with why added to its reason: U over the tolerance zone and the
    largest term of the uncertainty budget its device reported (Vision's ``budget``:
    term -> standard uncertainty, mm).  Every other result as it is."""
    if result.decision is not Decision.UNCERTAIN or result.U is None:
        return result
    zone = result.upper - result.lower
    note = f"U/tolerance {result.U / zone:.2f}" if zone > 0 else f"U {result.U:.4f} mm"
    budget: Mapping[str, float] = (getattr(getattr(value, "source", None), "diagnostics", None) or {}
                                   ).get("budget") or {}
    if budget:
        term, size = max(budget.items(), key=lambda kv: kv[1])
        note += f"; largest term: {term} (u {size:.4f} mm)"
    return replace(result, reason=f"{result.reason}; {note}" if result.reason else note)


def measured_result(spec: MeasurementSpec, value: MeasuredValue, *, tool: str | None, t0: float | None,
                    t1: float | None, reason: str | None = None) -> Result:
    """The result of a value the devices measured (with why it is uncertain when it is)."""
    if value.value is None or value.u is None:
        raise ValueError(f"{value.spec_id}: no value to record ({value.reason})")
    return why_uncertain(Result.measured(spec, value.value, value.u, tool=tool, sim_time_start=t0,
                                         sim_time_end=t1, reason=reason), value)


class FailuresInARow:
    """The measurements not done in a row (their reasons), and the alarm they raise at
    `limit` of them (0: never)."""

    def __init__(self, limit: int) -> None:
        self.limit = limit
        self.reasons: list[str] = []

    def measured(self) -> None:
        """A measurement was measured (even when its result waits): the row is broken."""
        self.reasons = []

    def not_done(self, spec_id: str, reason: str | None) -> None:
        if reason and REFUSED_BY_ZONES in reason:
            return          # the other arm of a two-arm run stood in the way: not this arm failing
        self.reasons.append(f"{spec_id}: {reason or 'not done'}")

    @property
    def alarm(self) -> str:
        """Why the run must stop ("" while it need not)."""
        if not self.limit or len(self.reasons) < self.limit:
            return ""
        return f"{len(self.reasons)} measurements in a row not done; the last: {self.reasons[-1][:300]}"


class Recorder:
    """Records the results of run `run_id` of `session` in `archive`, and keeps count:
    done (the specs with a result, from before too), counts (per decision or outcome
    label, from before too), recorded_now (by this process); `failures` hears of each
    measured and not done result."""

    def __init__(self, session: Session, archive: Archive, run_id: str, failures: FailuresInARow) -> None:
        self.session = session
        self.archive = archive
        self.run_id = run_id
        self.failures = failures
        self.done: set[str] = archive.done_spec_ids(run_id)
        self.counts: Counter[str] = Counter(archive.decision_counts(run_id))
        self.recorded_now = 0
        #: specs measured (or not done) and recorded since the cell's last good interim check
        self.since_check: list[str] = []
        #: the simulated time of the cell's last good interim check (0: none in this process)
        self.checked_s = 0.0

    def record(self, result: Result, events: Sequence[Event] = (), attached: Attached = NOTHING_ATTACHED) -> None:
        """Record `result` with `events` and what is attached, in one transaction (nothing
        when the archive has the spec's result already)."""
        if not self.archive.record_result(self.run_id, result, events=events, details=attached.details,
                                          frames=attached.frames):
            return
        self.done.add(result.spec_id)
        label = result.decision.value if result.decision is not None else result.outcome.value
        self.counts[label] += 1
        self.recorded_now += 1
        if result.outcome is Outcome.MEASURED:
            self.failures.measured()
        elif result.outcome is Outcome.NOT_DONE:
            self.failures.not_done(result.spec_id, result.reason)
        if result.outcome in (Outcome.MEASURED, Outcome.NOT_DONE):
            self.since_check.append(result.spec_id)

    def checked(self) -> int:
        """The cell's interim check passed: what was recorded since the last one stands;
        how many."""
        n, self.since_check = len(self.since_check), []
        self.checked_s = self.session.clock.now
        return n

    def supersede(self, event: Event, spec_ids: Sequence[str] | None = None) -> list[str]:
        """Take what was recorded since the last good check (or `spec_ids`) out of the
        archive (the check, or a diagnosis, found the cell wrong since: `event` says so and
        keeps them); their spec ids, in the order they were measured, to measure again."""
        if spec_ids is None:
            ids, self.since_check = self.since_check, []
        else:
            ids = list(spec_ids)
            self.since_check = [i for i in self.since_check if i not in set(ids)]
        if not ids:
            return []
        gone = self.archive.supersede(self.run_id, ids, event)
        self.done.difference_update(gone)
        self.counts = Counter(self.archive.decision_counts(self.run_id))
        return gone

    def unmeasured(self, spec_id: str, outcome: Outcome, reason: str, *, tool: str | None = None,
                   t0: float | None = None, t1: float | None = None, events: Sequence[Event] = (),
                   attached: Attached = NOTHING_ATTACHED) -> None:
        """Record that `spec_id` was not measured (NOT_DONE or CANNOT_BE_DONE), and why."""
        spec = self.session.specs[spec_id]
        self.record(Result.unmeasured(spec, outcome, reason, tool=tool, sim_time_start=t0, sim_time_end=t1),
                    list(events), attached)
