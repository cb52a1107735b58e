"""The per-kind measurers: hole diameter, position and edge distance, flange and stiffener
height and width, each from one range frame (:data:`MEASURERS`, by measurement kind).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Generic, TypeVar

import numpy as np
from numpy.typing import NDArray
from scipy import ndimage

from ita.part import geometry2d as g2
from ita.part.model import Feature, FlangeSegment, Hole, HoleRole, Stiffener
from ita.specs.model import MeasurementKind as K
from ita.specs.model import MeasurementSpec
from ita.vision.context import (
    BLUR_MM,
    EDGE_CORRELATION,
    FACE_MATCH_MM,
    MIN_PLANE_PIXELS,
    RIM_EDGE_MODEL_PX,
    STEP_CLEAR_MM,
    WHOLE_RIM,
    VisionContext,
    VisionFail,
    VisionFailure,
    VisionResult,
)
from ita.vision.fit import (
    LineFit,
    fit_parallel_planes,
)
from ita.vision.patches import Patch, View, nominal_points
from ita.vision.register import neighbour_rims, register_on_rims, rib_beneath
from ita.vision.rims import (
    edge_sigma,
    fit_edge,
    fit_face,
    fit_rim,
    frame_uv,
    free_edge,
    rect_patch,
)

FloatArray = NDArray[np.float64]

#: a rib's top plateau: pixels this close to its nominal height (a floor tens of mm below
#: moves a mixed pixel by more once it holds a few per cent of the footprint)
PLATEAU_MM = 0.5

#: a rib's top window: at least this half-width (mm) clear of the blur of both its edges (a
#: window reaching into the blur reads the top low: 4 um on a 2.5 mm rib 36 mm tall)
MIN_TOP_MM = 0.1


def _hole_diameter(view: View, spec: MeasurementSpec, hole: Hole, ctx: VisionContext) -> VisionResult:
    fit, near, diag = fit_rim(view, hole, "rim")
    px = diag["pixel_mm"]
    edge_model = RIM_EDGE_MODEL_PX * px if fit.coverage >= WHOLE_RIM else edge_sigma(px, fit.n)
    budget = {"rim fit": 2 * EDGE_CORRELATION * fit.radius_sigma, "edge model": 2 * edge_model,
              "scanner angle scale": 2e-4 * fit.radius, "rim model (wall, surfaces beyond)": 2 * diag["u_model"]}
    u = math.hypot(*budget.values())
    # the face round the hole, at its centre: a datum hole's face is the part's datum face
    diag.update(center=fit.center, budget=budget, face_z=near.z(float(fit.center[0]), float(fit.center[1])))
    return VisionResult(spec.id, spec.kind, 2 * fit.radius, u, diag)


def _hole_position(view: View, spec: MeasurementSpec, hole: Hole, ctx: VisionContext) -> VisionResult:
    fit, _, diag = fit_rim(view, hole, "rim")
    px = diag["pixel_mm"]
    u_fit = math.hypot(EDGE_CORRELATION * max(fit.center_sigma), edge_sigma(px, fit.n))
    shift, u_reg = np.zeros(2), math.nan
    used: list[str] = []
    left: list[str] = []
    sightings = [{"hole": hole.id, "xy": (float(fit.center[0]), float(fit.center[1])), "sigma": u_fit,
                  "systematic": float(diag["u_model_centre"]), "group": "whole rim"}]
    if hole.role is HoleRole.FASTENER:
        # a rim with a rib beneath is fitted less well than its neighbours' are: no radius for them
        radius = None if rib_beneath(view, hole, ctx) else fit.radius
        rims, left = neighbour_rims(view, hole, radius, ctx)
        sightings += [{"hole": r.hole, "xy": r.centre, "sigma": r.u_random, "systematic": r.u_model,
                       "group": "half rim"} for r in rims]
        shift, u_reg, used, left = register_on_rims(rims, left, ctx)
    pose_u = ctx.pose_sigma_m / ctx.placement.scale
    d = np.asarray(fit.center) + shift - np.asarray(hole.center[:2])
    # random from frame to frame: the rim fit and, with the pose as datum, the arm's pose
    # error (a new draw at each approach); the same in every frame: the edge model and the
    # neighbours' own position errors
    u_random = math.hypot(u_fit, pose_u) if not used else u_fit
    # with the pose as datum, the part's registration on its datums is the frame's datum too
    u_system = math.hypot(diag["u_model_centre"], u_reg) if used else \
        math.hypot(diag["u_model_centre"], ctx.registration_u_mm)
    u_axis = math.hypot(u_random, u_system)
    # the rims of this frame for a network adjustment (ita.vision.network) of the frames
    diag.update(center=fit.center, registered_on=used, left_out=left, shift=tuple(shift), deviation=tuple(d),
                datum="neighbours" if used else "pose", u_random=u_random, u_systematic=u_system,
                sightings=sightings, budget={"rim fit": u_fit, "edge model": float(diag["u_model_centre"]),
                                             **({"neighbours' positions": u_reg} if used else
                                                {"arm pose": pose_u, "registration": ctx.registration_u_mm})})
    return VisionResult(spec.id, spec.kind, 2 * float(np.hypot(*d)), 2 * u_axis, diag)


def _edge_distance(view: View, spec: MeasurementSpec, hole: Hole, ctx: VisionContext) -> VisionResult:
    fit, _, diag = fit_rim(view, hole, "rim")
    u, v = frame_uv(spec.direction or (1.0, 0.0, 0.0))
    c = np.asarray(hole.center[:2])
    edge = c + spec.nominal * u
    b = BLUR_MM + diag["pixel_mm"]
    patch, region = rect_patch(view, "free edge", edge, u, v, (-spec.nominal + hole.diameter / 2 + b, b + 6.0),
                                (-8.0, 8.0), hole.center[2])
    q = nominal_points(view, patch, hole.center[2])[..., :2] - edge
    s_u = q @ u
    near_region = region & (s_u < -b) & (np.hypot(*(q + edge - c).transpose(2, 0, 1)) > hole.diameter / 2 + b)
    near2, near_px = fit_face(view, patch, near_region, hole.center[2])
    line, ldiag = fit_edge(view, near2, near_px, patch, region & (np.abs(s_u) < b), region & (s_u > b), "free edge",
                        free_edge(ctx, hole, spec.nominal, u))
    dist = float(line.distance(np.asarray(fit.center))[0])
    sign = 1.0 if float(np.dot([-line.direction[1], line.direction[0]], u)) < 0 else -1.0
    value = sign * dist
    budget = {"edge line fit": line.offset_sigma_at(np.asarray(fit.center)) * EDGE_CORRELATION,
              "rim fit": EDGE_CORRELATION * max(fit.center_sigma),
              "edge model": math.sqrt(2) * edge_sigma(diag["pixel_mm"], 1), "rim model": diag["u_model"]}
    u_val = math.hypot(*budget.values())
    diag.update(edge_points=ldiag["points"], edge_rms=ldiag["rms"], edge_xy=ldiag["xy"], budget=budget)
    return VisionResult(spec.id, spec.kind, value, u_val, diag)


def _web_plane(view: View, c: FloatArray, u: FloatArray, v: FloatArray, u_range, v_range, ctx: VisionContext,
               name: str, clear: bool = False) -> tuple[FloatArray, float]:
    mid = c + 0.5 * (u_range[0] + u_range[1]) * u
    z_web, at = ctx.web_at(mid), mid
    if z_web is None and clear:
        # a rib meets the feature here: the floor on the nearer side of it along the patch
        for t in sorted(np.linspace(v_range[0], v_range[1], 9), key=abs):
            at = mid + t * v
            z_web = ctx.web_at(at)
            if z_web is not None:
                break
    if z_web is None:
        raise VisionFail(VisionFailure.NOT_MEASURABLE, f"no pocket floor beside the feature at {tuple(np.round(mid, 1))}")
    patch, region = rect_patch(view, name, c, u, v, u_range, v_range, z_web)
    if clear:
        region = region & _clear_of_steps(view, patch, z_web, ctx)
        pocket = next((p for p in ctx.pockets() if g2.points_in_polygon(np.atleast_2d(at), p.outline_array)[0]), None)
        if pocket is not None:           # one pocket's floor: a rib across the patch parts two
            xy = nominal_points(view, patch, z_web)[..., :2].reshape(-1, 2)
            inside = np.zeros(len(xy), dtype=bool)
            ok = np.isfinite(xy).all(axis=1)
            inside[ok] = g2.points_in_polygon(xy[ok], pocket.outline_array)
            region = region & inside.reshape(region.shape)
    _, used = fit_face(view, patch, region, z_web)
    return patch.take(view.points)[used], z_web


def _clear_of_steps(view: View, patch: Patch, z: float, ctx: VisionContext) -> NDArray[np.bool_]:
    """(h, w) over the patch: pixels whose beam stays on the nominal face at height z,
    every pixel within STEP_CLEAR_MM of them (in the image, at the face) meeting that face
    on the nominal mesh along its ray through the reported pose.  Without a nominal mesh (a
    generated part, whose patches are placed on its exact features): the pixels whose ray
    passes clear of every rib standing on that face (:func:`_clear_of_ribs`)."""
    if ctx.floor is None:
        return _clear_of_ribs(view, patch, z, ctx)
    h, w = view.shape
    reach = float(np.nanmedian(view.plane_range((0.0, 0.0, z), patch.take(view.dirs))))
    m = int(math.ceil(STEP_CLEAR_MM / view.pixel_mm(reach))) + 1
    r0, r1, c0, c1 = max(patch.r0 - m, 0), min(patch.r1 + m, h), max(patch.c0 - m, 0), min(patch.c1 + m, w)
    dirs = view.dirs[r0:r1, c0:c1].reshape(-1, 3)
    dist = ctx.floor.rays.first(np.broadcast_to(view.origin, dirs.shape), dirs)
    with np.errstate(invalid="ignore"):
        on = (np.abs(view.origin[2] + dist * dirs[:, 2] - z) < FACE_MATCH_MM).reshape(r1 - r0, c1 - c0)
    clear = ndimage.minimum_filter(on, size=2 * m + 1, mode="nearest")
    return clear[patch.r0 - r0:patch.r1 - r0, patch.c0 - c0:patch.c1 - c0]


#: heights along a ray at which it is tested against a rib's strip
_RAY_SAMPLES = 8


def _clear_of_ribs(view: View, patch: Patch, z: float, ctx: VisionContext) -> NDArray[np.bool_]:
    """(h, w) over the patch: pixels whose ray, from the face at height z up to the top of
    each nominal rib that stands higher, stays further than half the rib's width, the blur
    and STEP_CLEAR_MM from the rib's line (a flange height's web patch beside a rib that
    meets the flange there would fit the rib's side and top as the web)."""
    xy = nominal_points(view, patch, z)[..., :2]
    o = view.origin
    lean = (o[:2] - xy) / max(float(o[2]) - z, 1e-9)       # xy per mm of height, toward the sensor
    clear = np.ones(xy.shape[:2], dtype=bool)
    centre = np.nanmean(xy.reshape(-1, 2), axis=0)
    size = float(np.nanmax(np.linalg.norm(xy.reshape(-1, 2) - centre, axis=1)))
    for rib in ctx.features.values():
        if not isinstance(rib, Stiffener) or rib.height <= z:
            continue
        a, b = np.asarray(rib.start, dtype=float), np.asarray(rib.end, dtype=float)
        reach = rib.width / 2 + BLUR_MM + STEP_CLEAR_MM
        rise = rib.height - z
        if _point_segment(centre[None], a, b)[0] > size + reach + rise * float(np.nanmax(np.abs(lean))):
            continue
        for hh in np.linspace(0.0, rise, _RAY_SAMPLES):
            clear &= _point_segment(xy + lean * hh, a, b) > reach
    return clear


def _point_segment(p: FloatArray, a: FloatArray, b: FloatArray) -> FloatArray:
    """Distances (...) of points p (..., 2) from the segment a-b."""
    d = b - a
    t = np.clip(((p - a) @ d) / max(float(d @ d), 1e-12), 0.0, 1.0)
    return np.asarray(np.linalg.norm(p - (a + t[..., None] * d), axis=-1), dtype=np.float64)


def _height(top: FloatArray, webs: list[tuple[FloatArray, float]], ctx: VisionContext) -> tuple[float, float, dict]:
    """Height of the top face above datum A from its gap to the web faces beside it, fitted
    as parallel planes (points (n, 3) of each), plus the webs' nominal heights."""
    fit = fit_parallel_planes([top] + [w for w, _ in webs])
    h = [fit.offsets[0] - fit.offsets[1 + i] + zw for i, (_, zw) in enumerate(webs)]
    u_fit = fit.mean_gap_sigma(0, [1 + i for i in range(len(webs))])     # of the mean of the webs' heights
    u_web = ctx.web_tolerance / math.sqrt(3) / math.sqrt(len(webs))
    # each web's reference, for the Top Level to put its measured thickness in place of
    # the nominal (ita.toplevel.heights): where it was seen, its nominal height, the
    # height through it alone
    refs = [{"xy": [float(x) for x in np.mean(w[:, :2], axis=0)], "z": float(zw), "height": float(hi)}
            for (w, zw), hi in zip(webs, h)]
    return float(np.mean(h)), math.hypot(u_fit, u_web), {"rms": fit.rms, "rms_faces": list(fit.group_rms),
                                                         "u_fit": u_fit, "u_web": u_web,
                                                         "pixels": [len(top)] + [len(w) for w, _ in webs],
                                                         "webs": refs,
                                                         "budget": {"plane fits": u_fit,
                                                                    "web thickness (its tolerance)": u_web}}


def _flange(view: View, spec: MeasurementSpec, seg: FlangeSegment, ctx: VisionContext) -> VisionResult:
    u, v = frame_uv(spec.direction or _inward(seg, spec))
    p = np.asarray(spec.point[:2])
    outer = p - u * seg.from_wall(p)          # the wall's free face
    free = outer + u * seg.cap_width
    b = BLUR_MM + view.pixel_mm(ctx.standoff_m * 1000)
    along = (-8.0, 8.0)
    patch, region = rect_patch(view, "cap", outer, u, v, (-b - 5.0, seg.cap_width + b + 5.0), along, seg.height)
    q = nominal_points(view, patch, seg.height)[..., :2] - outer
    s_u = q @ u
    cap_region = region & (s_u > b) & (s_u < seg.cap_width - b)
    if spec.kind is K.FLANGE_HEIGHT:      # on a mesh part the segment may not follow a bend at the point
        cap_region &= _clear_of_steps(view, patch, seg.height, ctx)
    cap, cap_px = fit_face(view, patch, cap_region, seg.height)
    if spec.kind is K.FLANGE_HEIGHT:
        web = _web_plane(view, free, u, v, (b + 2.0, b + 14.0), along, ctx, "web", clear=True)
        value, unc, diag = _height(patch.take(view.points)[cap_px], [web], ctx)
        return VisionResult(spec.id, spec.kind, value, unc, diag)
    l_out, d_out = fit_edge(view, cap, cap_px, patch, region & (np.abs(s_u) < b), region & (s_u < -b), "outer edge")
    l_free, d_free = fit_edge(view, cap, cap_px, patch, region & (np.abs(s_u - seg.cap_width) < b),
                           region & (s_u > seg.cap_width + b), "free edge")
    return _width(spec, p, l_out, l_free, d_out, d_free)


def _width(spec: MeasurementSpec, p: FloatArray, a: LineFit, b: LineFit, da: dict, db: dict) -> VisionResult:
    value = abs(float(a.distance(p)[0]) - float(b.distance(p)[0])) if np.dot(a.direction, b.direction) > 0 else \
        abs(float(a.distance(p)[0]) + float(b.distance(p)[0]))
    budget = {"edge line fits": EDGE_CORRELATION * math.hypot(a.offset_sigma_at(p), b.offset_sigma_at(p)),
              "edge model": math.hypot(edge_sigma(da["pixel_mm"], a.n), edge_sigma(db["pixel_mm"], b.n)),
              "scanner angle scale": 2e-4 * value}
    u = math.hypot(*budget.values())
    return VisionResult(spec.id, spec.kind, value, u, {"edge_points": (a.n, b.n), "edge_rms": (a.rms, b.rms),
                                                       "modes": (da["mode"], db["mode"]),
                                                       "edge_xy": np.vstack([da["xy"], db["xy"]]), "budget": budget})


def _inward(seg: FlangeSegment, spec: MeasurementSpec) -> FloatArray:
    """The segment's normal into the flange at the point of its path nearest the spec's:
    on a segment, interpolated between its ends' normals (not the nearest vertex's, which
    on a sparse path can lie far along a corner arc)."""
    path, normals = seg.path_array, seg.normals_array
    if len(path) < 2:
        return normals[0]
    a, d = path[:-1], np.diff(path, axis=0)
    length2 = np.einsum("ij,ij->i", d, d)
    t = np.clip(np.einsum("ij,ij->i", np.asarray(spec.point[:2]) - a, d) / np.where(length2 > 0, length2, 1.0), 0, 1)
    k = int(np.argmin(np.linalg.norm(a + t[:, None] * d - np.asarray(spec.point[:2]), axis=1)))
    n = (1 - t[k]) * normals[k] + t[k] * normals[k + 1]
    return n / np.linalg.norm(n)


def _rib_offset(z: FloatArray, t: FloatArray, region: NDArray[np.bool_], height: float, reach: float) -> float:
    """Where the rib's top lies across the patch (mm along t) as the frame shows it: the
    median t of the pixels within PLATEAU_MM of its nominal height (0 with too few).  The
    frame's points sit where its reported pose puts them; an arm's lateral error of a few
    tenths moves a narrow rib's top window onto its edges, whose mixed pixels (a floor tens
    of millimetres below) pull the top face down.  Centred on the plateau the frame shows,
    the window keeps its margin from both edges."""
    with np.errstate(invalid="ignore"):
        top = region & np.isfinite(z) & (np.abs(z - height) < PLATEAU_MM) & (np.abs(t) < reach)
    if int(top.sum()) < MIN_PLANE_PIXELS:
        return 0.0
    return float(np.median(t[top]))


def _stiffener(view: View, spec: MeasurementSpec, rib: Stiffener, ctx: VisionContext) -> VisionResult:
    along, across = frame_uv(rib.direction)
    p = np.asarray(spec.point[:2])
    b = BLUR_MM + view.pixel_mm(ctx.standoff_m * 1000)
    half = rib.width / 2
    span = (-10.0, 10.0)
    patch, region = rect_patch(view, "rib", p, across, along, (-half - b - 4.0, half + b + 4.0), span, rib.height)
    q = nominal_points(view, patch, rib.height)[..., :2] - p
    t = q @ across
    t = t - _rib_offset(patch.take(view.points)[..., 2], t, region, rib.height, half + b)
    top_w = half - b          # the top's window keeps the beam's blur from both edges
    if spec.kind is K.STIFFENER_WIDTH:
        top_w = max(top_w, 0.3)   # the edges' reference plane only: a width hardly feels its height
    elif top_w < MIN_TOP_MM:
        raise VisionFail(VisionFailure.NOT_MEASURABLE,
                         f"rib {rib.id} is {rib.width:.2f} mm wide: its top is not seen clear of its edges' mixed "
                         f"pixels (the beam blurs {b:.2f} mm from each edge)")
    top, top_px = fit_face(view, patch, region & (np.abs(t) < top_w), rib.height)
    if spec.kind is K.STIFFENER_HEIGHT:
        webs = []
        missing: list[VisionFail] = []
        for side in (-1.0, 1.0):
            try:
                webs.append(_web_plane(view, p, side * across, along, (half + b + 1.0, half + b + 11.0), span, ctx,
                                       f"web {'left' if side < 0 else 'right'}"))
            except VisionFail as exc:     # one web beside the rib is enough (its own fit and tolerance)
                if exc.reason not in (VisionFailure.NOT_MEASURABLE, VisionFailure.TOO_FEW_PIXELS,
                                      VisionFailure.OUT_OF_VIEW):
                    raise
                missing.append(exc)
        if not webs:
            if all(e.reason is VisionFailure.OUT_OF_VIEW for e in missing):
                raise VisionFail(VisionFailure.OUT_OF_VIEW, "; ".join(e.detail for e in missing))
            raise VisionFail(VisionFailure.TOO_FEW_PIXELS, "no web visible beside the rib")
        value, unc, diag = _height(patch.take(view.points)[top_px], webs, ctx)
        return VisionResult(spec.id, spec.kind, value, unc, diag)
    lines = []
    for side in (-1.0, 1.0):
        lines.append(fit_edge(view, top, top_px, patch, region & (np.abs(t - side * half) < b),
                           region & (side * t > half + b), f"side {side:+.0f}"))
    return _width(spec, p, lines[0][0], lines[1][0], lines[0][1], lines[1][1])


_F = TypeVar("_F", Hole, FlangeSegment, Stiffener)


@dataclass(frozen=True)
class Measurer(Generic[_F]):
    """The measuring function of one kind of measurement and the kind of feature it measures."""

    feature: type[_F]
    run: Callable[[View, MeasurementSpec, _F, VisionContext], VisionResult]

    def __call__(self, view: View, spec: MeasurementSpec, feature: Feature, ctx: VisionContext) -> VisionResult:
        if not isinstance(feature, self.feature):
            raise TypeError(f"{spec.id}: {spec.kind.value} measures a {self.feature.__name__}, "
                            f"not a {type(feature).__name__}")
        return self.run(view, spec, feature, ctx)


MEASURERS: dict[K, Measurer[Hole] | Measurer[FlangeSegment] | Measurer[Stiffener]] = {
    K.HOLE_DIAMETER: Measurer(Hole, _hole_diameter),
    K.HOLE_POSITION: Measurer(Hole, _hole_position),
    K.EDGE_DISTANCE: Measurer(Hole, _edge_distance),
    K.FLANGE_HEIGHT: Measurer(FlangeSegment, _flange),
    K.FLANGE_WIDTH: Measurer(FlangeSegment, _flange),
    K.STIFFENER_HEIGHT: Measurer(Stiffener, _stiffener),
    K.STIFFENER_WIDTH: Measurer(Stiffener, _stiffener),
}
