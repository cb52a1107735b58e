"""A run's results as one QIF 3.0 document (ISO 23952), for a quality system to take.

    record = gather(archive, run_id)             # RunRecord: run, results, specs, verdict, tools
    root = results_document(record)              # the QIF tree (lxml)
    export_run(archive, run_id, "run.qif")       # both, written atomically

What the document holds (ids are numbered from 1 in this order):

- the header (ITA and its version), ISO 14253-1 as the standard the decisions follow,
  ITA as the inspection software; file units mm and degree;
- the datums and datum reference frames of the position specs ("A|B|C": A primary,
  B secondary, C tertiary);
- one measurement device per tool the run used (the SLRA, the ultrasonic probes);
- the part (its name);
- features: per spec the feature ITA measures there, at the spec's point (see
  :mod:`ita.qif.kinds`): its definition (size where it has one), its nominal location and
  direction, and an item; specs of one ITA feature at the same point share it (a hole's
  diameter and position);
- characteristics: per spec a definition with its tolerance (shared by specs of the
  same type and tolerance), a nominal with the target value, and an item named by the
  spec id with its kind (attribute ``ita.kind``), features and devices;
- results: one measurement per result, its value with ``combinedUncertainty`` (the
  standard uncertainty u; the expanded U = k u and k are attributes), its status
  (conforms PASS, does not conform FAIL, uncertain INDETERMINATE, not done and cannot be
  done NOT_ANALYZED, with the reason as its description), and the overall
  InspectionStatus from the part's verdict (accept PASS, reject FAIL, incomplete
  UNKNOWN); the actual component (serial number when the run has one) and the
  traceability: run id as report number, start and end, the operator when the run has
  one, the program revision (ITA's version and the digest of the run's plan).

``meanError`` is not written: the archive keeps no estimate of a remaining bias (the
SLRA's values are corrected by its calibration's bias before they are recorded).
"""

from __future__ import annotations

import math
import re
import uuid
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from datetime import datetime, timezone
from pathlib import Path
from typing import Any

from ita import __version__
from ita.archive.model import RunInfo, StoredResult
from ita.archive.store import Archive
from ita.errors import InputError, ItaError
from ita.files.atomic import output_path, write_atomic
from ita.qif.kinds import CHARACTERISTICS, KIND_ATTRIBUTE, UNKNOWN_KIND
from ita.qif.tree import (
    NS,
    VERSION,
    XSI,
    Element,
    decimal,
    el,
    ids,
    listing,
    to_bytes,
    triple,
)
from ita.report.data import Verdict, collect, status_of, summarize
from ita.specs.io import read_spec_table
from ita.specs.model import MeasurementKind, MeasurementSpec, Tool, Vec3
from ita.workcell.load import load_workcell

#: a result's status -> the QIF characteristic status
STATUS = {"conforms": "PASS", "does_not_conform": "FAIL", "uncertain": "INDETERMINATE",
          "not_done": "NOT_ANALYZED", "cannot_be_done": "NOT_ANALYZED"}
#: the part's verdict -> the QIF inspection status
INSPECTION_STATUS = {Verdict.ACCEPT: "PASS", Verdict.REJECT: "FAIL", Verdict.INCOMPLETE: "UNKNOWN"}
PRECEDENCE = ("PRIMARY", "SECONDARY", "TERTIARY", "QUATERNARY", "QUINARY", "SENARY")
DEVICE_DESCRIPTIONS = {
    Tool.SLRA: "scanning laser range assembly (SLRA) on the arm: range images measured by Vision",
    Tool.ULTRASONIC: "ultrasonic thickness gauge, contact probe bent 45 degrees",
    Tool.ULTRASONIC_BENT: "ultrasonic thickness gauge, contact probe bent 90 degrees",
}
#: run settings that name the plan a run followed, the first found is its revision
PLAN_DIGESTS = ("plan_digest", "sequence_digest", "mkb_digest")
_NMTOKEN_BAD = re.compile(r"[^\w.\-:]")


@dataclass(frozen=True)
class RunRecord:
    """What a QIF results document says of a run.

    specs: the part's specs by id (their normals, directions, features and datums; a
    result whose spec is not here, or differs in kind or point, is written from the
    result alone, its feature a point); tools: tool name -> class (for the devices'
    descriptions); created: when the document is made (ISO 8601, UTC).
    """

    run: RunInfo
    results: tuple[StoredResult, ...]
    specs: Mapping[str, MeasurementSpec]
    verdict: Verdict
    verdict_reason: str
    tools: Mapping[str, Tool] = field(default_factory=dict)
    version: str = __version__
    created: str = ""
    #: the part's last registration on its datums (an ``alignment`` event's payload), if any
    alignment: Mapping[str, Any] | None = None


@dataclass(frozen=True)
class Shape:
    """A feature as ITA writes it: a QIF feature type (Point, Circle, Plane,
    OppositeParallelLines), its name (the ITA feature id), location (mm) and direction;
    size: a circle's diameter or the lines' width; along: the lines' direction."""

    type: str
    name: str
    location: Vec3
    normal: Vec3 | None = None
    size: float | None = None
    along: Vec3 | None = None


@dataclass(frozen=True)
class ExportSummary:
    """What `export_run` wrote: the file, the run, how many results, the inspection
    status, and warnings (specs not found ...)."""

    path: Path
    run_id: str
    results: int
    inspection_status: str
    warnings: tuple[str, ...] = ()


# ------------------------------------------------------------------------ the features
def _cross(a: Vec3, b: Vec3) -> Vec3:
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


def _near(a: Sequence[float], b: Sequence[float], tol: float = 1e-6) -> bool:
    return all(abs(x - y) <= tol for x, y in zip(a, b))


def shapes(spec: MeasurementSpec, hole_diameters: Mapping[str, float]) -> list[Shape]:
    """The features a spec is measured on (the first its own; an edge distance's second
    is the edge).  A hole is a circle of its diameter (from the hole_diameter spec of its
    feature), a point where no spec gives the diameter."""
    k, p, n, d = spec.kind, spec.point, spec.normal, spec.direction
    if k in (MeasurementKind.HOLE_DIAMETER, MeasurementKind.HOLE_POSITION, MeasurementKind.EDGE_DISTANCE):
        diameter = spec.nominal if k is MeasurementKind.HOLE_DIAMETER else hole_diameters.get(spec.feature)
        hole = Shape("Circle", spec.feature, p, n, diameter) if diameter else Shape("Point", spec.feature, p, n)
        if k is MeasurementKind.EDGE_DISTANCE and d is not None:
            edge = tuple(c + spec.nominal * dc for c, dc in zip(p, d))
            return [hole, Shape("Plane", f"{spec.feature} edge", (edge[0], edge[1], edge[2]), d)]
        return [hole]
    if k in (MeasurementKind.FLANGE_HEIGHT, MeasurementKind.STIFFENER_HEIGHT):
        return [Shape("Plane", spec.feature, p, n)]
    if k in (MeasurementKind.FLANGE_WIDTH, MeasurementKind.STIFFENER_WIDTH) and d is not None:
        return [Shape("OppositeParallelLines", spec.feature, p, n, spec.nominal, _cross(n, d))]
    return [Shape("Point", spec.feature, p, n)]


def _spec_of(r: StoredResult, specs: Mapping[str, MeasurementSpec]) -> MeasurementSpec | None:
    """The part's spec of result `r` as the run measured it: the result's nominal and
    tolerance with the spec's normal, direction, feature and datum; None when the part's
    spec is missing or is of another kind or point now."""
    spec = specs.get(r.spec_id)
    if spec is None or spec.kind.value != r.kind or (r.point is not None and not _near(spec.point, r.point)):
        return None
    return MeasurementSpec(spec.id, spec.kind, spec.feature, r.point or spec.point, spec.normal, r.nominal,
                           r.lower, r.upper, spec.datum, spec.direction, spec.note)


# ------------------------------------------------------------------------ the builder
class _Ids:
    def __init__(self) -> None:
        self.last = 0

    def __call__(self) -> int:
        self.last += 1
        return self.last


def _num(x: float) -> str:
    """A number for a QIF list of doubles."""
    return f"{x:.9g}"


def _token(text: str) -> str:
    """`text` as an xs:token (whitespace collapsed)."""
    return " ".join(str(text).split())


def _label(text: str) -> str:
    """A datum label as an xs:NMTOKEN."""
    return _NMTOKEN_BAD.sub("_", text.strip()) or "_"


def _time(epoch: float) -> str:
    return datetime.fromtimestamp(epoch, timezone.utc).isoformat(timespec="seconds")


def _attributes(*pairs: tuple[str, str, str]) -> Element | None:
    """``<Attributes>`` of (element, name, value) triples: AttributeStr or AttributeD1."""
    if not pairs:
        return None
    return listing("Attributes", (el(kind, name=name, value=value) for kind, name, value in pairs))


class _Document:
    """Builds the sections of one results document; `root()` puts them in schema order."""

    def __init__(self, record: RunRecord) -> None:
        self.r = record
        self.new = _Ids()
        self.standard = self.new()
        self.software = self.new()
        self.datums: dict[str, int] = {}
        self.frames: dict[str, int] = {}
        self.devices: dict[str, int] = {}
        self.part = self.new()
        self.feature_defs: dict[tuple[object, ...], tuple[int, Element]] = {}
        self.features: dict[tuple[object, ...], tuple[int, int]] = {}
        self.feature_nominals: list[Element] = []
        self.feature_items: list[Element] = []
        self.char_defs: dict[tuple[object, ...], tuple[int, Element]] = {}
        self.char_nominals: list[Element] = []
        self.char_items: dict[str, int] = {}
        self.char_item_elements: list[Element] = []
        self.measurements: list[Element] = []
        self.fallbacks: list[str] = []
        # hole feature id -> its nominal diameter, from the part's hole_diameter specs
        self.hole_diameters = {s.feature: s.nominal for s in record.specs.values()
                               if s.kind is MeasurementKind.HOLE_DIAMETER}

    # -- references -------------------------------------------------------------
    def frame(self, datum: str) -> int:
        """The datum reference frame of `datum` ("A|B|C"), made on first use."""
        key = "|".join(_label(x) for x in datum.split("|") if x.strip()) or "A"
        if key not in self.frames:
            for label in key.split("|"):
                self.datums.setdefault(label, self.new())
            self.frames[key] = self.new()
        return self.frames[key]

    def device(self, tool: str | None) -> int | None:
        if not tool:
            return None
        if tool not in self.devices:
            self.devices[tool] = self.new()
        return self.devices[tool]

    def feature(self, shape: Shape) -> int:
        """The feature item of `shape` (its definition and nominal made on first use)."""
        key = (shape.type, shape.name, shape.location, shape.normal, shape.size, shape.along)
        if key in self.features:
            return self.features[key][1]
        def_key = (shape.type, shape.size)
        if def_key not in self.feature_defs:
            fid = self.new()
            if shape.type == "Circle":
                body = [el("InternalExternal", "INTERNAL"), el("Diameter", decimal(shape.size or 0.0))]
            elif shape.type == "OppositeParallelLines":
                body = [el("InternalExternal", "EXTERNAL"), el("Width", decimal(shape.size or 0.0)),
                        el("EndType", el("SlotEndEnum", "UNDEFINED"))]
            else:
                body = []
            self.feature_defs[def_key] = (fid, el(f"{shape.type}FeatureDefinition", *body, id=str(fid)))
        def_id = self.feature_defs[def_key][0]
        nid, iid = self.new(), self.new()
        if shape.type == "OppositeParallelLines":
            assert shape.along is not None and shape.normal is not None
            geometry = [el("CenterLine", el("StartPoint", triple(shape.location)), el("Vector", triple(shape.along))),
                        el("Normal", triple(shape.normal))]
        else:
            geometry = [el("Location", triple(shape.location)),
                        None if shape.normal is None else el("Normal", triple(shape.normal))]
        self.feature_nominals.append(el(f"{shape.type}FeatureNominal", el("Name", _token(shape.name)),
                                        el("FeatureDefinitionId", str(def_id)), *geometry, id=str(nid)))
        self.feature_items.append(el(f"{shape.type}FeatureItem", el("FeatureNominalId", str(nid)),
                                     el("FeatureName", _token(shape.name)),
                                     el("DeterminationMode", el("Checked")), id=str(iid)))
        self.features[key] = (nid, iid)
        return iid

    def nominal_of(self, item: int) -> int:
        return next(n for n, i in self.features.values() if i == item)

    # -- characteristics -----------------------------------------------------------
    def characteristic(self, r: StoredResult, spec: MeasurementSpec | None, tools: Sequence[str]) -> int:
        """The characteristic item of the spec of result `r` (made on first use)."""
        if r.spec_id in self.char_items:
            return self.char_items[r.spec_id]
        kind = spec.kind if spec is not None else _kind(r.kind)
        stem = CHARACTERISTICS[kind] if kind is not None else UNKNOWN_KIND
        datum = spec.datum if spec is not None else "A"
        if spec is not None:
            feature_items = [self.feature(s) for s in shapes(spec, self.hole_diameters)]
        else:
            self.fallbacks.append(r.spec_id)
            feature_items = [] if r.point is None else [self.feature(Shape("Point", r.spec_id, r.point))]
        # the definition: the tolerance (shared by specs of one type and tolerance)
        if stem == "Position":
            drf = self.frame(datum)
            def_key: tuple[object, ...] = (stem, r.nominal + r.upper, drf)
            body = [el("ToleranceValue", decimal(r.nominal + r.upper)), el("DatumReferenceFrameId", str(drf)),
                    el("MaterialCondition", "NONE"), el("ZoneShape", el("DiametricalZone"))]
        else:
            def_key = (stem, r.lower, r.upper, None if kind is not None else r.kind)
            body = [el("Tolerance", el("MaxValue", decimal(r.upper)), el("MinValue", decimal(r.lower)),
                       el("DefinedAsLimit", "false"))]
            if kind is None:
                body.append(el("WhatToMeasure", _token(r.kind or "a value of unknown kind")))
        if def_key not in self.char_defs:
            did = self.new()
            self.char_defs[def_key] = (did, el(f"{stem}CharacteristicDefinition", *body, id=str(did)))
        did = self.char_defs[def_key][0]
        # the nominal: the target value on the features
        nid, iid = self.new(), self.new()
        nominal_features = [self.nominal_of(i) for i in feature_items]
        parts: list[Element | None] = [el("CharacteristicDefinitionId", str(did))]
        if stem == "DistanceBetween":
            parts += [el("Name", _token(r.spec_id)), el("TargetValue", decimal(r.nominal))]
            if len(nominal_features) == 2:
                parts.append(listing("FeatureNominalPairs", [el("FeaturePair", el("FirstFeature", str(nominal_features[0])),
                                                                el("SecondFeature", str(nominal_features[1])))]))
            if spec is not None and spec.direction is not None:
                parts.append(el("AnalysisVector", triple(spec.direction)))
            parts.append(el("AnalysisMode", "ONEDIMENSIONAL" if spec is not None and spec.direction else
                            "THREEDIMENSIONAL"))
        else:
            if nominal_features:
                parts.append(ids("FeatureNominalIds", nominal_features))
            parts.append(el("Name", _token(r.spec_id)))
            if stem != "Position":
                parts.append(el("TargetValue", decimal(r.nominal)))
        self.char_nominals.append(el(f"{stem}CharacteristicNominal", *parts, id=str(nid)))
        # the item: the spec id, its kind (and datums where no frame carries them)
        extra = [("AttributeStr", KIND_ATTRIBUTE, kind.value)] if kind is not None else []
        if stem != "Position":
            extra.append(("AttributeStr", "ita.datum", datum))
        devices = [d for d in (self.device(t) for t in tools) if d is not None]
        self.char_item_elements.append(el(
            f"{stem}CharacteristicItem", _attributes(*extra), el("Name", _token(r.spec_id)),
            el("CharacteristicDesignator", el("Designator", _token(r.spec_id))),
            ids("FeatureItemIds", feature_items) if feature_items else None,
            ids("MeasurementDeviceIds", devices) if devices else None,
            el("CharacteristicNominalId", str(nid)), id=str(iid)))
        self.char_items[r.spec_id] = iid
        return iid

    def measurement(self, r: StoredResult, item: int, component: int) -> Element:
        spec_kind = _kind(r.kind)
        stem = CHARACTERISTICS[spec_kind] if spec_kind is not None else UNKNOWN_KIND
        status = STATUS[status_of(r)]
        device = self.device(r.tool)
        extra: list[tuple[str, str, str]] = []
        value = None
        if r.value is not None and r.u is not None:
            value = el("Value", decimal(r.value), combinedUncertainty=decimal(r.u))
            extra = [("AttributeD1", "expandedUncertainty", decimal(r.k * r.u)),
                     ("AttributeD1", "coverageFactor", decimal(r.k))]
        reason = r.reason or ("" if r.decision is not None else status_of(r).replace("_", " "))
        return el(f"{stem}CharacteristicMeasurement", _attributes(*extra),
                  el("Description", reason) if reason else None,
                  el("Status", el("CharacteristicStatusEnum", status)),
                  el("CharacteristicItemId", str(item)),
                  el("TimeStamp", _time(r.wall_time)) if r.wall_time and math.isfinite(r.wall_time) else None,
                  el("ActualComponentId", str(component)),
                  ids("MeasurementDeviceIds", [device]) if device is not None else None,
                  value, id=str(self.new()))

    # -- the whole -----------------------------------------------------------------
    def root(self) -> Element:
        r, run = self.r, self.r.run
        specs = {res.spec_id: _spec_of(res, r.specs) for res in r.results}
        tools_of: dict[str, list[str]] = {}
        for res in r.results:
            if res.tool and res.tool not in tools_of.setdefault(res.spec_id, []):
                tools_of[res.spec_id].append(res.tool)
        items = [self.characteristic(res, specs[res.spec_id], tools_of.get(res.spec_id, [])) for res in r.results]
        results_id, component = self.new(), self.new()
        self.measurements = [self.measurement(res, item, component) for res, item in zip(r.results, items)]
        status = INSPECTION_STATUS[r.verdict]
        settings = run.settings
        serial = _setting(settings, "serial", "serial_number")
        operator = _setting(settings, "operator")
        digest = _setting(settings, *PLAN_DIGESTS)
        digest_name = next((k for k in PLAN_DIGESTS if settings.get(k)), "")
        version_text = f"ita {r.version}" + (f"; {digest_name} {digest}" if digest else "")
        traceability = el(
            "InspectionTraceability",
            el("ReportNumber", run.id),
            el("InspectionStart", run.created) if run.created else None,
            el("InspectionEnd", run.ended) if run.ended else None,
            el("InspectionSoftwareItems", ids("InspectionProgramExecutionSoftware", [self.software])),
            el("InspectionProgram", el("File", el("Name", _token(f"ITA inspection program of part {run.part}")),
                                       el("Version", _token(version_text))),
               el("FormalStandardId", str(self.standard)), el("Author", el("Name", "ITA prepare"))),
            el("InspectionOperator", el("Name", _token(operator))) if operator else None,
            el("ReportPreparationDate", r.created) if r.created else None,
            _attributes(("AttributeStr", "ita.run", run.id), ("AttributeStr", "ita.version", r.version),
                        *([("AttributeStr", f"ita.{digest_name}", digest)] if digest else []),
                        ("AttributeStr", "ita.verdict", r.verdict.value),
                        ("AttributeStr", "ita.verdict_reason", r.verdict_reason),
                        *([("AttributeStr", "ita.alignment", str(r.alignment.get("line", "")))]
                          if r.alignment else [])))
        instance = uuid.uuid5(uuid.NAMESPACE_URL, f"ita:run:{run.id}:{len(r.results)}:"
                              f"{max((x.seq for x in r.results), default=0)}")
        results = el(
            "Results",
            listing("MeasurementResultsSet", [el(
                "MeasurementResults",
                el("ThisResultsInstanceQPId", str(instance)),
                el("MeasuredCharacteristics", listing("CharacteristicMeasurements", self.measurements))
                if self.measurements else None,
                self._alignment(),
                el("InspectionStatus", el("InspectionStatusEnum", status)),
                ids("ActualComponentIds", [component]), id=str(results_id))]),
            listing("ActualComponentSets", [listing("ActualComponentSet", [el(
                "ActualComponent",
                el("SerialNumber", serial) if serial else None,
                el("Status", el("InspectionStatusEnum", status)),
                el("Traceability", el("InspectionStart", run.created) if run.created else None,
                   el("InspectionEnd", run.ended) if run.ended else None,
                   el("InspectionOperator", el("Name", _token(operator))) if operator else None,
                   ids("MeasurementDeviceIds", list(self.devices.values())) if self.devices else None),
                id=str(component))])]),
            traceability)
        return self._assemble(results, instance)

    def _alignment(self) -> Element | None:
        """The part's registration as an actual transform: from the part's nominal frame
        to where it was found (X = R x + Origin, mm), named after the datums it used."""
        a = self.r.alignment
        if not a:
            return None
        turn = math.radians(float(a.get("turn_deg", 0.0)))
        c, sn = math.cos(turn), math.sin(turn)
        shift = [float(x) for x in a.get("shift_mm", (0.0, 0.0, 0.0))]
        vec = " ".join
        return listing("ActualTransforms", [el(
            "Transform",
            el("Rotation", el("XDirection", vec(_num(x) for x in (c, sn, 0.0))),
               el("YDirection", vec(_num(x) for x in (-sn, c, 0.0))), el("ZDirection", "0 0 1")),
            el("Origin", vec(_num(x) for x in shift)),
            el("Name", _token(f"part registered on datums {', '.join(str(d) for d in a.get('datums', ()))}")),
            id=str(self.new()))])

    def _assemble(self, results: Element, instance: uuid.UUID) -> Element:
        r, run = self.r, self.r.run
        root = el("QIFDocument", versionQIF=VERSION, idMax="0")
        root.set(f"{{{XSI}}}schemaLocation", f"{NS} QIFApplications/QIFDocument.xsd")
        root.append(el("QPId", str(uuid.uuid5(instance, "document"))))
        root.append(el("Header", el("Application", el("Name", "ITA"), el("Organization", "ITA project")),
                       el("Description", f"Inspection results of run {run.id} of part {run.part}"),
                       el("Scope", "Results")))
        root.append(listing("StandardsDefinitions", [el(
            "Standard", el("Organization", el("StandardsOrganizationEnum", "ISO")), el("Designator", "14253-1"),
            el("Title", "Decision rules for verifying conformity or nonconformity with specifications"),
            el("Description", "ITA decides each characteristic by this rule with the expanded uncertainty U "
                              "(conforms, does not conform, uncertain)"), id=str(self.standard))]))
        root.append(listing("SoftwareDefinitions", [el(
            "Software", el("VendorName", "ITA project"), el("ApplicationName", "ITA"), el("Version", r.version),
            el("Description", "Intelligent Task Automation: planned, simulated, autonomous dimensional inspection"),
            id=str(self.software))]))
        root.append(el("FileUnits", el("PrimaryUnits",
                                       el("AngularUnit", el("SIUnitName", "radian"), el("UnitName", "degree"),
                                          el("UnitConversion", el("Factor", decimal(math.pi / 180)))),
                                       el("LinearUnit", el("SIUnitName", "meter"), el("UnitName", "mm"),
                                          el("UnitConversion", el("Factor", "0.001"))))))
        if self.datums:
            root.append(listing("DatumDefinitions", [el("DatumDefinition", el("DatumLabel", label), id=str(i))
                                                     for label, i in self.datums.items()]))
            root.append(listing("DatumReferenceFrames", [el(
                "DatumReferenceFrame", listing("Datums", [el(
                    "Datum", el("SimpleDatum", el("DatumDefinitionId", str(self.datums[label])),
                                el("MaterialModifier", "NONE"), el("ReferencedComponent", "NOMINAL")),
                    el("Precedence", el("PrecedenceEnum", PRECEDENCE[n]) if n < len(PRECEDENCE)
                       else el("OtherPrecedence", str(n + 1))))
                    for n, label in enumerate(key.split("|"))]), id=str(i)) for key, i in self.frames.items()]))
        if self.devices:
            root.append(el("MeasurementResources", listing("MeasurementDevices", [
                el("MeasurementDevice", el("Name", _token(name)), el("Description", _device_text(name, r.tools)),
                   id=str(i)) for name, i in self.devices.items()])))
        root.append(el("Product", listing("PartSet", [el("Part", el("ModelNumber", run.part), id=str(self.part),
                                                             label=run.part)])))
        if self.feature_nominals:
            root.append(el("Features",
                           listing("FeatureDefinitions", [e for _, e in self.feature_defs.values()]),
                           listing("FeatureNominals", self.feature_nominals),
                           listing("FeatureItems", self.feature_items)))
        if self.char_item_elements:
            root.append(el("Characteristics", el("FormalStandardId", str(self.standard)),
                           listing("CharacteristicDefinitions", [e for _, e in self.char_defs.values()]),
                           listing("CharacteristicNominals", self.char_nominals),
                           listing("CharacteristicItems", self.char_item_elements)))
        root.append(results)
        root.set("idMax", str(self.new.last))
        return root


def _kind(text: str | None) -> MeasurementKind | None:
    try:
        return MeasurementKind(text) if text is not None else None
    except ValueError:
        return None


def _setting(settings: Mapping[str, object], *names: str) -> str:
    for name in names:
        value = settings.get(name)
        if value not in (None, ""):
            return str(value)
    return ""


def _device_text(name: str, tools: Mapping[str, Tool]) -> str:
    tool = tools.get(name)
    return DEVICE_DESCRIPTIONS.get(tool, "a tool of the ITA workcell") if tool is not None else \
        "a tool of the ITA workcell"


def results_document(record: RunRecord) -> Element:
    """The QIF 3.0 document of `record` (an lxml element; `ita.qif.tree.to_bytes` writes it)."""
    return _Document(record).root()


# ------------------------------------------------------------------------ from the archive
def _part_specs(part_dir: Path | None) -> tuple[dict[str, MeasurementSpec], str | None]:
    """The specs of the part in `part_dir` by id, and a warning when they cannot be read."""
    if part_dir is None:
        return {}, "the run's part directory is not known: features are written as points without direction"
    path = Path(part_dir) / "specs.csv"
    try:
        table = read_spec_table(path)
    except InputError as exc:
        return {}, f"cannot read the part's specs ({exc.problems[0][0]}: {exc.problems[0][1]}): features are " \
                   "written as points without direction"
    return {s.id: s for s in table.specs}, None


def _tool_classes(part_dir: Path | None) -> dict[str, Tool]:
    """Tool name -> class from the part's workcell (the built-in cell's without its own)."""
    own = None if part_dir is None else Path(part_dir) / "workcell.toml"
    try:
        cell = load_workcell(own if own is not None and own.is_file() else None)
    except (ItaError, OSError, ValueError):
        return {}
    return {t.name: t.tool_class for t in cell.tools}


def gather(archive: Archive, run_id: str, part_dir: Path | None = None) -> tuple[RunRecord, list[str]]:
    """The record of run `run_id` (with the specs of `part_dir`, else of the run's own part
    directory) and the warnings met on the way."""
    run = archive.run(run_id)
    where = part_dir if part_dir is not None else (Path(run.part_dir) if run.part_dir else None)
    specs, warning = _part_specs(where)
    data = collect(archive, run_id, specs=list(specs.values()) or None)
    summary = summarize(data)
    aligned = [e.payload for e in archive.events(run_id, kinds=["alignment"]) if e.payload.get("registered")]
    record = RunRecord(run, data.results, specs, summary.verdict, summary.verdict_reason, _tool_classes(where),
                       created=datetime.now(timezone.utc).isoformat(timespec="seconds"),
                       alignment=aligned[-1] if aligned else None)
    return record, [warning] if warning else []


def export_run(archive: Archive, run_id: str, output: Path | str, *, part_dir: Path | None = None,
               make_dirs: bool = False) -> ExportSummary:
    """Write the QIF results document of run `run_id` to `output` atomically.  The target
    is checked before any work (InputError naming it, nothing written)."""
    target = output_path(output, what="--qif", make_dirs=make_dirs)
    record, warnings = gather(archive, run_id, part_dir)
    document = _Document(record)
    root = document.root()
    if document.fallbacks:
        few = ", ".join(document.fallbacks[:5]) + (" ..." if len(document.fallbacks) > 5 else "")
        warnings.append(f"{len(document.fallbacks)} result(s) without their spec in the part's specs.csv "
                        f"({few}): their features are points without direction")
    written = write_atomic(target, to_bytes(root), what="--qif")
    return ExportSummary(written, run_id, len(record.results), INSPECTION_STATUS[record.verdict], tuple(warnings))


__all__ = ["RunRecord", "ExportSummary", "Shape", "gather", "results_document", "export_run", "shapes",
           "STATUS", "INSPECTION_STATUS"]
