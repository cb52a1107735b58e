"""Building blocks of Vision in one range frame: rectangular patches, plane fits on faces,
sub-pixel jump-edge points with their far-surface share, rim circles of holes and edge
lines (see :mod:`ita.vision.measure` for the method).  Failures raise
:class:`~ita.vision.context.VisionFail`, which the measurers turn into exception replies.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy import ndimage

from ita.part.model import FlangeSegment, Hole
from ita.vision import edges
from ita.vision.context import (
    BLUR_MM,
    EDGE_MODEL_PX,
    FAR_CHECK_MM,
    FAR_MIXED_SHARE,
    FAR_MIXED_U_MM,
    FAR_SPREAD_MM,
    MAX_EDGE_RMS_MM,
    MAX_OCCLUDED,
    MAX_PLANE_RMS_MM,
    MIN_EDGE_POINTS,
    MIN_PLANE_PIXELS,
    MIX_RANGE_MM,
    OCCLUDER_MM,
    SURFACE_BAND_MM,
    VisionContext,
    VisionFail,
    VisionFailure,
)
from ita.vision.fit import (
    CircleFit,
    LineFit,
    PlaneFit,
    fit_circle,
    fit_circle_fixed_radius,
    fit_line,
    fit_plane,
)
from ita.vision.patches import Patch, View, nominal_points, place_patch

FloatArray = NDArray[np.float64]


def frame_uv(direction: ArrayLike) -> tuple[FloatArray, FloatArray]:
    d = np.asarray(direction, dtype=float)[:2]
    u: FloatArray = d / np.linalg.norm(d)
    return u, np.array([-u[1], u[0]])


def rect_patch(view: View, name: str, c: FloatArray, u: FloatArray, v: FloatArray, u_range: tuple[float, float],
                v_range: tuple[float, float], z: float) -> tuple[Patch, NDArray[np.bool_]]:
    """Patch over the rectangle c + s u + t v (s, t in the ranges) at height z, and its
    region mask; raises OUT_OF_VIEW."""
    corners = np.array([np.append(c + s * u + t * v, z) for s in u_range for t in v_range])
    patch = place_patch(view, name, corners)
    if patch is None:
        raise VisionFail(VisionFailure.OUT_OF_VIEW, f"patch {name!r} is outside the frame")
    q = nominal_points(view, patch, z)[..., :2] - c
    s, t = q @ u, q @ v
    region = (s >= u_range[0]) & (s <= u_range[1]) & (t >= v_range[0]) & (t <= v_range[1])
    return patch, region


def fit_face(view: View, patch: Patch, region: NDArray[np.bool_], z: float) -> tuple[PlaneFit, NDArray[np.bool_]]:
    """Plane fit to the pixels of `region` on the face at nominal height z; raises OCCLUDED,
    TOO_FEW_PIXELS, FIT_RESIDUAL.  Returns the fit and the pixels used."""
    p = patch.take(view.points)
    valid = np.isfinite(p[..., 2]) & region
    n_region = int(region.sum())
    with np.errstate(invalid="ignore"):
        front = valid & (p[..., 2] > z + OCCLUDER_MM)
        near = valid & (np.abs(p[..., 2] - z) < SURFACE_BAND_MM)
    if n_region and front.sum() > MAX_OCCLUDED * n_region:
        raise VisionFail(VisionFailure.OCCLUDED, f"{int(front.sum())} of {n_region} pixels of {patch.name!r} are "
                    f"more than {OCCLUDER_MM} mm in front of the face")
    if near.sum() < MIN_PLANE_PIXELS:
        raise VisionFail(VisionFailure.TOO_FEW_PIXELS, f"{int(near.sum())} valid pixels on {patch.name!r} "
                    f"(of {n_region}; need {MIN_PLANE_PIXELS})")
    fit = fit_plane(p[near])
    if fit is None:
        raise VisionFail(VisionFailure.TOO_FEW_PIXELS, f"no plane on {patch.name!r}")
    if fit.rms > MAX_PLANE_RMS_MM:
        raise VisionFail(VisionFailure.FIT_RESIDUAL, f"plane on {patch.name!r}: rms {fit.rms:.3f} mm > {MAX_PLANE_RMS_MM}")
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


def fit_rim(view: View, hole: Hole, name: str, min_coverage: float = math.pi,
            radius: float | None = None) -> tuple[CircleFit, PlaneFit, dict]:
    """The hole's rim circle on its entry face (see :func:`_fit_rim`), fitted once per view
    (a hole's diameter, position and edge distance are measured in the same frames): the
    same fit, or the same failure, each time it is asked for; the diagnostics a copy."""
    key = ("rim", hole, name, min_coverage, radius)
    if key not in view.found:
        try:
            view.found[key] = _fit_rim(view, hole, name, min_coverage, radius)
        except VisionFail as exc:
            view.found[key] = exc
    got = view.found[key]
    if isinstance(got, VisionFail):
        raise VisionFail(got.reason, got.detail)
    fit, face, diag = got
    return fit, face, dict(diag)


def _fit_rim(view: View, hole: Hole, name: str, min_coverage: float = math.pi,
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
    patch, q, rho = _rim_patch(view, hole, name, c, z, outer)
    found = _located(view, patch, q + c, rho, r, b, outer, z)
    if found is not None and float(np.hypot(*(found - c))) > RELOCATE_BAND * b:
        # the hole is not where the pose says (an arm off its calibration, a part off its
        # place): the rim band is centred where the frame shows the hole
        c = found
        patch, q, rho = _rim_patch(view, hole, name, c, z, outer)
    in_view_share = _circle_in_view(view, c, r, z)
    if in_view_share < 0.5:
        raise VisionFail(VisionFailure.OUT_OF_VIEW, f"only {in_view_share:.0%} of {hole.id}'s rim is in the frame")
    annulus = (rho > r + b) & (rho < outer)
    near, near_px = fit_face(view, patch, annulus, z)
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
        raise VisionFail(VisionFailure.TOO_FEW_PIXELS, f"{len(xy)} rim points of {hole.id} (need {MIN_EDGE_POINTS})")
    fit = fit_circle(xy) if radius is None else fit_circle_fixed_radius(xy, radius)
    if fit is None or fit.coverage < min_coverage:
        raise VisionFail(VisionFailure.TOO_FEW_PIXELS, f"rim points of {hole.id} cover {math.degrees(fit.coverage) if fit else 0:.0f}"
                    f" deg of the circle (need {math.degrees(min_coverage):.0f})")
    px = view.pixel_mm(float(np.median(view.plane_range(near.coef, patch.take(view.dirs)))))
    if fit.rms > MAX_EDGE_RMS_MM + 0.5 * px:
        raise VisionFail(VisionFailure.FIT_RESIDUAL, f"rim of {hole.id}: rms {fit.rms:.3f} mm")
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


#: the rim band is moved to where the frame shows the hole when that is further than this
#: share of the band's half-width from where the pose says it is
RELOCATE_BAND = 0.5


def _rim_patch(view: View, hole: Hole, name: str, c: FloatArray, z: float, outer: float
               ) -> tuple[Patch, FloatArray, FloatArray]:
    """The patch round a rim centred at c (part xy, mm) out to `outer`, its pixels' xy on
    the plane z from c (h, w, 2) and their distance from c."""
    corners = np.array([[c[0] + sx * outer, c[1] + sy * outer, z] for sx in (-1, 1) for sy in (-1, 1)])
    h, w = view.shape
    rc = view.pixel_of(corners)
    centre_rc = view.pixel_of(np.append(c, z)[None])
    if not view.geometry.contains(centre_rc).all():
        raise VisionFail(VisionFailure.OUT_OF_VIEW, f"centre of {hole.id} is outside the frame")
    rc = np.clip(rc, 0, [h - 1, w - 1])
    patch = Patch(name, int(rc[:, 0].min()), int(np.ceil(rc[:, 0].max())) + 1, int(rc[:, 1].min()),
                  int(np.ceil(rc[:, 1].max())) + 1, np.ones((1, 1), bool))
    q = nominal_points(view, patch, z)[..., :2] - c
    return patch, q, np.hypot(q[..., 0], q[..., 1])


def _located(view: View, patch: Patch, xy: FloatArray, rho: FloatArray, r: float, b: float, outer: float,
             z: float) -> FloatArray | None:
    """Where the frame shows the hole (part xy, mm): the centroid of the pixels within
    `outer` of the nominal centre that lie deeper than the face round it (or return
    nothing), the connected region nearest that centre; None when it is not one whole hole
    of about its size inside the patch (then the nominal centre stands)."""
    z_img = patch.take(view.points)[..., 2]
    ring = (rho > r + b) & (rho < outer) & np.isfinite(z_img)
    if ring.sum() < MIN_PLANE_PIXELS:
        return None
    face = float(np.median(z_img[ring]))
    inside = rho < outer
    deep = inside & (~np.isfinite(z_img) | (z_img < face - LOCATE_DEPTH_MM))
    labels, n = ndimage.label(deep)
    if n == 0:
        return None
    near = np.argmin(np.where(deep, rho, np.inf))
    region = labels == int(labels.flat[near])
    ring_all = (rho > r + b) & (rho < outer)
    per_pixel = np.pi * (outer ** 2 - (r + b) ** 2) / max(int(ring_all.sum()), 1)     # mm^2 of the plane
    expected = np.pi * r * r / per_pixel
    if not 0.6 * expected <= region.sum() <= 1.4 * expected or not _inside_patch(region):
        return None
    return np.asarray(xy[region].mean(axis=0), dtype=np.float64)


#: a pixel deeper than the face round a hole by more than this (mm) sees through the hole
LOCATE_DEPTH_MM = 1.0


def _inside_patch(region: NDArray[np.bool_]) -> bool:
    """Whether a region of a patch stays off its border (a hole cut by the frame's edge
    has no honest centroid)."""
    return not (region[0].any() or region[-1].any() or region[:, 0].any() or region[:, -1].any())


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


def edge_sigma(px: float, n: int) -> float:
    """A floor for a fitted edge's position: the sub-pixel model's residual bias."""
    return EDGE_MODEL_PX * px


def fit_edge(view: View, near: PlaneFit, near_px, patch: Patch, region_band, far_region, name: str,
          nominal: FloatArray | None = None) -> tuple[LineFit, dict]:
    """Line through the edge points; nominal: the edge's nominal polyline (k, 2) when it is
    curved: the points are straightened against it first (a line through an arc of
    radius R over +/-L sits about L^2 / 3R off the arc's apex)."""
    s, mode = _share(view, patch, near, near_px, far_region)
    xy = _edge_xy(view, patch, s, region_band, near)
    if nominal is not None and len(xy):
        xy = _straighten(xy, nominal)
    if len(xy) < MIN_EDGE_POINTS:
        raise VisionFail(VisionFailure.TOO_FEW_PIXELS, f"{len(xy)} points on edge {name!r} (need {MIN_EDGE_POINTS})")
    fit = fit_line(xy)
    px = view.pixel_mm(float(np.median(view.plane_range(near.coef, patch.take(view.dirs)))))
    if fit is None or fit.rms > MAX_EDGE_RMS_MM + 0.5 * px:
        raise VisionFail(VisionFailure.FIT_RESIDUAL, f"edge {name!r}: rms {fit.rms if fit else float('nan'):.3f} mm")
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


def _arc_length_of_nearest(path: FloatArray, s: FloatArray, point: FloatArray) -> float:
    """Arc length along the polyline `path` (k, 2) (cumulative lengths `s`) of its point
    nearest `point`: on a segment, not only at a vertex (a sparse path's nearest vertex
    can be far along the edge from the point)."""
    a, b = path[:-1], path[1:]
    d = b - a
    length2 = np.einsum("ij,ij->i", d, d)
    t = np.clip(np.einsum("ij,ij->i", point - a, d) / np.where(length2 > 0, length2, 1.0), 0.0, 1.0)
    gap = np.linalg.norm(a + t[:, None] * d - point, axis=1)
    k = int(np.argmin(gap))
    return float(s[k] + t[k] * np.sqrt(length2[k]))


def free_edge(ctx: VisionContext, hole: Hole, distance: float, u: FloatArray) -> FloatArray | None:
    """Nominal free edge of the hole's flange cap near it, (k, 2), +/-12 mm, centred on the
    point `distance` along u from the hole; None when the parent is not a flange."""
    seg = ctx.features.get(hole.parent)
    if not isinstance(seg, FlangeSegment):
        return None
    edge = seg.path_array + seg.normals_array * seg.cap_width
    foot = np.asarray(hole.center[:2]) + distance * u
    step = np.linalg.norm(np.diff(edge, axis=0), axis=1)
    s = np.concatenate([[0.0], np.cumsum(step)])
    grid = _arc_length_of_nearest(edge, s, foot) + np.linspace(-12.0, 12.0, 25)
    pts = np.column_stack([np.interp(grid, s, edge[:, 0]), np.interp(grid, s, edge[:, 1])])
    t = pts[-1] - pts[0]
    t = t / np.linalg.norm(t)
    shift = foot - pts[12]
    return pts + (shift @ np.array([-t[1], t[0]])) * np.array([-t[1], t[0]]) + (shift @ t) * t
