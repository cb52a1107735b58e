"""The part's solid, built from its features with manifold3d (watertight by construction).

`build_mesh(features)` depends on the features only, so the same function builds the
nominal part and, from the as-built features, the as-built part.  Web: the region inside
the outer flange path minus the opening and the web holes, as thick as the thinnest
pocket, with each thicker pocket's floor added as a slab that ends under its ribs and
caps.  Flange walls and caps and the ribs are footprints extruded over their heights;
fastener holes are cut through the caps only.
"""

from __future__ import annotations

from typing import Iterable, Sequence

import manifold3d as m3d
import numpy as np
import trimesh

from ita.part import geometry2d as g2
from ita.part.model import Feature, FlangeSegment, Hole, HoleRole, Pocket, Stiffener

MAX_SAG_MM = 0.02  # chord sag of hole polygons
RIB_IN_WALL = 0.5  # ribs end this fraction of the wall thickness inside the walls
OVERLAP_MM = 0.5  # how far differing flange segments reach into their neighbours


def _cs(polys: Iterable[np.ndarray]) -> m3d.CrossSection:
    return m3d.CrossSection([g2.ccw(np.asarray(p, dtype=float)) for p in polys])


def _loop(segments: Sequence[FlangeSegment], fraction: float) -> np.ndarray:
    """(n, 2) float: closed contour of a flange's segments (in s order), moved into the
    flange's wall by `fraction` of the wall thickness."""
    parts = []
    for seg in sorted(segments, key=lambda s: s.s_range[0]):
        d = seg.wall_thickness * fraction
        parts.append((seg.path_array + d * seg.normals_array)[:-1])
    return np.vstack(parts)


def _prism(cs: m3d.CrossSection, z0: float, z1: float) -> m3d.Manifold:
    return m3d.Manifold.extrude(cs, z1 - z0).translate((0.0, 0.0, z0))


def _hole_polygon(hole: Hole) -> np.ndarray:
    r = hole.diameter / 2
    return g2.circle_polygon(np.asarray(hole.center[:2]), r, g2.circle_segments(r, MAX_SAG_MM))


def _grouped(items: Iterable[tuple[tuple[float, float], np.ndarray]]) -> list[m3d.Manifold]:
    """Prisms of the 2-D unions of polygons sharing the same (z0, z1)."""
    groups: dict[tuple[float, float], list[np.ndarray]] = {}
    for key, poly in items:
        groups.setdefault((round(key[0], 9), round(key[1], 9)), []).append(poly)
    return [_prism(_cs(polys), z0, z1) for (z0, z1), polys in sorted(groups.items())]


def _extended(path: np.ndarray, normals: np.ndarray, length: float) -> tuple[np.ndarray, np.ndarray]:
    """(n + 2, 2) path and normals lengthened at both ends along their end tangents."""
    t0 = (path[0] - path[1]) / np.linalg.norm(path[0] - path[1])
    t1 = (path[-1] - path[-2]) / np.linalg.norm(path[-1] - path[-2])
    return (np.vstack([path[0] + length * t0, path, path[-1] + length * t1]),
            np.vstack([normals[0], normals, normals[-1]]))


def _flange_solids(segments: Sequence[FlangeSegment]) -> list[m3d.Manifold]:
    """Walls and caps of one flange, unioned in 2-D per distinct z range.  Segments that
    differ (as built) reach OVERLAP_MM into their neighbours, so that no two pieces end
    on one shared plane."""
    same = len({(s.height, s.wall_thickness, s.cap_width, s.cap_thickness) for s in segments}) == 1
    items = []
    for s in segments:
        path, nrm = s.path_array, s.normals_array
        if not same:
            path, nrm = _extended(path, nrm, OVERLAP_MM)
        items.append(((0.0, s.height), g2.strip_polygon(path, nrm, 0.0, s.wall_thickness)))
        items.append(((s.height - s.cap_thickness, s.height),
                      g2.strip_polygon(path, nrm, 0.0, s.cap_width)))
    return _grouped(items)


def build_solid(features: Sequence[Feature]) -> m3d.Manifold:
    """The part as a manifold3d solid (mm, part frame).

    Pieces never share a face exactly where that can be avoided (exact coincidences leave
    zero-length edges in a union): slabs and ribs are rooted half-way into the web, slabs
    of neighbouring pockets stop short of each other inside their rib, holes are cut last.
    """
    flanges = [f for f in features if isinstance(f, FlangeSegment)]
    outer = [f for f in flanges if f.side == "outer"]
    inner = [f for f in flanges if f.side == "inner"]
    pockets = [f for f in features if isinstance(f, Pocket)]
    ribs = [f for f in features if isinstance(f, Stiffener)]
    holes = [f for f in features if isinstance(f, Hole)]
    if not outer or not pockets:
        raise ValueError("a bulkhead needs an outer flange and at least one pocket")
    web = _cs([_loop(outer, 0.0)])
    if inner:
        web = web - _cs([_loop(inner, 0.0)])
    base = min(p.web_thickness for p in pockets)
    solids = [_prism(web, 0.0, base)]
    rib_quarter = min((r.width for r in ribs), default=0.0) / 4
    slabs = [((base / 2, p.web_thickness), p) for p in pockets if p.web_thickness > base + 1e-9]
    for (z0, z1), p in slabs:
        solids.append(_prism(_cs([p.outline_array]).offset(rib_quarter, m3d.JoinType.Miter) ^ web, z0, z1))
    solids += _flange_solids(outer) + (_flange_solids(inner) if inner else [])
    if ribs:
        clip = _cs([_loop(outer, RIB_IN_WALL)])
        if inner:
            clip = clip - _cs([_loop(inner, RIB_IN_WALL)])
        rects = ((((base / 2, r.height)), g2.rect_polygon(r.start, r.end, r.width, extend=20.0)) for r in ribs)
        solids += [m3d.Manifold.batch_boolean([m, _prism(clip, -1.0, 1000.0)], m3d.OpType.Intersect)
                   for m in _grouped(rects)]
    solid = m3d.Manifold.batch_boolean(solids, m3d.OpType.Add)
    by_id = {s.id: s for s in flanges}
    floor_top = max(p.web_thickness for p in pockets) + 1.0
    cutters = []
    for h in holes:
        if h.role is HoleRole.FASTENER:
            top = by_id[h.parent].height if h.parent in by_id else h.center[2]
            cutters.append(((top - h.depth - 1.0, top + 1.0), _hole_polygon(h)))
        else:
            cutters.append(((-1.0, floor_top), _hole_polygon(h)))
    if cutters:
        solid = m3d.Manifold.batch_boolean([solid] + _grouped(cutters), m3d.OpType.Subtract)
    return solid


def to_trimesh(solid: m3d.Manifold) -> trimesh.Trimesh:
    """A trimesh of a manifold3d solid (vertices (n, 3) float, faces (m, 3) int).

    The vertices are kept as manifold3d indexes them (no merging): its output is a closed
    2-manifold even where, as built, two vertices coincide (a pinch of zero-length edges
    that merging would turn into non-manifold edges).
    """
    mesh = solid.to_mesh()
    verts = np.asarray(mesh.vert_properties, dtype=float)[:, :3]
    faces = np.asarray(mesh.tri_verts, dtype=np.int64)
    return trimesh.Trimesh(vertices=verts, faces=faces, process=False)


def build_mesh(features: Sequence[Feature]) -> trimesh.Trimesh:
    """The watertight triangle mesh of the part described by `features` (mm)."""
    return to_trimesh(build_solid(features))
