"""Dimensional measurement from one SLRA range frame: a spec in, a value with its standard
uncertainty or an exception reply out.

    ctx = VisionContext.from_part(part, workcell)
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
* a lightening hole has no neighbour in view (pocket walls lie outside the window): its
  datum is the arm's pose (`datum = "pose"`), whose error is a new draw of the arm's
  repeatability at each approach.  `frames_for` asks for ctx.pose_datum_frames frames, each
  after its own approach, and `measure_frames` averages their deviations: the random part
  (pose, rim fit) falls by the square root of their number (never below what the frames'
  own scatter shows); the systematic part (the edge model) does not.  This assumes the
  arm's error at a taught pose is repeatability only (the simulated arm has no absolute
  accuracy error); a calibrated arm's residual accuracy would be one more systematic term.

Pixels.  A frame has ctx.shape pixels, except a fastener hole's position: its window holds
two neighbours, and where that would put fewer than MIN_HOLE_PIXELS across the hole's
diameter, `scan_for` asks for a finer raster (see :func:`_raster_for`).

Rims of large holes.  What lies beyond a rim may differ round it (a fixture under part of a
lightening hole, the far floor under the rest): each edge pixel's far share comes from the
surface on its own radius, from the range where that surface mixes in phase and from the
intensity where it does not.  Rays cross a large hole's rim tilted outward, so the bore's
wall shows beyond it, dark; the edge found then lies between the rim and depth * tilt^2
inside it: the rim points move out by half of that, and the other half is a type-B term.

Failures are replies, never made-up values: OUT_OF_VIEW (a patch the measurement needs is
outside the frame), OCCLUDED (something nearer than the surface covers a patch),
TOO_FEW_PIXELS (too few valid pixels or edge points), FIT_RESIDUAL (a fit does not match).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from enum import Enum
from typing import Any, Union

import numpy as np
from numpy.typing import NDArray
from scipy import ndimage

from ita.part import geometry2d as g2
from ita.part.model import Feature, FlangeSegment, Hole, HoleRole, Pocket, Stiffener
from ita.sensors.slra_frame import RangeFrame, ScanGeometry
from ita.specs.model import MeasurementKind as K
from ita.specs.model import MeasurementSpec
from ita.vision import edges
from ita.vision.fit import (
    CircleFit,
    LineFit,
    PlaneFit,
    fit_circle,
    fit_circle_fixed_radius,
    fit_line,
    fit_parallel_planes,
    fit_plane,
)
from ita.vision.patches import Patch, View, nominal_points, place_patch
from ita.workcell.model import PartPlacement

FloatArray = NDArray[np.float64]

SLRA_KINDS = (K.HOLE_DIAMETER, K.HOLE_POSITION, K.FLANGE_HEIGHT, K.FLANGE_WIDTH,
              K.STIFFENER_HEIGHT, K.STIFFENER_WIDTH, K.EDGE_DISTANCE)
BLUR_MM = 1.0            # edge band half-width: >= 3 sigma of the SLRA's beam footprint
SURFACE_BAND_MM = 3.0    # a face's pixels lie within this of its nominal height
OCCLUDER_MM = 3.0        # a pixel this far in front of a face occludes it
MAX_OCCLUDED = 0.25      # share of a patch's pixels in front that makes it occluded
MIN_PLANE_PIXELS = 25
MIN_EDGE_POINTS = 12
MAX_PLANE_RMS_MM = 0.6
MAX_EDGE_RMS_MM = 0.3    # plus half a pixel
EDGE_CORRELATION = 1.6   # inflates edge-fit sigmas: row and column crossings share pixels
EDGE_MODEL_PX = 0.05     # residual bias of a sub-pixel edge point (pixels), not averaged away
MIX_RANGE_MM = 100.0     # a surface this far beyond the face mixes with it in phase (range share)
FAR_SPREAD_MM = 2.0      # beyond a rim, heights this far from their median are another surface,
FAR_MIXED_SHARE = 0.03   # and more than this share of them means several surfaces
FAR_MIXED_U_MM = 0.06    # then the rim's position (radius, centre) carries this much more
FAR_CHECK_MM = 0.6       # the surface just beyond a rim is looked for this far inside it (2 sigma of the beam)
DATUM_MIN_COVERAGE = math.radians(120)  # rim span a datum neighbour's fit needs
DIAMETER_TOLERANCE = 0.076  # +/- of a hole's diameter when its spec does not say
MAX_DATUM_HOLES = 6      # a fastener hole registers on at most this many neighbours in view
POSE_DATUM_FRAMES = 16   # re-approaches averaged for a position whose only datum is the pose
REAPPROACH_SHAPE = (128, 128)  # pixels of each re-approach frame (a rim fit needs no more)
MIN_HOLE_PIXELS = 11     # a fastener hole's position frame spans the hole's diameter with at least this many pixels
RASTER_STEP = 128        # a finer raster than ctx.shape grows in steps of this many pixels a side
MAX_RASTER = 1024        # and to at most this many


class Reason(str, Enum):
    """Why a measurement could not be made."""

    OUT_OF_VIEW = "out_of_view"
    OCCLUDED = "occluded"
    TOO_FEW_PIXELS = "too_few_pixels"
    FIT_RESIDUAL = "fit_residual"
    NOT_MEASURABLE = "not_measurable"


@dataclass(frozen=True)
class VisionException:
    """The reply when a measurement cannot be made: the reason and what was seen."""

    spec_id: str
    reason: Reason
    detail: str = ""
    ok = False


@dataclass(frozen=True)
class VisionResult:
    """A measured value (mm) with its standard uncertainty u (mm); U = 2u expanded."""

    spec_id: str
    kind: K
    value: float
    uncertainty: float
    diagnostics: dict[str, Any] = field(default_factory=dict, compare=False)
    ok = True

    @property
    def expanded(self) -> float:
        """Expanded uncertainty U = 2u (about 95 %)."""
        return 2.0 * self.uncertainty


Reply = Union[VisionResult, VisionException]  # noqa: UP007 (a runtime alias)


class _Fail(Exception):
    def __init__(self, reason: Reason, detail: str):
        super().__init__(detail)
        self.reason, self.detail = reason, detail


@dataclass(frozen=True)
class VisionContext:
    """What Vision knows besides the frame: nominal features, the part's placement, the
    SLRA's nominal standoff and largest window, and tolerances it needs for references.

    web_tolerance: +/- of the web thickness (a height's reference); position_zones: hole id
    -> true-position zone diameter; diameter_tolerances: hole id -> +/- of its diameter
    (a datum neighbour's radius, see :func:`_register_on_neighbours`); pose_sigma_m: the
    arm's pose error per axis (1 sigma);
    pose_datum_frames: frames (each from its own approach) averaged for a position whose
    only datum is the pose (see :func:`frames_for`).
    """

    features: Mapping[str, Feature]
    placement: PartPlacement
    standoff_m: float = 0.45
    max_fov_deg: tuple[float, float] = (30.0, 24.0)
    web_tolerance: float = 0.127
    position_zones: Mapping[str, float] = field(default_factory=dict)
    pose_sigma_m: float = 0.25e-3 / 3
    shape: tuple[int, int] = (256, 256)
    pose_datum_frames: int = POSE_DATUM_FRAMES
    diameter_tolerances: Mapping[str, float] = field(default_factory=dict)

    @classmethod
    def from_part(cls, part: Any, workcell: Any, tool: str = "slra_1", specs: Any = None) -> VisionContext:
        """Context of a loaded Part in a Workcell (specs: default read from the part)."""
        from ita.specs.io import read_specs

        specs = read_specs(part.specs_path) if specs is None else specs
        t = workcell.tool(tool)
        web = [s.upper for s in specs if s.kind is K.WEB_THICKNESS]
        zones = {s.feature: s.upper for s in specs if s.kind is K.HOLE_POSITION}
        diameters = {s.feature: (s.upper - s.lower) / 2 for s in specs if s.kind is K.HOLE_DIAMETER}
        return cls({f.id: f for f in part.features}, workcell.part, t.standoff_nominal, tuple(t.fov_deg),
                   max(web) if web else 0.127, zones, workcell.arm.repeatability_m / 3,
                   diameter_tolerances=diameters)

    def pockets(self) -> list[Pocket]:
        return [f for f in self.features.values() if isinstance(f, Pocket)]

    def web_at(self, xy: FloatArray) -> float | None:
        """Nominal web height (mm) of the pocket containing part point (2,), if any."""
        for p in self.pockets():
            if g2.points_in_polygon(np.atleast_2d(xy), p.outline_array)[0]:
                return p.web_thickness
        return None


# ----------------------------------------------------------------------------- windows

def _window_mm(spec: MeasurementSpec, ctx: VisionContext) -> float:
    f = ctx.features.get(spec.feature)
    margin = 2 * (BLUR_MM + 3.0) + 2.0
    if spec.kind is K.HOLE_DIAMETER and isinstance(f, Hole):
        return f.diameter + margin
    if spec.kind is K.HOLE_POSITION and isinstance(f, Hole):
        if f.role is HoleRole.FASTENER:
            nb = _neighbours(f, ctx, 1e9)[:2]
            reach = max((math.dist(h.center[:2], f.center[:2]) + h.diameter / 2 for h in nb), default=f.diameter)
            return 2 * (reach + BLUR_MM + 9.0)
        return f.diameter + margin
    if spec.kind is K.EDGE_DISTANCE and isinstance(f, Hole):
        return 2 * (abs(spec.nominal) + 12.0)
    if spec.kind in (K.FLANGE_HEIGHT, K.FLANGE_WIDTH) and isinstance(f, FlangeSegment):
        return 2 * (f.cap_width + 2.0)
    if spec.kind in (K.STIFFENER_HEIGHT, K.STIFFENER_WIDTH) and isinstance(f, Stiffener):
        return 2 * (f.width / 2 + 14.0)
    return 100.0


def scan_for(spec: MeasurementSpec, ctx: VisionContext) -> ScanGeometry:
    """The scan window and raster Vision asks of the SLRA for `spec` (from the nominal
    standoff): ctx.shape pixels, or more where :func:`_raster_for` needs them."""
    ang = math.degrees(2 * math.atan(_window_mm(spec, ctx) / 2 / (ctx.standoff_m * 1000)))
    fov = (min(ang, ctx.max_fov_deg[0]), min(ang, ctx.max_fov_deg[1]))
    return ScanGeometry(_raster_for(spec, ctx, fov), fov)


def _raster_for(spec: MeasurementSpec, ctx: VisionContext, fov_deg: tuple[float, float]) -> tuple[int, int]:
    """Pixels (rows, cols) of `spec`'s frame over a window of `fov_deg` (horizontal, vertical).

    A fastener hole's position is fitted on its own rim and its neighbours' half-rims, whose
    edge points grow with the pixels across a hole: where the window (wide enough for two
    neighbours) would put fewer than :data:`MIN_HOLE_PIXELS` across the hole's diameter at
    the nominal standoff, that axis gets the first multiple of :data:`RASTER_STEP` that puts
    that many (at most :data:`MAX_RASTER`).  Everything else: ctx.shape.
    """
    f = ctx.features.get(spec.feature)
    if not (spec.kind is K.HOLE_POSITION and isinstance(f, Hole) and f.role is HoleRole.FASTENER):
        return ctx.shape
    out = []
    for n, deg in zip(ctx.shape, (fov_deg[1], fov_deg[0])):     # rows span the vertical window
        window_mm = 2 * ctx.standoff_m * 1000 * math.tan(math.radians(deg) / 2)
        need = MIN_HOLE_PIXELS * window_mm / f.diameter
        out.append(n if need <= n else max(n, min(MAX_RASTER, RASTER_STEP * math.ceil(need / RASTER_STEP))))
    return out[0], out[1]


@dataclass(frozen=True)
class FramePlan:
    """The frames a spec needs: `count` frames, each after its own approach of the arm (a
    new draw of its pose error), the first of the spec's window, the others of `shape`
    pixels over the same window."""

    count: int
    shape: tuple[int, int]


def frames_for(spec: MeasurementSpec, ctx: VisionContext) -> FramePlan:
    """How many frames `spec` needs.  A lightening hole's position has no datum in view but
    the arm's pose, whose error (repeatability) is new at every approach: the deviations of
    ctx.pose_datum_frames approaches are averaged (:func:`measure_frames`), at
    :data:`REAPPROACH_SHAPE` pixels (its rim has hundreds of edge points even so).
    Everything else needs one frame."""
    f = ctx.features.get(spec.feature)
    if spec.kind is K.HOLE_POSITION and isinstance(f, Hole) and f.role is not HoleRole.FASTENER:
        return FramePlan(max(1, ctx.pose_datum_frames), REAPPROACH_SHAPE)
    return FramePlan(1, ctx.shape)


def _neighbours(hole: Hole, ctx: VisionContext, within: float) -> list[Hole]:
    out = [h for h in ctx.features.values() if isinstance(h, Hole) and h.role is HoleRole.FASTENER
           and h.id != hole.id and abs(h.center[2] - hole.center[2]) < 1.0
           and math.dist(h.center[:2], hole.center[:2]) < within]
    return sorted(out, key=lambda h: math.dist(h.center[:2], hole.center[:2]))


# ----------------------------------------------------------------------------- building blocks

def _frame_uv(u: FloatArray) -> tuple[FloatArray, FloatArray]:
    u = np.asarray(u, dtype=float)[:2]
    u = u / np.linalg.norm(u)
    return u, np.array([-u[1], u[0]])


def _rect_patch(view: View, name: str, c: FloatArray, u: FloatArray, v: FloatArray, u_range: tuple[float, float],
                v_range: tuple[float, float], z: float) -> tuple[Patch, NDArray[np.bool_]]:
    """Patch over the rectangle c + s u + t v (s, t in the ranges) at height z, and its
    region mask; raises OUT_OF_VIEW."""
    corners = np.array([np.append(c + s * u + t * v, z) for s in u_range for t in v_range])
    patch = place_patch(view, name, corners)
    if patch is None:
        raise _Fail(Reason.OUT_OF_VIEW, f"patch {name!r} is outside the frame")
    q = nominal_points(view, patch, z)[..., :2] - c
    s, t = q @ u, q @ v
    region = (s >= u_range[0]) & (s <= u_range[1]) & (t >= v_range[0]) & (t <= v_range[1])
    return patch, region


def _face(view: View, patch: Patch, region: NDArray[np.bool_], z: float) -> tuple[PlaneFit, NDArray[np.bool_]]:
    """Plane fit to the pixels of `region` on the face at nominal height z; raises OCCLUDED,
    TOO_FEW_PIXELS, FIT_RESIDUAL.  Returns the fit and the pixels used."""
    p = patch.take(view.points)
    valid = np.isfinite(p[..., 2]) & region
    n_region = int(region.sum())
    with np.errstate(invalid="ignore"):
        front = valid & (p[..., 2] > z + OCCLUDER_MM)
        near = valid & (np.abs(p[..., 2] - z) < SURFACE_BAND_MM)
    if n_region and front.sum() > MAX_OCCLUDED * n_region:
        raise _Fail(Reason.OCCLUDED, f"{int(front.sum())} of {n_region} pixels of {patch.name!r} are "
                    f"more than {OCCLUDER_MM} mm in front of the face")
    if near.sum() < MIN_PLANE_PIXELS:
        raise _Fail(Reason.TOO_FEW_PIXELS, f"{int(near.sum())} valid pixels on {patch.name!r} "
                    f"(of {n_region}; need {MIN_PLANE_PIXELS})")
    fit = fit_plane(p[near])
    if fit is None:
        raise _Fail(Reason.TOO_FEW_PIXELS, f"no plane on {patch.name!r}")
    if fit.rms > MAX_PLANE_RMS_MM:
        raise _Fail(Reason.FIT_RESIDUAL, f"plane on {patch.name!r}: rms {fit.rms:.3f} mm > {MAX_PLANE_RMS_MM}")
    with np.errstate(invalid="ignore"):
        near &= np.abs(p[..., 2] - (fit.coef[0] * p[..., 0] + fit.coef[1] * p[..., 1] + fit.coef[2])) < 3.5 * fit.rms
    return fit, near


def _share(view: View, patch: Patch, near: PlaneFit, near_px: NDArray[np.bool_] | None,
           far_region: NDArray[np.bool_], far_ref: NDArray[np.int64] | None = None) -> tuple[FloatArray, str]:
    """Far share s (h, w) over the patch for an edge between the face `near` and what lies in
    `far_region`; from ranges when the far side returns, from intensity otherwise.
    far_ref: (2, h, w) patch pixel whose far surface each pixel mixes with (default: the
    nearest far pixel)."""
    d = patch.take(view.dirs)
    r = patch.take(view.range_mm)
    inten = patch.take(view.intensity)
    r_n = view.plane_range(near.coef, d)
    with np.errstate(invalid="ignore"):
        on_near = np.isfinite(r) & (np.abs(r - r_n) < max(4 * near.rms, 0.3))
    if near_px is not None:
        on_near &= near_px | ~far_region
    i_near = float(np.median(inten[on_near])) if on_near.any() else np.nan
    far_valid = far_region & np.isfinite(r)
    s_i = _intensity_share(view, near, d, r_n, inten, on_near)
    if far_valid.sum() < max(6, 0.5 * far_region.sum()):
        s_i[~np.isfinite(r) & (inten <= 0)] = 1.0
        return s_i, "intensity"
    # what lies beyond may be several surfaces (a rib or a fixture under part of a hole, the
    # far floor under the rest): each pixel takes the range and brightness of the far pixel
    # it mixes with, and its share comes from the range where that surface is near enough
    # to mix in phase, from the intensity where it is not (per pixel, never one mode for all)
    _, (ri, ci) = ndimage.distance_transform_edt(~far_valid, return_indices=True)
    if far_ref is not None:
        use = far_valid[far_ref[0], far_ref[1]]
        ri, ci = np.where(use, far_ref[0], ri), np.where(use, far_ref[1], ci)
    r_f, ratio = r[ri, ci], inten[ri, ci] / i_near
    with np.errstate(invalid="ignore"):
        in_phase = (r_f - r_n > 0.3) & (r_f - r_n < MIX_RANGE_MM)
    if not in_phase.any():
        s_i[~np.isfinite(r) & (inten <= 0)] = 1.0
        return s_i, "intensity"
    # a dark third surface (a bore's wall near grazing) is "not the face" too
    s_r = np.fmax(edges.far_share_from_range(r, r_n, r_f, ratio), np.where(np.isfinite(r), s_i, np.nan))
    s = np.where(in_phase, s_r, s_i)
    s[~in_phase & ~np.isfinite(r) & (inten <= 0)] = 1.0
    return s, "range" if in_phase.all() else "range+intensity"


def _intensity_share(view: View, near: PlaneFit, d: FloatArray, r_n: FloatArray, inten: FloatArray,
                     on_near: NDArray[np.bool_]) -> FloatArray:
    """Far share from intensity against the face's expected return K cos(theta) / R^2."""
    cos = np.abs(d @ near.normal)
    k = np.median((inten * r_n ** 2 / cos)[on_near]) if on_near.any() else np.nan
    return edges.far_share_from_intensity(inten, k * cos / r_n ** 2)


def _edge_xy(view: View, patch: Patch, s: FloatArray, band: NDArray[np.bool_], near: PlaneFit) -> FloatArray:
    """Part-frame (x, y) (n, 2) of the sub-pixel edge points of `s` inside `band`."""
    rc = edges.crossings(s, band)
    if not len(rc):
        return np.zeros((0, 2))
    xyz = view.on_plane(rc + [patch.r0, patch.c0], near.coef)
    return xyz[:, :2]


def _circle(view: View, hole: Hole, name: str, min_coverage: float = math.pi,
            radius: float | None = None) -> tuple[CircleFit, PlaneFit, dict]:
    """The hole's rim circle on its entry face; its points must span `min_coverage` (rad).
    radius: fit the centre only, with this radius (mm).

    Each rim pixel mixes the face with what lies just beyond the rim on its own radius;
    its far share takes that surface from a pixel well inside (clear of the blur).  Where
    the surface seen just inside the rim (:data:`FAR_CHECK_MM` in) is another one (a rib's
    top against the floor beside it, a return against none), that reference is wrong and
    the edge found there is off by a good part of the blur: such radii give no rim points
    (see :func:`_other_far`), in frames whose pixels are fine enough to tell (a quarter of
    FAR_CHECK_MM or less; coarser pixels would blur the check into the rim itself)."""
    c, r, z = np.asarray(hole.center[:2]), hole.diameter / 2, hole.center[2]
    b = BLUR_MM + view.pixel_mm(view.range_mm[np.isfinite(view.range_mm)].mean() if np.isfinite(view.range_mm).any()
                                else 450.0)
    outer = r + b + max(3.0, 6 * view.pixel_mm(450.0))
    corners = np.array([[c[0] + sx * outer, c[1] + sy * outer, z] for sx in (-1, 1) for sy in (-1, 1)])
    h, w = view.shape
    rc = view.pixel_of(corners)
    centre_rc = view.pixel_of(np.append(c, z)[None])
    if not view.geometry.contains(centre_rc).all():
        raise _Fail(Reason.OUT_OF_VIEW, f"centre of {hole.id} is outside the frame")
    rc = np.clip(rc, 0, [h - 1, w - 1])
    patch = Patch(name, int(rc[:, 0].min()), int(np.ceil(rc[:, 0].max())) + 1, int(rc[:, 1].min()),
                  int(np.ceil(rc[:, 1].max())) + 1, np.ones((1, 1), bool))
    q = nominal_points(view, patch, z)[..., :2] - c
    rho = np.hypot(q[..., 0], q[..., 1])
    in_view_share = _circle_in_view(view, c, r, z)
    if in_view_share < 0.5:
        raise _Fail(Reason.OUT_OF_VIEW, f"only {in_view_share:.0%} of {hole.id}'s rim is in the frame")
    annulus = (rho > r + b) & (rho < outer)
    near, near_px = _face(view, patch, annulus, z)
    far_r = max(r - b, 0.5 * r)
    far_region = rho < far_r
    # each pixel mixes with what lies beyond the rim on its own radius
    far_ref = _radial_pixels(view, patch, q, rho, c, z, far_r - view.pixel_mm(450.0))
    s, mode = _share(view, patch, near, near_px, far_region, far_ref)
    band = np.abs(rho - r) < b
    px_far = view.pixel_mm(450.0)
    if px_far <= FAR_CHECK_MM / 4:     # pixels fine enough to see what lies just inside the rim
        check_ref = _radial_pixels(view, patch, q, rho, c, z, max(r - FAR_CHECK_MM - px_far, far_r - px_far))
        band &= ~_other_far(patch.take(view.points)[..., 2], far_ref, check_ref, z)
    xy = _edge_xy(view, patch, s, band, near)
    hidden, tilt = _wall_hidden(view, xy, c, z, hole.depth)
    wall_u = 0.0
    if hidden.sum() >= max(MIN_EDGE_POINTS, 0.4 * len(xy)):
        xy = xy[hidden]
    elif len(xy):
        xy, wall_u = _past_the_wall(xy, c, tilt, hole.depth)
    if len(xy) < MIN_EDGE_POINTS:
        raise _Fail(Reason.TOO_FEW_PIXELS, f"{len(xy)} rim points of {hole.id} (need {MIN_EDGE_POINTS})")
    fit = fit_circle(xy) if radius is None else fit_circle_fixed_radius(xy, radius)
    if fit is None or fit.coverage < min_coverage:
        raise _Fail(Reason.TOO_FEW_PIXELS, f"rim points of {hole.id} cover {math.degrees(fit.coverage) if fit else 0:.0f}"
                    f" deg of the circle (need {math.degrees(min_coverage):.0f})")
    px = view.pixel_mm(float(np.median(view.plane_range(near.coef, patch.take(view.dirs)))))
    if fit.rms > MAX_EDGE_RMS_MM + 0.5 * px:
        raise _Fail(Reason.FIT_RESIDUAL, f"rim of {hole.id}: rms {fit.rms:.3f} mm")
    # several surfaces beyond the rim (a rib under the hole) break the two-surface model of
    # the mixed pixels: a type-B term, sized on such holes, instead of a false precision
    z_far = patch.take(view.points)[..., 2][far_region]
    z_far = z_far[np.isfinite(z_far)]
    spread = float(np.mean(np.abs(z_far - np.median(z_far)) > FAR_SPREAD_MM)) if len(z_far) > 5 else 0.0
    far_u = FAR_MIXED_U_MM if spread > FAR_MIXED_SHARE else 0.0
    model = math.hypot(far_u, wall_u)
    return fit, near, {"edge_points": int(fit.n), "rim_rms": fit.rms, "mode": mode, "pixel_mm": px,
                       "far_other_share": spread, "wall_u": wall_u, "u_model": model,
                       "u_model_centre": model,
                       "patch": (patch.r0, patch.r1, patch.c0, patch.c1), "rim_xy": xy}


def _radial_pixels(view: View, patch: Patch, q: FloatArray, rho: FloatArray, c: FloatArray, z: float,
                   at: float) -> NDArray[np.int64]:
    """(2, h, w) patch pixel on each pixel's own radius (q (h, w, 2) from the centre c, at
    distance rho) at distance `at` (mm) from c, on the plane z; clipped to the patch."""
    unit = q / np.maximum(rho, 1e-9)[..., None]
    pts = np.concatenate([c + at * unit, np.full(rho.shape + (1,), z)], axis=-1)
    rc = np.rint(view.pixel_of(pts.reshape(-1, 3))).reshape(rho.shape + (2,)) - [patch.r0, patch.c0]
    rc = np.nan_to_num(rc, nan=0.0).astype(np.int64)
    return np.stack([np.clip(rc[..., 0], 0, rho.shape[0] - 1), np.clip(rc[..., 1], 0, rho.shape[1] - 1)])


def _other_far(z_img: FloatArray, far_ref: NDArray[np.int64], check_ref: NDArray[np.int64],
               z: float) -> NDArray[np.bool_]:
    """(h, w) pixels whose far reference (height z_img at far_ref) is another surface than
    the one just inside the rim (at check_ref): one returns and the other does not, or
    their heights differ by more than FAR_SPREAD_MM and a third of the deeper one's depth
    below the face at z (the pixel at check_ref still holds some of the face: up to a
    fifth of it where the rim lies its farthest from nominal)."""
    z_f = z_img[far_ref[0], far_ref[1]]
    z_c = z_img[check_ref[0], check_ref[1]]
    fin_f, fin_c = np.isfinite(z_f), np.isfinite(z_c)
    with np.errstate(invalid="ignore"):
        depth = z - np.fmin(z_f, z_c)
        apart = np.abs(z_f - z_c) > np.maximum(FAR_SPREAD_MM, depth / 3)
    return (fin_f != fin_c) | (fin_f & fin_c & apart)


def _wall_hidden(view: View, xy: FloatArray, c: FloatArray, z: float, depth: float
                 ) -> tuple[NDArray[np.bool_], FloatArray]:
    """Rim points (n, 2) where the hole's wall is not in view, and the outward tilt tau (n,)
    of the ray at each (tan of its angle from the axis, across the rim).  Off the optical
    axis the beam sees down the far side of a bore: its wall (a third surface, near
    grazing) shows over depth * tau there and would pull the edge inward; such points are
    left out of the fit when enough others remain (see :func:`_past_the_wall`)."""
    if not len(xy):
        return np.zeros(0, dtype=bool), np.zeros(0)
    ray = xy - view.origin[:2]
    lateral = ray / max(abs(z - view.origin[2]), 1e-9)            # tan of the ray's tilt, as a vector
    radial = (xy - c) / np.linalg.norm(xy - c, axis=1, keepdims=True)
    tilt = np.maximum((lateral * radial).sum(1), 0.0)
    return depth * tilt < max(0.1, 0.25 * view.pixel_mm(abs(z - view.origin[2]))), tilt


def _past_the_wall(xy: FloatArray, c: FloatArray, tilt: FloatArray, depth: float) -> tuple[FloatArray, float]:
    """Rim points (n, 2) where the bore's wall shows beyond the rim (a large hole, whose
    whole rim the rays cross tilted outward by tau = `tilt` (n,)), moved to the middle of
    where the top rim may lie, and the standard uncertainty (mm) left on the radius.

    The wall shows over w = depth * tau, lit at about tau of the face's brightness (cos of
    its incidence against the face's).  A dark wall is "beyond" to the edge model, so the
    edge found lies between the rim (a black wall) and tau * w inside it (the share of the
    wall's light that the model takes for the face's): the points move out by half of
    depth * tau^2, and the other half is a uniform type-B term, the same all round (radius
    and, conservatively, each centre coordinate)."""
    half = depth * tilt ** 2 / 2
    radial = (xy - c) / np.maximum(np.linalg.norm(xy - c, axis=1, keepdims=True), 1e-9)
    return xy + half[:, None] * radial, float(np.mean(half)) / math.sqrt(3)


def _circle_in_view(view: View, c: FloatArray, r: float, z: float) -> float:
    t = np.linspace(0, 2 * np.pi, 72, endpoint=False)
    pts = np.column_stack([c[0] + r * np.cos(t), c[1] + r * np.sin(t), np.full(len(t), z)])
    return float(view.geometry.contains(view.pixel_of(pts), margin=1).mean())


def _edge_sigma(px: float, n: int) -> float:
    """A floor for a fitted edge's position: the sub-pixel model's residual bias."""
    return EDGE_MODEL_PX * px


def _line(view: View, near: PlaneFit, near_px, patch: Patch, region_band, far_region, name: str,
          nominal: FloatArray | None = None) -> tuple[LineFit, dict]:
    """Line through the edge points; nominal: the edge's nominal polyline (k, 2) when it is
    curved: the points are straightened against it first (a line through an arc of
    radius R over +/-L sits about L^2 / 3R off the arc's apex)."""
    s, mode = _share(view, patch, near, near_px, far_region)
    xy = _edge_xy(view, patch, s, region_band, near)
    if nominal is not None and len(xy):
        xy = _straighten(xy, nominal)
    if len(xy) < MIN_EDGE_POINTS:
        raise _Fail(Reason.TOO_FEW_PIXELS, f"{len(xy)} points on edge {name!r} (need {MIN_EDGE_POINTS})")
    fit = fit_line(xy)
    px = view.pixel_mm(float(np.median(view.plane_range(near.coef, patch.take(view.dirs)))))
    if fit is None or fit.rms > MAX_EDGE_RMS_MM + 0.5 * px:
        raise _Fail(Reason.FIT_RESIDUAL, f"edge {name!r}: rms {fit.rms if fit else float('nan'):.3f} mm")
    return fit, {"mode": mode, "points": fit.n, "rms": fit.rms, "pixel_mm": px, "xy": xy}


def _straighten(xy: FloatArray, curve: FloatArray) -> FloatArray:
    """Points (n, 2) moved across the tangent of `curve` (k, 2) at its middle by minus the
    curve's own offset from that tangent at their position along it."""
    mid = len(curve) // 2
    t = curve[min(mid + 1, len(curve) - 1)] - curve[max(mid - 1, 0)]
    t = t / np.linalg.norm(t)
    n = np.array([-t[1], t[0]])
    s_c, n_c = (curve - curve[mid]) @ t, (curve - curve[mid]) @ n
    order = np.argsort(s_c)
    s_p = (xy - curve[mid]) @ t
    bend = np.interp(s_p, s_c[order], n_c[order])
    return xy - bend[:, None] * n


def _free_edge(ctx: VisionContext, hole: Hole, distance: float, u: FloatArray) -> FloatArray | None:
    """Nominal free edge of the hole's flange cap near it, (k, 2), +/-12 mm, centred on the
    point `distance` along u from the hole; None when the parent is not a flange."""
    seg = ctx.features.get(hole.parent)
    if not isinstance(seg, FlangeSegment):
        return None
    edge = seg.path_array + seg.normals_array * seg.cap_width
    foot = np.asarray(hole.center[:2]) + distance * u
    step = np.linalg.norm(np.diff(edge, axis=0), axis=1)
    s = np.concatenate([[0.0], np.cumsum(step)])
    i = int(np.argmin(np.linalg.norm(edge - foot, axis=1)))
    grid = s[i] + np.linspace(-12.0, 12.0, 25)
    pts = np.column_stack([np.interp(grid, s, edge[:, 0]), np.interp(grid, s, edge[:, 1])])
    t = pts[-1] - pts[0]
    t = t / np.linalg.norm(t)
    shift = foot - pts[12]
    return pts + (shift @ np.array([-t[1], t[0]])) * np.array([-t[1], t[0]]) + (shift @ t) * t


# ----------------------------------------------------------------------------- per kind

def _hole_diameter(view: View, spec: MeasurementSpec, hole: Hole, ctx: VisionContext) -> VisionResult:
    fit, _, diag = _circle(view, hole, "rim")
    px = diag["pixel_mm"]
    u = math.hypot(2 * EDGE_CORRELATION * fit.radius_sigma, 2 * _edge_sigma(px, fit.n))
    u = math.hypot(u, 2e-4 * fit.radius, 2 * diag["u_model"])  # + scanner angle-scale calibration
    diag.update(center=fit.center)
    return VisionResult(spec.id, spec.kind, 2 * fit.radius, u, diag)


def _datum_neighbours(view: View, hole: Hole, ctx: VisionContext) -> list[Hole]:
    """The fastener holes beside `hole` (same face) that serve as its datum in this frame:
    those whose whole rim patch (rim, blur band, face annulus) lies inside the frame, with
    a margin of 3 sigma of the arm's pose error and a pixel, as seen from the REPORTED
    pose; of these, those with no rib beneath them in view (:func:`_rib_beneath`) when
    there is one such.  The set depends on the nominal part and the commanded pose only,
    never on what the frame shows, so repeated frames register on the same holes."""
    px = view.pixel_mm(ctx.standoff_m * 1000)
    margin = 3 * ctx.pose_sigma_m / ctx.placement.scale + px
    out = []
    for nb in _neighbours(hole, ctx, math.inf)[:MAX_DATUM_HOLES * 4]:
        reach = nb.diameter / 2 + BLUR_MM + px + max(3.0, 6 * px) + margin
        corners = np.array([[nb.center[0] + sx * reach, nb.center[1] + sy * reach, nb.center[2]]
                            for sx in (-1, 1) for sy in (-1, 1)])
        if view.geometry.contains(view.pixel_of(corners)).all():
            out.append(nb)
    clean = [nb for nb in out if not _rib_beneath(view, nb, ctx)]
    return (clean or out)[:MAX_DATUM_HOLES]


def _rib_beneath(view: View, hole: Hole, ctx: VisionContext) -> bool:
    """Whether a nominal stiffener shows through `hole` from the view's (reported) origin:
    its strip comes within the hole's radius and a millimetre of where the rays through
    the hole reach at the rib's heights (they lean away from the view axis by their tilt
    times the depth).  Such a rim has several surfaces beyond it, whose mixed pixels the
    two-surface edge model does not fit."""
    c, z = np.asarray(hole.center[:2]), hole.center[2]
    tilt = (c - view.origin[:2]) / max(view.origin[2] - z, 1e-9)
    for rib in ctx.features.values():
        if not isinstance(rib, Stiffener) or rib.height >= z:
            continue
        a, b = np.asarray(rib.start), np.asarray(rib.end)
        reach = hole.diameter / 2 + rib.width / 2 + 1.0
        seen = np.array([c + tilt * (z - rib.height), c + tilt * z])    # rib top down to datum A
        if _segments_apart(seen, np.array([a, b])) < reach:
            return True
    return False


def _segments_apart(p: FloatArray, q: FloatArray) -> float:
    """Least distance between the segments p (2, 2) and q (2, 2)."""
    def to_segment(x: FloatArray, s: FloatArray) -> float:
        d = s[1] - s[0]
        t = float(np.clip((x - s[0]) @ d / max(float(d @ d), 1e-12), 0.0, 1.0))
        return float(np.linalg.norm(x - (s[0] + t * d)))

    if _segments_cross(p, q):
        return 0.0
    return min(to_segment(p[0], q), to_segment(p[1], q), to_segment(q[0], p), to_segment(q[1], p))


def _segments_cross(p: FloatArray, q: FloatArray) -> bool:
    def side(a: FloatArray, b: FloatArray, x: FloatArray) -> float:
        return float((b[0] - a[0]) * (x[1] - a[1]) - (b[1] - a[1]) * (x[0] - a[0]))

    return (side(p[0], p[1], q[0]) * side(p[0], p[1], q[1]) < 0
            and side(q[0], q[1], p[0]) * side(q[0], q[1], p[1]) < 0)


def _register_on_neighbours(view: View, hole: Hole, radius: float | None, ctx: VisionContext
                            ) -> tuple[FloatArray, float, list[str], list[str]]:
    """The frame's shift (2,) from the datum neighbours' measured to nominal centres (their
    mean), its per-axis standard uncertainty, the neighbours used and those left out (a
    rim that cannot be measured in this frame; one whose offset is more than a zone radius
    from the median of three or more: out of its own tolerance, or mis-measured).

    Off the axis a neighbour's far side shows its bore's wall and is left out, so its rim
    points span about half the circle: its centre is fitted with the radius fixed to
    `radius` (the hole's own, fitted over its whole rim) plus the difference of their
    nominal diameters.  Their as-built diameters differ (each uniform over its
    tolerance), which moves a half-circle's centre by about 1.3 times the radius
    difference along its bisector: a type-B term in the uncertainty.  radius None: their
    radii are fitted too."""
    offsets, u_nb, used, left = [], [], [], []
    for nb in _datum_neighbours(view, hole, ctx):
        try:
            f2, _, d2 = _circle(view, nb, f"rim {nb.id}", DATUM_MIN_COVERAGE,
                                None if radius is None else radius + (nb.diameter - hole.diameter) / 2)
        except _Fail:
            left.append(nb.id)
            continue
        t_r = math.hypot(ctx.diameter_tolerances.get(nb.id, DIAMETER_TOLERANCE),
                         ctx.diameter_tolerances.get(hole.id, DIAMETER_TOLERANCE)) / 2 / math.sqrt(3)
        offsets.append(np.asarray(nb.center[:2]) - np.asarray(f2.center))
        u_nb.append(math.hypot(EDGE_CORRELATION * max(f2.center_sigma), _edge_sigma(d2["pixel_mm"], f2.n),
                               d2["u_model_centre"], 0.0 if radius is None else 1.3 * t_r))
        used.append(nb.id)
    if len(offsets) >= 3:
        mid = np.median(offsets, axis=0)
        ok = [float(np.linalg.norm(o - mid)) <= ctx.position_zones.get(i, 0.5) / 2
              for o, i in zip(offsets, used)]
        left += [i for i, k in zip(used, ok) if not k]
        offsets = [o for o, k in zip(offsets, ok) if k]
        u_nb = [u for u, k in zip(u_nb, ok) if k]
        used = [i for i, k in zip(used, ok) if k]
    if not used:
        return np.zeros(2), math.nan, used, left
    k = len(used)
    zone = max(ctx.position_zones.get(i, 0.5) for i in used)
    # each neighbour's own position error, taken as uniform over its zone (sigma zone / 4
    # per axis), averages down by k; so do the scatter of their rim fits and their radii
    u_reg = math.sqrt((zone / 4) ** 2 / k + float(np.mean(np.square(u_nb))) / k)
    return np.mean(offsets, axis=0), u_reg, used, left


def _hole_position(view: View, spec: MeasurementSpec, hole: Hole, ctx: VisionContext) -> VisionResult:
    fit, _, diag = _circle(view, hole, "rim")
    px = diag["pixel_mm"]
    u_fit = math.hypot(EDGE_CORRELATION * max(fit.center_sigma), _edge_sigma(px, fit.n))
    shift, u_reg, used, left = np.zeros(2), math.nan, [], []
    if hole.role is HoleRole.FASTENER:
        # a rim with a rib beneath is fitted less well than its neighbours' are: no radius for them
        radius = None if _rib_beneath(view, hole, ctx) else fit.radius
        shift, u_reg, used, left = _register_on_neighbours(view, hole, radius, ctx)
    pose_u = ctx.pose_sigma_m / ctx.placement.scale
    d = np.asarray(fit.center) + shift - np.asarray(hole.center[:2])
    # random from frame to frame: the rim fit and, with the pose as datum, the arm's pose
    # error (a new draw at each approach); the same in every frame: the edge model and the
    # neighbours' own position errors
    u_random = math.hypot(u_fit, pose_u) if not used else u_fit
    u_system = math.hypot(diag["u_model_centre"], u_reg) if used else diag["u_model_centre"]
    u_axis = math.hypot(u_random, u_system)
    diag.update(center=fit.center, registered_on=used, left_out=left, shift=tuple(shift), deviation=tuple(d),
                datum="neighbours" if used else "pose", u_random=u_random, u_systematic=u_system)
    return VisionResult(spec.id, spec.kind, 2 * float(np.hypot(*d)), 2 * u_axis, diag)


def _edge_distance(view: View, spec: MeasurementSpec, hole: Hole, ctx: VisionContext) -> VisionResult:
    fit, _, diag = _circle(view, hole, "rim")
    u, v = _frame_uv(spec.direction or (1.0, 0.0, 0.0))
    c = np.asarray(hole.center[:2])
    edge = c + spec.nominal * u
    b = BLUR_MM + diag["pixel_mm"]
    patch, region = _rect_patch(view, "free edge", edge, u, v, (-spec.nominal + hole.diameter / 2 + b, b + 6.0),
                                (-8.0, 8.0), hole.center[2])
    q = nominal_points(view, patch, hole.center[2])[..., :2] - edge
    s_u = q @ u
    near_region = region & (s_u < -b) & (np.hypot(*(q + edge - c).transpose(2, 0, 1)) > hole.diameter / 2 + b)
    near2, near_px = _face(view, patch, near_region, hole.center[2])
    line, ldiag = _line(view, near2, near_px, patch, region & (np.abs(s_u) < b), region & (s_u > b), "free edge",
                        _free_edge(ctx, hole, spec.nominal, u))
    dist = float(line.distance(np.asarray(fit.center))[0])
    sign = 1.0 if float(np.dot([-line.direction[1], line.direction[0]], u)) < 0 else -1.0
    value = sign * dist
    u_val = math.sqrt(line.offset_sigma_at(np.asarray(fit.center)) ** 2 * EDGE_CORRELATION ** 2
                      + (EDGE_CORRELATION * max(fit.center_sigma)) ** 2 + 2 * _edge_sigma(diag["pixel_mm"], 1) ** 2
                      + diag["u_model"] ** 2)
    diag.update(edge_points=ldiag["points"], edge_rms=ldiag["rms"], edge_xy=ldiag["xy"])
    return VisionResult(spec.id, spec.kind, value, u_val, diag)


def _web_plane(view: View, c: FloatArray, u: FloatArray, v: FloatArray, u_range, v_range, ctx: VisionContext,
               name: str) -> tuple[FloatArray, float]:
    mid = c + 0.5 * (u_range[0] + u_range[1]) * u
    z_web = ctx.web_at(mid)
    if z_web is None:
        raise _Fail(Reason.NOT_MEASURABLE, f"no pocket floor beside the feature at {tuple(np.round(mid, 1))}")
    patch, region = _rect_patch(view, name, c, u, v, u_range, v_range, z_web)
    _, used = _face(view, patch, region, z_web)
    return patch.take(view.points)[used], z_web


def _height(top: FloatArray, webs: list[tuple[FloatArray, float]], ctx: VisionContext) -> tuple[float, float, dict]:
    """Height of the top face above datum A from its gap to the web faces beside it, fitted
    as parallel planes (points (n, 3) of each), plus the webs' nominal heights."""
    fit = fit_parallel_planes([top] + [w for w, _ in webs])
    h = [fit.offsets[0] - fit.offsets[1 + i] + zw for i, (_, zw) in enumerate(webs)]
    u_fit = math.sqrt(np.mean([fit.gap_sigma(0, 1 + i) ** 2 for i in range(len(webs))]))
    u_web = ctx.web_tolerance / math.sqrt(3) / math.sqrt(len(webs))
    return float(np.mean(h)), math.hypot(u_fit, u_web), {"rms": fit.rms, "u_fit": u_fit, "u_web": u_web,
                                                         "pixels": [len(top)] + [len(w) for w, _ in webs]}


def _flange(view: View, spec: MeasurementSpec, seg: FlangeSegment, ctx: VisionContext) -> VisionResult:
    u, v = _frame_uv(spec.direction or _inward(seg, spec))
    p = np.asarray(spec.point[:2])
    outer = p - u * (seg.wall_thickness + seg.cap_width) / 2          # the wall's free face
    free = outer + u * seg.cap_width
    b = BLUR_MM + view.pixel_mm(ctx.standoff_m * 1000)
    along = (-8.0, 8.0)
    patch, region = _rect_patch(view, "cap", outer, u, v, (-b - 5.0, seg.cap_width + b + 5.0), along, seg.height)
    q = nominal_points(view, patch, seg.height)[..., :2] - outer
    s_u = q @ u
    cap_region = region & (s_u > b) & (s_u < seg.cap_width - b)
    cap, cap_px = _face(view, patch, cap_region, seg.height)
    if spec.kind is K.FLANGE_HEIGHT:
        web = _web_plane(view, free, u, v, (b + 2.0, b + 14.0), along, ctx, "web")
        value, unc, diag = _height(patch.take(view.points)[cap_px], [web], ctx)
        return VisionResult(spec.id, spec.kind, value, unc, diag)
    l_out, d_out = _line(view, cap, cap_px, patch, region & (np.abs(s_u) < b), region & (s_u < -b), "outer edge")
    l_free, d_free = _line(view, cap, cap_px, patch, region & (np.abs(s_u - seg.cap_width) < b),
                           region & (s_u > seg.cap_width + b), "free edge")
    return _width(spec, p, l_out, l_free, d_out, d_free)


def _width(spec: MeasurementSpec, p: FloatArray, a: LineFit, b: LineFit, da: dict, db: dict) -> VisionResult:
    value = abs(float(a.distance(p)[0]) - float(b.distance(p)[0])) if np.dot(a.direction, b.direction) > 0 else \
        abs(float(a.distance(p)[0]) + float(b.distance(p)[0]))
    u = math.sqrt((EDGE_CORRELATION * a.offset_sigma_at(p)) ** 2 + (EDGE_CORRELATION * b.offset_sigma_at(p)) ** 2
                  + _edge_sigma(da["pixel_mm"], a.n) ** 2 + _edge_sigma(db["pixel_mm"], b.n) ** 2)
    u = math.hypot(u, 2e-4 * value)
    return VisionResult(spec.id, spec.kind, value, u, {"edge_points": (a.n, b.n), "edge_rms": (a.rms, b.rms),
                                                       "modes": (da["mode"], db["mode"]),
                                                       "edge_xy": np.vstack([da["xy"], db["xy"]])})


def _inward(seg: FlangeSegment, spec: MeasurementSpec) -> FloatArray:
    path = seg.path_array
    i = int(np.argmin(np.linalg.norm(path - np.asarray(spec.point[:2]), axis=1)))
    return seg.normals_array[i]


def _stiffener(view: View, spec: MeasurementSpec, rib: Stiffener, ctx: VisionContext) -> VisionResult:
    along, across = _frame_uv(rib.direction)
    p = np.asarray(spec.point[:2])
    b = BLUR_MM + view.pixel_mm(ctx.standoff_m * 1000)
    half = rib.width / 2
    span = (-10.0, 10.0)
    patch, region = _rect_patch(view, "rib", p, across, along, (-half - b - 4.0, half + b + 4.0), span, rib.height)
    q = nominal_points(view, patch, rib.height)[..., :2] - p
    t = q @ across
    top_w = max(half - b, 0.3)
    top, top_px = _face(view, patch, region & (np.abs(t) < top_w), rib.height)
    if spec.kind is K.STIFFENER_HEIGHT:
        webs = []
        for side in (-1.0, 1.0):
            try:
                webs.append(_web_plane(view, p, side * across, along, (half + b + 1.0, half + b + 11.0), span, ctx,
                                       f"web {'left' if side < 0 else 'right'}"))
            except _Fail as exc:
                if exc.reason is not Reason.NOT_MEASURABLE and exc.reason is not Reason.TOO_FEW_PIXELS:
                    raise
        if not webs:
            raise _Fail(Reason.TOO_FEW_PIXELS, "no web visible beside the rib")
        value, unc, diag = _height(patch.take(view.points)[top_px], webs, ctx)
        return VisionResult(spec.id, spec.kind, value, unc, diag)
    lines = []
    for side in (-1.0, 1.0):
        lines.append(_line(view, top, top_px, patch, region & (np.abs(t - side * half) < b),
                           region & (side * t > half + b), f"side {side:+.0f}"))
    return _width(spec, p, lines[0][0], lines[1][0], lines[0][1], lines[1][1])


_MEASURES = {
    K.HOLE_DIAMETER: (Hole, _hole_diameter),
    K.HOLE_POSITION: (Hole, _hole_position),
    K.EDGE_DISTANCE: (Hole, _edge_distance),
    K.FLANGE_HEIGHT: (FlangeSegment, _flange),
    K.FLANGE_WIDTH: (FlangeSegment, _flange),
    K.STIFFENER_HEIGHT: (Stiffener, _stiffener),
    K.STIFFENER_WIDTH: (Stiffener, _stiffener),
}


def measure(frame: RangeFrame, spec: MeasurementSpec, ctx: VisionContext) -> Reply:
    """Measure `spec` in `frame`: a VisionResult, or a VisionException saying why not."""
    entry = _MEASURES.get(spec.kind)
    feature = ctx.features.get(spec.feature)
    if entry is None or not isinstance(feature, entry[0]):
        return VisionException(spec.id, Reason.NOT_MEASURABLE,
                               f"the SLRA does not measure {spec.kind.value} of {spec.feature!r}")
    try:
        return entry[1](View(frame, ctx.placement), spec, feature, ctx)
    except _Fail as exc:
        return VisionException(spec.id, exc.reason, exc.detail)


def measure_frames(frames: Sequence[RangeFrame], spec: MeasurementSpec, ctx: VisionContext) -> Reply:
    """Measure `spec` in frames taken after separate approaches of the arm (see
    :func:`frames_for`).  A position: the mean of the frames' deviations, its random part
    (rim fit, pose error) divided by the square root of their number, taken no smaller
    than the scatter the frames themselves show; its systematic part (edge model,
    neighbours' own errors) as it is.  Other kinds: the first frame.  More than half of
    the frames failing is the first failure's reply."""
    if not frames:
        return VisionException(spec.id, Reason.NOT_MEASURABLE, "no frame")
    if len(frames) == 1 or spec.kind is not K.HOLE_POSITION:
        return measure(frames[0], spec, ctx)
    replies = [measure(f, spec, ctx) for f in frames]
    ok = [r for r in replies if isinstance(r, VisionResult)]
    failed = [r for r in replies if isinstance(r, VisionException)]
    if len(ok) < max(2, len(frames) // 2 + 1):
        first = failed[0]
        return VisionException(spec.id, first.reason, f"{len(failed)} of {len(frames)} frames failed; "
                               f"first: {first.detail}")
    return _mean_position(spec, ok)


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
            "center": replies[0].diagnostics["center"], "rim_xy": replies[0].diagnostics.get("rim_xy")}
    return VisionResult(spec.id, spec.kind, 2 * float(np.hypot(*mean)), 2 * math.hypot(u_random, u_system), diag)
