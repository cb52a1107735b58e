"""A run's report as a list of sections, each a JSON-ready dict the page's script draws.

    payload = report_payload(data, true_values=truth, mesh=(vertices, faces))
    payload["sections"]      # [{"id": "summary", "title": ..., "kind": "summary", ...}, ...]

The HTML report, the PDF and `ita serve` all show these sections.  A section is made by
one builder of SECTIONS from the ReportData (and the context: true values, the part
mesh); a builder returns None to leave its section out.  Kinds the script knows:
"summary", "figure" (a plotly figure), "results" (the per-feature table), "events" (a
list of archive events with whatever payload they carry), "kv" (name/value rows),
"scoring" (kv rows, a figure, a table).  To add a section (the Exception Handler's
diagnoses, say), add a builder here: the pages draw it without other changes.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

from ita.archive import timeline
from ita.archive.exceptions import ExceptionCounts
from ita.report import figures
from ita.report.data import (
    COLUMNS,
    STATUS_COLOURS,
    STATUS_ORDER,
    ReportData,
    Summary,
    notable_events,
    result_row,
    settings_rows,
    summarize,
    tour_length,
    tour_time,
    tours,
)
from ita.scoring.compare import compare
from ita.scoring.diagnoses import diagnosis_score


@dataclass(frozen=True)
class Context:
    """What the builders may use besides the data: the summary, true values (simulated
    runs only; None leaves scoring out), the part mesh (vertices, faces) in mm or None."""

    summary: Summary
    true_values: Mapping[str, float] | None = None
    mesh: Any = None
    injected: Any = None            # the faults injected (simulated runs; only scoring shows them)


Builder = Callable[[ReportData, Context], "dict[str, Any] | None"]


def _summary(data: ReportData, ctx: Context) -> dict[str, Any]:
    run = data.run
    return {"kind": "summary", "title": "Summary", "summary": ctx.summary.to_dict(),
            "run": {"id": run.id, "part": run.part, "part_dir": run.part_dir, "seed": run.seed,
                    "status": run.state_label, "created": run.created, "ended": run.ended},
            "settings": settings_rows(run), "colours": STATUS_COLOURS, "order": list(STATUS_ORDER),
            "alignment": [[f"{e.sim_time or 0.0:.1f} s", str(e.payload.get("why", "")),
                           str(e.payload.get("line") or e.payload.get("reason") or "")]
                          for e in data.events if e.kind == "alignment"]}


def _results(data: ReportData, ctx: Context) -> dict[str, Any]:
    return {"kind": "results", "title": "Results, feature by feature", "columns": list(COLUMNS),
            "rows": [result_row(r) for r in data.results], "colours": STATUS_COLOURS}


def _part(data: ReportData, ctx: Context) -> dict[str, Any] | None:
    if not data.specs:
        return None
    return {"kind": "figure", "title": "The part: every measurement by decision or deviation",
            "note": "Drag to rotate, scroll to zoom, hover a point for its result; click one to open it.",
            "figure": figures.part_figure(data.specs, data.results, ctx.mesh), "id": "part3d", "clickable": True}


def _gantt(data: ReportData, ctx: Context) -> dict[str, Any] | None:
    if not any(e.kind in ("command", "wait", "plan_start") for e in data.events):
        return {"kind": "text", "title": "Timeline of the command streams", "text": "No commands recorded."}
    ivs = timeline.intervals(data.events)
    waits = sum(1 for iv in ivs if iv.category == "waiting")
    return {"kind": "figure", "title": "Timeline of the command streams", "id": "gantt",
            "note": (f"{len(ivs) - waits} commands, {waits} WAITs (dotted: a stream waiting for another's "
                     "command, until its CONTINUE). Drag to zoom in, double-click to zoom out; vertical marks: "
                     "interrupts, stops, resumptions, exceptions."),
            "figure": figures.gantt_figure(data.events, data.results)}


def _s(seconds: Any) -> str:
    return f"{seconds:.1f} s" if isinstance(seconds, (int, float)) else "-"


def _two_arms(data: ReportData, ctx: Context) -> dict[str, Any] | None:
    """A run of a two-arm run: both arms' streams and zone claims on one time axis, and
    each arm's figures from the two-arm summary."""
    if not data.group:
        return None
    summary = next((e.payload for e in reversed(data.events) if e.kind == "two_arms"), {})
    rows = []
    for arm, a in (summary.get("per_arm") or {}).items():
        rows.append((f"{arm} (run {a.get('run_id')})",
                     f"{a.get('measured')} of {a.get('total')} measured; busy {_s(a.get('busy_s'))}, waiting "
                     f"{_s(a.get('waiting_s'))} for the other arm; {a.get('claims')} claims, {a.get('folds')} folds",
                     str(a.get("status", ""))))
    rows.append(("both", f"simulated cycle {_s(summary.get('simulated_cycle_s'))}; {summary.get('measured')} of "
                         f"{summary.get('total')} measured; arm-arm contacts {summary.get('arm_arm_contacts')}",
                 str(summary.get("status", ""))))
    return {"kind": "figure", "title": "Two arms: both arms' streams and their zone claims", "id": "two_arms",
            "note": ("A lane per arm and command stream, and per arm its interference-zone claims: grey, the "
                     "zones a motion held from its grant to its clear; red dotted, a wait for the other arm's "
                     "release (its WAIT until CONTINUE). Drag to zoom in, double-click to zoom out."),
            "figure": figures.two_arm_gantt_figure([(arm, events) for arm, _run, events in data.group]),
            "rows": rows}


def _breakdown(data: ReportData, ctx: Context) -> dict[str, Any] | None:
    s = ctx.summary
    if s.cycle_s <= 0:
        return None
    ivs = timeline.intervals(data.events, s.end_s)
    parts = timeline.breakdown(ivs, s.start_s, s.end_s)
    busy = timeline.stream_busy(ivs)
    rows = [(k.replace("_", " "), f"{v:.1f} s", f"{100 * v / s.cycle_s:.1f} %") for k, v in parts.items()]
    rows += [(f"stream {k}: busy / waiting", f"{b:.1f} s / {w:.1f} s", f"{100 * b / s.cycle_s:.1f} % busy")
             for k, (b, w) in sorted(busy.items())]
    return {"kind": "figure", "title": "Cycle-time breakdown", "id": "breakdown",
            "note": ("Each instant counts once, as the first of exceptions (handling one: tests, repairs, the "
                     "measurement again), measuring, tool change, motion, other, waiting that any stream is doing; "
                     "idle: no stream busy."),
            "figure": figures.breakdown_figure(parts, s.cycle_s), "rows": rows}


def _tours(data: ReportData, ctx: Context) -> dict[str, Any] | None:
    """The Sequence Planner's tours on the part (a figure), the next measurement marked
    while the run goes, and their lengths and times (a table)."""
    tl = tours(data.results)
    if not tl:
        return None
    rows = [(str(i + 1), tool, str(len(rs)), f"{tour_length(rs):.0f} mm",
             "-" if tour_time(rs) is None else f"{tour_time(rs):.1f} s") for i, (tool, rs) in enumerate(tl)]
    order = [str(x) for x in data.run.settings.get("specs") or []]
    have = {r.spec_id for r in data.results}
    where = {s.id: s for s in data.specs}
    todo = [where[i] for i in order if i not in have and i in where]
    running = data.run.status.value == "running"
    return {"kind": "figure", "title": "Tours: the Sequence Planner's order on the part", "id": "tours",
            "note": ("Each tour is the measurements one tool made in a row, in the order made, seen from above"
                     + ("; grey: still to measure, in the run's order; the star: the next" if todo and running
                        else "") + "."),
            "figure": figures.tours_figure(tl, todo if running else (), todo[0] if todo and running else None),
            "table": {"header": ["tour", "tool", "measurements", "path on the part", "simulated time"],
                      "rows": rows}}


def _diagnoses(data: ReportData, ctx: Context) -> dict[str, Any] | None:
    """The Exception Handler's diagnoses as the branch of its test tree each took: the
    exception with the posterior over its causes, each test with its outcome and the
    posterior at its node, the cause isolated (or those left), the recovery."""
    found = [e for e in data.events if e.kind == "diagnosis"]
    if not found:
        return None
    trees = [{"sim_time": e.sim_time, **{k: e.payload.get(k) for k in (
        "spec", "exception", "posterior", "tests", "cause", "remaining", "recovery", "updates", "during",
        "expected_s")}} for e in found]
    return {"kind": "diagnoses", "title": "The Exception Handler's test trees", "id": "diagnoses",
            "note": (f"{len(trees)} diagnoses, each the branch of the decision tree the Exception Handler took: "
                     "the exception and the posterior over its causes, each test it chose (its cost) with the "
                     "outcome, the posterior at the next node, the cause isolated and the recovery."),
            "trees": trees}


def _events(data: ReportData, ctx: Context) -> dict[str, Any]:
    rows = notable_events(data.events)
    counted = ExceptionCounts.from_events(data.events).text()
    return {"kind": "events", "title": "Exceptions and run events", "id": "events", "events": rows,
            "note": (f"{counted[0].upper() + counted[1:]}. Every exception (a plan that ended on a device's "
                     "exception or a timeout), recovery, interrupt, stop, resumption and resequencing of the run, "
                     "with what it recorded." if rows else "No exceptions.")}


def _task_tree(data: ReportData, ctx: Context) -> dict[str, Any] | None:
    """The Top Level's plan: the HTN decomposition of the run's job (its first lines, as
    the run kept them: as planned while the run goes on, as carried out once it ended;
    the last session's when the run was continued)."""
    trees = [e for e in data.events if e.kind == "task_tree"]
    if not trees:
        return None
    payload = trees[-1].payload
    lines = [str(line) for line in payload.get("lines", [])]
    figures_ = payload.get("planner", {})
    stage = str(payload.get("stage", "carried out"))
    note = (f"Job {payload.get('job')}, {stage}: the tasks, the method that decomposed each and what the Sequence "
            f"Planner was asked. Planned in {figures_.get('plan_s', 0):.2f} s"
            + (f"; {figures_.get('actions', 0):.0f} actions carried out, planned again "
               f"{figures_.get('replans', 0):.0f} times." if stage != "planned" else
               " (the run goes on: the plan as made)."))
    rows = [("\u00a0" * (len(line) - len(line.lstrip(" "))) + line.lstrip(" "),) for line in lines]
    return {"kind": "kv", "title": "The Top Level's plan (HTN)", "id": "task_tree", "header": ["task  <- method"],
            "rows": rows, "note": note, "collapsed": True}


def _exceptions(data: ReportData, ctx: Context) -> dict[str, Any] | None:
    """The Exception Handler's diagnoses: the exception, each test in order with its
    result and cost, the cause isolated, the world updated, the recovery."""
    found = [e for e in data.events if e.kind == "diagnosis"]
    if not found:
        return None
    scored = None
    if ctx.injected:
        scored = diagnosis_score(list(ctx.injected), [e.payload for e in found])["diagnoses"]
    rows = []
    for i, e in enumerate(found):
        d = e.payload
        tests = "; ".join(f"{t['test']} -> {t['outcome']} ({t['seconds']:.0f} s, est. {t['estimated_s']:.0f} s)"
                          for t in d.get("tests", [])) or "none"
        posterior = ", ".join(f"{c} {p:.2f}" for c, p in d.get("posterior", [])[:4])
        rows.append((f"{e.sim_time:.1f}" if e.sim_time is not None else "", d.get("spec", ""),
                     d.get("exception", ""), posterior, tests,
                     d.get("cause") or "unresolved: " + ", ".join(c for c, _ in d.get("remaining", [])),
                     "; ".join(d.get("updates", [])) or "-", d.get("recovery", ""))
                    + ((_injected_found(scored[i]),) if scored is not None else ()))
    header = ["sim time (s)", "spec", "exception", "posterior (first four)", "tests in order",
              "cause", "world update", "recovery"]
    note = (f"{ExceptionCounts.from_events(data.events).text()}; {len(rows)} diagnoses (one per diagnosed "
            "exception, a second fault met while handling one included): the posterior over the exception's causes, the tests the Exception "
            "Handler made in the cell in the order its decision tree chose them, what each found and "
            "cost, the cause isolated, the world model's update and the recovery.")
    if scored is not None:
        header.append("injected cause found (simulation)")
        note += (" The last column holds each diagnosis against the faults the simulation injected and that "
                 "were on while the failed plan ran; the system never reads them.")
    return {"kind": "kv", "title": "Exceptions and their diagnoses", "note": note, "header": header,
            "rows": rows, "collapsed": len(rows) > 12}


def _injected_found(row: dict) -> str:
    """The last column of the exceptions table: whether the diagnosis named an injected cause."""
    if not row["injected"]:
        return "no fault injected"
    return "yes" if row["named"] else "no (injected: " + ", ".join(row["injected"]) + ")"


def _scoring(data: ReportData, ctx: Context) -> dict[str, Any] | None:
    if ctx.true_values is None:
        return None
    sc = compare(data.results, ctx.true_values)
    stats = sc.error_stats()
    kinds = {r.spec_id: r.kind or "?" for r in data.results}
    by_kind: dict[str, list[float]] = {}
    for s in sc.scored:
        if s.error is not None:
            by_kind.setdefault(kinds.get(s.spec_id, "?"), []).append(1000 * s.error)
    rows = [("results scored", str(len(sc.scored))),
            ("false accepts (decided conforms, truly out of tolerance)", str(len(sc.false_accepts))),
            ("false rejects (decided does not conform, truly in tolerance)", str(len(sc.false_rejects))),
            ("nonconformities not proven (uncertain or not measured, truly out)", str(len(sc.missed))),
            ("results without a true value", str(len(sc.unscored)))]
    if stats["n"]:
        rows += [("error mean / std / rms (µm)",
                  f"{1000 * stats['mean']:.2f} / {1000 * stats['std']:.2f} / {1000 * stats['rms']:.2f}"),
                 ("largest |error| (µm)", f"{1000 * stats['max_abs']:.2f}"),
                 ("|error| within U", f"{100 * stats['within_u']:.1f} %")]
    if ctx.injected:
        diagnoses = [e.payload for e in data.events if e.kind == "diagnosis"]
        scored = diagnosis_score(list(ctx.injected), diagnoses)
        rows += [("faults injected (simulation)", str(len(ctx.injected))),
                 ("diagnoses that named the injected cause (of those with one to find)",
                  f"{scored['named']} of {scored['with_fault']}"),
                 ("injected faults no diagnosis named (some raised no exception)", str(len(scored["unexplained"])))]
    statuses = [s for s in STATUS_ORDER if any(k[0] == s for k in sc.confusion)]
    confusion = [(s.replace("_", " "), str(sc.confusion.get((s, True), 0)), str(sc.confusion.get((s, False), 0)))
                 for s in statuses]
    wrong = set(sc.false_accepts) | set(sc.false_rejects)
    wrong_rows = [(s.spec_id, s.status.replace("_", " "), f"{s.value:.4f}", f"{s.true_value:.4f}",
                   f"{s.expanded_u:.4f}") for s in sc.scored if s.spec_id in wrong]
    return {"kind": "scoring", "title": "Scoring against the as-built part (simulation only)", "id": "scoring",
            "note": ("This section compares the results with the true dimensions of the simulated part, which "
                     "the inspection itself never sees. A real inspection has no such section."),
            "rows": rows, "confusion": confusion, "wrong": wrong_rows,
            "figure": figures.error_histogram_figure(by_kind) if by_kind else None}


#: the report's sections, in order
SECTIONS: tuple[tuple[str, Builder], ...] = (
    ("summary", _summary),
    ("results", _results),
    ("part3d", _part),
    ("gantt", _gantt),
    ("two_arms", _two_arms),
    ("breakdown", _breakdown),
    ("events", _events),
    ("exceptions", _exceptions),
    ("diagnoses", _diagnoses),
    ("task_tree", _task_tree),
    ("tours", _tours),
    ("scoring", _scoring),
)


def build_sections(data: ReportData, ctx: Context, only: tuple[str, ...] | None = None) -> list[dict[str, Any]]:
    """The sections of SECTIONS (or those named in `only`) that have something to show."""
    out = []
    for name, build in SECTIONS:
        if only is not None and name not in only:
            continue
        section = build(data, ctx)
        if section is not None:
            out.append({"id": name} | section)
    return out


def report_payload(data: ReportData, *, true_values: Mapping[str, float] | None = None, mesh: Any = None,
                   only: tuple[str, ...] | None = None, injected: Any = None) -> dict[str, Any]:
    """Everything a page needs to draw the report of `data`: run, summary and sections
    (`injected`: the faults injected, for scoring the diagnoses)."""
    summary = summarize(data)
    ctx = Context(summary, true_values, mesh, injected)
    return {"run": data.run.id, "part": data.run.part, "status": data.run.state_label,
            "summary": summary.to_dict(), "sections": build_sections(data, ctx, only)}
