"""The values a mesh itself has, found with exact rays from each spec's point.

    values = mesh_values(mesh, specs, {f.id: f for f in features})   # spec id -> mm

What a master's certificate says (the nominal mesh of a user's part, measured the way a
run measures it: ita.offline.master) and what a part simulated from a mesh is scored
against (its asbuilt.stl or nominal mesh: ita.scoring.truth).  It reads no stored truth:
it looks at the mesh it is given.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
import trimesh

from ita.part.infer import INSIDE_MM, MeshRays, ring
from ita.part.model import Feature, Hole
from ita.specs.model import MeasurementKind as K
from ita.specs.model import MeasurementSpec

__all__ = ["mesh_values"]


def mesh_values(mesh: trimesh.Trimesh, specs: Sequence[MeasurementSpec], features: dict[str, Feature]) -> dict[str, float]:
    """Spec id -> the value the mesh itself has (mm), found with exact rays from the spec's
    point: the truth of a part simulated from a mesh (its asbuilt.stl, or its nominal mesh).
    A hole's diameter and position come from the circle through its bore (the mesh's
    polygon, as the simulator's beam sees it), an edge distance from that circle's centre
    to the face's edge along the spec's direction, a height from the top face under the
    point, a width across it, a thickness through it.  Specs whose geometry the rays do not
    find are left out (scored as having no truth)."""
    rays = MeshRays(mesh)
    out: dict[str, float] = {}
    circles: dict[str, tuple[np.ndarray, float, np.ndarray]] = {}

    def circle(h: Hole) -> tuple[np.ndarray, float, np.ndarray] | None:
        if h.id not in circles:
            n = np.asarray(h.axis, dtype=float)
            c = np.asarray(h.center, dtype=float) - min(INSIDE_MM, h.depth / 2) * n
            radial = ring(n, 720)
            d = rays.first(c, radial)
            if not np.all(np.isfinite(d)):
                return None
            u, v = radial[0], np.cross(n, radial[0])
            pts = (radial * d[:, None]) @ np.column_stack([u, v])       # in the entry plane, about c
            a = np.column_stack([2 * pts, np.ones(len(pts))])
            sol = np.linalg.lstsq(a, (pts ** 2).sum(1), rcond=None)[0]
            centre2, radius = sol[:2], float(np.sqrt(sol[2] + sol[:2] @ sol[:2]))
            circles[h.id] = (np.asarray(h.center) + centre2[0] * u + centre2[1] * v, radius, n)
        return circles[h.id]

    for s in specs:
        p, n = np.asarray(s.point, dtype=float), np.asarray(s.normal, dtype=float)
        f = features.get(s.feature)
        value: float | None = None
        if s.kind in (K.WEB_THICKNESS, K.FLANGE_THICKNESS):
            d = float(rays.first((p + 2 * n)[None], (-n)[None])[0])
            if math.isfinite(d):
                back = float(rays.first((p + (2 - d - 0.01) * n)[None], (-n)[None])[0])
                value = back + 0.01 if math.isfinite(back) else None
        elif s.kind in (K.HOLE_DIAMETER, K.HOLE_POSITION, K.EDGE_DISTANCE) and isinstance(f, Hole):
            got = circle(f)
            if got is not None:
                centre, radius, axis = got
                if s.kind is K.HOLE_DIAMETER:
                    value = 2 * radius
                elif s.kind is K.HOLE_POSITION:
                    off = centre - np.asarray(f.center)
                    value = 2 * float(np.linalg.norm(off - np.dot(off, axis) * axis))
                elif s.direction is not None:
                    u = np.asarray(s.direction, dtype=float)
                    u = u - np.dot(u, axis) * axis
                    u /= np.linalg.norm(u)
                    start = centre - INSIDE_MM * axis + (radius + 0.3) * u
                    hit = float(rays.first(start[None], u[None])[0])
                    value = radius + 0.3 + hit if math.isfinite(hit) else None
        elif s.kind in (K.STIFFENER_HEIGHT, K.FLANGE_HEIGHT):
            d = float(rays.first((p + 5 * n)[None], (-n)[None])[0])
            value = float((p + (5 - d) * n)[2]) if math.isfinite(d) else None
        elif s.kind in (K.STIFFENER_WIDTH, K.FLANGE_WIDTH) and s.direction is not None:
            u = np.asarray(s.direction, dtype=float)
            start = p - INSIDE_MM * n
            sides = rays.first(np.vstack([start, start]), np.vstack([u, -u]))
            value = float(sides.sum()) if np.all(np.isfinite(sides)) else None
        if value is not None:
            out[s.id] = round(float(value), 6)
    return out
