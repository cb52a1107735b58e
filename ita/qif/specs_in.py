"""`ita spec import FILE.qif --out DIR`: a QIF file's characteristics as ITA's specs.

    summary = import_qif("model.qif", "out/")    # out/specs.csv and out/refused.csv

Every characteristic of the file is one row of the two files (its items where the file
has items, and the nominals no item names; else its nominals): specs.csv (ITA's spec
CSV, docs/specs.md) holds those that map to a kind ITA measures (:mod:`ita.qif.mapping`),
refused.csv (id, qif_type, reason, qif_id, name, line) the others with the reason.  With
`expand_patterns` a characteristic of several features is one spec per feature
(ids ``ID.1``, ``ID.2`` ...) instead of a refusal.

A row's id is the characteristic's name when that is a valid spec id no other
characteristic has (ITA's own export names each item by its spec id, so a round trip
gives the same ids), else its QIF id.  Each spec's note names the QIF element it came
from.  Both files are written only after the whole file is read and mapped, atomically,
the second inside the first's write: a file that is not QIF 3 writes nothing.
"""

from __future__ import annotations

import csv
import io
import math
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path

from ita.files.atomic import output_path, write_atomic, write_with
from ita.qif.mapping import Draft, Mapped, Refused, map_row
from ita.qif.read import QifFile, Row
from ita.specs.io import ID_PATTERN, format_specs, parse_specs_text
from ita.specs.model import MeasurementSpec

REFUSED_COLUMNS = ("id", "qif_type", "reason", "qif_id", "name", "line")


@dataclass(frozen=True)
class ImportSummary:
    """What an import wrote: the files, how many characteristics, how many mapped (and
    the specs they gave), how many refused and why (reason -> count), and warnings."""

    source: Path
    specs_path: Path
    refused_path: Path
    characteristics: int
    mapped: int
    specs: int
    refused: int
    reasons: dict[str, int] = field(default_factory=dict)
    warnings: tuple[str, ...] = ()


def _ids(rows: list[Row]) -> list[str]:
    """A unique spec id per row: its name when valid and unique, else its QIF id."""
    names = Counter(r.name for r in rows if r.name)
    out: list[str] = []
    used: set[str] = set()
    for r in rows:
        if r.name and names[r.name] == 1 and ID_PATTERN.match(r.name):
            base = r.name
        elif ID_PATTERN.match(r.qif_id):
            base = r.qif_id
        else:
            base = "Q" + "".join(c for c in r.qif_id if c.isalnum())[:60]
        candidate, n = base, 1
        while candidate in used:
            n += 1
            candidate = f"{base}-{n}"
        used.add(candidate)
        out.append(candidate)
    return out


def _note(row: Row, draft: Draft, part: str = "") -> str:
    text = f"from QIF {row.tag} {row.qif_id}"
    if row.name:
        text += f" '{row.name}'"
    if row.designator and row.designator != row.name:
        text += f" (designator {row.designator})"
    text += part
    if draft.notes:
        text += "; " + "; ".join(draft.notes)
    return " ".join(text.split())


def _spec(spec_id: str, row: Row, draft: Draft, part: str = "") -> MeasurementSpec:
    return MeasurementSpec(spec_id, draft.kind, " ".join(draft.feature.split()) or "F", _point(draft.point),
                           _unit(draft.normal), _mm(draft.nominal), _mm(draft.lower), _mm(draft.upper), draft.datum,
                           None if draft.direction is None else _unit(draft.direction), _note(row, draft, part))


def _unit(v: tuple[float, float, float]) -> tuple[float, float, float]:
    n = math.sqrt(v[0] ** 2 + v[1] ** 2 + v[2] ** 2)
    if abs(n - 1.0) > 1e-15:
        v = (v[0] / n, v[1] / n, v[2] / n)
    return (v[0] + 0.0, v[1] + 0.0, v[2] + 0.0)  # no -0.0 in the file


def _mm(x: float) -> float:
    """A length rounded to 1e-9 mm: a unit conversion's or a limit's subtraction's last
    bits are noise (35.2 - 35 is 0.20000000000000284)."""
    return round(x, 9) + 0.0


def _point(p: tuple[float, float, float]) -> tuple[float, float, float]:
    return (_mm(p[0]), _mm(p[1]), _mm(p[2]))


def reason_class(reason: str) -> str:
    """The reason's head (before its first colon or parenthesis), for counting."""
    head = reason.split(":", 1)[0]
    return head.split(" (", 1)[0].strip()


def convert(doc: QifFile, *, expand_patterns: bool = False) -> tuple[list[MeasurementSpec], list[list[str]], int]:
    """The specs, the refused rows (REFUSED_COLUMNS) and the number of characteristics."""
    rows = list(doc.rows())
    ids = _ids(rows)
    specs: list[MeasurementSpec] = []
    refused: list[list[str]] = []
    for row, spec_id in zip(rows, ids):
        outcome = map_row(doc, row, expand_patterns=expand_patterns)
        if isinstance(outcome, Refused):
            refused.append([spec_id, row.tag, outcome.reason, row.qif_id, row.name, str(row.line)])
            continue
        assert isinstance(outcome, Mapped)
        if len(outcome.drafts) == 1:
            specs.append(_spec(spec_id, row, outcome.drafts[0]))
        else:
            k = len(outcome.drafts)
            specs += [_spec(f"{spec_id}.{i + 1}", row, d, f", feature {i + 1} of {k}")
                      for i, d in enumerate(outcome.drafts)]
    return specs, refused, len(rows)


def _refused_text(rows: list[list[str]]) -> str:
    buf = io.StringIO()
    writer = csv.writer(buf, lineterminator="\n")
    writer.writerow(REFUSED_COLUMNS)
    writer.writerows(rows)
    return buf.getvalue()


def import_qif(source: Path | str, out_dir: Path | str, *, expand_patterns: bool = False) -> ImportSummary:
    """Read the QIF file `source` and write `out_dir`/specs.csv and `out_dir`/refused.csv.
    InputError (nothing written) for a file that is not QIF 3 or a directory that cannot
    take the files."""
    source = Path(source)
    doc = QifFile.load(source)
    specs, refused, total = convert(doc, expand_patterns=expand_patterns)
    specs_text = format_specs(specs)
    parse_specs_text(specs_text, "specs.csv")  # what is written reads back (a bug otherwise)
    warnings = () if doc.units.stated else ("the file states no length unit (FileUnits): lengths taken as mm",)
    out = Path(out_dir)
    specs_path = output_path(out / "specs.csv", what="--out", make_dirs=True)
    refused_path = output_path(out / "refused.csv", what="--out")

    def write_both(tmp: Path) -> None:
        tmp.write_text(specs_text, encoding="utf-8")
        write_atomic(refused_path, _refused_text(refused), what="--out")

    write_with(specs_path, write_both, what="--out")
    return ImportSummary(source, specs_path, refused_path, total, total - len(refused), len(specs), len(refused),
                         dict(Counter(reason_class(r[2]) for r in refused).most_common()), warnings)
