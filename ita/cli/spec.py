"""`ita spec`: list, show, add, edit, remove, import, export, validate measurement specs, and
pick one from the part's mesh at a point (`ita spec pick --at X,Y,Z`)."""

from __future__ import annotations

import json
import sys
from dataclasses import asdict
from pathlib import Path

import click

from ita.cli.common import FiniteFloatRange, part_option, reports_errors
from ita.specs.model import KIND_DESCRIPTIONS, MeasurementKind, MeasurementSpec

KIND_CHOICE = click.Choice([k.value for k in MeasurementKind])

FIELD_OPTIONS: list[tuple[str, str]] = [
    ("kind", "what is measured: " + ", ".join(k.value for k in MeasurementKind)),
    ("feature", "id of the part feature the spec belongs to"),
    ("point", "point on the part's surface 'x,y,z' (mm, part frame)"),
    ("normal", "outward surface normal 'nx,ny,nz'"),
    ("nominal", "nominal value (mm)"),
    ("lower", "lower tolerance, a signed deviation (mm), e.g. -0.127"),
    ("upper", "upper tolerance, a signed deviation (mm), e.g. 0.127"),
    ("datum", "datum reference, e.g. A or A|B|C"),
    ("direction", "in-plane measuring direction 'dx,dy,dz' (widths, edge distances)"),
    ("note", "free text"),
]
TRIPLES = {"point": ("x", "y", "z"), "normal": ("nx", "ny", "nz"), "direction": ("dx", "dy", "dz")}


def field_options(required: bool):
    """Decorator adding one option per spec field."""

    def decorate(func):
        for name, help_text in reversed(FIELD_OPTIONS):
            needed = required and name not in ("direction", "note")
            func = click.option(f"--{name}", required=needed, help=help_text)(func)
        return func

    return decorate


def to_columns(values: dict[str, str | None]) -> dict[str, str]:
    """Option values -> CSV column fields ('point' -> x, y, z)."""
    out: dict[str, str] = {}
    for name, value in values.items():
        if value is None:
            continue
        if name in TRIPLES:
            parts = [p.strip() for p in value.split(",")] if value.strip() else ["", "", ""]
            if len(parts) != 3:
                raise click.BadParameter(f"expected three comma-separated numbers, got {value!r}",
                                         param_hint=f"--{name}")
            out.update(zip(TRIPLES[name], parts))
        else:
            out[name] = value
    return out


def spec_dict(s: MeasurementSpec) -> dict:
    """JSON-ready dict of a spec."""
    d = asdict(s)
    d["kind"] = s.kind.value
    return d


def _load_part(part_dir: Path | None):
    from ita.part.store import load_part

    return load_part(part_dir)


@click.group()
def spec() -> None:
    """Measurement specifications: what to measure, where, nominal and tolerance.

    Specs live in the part's specs.csv (schema: docs/specs.md). Every change is checked
    (kinds, numbers, tolerances, ids, points on the part's surface) and written
    atomically; when anything is wrong nothing is written and the exit code is 2.
    """


@spec.command("list")
@click.option("--kind", type=KIND_CHOICE, help="Only specs of this kind.")
@click.option("--json", "as_json", is_flag=True, help="Print JSON instead of a table.")
@part_option
@reports_errors
def list_cmd(kind: str | None, as_json: bool, part_dir: Path | None) -> None:
    """List the part's specs."""
    from ita.part import specfile

    specs = specfile.load(_load_part(part_dir))
    if kind:
        specs = [s for s in specs if s.kind.value == kind]
    if as_json:
        click.echo(json.dumps([spec_dict(s) for s in specs], indent=1))
        return
    click.echo(f"{'id':<16} {'kind':<17} {'feature':<12} {'nominal':>9} {'lower':>8} {'upper':>8}  datum")
    for s in specs:
        click.echo(f"{s.id:<16} {s.kind.value:<17} {s.feature:<12} {s.nominal:>9.3f} "
                   f"{s.lower:>+8.3f} {s.upper:>+8.3f}  {s.datum}")
    click.echo(f"{len(specs)} specs", err=True)


@spec.command("show")
@click.argument("spec_id")
@click.option("--json", "as_json", is_flag=True, help="Print JSON.")
@part_option
@reports_errors
def show_cmd(spec_id: str, as_json: bool, part_dir: Path | None) -> None:
    """Show every field of spec SPEC_ID."""
    from ita.errors import InputError, Location
    from ita.part import specfile

    part = _load_part(part_dir)
    found = [s for s in specfile.load(part) if s.id == spec_id]
    if not found:
        raise InputError([(Location(str(part.specs_path)), f"no spec with id {spec_id!r}")])
    s = found[0]
    if as_json:
        click.echo(json.dumps(spec_dict(s), indent=1))
        return
    rows = [
        ("id", s.id), ("kind", f"{s.kind.value}  ({KIND_DESCRIPTIONS[s.kind]})"),
        ("feature", s.feature), ("point (mm)", ", ".join(f"{c:.3f}" for c in s.point)),
        ("normal", ", ".join(f"{c:.4f}" for c in s.normal)),
        ("nominal (mm)", f"{s.nominal:.4f}"),
        ("tolerance (mm)", f"{s.lower:+.4f} / {s.upper:+.4f}  "
                           f"(limits {s.low_limit:.4f} .. {s.high_limit:.4f})"),
        ("datum", s.datum),
        ("direction", ", ".join(f"{c:.4f}" for c in s.direction) if s.direction else "-"),
        ("note", s.note or "-"),
    ]
    for key, value in rows:
        click.echo(f"{key:<15} {value}")


@spec.command("add")
@click.option("--id", "spec_id", required=True, help="New spec id.")
@field_options(required=True)
@part_option
@reports_errors
def add_cmd(spec_id: str, part_dir: Path | None, **fields: str | None) -> None:
    """Add a spec (all fields but --direction and --note are required)."""
    from ita.part import specfile

    new = specfile.add(_load_part(part_dir), {"id": spec_id, **to_columns(fields)})
    click.echo(f"added {new.id}")


@spec.command("edit")
@click.argument("spec_id")
@click.option("--id", "new_id", help="Rename the spec.")
@field_options(required=False)
@part_option
@reports_errors
def edit_cmd(spec_id: str, new_id: str | None, part_dir: Path | None, **fields: str | None) -> None:
    """Change fields of spec SPEC_ID, e.g. `ita spec edit WT-P01-1 --nominal 2.6`."""
    from ita.part import specfile

    changes = to_columns(fields)
    if new_id is not None:
        changes["id"] = new_id
    if not changes:
        raise click.UsageError("nothing to change: give at least one --FIELD VALUE")
    edited = specfile.change(_load_part(part_dir), spec_id, changes)
    click.echo(f"edited {edited.id}")


@spec.command("remove")
@click.argument("spec_ids", nargs=-1, required=True)
@part_option
@reports_errors
def remove_cmd(spec_ids: tuple[str, ...], part_dir: Path | None) -> None:
    """Remove the specs SPEC_IDS."""
    from ita.part import specfile

    left = specfile.remove(_load_part(part_dir), list(spec_ids))
    click.echo(f"removed {len(spec_ids)}; {left} specs left")


@spec.command("import")
@click.argument("file", type=click.Path(path_type=Path, dir_okay=False))
@click.option("--replace", "replace_all", is_flag=True,
              help="Replace all of the part's specs instead of adding to them.")
@click.option("--out", "out_dir", type=click.Path(path_type=Path),
              help="FILE is a QIF 3 file (MBD or plan): write its characteristics as DIR/specs.csv (those ITA "
                   "measures) and DIR/refused.csv (the others, with the reason) instead of importing into the part.")
@click.option("--expand-patterns", is_flag=True,
              help="With --out: a characteristic of several features (4X) becomes one spec per feature instead "
                   "of a refusal.")
@part_option
@reports_errors
def import_cmd(file: Path, replace_all: bool, out_dir: Path | None, expand_patterns: bool,
               part_dir: Path | None) -> None:
    """Import the specs of FILE (CSV, same schema); all rows or none.

    With --out DIR, FILE is a QIF 3 file: every characteristic is one row of
    DIR/specs.csv (ITA's spec format, the point and direction from the feature's nominal
    geometry, the tolerance, the datums) or of DIR/refused.csv (id, QIF type, reason).
    Nothing is written when FILE is not QIF 3.  Check the result with `ita spec validate
    DIR/specs.csv --part P`, then import it into the part."""
    if out_dir is None:
        if expand_patterns:
            raise click.UsageError("--expand-patterns goes with --out (a QIF file)")
        if file.suffix.lower() == ".qif":
            raise click.UsageError("a QIF file is imported with --out DIR: its specs.csv and refused.csv go there")
        from ita.part import specfile

        n = specfile.import_file(_load_part(part_dir), file, replace_all=replace_all)
        click.echo(f"imported {n} specs from {file}")
        return
    if replace_all:
        raise click.UsageError("--replace imports into the part; --out writes files (give one of them)")
    from ita.qif.specs_in import import_qif

    done = import_qif(file, out_dir, expand_patterns=expand_patterns)
    for warning in done.warnings:
        click.echo(f"warning: {warning}", err=True)
    click.echo(f"{file}: {done.characteristics} characteristics: {done.mapped} mapped to {done.specs} specs "
               f"({done.specs_path}), {done.refused} refused ({done.refused_path})")
    for reason, n in done.reasons.items():
        click.echo(f"  refused {n:>3}: {reason}")


@spec.command("export")
@click.argument("file", type=click.Path(path_type=Path, dir_okay=False))
@click.option("--kind", type=KIND_CHOICE, help="Only specs of this kind.")
@click.option("--mkdir", "make_dirs", is_flag=True, help="Create FILE's directory if it is missing.")
@part_option
@reports_errors
def export_cmd(file: Path, kind: str | None, make_dirs: bool, part_dir: Path | None) -> None:
    """Write the part's specs to FILE (CSV), atomically.

    Refuses to write over anything that is not a regular file (a device, a FIFO...)."""
    from ita.part import specfile

    part = _load_part(part_dir)
    specs = specfile.load(part)
    if kind:
        specs = [s for s in specs if s.kind.value == kind]
    n = specfile.export_file(part, file, specs, make_dirs=make_dirs)
    click.echo(f"exported {n} specs to {file}")


@spec.command("validate")
@click.argument("file", required=False, type=click.Path(path_type=Path, dir_okay=False))
@click.option("--max-distance", type=FiniteFloatRange(min=0.0), default=0.5, show_default=True,
              help="How far (mm) a spec point may lie from the part's surface.")
@part_option
@reports_errors
def validate_cmd(file: Path | None, max_distance: float, part_dir: Path | None) -> None:
    """Check FILE (default: the part's specs.csv) against the schema and the part.

    The points are checked against the mesh in chunks, so memory stays bounded however
    long the file (a million rows in under 2 GB); at most 1000 problems are listed.

    Exit codes: 0 every spec valid; 1 warnings the run can live with (a spec whose feature
    the mesh does not show: the run marks it cannot be done, with the reason, and measures
    the rest); 2 a file it cannot read, or points off the part."""
    from ita.part import specfile

    n, warnings = specfile.validate_file(_load_part(part_dir), file, max_distance)
    if not warnings:
        click.echo(f"ok: {n} specs valid")
        return
    for where, message in warnings:
        click.echo(f"warning: {where}: {message}", err=True)
    click.echo(f"{n} specs: {len(warnings)} cannot be measured (a run marks them cannot be done, with the "
               f"reason), {n - len(warnings)} valid")
    sys.exit(1)


def _triple(ctx: click.Context, param: click.Parameter, value: str | None) -> tuple[float, float, float] | None:
    """A point 'x,y,z' of three finite numbers (mm)."""
    import math

    if value is None:
        return None
    parts = value.replace(" ", "").split(",")
    try:
        out = tuple(float(x) for x in parts)
    except ValueError:
        raise click.BadParameter(f"three numbers x,y,z in mm, e.g. 10,20,3 (got {value!r})") from None
    if len(out) != 3 or not all(math.isfinite(x) for x in out):
        raise click.BadParameter(f"three finite numbers x,y,z in mm, e.g. 10,20,3 (got {value!r})")
    return (out[0], out[1], out[2])


@spec.command("pick")
@click.option("--at", "at", required=True, callback=_triple, metavar="X,Y,Z",
              help="The point picked on the part (mm, part frame; datum A at z = 0).")
@click.option("--kind", type=KIND_CHOICE, default=None,
              help="The kind of measurement wanted there (default: the first that fits).")
@click.option("--json", "as_json", is_flag=True, help="Print JSON.")
@part_option
@reports_errors
def pick_cmd(at: tuple[float, float, float], kind: str | None, as_json: bool, part_dir: Path | None) -> None:
    """Propose a spec from the part's mesh at a picked point: what is there (a hole from its
    wall or rim, a web or a wall with its back face, the top of a rib or a rim), the kinds
    that fit it, the nominal measured on the mesh, the feature, the point and the normal.
    Add it with `ita spec add` (with its tolerance and datum).

    Exit codes: 0 a proposal; 1 nothing of that kind measurable there (the reason is said,
    and in the JSON); 2 bad input."""
    from ita.offline.spec_reach import reach_at
    from ita.part.pick import propose
    from ita.workcell import workcell_for

    part = _load_part(part_dir)
    proposal = propose(part, at, None if kind is None else MeasurementKind(kind))
    reach = {} if proposal.point is None or proposal.normal is None else \
        reach_at(workcell_for(part.directory, part.mesh.bounds), proposal.point, proposal.normal)
    if as_json:
        click.echo(json.dumps({**proposal.to_dict(), "reach": reach}, indent=1))
    elif proposal.kind is None:
        click.echo(f"nothing to propose at {at}: {proposal.reason}"
                   + (f" (what fits: {', '.join(proposal.candidates)})" if proposal.candidates else ""))
    else:
        d = proposal.to_dict()
        click.echo(f"{proposal.what}: {proposal.kind} of {proposal.feature}, nominal {proposal.nominal:.4f} mm")
        click.echo(f"  point {d['point']}  normal {d['normal']}" + (f"  direction {d['direction']}"
                                                                   if d["direction"] else ""))
        click.echo("  the arm's reach: " + ", ".join(f"{c} {v}" for c, v in reach.items())
                   + ("" if "reachable" in reach.values() else "  (no tool reaches it: it would be cannot be done)"))
        if len(proposal.candidates) > 1:
            click.echo(f"  also fits: {', '.join(k for k in proposal.candidates if k != proposal.kind)} (--kind)")
        fmt = ",".join
        click.echo(f"  add it: ita spec add --id ID --kind {proposal.kind} --feature {proposal.feature} "
                   f"--point {fmt(f'{x:g}' for x in d['point'])} --normal {fmt(f'{x:g}' for x in d['normal'])} "
                   f"--nominal {proposal.nominal:g} --lower L --upper U --datum A"
                   + (f" --direction {fmt(f'{x:g}' for x in d['direction'])}" if d["direction"] else ""))
    if proposal.kind is None:
        sys.exit(1)
