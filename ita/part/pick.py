"""A measurement proposed from the part's mesh at a point a person picked (the seed's
Offline Measurement Entry: "a graphics display of the bulkhead to select measurement
locations"): what is there, which kinds of measurement fit it, the nominal measured on
the mesh, the point and the normal a spec needs.

    proposal = propose(part, (x, y, z))              # the first kind that fits
    proposal = propose(part, (x, y, z), kind=K.HOLE_POSITION)
    proposal.to_dict()       # kind, feature, point, normal, nominal, direction, candidates, what, reason

What the mesh shows at the point (its nearest surface, within PICK_MM):

- a bore's wall (the point on or inside a hole): a hole, its axis the direction its wall
  runs straight, its centre on the face it opens onto: hole_diameter, hole_position,
  edge_distance (to the nearest edge of that face);
- the top of a narrow wall with a floor on both sides: a rib (stiffener_height,
  stiffener_width across it); with a floor on one side: a rim (flange_height);
- a face whose back wall lies within the gauge's range and parallel: a thickness
  (web_thickness where the back is datum A, the part's back face; flange_thickness else).

Heights and positions are in the part frame (datum A at z = 0: the generator's and the
specs' convention).  Only the nominal mesh is read.  Nothing measurable: no kind, and
the reason.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import trimesh

from ita.part.infer import (
    INSIDE_MM,
    MAX_RIB_WIDTH_MM,
    MeshRays,
    _across,
    _find_hole,
    _thickness_problem,
    ring,
)
from ita.part.model import FlangeSegment, Hole, Stiffener
from ita.specs.io import read_specs
from ita.specs.model import MeasurementKind as K
from ita.specs.model import MeasurementSpec

__all__ = ["PICK_MM", "Proposal", "propose"]

FloatArray = np.ndarray

#: the picked point lies within this of the part's surface
PICK_MM = 5.0
#: a hole's bore is at most this across (wider: an opening, whose rim is a flange's)
MAX_HOLE_MM = 100.0
#: a floor beside a wall's top lies at least this far below it
FLOOR_BELOW_MM = 1.0
#: a face is "up" (a top, a floor) within this of +Z
UP_COS = 0.95


@dataclass(frozen=True)
class Proposal:
    """What a pick proposes: the kind (None: nothing measurable, `reason` says why), the
    feature (an id of the part's specs when one is there, else a new one), the spec's
    point and normal, the nominal measured on the mesh, a direction where the kind needs
    one, the other kinds that fit the point, and what the mesh shows there in words."""

    kind: str | None
    feature: str | None = None
    point: tuple[float, float, float] | None = None
    normal: tuple[float, float, float] | None = None
    nominal: float | None = None
    direction: tuple[float, float, float] | None = None
    candidates: tuple[str, ...] = ()
    what: str = ""
    reason: str = ""
    nominals: dict[str, float] = field(default_factory=dict)

    def to_dict(self) -> dict[str, Any]:
        return {"kind": self.kind, "feature": self.feature, "point": _list(self.point), "normal": _list(self.normal),
                "nominal": self.nominal, "direction": _list(self.direction), "candidates": list(self.candidates),
                "what": self.what, "reason": self.reason or None}


def _list(v: Sequence[float] | None) -> list[float] | None:
    return None if v is None else [round(float(x), 4) + 0.0 for x in v]      # no -0.0


def _v(x: FloatArray) -> tuple[float, float, float]:
    return (float(x[0]), float(x[1]), float(x[2]))


@dataclass(frozen=True)
class _Found:
    """What the mesh shows: a kind of feature, the kinds that fit with their nominal,
    point, normal and direction, and the feature (when the part already names it)."""

    what: str
    prefix: str
    fits: dict[str, tuple[float, FloatArray, FloatArray, FloatArray | None]]
    at: FloatArray | None = None        # where the feature is (a hole's centre): the part's own id is looked up there


def propose(part: Any, at: Sequence[float], kind: K | None = None) -> Proposal:
    """The measurement proposed at part point `at` (mm) of `part` (its mesh, features and
    specs; ita.part.store.Part), of `kind` when given (else the first that fits)."""
    mesh: trimesh.Trimesh = part.mesh
    at_ = np.asarray(at, dtype=float)
    if at_.shape != (3,) or not np.all(np.isfinite(at_)):
        return Proposal(None, reason=f"a point is three finite numbers x,y,z in mm (got {list(at)})")
    closest, distance, face = trimesh.proximity.closest_point(mesh, at_[None])
    if float(distance[0]) > PICK_MM:
        return Proposal(None, reason=f"nothing of the part within {PICK_MM:g} mm of {_xyz(at_)} "
                                     f"(the nearest surface is {float(distance[0]):.1f} mm away)")
    p, n = np.asarray(closest[0], dtype=float), np.asarray(mesh.face_normals[int(face[0])], dtype=float)
    rays = MeshRays(mesh)
    found = _hole_at(rays, p, n)           # a bore's wall faces any way across its axis
    if found is None and n[2] >= UP_COS:
        found = _top_at(rays, p)
    if found is None:
        found = _thickness_at(rays, p, n, float(mesh.bounds[0][2]))
    if isinstance(found, str):
        return Proposal(None, point=_v(p), normal=_v(n), reason=found)
    chosen = kind.value if kind is not None else next(iter(found.fits))
    if chosen not in found.fits:
        return Proposal(None, point=_v(p), normal=_v(n), candidates=tuple(found.fits), what=found.what,
                        reason=f"a {chosen} does not fit here: the mesh shows {found.what}; what fits: "
                               f"{', '.join(found.fits)}")
    nominal, point, normal, direction = found.fits[chosen]
    feature = _known_feature(part, found, point if found.at is None else found.at) or _new_feature(part, found.prefix)
    return Proposal(chosen, feature, _v(point), _v(normal), round(float(nominal), 4),
                    None if direction is None else _v(direction), tuple(found.fits), found.what,
                    nominals={k: round(float(v[0]), 4) for k, v in found.fits.items()})


# -- holes ------------------------------------------------------------------------------------

def _hole_at(rays: MeshRays, p: FloatArray, n: FloatArray) -> _Found | str | None:
    """A hole whose bore wall is at p (its normal n into the bore); None: not a bore."""
    across = float(rays.first((p + 0.01 * n)[None], n[None])[0]) + 0.01
    if not math.isfinite(across) or across > MAX_HOLE_MM:
        return None
    c0 = p + n * across / 2
    axis = _bore_axis(rays, c0, n, across / 2)
    if axis is None:
        return None
    c0, r = _centred(rays, c0, axis)
    c, axis = _entry(rays, c0, axis, r)
    if c is None:
        return "a bore, but no face it opens onto that the mesh shows"
    spec = MeasurementSpec("PICK", K.HOLE_POSITION, "PICK", _v(c), _v(axis), 0.0, 0.0, 0.5)
    hole = _find_hole(rays, "PICK", [spec])      # a position: the mesh gives the diameter
    if isinstance(hole, str):
        return hole
    fits: dict[str, tuple[float, FloatArray, FloatArray, FloatArray | None]] = {
        K.HOLE_DIAMETER.value: (hole.diameter, c, axis, None),
        K.HOLE_POSITION.value: (0.0, c, axis, None)}
    edge = _edge_from(rays, c, axis, hole.diameter / 2)
    if edge is not None:
        distance, direction = edge
        r = hole.diameter / 2        # the point on the ligament between the rim and the edge, as the generator puts it
        fits[K.EDGE_DISTANCE.value] = (distance, c + direction * (r + (distance - r) / 2), axis, direction)
    return _Found(f"a hole {hole.diameter:.3f} mm across, {hole.depth:.2f} mm deep, axis {_xyz(axis, 3)}", "H",
                  fits, c)


def _bore_axis(rays: MeshRays, c0: FloatArray, n: FloatArray, r: float) -> FloatArray | None:
    """The axis of a bore through c0 (n across it): the direction at right angles to n
    about which rays from c0 meet the wall at one radius; None when no direction is round."""
    ref = np.array([0.0, 0.0, 1.0]) if abs(n[2]) < 0.9 else np.array([1.0, 0.0, 0.0])
    a0 = np.cross(n, ref)
    a0 /= np.linalg.norm(a0)
    b0 = np.cross(n, a0)
    best, spread = None, math.inf
    for t in np.radians(np.arange(0.0, 180.0, 5.0)):
        axis = math.cos(t) * a0 + math.sin(t) * b0
        radii = rays.first(np.broadcast_to(c0, (24, 3)), ring(axis))
        if not np.all(np.isfinite(radii)):
            continue
        s = float(radii.max() - radii.min())
        if s < spread:
            best, spread = axis, s
    if best is None or spread > 0.05 * r + 0.05:
        return None
    return best


def _centred(rays: MeshRays, c0: FloatArray, axis: FloatArray) -> tuple[FloatArray, float]:
    """The bore's centre near c0 (in the plane at right angles to its axis) and its
    radius: a point off the centre by d sees the wall at R - d.u along u, so the centre
    lies twice the mean of (r_i - R) u_i from it; a few rounds (a pick on a faceted bore starts off its
    middle by the facets' sagitta)."""
    dirs = ring(axis, 48)
    c = c0
    radii = rays.first(np.broadcast_to(c, dirs.shape), dirs)
    for _ in range(4):
        if not np.all(np.isfinite(radii)):
            break
        c = c + 2.0 * np.mean((radii - radii.mean())[:, None] * dirs, axis=0)
        radii = rays.first(np.broadcast_to(c, dirs.shape), dirs)
    return c, float(np.mean(radii[np.isfinite(radii)])) if np.isfinite(radii).any() else 0.0


def _entry(rays: MeshRays, c0: FloatArray, axis: FloatArray, r: float) -> tuple[FloatArray | None, FloatArray]:
    """The bore's centre on the face it opens onto, and its axis out of that face: the
    opening toward +Z (or, a hole in a side, away from the part's middle)."""
    if abs(axis[2]) > 0.1:
        axis = axis if axis[2] > 0 else -axis
    elif float(np.dot(axis, c0 - rays.mesh.bounds.mean(axis=0))) < 0:
        axis = -axis
    u = np.cross(axis, np.array([1.0, 0.0, 0.0]) if abs(axis[0]) < 0.9 else np.array([0.0, 1.0, 0.0]))
    u /= np.linalg.norm(u)
    outside = c0 + u * (r + 1.0)               # beside the bore, in the material
    start = outside + axis * 0.01
    to_face = float(rays.first(start[None], axis[None])[0]) + 0.01
    if not math.isfinite(to_face):
        return None, axis
    return c0 + axis * (to_face + float(np.dot(outside - c0, axis))), axis


def _edge_from(rays: MeshRays, c: FloatArray, axis: FloatArray, r: float) -> tuple[float, FloatArray] | None:
    """The distance from a hole's centre c on its entry face to that face's nearest edge
    (where the face ends, looked for just below it), and the direction to it."""
    dirs = ring(axis, 72)
    start = c - axis * INSIDE_MM + dirs * (r + 0.05)
    out = rays.first(start, dirs) + r + 0.05
    k = int(np.argmin(out))
    if not math.isfinite(out[k]) or out[k] > 20 * max(r, 1.0):
        return None
    return float(out[k]), dirs[k]


# -- tops of walls and ribs, thicknesses ------------------------------------------------------

def _top_at(rays: MeshRays, p: FloatArray) -> _Found | None:
    """A rib (a floor on both sides) or a rim (one side) whose top is at p; None: no
    narrow wall under it."""
    found = _across(rays, p, None, MAX_RIB_WIDTH_MM)
    if isinstance(found, str):
        return None
    u, d_plus, d_minus = found
    width = d_plus + d_minus
    down = np.array([0.0, 0.0, -1.0])
    floors = []
    for side, reach in ((u, d_plus), (-u, d_minus)):
        q = p + side * (reach + 3.0) + np.array([0.0, 0.0, 1.0])
        depth = float(rays.first(q[None], down[None])[0]) - 1.0
        floors.append(math.isfinite(depth) and depth > FLOOR_BELOW_MM)
    middle = p + u * (d_plus - d_minus) / 2
    up = np.array([0.0, 0.0, 1.0])
    if all(floors):
        return _Found(f"the top of a rib {width:.2f} mm wide", "R", {
            K.STIFFENER_HEIGHT.value: (float(p[2]), middle, up, None),
            K.STIFFENER_WIDTH.value: (width, middle, up, u)})
    if any(floors):
        return _Found(f"the top of a wall {width:.2f} mm thick with a floor on one side (a rim)", "RIM", {
            K.FLANGE_HEIGHT.value: (float(p[2]), middle, up, None)})
    return None


def _thickness_at(rays: MeshRays, p: FloatArray, n: FloatArray, back_z: float) -> _Found | str:
    """A thickness along the normal at p: the web's (its back on datum A) or a wall's or a
    cap's; else why the gauge cannot measure one there."""
    if n[2] < -0.5:
        return f"the face at {_xyz(p)} faces down: the part lies on the fixture on datum A, no tool reaches it"
    spec = MeasurementSpec("PICK", K.WEB_THICKNESS, "PICK", _v(p), _v(n), 1.0, -0.1, 0.1)
    why = _thickness_problem(rays, spec)
    if why:
        return f"nothing measurable at {_xyz(p)}: {why}"
    depth = float(rays.first((p - 0.01 * n)[None], (-n)[None])[0]) + 0.01
    back = p - n * depth
    if n[2] >= UP_COS and abs(float(back[2]) - back_z) < 0.01:
        return _Found(f"a web {depth:.3f} mm thick (its back on datum A)", "P",
                      {K.WEB_THICKNESS.value: (depth, p, n, None)})
    return _Found(f"a wall {depth:.3f} mm thick", "W", {K.FLANGE_THICKNESS.value: (depth, p, n, None)})


# -- feature ids ------------------------------------------------------------------------------

def _known_feature(part: Any, found: _Found, point: FloatArray) -> str | None:
    """The id of the part's feature that is the one found (a hole at its centre, the rib or
    the wall under the point), when the part has it."""
    for f in getattr(part, "features", ()):
        if isinstance(f, Hole) and found.prefix == "H":
            if math.dist(f.center, point) < f.diameter / 2:
                return f.id
        elif isinstance(f, Stiffener) and found.prefix == "R":
            d = np.asarray(f.direction)
            rel = np.asarray(point[:2]) - np.asarray(f.start)
            along, off = float(np.dot(rel, d)), abs(float(rel[0] * d[1] - rel[1] * d[0]))
            length = math.dist(f.start, f.end)
            if -0.5 <= along <= length + 0.5 and off <= f.width / 2 + 0.5 and abs(point[2] - f.height) < 0.5:
                return f.id
        elif isinstance(f, FlangeSegment) and found.prefix == "RIM":
            if -0.5 <= f.from_wall(point) <= f.cap_width + 0.5 and abs(point[2] - f.height) < 0.5:
                return f.id
    return None


def _new_feature(part: Any, prefix: str) -> str:
    """A feature id of `prefix` and the first number no spec of the part uses."""
    used: set[str] = set()
    try:
        used = {s.feature for s in read_specs(part.specs_path)}
    except Exception:  # noqa: BLE001 - a part whose specs cannot be read yet: any number is free
        used = set()
    used |= {f.id for f in getattr(part, "features", ())}
    k = 1
    while f"{prefix}{k}" in used or f"{prefix}-{k}" in used:
        k += 1
    return f"{prefix}{k}"


def _xyz(v: Sequence[float] | FloatArray, digits: int = 1) -> str:
    return "(" + ", ".join(f"{float(x):.{digits}f}" for x in v) + ")"
