"""What a run's report and the System Monitor show, as plain values read from the archive.

    data = collect(archive, run_id, specs=part_specs)      # ReportData
    s = summarize(data)                                     # Summary: verdict, counts, cycle time
    rows = [result_row(r) for r in data.results]            # the per-feature table (CSV, JSON, HTML)

Nothing here draws: `figures` makes chart specifications, `page` and `pdf` make files,
`ita.web` serves the same values.  This module never reads true values: scoring gets them
from `ita.scoring`, for simulated runs only.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from enum import Enum
from typing import Any

from ita.archive import timeline
from ita.archive.model import Event, RunInfo, RunStatus, StoredResult
from ita.archive.store import Archive

MANUAL_HOURS = 24.0  # the manual method, about 1000 points (the seed's abstract)
GOAL_HOURS = 2.4     # the 1987 goal: an order of magnitude faster

STATUS_ORDER = ("conforms", "does_not_conform", "uncertain", "not_done", "cannot_be_done")
STATUS_COLOURS = {"conforms": "#2ca02c", "does_not_conform": "#d62728", "uncertain": "#ff9f1c",
                  "not_done": "#6b6b6b", "cannot_be_done": "#9467bd", "not_attempted": "#cfcfcf"}

#: the per-feature table's columns, in order (CSV header, JSON keys)
COLUMNS = ("seq", "spec_id", "kind", "tool", "outcome", "decision", "nominal", "lower", "upper", "low_limit",
           "high_limit", "value", "deviation", "u", "k", "U", "U_over_tolerance", "position_in_band", "reason",
           "sim_time_start", "sim_time_end", "wall_time", "x", "y", "z")

#: event kinds a run's "events" section lists as they are (the Exception Handler's among them)
NOTABLE_EVENTS = ("exception", "recovery", "diagnosis", "interrupt", "stop", "resume", "sequence", "run_end")


class Verdict(str, Enum):
    """The part's verdict: ACCEPT only when every spec conforms, REJECT when any does not,
    INCOMPLETE otherwise (something not measured or not proven)."""

    ACCEPT = "accept"
    REJECT = "reject"
    INCOMPLETE = "incomplete"


@dataclass(frozen=True)
class SpecPoint:
    """Where a spec is on the part (mm, part frame), and what it measures."""

    id: str
    kind: str | None
    point: tuple[float, float, float]
    normal: tuple[float, float, float] | None = None


@dataclass(frozen=True)
class ReportData:
    """Everything the report shows, read from the archive (and the part's specs)."""

    run: RunInfo
    results: tuple[StoredResult, ...]
    events: tuple[Event, ...]
    specs: tuple[SpecPoint, ...]
    part_known: bool = True          # the part's own specs were given (not only the results' points)
    #: a run of a two-arm run: each arm's (arm, run id, its run's events), this one's too,
    #: in the cell's order (empty: a one-arm run, or the other's run not in the archive)
    group: tuple[tuple[str, str, tuple[Event, ...]], ...] = ()

    @property
    def part_specs(self) -> int:
        """How many specs the part has (the run's total when the part's specs are unknown)."""
        return max(len(self.specs), self.run.total or 0, len(self.results))

    @property
    def part_unknown(self) -> bool:
        """Whether the part's specs are not at hand (its directory gone) while the run was
        limited to the first N: then nobody can say it covered the part."""
        return not self.part_known and self.run.settings.get("limit") is not None


@dataclass(frozen=True)
class Summary:
    """The summary of a run.

    verdict and verdict_reason: the part's verdict (see Verdict) and why; counts: results
    per status (STATUS_ORDER); done/run_total: results / specs the run set out to do;
    part_total: specs of the part; complete: the run covered every spec of the part and
    ended; cycle_s: simulated span of the run; rate_s: simulated seconds per result;
    projected_h: cycle time extrapolated to every spec of the part (== cycle for a
    complete run); speedup_manual, ratio_goal: only for a complete run (else None).
    """

    verdict: Verdict
    verdict_reason: str
    counts: dict[str, int]
    done: int
    run_total: int
    part_total: int
    complete: bool
    start_s: float
    end_s: float
    cycle_s: float
    rate_s: float | None
    projected_h: float | None
    speedup_manual: float | None
    ratio_goal: float | None
    missing: tuple[str, ...] = field(default=())
    part_known: bool = True      # False: the part's specs are not at hand (part_total is the run's)

    @property
    def cycle_h(self) -> float:
        return self.cycle_s / 3600.0

    def to_dict(self) -> dict[str, Any]:
        return {"verdict": self.verdict.value, "verdict_reason": self.verdict_reason, "counts": dict(self.counts),
                "done": self.done, "run_total": self.run_total, "part_total": self.part_total,
                "complete": self.complete, "start_s": self.start_s, "end_s": self.end_s, "cycle_s": self.cycle_s,
                "cycle_h": self.cycle_h, "rate_s": self.rate_s, "projected_h": self.projected_h,
                "speedup_manual": self.speedup_manual, "ratio_goal": self.ratio_goal,
                "manual_h": MANUAL_HOURS, "goal_h": GOAL_HOURS, "missing": list(self.missing[:50]),
                "missing_count": len(self.missing), "part_known": self.part_known}


def _xyz(values: Iterable[float]) -> tuple[float, float, float]:
    x, y, z = (float(c) for c in values)
    return (x, y, z)


def collect(archive: Archive, run_id: str, specs: Iterable[Any] | None = None) -> ReportData:
    """Read run `run_id`; `specs` (MeasurementSpec-like: id, kind, point) are the part's
    specs: they place the unmeasured ones and say what a complete run would be."""
    points: dict[str, SpecPoint] = {}
    for s in specs or ():
        kind = getattr(s.kind, "value", s.kind)
        normal = getattr(s, "normal", None)
        points[s.id] = SpecPoint(s.id, kind, _xyz(s.point), None if normal is None else _xyz(normal))
    known = bool(points)
    results = tuple(archive.results(run_id))
    for r in results:
        if r.point is not None and r.spec_id not in points:
            points[r.spec_id] = SpecPoint(r.spec_id, r.kind, r.point)
    events = tuple(archive.events(run_id))
    return ReportData(archive.run(run_id), results, events, tuple(points.values()), known,
                      _group(archive, run_id, events))


def _group(archive: Archive, run_id: str, events: tuple[Event, ...]) -> tuple[tuple[str, str, tuple[Event, ...]], ...]:
    """The arms' runs of the two-arm run `run_id` is one of (its ``two_arms`` event)."""
    found = next((e for e in reversed(events) if e.kind == "two_arms"), None)
    if found is None:
        return ()
    known = {r.id for r in archive.runs()}
    out = []
    for arm, a in (found.payload.get("per_arm") or {}).items():
        other = str(a.get("run_id", ""))
        if other == run_id:
            out.append((str(arm), other, events))
        elif other in known:
            out.append((str(arm), other, tuple(archive.events(other))))
    return tuple(out) if len(out) > 1 else ()


def arm_runs(archive: Archive, run_id: str) -> tuple[tuple[str, str], ...]:
    """(arm, run id) of every run of the two-arm run `run_id` is one of (its setting
    ``two_arms``: each arm's run, then its hand-over run), while it runs too; () for a run
    of one arm."""
    group = (archive.run(run_id).settings.get("two_arms") or {}).get("group")
    if not group:
        return ()
    out = [(str(r.settings.get("arm") or "?"), r.id) for r in archive.runs(prefix=f"{group}-")   # its runs' ids
           if (r.settings.get("two_arms") or {}).get("group") == group]
    return tuple(sorted(out, key=lambda a: (a[1].endswith("-h"), a[1])))


def status_of(r: StoredResult) -> str:
    """"conforms", "does_not_conform", "uncertain", "not_done" or "cannot_be_done"."""
    return r.decision.value if r.decision is not None else r.outcome.value


# ------------------------------------------------------------------------- one result
def reason_of(r: StoredResult) -> str:
    """Why a result is what it is, for every result not proven to conform (and notes of
    the others): the recorded reason of one not measured; for an uncertain value, which
    limit it lies within U of (or that U is too large for the band)."""
    st = status_of(r)
    if r.value is None or r.U is None:
        return r.reason or st.replace("_", " ")
    lo, hi, v, big_u = r.low_limit, r.high_limit, r.value, r.U
    note = f"; {r.reason}" if r.reason else ""
    if st == "uncertain":
        if 2 * big_u >= hi - lo:
            return (f"U {big_u:.4f} mm is half the tolerance band ({hi - lo:.4f} mm) or more: conformance "
                    f"cannot be proven" + note)
        side, limit = ("low", lo) if abs(v - lo) <= abs(v - hi) else ("high", hi)
        return f"within U {big_u:.4f} mm of the {side} limit {limit:.4f} mm ({v - limit:+.4f} mm)" + note
    if st == "does_not_conform":
        side, limit = ("below the low", lo) if v < lo else ("above the high", hi)
        return f"{abs(v - limit):.4f} mm {side} limit {limit:.4f} mm, beyond U {big_u:.4f} mm" + note
    return r.reason or ""


def result_row(r: StoredResult) -> dict[str, Any]:
    """One row of the per-feature table (keys: COLUMNS).  deviation = value - nominal;
    U_over_tolerance = U / (upper - lower), the share of the band the uncertainty takes;
    position_in_band = (value - low) / (high - low): 0 at the low limit, 1 at the high."""
    band = r.upper - r.lower
    value = r.value
    point = r.point or (None, None, None)
    return {
        "seq": r.seq, "spec_id": r.spec_id, "kind": r.kind, "tool": r.tool, "outcome": r.outcome.value,
        "decision": status_of(r), "nominal": r.nominal, "lower": r.lower, "upper": r.upper,
        "low_limit": r.low_limit, "high_limit": r.high_limit, "value": value,
        "deviation": None if value is None else value - r.nominal, "u": r.u, "k": r.k, "U": r.U,
        "U_over_tolerance": None if r.U is None or band <= 0 else r.U / band,
        "position_in_band": None if value is None or band <= 0 else (value - r.low_limit) / band,
        "reason": reason_of(r) if r.failed or r.reason else "",
        "sim_time_start": r.sim_time_start, "sim_time_end": r.sim_time_end, "wall_time": r.wall_time,
        "x": point[0], "y": point[1], "z": point[2],
    }


# ------------------------------------------------------------------------------ summary
def run_verdict(info: RunInfo) -> str:
    """The verdict over a run's own measurements (accept, reject, incomplete), from the
    counts it recorded at its end; "-" while it has none."""
    counts = info.totals.get("counts") if isinstance(info.totals, dict) else None
    if not isinstance(counts, dict) or info.total is None:
        return "-"
    return verdict_of({str(k): int(v) for k, v in counts.items()}, int(info.total))[0].value


def verdict_of(counts: dict[str, int], part_total: int) -> tuple[Verdict, str, int]:
    """(verdict, why, specs without a conforming result)."""
    done = sum(counts.values())
    bad = counts.get("does_not_conform", 0)
    unproven = counts.get("uncertain", 0) + counts.get("not_done", 0) + counts.get("cannot_be_done", 0)
    missing = max(part_total - done, 0)
    if bad:
        return Verdict.REJECT, f"{bad} spec(s) do not conform", unproven + missing
    if not unproven and not missing and done:
        return Verdict.ACCEPT, f"all {done} specs conform", 0
    parts = []
    if missing:
        parts.append(f"{missing} of {part_total} specs have no result")
    for key in ("uncertain", "not_done", "cannot_be_done"):
        if counts.get(key):
            parts.append(f"{counts[key]} {key.replace('_', ' ')}")
    return Verdict.INCOMPLETE, "; ".join(parts) or "no results", unproven + missing


def summarize(data: ReportData) -> Summary:
    """The run's summary: verdict, counts, cycle time, and the comparison with the manual
    method and the 1987 goal only when the run covered the whole part."""
    counts = {s: 0 for s in STATUS_ORDER}
    for r in data.results:
        counts[status_of(r)] += 1
    start, end = timeline.span(data.events, data.results)
    cycle_s = end - start
    done = len(data.results)
    part_total = data.part_specs
    run_total = data.run.total if data.run.total is not None else done
    verdict, why, _ = verdict_of(counts, part_total)
    if data.part_unknown and verdict is not Verdict.REJECT:
        verdict = Verdict.INCOMPLETE
        why = "; ".join(w for w in (f"the run was limited to the first {data.run.settings['limit']} measurements "
                                    "and the part's specs are not at hand", why if verdict_of(
                                        counts, part_total)[0] is Verdict.INCOMPLETE else "") if w)
    ended = data.run.status is RunStatus.COMPLETED
    complete = ended and done >= part_total and done > 0 and not data.part_unknown
    rate = cycle_s / done if done else None
    projected_h = cycle_s / 3600.0 if complete else (rate * part_total / 3600.0 if rate and not data.part_unknown
                                                       else None)
    have = {r.spec_id for r in data.results}
    missing = tuple(s.id for s in data.specs if s.id not in have)
    return Summary(verdict, why, counts, done, run_total, part_total, complete, start, end, cycle_s, rate,
                   projected_h, MANUAL_HOURS / projected_h if complete and projected_h else None,
                   projected_h / GOAL_HOURS if complete and projected_h is not None else None, missing,
                   not data.part_unknown)


def tours(results: Sequence[StoredResult]) -> list[tuple[str, list[StoredResult]]]:
    """Maximal runs of consecutive results (in recorded order) with the same tool."""
    out: list[tuple[str, list[StoredResult]]] = []
    for r in results:
        tool = r.tool or "-"
        if out and out[-1][0] == tool:
            out[-1][1].append(r)
        else:
            out.append((tool, [r]))
    return out


def tour_length(rs: Sequence[StoredResult]) -> float:
    pts = [r.point for r in rs if r.point is not None]
    return sum(math.dist(a, b) for a, b in itertools.pairwise(pts))


def tour_time(rs: Sequence[StoredResult]) -> float | None:
    a = [r.sim_time_start for r in rs if r.sim_time_start is not None]
    b = [r.sim_time_end for r in rs if r.sim_time_end is not None]
    return max(b) - min(a) if a and b else None


def event_row(e: Event) -> dict[str, Any]:
    """An event as the event lists show it."""
    return {"seq": e.seq, "sim_time": e.sim_time, "wall_time": e.wall_time, "kind": e.kind, "stream": e.stream,
            "spec_id": e.spec_id, "payload": dict(e.payload)}


def notable_events(events: Sequence[Event]) -> list[dict[str, Any]]:
    """The run's exceptions, recoveries, interrupts, stops, resumptions, resequencing and
    end: every event of those kinds, as rows, whatever its payload holds."""
    return [event_row(e) for e in events if e.kind in NOTABLE_EVENTS]


def jsonable(obj: Any) -> Any:
    """`obj` with NaN and infinities as None, tuples as lists, numpy scalars as numbers
    (strict JSON for the pages)."""
    if isinstance(obj, float):
        return obj if math.isfinite(obj) else None
    if isinstance(obj, dict):
        return {str(k): jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [jsonable(v) for v in obj]
    if hasattr(obj, "item") and not isinstance(obj, (str, bytes)):
        return jsonable(obj.item())
    if isinstance(obj, Enum):
        return obj.value
    return obj


def settings_rows(run: RunInfo) -> list[tuple[str, str]]:
    """The run's settings as (name, value) a person reads (the spec list is counted)."""
    names = {"simulated": "simulated", "simulated_part": "part in the simulated cell", "limit": "limit (first N of the sequence)", "part_arg": "part directory",
             "mkb_digest": "MKB digest", "sequence_total_s": "sequence plan's arm time (s)"}
    out = []
    for key, value in sorted(run.settings.items()):
        if key == "specs" and isinstance(value, list):
            out.append(("specs the run set out to do", str(len(value))))
            continue
        if value is None:
            value = "-" if key != "limit" else "none (every measurement)"
        if isinstance(value, float):
            value = f"{value:.1f}"
        if key == "faults" and isinstance(value, dict):
            value = _faults_text(value)
        elif isinstance(value, dict):
            value = "; ".join(f"{k.replace('_', ' ')} {_plain(v)}" for k, v in sorted(value.items()))
        elif isinstance(value, list):
            value = ", ".join(map(str, value))
        out.append((names.get(key, key.replace("_", " ")), str(value)))
    return out


def _plain(value: Any) -> str:
    return ", ".join(map(str, value)) if isinstance(value, (list, tuple)) else str(value)


def _faults_text(faults: dict) -> str:
    """The fault injection of a run, as `ita inspect --faults/--fault-kinds/--inject` said it."""
    parts = []
    rate = faults.get("rate") or 0.0
    if rate:
        kinds = faults.get("kinds") or []
        parts.append(f"each command {100 * float(rate):g} % from " + (", ".join(kinds) if kinds else "every kind"))
    scripted = faults.get("scripted") or []
    if scripted:
        parts.append("scripted: " + ", ".join(map(str, scripted)))
    if "seed" in faults:
        parts.append(f"seed {faults['seed']}")
    return "; ".join(parts) or "none"
