"""Registration of a fastener hole's frame on its neighbouring holes in the same image:
which neighbours serve (fixed by the nominal part and the commanded pose), their rims
fitted at the hole's radius, the frame's shift as the mean offset of their measured from
their nominal centres, with the neighbours' own position scatter as an uncertainty term.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ita.part.model import Hole, Stiffener
from ita.vision.context import (
    BLUR_MM,
    DATUM_MIN_COVERAGE,
    DIAMETER_TOLERANCE,
    EDGE_CORRELATION,
    MAX_DATUM_HOLES,
    VisionContext,
    VisionFail,
    fastener_neighbours,
)
from ita.vision.patches import View
from ita.vision.rims import edge_sigma, fit_rim

FloatArray = NDArray[np.float64]


def _datum_neighbours(view: View, hole: Hole, ctx: VisionContext) -> list[Hole]:
    """The fastener holes beside `hole` (same face) that serve as its datum in this frame:
    those whose whole rim patch (rim, blur band, face annulus) lies inside the frame, with
    a margin of 3 sigma of the arm's pose error and a pixel, as seen from the REPORTED
    pose; of these, those with no rib beneath them in view (:func:`rib_beneath`) when
    there is one such.  The set depends on the nominal part and the commanded pose only,
    never on what the frame shows, so repeated frames register on the same holes."""
    px = view.pixel_mm(ctx.standoff_m * 1000)
    margin = 3 * ctx.pose_sigma_m / ctx.placement.scale + px
    out = []
    for nb in fastener_neighbours(hole, ctx, math.inf)[:MAX_DATUM_HOLES * 4]:
        reach = nb.diameter / 2 + BLUR_MM + px + max(3.0, 6 * px) + margin
        corners = np.array([[nb.center[0] + sx * reach, nb.center[1] + sy * reach, nb.center[2]]
                            for sx in (-1, 1) for sy in (-1, 1)])
        if view.geometry.contains(view.pixel_of(corners)).all():
            out.append(nb)
    clean = [nb for nb in out if not rib_beneath(view, nb, ctx)]
    return (clean or out)[:MAX_DATUM_HOLES]


def rib_beneath(view: View, hole: Hole, ctx: VisionContext) -> bool:
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


@dataclass(frozen=True)
class NeighbourRim:
    """A datum neighbour's rim fitted in a frame: its centre (x, y mm, part frame, as the
    frame's reported pose places it) and the standard uncertainty per axis of that centre:
    what is new in each frame (`u_random`: the rim fit, the edge points, the radius it
    was fitted with) and what the edge model adds (`u_model`)."""

    hole: str
    centre: tuple[float, float]
    u_random: float
    u_model: float

    @property
    def u(self) -> float:
        return math.hypot(self.u_random, self.u_model)


def neighbour_rims(view: View, hole: Hole, radius: float | None, ctx: VisionContext
                   ) -> tuple[list[NeighbourRim], list[str]]:
    """The datum neighbours' rims fitted in this frame, and the ids of those that cannot
    be (see :func:`register_on_neighbours`)."""
    rims, left = [], []
    for nb in _datum_neighbours(view, hole, ctx):
        try:
            f2, _, d2 = fit_rim(view, nb, f"rim {nb.id}", DATUM_MIN_COVERAGE,
                                None if radius is None else radius + (nb.diameter - hole.diameter) / 2)
        except VisionFail:
            left.append(nb.id)
            continue
        t_r = math.hypot(ctx.diameter_tolerances.get(nb.id, DIAMETER_TOLERANCE),
                         ctx.diameter_tolerances.get(hole.id, DIAMETER_TOLERANCE)) / 2 / math.sqrt(3)
        u_random = math.hypot(EDGE_CORRELATION * max(f2.center_sigma), edge_sigma(d2["pixel_mm"], f2.n),
                              0.0 if radius is None else 1.3 * t_r)
        rims.append(NeighbourRim(nb.id, (float(f2.center[0]), float(f2.center[1])), u_random,
                                 float(d2["u_model_centre"])))
    return rims, left


def register_on_neighbours(view: View, hole: Hole, radius: float | None, ctx: VisionContext
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
    return register_on_rims(*neighbour_rims(view, hole, radius, ctx), ctx)


def register_on_rims(rims: list[NeighbourRim], left: list[str], ctx: VisionContext
                     ) -> tuple[FloatArray, float, list[str], list[str]]:
    """:func:`register_on_neighbours` from the neighbours' rims already fitted."""
    left = list(left)
    nominal = {h.id: h for h in ctx.features.values() if isinstance(h, Hole)}
    offsets = [np.asarray(nominal[r.hole].center[:2]) - np.asarray(r.centre) for r in rims]
    u_nb = [r.u for r in rims]
    used = [r.hole for r in rims]
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
