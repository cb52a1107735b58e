"""A picture of a part seen from +Z (the inspected side), its spec points coloured by kind.

Headless (matplotlib's Agg backend).  The mesh's upward faces are drawn shaded by height,
so the web, ribs and flange caps read at a glance; each spec is a dot at its point, with
a legend giving the count per kind.
"""

from __future__ import annotations

from pathlib import Path
from typing import Sequence

import numpy as np

from ita.files.atomic import output_path, write_with
from ita.part.model import Part
from ita.specs.model import MeasurementKind, MeasurementSpec

KIND_COLOURS: dict[MeasurementKind, str] = {
    MeasurementKind.WEB_THICKNESS: "#1f77b4",
    MeasurementKind.FLANGE_THICKNESS: "#17becf",
    MeasurementKind.HOLE_DIAMETER: "#d62728",
    MeasurementKind.HOLE_POSITION: "#ff9896",
    MeasurementKind.FLANGE_HEIGHT: "#2ca02c",
    MeasurementKind.FLANGE_WIDTH: "#98df8a",
    MeasurementKind.STIFFENER_HEIGHT: "#9467bd",
    MeasurementKind.STIFFENER_WIDTH: "#e377c2",
    MeasurementKind.EDGE_DISTANCE: "#ff7f0e",
}
# draw order: big sparse kinds first, so that points sharing a spot stay visible
_ORDER = (MeasurementKind.HOLE_POSITION, MeasurementKind.HOLE_DIAMETER,
          MeasurementKind.EDGE_DISTANCE, MeasurementKind.FLANGE_WIDTH,
          MeasurementKind.FLANGE_HEIGHT, MeasurementKind.FLANGE_THICKNESS,
          MeasurementKind.STIFFENER_WIDTH, MeasurementKind.STIFFENER_HEIGHT,
          MeasurementKind.WEB_THICKNESS)


def render_part(part: Part, specs: Sequence[MeasurementSpec], path: Path,
                dpi: int = 150, title: str | None = None, make_dirs: bool = False) -> Path:
    """Draw `part` from +Z with `specs` on it into the PNG `path` (exactly that name, written
    atomically; see ita.files.atomic for what is refused); returns the path written."""
    output_path(path, what="-o", make_dirs=make_dirs)  # refuse before the drawing work
    import matplotlib

    matplotlib.use("Agg", force=True)
    import matplotlib.pyplot as plt
    from matplotlib.collections import PolyCollection

    mesh = part.mesh
    up = mesh.face_normals[:, 2] > 0.5
    tris = mesh.triangles[up]
    z = tris[:, :, 2].mean(axis=1)
    order = np.argsort(z)  # higher faces drawn last
    lo, hi = mesh.bounds
    span = hi - lo
    fig_w = 14.0
    fig, ax = plt.subplots(figsize=(fig_w, fig_w * span[1] / span[0] * 0.92 + 1.2))
    shade = (z[order] - lo[2]) / max(span[2], 1e-9)
    colours = plt.get_cmap("Greys")(0.25 + 0.55 * shade)
    ax.add_collection(PolyCollection(tris[order][:, :, :2], facecolors=colours,
                                     edgecolors="none", antialiased=False, zorder=1))
    for kind in _ORDER:
        pts = np.array([s.point for s in specs if s.kind is kind]).reshape(-1, 3)
        if len(pts) == 0:
            continue
        size = 14 if kind is MeasurementKind.HOLE_POSITION else 7
        ax.scatter(pts[:, 0], pts[:, 1], s=size, c=KIND_COLOURS[kind], zorder=3,
                   label=f"{kind.value} ({len(pts)})", linewidths=0)
    pad = 0.02 * span[0]
    ax.set_xlim(lo[0] - pad, hi[0] + pad)
    ax.set_ylim(lo[1] - pad, hi[1] + pad)
    ax.set_aspect("equal")
    ax.set_xlabel("X (mm)")
    ax.set_ylabel("Y (mm)")
    ax.set_title(title or f"{part.name}: {span[0]:.0f} x {span[1]:.0f} x {span[2]:.0f} mm, "
                 f"{len(specs)} specs (view from +Z)")
    ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.07), ncol=5, fontsize=8,
              markerscale=2.5, frameon=False)
    fig.tight_layout()
    try:
        return write_with(path, lambda tmp: fig.savefig(tmp, dpi=dpi, format="png"), what="-o",
                          make_dirs=make_dirs, suffix=".png")
    finally:
        plt.close(fig)
