"""Features found on a part's own mesh from its specs, for parts without `features.json`.

A spec says where a feature is (its point and normal, its direction); the mesh says what
is there.  Rays cast from the spec point find it:

- a hole (for hole diameter, position and edge distance specs; the point is the hole's
  centre on its entry face, the normal its axis, in any direction): the bore's radius from
  rays across the axis just inside the entry face, the entry face from rays onto the ring
  around the rim, the depth from rays through the material beside the bore;
- a rib (stiffener height and width; the point on its top, normal +Z): its width and
  centre line from the narrowest pair of opposite rays inside the top, its length from
  rays along it;
- a flange cap (flange height and width; the point on the cap top, normal +Z, the
  direction across the cap toward its free edge): the cap's width, its thickness and the
  wall's thickness under it, as a short straight segment;
- a wall without a cap, a rim (flange height without a width spec; the point on the
  wall's top): its thickness across and the floor beside it, the side its height is
  measured from, as a segment whose cap is the wall's whole top.

A part without features.json has its thickness specs checked too: a face at the point, a
back wall within the gauge's range, parallel to the face.

Whatever cannot be found is a problem naming the spec and the reason, for `ita spec
validate` and `ita prepare` to refuse (nothing is planned that cannot be measured).  Only
the nominal mesh is read: the as-built part (the simulator's) is never seen here.

    features, problems = infer_features(mesh, specs, known={f.id: f for f in part.features})
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import overload

import numpy as np
import trimesh
from numpy.typing import NDArray

from ita.part.model import Feature, FlangeSegment, Hole, HoleRole, Stiffener
from ita.specs.model import MeasurementKind as K
from ita.specs.model import MeasurementSpec

FloatArray = NDArray[np.float64]

HOLE_KINDS = (K.HOLE_DIAMETER, K.HOLE_POSITION, K.EDGE_DISTANCE)
RIB_KINDS = (K.STIFFENER_HEIGHT, K.STIFFENER_WIDTH)
FLANGE_KINDS = (K.FLANGE_HEIGHT, K.FLANGE_WIDTH)
#: kinds whose measurement (the SLRA's) needs the feature's geometry
GEOMETRY_KINDS = HOLE_KINDS + RIB_KINDS + FLANGE_KINDS
THICKNESS_KINDS = (K.WEB_THICKNESS, K.FLANGE_THICKNESS)
GAUGE_RANGE_MM = 100.0        # the ultrasonic gauge's range
MAX_BACK_WALL_TILT_DEG = 3.0  # a thickness's back wall within this of parallel to its face

RAYS = 24                 # rays across a bore or around a ring
INSIDE_MM = 0.3           # rays start this far inside a face
ROUND_SHARE = 0.04        # a bore's radii agree within this share of the radius (a polygon of 24+ sides)
DIAMETER_SHARE = 0.05     # the mesh's hole and the spec's nominal diameter agree within this share (or 0.1 mm)
FACE_MM = 0.2             # the ring around a rim lies within this of the entry plane
MAX_RIB_WIDTH_MM = 30.0   # wider than this is no rib
UP_COS = 0.999            # a rib's or a cap's top faces +Z within ~2.5 deg
FASTENER_PITCH_MM = 100.0  # holes on one face this close are a fastener row (datums for each other)
SEGMENT_HALF_MM = 20.0    # a found flange segment reaches this far along the cap each side where no end shows
MAX_RIM_WIDTH_MM = 60.0   # a wall without a cap (a rim) at most this thick
FLOOR_CLEAR_MM = 3.0      # a rim's floor is looked for this far past its face
MIN_RIM_HEIGHT_MM = 1.0   # and lies at least this far below its top
ON_TOP_MM = 0.5           # every spec of a found flange or rim lies on its top within this


@dataclass(frozen=True)
class NotFound:
    """A spec whose feature the mesh does not show (or, a thickness, that the gauge cannot
    measure there), and why."""

    spec_id: str
    feature: str
    reason: str
    thickness: bool = False

    @property
    def message(self) -> str:
        """The problem in a sentence, naming the spec."""
        if self.thickness:
            return f"{self.spec_id}: the gauge cannot measure this thickness on the part's mesh: {self.reason}"
        return f"{self.spec_id}: feature {self.feature!r} not found on the part's mesh: {self.reason}"


class MeshRays:
    """First hits on a mesh (both faces), distances in mm."""

    def __init__(self, mesh: trimesh.Trimesh):
        self.mesh = mesh
        self.normals = np.asarray(mesh.face_normals, dtype=float)
        self.anchor = np.asarray(mesh.triangles[:, 0], dtype=float)
        self.intersector: trimesh.ray.ray_pyembree.RayMeshIntersector | trimesh.ray.ray_triangle.RayMeshIntersector
        try:
            self.intersector = trimesh.ray.ray_pyembree.RayMeshIntersector(mesh)
        except Exception:  # no embree: trimesh's own (slower, same answers)
            self.intersector = trimesh.ray.ray_triangle.RayMeshIntersector(mesh)

    def first(self, origins: FloatArray, dirs: FloatArray) -> FloatArray:
        """(n,) distance along unit `dirs` (n, 3) from `origins` (n, 3) to the first face; inf: none."""
        return self.hits(origins, dirs)[0]

    def hits(self, origins: FloatArray, dirs: FloatArray) -> tuple[FloatArray, NDArray[np.int64]]:
        """(n,) distances as :meth:`first`, and (n,) the faces hit (-1: none)."""
        origins = np.atleast_2d(np.asarray(origins, dtype=float))
        dirs = np.atleast_2d(np.asarray(dirs, dtype=float))
        origins = np.broadcast_to(origins, dirs.shape).copy() if len(origins) == 1 else origins
        dirs = np.broadcast_to(dirs, origins.shape).copy() if len(dirs) == 1 else dirs
        face = np.asarray(self.intersector.intersects_first(origins, dirs), dtype=np.int64)
        out = np.full(len(dirs), np.inf)
        hit = face >= 0
        nf = self.normals[face[hit]]
        with np.errstate(divide="ignore", invalid="ignore"):
            out[hit] = np.abs(np.einsum("ij,ij->i", nf, self.anchor[face[hit]] - origins[hit])
                              / np.einsum("ij,ij->i", nf, dirs[hit]))
        return out, face


def basis(n: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Two unit vectors across unit `n`, with `n` a right-handed frame."""
    a = np.array([1.0, 0.0, 0.0]) if abs(n[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    u = np.cross(n, a)
    u /= np.linalg.norm(u)
    return u, np.cross(n, u)


def ring(n: FloatArray, count: int = RAYS) -> FloatArray:
    u, v = basis(n)
    t = np.linspace(0.0, 2 * math.pi, count, endpoint=False)
    return np.cos(t)[:, None] * u + np.sin(t)[:, None] * v


def _find_hole(rays: MeshRays, fid: str, specs: Sequence[MeasurementSpec]) -> Hole | str:
    centred = [s for s in specs if s.kind in (K.HOLE_DIAMETER, K.HOLE_POSITION)]
    if not centred:
        return ("an edge distance needs its hole's diameter or position spec: their point is the hole's "
                "centre on its entry face, which the edge distance's point is not")
    s = centred[0]
    c, n = np.asarray(s.point, dtype=float), np.asarray(s.normal, dtype=float)
    n = n / np.linalg.norm(n)
    radial = ring(n)
    size = float(np.max(rays.mesh.extents))
    radii = rays.first(c - INSIDE_MM * n, radial)
    if not np.all(np.isfinite(radii)) or float(radii.max()) > size / 2:
        return f"no hole at {_xyz(c)} along {_xyz(n, 3)}: rays across the axis there leave the part"
    r = float(np.mean(radii))
    if float(radii.max() - radii.min()) > ROUND_SHARE * r + 0.02:
        return (f"no round hole at {_xyz(c)} along {_xyz(n, 3)}: the bore's radius there runs from "
                f"{radii.min():.2f} to {radii.max():.2f} mm (is the point the hole's centre, the normal its axis?)")
    # a polygonal bore's rays hit its sides between the corners: the circle through the corners
    r_circle = r / math.cos(math.pi / max(_polygon_sides(rays, c - INSIDE_MM * n, n, r), 3))
    nominal = next((x.nominal for x in specs if x.kind is K.HOLE_DIAMETER), None)
    diameter = float(nominal) if nominal is not None else 2 * r_circle
    if nominal is not None and abs(2 * r_circle - nominal) > max(0.1, DIAMETER_SHARE * nominal):
        return (f"the mesh's hole at {_xyz(c)} is {2 * r_circle:.3f} mm across; its diameter spec says "
                f"{nominal:.3f} mm")
    around = c + (r_circle + 1.0) * radial
    to_face = rays.first(around + 2.0 * n, np.broadcast_to(-n, around.shape))
    on_face = np.abs(to_face - 2.0) < FACE_MM
    if on_face.mean() < 0.5:
        return (f"no entry face around the hole at {_xyz(c)}: the point must be the hole's centre on the face "
                f"it is drilled from (normal out of that face)")
    through = rays.first(around[on_face] - 0.01 * n, np.broadcast_to(-n, around[on_face].shape))
    bore = rays.first((c + n)[None], (-n)[None])[0] - 1.0
    depth = float(min(np.median(through[np.isfinite(through)]) + 0.01 if np.isfinite(through).any() else bore, bore))
    if not math.isfinite(depth) or depth <= 0:
        return f"the hole at {_xyz(c)} has no depth the mesh shows"
    return Hole(fid, HoleRole.FASTENER, (float(c[0]), float(c[1]), float(c[2])),
                (float(n[0]), float(n[1]), float(n[2])), round(diameter, 6), round(depth, 6), parent="")


def _polygon_sides(rays: MeshRays, p: FloatArray, n: FloatArray, r: float) -> int:
    """Sides of a polygonal bore (its radii dip between corners); a large count for a true circle."""
    d = rays.first(p, ring(n, 360))
    if not np.all(np.isfinite(d)):
        return 10_000
    x = d - d.mean()
    if float(np.ptp(d)) < 1e-4 * r:
        return 10_000
    spectrum = np.abs(np.fft.rfft(x))
    return int(np.argmax(spectrum[3:]) + 3)


@overload
def _across(rays: MeshRays, p: FloatArray, given: FloatArray, limit: float) -> tuple[FloatArray, float, float]: ...
@overload
def _across(rays: MeshRays, p: FloatArray, given: None, limit: float) -> tuple[FloatArray, float, float] | str: ...
def _across(rays: MeshRays, p: FloatArray, given: FloatArray | None, limit: float) -> tuple[FloatArray, float, float] | str:
    """The direction across a wall-like feature at top point p (n = +Z) and the distances to its
    two side faces (+u, -u) from just inside the top; the narrowest direction when none is given."""
    start = p - np.array([0.0, 0.0, INSIDE_MM])
    if given is not None:
        u = np.array([given[0], given[1], 0.0])
        u /= np.linalg.norm(u)
        d = rays.first(np.vstack([start, start]), np.vstack([u, -u]))
        return u, float(d[0]), float(d[1])
    t = np.radians(np.arange(0.0, 180.0, 2.0))
    dirs = np.column_stack([np.cos(t), np.sin(t), np.zeros_like(t)])
    d = rays.first(np.repeat(start[None], 2 * len(t), axis=0), np.vstack([dirs, -dirs]))
    width = d[: len(t)] + d[len(t):]
    k = int(np.argmin(width))
    if not math.isfinite(width[k]) or width[k] > limit:
        return f"no wall narrower than {limit:g} mm under {_xyz(p)}"
    return dirs[k], float(d[k]), float(d[len(t) + k])


def _find_rib(rays: MeshRays, fid: str, specs: Sequence[MeasurementSpec]) -> Stiffener | str:
    s = specs[0]
    p, n = np.asarray(s.point, dtype=float), np.asarray(s.normal, dtype=float)
    if n[2] < UP_COS:
        return f"the rib's top at {_xyz(p)} does not face +Z (normal {_xyz(n, 3)}): the SLRA measures ribs standing on the part's web"
    given = next((x.direction for x in specs if x.direction is not None), None)
    found = _across(rays, p, None if given is None else np.asarray(given, dtype=float), MAX_RIB_WIDTH_MM)
    if isinstance(found, str):
        return f"no rib at {_xyz(p)}: {found}"
    u, d_plus, d_minus = found
    width = d_plus + d_minus
    if not math.isfinite(width) or width > MAX_RIB_WIDTH_MM:
        return f"no rib at {_xyz(p)}: its sides are not within {MAX_RIB_WIDTH_MM:g} mm across"
    centre = p[:2] + u[:2] * (d_plus - d_minus) / 2
    along = np.array([-u[1], u[0], 0.0])
    start = np.array([*centre, p[2] - INSIDE_MM])
    ends = rays.first(np.vstack([start, start]), np.vstack([along, -along]))
    if not np.all(np.isfinite(ends)):
        return f"the rib at {_xyz(p)} has no end the mesh shows"
    a, b = centre + along[:2] * ends[0], centre - along[:2] * ends[1]
    return Stiffener(fid, (float(b[0]), float(b[1])), (float(a[0]), float(a[1])), round(float(width), 6),
                     round(float(p[2]), 6))


def _find_flange(rays: MeshRays, fid: str, specs: Sequence[MeasurementSpec]) -> FlangeSegment | str:
    """The flange (or rim) under its specs: found at each point its specs name (a width
    spec's direction there says which way the cap points; none: a rim), one segment when
    they are one, else a path through the wall's face at each point with its normal there
    (a run round a corner arc)."""
    points: dict[tuple[float, ...], MeasurementSpec] = {}
    for x in specs:
        key = tuple(round(float(c), 3) for c in x.point)
        if key not in points or (points[key].direction is None and x.direction is not None):
            points[key] = x
    pieces = []
    for x in points.values():
        got = _flange_at(rays, fid, x)
        if isinstance(got, str):
            return got
        pieces.append((np.asarray(x.point[:2], dtype=float), got))
    if len(pieces) == 1:
        return pieces[0][1]
    first = pieces[0][1]
    for p, seg in pieces[1:]:
        if abs(seg.cap_width - first.cap_width) > ON_TOP_MM or abs(seg.height - first.height) > ON_TOP_MM:
            return (f"its walls differ: {first.cap_width:.1f} mm across and {first.height:.1f} high at its first spec, "
                    f"{seg.cap_width:.1f} and {seg.height:.1f} at {_xyz(p)}: give each its own feature id")
    return _joined(fid, pieces)


def _joined(fid: str, pieces: list[tuple[FloatArray, FlangeSegment]]) -> FlangeSegment:
    """One segment through the wall's face at each piece's point, in order along the run
    (from the point farthest from their middle, nearest next), reaching SEGMENT_HALF_MM
    past the first and the last; the first piece's sections."""
    faces = [(p - seg.normals_array[0] * seg.from_wall(p), seg.normals_array[0]) for p, seg in pieces]
    middle = np.mean([f for f, _ in faces], axis=0)
    order = [int(np.argmax([np.linalg.norm(f - middle) for f, _ in faces]))]
    while len(order) < len(faces):
        last = faces[order[-1]][0]
        rest = [k for k in range(len(faces)) if k not in order]
        order.append(min(rest, key=lambda k: float(np.linalg.norm(faces[k][0] - last))))
    path = [faces[k][0] for k in order]
    normals = [faces[k][1] for k in order]
    head = (path[0] - path[1]) / max(float(np.linalg.norm(path[0] - path[1])), 1e-9)
    tail = (path[-1] - path[-2]) / max(float(np.linalg.norm(path[-1] - path[-2])), 1e-9)
    path = [path[0] + head * SEGMENT_HALF_MM, *path, path[-1] + tail * SEGMENT_HALF_MM]
    normals = [normals[0], *normals, normals[-1]]
    first = pieces[order[0]][1]
    length = float(sum(np.linalg.norm(np.diff(np.asarray(path), axis=0), axis=1)))
    return FlangeSegment(fid, first.side, (0.0, length), tuple((float(x), float(y)) for x, y in path),
                         tuple((float(x), float(y)) for x, y in normals), first.height, first.wall_thickness,
                         first.cap_width, first.cap_thickness)


def _flange_at(rays: MeshRays, fid: str, s: MeasurementSpec) -> FlangeSegment | str:
    """The flange cap or rim under spec s's point (see :func:`_find_flange`)."""
    p, n = np.asarray(s.point, dtype=float), np.asarray(s.normal, dtype=float)
    if n[2] < UP_COS:
        return f"the flange cap's top at {_xyz(p)} does not face +Z (normal {_xyz(n, 3)})"
    if s.direction is None:
        return _find_rim(rays, fid, p)
    found = _across(rays, p, np.asarray(s.direction, dtype=float), 1e9)
    u, to_free, to_outer = found
    if not (math.isfinite(to_free) and math.isfinite(to_outer)):
        return f"no flange cap at {_xyz(p)}: its faces across {_xyz(u, 3)} are not both on the part"
    cap_width = to_free + to_outer
    outer = p - u * to_outer
    down = np.array([0.0, 0.0, -1.0])
    free_side = outer + u * max(cap_width - 1.0, cap_width / 2)
    cap_thickness = float(rays.first((free_side + 0.01 * down)[None], down[None])[0]) + 0.01
    if not math.isfinite(cap_thickness) or cap_thickness >= p[2]:
        return f"no flange cap at {_xyz(p)}: nothing under the cap's free edge (is it a wall, not an L section?)"
    below = outer + np.array([0.0, 0.0, -cap_thickness - 2.0]) + 0.01 * u
    wall = float(rays.first(below[None], u[None])[0]) + 0.01
    if not math.isfinite(wall) or wall >= cap_width:
        return f"no wall under the flange cap at {_xyz(p)}"
    along = np.array([-u[1], u[0], 0.0])
    mid = outer + u * min(wall / 2, cap_width / 2) - np.array([0.0, 0.0, INSIDE_MM])
    reach = rays.first(np.vstack([mid, mid]), np.vstack([along, -along]))
    half_a, half_b = (float(x) if math.isfinite(x) else SEGMENT_HALF_MM for x in reach)    # its straight run
    a, b = outer[:2] - along[:2] * half_b, outer[:2] + along[:2] * half_a
    path = ((float(a[0]), float(a[1])), (float(b[0]), float(b[1])))
    normal = (float(u[0]), float(u[1]))
    return FlangeSegment(fid, "outer", (0.0, half_a + half_b), path, (normal, normal), round(float(p[2]), 6),
                         round(wall, 6), round(float(cap_width), 6), round(cap_thickness, 6))


def _find_rim(rays: MeshRays, fid: str, p: FloatArray) -> FlangeSegment | str:
    """A wall without a cap (a rim) under top point p: its narrowest direction across, the
    floor beside it (the side where, just past the wall, the mesh lies below its top: the
    web its height is measured from), as a segment whose cap is the wall's top, its normal
    from the wall's other face toward that floor.  Without a width spec a flange height's
    feature is such a wall; an L section names its cap's direction by its width spec."""
    found = _across(rays, p, None, MAX_RIM_WIDTH_MM)
    if isinstance(found, str):
        return f"no wall or flange cap at {_xyz(p)}: {found} (an L section's cap needs a width spec: its direction)"
    u, d_plus, d_minus = found
    down = np.array([0.0, 0.0, -1.0])
    floors = []
    for side, reach in ((u, d_plus), (-u, d_minus)):
        q = p + side * (reach + FLOOR_CLEAR_MM) + np.array([0.0, 0.0, 1.0])
        depth = float(rays.first(q[None], down[None])[0]) - 1.0
        if math.isfinite(depth) and depth > MIN_RIM_HEIGHT_MM:
            floors.append((depth, side, reach))
    if not floors:
        return f"no floor beside the wall under {_xyz(p)}: a rim's height is measured from the web beside it"
    depth, inward, to_free = min(floors, key=lambda f: f[0])      # the nearer floor (the web, not the fixture)
    width = d_plus + d_minus
    outer = p - inward * (width - to_free)
    along = np.array([-inward[1], inward[0], 0.0])
    mid = outer + inward * width / 2 - np.array([0.0, 0.0, INSIDE_MM])
    ends = rays.first(np.vstack([mid, mid]), np.vstack([along, -along]))     # a rim runs wall to wall
    half_a, half_b = (float(x) if math.isfinite(x) else SEGMENT_HALF_MM for x in ends)
    a, b = outer[:2] - along[:2] * half_b, outer[:2] + along[:2] * half_a
    normal = (float(inward[0]), float(inward[1]))
    return FlangeSegment(fid, "outer", (0.0, half_a + half_b), ((float(a[0]), float(a[1])), (float(b[0]), float(b[1]))),
                         (normal, normal), round(float(p[2]), 6), round(width, 6), round(width, 6), round(depth, 6))


def _on_segment(seg: FlangeSegment, specs: Sequence[MeasurementSpec]) -> FlangeSegment | str:
    """The segment found from one spec when every spec of its feature lies on its top
    (within the cap, across, and along its straight run); else why not."""
    off = [s.id for s in specs if not -ON_TOP_MM <= seg.from_wall(s.point) <= seg.cap_width + ON_TOP_MM]
    if off:
        return (f"{', '.join(off)} not on the straight wall found at the feature's first spec (a wall {seg.cap_width:.1f} "
                f"mm across): give each straight wall or flange run its own feature id")
    return seg


def _thickness_problem(rays: MeshRays, s: MeasurementSpec) -> str:
    """Why a thickness spec cannot be measured by the gauge along its normal ("" when it
    can): no face at the point, no back wall within the gauge's range, or a back wall not
    parallel to the face (the gauge reads the nearest back wall in its beam, not the
    thickness along the normal)."""
    p, n = np.asarray(s.point, dtype=float), np.asarray(s.normal, dtype=float)
    n = n / np.linalg.norm(n)
    o = (p + 2.0 * n)[None]
    face = rays.intersector.intersects_first(o, (-n)[None])[0]
    to_face = rays.first(o, (-n)[None])[0]
    if face < 0 or abs(to_face - 2.0) > 1.0 or float(np.dot(rays.normals[face], n)) < 0.5:
        return f"no face at {_xyz(p)} facing {_xyz(n, 3)} (the point must be on the face, the normal out of it)"
    start = (p + (2.0 - to_face - 0.01) * n)[None]
    back = int(rays.intersector.intersects_first(start, (-n)[None])[0])
    depth = rays.first(start, (-n)[None])[0] + 0.01
    if back < 0 or depth > GAUGE_RANGE_MM:
        return f"no back wall within the gauge's {GAUGE_RANGE_MM:g} mm under {_xyz(p)}"
    tilt = math.degrees(math.acos(float(np.clip(-np.dot(rays.normals[back], n), -1.0, 1.0))))
    if tilt > MAX_BACK_WALL_TILT_DEG:
        return (f"the back wall under {_xyz(p)} ({depth:.2f} mm down) is {tilt:.0f} deg off parallel to the face: the "
                f"gauge reads the nearest back wall in its beam, not the thickness along the normal "
                f"(at most {MAX_BACK_WALL_TILT_DEG:g} deg)")
    return ""


def _xyz(v: FloatArray, digits: int = 1) -> str:
    return "(" + ", ".join(f"{x:.{digits}f}" for x in v) + ")"


def infer_features(mesh: trimesh.Trimesh, specs: Sequence[MeasurementSpec],
                   known: Mapping[str, Feature] = {}) -> tuple[tuple[Feature, ...], tuple[NotFound, ...]]:
    """The features the SLRA's specs name and `known` lacks, found on `mesh` (mm, part frame),
    and the specs whose feature is not there (with the reason).  A feature whose specs ask
    for different kinds of feature (a hole and a rib) is not found."""
    by_feature: dict[str, list[MeasurementSpec]] = {}
    for s in specs:
        if s.kind in GEOMETRY_KINDS and s.feature not in known:
            by_feature.setdefault(s.feature, []).append(s)
    thickness = [s for s in specs if s.kind in THICKNESS_KINDS] if not known else []
    if not by_feature and not thickness:
        return (), ()
    rays = MeshRays(mesh)
    found: list[Feature] = []
    missing: list[NotFound] = [NotFound(s.id, s.feature, why, thickness=True) for s in thickness
                               if (why := _thickness_problem(rays, s))]
    for fid, group in by_feature.items():
        kinds = {s.kind for s in group}
        if kinds <= set(HOLE_KINDS):
            got: Feature | str = _find_hole(rays, fid, group)
        elif kinds <= set(RIB_KINDS):
            got = _find_rib(rays, fid, group)
        elif kinds <= set(FLANGE_KINDS):
            got = _find_flange(rays, fid, group)
            if isinstance(got, FlangeSegment):
                got = _on_segment(got, group)
        else:
            got = (f"its specs ask for different features ({', '.join(sorted(k.value for k in kinds))}); "
                   f"give each feature its own id")
        if isinstance(got, str):
            missing += [NotFound(s.id, fid, got) for s in group]
        else:
            found.append(got)
    return tuple(_fastener_roles(found)), tuple(missing)


def _fastener_roles(features: list[Feature]) -> list[Feature]:
    """Found holes with another found hole on the same face within FASTENER_PITCH_MM are fasteners (their
    neighbours are datums in a frame); a lone hole's position has the arm's pose for datum
    (re-approached and averaged), as a lightening hole's."""
    from dataclasses import replace

    holes = [f for f in features if isinstance(f, Hole)]
    out = []
    for f in features:
        if isinstance(f, Hole):
            near = [h for h in holes if h.id != f.id and np.dot(h.axis, f.axis) > UP_COS
                    and abs(np.dot(np.subtract(h.center, f.center), f.axis)) < 1.0
                    and math.dist(h.center, f.center) < FASTENER_PITCH_MM]
            if not near:
                f = replace(f, role=HoleRole.LIGHTENING)
        out.append(f)
    return out
