"""Pictures of a measurement: the range image, the intensity image, and what Vision fitted.

Matplotlib (Agg) is imported only when a picture is drawn.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ita.files.atomic import write_with
from ita.sensors.slra_frame import RangeFrame
from ita.specs.model import MeasurementSpec
from ita.vision.patches import View


def render_measurement(frame: RangeFrame, spec: MeasurementSpec, ctx, reply, path: Path) -> Path:
    """Write a PNG of `frame` with the reply's patch and edge points (those of a
    VisionResult's diagnostics) drawn over it, titled with the value or the reason."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.patches import Rectangle

    view = View(frame, ctx.placement)
    fig, axes = plt.subplots(1, 2, figsize=(11, 5.2))
    axes[0].imshow(frame.range_m * 1000, cmap="viridis")
    axes[0].set_title("range (mm)")
    axes[1].imshow(frame.intensity, cmap="gray")
    axes[1].set_title("intensity")
    diag = getattr(reply, "diagnostics", {}) or {}
    for ax in axes:
        if "patch" in diag:
            r0, r1, c0, c1 = diag["patch"]
            ax.add_patch(Rectangle((c0 - 0.5, r0 - 0.5), c1 - c0, r1 - r0, fill=False, ec="w", lw=1))
        for key, colour in (("rim_xy", "r"), ("edge_xy", "orange")):
            xy = diag.get(key)
            if xy is not None and len(xy):
                z = float(spec.point[2])
                rc = view.pixel_of(np.column_stack([xy, np.full(len(xy), z)]))
                ax.plot(rc[:, 1], rc[:, 0], ".", ms=1.5, color=colour)
    if reply.ok:
        title = f"{spec.id}: {reply.value:.4f} mm, U = {reply.expanded:.4f} (nominal {spec.nominal})"
    else:
        title = f"{spec.id}: {reply.reason.value} - {reply.detail}"
    fig.suptitle(title, fontsize=9)
    try:  # exactly the name given, atomically, never over a device (ita.files.atomic)
        return write_with(path, lambda tmp: fig.savefig(tmp, dpi=90, format="png"), what="--render",
                          make_dirs=True, suffix=".png")
    finally:
        plt.close(fig)
