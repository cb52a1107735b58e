"""The report of a run: one self-contained HTML page (inline CSS, charts as inline PNG).

Sections: summary (cycle time against the 24 hours of the manual method and the
2.4-hour goal of 1987, counts by decision), the part with every measurement coloured by
decision, the tours (the order the run measured in, per tool), the timeline of the
command streams (Gantt chart, WAITs hatched), the exceptions, the cycle-time breakdown,
every result; and, only when the caller passes true values, a separate scoring section
(false accepts and rejects, error histogram).  This module never reads true values
itself: `ita.scoring` does, for the CLI.

    html = build_report(archive, run_id, specs=specs, true_values=None)

Charts use matplotlib's Agg backend, imported when a report is built.
"""

from __future__ import annotations

import base64
import html
import io
import itertools
import json
import math
import os
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ita.archive import timeline
from ita.archive.model import Event, RunInfo, StoredResult
from ita.archive.store import Archive

MANUAL_HOURS = 24.0  # the manual method, about 1000 points (the seed's abstract)
GOAL_HOURS = 2.4     # the 1987 goal: an order of magnitude faster

STATUS_ORDER = ("conforms", "does_not_conform", "uncertain", "not_done", "cannot_be_done")
STATUS_COLOURS = {"conforms": "#2ca02c", "does_not_conform": "#d62728", "uncertain": "#ff9f1c",
                  "not_done": "#6b6b6b", "cannot_be_done": "#9467bd", "not_attempted": "#cfcfcf"}
CATEGORY_COLOURS = {"measuring": "#1f77b4", "tool_change": "#9467bd", "motion": "#ff7f0e",
                    "other": "#8c8c8c", "waiting": "#e6e6e6", "idle": "#ffffff"}
TOOL_COLOURS = ("#1f77b4", "#d62728", "#2ca02c", "#9467bd", "#8c564b", "#e377c2")
STREAM_ORDER = ("top", "arm", "slra", "gauge")
DETAIL_PLANS = 5

CSS = """
body{font-family:system-ui,-apple-system,'Segoe UI',Helvetica,Arial,sans-serif;margin:2em auto;
max-width:1100px;color:#222;line-height:1.4;padding:0 1em}
h1{font-size:1.6em;margin-bottom:.2em}h2{border-bottom:2px solid #ddd;padding-bottom:.2em;margin-top:2em}
table{border-collapse:collapse;margin:.5em 0}td,th{border:1px solid #ccc;padding:.25em .6em;text-align:left}
th{background:#f4f4f4}td.num{text-align:right;font-variant-numeric:tabular-nums}
.chip{display:inline-block;width:.9em;height:.9em;border-radius:2px;margin-right:.4em;vertical-align:middle}
.meta{color:#666}.bar{display:flex;height:1.4em;border:1px solid #bbb;margin:.5em 0;max-width:800px}
.bar div{height:100%}img{max-width:100%;height:auto;border:1px solid #eee}
section.scoring{border:3px dashed #b35900;background:#fff8f0;padding:0 1em 1em;margin-top:2em}
section.scoring h2{color:#b35900}.note{color:#555;font-size:.9em}
details summary{cursor:pointer;font-weight:600;margin:.5em 0}
"""


@dataclass(frozen=True)
class SpecPoint:
    """Where a spec is on the part (mm, part frame), and what it measures."""

    id: str
    kind: str | None
    point: tuple[float, float, float]


@dataclass(frozen=True)
class ReportData:
    """Everything the report shows, read from the archive (and the part's specs)."""

    run: RunInfo
    results: tuple[StoredResult, ...]
    events: tuple[Event, ...]
    specs: tuple[SpecPoint, ...]


def collect(archive: Archive, run_id: str, specs: Iterable[Any] | None = None) -> ReportData:
    """Read run `run_id`; `specs` (MeasurementSpec-like: id, kind, point) place the specs
    that have no result yet on the part map."""
    points: dict[str, SpecPoint] = {}
    for s in specs or ():
        kind = getattr(s.kind, "value", s.kind)
        points[s.id] = SpecPoint(s.id, kind, tuple(float(c) for c in s.point))
    results = tuple(archive.results(run_id))
    for r in results:
        if r.point is not None and r.spec_id not in points:
            points[r.spec_id] = SpecPoint(r.spec_id, r.kind, r.point)
    return ReportData(archive.run(run_id), results, tuple(archive.events(run_id)), tuple(points.values()))


def build_report(archive: Archive, run_id: str, *, specs: Iterable[Any] | None = None,
                 true_values: Mapping[str, float] | None = None) -> str:
    """The HTML report of run `run_id`; a scoring section only when `true_values` is given."""
    return render_html(collect(archive, run_id, specs), true_values)


def write_report(path: Path | str, text: str) -> Path:
    """Write the report atomically (a temporary file renamed into place); returns the path."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    try:
        tmp.write_text(text, encoding="utf-8")
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
    return path


# --------------------------------------------------------------------------- numbers
def status_of(r: StoredResult) -> str:
    """"conforms", "does_not_conform", "uncertain", "not_done" or "cannot_be_done"."""
    return r.decision.value if r.decision is not None else r.outcome.value


def summary(data: ReportData) -> dict[str, Any]:
    """The summary figures: counts, cycle time (s, h), ratios to the manual method and the goal."""
    counts = {s: 0 for s in STATUS_ORDER}
    for r in data.results:
        counts[status_of(r)] += 1
    start, end = timeline.span(data.events, data.results)
    cycle_s = end - start
    cycle_h = cycle_s / 3600.0
    done = len(data.results)
    total = data.run.total if data.run.total is not None else max(done, len(data.specs))
    projected_h = cycle_h * total / done if done and total > done else cycle_h
    return {
        "total": total, "done": done, "counts": counts, "start_s": start, "end_s": end,
        "cycle_s": cycle_s, "cycle_h": cycle_h, "projected_h": projected_h,
        "speedup_manual": MANUAL_HOURS / projected_h if projected_h > 0 else math.inf,
        "ratio_goal": projected_h / GOAL_HOURS,
    }


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


def _tour_length(rs: Sequence[StoredResult]) -> float:
    pts = [r.point for r in rs if r.point is not None]
    return sum(math.dist(a, b) for a, b in itertools.pairwise(pts))


# ---------------------------------------------------------------------------- charts
def _plt():
    import matplotlib

    matplotlib.use("Agg", force=True)
    import matplotlib.pyplot as plt

    return plt


def _png(fig: Any) -> str:
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=110, bbox_inches="tight", metadata={"Software": None})
    _plt().close(fig)
    return "data:image/png;base64," + base64.b64encode(buf.getvalue()).decode("ascii")


def _img(src: str, alt: str) -> str:
    return f'<img src="{src}" alt="{html.escape(alt)}">'


def part_map_png(data: ReportData) -> str | None:
    """The part from +Z, each spec a dot coloured by its decision (grey: not attempted)."""
    if not data.specs:
        return None
    plt = _plt()
    status = {r.spec_id: status_of(r) for r in data.results}
    fig, ax = plt.subplots(figsize=(10, 6.5))
    for st in ("not_attempted",) + STATUS_ORDER:
        pts = [s.point for s in data.specs if status.get(s.id, "not_attempted") == st]
        if pts:
            ax.scatter([p[0] for p in pts], [p[1] for p in pts], s=10 if st == "conforms" else 18,
                       c=STATUS_COLOURS[st], label=f"{st.replace('_', ' ')} ({len(pts)})",
                       edgecolors="none" if st != "does_not_conform" else "black", linewidths=0.4)
    ax.set_aspect("equal")
    ax.set_xlabel("x (mm)")
    ax.set_ylabel("y (mm)")
    ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.1), ncol=6, fontsize=8, frameon=False)
    ax.set_title("measurements by decision (part seen from +Z)")
    return _png(fig)


def tours_png(data: ReportData) -> str | None:
    """The measured order drawn as a path per tool, over all spec points."""
    if not any(r.point for r in data.results):
        return None
    plt = _plt()
    fig, ax = plt.subplots(figsize=(10, 6.5))
    if data.specs:
        ax.scatter([s.point[0] for s in data.specs], [s.point[1] for s in data.specs], s=4, c="#d8d8d8")
    colours: dict[str, str] = {}
    for tool, rs in tours(data.results):
        pts = [r.point for r in rs if r.point is not None]
        if not pts:
            continue
        first = tool not in colours
        colour = colours.setdefault(tool, TOOL_COLOURS[len(colours) % len(TOOL_COLOURS)])
        ax.plot([p[0] for p in pts], [p[1] for p in pts], "-", lw=0.8, c=colour,
                label=tool if first else None)
        ax.plot([pts[0][0]], [pts[0][1]], "o", c=colour, ms=5)
    ax.set_aspect("equal")
    ax.set_xlabel("x (mm)")
    ax.set_ylabel("y (mm)")
    ax.legend(fontsize=8, loc="upper right")
    ax.set_title("tours as run (a dot marks where each tour starts)")
    return _png(fig)


def _time_unit(span_s: float) -> tuple[float, str]:
    if span_s > 3 * 3600:
        return 3600.0, "h"
    if span_s > 600:
        return 60.0, "min"
    return 1.0, "s"


def gantt_png(ivs: Sequence[timeline.Interval], plans: Sequence[timeline.Interval],
              t0: float, t1: float, title: str) -> str | None:
    """Gantt chart of the streams over [t0, t1]: commands coloured by category, WAITs hatched."""
    if not ivs and not plans:
        return None
    plt = _plt()
    from matplotlib.patches import Patch

    streams = [s for s in STREAM_ORDER if s == "top" and plans or any(iv.stream == s for iv in ivs)]
    streams += sorted({iv.stream for iv in ivs} - set(streams))
    unit, uname = _time_unit(t1 - t0)
    fig, ax = plt.subplots(figsize=(11, 0.7 * len(streams) + 1.6))
    rows = {s: i for i, s in enumerate(reversed(streams))}

    def bars(items: Iterable[timeline.Interval]) -> list[tuple[float, float]]:
        return [((max(iv.start, t0)) / unit, max((min(iv.end, t1) - max(iv.start, t0)) / unit, 1e-9))
                for iv in items if iv.end >= t0 and iv.start <= t1]

    for s in streams:
        y = rows[s]
        if s == "top":
            for j, colour in enumerate(("#c6dbef", "#9ecae1")):
                ax.broken_barh(bars(plans[j::2]), (y - 0.3, 0.6), facecolors=colour, edgecolor="none")
        mine = [iv for iv in ivs if iv.stream == s]
        for cat in ("waiting",) + tuple(c for c in timeline.CATEGORIES if c != "waiting"):
            sel = bars(iv for iv in mine if iv.category == cat)
            if not sel:
                continue
            if cat == "waiting":
                ax.broken_barh(sel, (y - 0.4, 0.8), facecolors=CATEGORY_COLOURS[cat], edgecolor="#aaaaaa",
                               hatch="///", linewidth=0)
            else:
                ax.broken_barh(sel, (y - 0.35, 0.7), facecolors=CATEGORY_COLOURS[cat], edgecolor="none")
    ax.set_yticks(range(len(streams)))
    ax.set_yticklabels(list(reversed(streams)))
    ax.set_xlim(t0 / unit, t1 / unit if t1 > t0 else t0 / unit + 1)
    ax.set_xlabel(f"simulated time ({uname})")
    ax.set_title(title)
    handles = [Patch(facecolor=CATEGORY_COLOURS[c], edgecolor="#888" if c == "waiting" else "none",
                     hatch="///" if c == "waiting" else None, label=c.replace("_", " "))
               for c in timeline.CATEGORIES]
    if plans:
        handles.append(Patch(facecolor="#9ecae1", label="measurement plan (top)"))
    ax.legend(handles=handles, loc="upper center", bbox_to_anchor=(0.5, -0.35 if len(streams) < 4 else -0.2),
              ncol=6, fontsize=8, frameon=False)
    return _png(fig)


def histogram_png(errors_um: Sequence[float], title: str) -> str | None:
    if not errors_um:
        return None
    plt = _plt()
    fig, ax = plt.subplots(figsize=(8, 3.5))
    ax.hist(errors_um, bins=min(60, max(10, len(errors_um) // 10)), color="#1f77b4", edgecolor="white")
    ax.axvline(0, color="black", lw=0.8)
    ax.set_xlabel("measured - true (µm)")
    ax.set_ylabel("results")
    ax.set_title(title)
    return _png(fig)


# ------------------------------------------------------------------------------ html
def _e(x: Any) -> str:
    return html.escape("" if x is None else str(x))


def _f(x: float | None, digits: int = 4) -> str:
    return "" if x is None or (isinstance(x, float) and math.isnan(x)) else f"{x:.{digits}f}"


def _swatch(colour: str) -> str:
    return f'<span class="chip" style="background:{colour}"></span>'


def _chip(status: str) -> str:
    return _swatch(STATUS_COLOURS.get(status, "#000"))


def _table(header: Sequence[str], rows: Iterable[Sequence[str]], numeric: Sequence[int] = ()) -> str:
    out = ["<table><tr>" + "".join(f"<th>{_e(h)}</th>" for h in header) + "</tr>"]
    for row in rows:
        out.append("<tr>" + "".join(f'<td class="num">{c}</td>' if i in numeric else f"<td>{c}</td>"
                                    for i, c in enumerate(row)) + "</tr>")
    out.append("</table>")
    return "\n".join(out)


def _hours(seconds: float) -> str:
    return f"{seconds / 3600:.3f} h"


def _summary_html(data: ReportData, s: dict[str, Any]) -> str:
    run = data.run
    rows = [
        ("measurements done", f"{s['done']} of {s['total']}"),
        ("cycle time (simulated)", f"{_hours(s['cycle_s'])} ({s['cycle_s']:.1f} s)"),
    ]
    if s["done"] < s["total"] and s["done"]:
        rows.append((f"projected for all {s['total']} measurements", f"{s['projected_h']:.3f} h"))
    rows += [
        (f"manual method ({MANUAL_HOURS:g} h)", f"{s['speedup_manual']:.1f}x faster"
         if math.isfinite(s["speedup_manual"]) else "n/a"),
        (f"goal of 1987 ({GOAL_HOURS:g} h)", f"{s['ratio_goal']:.2f} of the goal time ("
         + ("met" if s["ratio_goal"] <= 1 else "not met") + ")"),
    ]
    out = [_table(("", ""), [(_e(a), _e(b)) for a, b in rows])]
    scale = max(MANUAL_HOURS, s["projected_h"], 1e-9)
    bars = [("manual method", MANUAL_HOURS, "#999"), ("1987 goal", GOAL_HOURS, "#ff9f1c"),
            ("this run" + (" (projected)" if s["projected_h"] != s["cycle_h"] else ""), s["projected_h"], "#1f77b4")]
    out.append("<table>" + "".join(
        f'<tr><td>{_e(n)}</td><td style="width:600px"><div style="background:{c};height:1em;'
        f'width:{100 * v / scale:.2f}%"></div></td><td class="num">{v:.2f} h</td></tr>' for n, v, c in bars)
        + "</table>")
    out.append("<h3>counts by decision</h3>")
    out.append(_table(("decision", "results"),
                      [(_chip(k) + _e(k.replace("_", " ")), str(v)) for k, v in s["counts"].items()],
                      numeric=(1,)))
    meta = {"run": run.id, "part": run.part, "part directory": run.part_dir, "seed": run.seed,
            "status": run.state_label, "created (UTC)": run.created, "ended (UTC)": run.ended}
    out.append('<p class="meta">' + " · ".join(f"{_e(k)}: {_e(v)}" for k, v in meta.items() if v is not None)
               + "</p>")
    if run.settings:
        out.append(f'<p class="meta">settings: <code>{_e(json.dumps(run.settings, sort_keys=True))}</code></p>')
    return "\n".join(out)


def _exceptions_html(events: Sequence[Event]) -> str:
    exc = [e for e in events if e.kind == "exception"]
    if not exc:
        return "<p>No exceptions.</p>"
    rows = []
    for e in exc:
        p = dict(e.payload)
        rest = {k: v for k, v in p.items() if k not in ("message", "diagnosis", "recovery", "spec")}
        rows.append((str(e.seq), _f(e.sim_time, 1), _e(e.stream), _e(e.spec_id or p.get("spec")),
                     _e(p.get("message")), _e(p.get("diagnosis")), _e(p.get("recovery")),
                     f"<code>{_e(json.dumps(rest, sort_keys=True))}</code>" if rest else ""))
    return f"<p>{len(exc)} exception(s).</p>" + _table(
        ("event", "sim time (s)", "stream", "spec", "message", "diagnosis", "recovery", "details"), rows,
        numeric=(0, 1))


def _breakdown_html(parts: dict[str, float], busy: dict[str, tuple[float, float]], cycle_s: float) -> str:
    if cycle_s <= 0:
        return "<p>No simulated time recorded.</p>"
    bar = '<div class="bar">' + "".join(
        f'<div title="{_e(c)}" style="width:{100 * v / cycle_s:.3f}%;background:{CATEGORY_COLOURS[c]}"></div>'
        for c, v in parts.items() if v > 0) + "</div>"
    rows = [(_swatch(CATEGORY_COLOURS[c]) + _e(c.replace("_", " ")), f"{v:.1f}",
             f"{v / 3600:.3f}", f"{100 * v / cycle_s:.1f} %") for c, v in parts.items()]
    rows.append(("<b>cycle time</b>", f"{cycle_s:.1f}", f"{cycle_s / 3600:.3f}", "100.0 %"))
    out = [bar, _table(("", "s", "h", "share"), rows, numeric=(1, 2, 3)),
           ('<p class="note">Each instant counts once, as the first of measuring, tool change, motion, '
            'other, waiting that any stream is doing; idle: no stream busy.</p>')]
    if busy:
        out.append("<h3>per stream</h3>")
        out.append(_table(("stream", "busy (s)", "utilisation", "waiting (s)"),
                          [(_e(k), f"{b:.1f}", f"{100 * b / cycle_s:.1f} %", f"{w:.1f}")
                           for k, (b, w) in sorted(busy.items())], numeric=(1, 2, 3)))
    return "\n".join(out)


def _results_html(results: Sequence[StoredResult]) -> str:
    rows = []
    for r in results:
        st = status_of(r)
        rows.append((str(r.seq), _e(r.spec_id), _e(r.kind), _e(r.tool), _f(r.value), _f(r.U),
                     _f(r.nominal), f"{r.lower:+.4f} / {r.upper:+.4f}", _chip(st) + _e(st.replace("_", " ")),
                     _e(r.reason)))
    return _table(("#", "spec", "kind", "tool", "value (mm)", "U (mm)", "nominal (mm)", "tolerance (mm)",
                   "decision", "reason"), rows, numeric=(0, 4, 5, 6))


def _scoring_html(data: ReportData, true_values: Mapping[str, float]) -> str:
    from ita.scoring.compare import compare

    sc = compare(data.results, true_values)
    stats = sc.error_stats()
    out = ['<section class="scoring" id="scoring">',
           "<h2>Scoring against the as-built part (simulation only)</h2>",
           ('<p class="note">This section compares the results with the true dimensions of the simulated '
            "part, which the inspection itself never sees. A real inspection has no such section.</p>")]
    out.append(_table(("", ""), [
        ("results scored", str(len(sc.scored))),
        ("false accepts (decided conforms, truly out of tolerance)", str(len(sc.false_accepts))),
        ("false rejects (decided does not conform, truly in tolerance)", str(len(sc.false_rejects))),
        ("nonconformities not proven (uncertain or not measured, truly out)", str(len(sc.missed))),
        ("results without a true value", str(len(sc.unscored))),
    ], numeric=(1,)))
    statuses = [s for s in STATUS_ORDER if any(k[0] == s for k in sc.confusion)]
    out.append("<h3>decision against truth</h3>")
    out.append(_table(("decision", "truly in tolerance", "truly out of tolerance"),
                      [(_chip(s) + _e(s.replace("_", " ")), str(sc.confusion.get((s, True), 0)),
                        str(sc.confusion.get((s, False), 0))) for s in statuses], numeric=(1, 2)))
    if stats["n"]:
        out.append("<h3>measurement error</h3>")
        out.append(_table(("n", "mean (µm)", "std (µm)", "rms (µm)", "max |error| (µm)", "|error| ≤ U"), [(
            str(stats["n"]), f"{1000 * stats['mean']:.2f}", f"{1000 * stats['std']:.2f}",
            f"{1000 * stats['rms']:.2f}", f"{1000 * stats['max_abs']:.2f}", f"{100 * stats['within_u']:.1f} %")],
            numeric=(0, 1, 2, 3, 4, 5)))
        src = histogram_png([1000 * e for e in sc.errors], "error histogram (measured - true)")
        if src:
            out.append(_img(src, "error histogram"))
    wrong = [s for s in sc.scored if s.spec_id in set(sc.false_accepts) | set(sc.false_rejects)]
    if wrong:
        out.append("<h3>wrong decisions</h3>")
        out.append(_table(("spec", "decision", "value (mm)", "true (mm)", "U (mm)"), [
            (_e(s.spec_id), _e(s.status.replace("_", " ")), _f(s.value), _f(s.true_value), _f(s.expanded_u))
            for s in wrong], numeric=(2, 3, 4)))
    out.append("</section>")
    return "\n".join(out)


def render_html(data: ReportData, true_values: Mapping[str, float] | None = None) -> str:
    """The report page for `data`; the scoring section only with `true_values`."""
    s = summary(data)
    t0, t1 = s["start_s"], s["end_s"]
    ivs = timeline.intervals(data.events, t1)
    plans = timeline.plan_intervals(data.events, t1)
    parts = timeline.breakdown(ivs, t0, t1)
    body = [f"<h1>ITA inspection report: run {_e(data.run.id)}</h1>",
            f'<p class="meta">part {_e(data.run.part)}, status {_e(data.run.state_label)}</p>',
            "<h2>Summary</h2>", _summary_html(data, s)]

    body.append("<h2>The part</h2>")
    src = part_map_png(data)
    body.append(_img(src, "part map coloured by decision") if src else "<p>No spec points known.</p>")

    body.append("<h2>Tours</h2>")
    tl = tours(data.results)
    src = tours_png(data)
    if src:
        body.append(_img(src, "tours"))
    if tl:
        if len(tl) > 20:
            body.append(f"<details><summary>{len(tl)} tours</summary>")
        body.append(_table(("tour", "tool", "measurements", "path length (mm)", "simulated time (s)"), [
            (str(i + 1), _e(tool), str(len(rs)), f"{_tour_length(rs):.0f}",
             _f(_tour_time(rs), 1)) for i, (tool, rs) in enumerate(tl)], numeric=(0, 2, 3, 4)))
        if len(tl) > 20:
            body.append("</details>")
    else:
        body.append("<p>No results yet.</p>")

    body.append("<h2>Timeline of the command streams</h2>")
    src = gantt_png(ivs, plans, t0, t1, "command streams over the whole run")
    if src:
        body.append(_img(src, "Gantt chart of the command streams"))
        ends = sorted(r.sim_time_end for r in data.results if r.sim_time_end is not None)
        if len(ends) > DETAIL_PLANS and ends[DETAIL_PLANS - 1] < t1:
            detail = gantt_png(ivs, plans, t0, ends[DETAIL_PLANS - 1],
                               f"detail: the first {DETAIL_PLANS} measurements (WAITs hatched)")
            body.append(_img(detail, "Gantt chart, detail"))
        n_wait = sum(1 for iv in ivs if iv.category == "waiting")
        body.append(f'<p class="note">{len(ivs) - n_wait} commands, {n_wait} WAITs.</p>')
    else:
        body.append("<p>No commands recorded.</p>")

    body.append("<h2>Exceptions</h2>")
    body.append(_exceptions_html(data.events))

    body.append("<h2>Cycle-time breakdown</h2>")
    body.append(_breakdown_html(parts, timeline.stream_busy(ivs), t1 - t0))

    body.append("<h2>Results</h2>")
    failed = [r for r in data.results if r.failed]
    body.append(f"<details{' open' if 0 < len(failed) <= 50 else ''}><summary>{len(failed)} results not "
                f"proven to conform</summary>{_results_html(failed)}</details>")
    body.append(f"<details><summary>all {len(data.results)} results</summary>{_results_html(data.results)}"
                "</details>")

    if true_values is not None:
        body.append(_scoring_html(data, true_values))

    return ("<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">"
            f"<title>ITA report {_e(data.run.id)}</title><style>{CSS}</style></head><body>\n"
            + "\n".join(body) + "\n</body></html>\n")


def _tour_time(rs: Sequence[StoredResult]) -> float | None:
    a = [r.sim_time_start for r in rs if r.sim_time_start is not None]
    b = [r.sim_time_end for r in rs if r.sim_time_end is not None]
    return max(b) - min(a) if a and b else None
