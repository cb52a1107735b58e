"""Pure operations on a list of specs: add, edit, remove, merge.  Nothing here writes files.

Each returns a new list or raises InputError saying what is wrong; the caller validates
the result against the part and writes it atomically.
"""

from __future__ import annotations

from typing import Mapping, Sequence

from ita.errors import InputError, Location
from ita.specs.io import COLUMNS, parse_row, spec_to_row
from ita.specs.model import MeasurementSpec

CLI = "<command line>"


def spec_from_fields(fields: Mapping[str, str], origin: str = CLI) -> MeasurementSpec:
    """Build a spec from column-name -> text fields (as in the CSV); raises InputError."""
    problems: list[tuple[Location, str]] = []
    spec = parse_row(dict(fields), origin, 0, problems)
    if problems or spec is None:
        raise InputError(problems)
    return spec


def _index(specs: Sequence[MeasurementSpec], spec_id: str) -> int:
    for i, s in enumerate(specs):
        if s.id == spec_id:
            return i
    raise InputError([(Location(CLI, field="id"), f"no spec with id {spec_id!r}")])


def add_spec(specs: Sequence[MeasurementSpec], new: MeasurementSpec) -> list[MeasurementSpec]:
    """specs + [new]; raises InputError when the id is taken."""
    if any(s.id == new.id for s in specs):
        raise InputError([(Location(CLI, field="id"), f"a spec with id {new.id!r} already exists")])
    return [*specs, new]


def edit_spec(
    specs: Sequence[MeasurementSpec], spec_id: str, changes: Mapping[str, str]
) -> list[MeasurementSpec]:
    """Replace fields (CSV column names -> text) of spec `spec_id`; re-validates the row."""
    i = _index(specs, spec_id)
    unknown = [k for k in changes if k not in COLUMNS]
    if unknown:
        raise InputError([(Location(CLI, field=k), "unknown field") for k in unknown])
    row = dict(zip(COLUMNS, spec_to_row(specs[i])))
    row.update(changes)
    edited = spec_from_fields(row)
    if edited.id != spec_id and any(s.id == edited.id for s in specs):
        raise InputError([(Location(CLI, field="id"), f"a spec with id {edited.id!r} already exists")])
    out = list(specs)
    out[i] = edited
    return out


def remove_specs(specs: Sequence[MeasurementSpec], ids: Sequence[str]) -> list[MeasurementSpec]:
    """specs without those of `ids`; raises InputError naming any id not present."""
    present = {s.id for s in specs}
    missing = [i for i in ids if i not in present]
    if missing:
        raise InputError([(Location(CLI, field="id"), f"no spec with id {m!r}") for m in missing])
    drop = set(ids)
    return [s for s in specs if s.id not in drop]


def merge_specs(
    specs: Sequence[MeasurementSpec], incoming: Sequence[MeasurementSpec],
    incoming_file: str, incoming_lines: Sequence[int],
) -> list[MeasurementSpec]:
    """specs + incoming; raises InputError (file, line) for each incoming id already present."""
    present = {s.id for s in specs}
    problems = [
        (Location(incoming_file, line, field="id"), f"id {s.id!r} already exists in the part's specs")
        for s, line in zip(incoming, incoming_lines) if s.id in present
    ]
    if problems:
        raise InputError(problems)
    return [*specs, *incoming]
