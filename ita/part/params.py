"""Parameters of the parametric bulkhead, read from `bulkhead/part.toml`.

One frozen dataclass per TOML table; `BulkheadParams.load(path)` checks that every table
and key is known, every value has the right type and lies in its range, and the
constraints between fields hold (`ita.part.limits`), and raises InputError naming the
file, the field and its range otherwise: before anything is generated.
"""

from __future__ import annotations

import tomllib
from dataclasses import dataclass, fields
from pathlib import Path
from typing import Any, get_type_hints

from ita.errors import InputError, Location
from ita.part.limits import cross_problems, range_problem


@dataclass(frozen=True)
class PartInfo:
    name: str
    material: str
    seed: int


@dataclass(frozen=True)
class Outline:
    width: float
    height: float
    corner_radius: float


@dataclass(frozen=True)
class Web:
    thickness: float


@dataclass(frozen=True)
class Flange:
    height: float
    wall_thickness: float
    cap_width: float
    cap_thickness: float
    segments: int
    fastener_pitch: float
    fastener_diameter: float


@dataclass(frozen=True)
class Stiffeners:
    width: float
    height: float
    x: tuple[float, ...]
    y: tuple[float, ...]


@dataclass(frozen=True)
class Holes:
    tooling_diameter: float
    lightening_min_diameter: float
    lightening_max_diameter: float
    lightening_margin: float
    lightening_fraction: float


@dataclass(frozen=True)
class SpecParams:
    web_thickness_points: int
    web_point_margin: float
    stiffener_long_span: float


@dataclass(frozen=True)
class Tolerance:
    thickness: float
    fastener_diameter: float
    tooling_diameter: float
    lightening_diameter: float
    true_position: float
    lightening_true_position: float
    height: float
    general: float


@dataclass(frozen=True)
class TruthParams:
    spread: float
    out_of_tolerance: float


@dataclass(frozen=True)
class BulkheadParams:
    """Every parameter of the bulkhead generator (see bulkhead/part.toml for meanings)."""

    part: PartInfo
    outline: Outline
    opening: Outline
    web: Web
    outer_flange: Flange
    inner_flange: Flange
    stiffeners: Stiffeners
    holes: Holes
    specs: SpecParams
    tolerance: Tolerance
    truth: TruthParams

    @classmethod
    def load(cls, path: Path) -> "BulkheadParams":
        """Read and check a part.toml; raises InputError naming file and field."""
        try:
            data = tomllib.loads(Path(path).read_text(encoding="utf-8"))
        except FileNotFoundError:
            raise InputError([(Location(str(path)), "part parameters file not found")]) from None
        except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
            raise InputError([(Location(str(path)), f"not valid TOML: {exc}")]) from None
        return cls.from_dict(data, str(path))

    @classmethod
    def from_dict(cls, data: dict[str, Any], file: str = "<part.toml>") -> "BulkheadParams":
        """Build from parsed TOML tables; raises InputError listing every problem: of a
        table, a key, a type, a range, and (when every field is good) between fields."""
        problems: list[tuple[Location, str]] = []
        tables: dict[str, Any] = {}
        hints = get_type_hints(cls)
        for f in fields(cls):
            table = data.get(f.name)
            if not isinstance(table, dict):
                problems.append((Location(file, field=f.name), "missing table"))
                continue
            tables[f.name] = _section(hints[f.name], table, f"{file}", f.name, problems)
        for name in set(data) - {f.name for f in fields(cls)}:
            problems.append((Location(file, field=name), "unknown table"))
        if problems:
            raise InputError(problems)
        params = cls(**tables)
        problems = cross_problems(params, file)
        if problems:
            raise InputError(problems)
        return params


def _section(kind: type, table: dict[str, Any], file: str, name: str,
             problems: list[tuple[Location, str]]) -> Any:
    """Convert one TOML table to dataclass `kind`, appending problems."""
    hints = get_type_hints(kind)
    values: dict[str, Any] = {}
    for f in fields(kind):
        loc = Location(file, field=f"{name}.{f.name}")
        if f.name not in table:
            problems.append((loc, "missing key"))
            continue
        value, want = table[f.name], hints[f.name]
        if any(isinstance(v, int) and abs(v) > 2**63 for v in (value if isinstance(value, list) else [value])):
            raw = tuple(value) if isinstance(value, list) else value       # too large for a float
            problems.append((loc, range_problem(kind.__name__, f.name, raw) or f"{value} is out of range"))
            continue
        if want is float and isinstance(value, (int, float)) and not isinstance(value, bool):
            values[f.name] = float(value)
        elif want is int and isinstance(value, int) and not isinstance(value, bool):
            values[f.name] = value
        elif want is str and isinstance(value, str):
            values[f.name] = value
        elif want == tuple[float, ...] and isinstance(value, list) and all(
            isinstance(v, (int, float)) and not isinstance(v, bool) for v in value
        ):
            values[f.name] = tuple(float(v) for v in value)
        else:
            problems.append((loc, f"expected {getattr(want, '__name__', str(want))}, got {value!r}"))
            continue
        why = range_problem(kind.__name__, f.name, values[f.name])
        if why:
            problems.append((loc, why))
            del values[f.name]
    for key in set(table) - {f.name for f in fields(kind)}:
        problems.append((Location(file, field=f"{name}.{key}"), "unknown key"))
    return kind(**values) if len(values) == len(fields(kind)) else None
