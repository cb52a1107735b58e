"""The Path Planner's paths of a whole run in one 3-D view: every arm move the run made
(the tool point's path, as each result's details keep it), one colour per tool, in the
workcell with the part.  A run of a two-arm run shows both arms: every arm's runs (its
hand-over too), a colour per arm and tool, each arm at rest and its pedestal.

    figure = run_paths_figure(archive, run_id, scene)     # None: no path kept
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ita.archive.store import Archive
from ita.report import figures
from ita.report.data import arm_runs

__all__ = ["MAX_POINTS_PER_MOVE", "run_paths_figure"]

#: a move's path keeps at most this many of its points in the run's view
MAX_POINTS_PER_MOVE = 40

_PALETTE = ("#d62728", "#1f77b4", "#2ca02c", "#ff7f0e", "#9467bd", "#8c564b", "#17becf", "#e377c2")


def run_paths_figure(archive: Archive, run_id: str, scene: Any) -> dict[str, Any] | None:
    """Every move of the run in the workcell (world frame, m): the cell's boxes, the part,
    and per tool the tool point's paths (a gap between moves); hover: the measurement and
    the command.  A run of a two-arm run: every arm's moves, per arm and tool, and each
    arm at rest with its pedestal.  None when the run kept no path."""
    arms = arm_runs(archive, run_id)
    runs = arms or (("", run_id),)
    by_tool: dict[str, tuple[list[Any], list[Any], list[Any], list[str]]] = {}
    moves = 0
    for arm, rid in runs:
        for r in archive.results(rid):
            for p in archive.details(rid, r.spec_id).get("arm_paths") or []:
                tcp = np.asarray(p.get("tcp") or [], dtype=float).reshape(-1, 3)
                if not len(tcp):
                    continue
                if len(tcp) > MAX_POINTS_PER_MOVE:
                    keep = np.unique(np.linspace(0, len(tcp) - 1, MAX_POINTS_PER_MOVE).round().astype(int))
                    tcp = tcp[keep]
                tool = str(p.get("tool") or "no tool")
                xs, ys, zs, text = by_tool.setdefault(f"{arm}: {tool}" if arm else tool, ([], [], [], []))
                xs += [*tcp[:, 0].round(4).tolist(), None]
                ys += [*tcp[:, 1].round(4).tolist(), None]
                zs += [*tcp[:, 2].round(4).tolist(), None]
                label = f"{arm + ' ' if arm else ''}{r.spec_id}: {p.get('name', '')} {p.get('cmd', '')}"
                text += [label] * len(tcp) + [""]
                moves += 1
    if not moves:
        return None
    traces: list[dict[str, Any]] = []
    if scene is not None:
        boxes = scene.boxes() + (scene.second_arm_boxes() if arms else [])
        for v, f in boxes:
            traces.append(figures.mesh_trace(v, f, name="cell", colour="#d9d2c5", opacity=0.35, digits=4))
        part = scene.mesh_world()
        if part is not None:
            traces.append(figures.mesh_trace(*part, colour="#9fb3c8", digits=4))
        for arm in dict.fromkeys(a for a, _ in arms):
            try:
                traces.append(figures.links_trace(scene.arm_at_rest(arm), f"{arm} at rest", digits=4))
            except KeyError:            # an arm this cell no longer names
                continue
    for i, (tool, (xs, ys, zs, text)) in enumerate(sorted(by_tool.items())):
        colour = _PALETTE[i % len(_PALETTE)]
        traces.append({"type": "scatter3d", "mode": "lines", "x": xs, "y": ys, "z": zs, "text": text,
                       "hoverinfo": "text", "name": f"{tool} ({xs.count(None)} moves)", "connectgaps": False,
                       "line": {"color": colour, "width": 3}})
    return {"moves": moves, "figure": {"data": traces, "layout": {
        "font": figures.FONT, "height": 720, "margin": {"l": 0, "r": 0, "t": 10, "b": 0}, "legend": {"x": 0, "y": 1},
        "scene": {"aspectmode": "data", "xaxis": {"title": {"text": "x (m)"}}, "yaxis": {"title": {"text": "y (m)"}},
                  "zaxis": {"title": {"text": "z (m)"}}}}}}

