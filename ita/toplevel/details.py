"""What the archive keeps beside a result so that a person can examine it later.

    extra = measurement_details(session, outcome, plan_no=7, group=0)
    archive.record_result(run_id, result, events, details=extra.details[spec_id], frames=extra.frames)

Per measurement a JSON-ready object: the plan (its source, MACROP and steps), for an
SLRA result what Vision drew on the frame (its patch, the rim or edge points, the fitted
circle, the nominal point: all in pixels of the stored frame, so a viewer needs no
geometry), for a gauge result its reading, and the arm's flown paths (the tool point in
the world frame, a few dozen knots per command: the 3-D view draws them).  The range
frames themselves go to the archive's frames table: the first frame of each SCAN (the
view's own raster), with how many frames the scan took.  The other members of an SLRA
view group point at the frame of the plan that served them (`frame_of`).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, SupportsFloat, cast

import numpy as np
from numpy.typing import ArrayLike

from ita.archive import StoredFrame
from ita.devices.data import ArmPath, MeasuredValue, ScanData, arm_paths
from ita.logic.json_value import JsonObject, JsonValue
from ita.vision.patches import View

if TYPE_CHECKING:
    from ita.sensors.slra_frame import RangeFrame
    from ita.specs.model import MeasurementSpec
    from ita.task.measure import MeasureOutcome
    from ita.task.session import Session
    from ita.workcell.model import PartPlacement

__all__ = ["MeasurementDetails", "measurement_details", "vision_overlay"]

#: most rim or edge points kept per overlay (evenly thinned)
MAX_OVERLAY_POINTS = 400
_SCALARS = ("edge_points", "rim_rms", "pixel_mm", "mode", "datum", "rms", "edge_rms", "u_fit", "u_web",
            "u_random", "u_systematic", "far_other_share", "frames")


@dataclass(frozen=True, eq=False)
class MeasurementDetails:
    """details: spec id -> its JSON-ready details; frames: the plan's stored frames."""

    details: Mapping[str, JsonObject] = field(default_factory=dict)
    frames: tuple[StoredFrame, ...] = ()


def _plan(outcome: MeasureOutcome) -> JsonObject | None:
    plan = outcome.plan
    if plan is None:
        return None
    return {"macrop": plan.macrop_name, "source": plan.source.value, "seconds": round(plan.seconds, 4),
            "steps": [{"n": s.number, "text": s.text, "after": list(s.predecessors)} for s in plan.steps]}


def _path(cmd: str, name: str, started: float | None, path: ArmPath) -> JsonObject:
    return {"cmd": cmd, "name": name.lower(), "t0": started, "tool": path.tool, "times": list(path.times),
            "tcp": [list(p) for p in path.tcp], "q_end": list(path.q[-1]) if path.q else None}


def _paths(outcome: MeasureOutcome, plan_no: int) -> list[JsonObject]:
    report = outcome.report
    if report is None:
        return []
    starts = {o.step: o.started_s for o in report.outcomes}
    return [_path(f"{plan_no}.{c.step}", c.name, starts.get(c.step), p) for c, p in arm_paths(report)]


def _thin(points: np.ndarray, most: int = MAX_OVERLAY_POINTS) -> np.ndarray:
    if len(points) <= most:
        return points
    kept: np.ndarray = points[np.linspace(0, len(points) - 1, most).astype(int)]
    return kept


def _pixels(view: View, xy: ArrayLike, z: float) -> list[list[float]]:
    pts = np.asarray(xy, dtype=float).reshape(-1, 2)
    if not len(pts):
        return []
    rc = view.pixel_of(np.column_stack([_thin(pts), np.full(min(len(pts), MAX_OVERLAY_POINTS), z)]))
    return [[round(float(r), 2), round(float(c), 2)] for r, c in rc if math.isfinite(r) and math.isfinite(c)]


def _scalar(v: object) -> JsonValue:
    """A diagnostic or reading value as a JSON scalar (a number rounded, an enum's text);
    None for anything else."""
    if isinstance(v, (bool, int, str)) or v is None:
        return v
    if isinstance(v, float) or hasattr(v, "item"):
        f = float(cast(SupportsFloat, v))     # a float or a numpy scalar
        return round(f, 6) if math.isfinite(f) else None
    value = getattr(v, "value", None)
    return value if isinstance(value, str) else None


def vision_overlay(frame: RangeFrame, placement: PartPlacement, spec: MeasurementSpec, value: MeasuredValue
                   ) -> JsonObject:
    """What Vision saw of `spec` in `frame` (a RangeFrame), in the frame's pixels (row,
    col): patch [r0, r1, c0, c1], rim and edge points, the fitted circle, the nominal
    point; and the reason when it failed."""
    view = View(frame, placement)
    source = value.source
    diag = dict(getattr(source, "diagnostics", {}) or {})
    z = float(spec.point[2])
    out: JsonObject = {}
    nominal = view.pixel_of(np.asarray([spec.point], dtype=float))[0]
    if np.all(np.isfinite(nominal)):
        out["nominal"] = [round(float(nominal[0]), 2), round(float(nominal[1]), 2)]
    if "patch" in diag:
        out["patch"] = [int(v) for v in diag["patch"]]
    for key, name in (("rim_xy", "rim"), ("edge_xy", "edge")):
        if diag.get(key) is not None:
            out[name] = _pixels(view, diag[key], z)
    center = diag.get("center")
    rim = diag.get("rim_xy")
    if center is not None and (rim is not None or value.ok):
        c = np.asarray(center, dtype=float)[:2]
        kind = str(getattr(spec.kind, "value", spec.kind))
        if kind == "hole_diameter" and value.ok and value.value is not None:
            radius = float(value.value) / 2
        elif rim is not None and len(rim):
            radius = float(np.median(np.hypot(*(np.asarray(rim, dtype=float)[:, :2] - c).T)))
        else:
            radius = math.nan
        if math.isfinite(radius):
            a = np.linspace(0, 2 * math.pi, 73)
            out["circle"] = _pixels(view, np.column_stack([c[0] + radius * np.cos(a), c[1] + radius * np.sin(a)]), z)
            out["circle_mm"] = {"center": [round(float(c[0]), 4), round(float(c[1]), 4)], "radius": round(radius, 4)}
    out["numbers"] = {k: _scalar(diag[k]) for k in _SCALARS if k in diag and _scalar(diag[k]) is not None}
    if not value.ok:
        out["reason"] = value.reason
    return out


def _gauge(value: MeasuredValue) -> JsonObject:
    src = value.source
    out: JsonObject = {"value": value.value, "u": value.u}
    for name in ("thickness_mm", "u_mm", "amplitude", "dwell_s", "probe", "coverage_k", "velocity_factor", "message"):
        if hasattr(src, name):
            out[name] = _scalar(getattr(src, name))
    reason = getattr(src, "reason", None)
    if reason is not None:
        out["reason"] = getattr(reason, "value", str(reason))
    return out


def _scans(outcome: MeasureOutcome) -> list[ScanData]:
    report = outcome.report
    if report is None:
        return []
    replies = [o.reply for o in report.outcomes]
    if report.failure is not None:
        replies.append(report.failure.reply)
    return [r.data for r in replies if isinstance(r.data, ScanData)]


def measurement_details(session: Session, outcome: MeasureOutcome, *, plan_no: int = 0,
                        group: int | None = None) -> MeasurementDetails:
    """The details of `outcome` (its spec and its view group's other members) and the
    frames to keep (see the module docstring).  Never raises for want of data: what is
    missing is left out."""
    specs = session.specs
    main = outcome.spec_id
    base: JsonObject = {"tool": outcome.tool, "group": group, "plan_no": plan_no}
    mine: JsonObject = dict(base)
    plan = _plan(outcome)
    if plan is not None:
        mine["plan"] = plan
    paths = _paths(outcome, plan_no)
    if paths:
        mine["arm_paths"] = paths
    scans = _scans(outcome)
    frames: list[StoredFrame] = []
    for n, scan in enumerate(scans):
        if scan.frames:
            frames.append(StoredFrame.of(scan.frames[0], main, n, group=scan.group, frames_in_scan=len(scan.frames)))
    details: dict[str, JsonObject] = {main: mine}
    values: list[MeasuredValue] = [v for v in (outcome.value, *outcome.others) if v is not None]
    placement = session.ctx.workcell.part
    for value in values:
        d = mine if value.spec_id == main else details.setdefault(value.spec_id, dict(base) | {"frame_of": main})
        spec = specs.get(value.spec_id)
        if spec is None:
            continue
        if scans and scans[-1].frames:
            try:
                overlay = vision_overlay(scans[-1].frames[0], placement, spec, value)
                d["vision"] = overlay
                overlay["frame"] = len(scans) - 1
            except Exception as exc:  # noqa: BLE001 - a picture must never cost a result
                d["vision"] = {"error": f"{type(exc).__name__}: {exc}"}
        else:
            d["gauge"] = _gauge(value)
    return MeasurementDetails(details, tuple(frames))
