"""Pictures of a planned path in the workcell (matplotlib, headless Agg).

Three orthographic views (top x-y, front y-z seen from the arm, side x-z): the region
tree's solid regions (the workcell's boxes, the part's conservative boxes in grey), the
tool point's path along the trajectory, the visibility route, and the arm (its collision
tubes and the held tool's) at a few instants.

    render_path(planner, result, tool, "path.png", title="...")
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from ita.collision.shapes import BOX
from ita.files.atomic import write_with
from ita.kinematics import link_segments

VIEWS = (("top (x, y)", (0, 1)), ("front (y, z), from the arm", (1, 2)), ("side (x, z)", (0, 2)))
INSTANTS = 5


def _outlines(regions: Any, axes: tuple[int, int]) -> list[np.ndarray]:
    """Projected outlines (convex hulls of the 8 corners) of the box regions."""
    from scipy.spatial import ConvexHull, QhullError

    signs = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)], dtype=float)
    out = []
    for k in np.flatnonzero(regions.kind == BOX):
        corners = regions.position[k] + (signs * (regions.half[k] + regions.rad[k])) @ regions.rotation[k].T
        pts = corners[:, list(axes)]
        try:
            hull = ConvexHull(pts)
            out.append(pts[hull.vertices])
        except QhullError:  # a flat projection: its bounding rectangle
            lo, hi = pts.min(axis=0), pts.max(axis=0)
            out.append(np.array([[lo[0], lo[1]], [hi[0], lo[1]], [hi[0], hi[1]], [lo[0], hi[1]]]))
    return out


def render_path(planner: Any, result: Any, tool: Any, path: Path, title: str = "",
                skip: tuple[str, ...] = ("floor", "fence_front", "fence_left", "fence_right")) -> Path:
    """Draw a PathResult of `planner` (with `tool` held) to a PNG file; returns the path.

    skip: objects not drawn (the floor and the fence would hide the rest)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.collections import PolyCollection

    tree = planner.tree
    ctx = planner.context(tool)
    fig, axs = plt.subplots(1, 3, figsize=(18, 6.5))
    names = [n for n in tree.objects if n not in skip]
    traj = result.trajectory
    if traj is not None:
        times = np.linspace(0.0, traj.duration, INSTANTS)
        arm = link_segments(ctx.model, traj.sample(times))              # (k, t, 2, 3)
    for ax, (label, axes) in zip(axs, VIEWS):
        for name in names:
            grey = name == "part"
            polys = _outlines(tree.regions(tree.leaves(name)), axes)
            ax.add_collection(PolyCollection(polys, facecolors="0.85" if grey else "#c9d6e8",
                                             edgecolors="0.6" if grey else "#5b7aa6", linewidths=0.3,
                                             alpha=0.6 if grey else 0.5))
        if traj is not None:
            colours = plt.cm.viridis(np.linspace(0.0, 0.9, INSTANTS))
            for k in range(INSTANTS):
                for t, seg in enumerate(arm[k]):
                    width = 2.0 + 40.0 * float(ctx.model.tube_radii[t])
                    ax.plot(seg[:, axes[0]], seg[:, axes[1]], color=colours[k], lw=width, alpha=0.35,
                            solid_capstyle="round")
        if len(result.route):
            ax.plot(result.route[:, axes[0]], result.route[:, axes[1]], "k--", lw=0.8, label="visibility route")
        if len(result.tool_path):
            tp = result.tool_path
            ax.plot(tp[:, axes[0]], tp[:, axes[1]], color="crimson", lw=2.0, label="tool point")
            ax.plot(*tp[0, list(axes)], "o", color="crimson", ms=7, label="start")
            ax.plot(*tp[-1, list(axes)], "s", color="crimson", ms=7, label="goal")
        ax.set_title(label)
        ax.set_aspect("equal")
        ax.autoscale_view()
        ax.grid(True, lw=0.3)
        ax.set_xlabel("xyz"[axes[0]] + " (m)")
        ax.set_ylabel("xyz"[axes[1]] + " (m)")
    if axs[0].get_legend_handles_labels()[0]:
        axs[0].legend(loc="lower left", fontsize=8)
    fig.suptitle(title or result.message)
    fig.tight_layout()
    try:  # exactly the name given, atomically, never over a device (ita.files.atomic)
        return write_with(path, lambda tmp: fig.savefig(tmp, dpi=110, format="png"), what="-o",
                          suffix=".png")
    finally:
        plt.close(fig)
