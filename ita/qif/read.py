"""Reading a QIF 3 document: checked to be QIF 3, every element by its id, lengths in mm
through the file's own units, and its characteristics as rows.

    doc = QifFile.load(path)          # InputError (one problem: what and where) if not QIF 3
    for row in doc.rows():            # its items where it has items (and nominals no item
        ...                           # names), else its nominals

Nothing is assumed of the file's producer: elements are found by their QIF names in the
QIF namespace, references are followed by id (an external reference, ``xId``, is not
followed), a value's ``linearUnit`` names a unit of the file's FileUnits, geometry is in
the primary LinearUnit and tolerances in the PMILinearUnit when the file has one.
The parser reads no DTD, resolves no entity and opens no network address.
"""

from __future__ import annotations

import math
import re
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path

from lxml import etree

from ita.errors import InputError, Location
from ita.qif.tree import NS, OTHER_VERSIONS, Element, kid, kids, local, text

Vec3 = tuple[float, float, float]

#: mm per unit of the length units a file may name without a conversion factor
KNOWN_LENGTHS = {"mm": 1.0, "millimeter": 1.0, "millimetre": 1.0, "m": 1000.0, "meter": 1000.0, "metre": 1000.0,
                 "cm": 10.0, "um": 1e-3, "micrometer": 1e-3, "micron": 1e-3, "in": 25.4, "inch": 25.4,
                 "ft": 304.8, "foot": 304.8, "feet": 304.8, "mil": 0.0254, "thou": 0.0254}
SUFFIXES = ("CharacteristicItem", "CharacteristicNominal", "CharacteristicDefinition")
MAX_BYTES = 512 * 1024 * 1024


class Refuse(Exception):
    """A characteristic ITA does not take: its reason (a row of refused.csv)."""

    def __init__(self, reason: str):
        super().__init__(reason)
        self.reason = reason


def _error(path: Path, message: str, line: int = 0, column: int = 0) -> InputError:
    return InputError([(Location(str(path), line, column), message)])


@dataclass(frozen=True)
class Units:
    """mm per unit: of geometry (the primary LinearUnit), of tolerances and targets (the
    PMILinearUnit, else the LinearUnit), and of every unit the file names."""

    geometry: float = 1.0
    pmi: float = 1.0
    named: dict[str, float] = field(default_factory=dict)
    stated: bool = True


def _unit_mm(unit: Element, path: Path) -> tuple[str, float]:
    name = text(unit, "UnitName") or ""
    factor = text(unit, "UnitConversion", "Factor")
    if factor is not None:
        try:
            value = float(factor) * 1000.0
        except ValueError:
            raise _error(path, f"unit {name!r}: conversion factor {factor!r} is not a number",
                         unit.sourceline or 0) from None
        if not (math.isfinite(value) and value > 0):
            raise _error(path, f"unit {name!r}: conversion factor {factor!r} is not positive", unit.sourceline or 0)
        return name, value
    known = KNOWN_LENGTHS.get(name.strip().lower())
    if known is None:
        raise _error(path, f"length unit {name!r} has no conversion factor and is no unit ITA knows",
                     unit.sourceline or 0)
    return name, known


def read_units(root: Element, path: Path) -> Units:
    """The file's length units (mm per unit); mm when the file has no FileUnits."""
    units = kid(root, "FileUnits")
    if units is None:
        return Units(stated=False)
    named: dict[str, float] = {}
    for group in ("PrimaryUnits", "OtherUnits", "UserDefinedUnits"):
        for unit in kids(kid(units, group)) if kid(units, group) is not None else ():
            if local(unit) in ("LinearUnit", "PMILinearUnit"):
                name, mm = _unit_mm(unit, path)
                named.setdefault(name, mm)
    primary = kid(units, "PrimaryUnits")
    linear = kid(primary, "LinearUnit")
    pmi = kid(primary, "PMILinearUnit")
    geometry = _unit_mm(linear, path)[1] if linear is not None else 1.0
    return Units(geometry, _unit_mm(pmi, path)[1] if pmi is not None else geometry, named,
                 stated=linear is not None or pmi is not None)


@dataclass(frozen=True)
class Row:
    """One characteristic of the document: an item, or a nominal (no item names it).

    element: the item or nominal; nominal, definition: its nominal and definition (None
    when the reference is missing); stem: the QIF type (Diameter, Flatness ...)."""

    element: Element
    qif_id: str
    tag: str
    stem: str
    name: str
    designator: str
    nominal: Element | None
    definition: Element | None
    missing: str = ""

    @property
    def line(self) -> int:
        return int(self.element.sourceline or 0)

    @property
    def attributes(self) -> dict[str, str]:
        """The row's user attributes (``<Attributes>``: name -> value), its nominal's under its own."""
        out: dict[str, str] = {}
        for owner in (self.nominal, self.element):
            for a in kids(kid(owner, "Attributes")) if kid(owner, "Attributes") is not None else ():
                if a.get("name") is not None and a.get("value") is not None:
                    out[a.get("name")] = a.get("value")
        return out


def stem_of(tag: str) -> str:
    for suffix in SUFFIXES:
        if tag.endswith(suffix):
            return tag[: -len(suffix)]
    return tag


class QifFile:
    """A QIF 3 document: its root, its elements by id, its units."""

    def __init__(self, path: Path, root: Element, by_id: dict[str, Element], units: Units):
        self.path = path
        self.root = root
        self.by_id = by_id
        self.units = units

    @classmethod
    def load(cls, path: Path | str) -> QifFile:
        """Read and check `path`: XML, a QIFDocument of the QIF 3 namespace, versionQIF
        3.x, every id once.  InputError with file and line otherwise."""
        path = Path(path)
        try:
            if path.stat().st_size > MAX_BYTES:
                raise _error(path, f"larger than {MAX_BYTES // 2**20} MiB: not read")
            data = path.read_bytes()
        except FileNotFoundError:
            raise _error(path, "file not found") from None
        except IsADirectoryError:
            raise _error(path, "is a directory, not a QIF file") from None
        except OSError as exc:
            raise _error(path, f"cannot read: {exc.strerror}") from None
        parser = etree.XMLParser(resolve_entities=False, no_network=True, load_dtd=False, dtd_validation=False,
                                 huge_tree=False, remove_comments=True, remove_pis=True)
        try:
            root = etree.fromstring(data, parser)
        except etree.XMLSyntaxError as exc:
            line, column = exc.position if exc.position else (0, 0)
            why = re.sub(r",? line \d+, column \d+\s*$", "", str(exc.msg))
            raise _error(path, f"not a QIF file: not XML ({why})", line, column) from None
        if root is None:
            raise _error(path, "not a QIF file: empty")
        _check_root(root, path)
        by_id: dict[str, Element] = {}
        for e in root.iter():
            qid = e.get("id") if isinstance(e.tag, str) else None
            if qid is None:
                continue
            qid = qid.strip()
            if qid in by_id:
                raise _error(path, f"id {qid} is used twice (first on line {by_id[qid].sourceline})",
                             e.sourceline or 0)
            by_id[qid] = e
        return cls(path, root, by_id, read_units(root, path))

    # -- references ----------------------------------------------------------------
    def ref(self, element: Element | None) -> Element | None:
        """The element a reference element (``<Id>12</Id>``, ``<FeatureNominalId>``...)
        names; None for a missing reference or an external one (``xId``)."""
        if element is None or element.text is None or element.get("xId") is not None:
            return None
        return self.by_id.get(element.text.strip())

    def refs(self, element: Element | None) -> list[tuple[str, Element | None]]:
        """The (id text, element or None) of each ``<Id>`` of a reference list."""
        if element is None:
            return []
        return [((i.text or "").strip(), self.ref(i)) for i in kids(element, "Id")]

    # -- numbers ---------------------------------------------------------------------
    def length(self, element: Element | None, *, pmi: bool, what: str) -> float:
        """A length value in mm (its linearUnit, else the file's unit for tolerances or
        geometry).  Refuse naming `what` when missing or not a number."""
        if element is None or element.text is None or not element.text.strip():
            raise Refuse(f"no {what}")
        try:
            value = float(element.text)
        except ValueError:
            raise Refuse(f"{what} {element.text.strip()!r} on line {element.sourceline} is not a number") from None
        if not math.isfinite(value):
            raise Refuse(f"{what} on line {element.sourceline} is not finite")
        return value * self.scale(element, pmi=pmi)

    def scale(self, element: Element, *, pmi: bool) -> float:
        unit = element.get("linearUnit")
        if unit is None:
            return self.units.pmi if pmi else self.units.geometry
        if unit not in self.units.named:
            raise Refuse(f"unit {unit!r} (linearUnit, line {element.sourceline}) is not in the file's FileUnits")
        return self.units.named[unit]

    def point(self, element: Element | None, what: str) -> Vec3:
        """A point in mm."""
        x, y, z = self._three(element, what)
        assert element is not None  # _three refuses a missing one
        s = self.scale(element, pmi=False)
        return (x * s, y * s, z * s)

    def vector(self, element: Element | None, what: str) -> Vec3:
        """A unit vector (normalised; Refuse for a zero one)."""
        x, y, z = self._three(element, what)
        n = math.sqrt(x * x + y * y + z * z)
        if n < 1e-12:
            raise Refuse(f"{what} is a zero vector")
        return (x / n, y / n, z / n)

    def _three(self, element: Element | None, what: str) -> Vec3:
        if element is None or not (element.text or "").strip():
            raise Refuse(f"no {what}")
        try:
            x, y, z = (float(c) for c in element.text.split())
        except ValueError:
            raise Refuse(f"{what} on line {element.sourceline} is not three numbers") from None
        if not all(map(math.isfinite, (x, y, z))):
            raise Refuse(f"{what} on line {element.sourceline} is not finite")
        return (x, y, z)

    # -- the characteristics -----------------------------------------------------------
    def _section(self, name: str) -> list[Element]:
        chars = kid(self.root, "Characteristics")
        section = kid(chars, name)
        return [e for e in kids(section)] if section is not None else []

    def rows(self) -> Iterator[Row]:
        """Every characteristic once: the items (when the file has any) and the nominals
        no item names; else the nominals; else the definitions (with no nominal to say
        what they apply to)."""
        items = self._section("CharacteristicItems")
        nominals = self._section("CharacteristicNominals")
        named: set[str] = set()
        for item in items:
            nominal = self.ref(kid(item, "CharacteristicNominalId"))
            missing = "" if nominal is not None else \
                f"its nominal {text(item, 'CharacteristicNominalId')} is not in the file"
            if nominal is not None:
                named.add(nominal.get("id", "").strip())
            yield self._row(item, nominal, missing)
        for nominal in nominals:
            if nominal.get("id", "").strip() not in named:
                yield self._row(nominal, nominal, "")
        if not items and not nominals:
            for definition in self._section("CharacteristicDefinitions"):
                yield Row(definition, definition.get("id", "").strip(), local(definition),
                          stem_of(local(definition)), text(definition, "Name") or "",
                          text(definition, "CharacteristicDesignator", "Designator") or "", None, definition,
                          "a definition without a nominal: nothing says which feature it applies to")

    def _row(self, element: Element, nominal: Element | None, missing: str) -> Row:
        definition = self.ref(kid(nominal, "CharacteristicDefinitionId")) if nominal is not None else None
        if nominal is not None and definition is None and not missing:
            missing = f"its definition {text(nominal, 'CharacteristicDefinitionId')} is not in the file"
        name = text(element, "Name") or (text(nominal, "Name") if nominal is not None else None) or ""
        designator = (text(element, "CharacteristicDesignator", "Designator")
                      or (text(nominal, "CharacteristicDesignator", "Designator") if nominal is not None else None)
                      or "")
        return Row(element, element.get("id", "").strip(), local(element), stem_of(local(element)), name,
                   designator, nominal, definition, missing)


def _check_root(root: Element, path: Path) -> None:
    line = int(root.sourceline or 0)
    tag = root.tag if isinstance(root.tag, str) else ""
    namespace = tag[1:].partition("}")[0] if tag.startswith("{") else ""
    name = local(root)
    if namespace in OTHER_VERSIONS:
        raise _error(path, f"a QIF {OTHER_VERSIONS[namespace]} document (namespace {namespace}); "
                           "ITA reads QIF 3", line)
    if name != "QIFDocument" or namespace != NS:
        if namespace.startswith("http://qifstandards.org/"):
            raise _error(path, f"a QIF document of namespace {namespace}, not QIF 3's {NS}", line)
        shown = f"<{name}>" + (f" of namespace {namespace}" if namespace else " (no namespace)")
        raise _error(path, f"not a QIF file: the root element is {shown}, not <QIFDocument> of {NS}", line)
    version = (root.get("versionQIF") or "").strip()
    if not version:
        raise _error(path, "QIFDocument has no versionQIF: cannot tell its QIF version", line)
    if version.split(".")[0] != "3":
        raise _error(path, f"QIF version {version} (versionQIF); ITA reads QIF 3", line)
