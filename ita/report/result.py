"""One result, opened: what the result page of `ita serve` and the report's drill-down show.

    page = result_payload(archive, run_id, "HD-OF-017", scene=scene)

Its row of the per-feature table, the details the Top Level kept (plan, Vision's
overlay, the gauge's reading, the arm's paths), the range image with the overlay, the
plan's events and timeline, and the arm's path in the workcell (when a scene is given).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ita.archive.store import Archive
from ita.report import figures
from ita.report.data import STATUS_COLOURS, event_row, result_row


def _thin(a: np.ndarray, most: int) -> np.ndarray:
    """Every k-th pixel so that neither side exceeds `most` (k = 1 when small enough)."""
    k = max(1, int(np.ceil(max(a.shape) / most)))
    return a[::k, ::k]


def result_payload(archive: Archive, run_id: str, spec_id: str, *, scene: Any = None,
                   max_pixels: int = 512) -> dict[str, Any] | None:
    """The page of result `spec_id` of run `run_id` (None when the run has no such
    result).  max_pixels: the range image is thinned to at most this many pixels a side
    (the overlay is scaled with it)."""
    r = archive.result(run_id, spec_id)
    if r is None:
        return None
    details = archive.details(run_id, spec_id)
    owner = details.get("frame_of") or spec_id
    events = archive.events(run_id, spec_id=owner)
    out: dict[str, Any] = {"row": result_row(r), "colours": STATUS_COLOURS, "details": details,
                           "events": [event_row(e) for e in events]}
    vision = details.get("vision") or {}
    frames = archive.frames(run_id, owner)
    if frames:
        frame = frames[min(int(vision.get("frame", len(frames) - 1)), len(frames) - 1)]
        k = max(1, int(np.ceil(max(frame.shape) / max_pixels)))
        overlay = _scaled(vision, k)
        title = (f"{spec_id}: {r.value:.4f} mm, U {r.U:.4f} mm" if r.value is not None else
                 f"{spec_id}: {vision.get('reason') or r.reason or 'not measured'}")
        out["range_figure"] = figures.range_image_figure(frame.range_m[::k, ::k], frame.intensity[::k, ::k],
                                                         overlay, title)
        scan = frame.meta.get("frames_in_scan", 1)
        out["frame_note"] = (f"frame {frame.n + 1} of the plan of {owner}, {frame.shape[0]} x {frame.shape[1]} "
                             f"pixels" + (f"; the scan took {scan} frames (one kept)" if scan and scan > 1 else ""))
    elif r.kind and not details.get("gauge"):
        out["frame_note"] = "No range frame was kept for this result."
    plan_events = [e for e in events if e.kind in ("command", "wait", "continue", "reply", "plan_start",
                                                   "plan_end", "exception", "recovery")]
    if any(e.kind == "command" for e in plan_events):
        out["timeline_figure"] = figures.gantt_figure(plan_events)
    paths = (archive.details(run_id, owner) if owner != spec_id else details).get("arm_paths") or []
    if scene is not None and paths:
        q_end = next((p["q_end"] for p in reversed(paths) if p.get("q_end")), None)
        point = None if r.point is None else scene.to_world(r.point)
        out["workcell_figure"] = figures.workcell_figure(
            scene.boxes(), scene.mesh_world(), paths, None if q_end is None else scene.arm_links(q_end), point)
    return out


def _scaled(overlay: dict[str, Any], k: int) -> dict[str, Any]:
    """The overlay's pixel coordinates divided by k (the image thinned by k)."""
    if k == 1:
        return overlay
    out = dict(overlay)
    for key in ("rim", "edge", "circle"):
        if overlay.get(key):
            out[key] = [[(p[0] + 0.5) / k - 0.5, (p[1] + 0.5) / k - 0.5] for p in overlay[key]]
    if overlay.get("nominal"):
        p = overlay["nominal"]
        out["nominal"] = [(p[0] + 0.5) / k - 0.5, (p[1] + 0.5) / k - 0.5]
    if overlay.get("patch"):
        r0, r1, c0, c1 = overlay["patch"]
        out["patch"] = [r0 / k, r1 / k, c0 / k, c1 / k]
    return out
