"""Reading and writing measurement specification files (CSV).

Schema (one header row, then one spec per row; lines starting with '#' are comments):

    id,kind,feature,x,y,z,nx,ny,nz,nominal,lower,upper,datum,dx,dy,dz,note

x,y,z: point on the part's surface, mm, part frame; nx,ny,nz: outward surface normal
(normalised on reading); nominal, lower, upper: mm, lower/upper signed deviations with
lower < upper; datum: datum reference (text); dx,dy,dz: in-plane measuring direction for
widths and edge distances (all three empty otherwise); note: free text.  See
docs/specs.md.

Reading collects every problem of every row (file, line, field) and raises one
InputError; writing is atomic (a temporary file in the same directory, fsync, rename), so
a crash never leaves a half-written specs file.
"""

from __future__ import annotations

import csv
import io
import math
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Iterable, Sequence

from ita.errors import InputError, Location
from ita.files.atomic import write_atomic
from ita.specs.model import MeasurementKind, MeasurementSpec

COLUMNS: tuple[str, ...] = (
    "id", "kind", "feature", "x", "y", "z", "nx", "ny", "nz",
    "nominal", "lower", "upper", "datum", "dx", "dy", "dz", "note",
)
REQUIRED: tuple[str, ...] = COLUMNS[:13]
ID_PATTERN = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_.\-]{0,63}$")


@dataclass(frozen=True)
class SpecTable:
    """Specs read from a file, with the 1-based line of each (for error messages)."""

    path: Path
    specs: tuple[MeasurementSpec, ...]
    lines: tuple[int, ...]

    def line_of(self, spec_id: str) -> int:
        """Line number of the spec with id `spec_id` (0 when unknown)."""
        for spec, line in zip(self.specs, self.lines):
            if spec.id == spec_id:
                return line
        return 0


def _number(text: str, loc: Location, problems: list[tuple[Location, str]]) -> float | None:
    value = text.strip()
    if value == "":
        problems.append((loc, "missing value (a number is required)"))
        return None
    try:
        number = float(value)
    except ValueError:
        problems.append((loc, f"not a number: {value!r}"))
        return None
    if not math.isfinite(number):
        problems.append((loc, f"not a finite number: {value!r}"))
        return None
    return number


def _vector(
    row: dict[str, str], names: tuple[str, str, str], file: str, line: int,
    problems: list[tuple[Location, str]], optional: bool = False,
) -> tuple[float, float, float] | None:
    cells = [(row.get(n) or "").strip() for n in names]
    if optional and not any(cells):
        return None
    x, y, z = (_number(c, Location(file, line, field=n), problems) for c, n in zip(cells, names))
    if x is None or y is None or z is None:
        return None
    return (x, y, z)


def _unit(
    v: tuple[float, float, float] | None, loc: Location, problems: list[tuple[Location, str]]
) -> tuple[float, float, float] | None:
    if v is None:
        return None
    n = math.sqrt(v[0] ** 2 + v[1] ** 2 + v[2] ** 2)
    if n < 1e-9:
        problems.append((loc, "zero-length vector"))
        return None
    return (v[0] / n, v[1] / n, v[2] / n)


def parse_row(
    row: dict[str, str], file: str, line: int, problems: list[tuple[Location, str]]
) -> MeasurementSpec | None:
    """Parse one CSV row into a spec, appending any problems; None when the row is bad."""
    before = len(problems)
    at = lambda f: Location(file, line, field=f)  # noqa: E731
    spec_id = (row.get("id") or "").strip()
    if not ID_PATTERN.match(spec_id):
        problems.append((at("id"), f"bad id {spec_id!r}: 1-64 characters of letters, digits, '_', '-', '.'"))
    try:
        kind = MeasurementKind.parse(row.get("kind") or "")
    except ValueError as exc:
        problems.append((at("kind"), str(exc)))
        kind = None
    feature = (row.get("feature") or "").strip()
    if not feature:
        problems.append((at("feature"), "missing feature id"))
    point = _vector(row, ("x", "y", "z"), file, line, problems)
    normal = _unit(_vector(row, ("nx", "ny", "nz"), file, line, problems), at("nx"), problems)
    nominal = _number(row.get("nominal") or "", at("nominal"), problems)
    lower = _number(row.get("lower") or "", at("lower"), problems)
    upper = _number(row.get("upper") or "", at("upper"), problems)
    if lower is not None and upper is not None and not lower < upper:
        problems.append((at("lower"), f"lower tolerance {lower:g} is not below upper tolerance {upper:g}"))
    direction = _unit(
        _vector(row, ("dx", "dy", "dz"), file, line, problems, optional=True), at("dx"), problems
    )
    datum = (row.get("datum") or "").strip()
    if not datum:
        problems.append((at("datum"), "missing datum (e.g. A or A|B|C)"))
    if len(problems) > before:
        return None
    # each of these is None only with a problem appended
    assert kind is not None and point is not None and normal is not None
    assert nominal is not None and lower is not None and upper is not None
    return MeasurementSpec(
        id=spec_id, kind=kind, feature=feature, point=point, normal=normal,
        nominal=nominal, lower=lower, upper=upper, datum=datum,
        direction=direction, note=(row.get("note") or "").strip(),
    )


def parse_specs_text(text: str, file: str) -> SpecTable:
    """Parse the text of a specs CSV file; raises InputError listing every bad row."""
    problems: list[tuple[Location, str]] = []
    text = text.removeprefix("\ufeff")  # a UTF-8 byte-order mark is not part of the header
    lines = text.splitlines(keepends=True)
    body = [(i + 1, ln) for i, ln in enumerate(lines) if ln.strip() and not ln.lstrip().startswith("#")]
    if not body:
        raise InputError([(Location(file), "empty specs file: a header row is required")])
    header_line, header_text = body[0]
    try:
        header = [h.strip() for h in _cells(header_text)]
    except csv.Error as exc:
        raise InputError([(Location(file, header_line), f"header is not valid CSV: {exc}")]) from None
    repeated = sorted({h for h in header if header.count(h) > 1})
    if repeated:
        raise InputError([(Location(file, header_line), f"header repeats column(s): {', '.join(repeated)}")])
    missing = [c for c in REQUIRED if c not in header]
    unknown = [h for h in header if h not in COLUMNS]
    if missing or unknown:
        if missing:
            problems.append((Location(file, header_line), f"header lacks column(s): {', '.join(missing)}"))
        if unknown:
            problems.append((Location(file, header_line), f"unknown column(s): {', '.join(unknown)}"))
        raise InputError(problems)
    specs: list[MeasurementSpec] = []
    spec_lines: list[int] = []
    first_line_of: dict[str, int] = {}
    for line_no, raw in body[1:]:
        try:
            cells = _cells(raw)
        except csv.Error as exc:
            problems.append((Location(file, line_no), f"not valid CSV: {exc}"))
            continue
        if len(cells) > len(header):
            problems.append((Location(file, line_no), f"{len(cells)} cells but the header has {len(header)}"))
            continue
        row = dict(zip(header, cells))
        spec = parse_row(row, file, line_no, problems)
        if spec is None:
            continue
        if spec.id in first_line_of:
            problems.append((
                Location(file, line_no, field="id"),
                f"duplicate id {spec.id!r} (first on line {first_line_of[spec.id]})",
            ))
            continue
        first_line_of[spec.id] = line_no
        specs.append(spec)
        spec_lines.append(line_no)
    if problems:
        raise InputError(problems)
    return SpecTable(Path(file), tuple(specs), tuple(spec_lines))


def _cells(line: str) -> list[str]:
    """The cells of one CSV line; csv.Error for an unterminated quote, a stray quote or a
    cell over the csv module's field limit (128 KiB)."""
    return next(csv.reader([line], strict=True), [])


def read_spec_table(path: Path) -> SpecTable:
    """Read a specs CSV file with line numbers; raises InputError on any bad row."""
    try:
        text = Path(path).read_text(encoding="utf-8")
    except FileNotFoundError:
        raise InputError([(Location(str(path)), "specs file not found")]) from None
    except UnicodeDecodeError as exc:
        raise InputError([(Location(str(path)), f"not UTF-8 text ({exc.reason})")]) from None
    except OSError as exc:
        raise InputError([(Location(str(path)), f"cannot read: {exc.strerror}")]) from None
    return parse_specs_text(text, str(path))


def read_specs(path: Path) -> list[MeasurementSpec]:
    """Read a specs CSV file; raises InputError naming file, line and field of every bad row."""
    return list(read_spec_table(path).specs)


def _fmt(v: float) -> str:
    return repr(float(v)) if v != int(v) else f"{v:.1f}"


def spec_to_row(spec: MeasurementSpec) -> list[str]:
    """The CSV cells of one spec, in COLUMNS order."""
    d = spec.direction
    return [
        spec.id, spec.kind.value, spec.feature,
        *(_fmt(c) for c in spec.point), *(_fmt(c) for c in spec.normal),
        _fmt(spec.nominal), _fmt(spec.lower), _fmt(spec.upper), spec.datum,
        *((_fmt(c) for c in d) if d is not None else ("", "", "")),
        spec.note,
    ]


def format_specs(specs: Iterable[MeasurementSpec]) -> str:
    """The CSV text of `specs` (header included)."""
    buf = io.StringIO()
    writer = csv.writer(buf, lineterminator="\n")
    writer.writerow(COLUMNS)
    for spec in specs:
        writer.writerow(spec_to_row(spec))
    return buf.getvalue()


def atomic_write_text(path: Path, text: str, *, make_dirs: bool = True, what: str = "") -> None:
    """Write `text` to `path` atomically (ita.files.atomic): never over a device or other
    non-regular file; parent directories made only with `make_dirs`."""
    write_atomic(path, text, what=what, make_dirs=make_dirs)


def write_specs(path: Path, specs: Sequence[MeasurementSpec], *, make_dirs: bool = True,
                what: str = "") -> None:
    """Write specs as CSV atomically.  Raises InputError on duplicate ids or a target that
    cannot be written (nothing written)."""
    seen: set[str] = set()
    for spec in specs:
        if spec.id in seen:
            raise InputError([(Location(str(path), field="id"), f"duplicate id {spec.id!r}")])
        seen.add(spec.id)
    atomic_write_text(Path(path), format_specs(specs), make_dirs=make_dirs, what=what)
