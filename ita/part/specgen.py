"""Measurement specifications derived from the bulkhead's nominal features.

Where each kind is measured (all from the +Z side):
- web_thickness: pocket floor points (ultrasonic, normal +Z), spread by floor area;
- flange_thickness: cap top over the overhang (cap thickness, normal +Z) and the wall's
  free face on straight runs (wall thickness, normal sideways, away from the flange);
- flange_height / flange_width: cap top between two fastener holes; width across the cap;
- hole_diameter / hole_position: centre on the entry face, normal = hole axis;
- edge_distance: fastener hole centre to the cap's free edge; point on the cap top
  between rim and edge, direction from the hole toward the edge;
- stiffener_height / stiffener_width: rib top at stations between crossings.
Heights are from datum A (z = 0).  Ids read `<KIND>-<feature>[-<n>]`, e.g. WT-P03-2.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from ita.part import geometry2d as g2
from ita.part.layout import Layout
from ita.part.model import HoleRole, Stiffener
from ita.part.params import BulkheadParams
from ita.specs.model import MeasurementKind as K
from ita.specs.model import MeasurementSpec

UP = (0.0, 0.0, 1.0)


def _v3(x: float, y: float, z: float) -> tuple[float, float, float]:
    return (round(float(x), 4), round(float(y), 4), round(float(z), 4))


def _v3_at(xy: NDArray[np.float64], z: float) -> tuple[float, float, float]:
    """`_v3` of the point (x, y) of a plane point at height z."""
    x, y = xy
    return _v3(x, y, z)


def _dir(x: float, y: float) -> tuple[float, float, float]:
    """An in-plane unit vector (not rounded, so that it stays unit)."""
    n = float(np.hypot(x, y))
    return (float(x) / n, float(y) / n, 0.0)


def _spec(sid: str, kind: K, feature: str, point, normal, nominal: float, tol: float,
          datum: str = "A", direction=None, note: str = "") -> MeasurementSpec:
    return MeasurementSpec(sid, kind, feature, point, normal, round(nominal, 4), -tol, tol,
                           datum, direction, note)


def _farthest_points(pts: np.ndarray, n: int, rng: np.random.Generator) -> np.ndarray:
    """(n, 2) float: n of the (k, 2) points spread by farthest-point sampling from a
    random start."""
    chosen = [int(rng.integers(len(pts)))]
    dist = np.linalg.norm(pts - pts[chosen[0]], axis=1)
    for _ in range(min(n, len(pts)) - 1):
        chosen.append(int(np.argmax(dist)))
        dist = np.minimum(dist, np.linalg.norm(pts - pts[chosen[-1]], axis=1))
    return pts[chosen]


def _web_specs(lay: Layout, p: BulkheadParams, rng: np.random.Generator) -> list[MeasurementSpec]:
    margin, tol = p.specs.web_point_margin, p.tolerance.thickness
    usable: dict[str, np.ndarray] = {}
    for pocket in lay.pockets:
        pts = lay.candidates[pocket.id]
        ok = g2.distance_to_polygon(pts, pocket.outline_array) >= margin
        for h in lay.holes:
            if h.parent == pocket.id:
                ok &= np.linalg.norm(pts - h.center[:2], axis=1) >= h.diameter / 2 + margin
        usable[pocket.id] = pts[ok]
    area = np.array([abs(g2.signed_area(q.outline_array)) for q in lay.pockets])
    share = p.specs.web_thickness_points * area / area.sum()
    count = np.maximum(np.floor(share).astype(int), 2)
    for i in np.argsort(-(share - np.floor(share)))[: max(0, p.specs.web_thickness_points - count.sum())]:
        count[i] += 1
    specs = []
    for pocket, n in zip(lay.pockets, count):
        if len(usable[pocket.id]) == 0:
            continue
        pts = _farthest_points(usable[pocket.id], int(n), rng)
        for k, (x, y) in enumerate(sorted(map(tuple, pts), key=lambda q: (-q[1], q[0]))):
            specs.append(_spec(f"WT-{pocket.id}-{k + 1}", K.WEB_THICKNESS, pocket.id,
                               _v3(x, y, pocket.web_thickness), UP, pocket.web_thickness, tol,
                               note="pocket floor, ultrasonic"))
    return specs


def _near_rib(pts: np.ndarray, ribs: tuple[Stiffener, ...], clearance: float) -> np.ndarray:
    """(n,) bool: points of (n, 2) within `clearance` of a rib's side faces."""
    near = np.zeros(len(pts), dtype=bool)
    for r in ribs:
        seg = np.array([r.start, r.end])
        near |= g2.distance_to_polygon(pts, seg) < r.width / 2 + clearance
    return near


def _flange_specs(lay: Layout, p: BulkheadParams) -> list[MeasurementSpec]:
    tol, specs = p.tolerance, []
    for seg in lay.flanges:
        contour = lay.contours[seg.side]
        n_holes = len([h for h in lay.holes if h.parent == seg.id])
        s0, s1 = seg.s_range
        mids = s0 + np.arange(1, n_holes) * (s1 - s0) / max(n_holes, 1)
        if len(mids) < 2:
            continue
        pts, nrm, straight = contour.at(mids)
        inward = -nrm if seg.side == "outer" else nrm
        cap = pts + inward * (seg.wall_thickness + seg.cap_width) / 2
        fh = sorted({1, len(mids) - 2})
        ft = sorted({0, len(mids) - 1} | ({len(mids) // 2} - set(fh)))
        for k, i in enumerate(fh):
            at, d = _v3_at(cap[i], seg.height), _dir(*inward[i])
            specs.append(_spec(f"FH-{seg.id}-{k + 1}", K.FLANGE_HEIGHT, seg.id, at, UP,
                               seg.height, tol.height, note="cap top above datum A"))
            specs.append(_spec(f"FW-{seg.id}-{k + 1}", K.FLANGE_WIDTH, seg.id, at, UP,
                               seg.cap_width, tol.general, direction=d,
                               note="cap width from the wall's free face"))
        under = _near_rib(cap, lay.stiffeners, 8.0)
        for k, i in enumerate(j for j in ft if not under[j]):
            specs.append(_spec(f"FT-{seg.id}-C{k + 1}", K.FLANGE_THICKNESS, seg.id,
                               _v3_at(cap[i], seg.height), UP, seg.cap_thickness, tol.thickness,
                               note="cap thickness, ultrasonic from the cap top"))
        i = len(mids) // 2
        if straight[i] and not _near_rib(pts[i:i + 1] + inward[i:i + 1], lay.stiffeners, 15.0)[0]:
            z = (p.web.thickness + seg.height - seg.cap_thickness) / 2
            specs.append(_spec(f"FT-{seg.id}-W1", K.FLANGE_THICKNESS, seg.id, _v3_at(pts[i], z),
                               _dir(*-inward[i]), seg.wall_thickness, tol.thickness,
                               note="wall thickness, ultrasonic from the free face"))
    return specs


def _hole_specs(lay: Layout, p: BulkheadParams) -> list[MeasurementSpec]:
    tol, specs = p.tolerance, []
    flange = {f.id: f for f in lay.flanges}
    for h in lay.holes:
        dia_tol, tp = {
            HoleRole.FASTENER: (tol.fastener_diameter, tol.true_position),
            HoleRole.LIGHTENING: (tol.lightening_diameter, tol.lightening_true_position),
            HoleRole.TOOLING: (tol.tooling_diameter, 0.0),
        }[h.role]
        c = _v3(*h.center)
        specs.append(_spec(f"HD-{h.id}", K.HOLE_DIAMETER, h.id, c, h.axis, h.diameter, dia_tol,
                           note=f"{h.role.value} hole"))
        if tp > 0:
            specs.append(MeasurementSpec(f"HP-{h.id}", K.HOLE_POSITION, h.id, c, h.axis, 0.0, 0.0,
                                         tp, "A|B|C", None, "true position, diameter zone"))
        if h.role is HoleRole.FASTENER:
            seg = flange[h.parent]
            _, nrm, _ = lay.contours[seg.side].at(np.array([lay.hole_s[h.id]]))
            inward = (-nrm if seg.side == "outer" else nrm)[0]
            edge = seg.cap_width - (seg.wall_thickness + seg.cap_width) / 2
            r = h.diameter / 2
            at = np.asarray(h.center[:2]) + inward * (r + (edge - r) / 2)
            specs.append(_spec(f"ED-{h.id}", K.EDGE_DISTANCE, h.id, _v3_at(at, h.center[2]), UP,
                               edge, tol.general, direction=_dir(*inward),
                               note="hole centre to the cap's free edge"))
    return specs


def _stiffener_specs(lay: Layout, p: BulkheadParams) -> list[MeasurementSpec]:
    outer, inner = lay.contours["outer"], lay.contours["inner"]
    keep_out = (p.outer_flange.cap_width + 10.0, p.inner_flange.cap_width + 10.0)
    specs = []
    for r in lay.stiffeners:
        u, length = r.direction, float(np.linalg.norm(np.subtract(r.end, r.start)))
        t = np.arange(0.0, length, 1.0)
        pts = np.asarray(r.start) + t[:, None] * u
        ok = (outer.sdf(pts) < -keep_out[0]) & (inner.sdf(pts) > keep_out[1])
        others = tuple(o for o in lay.stiffeners if abs(float(np.dot(o.direction, u))) < 0.5)
        ok &= ~_near_rib(pts, others, 10.0)
        # split the visible samples into runs between crossings
        runs = np.split(t[ok], np.flatnonzero(np.diff(t[ok]) > 1.5) + 1) if ok.any() else []
        stations = []
        for run in runs:
            if len(run) < 20:
                continue
            a, b = run[0], run[-1]
            fr = (1 / 3, 2 / 3) if b - a > p.specs.stiffener_long_span else (0.5,)
            stations += [a + f * (b - a) for f in fr]
        across = _dir(-u[1], u[0])
        for k, s in enumerate(stations):
            at = _v3_at(np.asarray(r.start) + s * u, r.height)
            specs.append(_spec(f"SH-{r.id}-{k + 1}", K.STIFFENER_HEIGHT, r.id, at, UP, r.height,
                               p.tolerance.height, note="rib top above datum A"))
            specs.append(_spec(f"SW-{r.id}-{k + 1}", K.STIFFENER_WIDTH, r.id, at, UP, r.width,
                               p.tolerance.thickness, direction=across, note="rib thickness"))
    return specs


def make_specs(lay: Layout, params: BulkheadParams, rng: np.random.Generator) -> list[MeasurementSpec]:
    """All measurement specs of the bulkhead, in a stable order."""
    return (_web_specs(lay, params, rng) + _flange_specs(lay, params) + _hole_specs(lay, params)
            + _stiffener_specs(lay, params))
