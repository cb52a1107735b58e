"""The bulkhead's nominal features, laid out from its parameters.

`lay_out(params, rng)` places flange segments on the two contours, fastener holes along
their caps, stiffeners on a grid (cut where they cross the opening), pockets between them,
the two tooling holes (datums B and C) and lightening holes in the pockets.  The result
also keeps what the spec generator needs (contours, the arc length of each fastener hole).
"""

from __future__ import annotations

from dataclasses import dataclass

import manifold3d as m3d
import numpy as np

from ita.part import geometry2d as g2
from ita.part.model import FlangeSegment, Hole, HoleRole, Pocket, Stiffener
from ita.part.params import BulkheadParams, Flange

GRID_MM = 5.0  # candidate grid for hole and probe placement


@dataclass(frozen=True)
class Layout:
    """Nominal features plus the context the spec generator needs.

    contours: side ("outer"/"inner") -> contour; hole_s: fastener hole id -> arc length on
    its contour; candidates: pocket id -> (k, 2) floor points on the placement grid.
    """

    contours: dict[str, g2.RoundedRect]
    flanges: tuple[FlangeSegment, ...]
    stiffeners: tuple[Stiffener, ...]
    pockets: tuple[Pocket, ...]
    holes: tuple[Hole, ...]
    hole_s: dict[str, float]
    candidates: dict[str, np.ndarray]

    @property
    def features(self) -> tuple:
        """All features: flanges, stiffeners, pockets, holes."""
        return self.flanges + self.stiffeners + self.pockets + self.holes


def contours(params: BulkheadParams) -> dict[str, g2.RoundedRect]:
    """The outline ("outer") and opening ("inner") contours."""
    o, i = params.outline, params.opening
    return {
        "outer": g2.RoundedRect(o.width / 2, o.height / 2, o.corner_radius),
        "inner": g2.RoundedRect(i.width / 2, i.height / 2, i.corner_radius),
    }


def _flange(contour: g2.RoundedRect, f: Flange, side: str, prefix: str) -> list[FlangeSegment]:
    length, out = contour.length, []
    for j in range(f.segments):
        s0, s1 = j * length / f.segments, (j + 1) * length / f.segments
        pts, nrm, _ = contour.at(contour.sample_s(s0, s1))
        inward = -nrm if side == "outer" else nrm
        out.append(FlangeSegment(
            id=f"{prefix}{j + 1:02d}", side=side, s_range=(s0, s1),
            path=tuple(map(tuple, pts.tolist())), normals=tuple(map(tuple, inward.tolist())),
            height=f.height, wall_thickness=f.wall_thickness, cap_width=f.cap_width,
            cap_thickness=f.cap_thickness,
        ))
    return out


def _fasteners(contour: g2.RoundedRect, segs: list[FlangeSegment], f: Flange,
               prefix: str) -> tuple[list[Hole], dict[str, float]]:
    holes: list[Hole] = []
    hole_s: dict[str, float] = {}
    inset = (f.wall_thickness + f.cap_width) / 2
    for seg in segs:
        s0, s1 = seg.s_range
        n = max(1, round((s1 - s0) / f.fastener_pitch))
        s = s0 + (np.arange(n) + 0.5) * (s1 - s0) / n
        pts, nrm, _ = contour.at(s)
        c = pts + inset * (-nrm if seg.side == "outer" else nrm)
        for k in range(n):
            hid = f"{prefix}-{len(holes) + 1:03d}"
            holes.append(Hole(hid, HoleRole.FASTENER, (float(c[k, 0]), float(c[k, 1]), f.height),
                              (0.0, 0.0, 1.0), f.fastener_diameter, f.cap_thickness, seg.id))
            hole_s[hid] = float(s[k])
    return holes, hole_s


def _cs(poly: np.ndarray) -> m3d.CrossSection:
    return m3d.CrossSection([g2.ccw(poly)])


def _stiffeners(params: BulkheadParams, cont: dict[str, g2.RoundedRect]) -> list[Stiffener]:
    st = params.stiffeners
    clip = _cs(cont["outer"].polygon(-params.outer_flange.wall_thickness / 2)) - _cs(
        cont["inner"].polygon(params.inner_flange.wall_thickness / 2))
    big = max(params.outline.width, params.outline.height)
    ribs: list[Stiffener] = []
    for axis, coords, prefix in ((0, st.x, "RV"), (1, st.y, "RH")):
        for c in sorted(coords):
            a, b = np.array([c, -big]), np.array([c, big])
            if axis == 1:
                a, b = a[::-1], b[::-1]
            pieces = (_cs(g2.rect_polygon(a, b, st.width)) ^ clip).decompose()
            spans = sorted((p.bounds()[1 - axis], p.bounds()[3 - axis]) for p in pieces)
            for lo, hi in spans:
                s, e = [c, lo], [c, hi]
                if axis == 1:
                    s, e = s[::-1], e[::-1]
                ribs.append(Stiffener(f"{prefix}{len([r for r in ribs if r.id.startswith(prefix)]) + 1:02d}",
                                      (float(s[0]), float(s[1])), (float(e[0]), float(e[1])),
                                      st.width, st.height))
    return ribs


def _pockets(params: BulkheadParams, cont: dict[str, g2.RoundedRect]) -> list[Pocket]:
    st, o = params.stiffeners, params.outline
    floor = _cs(cont["outer"].polygon(-params.outer_flange.cap_width)) - _cs(
        cont["inner"].polygon(params.inner_flange.cap_width))
    h = st.width / 2
    xs = [-o.width] + [x + s * h for x in sorted(st.x) for s in (-1, 1)] + [o.width]
    ys = [-o.height] + [y + s * h for y in sorted(st.y) for s in (-1, 1)] + [o.height]
    found = []
    for x0, x1 in zip(xs[::2], xs[1::2]):
        for y0, y1 in zip(ys[::2], ys[1::2]):
            box = np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]])
            for piece in (_cs(box) ^ floor).decompose():
                if piece.area() < 1000.0:
                    continue
                poly = max(piece.to_polygons(), key=lambda p: abs(g2.signed_area(np.asarray(p))))
                poly = g2.ccw(np.asarray(poly, dtype=float))
                found.append((-round(poly[:, 1].mean()), round(poly[:, 0].mean()), poly))
    found.sort(key=lambda t: (t[0], t[1]))
    return [Pocket(f"P{i + 1:02d}", tuple(map(tuple, poly.tolist())), params.web.thickness)
            for i, (_, _, poly) in enumerate(found)]


def floor_candidates(pocket: Pocket) -> np.ndarray:
    """(k, 2) float: points of the placement grid inside the pocket's floor outline."""
    poly = pocket.outline_array
    lo, hi = np.floor(poly.min(axis=0) / GRID_MM), np.ceil(poly.max(axis=0) / GRID_MM)
    gx, gy = np.meshgrid(np.arange(lo[0], hi[0] + 1), np.arange(lo[1], hi[1] + 1))
    pts = np.column_stack([gx.ravel(), gy.ravel()]) * GRID_MM
    return pts[g2.points_in_polygon(pts, poly)]


def _web_holes(params: BulkheadParams, pockets: list[Pocket], cand: dict[str, np.ndarray],
               rng: np.random.Generator) -> list[Hole]:
    hp, t = params.holes, params.web.thickness
    cent = {p.id: p.outline_array.mean(axis=0) for p in pockets}
    b = min(pockets, key=lambda p: (round(cent[p.id][0]), round(abs(cent[p.id][1])), cent[p.id][1]))
    c = min(pockets, key=lambda p: (-round(cent[p.id][0]), round(abs(cent[p.id][1])), -cent[p.id][1]))
    holes: list[Hole] = []
    for pocket in pockets:
        pts = cand[pocket.id]
        if len(pts) == 0:
            continue
        clear = g2.distance_to_polygon(pts, pocket.outline_array)
        best = int(np.argmax(clear))
        x, y = float(pts[best, 0]), float(pts[best, 1])
        eligible = rng.random() < hp.lightening_fraction
        if pocket.id in (b.id, c.id):
            datum = "B" if pocket.id == b.id else "C"
            holes.append(Hole(f"TH-{datum}", HoleRole.TOOLING, (x, y, t), (0.0, 0.0, 1.0),
                              hp.tooling_diameter, t, pocket.id, datum))
            continue
        d = np.floor(min(hp.lightening_max_diameter, 2 * (clear[best] - hp.lightening_margin)) / 5) * 5
        if eligible and d >= hp.lightening_min_diameter:
            n = len([h for h in holes if h.role is HoleRole.LIGHTENING]) + 1
            holes.append(Hole(f"LH-{n:02d}", HoleRole.LIGHTENING, (x, y, t), (0.0, 0.0, 1.0),
                              float(d), t, pocket.id))
    return sorted(holes, key=lambda h: h.id)


def lay_out(params: BulkheadParams, rng: np.random.Generator) -> Layout:
    """All nominal features of the bulkhead described by `params`."""
    cont = contours(params)
    outer = _flange(cont["outer"], params.outer_flange, "outer", "OFL")
    inner = _flange(cont["inner"], params.inner_flange, "inner", "IFL")
    of_holes, of_s = _fasteners(cont["outer"], outer, params.outer_flange, "OF")
    if_holes, if_s = _fasteners(cont["inner"], inner, params.inner_flange, "IF")
    pockets = _pockets(params, cont)
    cand = {p.id: floor_candidates(p) for p in pockets}
    web_holes = _web_holes(params, pockets, cand, rng)
    return Layout(
        contours=cont, flanges=tuple(outer + inner), stiffeners=tuple(_stiffeners(params, cont)),
        pockets=tuple(pockets), holes=tuple(of_holes + if_holes + web_holes),
        hole_s={**of_s, **if_s}, candidates=cand,
    )
