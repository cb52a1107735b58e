"""A QIF characteristic as ITA specs, or the reason ITA does not take it.

    outcome = map_row(doc, row)           # Mapped (drafts of specs) or Refused (a reason)

The rules, by QIF type (the kinds in :mod:`ita.qif.kinds`); lengths in mm, the file's
coordinate system taken as the part frame:

- Diameter of an internal Cylinder or Circle: hole_diameter, at the hole's centre on its
  entry face, the normal out of it (a cylinder's entry is the end whose outward axis
  points more along +Z, the side datum A's part is on: ITA's views come from above);
  the target, else the feature's diameter.
- Position of such a hole with a diametrical zone: hole_position, nominal 0, tolerance
  0 .. the zone's diameter, datums from the datum reference frame.  A material condition
  (MMC, LMC) is noted and not applied: ITA decides regardless of feature size, which
  never accepts what the modifier would reject.
- Thickness of a Plane or Point (with its normal), or of an external pair of planes:
  web_thickness when the face looks within 45 degrees of +Z, else flange_thickness.
- Height of a Plane facing +Z whose height above datum A (its z) is the target:
  stiffener_height.
- Width of external opposite parallel lines (on a top face) or planes (with a depth
  vector and depth): stiffener_width, across the lines.
- DistanceBetween (or DistanceFrom) of a hole and a Plane or Line parallel to its axis,
  as far apart as the target: edge_distance, along the perpendicular from the hole's
  centre; of two parallel faces with the material between them: a thickness.

A height or width is a stiffener's unless the file says flange (ITA's own export names
each item's kind in its attribute ``ita.kind``; such a file's kinds, features and datums
are taken as it states them).  Everything else is refused with its reason: other
characteristic types (form, orientation, profile, runout, angles, radii ...),
characteristics of several features (a pattern: one spec each with `expand_patterns`),
distances among more than two features, slots and other internal widths, external
diameters, missing tolerances, targets or references.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

from ita.qif.kinds import FAMILIES, KIND_ATTRIBUTE, KINDS_OF
from ita.qif.read import QifFile, Refuse, Row, Vec3
from ita.qif.tree import Element, kid, kids, local, q, text
from ita.specs.model import MeasurementKind as K

UP = (0.0, 0.0, 1.0)
WEB_COS = math.cos(math.radians(45.0))   # a thickness face within 45 deg of +Z is the web's
TOP_COS = 0.999                          # a top face faces +Z within ~2.5 deg (as ITA's ribs and caps)
PARALLEL_COS = 0.999                     # two faces or a face and an axis within ~2.5 deg
DATUM_PRECEDENCE = ("PRIMARY", "SECONDARY", "TERTIARY", "QUATERNARY", "QUINARY", "SENARY")


# ----------------------------------------------------------------------------- vectors
def _dot(a: Vec3, b: Vec3) -> float:
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


def _sub(a: Vec3, b: Vec3) -> Vec3:
    return (a[0] - b[0], a[1] - b[1], a[2] - b[2])


def _add(a: Vec3, b: Vec3, s: float = 1.0) -> Vec3:
    return (a[0] + s * b[0], a[1] + s * b[1], a[2] + s * b[2])


def _cross(a: Vec3, b: Vec3) -> Vec3:
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


def _unit(a: Vec3) -> Vec3:
    n = math.sqrt(_dot(a, a))
    if n < 1e-12:
        raise Refuse("a zero direction")
    return (a[0] / n, a[1] / n, a[2] / n)


def _neg(a: Vec3) -> Vec3:
    return (-a[0], -a[1], -a[2])


# ----------------------------------------------------------------------------- features
@dataclass(frozen=True)
class Feature:
    """A feature nominal's geometry (mm): type (Cylinder, Circle, Plane, Point, Line,
    OppositeParallelLines, OppositeParallelPlanes, or any other QIF type), location,
    normal, axis (a cylinder's or line's direction, the lines' or planes' length vector),
    depth (a pair of planes' depth vector), size (diameter or width), length and depth
    size, internal ("INTERNAL", "EXTERNAL" or "")."""

    qif_id: str
    type: str
    name: str
    location: Vec3 | None = None
    normal: Vec3 | None = None
    axis: Vec3 | None = None
    depth: Vec3 | None = None
    size: float | None = None
    length: float | None = None
    depth_size: float | None = None
    internal: str = ""

    def label(self) -> str:
        return f"{self.type} feature {self.qif_id}"


def _opt_point(doc: QifFile, e: Element | None, what: str) -> Vec3 | None:
    return None if e is None else doc.point(e, what)


def _opt_vector(doc: QifFile, e: Element | None, what: str) -> Vec3 | None:
    return None if e is None else doc.vector(e, what)


def _opt_length(doc: QifFile, e: Element | None, what: str) -> float | None:
    return None if e is None else doc.length(e, pmi=False, what=what)


def read_feature(doc: QifFile, nominal: Element, name: str | None = None) -> Feature:
    """The geometry of a feature nominal (Refuse when what it has is malformed); `name`:
    its item's FeatureName, else the nominal's Name."""
    tag = local(nominal)
    ftype = tag[: -len("FeatureNominal")] if tag.endswith("FeatureNominal") else tag
    qid = nominal.get("id", "").strip()
    name = name or text(nominal, "Name") or ""
    definition = doc.ref(kid(nominal, "FeatureDefinitionId"))
    where = f"feature {qid}"
    internal = (text(definition, "InternalExternal") or "").upper() if definition is not None else ""
    common = {"qif_id": qid, "type": ftype, "name": name, "internal": internal}
    if ftype == "Cylinder":
        return Feature(**common, location=_opt_point(doc, kid(nominal, "Axis", "AxisPoint"), f"{where}'s axis point"),
                       axis=_opt_vector(doc, kid(nominal, "Axis", "Direction"), f"{where}'s axis direction"),
                       size=_opt_length(doc, kid(definition, "Diameter"), f"{where}'s diameter"),
                       length=_opt_length(doc, kid(definition, "Length"), f"{where}'s length"))
    if ftype in ("Circle", "Plane", "Point", "Line"):
        return Feature(**common, location=_opt_point(doc, kid(nominal, "Location"), f"{where}'s location"),
                       normal=_opt_vector(doc, kid(nominal, "Normal"), f"{where}'s normal"),
                       axis=_opt_vector(doc, kid(nominal, "Direction"), f"{where}'s direction"),
                       size=_opt_length(doc, kid(definition, "Diameter"), f"{where}'s diameter"))
    if ftype == "OppositeParallelLines":
        return Feature(**common, location=_opt_point(doc, kid(nominal, "CenterLine", "StartPoint"),
                                                     f"{where}'s centre line"),
                       axis=_opt_vector(doc, kid(nominal, "CenterLine", "Vector"), f"{where}'s centre line"),
                       normal=_opt_vector(doc, kid(nominal, "Normal"), f"{where}'s normal"),
                       size=_opt_length(doc, kid(definition, "Width"), f"{where}'s width"))
    if ftype == "OppositeParallelPlanes":
        return Feature(**common, location=_opt_point(doc, kid(nominal, "CenterPlane", "Point"),
                                                     f"{where}'s centre plane"),
                       normal=_opt_vector(doc, kid(nominal, "CenterPlane", "Normal"), f"{where}'s centre plane"),
                       axis=_opt_vector(doc, kid(nominal, "LengthVector"), f"{where}'s length vector"),
                       depth=_opt_vector(doc, kid(nominal, "DepthVector"), f"{where}'s depth vector"),
                       size=_opt_length(doc, kid(definition, "Width"), f"{where}'s width"),
                       depth_size=_opt_length(doc, kid(definition, "Depth"), f"{where}'s depth"))
    return Feature(**common)


def _need(value: object, feature: Feature, what: str) -> None:
    if value is None:
        raise Refuse(f"{feature.label()} has no {what}")


# ----------------------------------------------------------------------------- the targets
def _nominals(doc: QifFile, refs: Sequence[tuple[str, Element | None]], what: str) -> list[Element]:
    out = []
    for qid, e in refs:
        if e is None:
            raise Refuse(f"its {what} {qid or '(empty)'} is not in the file (or is external)")
        out.append(e)
    return out


def feature_targets(doc: QifFile, row: Row) -> list[list[Element]]:
    """The feature nominals the characteristic applies to, one list per measurement
    (one feature each; a distance's two)."""
    distance = row.stem in ("DistanceBetween", "DistanceFrom")
    found: list[Element] = []
    pairs: list[list[Element]] = []
    element = row.element
    if row.tag.endswith("CharacteristicItem") and kid(element, "FeatureItemIds") is not None:
        for qid, item in doc.refs(kid(element, "FeatureItemIds")):
            if item is None:
                raise Refuse(f"its feature item {qid or '(empty)'} is not in the file (or is external)")
            nominal = doc.ref(kid(item, "FeatureNominalId"))
            if nominal is None:
                raise Refuse(f"feature item {qid}'s nominal {text(item, 'FeatureNominalId')} is not in the file")
            found.append(nominal)
    elif row.nominal is not None:
        for pair in kids(kid(row.nominal, "FeatureNominalPairs")) if kid(row.nominal, "FeatureNominalPairs") \
                is not None else ():
            first, second = kid(pair, "FirstFeature"), kid(pair, "SecondFeature")
            pairs.append(_nominals(doc, [((text(pair, "FirstFeature") or ""), doc.ref(first)),
                                         ((text(pair, "SecondFeature") or ""), doc.ref(second))], "feature"))
        found = _nominals(doc, doc.refs(kid(row.nominal, "FeatureNominalIds")), "feature nominal")
    if pairs:
        return pairs
    origin = _origin(doc, row.nominal) if row.stem == "DistanceFrom" and row.nominal is not None else None
    if origin is not None:
        return [[origin, f] for f in found]
    if not distance:
        return [[f] for f in found]
    if not found:
        return []
    if len(found) != 2:
        raise Refuse(f"a distance among {len(found)} features: ITA measures a distance between two")
    return [found]


def item_names(doc: QifFile, row: Row) -> dict[str, str]:
    """Feature nominal id -> the FeatureName of the row's feature item for it (an item's
    features are named on their items)."""
    names: dict[str, str] = {}
    if row.tag.endswith("CharacteristicItem"):
        for _, item in doc.refs(kid(row.element, "FeatureItemIds")):
            nominal = doc.ref(kid(item, "FeatureNominalId")) if item is not None else None
            name = text(item, "FeatureName") if item is not None else None
            if nominal is not None and name:
                names.setdefault(nominal.get("id", "").strip(), name)
    return names


def _origin(doc: QifFile, nominal: Element) -> Element | None:
    ref = kid(nominal, "OriginReference")
    if ref is None:
        return None
    feature = kid(ref, "FeatureNominalId")
    if feature is not None:
        found = doc.ref(feature)
        if found is None:
            raise Refuse(f"its origin feature {text(ref, 'FeatureNominalId')} is not in the file")
        return found
    datum = doc.ref(kid(ref, "DatumDefinitionId"))
    features = doc.refs(kid(datum, "FeatureNominalIds")) if datum is not None else []
    if not features or features[0][1] is None:
        raise Refuse("its origin is a datum without a feature nominal")
    return features[0][1]


# ----------------------------------------------------------------------------- tolerances
def linear_tolerance(doc: QifFile, row: Row, target: float) -> tuple[float, float]:
    """(lower, upper): the definition's tolerance as signed deviations from `target`, mm."""
    definition = row.definition
    tol = kid(definition, "Tolerance")
    if tol is None:
        non = text(definition, "NonTolerance")
        dims = text(definition, "DimensionType")
        raise Refuse("no tolerance" + (f" (NonTolerance {non})" if non else "") +
                     (f" ({dims.lower().replace('_', ' ')})" if dims else ""))
    source = tol
    ref = kid(tol, "DefinitionId")
    if ref is not None:
        source = doc.ref(ref)
        if source is None:
            raise Refuse(f"its tolerance definition {text(tol, 'DefinitionId')} is not in the file")
    hi_e, lo_e = kid(source, "MaxValue"), kid(source, "MinValue")
    if hi_e is None or lo_e is None:
        raise Refuse("a one-sided tolerance (only a " + ("maximum" if hi_e is not None else "minimum") +
                     "): ITA's specs need both limits")
    hi = doc.length(hi_e, pmi=True, what="upper tolerance")
    lo = doc.length(lo_e, pmi=True, what="lower tolerance")
    if (text(tol, "DefinedAsLimit") or "false").strip().lower() in ("true", "1"):
        hi, lo = hi - target, lo - target
    if not lo < hi:
        raise Refuse(f"its lower tolerance {lo:g} mm is not below its upper {hi:g} mm")
    return lo, hi


def datums(doc: QifFile, definition: Element | None) -> str | None:
    """The datum labels of the definition's datum reference frame in precedence order
    ("A|B|C"; a compound datum's labels joined by '-'); None without a frame."""
    frame = doc.ref(kid(definition, "DatumReferenceFrameId")) if definition is not None else None
    if frame is None:
        return None
    found: list[tuple[int, int, str]] = []
    for n, d in enumerate(kids(kid(frame, "Datums")) if kid(frame, "Datums") is not None else ()):
        labels = []
        for ref in d.iter(q("DatumDefinitionId")):
            definition_ = doc.ref(ref)
            label = text(definition_, "DatumLabel") if definition_ is not None else None
            labels.append(label or (ref.text or "?").strip())
        precedence = text(d, "Precedence", "PrecedenceEnum") or ""
        rank = DATUM_PRECEDENCE.index(precedence) if precedence in DATUM_PRECEDENCE else n
        if labels:
            found.append((rank, n, "-".join(labels)))
    return "|".join(label for _, _, label in sorted(found)) or None


# ----------------------------------------------------------------------------- the mappers
@dataclass(frozen=True)
class Draft:
    """A spec without its id: what one measurement of the characteristic is."""

    kind: K
    feature: str
    point: Vec3
    normal: Vec3
    nominal: float
    lower: float
    upper: float
    datum: str
    direction: Vec3 | None = None
    notes: tuple[str, ...] = ()


@dataclass(frozen=True)
class Context:
    """What every mapper reads: the file, the row, the kind the file states (ita.kind:
    trusted, ITA's own export), the target value (mm) and the datums."""

    doc: QifFile
    row: Row
    stated: K | None
    notes: list[str] = field(default_factory=list)

    def target(self, fallback: float | None = None) -> float:
        e = kid(self.row.nominal, "TargetValue")
        if e is None:
            if fallback is not None:
                self.notes.append("no target value: the feature's size taken")
                return fallback
            raise Refuse("no target value")
        return self.doc.length(e, pmi=True, what="target value")

    def datum(self) -> str:
        stated = self.row.attributes.get("ita.datum") if self.stated is not None else None
        return stated or datums(self.doc, self.row.definition) or "A"

    def pick(self, default: K) -> K:
        return self.stated if self.stated is not None else default


def _name(f: Feature) -> str:
    return f.name or f"F{f.qif_id}"


def _hole(c: Context, f: Feature) -> tuple[Vec3, Vec3, float | None]:
    """(centre on the entry face, outward normal, diameter) of a hole feature."""
    if f.type == "Point" and c.stated is not None and f.location is not None and f.normal is not None:
        return f.location, f.normal, None
    if f.type not in ("Cylinder", "Circle"):
        raise Refuse(f"on a {f.label()}: ITA measures holes (internal cylinders and circles)")
    if f.internal == "EXTERNAL":
        raise Refuse(f"on an external {f.type.lower()} (a boss or pin): ITA measures holes")
    if f.type == "Cylinder":
        _need(f.location, f, "axis point")
        _need(f.axis, f, "axis direction")
        assert f.location is not None and f.axis is not None
        point, normal = f.location, _neg(f.axis)
        if f.length and f.axis[2] > normal[2]:  # the far end faces up more: the entry
            point, normal = _add(f.location, f.axis, f.length), f.axis
        return point, normal, f.size
    _need(f.location, f, "location")
    _need(f.normal, f, "normal")
    assert f.location is not None and f.normal is not None
    return f.location, f.normal, f.size


def _diameter(c: Context, fs: Sequence[Feature]) -> Draft:
    point, normal, size = _hole(c, fs[0])
    target = c.target(size)
    lo, hi = linear_tolerance(c.doc, c.row, target)
    return Draft(K.HOLE_DIAMETER, _name(fs[0]), point, normal, target, lo, hi, c.datum())


def _position(c: Context, fs: Sequence[Feature]) -> Draft:
    d = c.row.definition
    shape = kid(d, "ZoneShape")
    zone = local(next(kids(shape), None)) if shape is not None and next(kids(shape), None) is not None else ""
    if zone != "DiametricalZone":
        raise Refuse(f"a position with a {zone or 'unstated'} zone: ITA's hole_position is a diametrical zone")
    point, normal, _ = _hole(c, fs[0])
    tol = c.doc.length(kid(d, "ToleranceValue"), pmi=True, what="position tolerance")
    if not tol > 0:
        raise Refuse(f"a position tolerance of {tol:g} mm")
    condition = (text(d, "MaterialCondition") or "NONE").upper()
    if condition not in ("NONE", "REGARDLESS"):
        c.notes.append(f"material condition {condition} not applied (decided regardless of feature size)")
    if kid(d, "SecondCompositeSegmentPositionDefinition") is not None:
        c.notes.append("composite position: only its first segment")
    return Draft(K.HOLE_POSITION, _name(fs[0]), point, normal, 0.0, 0.0, tol, c.datum())


def _thickness_kind(c: Context, normal: Vec3) -> K:
    return c.pick(K.WEB_THICKNESS if abs(normal[2]) >= WEB_COS else K.FLANGE_THICKNESS)


def _thickness(c: Context, fs: Sequence[Feature]) -> Draft:
    f = fs[0]
    if f.type in ("Plane", "Point"):
        _need(f.location, f, "location")
        _need(f.normal, f, "normal (the side measured from)")
        assert f.location is not None and f.normal is not None
        point, normal = f.location, f.normal
    elif f.type == "OppositeParallelPlanes" and f.internal != "INTERNAL":
        _need(f.location, f, "centre plane")
        _need(f.normal, f, "centre plane normal")
        _need(f.size, f, "width")
        assert f.location is not None and f.normal is not None and f.size is not None
        normal = f.normal if f.normal[2] >= 0 else _neg(f.normal)
        point = _add(f.location, normal, f.size / 2)
    else:
        raise Refuse(f"a thickness of a {f.label()}: ITA measures thickness at a face")
    target = c.target()
    lo, hi = linear_tolerance(c.doc, c.row, target)
    return Draft(_thickness_kind(c, normal), _name(f), point, normal, target, lo, hi, c.datum())


def _height(c: Context, fs: Sequence[Feature]) -> Draft:
    f = fs[0]
    if f.type != "Plane":
        raise Refuse(f"a height of a {f.label()}: ITA measures the height of a top face")
    _need(f.location, f, "location")
    _need(f.normal, f, "normal")
    assert f.location is not None and f.normal is not None
    target = c.target()
    lo, hi = linear_tolerance(c.doc, c.row, target)
    if c.stated is None:
        if _dot(f.normal, UP) < TOP_COS:
            raise Refuse("a height of a face not facing +Z: ITA's heights are of top faces above datum A")
        if abs(f.location[2] - target) > max(hi - lo, 0.01):
            raise Refuse(f"a height of {target:g} mm whose face lies {f.location[2]:g} mm above datum A "
                         "(the XY plane): not a height above datum A")
    return Draft(c.pick(K.STIFFENER_HEIGHT), _name(f), f.location, f.normal, target, lo, hi, c.datum())


def _width(c: Context, fs: Sequence[Feature]) -> Draft:
    f = fs[0]
    if f.internal == "INTERNAL":
        raise Refuse(f"the width of a slot ({f.label()}, internal): ITA measures widths of ribs and flange caps")
    if f.type == "OppositeParallelLines":
        _need(f.location, f, "centre line")
        _need(f.axis, f, "centre line direction")
        _need(f.normal, f, "normal")
        assert f.location is not None and f.axis is not None and f.normal is not None
        point, normal, direction = f.location, f.normal, _unit(_cross(f.axis, f.normal))
    elif f.type == "OppositeParallelPlanes":
        _need(f.location, f, "centre plane")
        _need(f.normal, f, "centre plane normal")
        if f.depth is None or f.depth_size is None:
            raise Refuse(f"the width of {f.label()} without a depth vector and depth: its top face cannot be "
                         "placed")
        assert f.location is not None and f.normal is not None
        point, normal, direction = _add(f.location, f.depth, f.depth_size / 2), f.depth, f.normal
        c.notes.append("point: the centre of the pair's top, half its depth from its centre")
    else:
        raise Refuse(f"a width of a {f.label()}: ITA measures widths across opposite parallel lines or planes")
    target = c.target(f.size)
    lo, hi = linear_tolerance(c.doc, c.row, target)
    return Draft(c.pick(K.STIFFENER_WIDTH), _name(f), point, normal, target, lo, hi, c.datum(), direction)


def _edge(c: Context, hole: Feature, edge: Feature, target: float, lo: float, hi: float) -> Draft:
    centre, axis, _ = _hole(c, hole)
    _need(edge.location, edge, "location")
    assert edge.location is not None
    if edge.type == "Plane":
        _need(edge.normal, edge, "normal")
        assert edge.normal is not None
        if abs(_dot(edge.normal, axis)) > 1 - PARALLEL_COS:
            raise Refuse(f"a distance from a hole to a plane not parallel to its axis ({edge.label()})")
        gap = _dot(_sub(edge.location, centre), edge.normal)
        direction = edge.normal if gap >= 0 else _neg(edge.normal)
        distance = abs(gap)
    else:
        _need(edge.axis, edge, "direction")
        assert edge.axis is not None
        if abs(_dot(edge.axis, axis)) > 1 - PARALLEL_COS:
            raise Refuse(f"a distance from a hole to a line not across its axis ({edge.label()})")
        offset = _sub(edge.location, centre)
        across = _sub(offset, (edge.axis[0] * _dot(offset, edge.axis), edge.axis[1] * _dot(offset, edge.axis),
                               edge.axis[2] * _dot(offset, edge.axis)))
        across = _sub(across, (axis[0] * _dot(across, axis), axis[1] * _dot(across, axis),
                               axis[2] * _dot(across, axis)))
        distance = math.sqrt(_dot(across, across))
        direction = _unit(across)
    if c.stated is None and abs(distance - target) > max(hi - lo, 0.01 * target):
        raise Refuse(f"the hole's centre lies {distance:g} mm from {edge.label()}, not the target {target:g} mm: "
                     "not a centre-to-edge distance")
    return Draft(K.EDGE_DISTANCE, _name(hole), centre, axis, target, lo, hi, c.datum(), direction)


def _faces_thickness(c: Context, a: Feature, b: Feature, target: float, lo: float, hi: float) -> Draft:
    for f in (a, b):
        _need(f.location, f, "location")
        _need(f.normal, f, "normal")
    assert a.location is not None and a.normal is not None and b.location is not None and b.normal is not None
    cos = _dot(a.normal, b.normal)
    if abs(cos) < PARALLEL_COS:
        raise Refuse(f"a distance between faces that are not parallel ({a.label()}, {b.label()})")
    if cos > 0:
        raise Refuse("a step between two faces facing the same way: ITA's heights are of a top face above "
                     "datum A")
    gap = _dot(_sub(b.location, a.location), a.normal)
    if gap > 0:
        raise Refuse("a distance across a gap between facing faces (a slot or pocket width): ITA measures no "
                     "internal width")
    face = a if a.normal[2] >= b.normal[2] else b
    assert face.location is not None and face.normal is not None
    if c.stated is None and abs(abs(gap) - target) > max(hi - lo, 0.01 * target):
        raise Refuse(f"the faces lie {abs(gap):g} mm apart, not the target {target:g} mm")
    return Draft(_thickness_kind(c, face.normal), _name(face), face.location, face.normal, target, lo, hi,
                 c.datum())


HOLES = ("Cylinder", "Circle")


def _distance(c: Context, fs: Sequence[Feature]) -> Draft:
    a, b = fs
    target = c.target()
    lo, hi = linear_tolerance(c.doc, c.row, target)
    holes = [f for f in (a, b) if f.type in HOLES or (f.type == "Point" and c.stated is K.EDGE_DISTANCE)]
    others = [f for f in (a, b) if f not in holes]
    if len(holes) == 1 and others[0].type in ("Plane", "Line"):
        return _edge(c, holes[0], others[0], target, lo, hi)
    if a.type == b.type == "Plane":
        return _faces_thickness(c, a, b, target, lo, hi)
    raise Refuse(f"a distance between a {a.type} and a {b.type} feature: ITA measures a hole's distance to an "
                 "edge and the distance between the two faces of a wall")


MAPPERS: dict[str, Callable[[Context, Sequence[Feature]], Draft]] = {
    "Diameter": _diameter, "Position": _position, "Thickness": _thickness, "Height": _height, "Width": _width,
    "DistanceBetween": _distance, "DistanceFrom": _distance,
}


# ----------------------------------------------------------------------------- a row
@dataclass(frozen=True)
class Mapped:
    row: Row
    drafts: tuple[Draft, ...]


@dataclass(frozen=True)
class Refused:
    row: Row
    reason: str


def refusal_of_type(stem: str) -> str:
    """Why ITA takes no characteristic of QIF type `stem`."""
    family = FAMILIES.get(stem)
    what = f"{family} ({_words(stem)})" if family else f"a {_words(stem)} characteristic"
    return f"{what}: ITA measures thicknesses, hole diameters and positions, edge distances, heights and widths"


def _words(stem: str) -> str:
    out = "".join(f" {ch.lower()}" if ch.isupper() else ch for ch in stem).strip()
    return out


def map_row(doc: QifFile, row: Row, *, expand_patterns: bool = False) -> Mapped | Refused:
    """The specs of one characteristic, or why there are none."""
    try:
        if row.missing:
            raise Refuse(row.missing)
        if row.stem not in MAPPERS:
            raise Refuse(refusal_of_type(row.stem))
        said = row.attributes.get(KIND_ATTRIBUTE)
        stated = next((k for k in KINDS_OF[row.stem] if k.value == said), None)
        targets = feature_targets(doc, row)
        names = item_names(doc, row)
        if not targets:
            raise Refuse("no feature: nothing says where it is")
        if len(targets) > 1 and not expand_patterns:
            raise Refuse(f"applies to {len(targets)} features (a pattern): ITA's spec is of one; "
                         "--expand-patterns takes one spec per feature")
        drafts = []
        for n, group in enumerate(targets):
            context = Context(doc, row, stated)
            if said and stated is None:
                context.notes.append(f"its {KIND_ATTRIBUTE} {said!r} is no kind of a {row.stem} characteristic")
            try:
                features = [read_feature(doc, e, names.get(e.get("id", "").strip())) for e in group]
                draft = MAPPERS[row.stem](context, features)
            except Refuse as exc:
                raise Refuse(f"feature {n + 1} of {len(targets)}: {exc.reason}" if len(targets) > 1
                             else exc.reason) from None
            drafts.append(Draft(**{**draft.__dict__, "notes": tuple(context.notes)}))
        return Mapped(row, tuple(drafts))
    except Refuse as exc:
        return Refused(row, exc.reason)
    except (ArithmeticError, AttributeError, IndexError, KeyError, TypeError, ValueError) as exc:
        # a file of a shape no rule foresaw: the characteristic is refused, never dropped
        return Refused(row, f"ITA cannot read it ({type(exc).__name__}: {exc})")
