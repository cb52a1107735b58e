"""A picture of a sequence plan: each tool group's tour drawn over the part seen from +Z.

Headless (matplotlib's Agg backend).  The part's upward faces are shaded by height (as in
ita.part.render); each tool's tour is a polyline through its measurement points in
visiting order, starting at a marked first point; done measurements are grey dots and
those that cannot be done red crosses.  The rack is off the part and not drawn: the
legend gives each tour's cost including the trips from and to it.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from ita.files.atomic import write_with
from ita.specs.model import MeasurementSpec

if TYPE_CHECKING:
    from ita.part.model import Part
    from ita.sequence.plan import SequencePlan

GROUP_COLOURS = ("#1f77b4", "#d62728", "#2ca02c", "#9467bd", "#ff7f0e", "#17becf")


def render_plan(part: Part, specs_by_id: Mapping[str, MeasurementSpec], plan: SequencePlan,
                path: Path, dpi: int = 150) -> Path:
    """Draw `plan`'s tours over `part` into the PNG `path`; returns the path."""
    import matplotlib

    matplotlib.use("Agg", force=True)
    import matplotlib.pyplot as plt
    from matplotlib.collections import PolyCollection

    mesh = part.mesh
    up = mesh.face_normals[:, 2] > 0.5
    tris = mesh.triangles[up]
    z = tris[:, :, 2].mean(axis=1)
    order = np.argsort(z)
    lo, hi = mesh.bounds
    span = hi - lo
    fig, ax = plt.subplots(figsize=(14.0, 14.0 * span[1] / span[0] * 0.92 + 1.4))
    shade = (z[order] - lo[2]) / max(span[2], 1e-9)
    ax.add_collection(PolyCollection(tris[order][:, :, :2], facecolors=plt.get_cmap("Greys")(0.2 + 0.4 * shade),
                                     edgecolors="none", antialiased=False, zorder=1))

    def xy(ids) -> np.ndarray:
        return np.array([specs_by_id[i].point[:2] for i in ids if i in specs_by_id]).reshape(-1, 2)

    unit = "s (interim estimate)" if plan.cost_interim else "s"
    for k, group in enumerate(plan.groups):
        pts = xy(group.order)
        if len(pts) == 0:
            continue
        colour = GROUP_COLOURS[k % len(GROUP_COLOURS)]
        ax.plot(pts[:, 0], pts[:, 1], "-", lw=0.7, color=colour, zorder=3 + k,
                label=f"{k + 1}. {group.tool}: {len(group.order)} points, {group.cost_s:.1f} {unit}")
        ax.scatter(pts[:, 0], pts[:, 1], s=5, color=colour, zorder=3 + k, linewidths=0)
        ax.scatter(pts[:1, 0], pts[:1, 1], s=60, marker="o", facecolors="none", edgecolors=colour,
                   linewidths=1.5, zorder=10)
    finished = xy(plan.finished())
    if len(finished):
        ax.scatter(finished[:, 0], finished[:, 1], s=8, color="#888888", zorder=11,
                   label=f"done ({len(plan.finished())})", linewidths=0)
    cannot = xy(i for i, _ in plan.cannot)
    if len(cannot):
        ax.scatter(cannot[:, 0], cannot[:, 1], s=25, marker="x", color="red", zorder=12,
                   label=f"cannot be done ({len(plan.cannot)})")
    pad = 0.02 * span[0]
    ax.set_xlim(lo[0] - pad, hi[0] + pad)
    ax.set_ylim(lo[1] - pad, hi[1] + pad)
    ax.set_aspect("equal")
    ax.set_xlabel("X (mm)")
    ax.set_ylabel("Y (mm)")
    ax.set_title(f"{plan.part}: sequence plan, method {plan.method}, {plan.tool_changes} tool change(s), "
                 f"total {plan.total_s:.1f} {unit}  (circle: first point of a tour)")
    ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.07), ncol=2, fontsize=8, frameon=False)
    fig.tight_layout()
    try:  # exactly the name given, atomically, never over a device (ita.files.atomic)
        return write_with(path, lambda tmp: fig.savefig(tmp, dpi=dpi, format="png"), what="--render",
                          suffix=".png")
    finally:
        plt.close(fig)
