"""The Path Planner's paths of a whole run in one 3-D view: every arm move the run made
(the tool point's path, as each result's details keep it), one colour per tool, in the
workcell with the part.

    figure = run_paths_figure(archive, run_id, scene)     # None: no path kept
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ita.archive.store import Archive
from ita.report import figures

__all__ = ["MAX_POINTS_PER_MOVE", "run_paths_figure"]

#: a move's path keeps at most this many of its points in the run's view
MAX_POINTS_PER_MOVE = 40

_PALETTE = ("#d62728", "#1f77b4", "#2ca02c", "#ff7f0e", "#9467bd", "#8c564b", "#17becf", "#e377c2")


def run_paths_figure(archive: Archive, run_id: str, scene: Any) -> dict[str, Any] | None:
    """Every move of the run in the workcell (world frame, m): the cell's boxes, the part,
    and per tool the tool point's paths (a gap between moves); hover: the measurement and
    the command.  None when the run kept no path."""
    by_tool: dict[str, tuple[list[Any], list[Any], list[Any], list[str]]] = {}
    moves = 0
    for r in archive.results(run_id):
        for p in archive.details(run_id, r.spec_id).get("arm_paths") or []:
            tcp = np.asarray(p.get("tcp") or [], dtype=float).reshape(-1, 3)
            if not len(tcp):
                continue
            if len(tcp) > MAX_POINTS_PER_MOVE:
                keep = np.unique(np.linspace(0, len(tcp) - 1, MAX_POINTS_PER_MOVE).round().astype(int))
                tcp = tcp[keep]
            xs, ys, zs, text = by_tool.setdefault(str(p.get("tool") or "no tool"), ([], [], [], []))
            xs += [*tcp[:, 0].round(4).tolist(), None]
            ys += [*tcp[:, 1].round(4).tolist(), None]
            zs += [*tcp[:, 2].round(4).tolist(), None]
            label = f"{r.spec_id}: {p.get('name', '')} {p.get('cmd', '')}"
            text += [label] * len(tcp) + [""]
            moves += 1
    if not moves:
        return None
    traces: list[dict[str, Any]] = []
    if scene is not None:
        for v, f in scene.boxes():
            traces.append(figures.mesh_trace(v, f, name="cell", colour="#d9d2c5", opacity=0.35, digits=4))
        part = scene.mesh_world()
        if part is not None:
            traces.append(figures.mesh_trace(*part, colour="#9fb3c8", digits=4))
    for i, (tool, (xs, ys, zs, text)) in enumerate(sorted(by_tool.items())):
        colour = _PALETTE[i % len(_PALETTE)]
        traces.append({"type": "scatter3d", "mode": "lines", "x": xs, "y": ys, "z": zs, "text": text,
                       "hoverinfo": "text", "name": f"{tool} ({xs.count(None)} moves)", "connectgaps": False,
                       "line": {"color": colour, "width": 3}})
    return {"moves": moves, "figure": {"data": traces, "layout": {
        "font": figures.FONT, "height": 720, "margin": {"l": 0, "r": 0, "t": 10, "b": 0}, "legend": {"x": 0, "y": 1},
        "scene": {"aspectmode": "data", "xaxis": {"title": {"text": "x (m)"}}, "yaxis": {"title": {"text": "y (m)"}},
                  "zaxis": {"title": {"text": "z (m)"}}}}}}
