"""`ita part`: look at the part to inspect (info, render) and copy the built-in one (build)."""

from __future__ import annotations

import json
from pathlib import Path

import click

from ita.cli.common import FiniteFloatRange, part_option, reports_errors, seed_option
from ita.errors import InputError, Location


@click.group()
def part() -> None:
    """The part to inspect: the built-in bulkhead, or --part DIR."""


@part.command()
@part_option
@click.option("--json", "as_json", is_flag=True, help="Print the summary as JSON.")
@reports_errors
def info(part_dir: Path | None, as_json: bool) -> None:
    """Print the part's size, its features and specs counted by kind."""
    from ita.logic.bridge import KnowledgeBase
    from ita.offline.spec_reach import spec_reach
    from ita.part.store import load_part
    from ita.part.summary import summarize
    from ita.specs.io import read_specs
    from ita.workcell import workcell_for

    loaded = load_part(part_dir)
    specs = read_specs(loaded.specs_path)
    reach = spec_reach(specs, workcell_for(loaded.directory, loaded.mesh.bounds), KnowledgeBase())
    unreachable = reach.n_unreachable
    summary = summarize(loaded, specs, unreachable=unreachable)
    if as_json:
        data = summary.to_dict()
        data["reach"] = {r.value: n for r, n in reach.counts().items()}
        click.echo(json.dumps(data, indent=1))
        return
    sx, sy, sz = summary.size
    click.echo(f"part       {summary.name}  ({summary.directory})")
    click.echo(f"size       {sx:.1f} x {sy:.1f} x {sz:.1f} mm (X x Y x Z)")
    click.echo(f"mesh       {summary.triangles} triangles, "
               f"{'watertight' if summary.watertight else 'NOT watertight'}")
    click.echo(f"features   {summary.feature_count}")
    for kind, n in summary.features:
        click.echo(f"  {kind:<18} {n:>5}")
    click.echo(f"specs      {summary.spec_count}")
    for kind, n in summary.specs:
        click.echo(f"  {kind:<18} {n:>5}")
    click.echo(reach.summary())


@part.command()
@part_option
@click.option("-o", "--output", type=click.Path(path_type=Path, dir_okay=False), required=True,
              help="PNG file to write, exactly this name (no extension is added).")
@click.option("--mkdir", "make_dirs", is_flag=True, help="Create the output's directory if it is missing.")
@reports_errors
def render(part_dir: Path | None, output: Path, make_dirs: bool) -> None:
    """Draw the part seen from +Z with its spec points coloured by kind (PNG).

    Refuses to write over anything that is not a regular file (a device, a FIFO...)."""
    from ita.part.render import render_part
    from ita.part.store import load_part
    from ita.specs.io import read_specs

    loaded = load_part(part_dir)
    written = render_part(loaded, read_specs(loaded.specs_path), output, make_dirs=make_dirs)
    click.echo(f"wrote {written}")


@part.command("new")
@click.argument("directory", type=click.Path(path_type=Path, file_okay=False))
@click.option("--params", "params_path", type=click.Path(path_type=Path, dir_okay=False, exists=True), default=None,
              help="A part.toml of the bulkhead generator (default: the built-in bulkhead's, bulkhead/part.toml): "
                   "other dimensions, flanges, stiffeners, holes, tolerances.")
@seed_option(default=None,
              help="The generator's seed (default: the parameter file's): another layout of lightening holes "
                   "and another as-built part.  Not the simulator's noise: that is `ita inspect --seed`.")
@reports_errors
def new(directory: Path, params_path: Path | None, seed: int | None) -> None:
    """Generate a new bulkhead into DIRECTORY (new or empty): nominal mesh, specs.csv,
    features and its as-built truth, ready for `ita inspect --part DIRECTORY`.

    Families of parts for tests and studies: `ita part new ref --seed 7`."""
    from ita.part.params import BulkheadParams

    if params_path is not None:
        BulkheadParams.load(params_path)  # ranges and constraints: refused at once, before the generator loads
    from ita.part.store import new_part

    made = new_part(directory, params_path, seed)
    click.echo(f"wrote {made}")


@part.command()
@click.option("-o", "--output", type=click.Path(path_type=Path, file_okay=False), default=None,
              help="Copy the built-in bulkhead into this new directory (an editable part).")
@reports_errors
def build(output: Path | None) -> None:
    """Generate the built-in bulkhead (if needed); with -o, copy it into a directory."""
    from ita.part.store import build_part, ensure_builtin

    if output is None:
        click.echo(f"built-in bulkhead at {ensure_builtin()}")
    else:
        click.echo(f"wrote {build_part(output)}")


@part.command()
@part_option
@click.option("--repeats", type=click.IntRange(min=2), default=4, show_default=True,
              help="Frames of each spec on the master, each after its own approach of the arm.")
@seed_option(help="Seed of the simulated frames' noise.")
@reports_errors
def calibrate(part_dir: Path | None, repeats: int, seed: int) -> None:
    """Calibrate the laser sensor on the part's master (the substitution method): measure
    every hole diameter, edge distance, flange and rib width of the part on its nominal
    geometry, whose values are known, REPEATS times; write the biases and uncertainties
    to the part's slra_calibration.json, which Vision then applies to this part's results.

    `ita prepare` (and `ita inspect`) make it when it is missing or stale, with 4 repeats;
    this makes it again now.  The cell's calibration stands for generated bulkheads only:
    a generated bulkhead is refused here.  The master is measured the way a run measures
    (the MKB's views), so the part is prepared first when it needs to be."""
    from ita.offline.master import ensure_master_calibration
    from ita.offline.prepare import prepare_inspection
    from ita.part.store import load_part
    from ita.sequence.plan import planning_context
    from ita.vision.for_part import part_calibration_path

    part = load_part(part_dir)
    if part_dir is None or part.metadata.get("generator") == "ita.part.bulkhead":
        raise InputError([(Location(str(part.directory)), "a generated bulkhead uses the cell's calibration "
                                                          "(bench/slra_calibration.py); calibrate a part of your own")])
    ctx = planning_context(part_dir, part=part)
    say = lambda m: click.echo(f"{m} ...", err=True)  # noqa: E731
    _, mkb, _ = prepare_inspection(ctx, part, progress=say, warm=False, calibrate=False)
    done = ensure_master_calibration(part, ctx.workcell, ctx.part_name, say, force=True, repeats=repeats, mkb=mkb,
                                     seed=seed)
    click.echo(f"wrote {part_calibration_path(part.directory)}: {done}")


@part.command()
@part_option
@seed_option(default=None, required=True, help="Seed of the deviations (another seed, another as-built part).")
@click.option("--spread", type=FiniteFloatRange(0.0, 1.0), default=0.25, show_default=True,
              help="One sigma of a deviation as a share of its tolerance.")
@click.option("--out-of-tolerance", type=FiniteFloatRange(0.0, 1.0), default=0.05, show_default=True,
              help="Share of the holes, and of the faces, pushed 1.15 to 1.6 tolerances off.")
@reports_errors
def asbuilt(part_dir: Path | None, seed: int, spread: float, out_of_tolerance: float) -> None:
    """Make an as-built part of your own part for the simulated cell: every hole its specs
    name redrilled off nominal (diameter and position, seeded draws) and every flat face
    its thicknesses, heights and widths end on moved along its normal, written as
    asbuilt.stl beside the nominal mesh with the statement of what was done in
    asbuilt.json.  Runs then inspect the as-built part, and reports score the results
    against its own values.  An existing asbuilt.* is never overwritten."""
    from ita.part.store import make_asbuilt

    if part_dir is None:
        raise InputError([(Location("--part"), "name your part's directory (the built-in bulkhead has its truth)")])
    click.echo(f"wrote {make_asbuilt(part_dir, seed, spread, out_of_tolerance)}")
