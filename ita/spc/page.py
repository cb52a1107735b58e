"""The SPC view's sections for the System Monitor's /spc page (drawn by ita.js like the
report's sections: "kv" tables and plotly "figure"s)."""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

from ita.spc.chart import Chart
from ita.spc.series import SerialRun

__all__ = ["FIGURES", "spc_sections"]

#: I-MR charts drawn: the flagged characteristics first, then the lowest Cpk
FIGURES = 6


def _num(x: float | None, digits: int = 4) -> str:
    return "-" if x is None or not math.isfinite(x) else f"{x:.{digits}f}"


def _figure(c: Chart) -> dict[str, Any]:
    s = c.series
    x = list(s.serials)
    mr = [None] + [abs(b - a) for a, b in zip(s.values, s.values[1:])]
    flagged = {sn for f in c.flags for sn in f.serials}
    line = {"type": "scatter", "mode": "lines+markers", "x": x, "y": list(s.values), "name": "value",
            "marker": {"color": ["#d62728" if sn in flagged else "#1f77b4" for sn in x]}, "xaxis": "x", "yaxis": "y"}
    limits = [{"type": "scatter", "mode": "lines", "x": [x[0], x[-1]], "y": [v, v], "name": name,
               "line": {"dash": dash, "color": colour}, "xaxis": "x", "yaxis": "y"}
              for name, v, dash, colour in (("UCL", c.ucl, "dash", "#888"), ("centre", c.centre, "solid", "#888"),
                                            ("LCL", c.lcl, "dash", "#888"),
                                            ("tolerance", s.high, "dot", "#d62728"))
              + ((("tolerance", s.low, "dot", "#d62728"),) if s.low is not None else ())
              if math.isfinite(v)]
    mr_trace = {"type": "bar", "x": x, "y": mr, "name": "moving range", "xaxis": "x2", "yaxis": "y2",
                "marker": {"color": "#9ecae1"}}
    mr_ucl = {"type": "scatter", "mode": "lines", "x": [x[0], x[-1]], "y": [c.mr_ucl, c.mr_ucl], "name": "MR UCL",
              "line": {"dash": "dash", "color": "#888"}, "xaxis": "x2", "yaxis": "y2"}
    return {"data": [line, *limits, mr_trace, mr_ucl],
            "layout": {"height": 380, "showlegend": False, "margin": {"t": 10, "l": 60, "r": 10, "b": 40},
                       "grid": {"rows": 2, "columns": 1, "roworder": "top to bottom"},
                       "yaxis": {"title": f"{s.id} (mm)", "domain": [0.38, 1.0]},
                       "yaxis2": {"title": "MR (mm)", "domain": [0.0, 0.28]},
                       "xaxis": {"anchor": "y", "showticklabels": False}, "xaxis2": {"anchor": "y2"}}}


def spc_sections(part: str, serials: Sequence[SerialRun], charts: Sequence[Chart], q: float,
                 selected: str | None = None) -> list[dict[str, Any]]:
    """The page's sections: the summary, the characteristics' table (flagged first, then by
    Cpk), and I-MR charts of the flagged ones, the lowest Cpk and the selected one."""
    flagged = [c for c in charts if c.flags]
    rest = sorted((c for c in charts if not c.flags), key=lambda c: c.cpk if c.cpk is not None else math.inf)
    ordered = flagged + rest
    summary = [("design", part), ("serials", f"{len(serials)}: " + ", ".join(s.serial for s in serials)),
               ("characteristics charted", str(len(charts))),
               ("flagged (special cause)", f"{len(flagged)} (Benjamini-Hochberg over the characteristics, q = {q:g})"),
               ("with a point beyond 3 sigma", f"{sum(1 for c in charts if c.beyond_3_sigma)} (plain Shewhart: "
                                               "not flagged on that alone)")]
    rows = [(c.series.id, c.series.kind, str(c.n), _num(c.mean), _num(c.sd), _num(c.cp, 2), _num(c.cpk, 2),
             "-" if c.cpk_ci is None else f"{c.cpk_ci[0]:.2f} .. {c.cpk_ci[1]:.2f}",
             "; ".join(f"{f.rule} at {', '.join(f.serials)} (q {f.q:.2g})" for f in c.flags))
            for c in ordered]
    sections: list[dict[str, Any]] = [
        {"kind": "kv", "id": "spc_summary", "title": "SPC across serials", "header": ["", ""], "rows": summary,
         "note": "Per characteristic over the serials (each serial's latest run): mean, standard deviation, Cp, "
                 "Cpk with its 95 % interval, and an individuals and moving-range chart. Special causes: one "
                 "serial unlike the others, or a step in the later serials."},
        {"kind": "kv", "id": "spc_table", "title": f"Characteristics ({len(charts)})",
         "header": ["characteristic", "kind", "n", "mean", "sd", "Cp", "Cpk", "Cpk 95 %", "flag"], "rows": rows,
         "collapsed": len(rows) > 40}]
    drawn = [c for c in ordered if c.n >= 2][:FIGURES]
    chosen = next((c for c in charts if c.series.id == selected), None)
    if chosen is not None and chosen not in drawn:
        drawn.insert(0, chosen)
    for c in drawn:
        why = "flagged: " + "; ".join(f"{f.rule} at {', '.join(f.serials)}" for f in c.flags) if c.flags else \
            f"Cpk {_num(c.cpk, 2)}"
        sections.append({"kind": "figure", "id": f"spc-{c.series.id}", "title": f"{c.series.id} ({why})",
                         "figure": _figure(c)})
    return sections
