"""Spec-file operations on a part: each reads, changes, validates the whole result against
the part's mesh, and writes atomically, or raises InputError and writes nothing."""

from __future__ import annotations

from pathlib import Path
from typing import Mapping, Protocol, Sequence

from ita.errors import InputError, Location
from ita.files.atomic import locked
from ita.part.infer import infer_features
from ita.specs import edit
from ita.specs.io import read_spec_table, write_specs
from ita.specs.model import MeasurementSpec
from ita.specs.validate import DEFAULT_MAX_DISTANCE_MM, check_on_surface


class PartLike(Protocol):
    """What spec operations need of a part."""

    @property
    def specs_path(self) -> Path: ...

    @property
    def mesh(self): ...


def load(part: PartLike) -> list[MeasurementSpec]:
    """The part's specs (InputError naming file, line and field when the file is bad)."""
    return list(read_spec_table(part.specs_path).specs)


def validate_file(part: PartLike, path: Path | None = None,
                  max_distance: float = DEFAULT_MAX_DISTANCE_MM) -> tuple[int, list[tuple[Location, str]]]:
    """Validate a specs file (default: the part's own) against the part: the count of specs
    and the warnings, the specs whose feature the mesh does not show (a run marks them
    cannot be done, with the reason, and measures the rest).  InputError for a file it
    cannot read and for points off the part."""
    table = read_spec_table(Path(path) if path is not None else part.specs_path)
    _require_specs(table)
    problems = check_on_surface(table.specs, part.mesh, str(table.path), table.lines, max_distance)
    if problems:
        raise InputError(problems)
    return len(table.specs), feature_problems(part, table.specs, str(table.path), table.lines)


def feature_problems(part: PartLike, specs: Sequence[MeasurementSpec], file: str,
                     lines: Sequence[int] | None = None) -> list[tuple[Location, str]]:
    """Problems for the SLRA's specs whose feature neither the part's features.json has nor
    its mesh shows at the spec's point (ita.part.infer), naming the feature field."""
    return _unfound_problems(_unfound(part, specs), specs, file, lines)


def _unfound(part: PartLike, specs: Sequence[MeasurementSpec]) -> tuple:
    """ita.part.infer.NotFound of `specs` against the part's features.json and its mesh."""
    found = set(getattr(part, "found", ()))
    known = {f.id: f for f in getattr(part, "features", ()) if f.id not in found}
    return infer_features(part.mesh, specs, known)[1]


def _unfound_problems(unfound, specs: Sequence[MeasurementSpec], file: str,
                      lines: Sequence[int] | None) -> list[tuple[Location, str]]:
    """The problems of ita.part.infer.NotFound records, at their specs' lines."""
    line_of = {s.id: (lines[i] if lines is not None else 0) for i, s in enumerate(specs)}
    return [(Location(file, line_of.get(n.spec_id, 0), field="x" if n.thickness else "feature"), n.message)
            for n in unfound]


def _require_specs(table) -> None:
    if not table.specs:
        raise InputError([(Location(str(table.path), 2), "no specs: the file has its header row and nothing to "
                                                         "measure (add rows, or `ita spec add`)")])


def check_measurable(part: PartLike) -> None:
    """InputError (file, line) when the part's specs file cannot be read or has no specs:
    the quick check a run makes before any work.  A spec whose feature the mesh does not
    show (the part's `unfound`, ita.part.infer) is not refused here: the run marks it
    cannot be done with the reason (the tool rules' `unmeasurable/1`) and measures the rest;
    only a part none of whose specs can be measured is refused."""
    table = read_spec_table(part.specs_path)
    _require_specs(table)
    unfound = getattr(part, "unfound", ())
    if unfound and {n.spec_id for n in unfound} >= {s.id for s in table.specs}:
        raise InputError(_unfound_problems(unfound, table.specs, str(table.path), table.lines))


def _save(part: PartLike, specs: Sequence[MeasurementSpec], changed: Sequence[MeasurementSpec],
          origin: str, lines: Sequence[int] | None, max_distance: float) -> None:
    problems = check_on_surface(changed, part.mesh, origin, lines, max_distance, context=specs)
    if not problems:
        ids = {s.id for s in changed}               # a feature is found from all its specs
        problems = _unfound_problems([n for n in _unfound(part, specs) if n.spec_id in ids], changed, origin, lines)
    if problems:
        raise InputError(problems)
    write_specs(part.specs_path, specs)


def add(part: PartLike, fields: Mapping[str, str],
        max_distance: float = DEFAULT_MAX_DISTANCE_MM) -> MeasurementSpec:
    """Add one spec given as CSV fields; returns it."""
    new = edit.spec_from_fields(fields)
    with locked(part.specs_path):
        specs = edit.add_spec(load(part), new)
        _save(part, specs, [new], edit.CLI, None, max_distance)
    return new


def change(part: PartLike, spec_id: str, changes: Mapping[str, str],
           max_distance: float = DEFAULT_MAX_DISTANCE_MM) -> MeasurementSpec:
    """Edit fields of one spec; returns the edited spec."""
    with locked(part.specs_path):
        specs = edit.edit_spec(load(part), spec_id, changes)
        new_id = changes.get("id", spec_id).strip()
        edited = next(s for s in specs if s.id == new_id)
        _save(part, specs, [edited], edit.CLI, None, max_distance)
    return edited


def remove(part: PartLike, ids: Sequence[str]) -> int:
    """Remove specs by id; returns how many remain."""
    with locked(part.specs_path):
        specs = edit.remove_specs(load(part), ids)
        write_specs(part.specs_path, specs)
    return len(specs)


def import_file(part: PartLike, path: Path, replace_all: bool = False,
                max_distance: float = DEFAULT_MAX_DISTANCE_MM) -> int:
    """Import every spec of `path` (all or nothing); returns how many were imported."""
    table = read_spec_table(Path(path))
    with locked(part.specs_path):
        base: list[MeasurementSpec] = [] if replace_all else load(part)
        specs = edit.merge_specs(base, table.specs, str(table.path), table.lines)
        _save(part, specs, table.specs, str(table.path), table.lines, max_distance)
    return len(table.specs)


def export_file(part: PartLike, path: Path, specs: Sequence[MeasurementSpec] | None = None,
                make_dirs: bool = False) -> int:
    """Write the part's specs (or the given subset) to `path` as CSV; returns the count.
    Refuses a device or other non-regular file, and a missing directory unless
    `make_dirs`."""
    chosen = load(part) if specs is None else list(specs)
    write_specs(Path(path), chosen, make_dirs=make_dirs, what="FILE")
    return len(chosen)
