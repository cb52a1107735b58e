"""Static charts for the printable report: PNG bytes drawn with matplotlib (Agg).

Each has axes with units, a legend and, where colour carries a value, a colour bar.
matplotlib is imported when a chart is drawn.
"""

from __future__ import annotations

import io
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from ita.archive import timeline
from ita.archive.model import Event, StoredResult
from ita.report.data import STATUS_COLOURS, STATUS_ORDER, SpecPoint, status_of
from ita.report.figures import CATEGORY_COLOURS, MARK_COLOURS, STREAM_ORDER


def _plt() -> Any:
    import matplotlib

    matplotlib.use("Agg", force=True)
    import matplotlib.pyplot as plt

    return plt


def _png(fig: Any, dpi: int = 150) -> bytes:
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=dpi, bbox_inches="tight", metadata={"Software": None})
    _plt().close(fig)
    return buf.getvalue()


def part_map_png(specs: Sequence[SpecPoint], results: Sequence[StoredResult], mesh: Any = None) -> bytes | None:
    """The part seen from +Z (its outline filled grey when the mesh is known), every spec
    a dot coloured by decision, with a legend of the counts."""
    if not specs:
        return None
    plt = _plt()
    from matplotlib.collections import PolyCollection

    status = {r.spec_id: status_of(r) for r in results}
    fig, ax = plt.subplots(figsize=(10, 6.4))
    if mesh is not None:
        v, f = mesh
        tri = np.asarray(v, dtype=float)[np.asarray(f, dtype=int)][:, :, :2]
        up = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]) > 0
        ax.add_collection(PolyCollection(tri[up], facecolors="#dde3ea", edgecolors="none", zorder=0))
    for st in ("not_attempted",) + STATUS_ORDER:
        pts = [s.point for s in specs if status.get(s.id, "not_attempted") == st]
        if pts:
            ax.scatter([p[0] for p in pts], [p[1] for p in pts], s=8 if st in ("conforms", "not_attempted") else 22,
                       c=STATUS_COLOURS[st], label=f"{st.replace('_', ' ')} ({len(pts)})", zorder=2,
                       edgecolors="black" if st == "does_not_conform" else "none", linewidths=0.4)
    ax.set_aspect("equal")
    ax.autoscale_view()
    ax.set_xlabel("x (mm)")
    ax.set_ylabel("y (mm)")
    ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.1), ncol=6, fontsize=8, frameon=False)
    ax.set_title("measurements by decision (the part seen from +Z)")
    return _png(fig)


def gantt_png(events: Sequence[Event], results: Sequence[StoredResult] = (), until: float | None = None,
              title: str = "command streams") -> bytes | None:
    """Gantt chart of the streams: commands by category, WAITs hatched, marks where the
    run was interrupted, stopped or resumed."""
    t0, t1 = timeline.span(events, results)
    if until is not None:
        t1 = min(t1, until)
    ivs = timeline.intervals(events)
    plans = timeline.plan_intervals(events)
    if not ivs and not plans:
        return None
    plt = _plt()
    from matplotlib.patches import Patch

    streams = [s for s in STREAM_ORDER if (s == "top" and plans) or any(iv.stream == s for iv in ivs)]
    unit, uname = (60.0, "min") if t1 - t0 > 600 else (1.0, "s")
    fig, ax = plt.subplots(figsize=(11, 0.7 * len(streams) + 1.8))
    rows = {s: i for i, s in enumerate(reversed(streams))}

    def bars(items: Any) -> list[tuple[float, float]]:
        return [(max(iv.start, t0) / unit, max((min(iv.end, t1) - max(iv.start, t0)) / unit, 1e-9))
                for iv in items if iv.end >= t0 and iv.start <= t1]

    for s in streams:
        y = rows[s]
        if s == "top":
            for j, colour in enumerate(("#9ecae1", "#c6dbef")):
                ax.broken_barh(bars(plans[j::2]), (y - 0.3, 0.6), facecolors=colour, edgecolor="none")
        for cat in timeline.CATEGORIES:
            sel = bars(iv for iv in ivs if iv.stream == s and iv.category == cat)
            if sel:
                waiting = cat == "waiting"
                ax.broken_barh(sel, (y - 0.4, 0.8) if waiting else (y - 0.35, 0.7),
                               facecolors="#eeeeee" if waiting else CATEGORY_COLOURS[cat],
                               edgecolor="#999999" if waiting else "none", hatch="///" if waiting else None,
                               linewidth=0)
    for e in events:
        if e.kind in ("interrupt", "stop", "resume") and e.sim_time is not None and t0 <= e.sim_time <= t1:
            ax.axvline(e.sim_time / unit, color=MARK_COLOURS[e.kind], lw=1.2, ls="--")
            ax.text(e.sim_time / unit, len(streams) - 0.45, e.kind.upper(), color=MARK_COLOURS[e.kind], fontsize=7)
    ax.set_yticks(range(len(streams)))
    ax.set_yticklabels(list(reversed(streams)))
    ax.set_xlim(t0 / unit, t1 / unit if t1 > t0 else t0 / unit + 1)
    ax.set_xlabel(f"simulated time ({uname})")
    ax.set_title(title)
    handles = [Patch(facecolor="#eeeeee" if c == "waiting" else CATEGORY_COLOURS[c],
                     edgecolor="#888" if c == "waiting" else "none", hatch="///" if c == "waiting" else None,
                     label="WAIT" if c == "waiting" else c.replace("_", " ")) for c in timeline.CATEGORIES]
    if plans:
        handles.append(Patch(facecolor="#9ecae1", label="measurement plan (top)"))
    ax.legend(handles=handles, loc="upper center", bbox_to_anchor=(0.5, -0.3), ncol=6, fontsize=8, frameon=False)
    return _png(fig)


def histogram_png(errors_by_kind: Mapping[str, Sequence[float]]) -> bytes | None:
    """Measurement error (µm) per kind, one panel each."""
    kinds = [k for k, v in sorted(errors_by_kind.items()) if v]
    if not kinds:
        return None
    plt = _plt()
    cols = min(3, len(kinds))
    rows = (len(kinds) + cols - 1) // cols
    fig, axes = plt.subplots(rows, cols, figsize=(10, 2.6 * rows), squeeze=False)
    for ax, kind in zip(axes.flat, kinds):
        e = errors_by_kind[kind]
        ax.hist(e, bins=min(40, max(8, len(e) // 5)), color="#1f77b4", edgecolor="white")
        ax.axvline(0, color="black", lw=0.8)
        ax.set_title(f"{kind} ({len(e)})", fontsize=9)
        ax.set_xlabel("measured - true (µm)", fontsize=8)
    for ax in list(axes.flat)[len(kinds):]:
        ax.set_visible(False)
    fig.tight_layout()
    return _png(fig)
