"""From a run's events to the timeline of its command streams and its cycle-time breakdown.

Conventions the Executive follows when it records events (all times simulated seconds):

- `command` on a stream (arm, slra, gauge) at its start time; payload "cmd" (an id
  unique in the run), "name" (move_to, measure, scan, change_tool, ...) and, best,
  "category": motion, measuring, tool_change or other.  Its end is payload "end", or
  sim_time + payload "duration", or the sim_time of the `reply` on the same stream with
  the same "cmd" (without "cmd": the next reply on that stream).
- `wait` on a stream at the time it starts waiting; it ends at payload "end" / "duration",
  or at the next `continue` on the same stream.
- `tool_change` (stream arm unless given) with "end" or "duration": a tool change.
- `diagnosis` (the Exception Handler's record, stream top) from its "t0" to its "t1":
  the handling of an exception, tests, repairs and the measurement again included.
An interval whose end cannot be found ends where the next command of its stream starts,
or at the end of the run.

The breakdown splits the run's span [start, end] into exceptions, measuring,
tool_change, motion, other, waiting and idle: at each instant the first of those that any
stream is doing (measuring while the arm also moves counts as measuring; anything while an
exception is handled counts as exceptions), so the parts add up to the cycle time.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass

from ita.archive.model import Event

CATEGORIES = ("exceptions", "measuring", "tool_change", "motion", "other", "waiting")  # priority order
IDLE = "idle"

_NAME_HINTS = (("measuring", ("measure", "scan", "pulse", "couplant", "range", "image", "gauge", "calibrat")),
               ("tool_change", ("tool", "pickup", "pick_up", "put_down", "putdown", "change", "rack")),
               ("motion", ("move", "approach", "retract", "path", "goto", "go_to", "depart", "home", "traj")))


@dataclass(frozen=True)
class Interval:
    """What one stream did from start to end (simulated s); category from CATEGORIES."""

    stream: str
    start: float
    end: float
    category: str
    label: str = ""
    spec_id: str | None = None

    @property
    def duration(self) -> float:
        return self.end - self.start


def category_of(payload: dict, kind: str = "command") -> str:
    """The category a command's payload declares, or one guessed from its name."""
    if kind == "wait":
        return "waiting"
    if kind == "tool_change":
        return "tool_change"
    declared = str(payload.get("category", "")).lower()
    if declared in CATEGORIES:
        return declared
    name = str(payload.get("name", "")).lower()
    for category, hints in _NAME_HINTS:
        if any(h in name for h in hints):
            return category
    return "other"


def _time(e: Event) -> float:
    """The simulated time of a timed event (one with a sim_time)."""
    assert e.sim_time is not None, e
    return float(e.sim_time)


def _explicit_end(e: Event) -> float | None:
    p = e.payload
    if isinstance(p.get("end"), (int, float)):
        return float(p["end"])
    if isinstance(p.get("duration"), (int, float)):
        return _time(e) + float(p["duration"])
    return None


def intervals(events: Sequence[Event], run_end: float | None = None) -> list[Interval]:
    """The commands, waits and tool changes of `events` (in seq order) as intervals."""
    timed = [e for e in events if e.sim_time is not None]
    if run_end is None:
        run_end = span(timed)[1]
    out: list[Interval] = []
    for i, e in enumerate(timed):
        if e.kind == "diagnosis" and isinstance(e.payload.get("t1"), (int, float)):
            t0 = float(e.payload.get("t0", e.sim_time))
            out.append(Interval("top", t0, max(t0, float(e.payload["t1"])), "exceptions", "diagnosis", e.spec_id))
            continue
        if e.kind not in ("command", "wait", "tool_change"):
            continue
        stream = e.stream or ("arm" if e.kind == "tool_change" else "top")
        end = _explicit_end(e)
        if end is None:
            end = _find_end(timed, i, stream, run_end)
        t0 = _time(e)
        name = str(e.payload.get("name", e.kind))
        out.append(Interval(stream, t0, max(t0, end), category_of(dict(e.payload), e.kind), name, e.spec_id))
    return out


def _find_end(timed: Sequence[Event], i: int, stream: str, run_end: float) -> float:
    e = timed[i]
    closer = "continue" if e.kind == "wait" else "reply"
    cmd = e.payload.get("cmd")
    for f in timed[i + 1:]:
        if f.stream != stream:
            continue
        if f.kind == closer and (e.kind == "wait" or cmd is None or f.payload.get("cmd") == cmd):
            return _time(f)
        if f.kind == "command" and e.kind == "command" and cmd is None:
            return _time(f)
    return run_end


def span(events: Iterable[Event], results: Iterable = ()) -> tuple[float, float]:
    """(start, end) of the run in simulated seconds: events, their explicit ends, result ends."""
    times: list[float] = []
    for e in events:
        if e.sim_time is None:
            continue
        times.append(float(e.sim_time))
        end = _explicit_end(e)
        if end is not None:
            times.append(end)
    for r in results:
        times += [t for t in (r.sim_time_start, r.sim_time_end) if t is not None]
    if not times:
        return (0.0, 0.0)
    return (min(times), max(times))


def breakdown(ivs: Sequence[Interval], start: float, end: float) -> dict[str, float]:
    """Seconds of [start, end] per category (CATEGORIES, then "idle"); they sum to end - start."""
    out = {c: 0.0 for c in CATEGORIES} | {IDLE: 0.0}
    if end <= start:
        return out
    rank = {c: i for i, c in enumerate(CATEGORIES)}
    marks: list[tuple[float, int, int]] = []
    for iv in ivs:
        a, b = max(iv.start, start), min(iv.end, end)
        if b > a:
            marks.append((a, 1, rank[iv.category]))
            marks.append((b, -1, rank[iv.category]))
    marks.sort()
    active = [0] * len(CATEGORIES)
    t = start
    for when, delta, r in marks:
        if when > t:
            top = next((i for i, n in enumerate(active) if n > 0), None)
            out[CATEGORIES[top] if top is not None else IDLE] += when - t
            t = when
        active[r] += delta
    if end > t:
        out[IDLE] += end - t
    return out


def _merged_length(spans: list[tuple[float, float]]) -> float:
    total = 0.0
    cur: tuple[float, float] | None = None   # the merged span being grown
    for a, b in sorted(spans):
        if cur is None or a > cur[1]:
            if cur is not None:
                total += cur[1] - cur[0]
            cur = (a, b)
        else:
            cur = (cur[0], max(cur[1], b))
    if cur is not None:
        total += cur[1] - cur[0]
    return total


def stream_busy(ivs: Sequence[Interval]) -> dict[str, tuple[float, float]]:
    """Per stream: (seconds on commands, seconds waiting), each with overlaps merged."""
    streams = sorted({iv.stream for iv in ivs})
    return {s: (_merged_length([(iv.start, iv.end) for iv in ivs if iv.stream == s and iv.category != "waiting"]),
                _merged_length([(iv.start, iv.end) for iv in ivs if iv.stream == s and iv.category == "waiting"]))
            for s in streams}


def plan_intervals(events: Sequence[Event], run_end: float | None = None) -> list[Interval]:
    """The measurement plans on the top stream: plan_start to the next plan_end of the same
    spec (payload "spec" or the event's spec_id), category "other", label the spec id."""
    timed = [e for e in events if e.sim_time is not None]
    if run_end is None:
        run_end = span(timed)[1]
    open_: dict[str, float] = {}
    out: list[Interval] = []
    for e in timed:
        spec = e.spec_id or e.payload.get("spec")
        if spec is None:
            continue
        if e.kind == "plan_start":
            open_[str(spec)] = _time(e)
        elif e.kind == "plan_end" and str(spec) in open_:
            t0 = open_.pop(str(spec))
            out.append(Interval("top", t0, max(t0, _time(e)), "other", str(spec), str(spec)))
    out += [Interval("top", t0, max(t0, run_end), "other", s, s) for s, t0 in open_.items()]
    return sorted(out, key=lambda iv: iv.start)
