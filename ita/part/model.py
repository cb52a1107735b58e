"""Value types of a part: its features (nominal geometry) and the loaded part.

Units: millimetres, part frame (web in XY, datum A = web back face at z = 0, features rise
on +Z).  Each feature carries the geometry that the mesh builder, Vision (to place its
patches) and the path planner (to build its region tree) need; `bounds()` gives every
feature's axis-aligned box.  Polylines are stored as tuples so features stay hashable;
the `*_array` properties return numpy views of them.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field, fields
from enum import Enum
from pathlib import Path
from typing import Any, ClassVar, Union

import numpy as np

Vec2 = tuple[float, float]
Vec3 = tuple[float, float, float]


class FeatureKind(str, Enum):
    """What a feature is.  The value is the spelling used in files."""

    POCKET = "pocket"
    STIFFENER = "stiffener"
    FLANGE = "flange"
    HOLE = "hole"


class HoleRole(str, Enum):
    """Why a hole is there (decides its tolerances)."""

    FASTENER = "fastener"
    LIGHTENING = "lightening"
    TOOLING = "tooling"


@dataclass(frozen=True)
class Pocket:
    """A machined pocket: web floor between stiffeners and flanges.

    outline: (n, 2) CCW polygon of the floor visible from +Z (inside the rib faces,
    outside the flange caps), mm; web_thickness: floor height above datum A, mm.  The
    web under the ribs and caps around it is not part of the pocket.
    """

    id: str
    outline: tuple[Vec2, ...]
    web_thickness: float
    kind: ClassVar[FeatureKind] = FeatureKind.POCKET

    @property
    def outline_array(self) -> np.ndarray:
        """(n, 2) float: the floor outline."""
        return np.asarray(self.outline, dtype=float)

    def bounds(self) -> np.ndarray:
        """(2, 3) float: min and max corner of the floor outline, z 0 .. web_thickness."""
        p = self.outline_array
        return np.array([[*p.min(axis=0), 0.0], [*p.max(axis=0), self.web_thickness]])


@dataclass(frozen=True)
class Stiffener:
    """A rib standing on the web: a wall of `width` along start-end, top at `height`.

    start, end: (x, y) ends of its centre line (mm; it is buried in the flange walls it
    meets); width: thickness across the centre line; height: top above datum A.
    """

    id: str
    start: Vec2
    end: Vec2
    width: float
    height: float
    kind: ClassVar[FeatureKind] = FeatureKind.STIFFENER

    @property
    def direction(self) -> np.ndarray:
        """(2,) float: unit vector from start to end."""
        d = np.subtract(self.end, self.start)
        return d / np.linalg.norm(d)

    def bounds(self) -> np.ndarray:
        """(2, 3) float: axis-aligned box of the rib."""
        p = np.array([self.start, self.end])
        h = self.width / 2
        return np.array([[*(p.min(axis=0) - h), 0.0], [*(p.max(axis=0) + h), self.height]])


@dataclass(frozen=True)
class FlangeSegment:
    """A segment of the outer or inner flange, an L section along a contour.

    side: "outer" (on the outline, cap pointing inward) or "inner" (around the opening,
    cap pointing away from it).  path: (n, 2) points of the wall's free face (the
    outline, or the opening's edge); normals: (n, 2) unit vectors from that face into the
    flange, i.e. the direction across the cap toward its free edge; s_range: arc length
    of the segment on its contour.  height: cap top above datum A; the wall spans
    0 .. wall_thickness along the normal, the cap 0 .. cap_width, z height-cap_thickness
    .. height.
    """

    id: str
    side: str
    s_range: Vec2
    path: tuple[Vec2, ...]
    normals: tuple[Vec2, ...]
    height: float
    wall_thickness: float
    cap_width: float
    cap_thickness: float
    kind: ClassVar[FeatureKind] = FeatureKind.FLANGE

    @property
    def path_array(self) -> np.ndarray:
        """(n, 2) float: the free face of the wall."""
        return np.asarray(self.path, dtype=float)

    @property
    def normals_array(self) -> np.ndarray:
        """(n, 2) float: unit normals into the flange."""
        return np.asarray(self.normals, dtype=float)

    def across(self, xy) -> tuple[float, np.ndarray]:
        """Where part point xy (mm) lies across the flange: its distance from the wall's free
        face along the flange's normal there, and that normal (2,).  The normal runs
        linearly along each piece of the path between its ends' normals; the foot is the
        path point whose normal passes through xy (a spec's point anywhere on the cap's
        top, on a straight run or round a corner arc)."""
        p, path, normals = np.asarray(xy, dtype=float)[:2], self.path_array, self.normals_array
        if len(path) < 2:
            return float(np.dot(p - path[0], normals[0])), normals[0]
        best: tuple[float, np.ndarray] | None = None
        for a, b, n0, n1 in zip(path[:-1], path[1:], normals[:-1], normals[1:]):
            d, m, r = b - a, n1 - n0, p - a
            # cross(r - t d, n0 + t m) = 0: c0 + c1 t + c2 t^2
            c0 = r[0] * n0[1] - r[1] * n0[0]
            c1 = (r[0] * m[1] - r[1] * m[0]) - (d[0] * n0[1] - d[1] * n0[0])
            c2 = -(d[0] * m[1] - d[1] * m[0])
            if abs(c2) >= 1e-12:
                roots = [float(t.real) for t in np.roots([c2, c1, c0]) if abs(t.imag) < 1e-9]
            else:
                roots = [-c0 / c1] if abs(c1) > 1e-12 else []
            for t in roots:
                if -1e-6 <= t <= 1 + 1e-6:
                    n = n0 + t * m
                    n = n / np.linalg.norm(n)
                    dist = float(np.dot(p - (a + t * d), n))
                    if best is None or abs(dist) < abs(best[0]):
                        best = (dist, n)
        if best is None:      # past the path's ends: from the nearer end, along its normal
            k = 0 if np.linalg.norm(p - path[0]) <= np.linalg.norm(p - path[-1]) else -1
            best = (float(np.dot(p - path[k], normals[k])), normals[k])
        return best

    def from_wall(self, xy) -> float:
        """How far part point xy (mm) lies from the wall's free face, across the flange
        (:meth:`across`)."""
        return self.across(xy)[0]

    def bounds(self) -> np.ndarray:
        """(2, 3) float: axis-aligned box of the segment (wall and cap)."""
        p = np.vstack([self.path_array, self.path_array + self.cap_width * self.normals_array])
        return np.array([[*p.min(axis=0), 0.0], [*p.max(axis=0), self.height]])


@dataclass(frozen=True)
class Hole:
    """A drilled hole with its axis along Z.

    center: (x, y, z) centre on the entry face (z = that face's height); axis: unit
    vector out of the entry face; depth: material drilled through; parent: id of the
    feature it is drilled in; datum: "B" or "C" for the tooling holes, else "".
    """

    id: str
    role: HoleRole
    center: Vec3
    axis: Vec3
    diameter: float
    depth: float
    parent: str
    datum: str = ""
    kind: ClassVar[FeatureKind] = FeatureKind.HOLE

    def bounds(self) -> np.ndarray:
        """(2, 3) float: axis-aligned box of the drilled cylinder."""
        c, r = np.asarray(self.center), self.diameter / 2
        return np.array([[c[0] - r, c[1] - r, c[2] - self.depth], [c[0] + r, c[1] + r, c[2]]])


Feature = Union[Pocket, Stiffener, FlangeSegment, Hole]
FEATURE_TYPES: dict[FeatureKind, type] = {
    FeatureKind.POCKET: Pocket, FeatureKind.STIFFENER: Stiffener,
    FeatureKind.FLANGE: FlangeSegment, FeatureKind.HOLE: Hole,
}


def feature_to_dict(feature: Feature) -> dict[str, Any]:
    """A JSON-ready dict of a feature, with its kind."""
    data = asdict(feature)
    data = {k: (v.value if isinstance(v, Enum) else v) for k, v in data.items()}
    return {"kind": feature.kind.value, **data}


def _tuples(value: Any) -> Any:
    return tuple(_tuples(v) for v in value) if isinstance(value, list) else value


def feature_from_dict(data: dict[str, Any]) -> Feature:
    """The feature of a `feature_to_dict` dict; raises KeyError/ValueError when malformed."""
    cls = FEATURE_TYPES[FeatureKind(data["kind"])]
    names = {f.name for f in fields(cls)}
    values = {k: _tuples(v) for k, v in data.items() if k in names}
    if cls is Hole:
        values["role"] = HoleRole(values["role"])
    return cls(**values)


@dataclass(frozen=True, eq=False)
class Part:
    """A loaded part: its nominal mesh (trimesh, mm), features and specs file.

    directory: where its files are; specs_path: its specs CSV (read it with
    ita.specs.io.read_specs); features: features.json's, and for the SLRA's specs whose
    feature it lacks (or has no features.json), the features found on the mesh
    (ita.part.infer); unfound: the specs whose feature the mesh does not show
    (ita.part.infer.NotFound, with the reason); found: ids of the features found on the
    mesh.
    """

    name: str
    directory: Path
    mesh: Any
    features: tuple[Feature, ...]
    specs_path: Path
    metadata: dict[str, Any] = field(default_factory=dict)
    unfound: tuple[Any, ...] = ()
    found: tuple[str, ...] = ()

    def feature(self, feature_id: str) -> Feature:
        """The feature with id `feature_id`; KeyError when there is none."""
        for f in self.features:
            if f.id == feature_id:
                return f
        raise KeyError(feature_id)
