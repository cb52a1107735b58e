"""Dimensional measurement from one SLRA range frame: a spec in, a value with its standard
uncertainty or an exception reply out.

Modules: :mod:`~ita.vision.context` (context, replies, constants), :mod:`~ita.vision.scan`
(windows, rasters, frames), :mod:`~ita.vision.rims` (patches, faces, edges, rims, lines),
:mod:`~ita.vision.register` (fastener registration on neighbours), :mod:`~ita.vision.kinds`
(the measurers per kind); this module measures a spec in one frame or several.

    ctx = vision_context(part, workcell)
    geometry = scan_for(spec, ctx)             # the window Vision wants the SLRA to scan
    plan = frames_for(spec, ctx)               # how many approaches (frames) it needs
    reply = measure(frame, spec, ctx)          # VisionResult | VisionException
    reply = measure_frames(frames, spec, ctx)  # the same from plan.count frames

Vision knows only the frame (with the pose the robot REPORTS), the nominal features and
the part's placement.  Method, as the seed describes: rectangular patches over the critical
areas of the feature, plane fits on the faces, sub-pixel jump-edge points (see edges.py),
circles for holes and lines for edges, all in the part frame (mm).

Datums in the image.  The arm's pose error (repeatability, `pose_sigma_m` per axis) moves
everything the frame shows; sizes are immune to it, and so is everything measured between
two things in the same image:
* heights are measured from the web beside the feature (z_top - z_web + the web's nominal
  thickness); the web's own tolerance (uniform, t / sqrt 3) enters the uncertainty;
* widths and edge distances are between two edges of the same image;
* a fastener hole's position is registered on its neighbours in the same image: the frame
  is shifted by the mean offset of their measured from their nominal centres.  Which
  neighbours serve is fixed by the nominal part and the commanded pose alone (those whose
  whole rim patch lies in the frame with a margin for the pose error), so repeated frames
  use the same ones; a hole with a nominal rib showing through it is left out when a
  clean one is in view.  The frame can still drop one: a rim that cannot be fitted in it,
  and of three or more, one more than a zone radius from their median.  Their half-seen
  rims are fitted with the hole's own radius (its as-built spread a type-B term).  Their
  own position scatter (assumed uniform over their tolerance zone: sigma = zone / 4 per
  axis, divided by the number of neighbours) enters the uncertainty: it does not repeat
  away, and it is the main term;
  the frame also reports every rim it fitted (the hole's own, whole, and its neighbours',
  half) as ``sightings``: the Top Level decides fastener positions by adjusting all of a
  face's frames together (:mod:`ita.vision.network`), where the neighbours' positions are
  unknowns of the adjustment rather than a zone's worth of uncertainty;
* a lightening hole has no neighbour in view (pocket walls lie outside the window): its
  datum is the arm's pose (`datum = "pose"`), whose error is a new draw of the arm's
  repeatability at each approach.  `frames_for` allows up to ctx.pose_datum_frames frames,
  each after its own approach (the SLRA takes only as many as its decision needs: 1, 2, 4,
  8 ..., see ita.devices.slra), and `measure_frames` averages their deviations: the random part
  (pose, rim fit) falls by the square root of their number (never below what the frames'
  own scatter shows); the systematic part (the edge model) does not.  This assumes the
  arm's error at a taught pose is repeatability only (the simulated arm has no absolute
  accuracy error); a calibrated arm's residual accuracy would be one more systematic term.

Pixels.  A frame has ctx.shape pixels, except a fastener hole's position: its window holds
two neighbours, and where that would put fewer than MIN_HOLE_PIXELS across the hole's
diameter, `scan_for` asks for a finer raster (see :mod:`ita.vision.scan`).

Rims of large holes.  What lies beyond a rim may differ round it (a fixture under part of a
lightening hole, the far floor under the rest): each edge pixel's far share comes from the
surface on its own radius, from the range where that surface mixes in phase and from the
intensity where it does not.  Rays cross a large hole's rim tilted outward, so the bore's
wall shows beyond it, dark; the edge found then lies between the rim and depth * tilt^2
inside it: the rim points move out by half of that, and the other half is a type-B term.

Failures are replies, never made-up values: OUT_OF_VIEW (a patch the measurement needs is
outside the frame), OCCLUDED (something nearer than the surface covers a patch),
TOO_FEW_PIXELS (too few valid pixels or edge points), FIT_RESIDUAL (a fit does not match).

Calibration.  Sizes (hole diameters, edge distances, flange and rib widths) are corrected
by the SLRA's calibration on reference workpieces, and their uncertainty is the frame's
own random part plus what the study measured (:mod:`ita.vision.calibration`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import replace

import numpy as np
from numpy.typing import NDArray

from ita.part.infer import basis
from ita.part.model import Hole
from ita.sensors.slra_frame import RangeFrame
from ita.specs.model import MeasurementKind as K
from ita.specs.model import MeasurementSpec
from ita.vision.calibration import SlraCalibration
from ita.vision.context import (
    VisionContext,
    VisionException,
    VisionFail,
    VisionFailure,
    VisionReply,
    VisionResult,
)
from ita.vision.kinds import MEASURERS

FloatArray = NDArray[np.float64]


def measure(frame: RangeFrame, spec: MeasurementSpec, ctx: VisionContext) -> VisionReply:
    """Measure `spec` in `frame`: a VisionResult, or a VisionException saying why not."""
    entry = MEASURERS.get(spec.kind)
    feature = ctx.features.get(spec.feature)
    if entry is None or not isinstance(feature, entry.feature):
        return VisionException(spec.id, VisionFailure.NOT_MEASURABLE,
                               f"the SLRA does not measure {spec.kind.value} of {spec.feature!r}")
    returns = float(np.isfinite(frame.range_m).mean()) if frame.range_m.size else 0.0
    if returns < MIN_RETURN_SHARE:
        return VisionException(spec.id, VisionFailure.TOO_FEW_PIXELS,
                               f"the frame has returns at {100 * returns:.1f} % of its pixels (a frame of the part "
                               f"has {100 * MIN_RETURN_SHARE:.0f} % or more): a dirty window or a failing beam, not "
                               "a frame to measure in")
    calibrated = feature
    if isinstance(feature, Hole) and feature.axis[2] < AXIS_UP_COS:
        ctx, spec, feature = along_axis(ctx, spec, feature)
    try:
        result = entry(ctx.views.of(frame, ctx.placement), spec, feature, ctx)
    except VisionFail as exc:
        return VisionException(spec.id, exc.reason, exc.detail)
    return (ctx.calibration or SlraCalibration()).apply(result, calibrated)


AXIS_UP_COS = 0.999999   # a hole whose axis is further than this from +Z is measured in its own frame
#: a frame with returns at fewer of its pixels than this share contradicts its own model (a
#: view of the part on its fixture returns at most pixels: 62 % and more over every frame of a
#: whole run of the bulkhead; a dirty window leaves about 3 %): no value is taken from it
MIN_RETURN_SHARE = 0.20


def along_axis(ctx: VisionContext, spec: MeasurementSpec, hole: Hole) -> tuple[VisionContext, MeasurementSpec, Hole]:
    """The context, spec and hole in a frame of the hole's own whose +Z is its axis (the
    measurers see every face along +Z): the part frame turned by R (columns: two axes
    across the hole's, then its axis), with the holes drilled into the same face."""
    n = np.asarray(hole.axis, dtype=float)
    rot = np.column_stack([*basis(n), n])                    # local -> part

    def local(p: Sequence[float]) -> tuple[float, float, float]:
        x = rot.T @ np.asarray(p, dtype=float)
        return float(x[0]), float(x[1]), float(x[2])

    up = (0.0, 0.0, 1.0)
    same_face = {f.id: replace(f, center=local(f.center), axis=up) for f in ctx.features.values()
                 if isinstance(f, Hole) and float(np.dot(f.axis, n)) > AXIS_UP_COS}
    pl = ctx.placement
    r0, r1, r2 = ((float(x), float(y), float(z)) for x, y, z in pl.rotation_matrix() @ rot)
    placement = replace(pl, rotation=(r0, r1, r2))
    spec = replace(spec, point=local(spec.point), normal=up,
                   direction=None if spec.direction is None else local(spec.direction))
    return replace(ctx, features=same_face, placement=placement, floor=None), spec, same_face[hole.id]


def measure_frames(frames: Sequence[RangeFrame], spec: MeasurementSpec, ctx: VisionContext) -> VisionReply:
    """Measure `spec` in frames taken after separate approaches of the arm (see
    :func:`frames_for`, and a reinspection's more frames).  A position: the mean of the
    frames' deviations, its random part (rim fit, pose error) divided by the square root
    of their number, taken no smaller than the scatter the frames themselves show; its
    systematic part (edge model, neighbours' own errors) as it is; the sightings of every
    frame, each under its own frame (a network adjusts each frame's pose).  Other kinds:
    the mean of the values, the budget's terms that are new in every frame
    (:data:`FRAME_TERMS`) divided the same way, the others as they are.  More than half of
    the frames failing is the first failure's reply."""
    if not frames:
        return VisionException(spec.id, VisionFailure.NOT_MEASURABLE, "no frame")
    if len(frames) == 1:
        return measure(frames[0], spec, ctx)
    replies = [measure(f, spec, ctx) for f in frames]
    ok = [r for r in replies if isinstance(r, VisionResult)]
    failed = [r for r in replies if isinstance(r, VisionException)]
    if len(ok) < max(2, len(frames) // 2 + 1):
        first = failed[0]
        return VisionException(spec.id, first.reason, f"{len(failed)} of {len(frames)} frames failed; "
                               f"first: {first.detail}")
    return _mean_position(spec, ok) if spec.kind is K.HOLE_POSITION else _mean_size(spec, ok)


#: budget terms of a size that are new in every frame (the fits' noise): they average away
FRAME_TERMS = ("the frame's own fits", "rim fit", "edge line fit", "edge line fits")


def _mean_size(spec: MeasurementSpec, replies: Sequence[VisionResult]) -> VisionResult:
    """A size (diameter, width, height, distance) from several frames' replies (n >= 2)."""
    values = np.array([float(r.value) for r in replies])
    n = len(values)
    budgets = [dict(r.diagnostics.get("budget") or {"the frame's own fits": float(r.uncertainty)}) for r in replies]
    u_model = math.sqrt(float(np.mean([sum(float(b[t]) ** 2 for t in FRAME_TERMS if t in b) for b in budgets])))
    scatter = float(np.std(values, ddof=1))
    u_random = max(u_model, scatter) / math.sqrt(n)
    fixed = {t: max(float(b.get(t, 0.0)) for b in budgets) for t in budgets[0] if t not in FRAME_TERMS}
    budget = {f"the frames' own fits (mean of {n} frames)": u_random, **fixed}
    diag = {**replies[0].diagnostics, "frames": n, "values": values.tolist(), "scatter": scatter,
            "budget": budget}
    centres = [r.diagnostics.get("center") for r in replies]
    if all(c is not None for c in centres):       # a hole's centre: the frames' mean (their pose errors average)
        c = np.asarray(centres, dtype=float)
        diag["center"] = tuple(float(x) for x in np.mean(c, axis=0))
        diag["center_scatter"] = float(np.sqrt(np.mean(np.var(c, axis=0, ddof=1))))   # per axis, one frame
    faces = [r.diagnostics.get("face_z") for r in replies]
    if all(f is not None for f in faces):
        diag["face_z"] = float(np.mean(np.asarray(faces, dtype=float)))
    return VisionResult(spec.id, spec.kind, float(values.mean()), math.hypot(*budget.values()), diag)


def _mean_position(spec: MeasurementSpec, replies: Sequence[VisionResult]) -> VisionResult:
    """The position from several frames' replies (n >= 2)."""
    d = np.array([r.diagnostics["deviation"] for r in replies])
    n = len(d)
    u_model = math.sqrt(float(np.mean([r.diagnostics["u_random"] ** 2 for r in replies])))
    scatter = math.sqrt(float(np.mean(np.var(d, axis=0, ddof=1))))       # per axis, observed
    u_random = max(u_model, scatter) / math.sqrt(n)
    u_system = max(r.diagnostics["u_systematic"] for r in replies)
    mean = d.mean(axis=0)
    diag = {"frames": n, "deviation": tuple(mean), "deviations": d, "scatter": scatter, "u_random": u_random,
            "u_systematic": u_system, "datum": replies[0].diagnostics["datum"],
            "center": replies[0].diagnostics["center"], "rim_xy": replies[0].diagnostics.get("rim_xy"),
            "sightings": [{**sight, "frame": k} for k, r in enumerate(replies)
                          for sight in r.diagnostics.get("sightings", ())],
            "budget": {f"arm pose and rim fit (mean of {n} frames)": u_random, "edge model": u_system}}
    return VisionResult(spec.id, spec.kind, 2 * float(np.hypot(*mean)), 2 * math.hypot(u_random, u_system), diag)
