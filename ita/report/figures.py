"""Interactive charts as plotly.js figure specifications: plain JSON-ready dicts.

    fig = gantt_figure(data.events, data.results)       # {"data": [...], "layout": {...}}

The browser draws them with the plotly.js that ships in the plotly wheel (served by
`ita serve`, inlined in the HTML report): no figure needs the plotly Python package.
Lines with `None` between segments stand for many bars at once, which stays fast for a
whole run (tens of thousands of commands).
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping, Sequence
from typing import Any

import numpy as np

from ita.archive import timeline
from ita.archive.model import Event, StoredResult
from ita.report.data import STATUS_COLOURS, STATUS_ORDER, SpecPoint, status_of

CATEGORY_COLOURS = {"exceptions": "#d62728", "measuring": "#1f77b4", "tool_change": "#9467bd", "motion": "#ff7f0e",
                    "other": "#8c8c8c", "waiting": "#b0b0b0"}
STREAM_ORDER = ("top", "arm", "slra", "gauge")
MARK_COLOURS = {"interrupt": "#ff9f1c", "stop": "#d62728", "resume": "#2ca02c", "exception": "#d62728",
                "recovery": "#9467bd"}
FONT = {"family": "system-ui, -apple-system, Segoe UI, Helvetica, Arial, sans-serif", "size": 12}


def _r(x: float | None, digits: int = 3) -> float | None:
    return None if x is None or not math.isfinite(x) else round(float(x), digits)


# --------------------------------------------------------------------------- Gantt
#: marks of the Gantt chart closer than this share of its span share one label
MARK_GAP_SHARE = 0.03


def _mark_labels(marks: Sequence[Event], gap: float) -> list[dict[str, Any]]:
    """One label per group of marks (interrupts, stops, resumptions, exceptions,
    recoveries) closer than `gap` seconds to the one before: its kind, with a count when
    several ("EXCEPTION x3"), the group's times and kinds on hover; labels of groups near
    each other alternate between two heights, so none lies on another."""
    groups: list[list[Event]] = []
    for e in sorted(marks, key=lambda e: float(e.sim_time or 0.0)):
        if groups and float(e.sim_time or 0.0) - float(groups[-1][-1].sim_time or 0.0) < gap:
            groups[-1].append(e)
        else:
            groups.append([e])
    out: list[dict[str, Any]] = []
    for k, g in enumerate(groups):
        kinds = sorted({e.kind for e in g})
        head = g[0]
        text = (kinds[0].upper() if len(kinds) == 1 else f"{len(g)} EVENTS") + (f" x{len(g)}" if len(kinds) == 1
                                                                               and len(g) > 1 else "")
        hover = "<br>".join(f"{e.sim_time:.1f} s {e.kind}" for e in g[:12]) + ("<br>..." if len(g) > 12 else "")
        out.append({"x": head.sim_time, "yref": "paper", "y": 1.02 if k % 2 == 0 else 1.10, "text": text,
                    "hovertext": hover, "showarrow": False, "xanchor": "left",
                    "font": {"color": MARK_COLOURS[head.kind if len(kinds) == 1 else "exception"], "size": 10}})
    return out


def gantt_figure(events: Sequence[Event], results: Sequence[StoredResult] = ()) -> dict[str, Any]:
    """The command streams over simulated time: commands coloured by category, WAITs as
    dotted grey bars, the measurement plans on the top stream (hover: the spec), and
    vertical marks where the run was interrupted, stopped, resumed, or met an exception."""
    start, end = timeline.span(events, results)
    ivs = timeline.intervals(events, end)
    plans = timeline.plan_intervals(events, end)
    streams = [s for s in STREAM_ORDER if (s == "top" and plans) or any(iv.stream == s for iv in ivs)]
    streams += sorted({iv.stream for iv in ivs} - set(streams))
    traces: list[dict[str, Any]] = []

    def segs(items: Iterable[timeline.Interval], y: str) -> tuple[list, list, list]:
        xs: list[Any] = []
        ys: list[Any] = []
        text: list[Any] = []
        for iv in items:
            label = f"{iv.label} ({iv.spec_id})" if iv.spec_id and iv.spec_id != iv.label else iv.label
            hover = f"{label}<br>{iv.start:.2f} to {iv.end:.2f} s ({iv.duration:.2f} s)"
            xs += [_r(iv.start), _r(max(iv.end, iv.start + 1e-3)), None]
            ys += [y, y, None]
            text += [hover, hover, None]
        return xs, ys, text

    if plans:
        for j, colour in enumerate(("#9ecae1", "#c6dbef")):
            xs, ys, text = segs(plans[j::2], "top")
            traces.append({"type": "scatter", "mode": "lines", "x": xs, "y": ys, "text": text,
                           "hoverinfo": "text", "line": {"color": colour, "width": 14},
                           "name": "measurement plan", "legendgroup": "plan", "showlegend": j == 0})
    for cat in timeline.CATEGORIES:
        mine = [iv for iv in ivs if iv.category == cat]
        if not mine:
            continue
        xs, ys, text = [], [], []
        for s in streams:
            a, b, c = segs((iv for iv in mine if iv.stream == s), s)
            xs += a
            ys += b
            text += c
        waiting = cat == "waiting"
        traces.append({"type": "scatter", "mode": "lines", "x": xs, "y": ys, "text": text, "hoverinfo": "text",
                       "name": "WAIT (until CONTINUE)" if waiting else cat.replace("_", " "),
                       "line": {"color": CATEGORY_COLOURS[cat], "width": 6 if waiting else 14,
                                "dash": "dot" if waiting else "solid"}})
    shapes: list[dict[str, Any]] = []
    marks = [e for e in events if e.kind in MARK_COLOURS and e.sim_time is not None]
    for e in marks:
        colour = MARK_COLOURS[e.kind]
        shapes.append({"type": "line", "x0": e.sim_time, "x1": e.sim_time, "yref": "paper", "y0": 0, "y1": 1,
                       "line": {"color": colour, "width": 1.5, "dash": "dash" if e.kind != "exception" else "dot"}})
    annotations = _mark_labels(marks, max(end - start, 1e-9) * MARK_GAP_SHARE)
    return {"data": traces, "layout": {
        "font": FONT, "height": 130 + 55 * max(len(streams), 1), "margin": {"l": 60, "r": 20, "t": 50, "b": 50},
        "xaxis": {"title": {"text": "simulated time (s)"}, "range": [start, end if end > start else start + 1],
                  "zeroline": False},
        "yaxis": {"categoryorder": "array", "categoryarray": list(reversed(streams)), "type": "category"},
        "legend": {"orientation": "h", "y": -0.35}, "hovermode": "closest", "shapes": shapes,
        "annotations": annotations, "dragmode": "zoom"}}


def zone_spans(zone_events: Sequence[Sequence[Any]]) -> tuple[list[tuple[float, float]], list[tuple[float, float]]]:
    """An arm's claims from the zone conductor's record (``[t, kind, zones]`` in order):
    the spans it held a motion's zones (granted or continued, to its clear) and the spans
    it waited for the other arm (its wait, to its continue)."""
    held: list[tuple[float, float]] = []
    waits: list[tuple[float, float]] = []
    since: float | None = None
    asked: float | None = None
    for row in zone_events:
        t, kind = float(row[0]), str(row[1])
        if kind == "wait":
            asked = t
        elif kind in ("grant", "continue"):
            if kind == "continue" and asked is not None and t > asked:
                waits.append((asked, t))
            asked, since = None, t
        elif kind == "clear" and since is not None:
            held.append((since, t))
            since = None
    return held, waits


def two_arm_gantt_figure(group: Sequence[tuple[str, Sequence[Event]]]) -> dict[str, Any]:
    """Both arms of a two-arm run over one simulated time: a lane per arm and stream
    (commands coloured by category, WAITs dotted) and a lane per arm of its zone claims
    (the spans it held a motion's zones, and dotted, the spans it waited for the other
    arm's release), from each arm's run and its ``zones`` event."""
    traces: list[dict[str, Any]] = []
    lanes: list[str] = []
    bars: dict[tuple[str, str, bool], tuple[list, list, list]] = {}

    def add(key: tuple[str, str, bool], lane: str, start: float, end: float, hover: str) -> None:
        xs, ys, text = bars.setdefault(key, ([], [], []))
        xs += [_r(start), _r(max(end, start + 1e-3)), None]
        ys += [lane, lane, None]
        text += [hover, hover, None]

    end_s = 0.0
    for arm, events in group:
        ivs = timeline.intervals(events)
        streams = [st for st in STREAM_ORDER if st != "top" and any(iv.stream == st for iv in ivs)]
        streams += sorted({iv.stream for iv in ivs} - set(streams) - {"top"})
        for st in streams:
            lane = f"{arm} {st}"
            lanes.append(lane)
            for iv in ivs:
                if iv.stream == st:
                    label = f"{iv.label} ({iv.spec_id})" if iv.spec_id and iv.spec_id != iv.label else iv.label
                    add((iv.category, "", iv.category == "waiting"), lane, iv.start, iv.end,
                        f"{arm}: {label}<br>{iv.start:.2f} to {iv.end:.2f} s")
                    end_s = max(end_s, iv.end)
        zones = next((e for e in reversed(events) if e.kind == "zones"), None)
        if zones is not None:
            lane = f"{arm} zones"
            lanes.append(lane)
            held, waits = zone_spans(zones.payload.get("events") or [])
            for a, b in held:
                add(("zones", "held", False), lane, a, b, f"{arm} holds a motion's zones<br>{a:.2f} to {b:.2f} s")
            for a, b in waits:
                add(("zones", "wait", True), lane, a, b,
                    f"{arm} waits for the other arm's zones<br>{a:.2f} to {b:.2f} s ({b - a:.1f} s)")
                end_s = max(end_s, b)
    for (cat, what, dotted), (xs, ys, text) in bars.items():
        if cat == "zones":
            name = "waiting for the other arm's zones" if what == "wait" else "zones held (a motion's claim)"
            colour = "#d62728" if what == "wait" else "#8c8c8c"
        else:
            name = "WAIT (until CONTINUE)" if cat == "waiting" else cat.replace("_", " ")
            colour = CATEGORY_COLOURS[cat]
        traces.append({"type": "scatter", "mode": "lines", "x": xs, "y": ys, "text": text, "hoverinfo": "text",
                       "name": name, "line": {"color": colour, "width": 6 if dotted else 14,
                                              "dash": "dot" if dotted else "solid"}})
    return {"data": traces, "layout": {
        "font": FONT, "height": 130 + 45 * max(len(lanes), 1), "margin": {"l": 90, "r": 20, "t": 30, "b": 50},
        "xaxis": {"title": {"text": "simulated time (s)"}, "range": [0.0, end_s if end_s > 0 else 1.0],
                  "zeroline": False},
        "yaxis": {"categoryorder": "array", "categoryarray": list(reversed(lanes)), "type": "category"},
        "legend": {"orientation": "h", "y": -0.3}, "hovermode": "closest", "dragmode": "zoom"}}


# ---------------------------------------------------------------------- breakdown
#: a colour per tour of the Sequence Planner's tours figure (cycled)
TOUR_COLOURS = ("#1f77b4", "#ff7f0e", "#2ca02c", "#9467bd", "#8c564b", "#e377c2", "#17becf", "#bcbd22")


def tours_figure(tours: Sequence[tuple[str, Sequence[StoredResult]]], todo: Sequence[SpecPoint] = (),
                 next_spec: SpecPoint | None = None) -> dict[str, Any]:
    """The Sequence Planner's tours drawn on the part, seen from above: each tour (the
    measurements one tool made in a row) as a path in the order they were made, the
    measurements still to make (in the run's order) in grey, the next one marked."""
    traces: list[dict[str, Any]] = []
    for i, (tool, rs) in enumerate(tours):
        pts = [(r.spec_id, r.point) for r in rs if r.point is not None]
        if not pts:
            continue
        colour = TOUR_COLOURS[i % len(TOUR_COLOURS)]
        traces.append({"type": "scatter", "mode": "lines+markers", "name": f"tour {i + 1}: {tool} ({len(pts)})",
                       "x": [_r(p[0], 1) for _, p in pts], "y": [_r(p[1], 1) for _, p in pts],
                       "customdata": [sid for sid, _ in pts], "text": [sid for sid, _ in pts],
                       "hovertemplate": "%{text}<extra>" + tool + "</extra>",
                       "line": {"color": colour, "width": 1.5}, "marker": {"size": 5, "color": colour}})
    if todo:
        traces.append({"type": "scatter", "mode": "lines+markers", "name": f"still to measure ({len(todo)})",
                       "x": [_r(s.point[0], 1) for s in todo], "y": [_r(s.point[1], 1) for s in todo],
                       "text": [s.id for s in todo], "hovertemplate": "%{text}<extra>to measure</extra>",
                       "line": {"color": "#b0b0b0", "width": 1, "dash": "dot"},
                       "marker": {"size": 4, "color": "#b0b0b0"}})
    if next_spec is not None:
        traces.append({"type": "scatter", "mode": "markers+text", "name": f"next: {next_spec.id}",
                       "x": [_r(next_spec.point[0], 1)], "y": [_r(next_spec.point[1], 1)], "text": ["next"],
                       "textposition": "top center", "marker": {"size": 16, "symbol": "star", "color": "#d62728"}})
    return {"data": traces, "layout": {
        "height": 560, "margin": {"l": 60, "r": 20, "t": 30, "b": 50}, "legend": {"orientation": "h", "y": -0.12},
        "xaxis": {"title": {"text": "x (mm)"}}, "yaxis": {"title": {"text": "y (mm)"}, "scaleanchor": "x"}}}


def breakdown_figure(parts: Mapping[str, float], cycle_s: float) -> dict[str, Any]:
    """The cycle time split into measuring, tool change, motion, other, waiting, idle."""
    colours = CATEGORY_COLOURS | {"idle": "#eeeeee"}
    data = [{"type": "bar", "orientation": "h", "y": ["cycle"], "x": [round(v, 2)], "name": k.replace("_", " "),
             "marker": {"color": colours.get(k, "#ccc"), "line": {"color": "#999", "width": 0.5}},
             "hovertemplate": f"{k.replace('_', ' ')}: %{{x:.1f}} s ({100 * v / cycle_s if cycle_s else 0:.1f} %)"
                              "<extra></extra>"}
            for k, v in parts.items() if v > 0]
    return {"data": data, "layout": {"font": FONT, "barmode": "stack", "height": 170,
                                     "margin": {"l": 50, "r": 20, "t": 10, "b": 60},
                                     "xaxis": {"title": {"text": "simulated seconds"}},
                                     "legend": {"orientation": "h", "y": -0.6}}}


# ------------------------------------------------------------------------ the part
def mesh_trace(vertices: Any, faces: Any, *, name: str = "part", colour: str = "#b8c4d0",
               opacity: float = 1.0, digits: int = 1) -> dict[str, Any]:
    """A mesh3d trace of vertices (n, 3) and faces (m, 3)."""
    v = np.round(np.asarray(vertices, dtype=float), digits)
    f = np.asarray(faces, dtype=int)
    return {"type": "mesh3d", "x": v[:, 0].tolist(), "y": v[:, 1].tolist(), "z": v[:, 2].tolist(),
            "i": f[:, 0].tolist(), "j": f[:, 1].tolist(), "k": f[:, 2].tolist(), "color": colour,
            "opacity": opacity, "name": name, "hoverinfo": "skip", "flatshading": True,
            "lighting": {"ambient": 0.55, "diffuse": 0.6, "specular": 0.1}, "showscale": False}


#: deviation over the tolerance, -1.5 .. +1.5, as inspection software shows it: green within
#: the tolerance (paler toward its limits), red beyond the upper limit, blue beyond the lower
DEVIATION_COLOURS = [[0.0, "#08306b"], [0.1666, "#4292c6"], [0.1667, "#a1d99b"], [0.5, "#2ca02c"],
                     [0.8333, "#a1d99b"], [0.8334, "#ef3b2c"], [1.0, "#67000d"]]


def _deviation_share(r: StoredResult) -> float | None:
    """Deviation from nominal over half the tolerance band: 0 on nominal, +-1 at a limit
    (with an asymmetric band, the limit on the deviation's side)."""
    if r.value is None:
        return None
    d = r.value - r.nominal
    half = r.upper if d >= 0 else -r.lower
    return d / half if half > 0 else None


def part_figure(specs: Sequence[SpecPoint], results: Sequence[StoredResult], mesh: Any = None,
                *, lift_mm: float = 1.5) -> dict[str, Any]:
    """The part in 3-D (part frame, mm) with every measurement: one trace per decision
    (hover: id, kind, value, decision), and a second colouring by deviation over the
    tolerance, switched by the buttons above the plot.  mesh: (vertices, faces) or None."""
    by_id = {r.spec_id: r for r in results}
    normals = {s.id: s.normal for s in specs}
    traces: list[dict[str, Any]] = []
    if mesh is not None:
        traces.append(mesh_trace(*mesh, opacity=1.0))

    def lifted(ids: Sequence[str], pts: Sequence[Sequence[float]]) -> np.ndarray:
        p = np.asarray(pts, dtype=float).reshape(-1, 3)
        n = np.asarray([normals.get(i) or (0.0, 0.0, 1.0) for i in ids], dtype=float).reshape(-1, 3)
        return np.round(p + lift_mm * n, 2)

    groups: dict[str, list[SpecPoint]] = {}
    for s in specs:
        r = by_id.get(s.id)
        groups.setdefault(status_of(r) if r is not None else "not_attempted", []).append(s)
    n_decision = 0
    for st in STATUS_ORDER + ("not_attempted",):
        members = groups.get(st, [])
        if not members:
            continue
        p = lifted([m.id for m in members], [m.point for m in members])
        text = []
        for m in members:
            r = by_id.get(m.id)
            value = "" if r is None or r.value is None else f"<br>value {r.value:.4f} mm (nominal {r.nominal:.4f})"
            text.append(f"<b>{m.id}</b> {m.kind or ''}{value}<br>{st.replace('_', ' ')}")
        traces.append({"type": "scatter3d", "mode": "markers", "x": p[:, 0].tolist(), "y": p[:, 1].tolist(),
                       "z": p[:, 2].tolist(), "text": text, "customdata": [m.id for m in members],
                       "hoverinfo": "text", "name": f"{st.replace('_', ' ')} ({len(members)})",
                       "marker": {"size": 3 if st in ("conforms", "not_attempted") else 5,
                                  "color": STATUS_COLOURS[st]}})
        n_decision += 1
    measured: list[tuple[SpecPoint, float, float]] = []   # (spec, deviation from nominal, its share)
    for s in specs:
        r = by_id.get(s.id)
        share = None if r is None else _deviation_share(r)
        if r is not None and r.value is not None and share is not None:
            measured.append((s, r.value - r.nominal, share))
    if measured:
        p = lifted([m.id for m, _, _ in measured], [m.point for m, _, _ in measured])
        dev = [d for _, _, d in measured]
        traces.append({"type": "scatter3d", "mode": "markers", "x": p[:, 0].tolist(), "y": p[:, 1].tolist(),
                       "z": p[:, 2].tolist(), "customdata": [m.id for m, _, _ in measured], "visible": False,
                       "text": [f"<b>{m.id}</b> {m.kind or ''}<br>deviation {deviation:+.4f}"
                                f" mm = {d:+.2f} of the tolerance" for m, deviation, d in measured],
                       "hoverinfo": "text", "name": "deviation / tolerance",
                       "marker": {"size": 4, "color": [round(d, 3) for d in dev], "cmin": -1.5, "cmax": 1.5,
                                  "colorscale": DEVIATION_COLOURS, "showscale": True,
                                  "colorbar": {"title": {"text": "deviation /<br>tolerance"}, "len": 0.6}}})
    base = [True] if mesh is not None else []
    by_decision = base + [True] * n_decision + ([False] if measured else [])
    by_deviation = base + [False] * n_decision + ([True] if measured else [])
    menus = [{"type": "buttons", "direction": "right", "x": 0, "y": 1.08, "xanchor": "left", "showactive": True,
              "buttons": [{"label": "colour by decision", "method": "restyle", "args": [{"visible": by_decision}]},
                          {"label": "colour by deviation", "method": "restyle",
                           "args": [{"visible": by_deviation}]}]}] if measured else []
    return {"data": traces, "layout": {
        "font": FONT, "height": 640, "margin": {"l": 0, "r": 0, "t": 40, "b": 0}, "updatemenus": menus,
        "legend": {"x": 0, "y": 0.95}, "uirevision": "part",
        "scene": {"aspectmode": "data", "xaxis": {"title": {"text": "x (mm)"}},
                  "yaxis": {"title": {"text": "y (mm)"}}, "zaxis": {"title": {"text": "z (mm)"}},
                  "camera": {"eye": {"x": 0.15, "y": -2.0, "z": 3.4}}}}}


def links_trace(segments: Any, name: str, digits: int | None = None) -> dict[str, Any]:
    """An arm's tubes (t, 2, 3 segment ends, world m) as one line trace; digits: rounded so."""
    xs: list[Any] = []
    ys: list[Any] = []
    zs: list[Any] = []
    for a, b in np.asarray(segments, dtype=float):
        if digits is not None:
            a, b = a.round(digits), b.round(digits)
        xs += [float(a[0]), float(b[0]), None]
        ys += [float(a[1]), float(b[1]), None]
        zs += [float(a[2]), float(b[2]), None]
    return {"type": "scatter3d", "mode": "lines", "x": xs, "y": ys, "z": zs, "name": name,
            "line": {"color": "#333", "width": 9}, "hoverinfo": "name"}


def workcell_figure(boxes: Sequence[Any], part_mesh_world: Any, paths: Sequence[Mapping[str, Any]],
                    arm_links: Any = None, spec_point_world: Sequence[float] | None = None) -> dict[str, Any]:
    """A measurement's flown arm path in the workcell (world frame, m): the fixed boxes,
    the part, the tool point's path of each arm command (hover: command and time), and
    the arm (links as lines) where the plan left it."""
    traces: list[dict[str, Any]] = []
    for box in boxes:
        v, f = box
        traces.append(mesh_trace(v, f, name="cell", colour="#d9d2c5", opacity=0.35, digits=4))
    if part_mesh_world is not None:
        traces.append(mesh_trace(*part_mesh_world, colour="#9fb3c8", digits=4))
    palette = ("#d62728", "#1f77b4", "#2ca02c", "#ff7f0e", "#9467bd", "#8c564b")
    for i, p in enumerate(paths):
        tcp = np.asarray(p.get("tcp") or [], dtype=float).reshape(-1, 3)
        if not len(tcp):
            continue
        t0 = p.get("t0") or 0.0
        times = list(p.get("times") or [0.0] * len(tcp))
        traces.append({"type": "scatter3d", "mode": "lines+markers", "x": tcp[:, 0].round(4).tolist(),
                       "y": tcp[:, 1].round(4).tolist(), "z": tcp[:, 2].round(4).tolist(),
                       "name": f"{p.get('cmd', '')} {p.get('name', '')} ({p.get('tool') or 'no tool'})",
                       "text": [f"{p.get('name', '')} {p.get('cmd', '')}<br>t = {t0 + t:.2f} s" for t in times],
                       "hoverinfo": "text", "line": {"color": palette[i % len(palette)], "width": 5},
                       "marker": {"size": 2, "color": palette[i % len(palette)]}})
    if arm_links is not None:
        traces.append(links_trace(arm_links, "arm at the end"))
    if spec_point_world is not None:
        x, y, z = (float(c) for c in spec_point_world)
        traces.append({"type": "scatter3d", "mode": "markers", "x": [x], "y": [y], "z": [z], "name": "the measurement",
                       "marker": {"size": 6, "color": "#ffcc00", "symbol": "diamond"}})
    return {"data": traces, "layout": {
        "font": FONT, "height": 560, "margin": {"l": 0, "r": 0, "t": 10, "b": 0}, "legend": {"x": 0, "y": 1},
        "scene": {"aspectmode": "data", "xaxis": {"title": {"text": "x (m)"}}, "yaxis": {"title": {"text": "y (m)"}},
                  "zaxis": {"title": {"text": "z (m)"}}}}}


# -------------------------------------------------------------------- range image
def range_image_figure(range_m: Any, intensity: Any, overlay: Mapping[str, Any] | None = None,
                       title: str = "") -> dict[str, Any]:
    """The range image (mm, colour bar) with Vision's patch, rim or edge points, fitted
    circle and the nominal point drawn over it; the intensity image a button away.
    Pixel axes: row down, column across, as the SLRA scans."""
    rng = np.asarray(range_m, dtype=float) * 1000.0
    inten = np.asarray(intensity, dtype=float)

    def grid(a: np.ndarray, digits: int) -> list:
        return [[None if not math.isfinite(v) else round(float(v), digits) for v in row] for row in a]

    finite = rng[np.isfinite(rng)]
    if finite.size:    # the surfaces near the view, not the far floor: the median's neighbourhood
        med = float(np.median(finite))
        lo = float(np.percentile(finite, 1))
        hi = min(float(np.percentile(finite, 99)), med + max(med - lo, 5.0) + 60.0)
    else:
        lo, hi = 0.0, 1.0
    traces: list[dict[str, Any]] = [
        {"type": "heatmap", "z": grid(rng, 2), "colorscale": "Viridis", "zmin": round(lo, 2), "zmax": round(hi, 2),
         "name": "range", "colorbar": {"title": {"text": "range (mm)"}},
         "hovertemplate": "row %{y}, col %{x}<br>range %{z:.2f} mm<extra></extra>"},
        {"type": "heatmap", "z": grid(inten, 3), "colorscale": "Greys", "reversescale": True, "visible": False,
         "name": "intensity", "colorbar": {"title": {"text": "intensity"}},
         "hovertemplate": "row %{y}, col %{x}<br>intensity %{z:.3f}<extra></extra>"}]
    shapes: list[dict[str, Any]] = []
    ov = dict(overlay or {})
    if ov.get("patch"):
        r0, r1, c0, c1 = ov["patch"]
        shapes.append({"type": "rect", "x0": c0 - 0.5, "x1": c1 - 0.5, "y0": r0 - 0.5, "y1": r1 - 0.5,
                       "line": {"color": "white", "width": 1.5, "dash": "dash"}})
    for key, colour, label in (("rim", "#ff3030", "rim points (edge pixels Vision used)"),
                               ("edge", "#ffa500", "edge points")):
        pts = ov.get(key) or []
        if pts:
            traces.append({"type": "scatter", "mode": "markers", "x": [p[1] for p in pts], "y": [p[0] for p in pts],
                           "name": label, "marker": {"size": 3, "color": colour}, "hoverinfo": "name"})
    if ov.get("circle"):
        c = ov["circle"]
        mm = ov.get("circle_mm") or {}
        label = "fitted circle" + (f" (r = {mm['radius']:.4f} mm)" if "radius" in mm else "")
        traces.append({"type": "scatter", "mode": "lines", "x": [p[1] for p in c], "y": [p[0] for p in c],
                       "name": label, "line": {"color": "#00e5ff", "width": 2}, "hoverinfo": "name"})
    if ov.get("nominal"):
        r, c = ov["nominal"]
        traces.append({"type": "scatter", "mode": "markers", "x": [c], "y": [r], "name": "nominal point",
                       "marker": {"symbol": "x", "size": 10, "color": "white", "line": {"color": "black", "width": 1}},
                       "hoverinfo": "name"})
    n_over = len(traces) - 2
    menus = [{"type": "buttons", "direction": "right", "x": 0, "y": 1.12, "xanchor": "left",
              "buttons": [{"label": "range", "method": "restyle",
                           "args": [{"visible": [True, False] + [True] * n_over}]},
                          {"label": "intensity", "method": "restyle",
                           "args": [{"visible": [False, True] + [True] * n_over}]}]}]
    h, w = rng.shape
    return {"data": traces, "layout": {
        "font": FONT, "title": {"text": title, "font": {"size": 13}}, "height": 560, "updatemenus": menus,
        "margin": {"l": 50, "r": 20, "t": 70, "b": 40}, "shapes": shapes,
        "xaxis": {"title": {"text": "column (pixel)"}, "range": [-0.5, w - 0.5], "constrain": "domain"},
        "yaxis": {"title": {"text": "row (pixel)"}, "range": [h - 0.5, -0.5], "scaleanchor": "x"},
        "legend": {"orientation": "h", "y": -0.12}}}


# -------------------------------------------------------------------------- scoring
def error_histogram_figure(errors_by_kind: Mapping[str, Sequence[float]]) -> dict[str, Any]:
    """Measurement error (measured - true, µm) per measurement kind, one histogram each
    (click a legend entry to hide a kind)."""
    data = [{"type": "histogram", "x": [round(e, 3) for e in errs], "name": f"{kind} ({len(errs)})",
             "opacity": 0.7, "nbinsx": 40} for kind, errs in sorted(errors_by_kind.items()) if errs]
    return {"data": data, "layout": {"font": FONT, "barmode": "overlay", "height": 340,
                                     "margin": {"l": 60, "r": 20, "t": 10, "b": 50},
                                     "xaxis": {"title": {"text": "measured - true (µm)"}},
                                     "yaxis": {"title": {"text": "results"}}}}
