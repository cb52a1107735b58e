"""The as-built truth of a generated part: how every feature really came out of machining.

This is the ONLY module that makes, writes or reads truth files (`<part>/truth/`).  Only
the simulator and the scoring may use it; planning, vision and measuring code must not
(tests/test_part_truth.py scans the source tree to hold that line).

Model: every dimension of every feature deviates from nominal by a normal draw with one
sigma = `spread` x its tolerance (true position: the radial offset, per axis sigma =
spread x zone radius / sqrt 2), clipped to 0.9 of the tolerance; then a seeded
`out_of_tolerance` fraction of the features gets one dimension pushed 1.15 to 1.6
tolerances off.  Datum holes B and C define the frame and so do not move.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any, Sequence

import numpy as np
import trimesh

from ita.errors import InputError, Location
from ita.files.atomic import write_atomic, write_with
from ita.part.bulkhead import GeneratedPart
from ita.part.faces import offset_faces
from ita.part.infer import MeshRays, basis
from ita.part.mesh import build_mesh
from ita.part.meshfile import read_mesh
from ita.part.model import (
    Feature,
    FlangeSegment,
    Hole,
    HoleRole,
    Pocket,
    Stiffener,
    feature_from_dict,
    feature_to_dict,
)
from ita.part.params import Tolerance
from ita.specs.model import MeasurementKind as K
from ita.specs.model import MeasurementSpec

TRUTH_DIR = "truth"
MESH_FILE = "asbuilt.ply"  # indexed, float64: kept exactly as built (see mesh.to_trimesh)
FEATURES_FILE = "asbuilt_features.json"
VALUES_FILE = "truth.json"


@dataclass(frozen=True, eq=False)
class Truth:
    """The as-built part: features, mesh (mm), true value of each spec, deviations.

    values: spec id -> true value (mm); deviations: feature id -> {dimension: deviation};
    out_of_tolerance: ids of the features made out of tolerance on purpose.
    """

    features: tuple[Feature, ...]
    mesh: trimesh.Trimesh
    values: dict[str, float]
    deviations: dict[str, dict[str, float]]
    out_of_tolerance: tuple[str, ...]
    seed: int


def _dimensions(f: Feature, tol: Tolerance) -> dict[str, float]:
    """Tolerance (half band, or true-position zone diameter for "position") per dimension."""
    if isinstance(f, Pocket):
        return {"web_thickness": tol.thickness}
    if isinstance(f, Stiffener):
        return {"height": tol.height, "width": tol.thickness}
    if isinstance(f, FlangeSegment):
        return {"height": tol.height, "cap_width": tol.general,
                "cap_thickness": tol.thickness, "wall_thickness": tol.thickness}
    dia = {HoleRole.FASTENER: tol.fastener_diameter, HoleRole.TOOLING: tol.tooling_diameter,
           HoleRole.LIGHTENING: tol.lightening_diameter}[f.role]
    if f.role is HoleRole.TOOLING:
        return {"diameter": dia}
    pos = tol.true_position if f.role is HoleRole.FASTENER else tol.lightening_true_position
    return {"diameter": dia, "position": pos}


def draw_deviations(features: Sequence[Feature], tol: Tolerance, spread: float, fraction: float,
                    rng: np.random.Generator) -> tuple[dict[str, dict[str, float]], tuple[str, ...]]:
    """Deviations per feature and dimension ("position" -> "dx", "dy"), and the ids of the
    features made out of tolerance."""
    devs: dict[str, dict[str, float]] = {}
    for f in features:
        d: dict[str, float] = {}
        for dim, t in _dimensions(f, tol).items():
            if dim == "position":
                r = t / 2
                dx, dy = np.clip(rng.normal(0.0, spread * r / math.sqrt(2), 2), -0.6 * r, 0.6 * r)
                d["dx"], d["dy"] = float(dx), float(dy)
            else:
                d[dim] = float(np.clip(rng.normal(0.0, spread * t), -0.9 * t, 0.9 * t))
        devs[f.id] = d
    n_out = int(round(fraction * len(features)))
    out = sorted(rng.choice([f.id for f in features], size=n_out, replace=False).tolist())
    by_id = {f.id: f for f in features}
    for fid in out:
        dims = _dimensions(by_id[fid], tol)
        dim = sorted(dims)[int(rng.integers(len(dims)))]
        size = float(rng.uniform(1.15, 1.6))
        if dim == "position":
            ang = float(rng.uniform(0, 2 * math.pi))
            devs[fid]["dx"] = size * dims[dim] / 2 * math.cos(ang)
            devs[fid]["dy"] = size * dims[dim] / 2 * math.sin(ang)
        else:
            devs[fid][dim] = float(rng.choice([-1.0, 1.0])) * size * dims[dim]
    return devs, tuple(out)


def apply_deviations(features: Sequence[Feature], devs: dict[str, dict[str, float]]) -> tuple[Feature, ...]:
    """The as-built features: nominal features with their deviations applied."""
    out: list[Feature] = []
    for f in features:
        d = devs.get(f.id, {})
        changes = {k: getattr(f, k) + v for k, v in d.items() if k not in ("dx", "dy")}
        if isinstance(f, Hole):
            x, y, z = f.center
            changes["center"] = (x + d.get("dx", 0.0), y + d.get("dy", 0.0), z)
        out.append(replace(f, **changes))
    flanges = {f.id: f for f in out if isinstance(f, FlangeSegment)}
    return tuple(
        replace(f, center=(f.center[0], f.center[1], flanges[f.parent].height))
        if isinstance(f, Hole) and f.role is HoleRole.FASTENER and f.parent in flanges else f
        for f in out
    )


def true_values(specs: Sequence[MeasurementSpec], nominal: Sequence[Feature],
                asbuilt: Sequence[Feature]) -> dict[str, float]:
    """Spec id -> true (as-built) value; specs of unknown features are left out."""
    nom, act = {f.id: f for f in nominal}, {f.id: f for f in asbuilt}
    values: dict[str, float] = {}
    for s in specs:
        if s.feature not in act:
            continue
        f, f0 = act[s.feature], nom[s.feature]
        # each kind of spec is on its one kind of feature (a spec's feature of another kind
        # fails here as it did on its missing attribute)
        if s.kind is K.WEB_THICKNESS:
            assert isinstance(f, Pocket) and isinstance(f0, Pocket)
            v = s.nominal + f.web_thickness - f0.web_thickness
        elif s.kind is K.FLANGE_THICKNESS:
            dim = "cap_thickness" if s.normal[2] > 0.5 else "wall_thickness"
            v = s.nominal + getattr(f, dim) - getattr(f0, dim)
        elif s.kind in (K.FLANGE_HEIGHT, K.STIFFENER_HEIGHT):
            assert isinstance(f, (FlangeSegment, Stiffener)) and isinstance(f0, (FlangeSegment, Stiffener))
            v = s.nominal + f.height - f0.height
        elif s.kind is K.FLANGE_WIDTH:
            assert isinstance(f, FlangeSegment) and isinstance(f0, FlangeSegment)
            v = s.nominal + f.cap_width - f0.cap_width
        elif s.kind is K.STIFFENER_WIDTH:
            assert isinstance(f, Stiffener) and isinstance(f0, Stiffener)
            v = s.nominal + f.width - f0.width
        elif s.kind is K.HOLE_DIAMETER:
            assert isinstance(f, Hole) and isinstance(f0, Hole)
            v = s.nominal + f.diameter - f0.diameter
        elif s.kind is K.HOLE_POSITION:
            assert isinstance(f, Hole) and isinstance(f0, Hole)
            v = 2.0 * math.dist(f.center[:2], f0.center[:2])
        elif s.kind is K.EDGE_DISTANCE:
            assert isinstance(f, Hole) and isinstance(f0, Hole)
            shift = np.subtract(f.center[:2], f0.center[:2])
            grow = 0.0
            if f.parent in act:
                flange, flange0 = act[f.parent], nom[f.parent]
                assert isinstance(flange, FlangeSegment) and isinstance(flange0, FlangeSegment)
                grow = flange.cap_width - flange0.cap_width
            v = s.nominal + grow - float(np.dot(shift, (s.direction or (0.0, 0.0, 0.0))[:2]))
        else:
            continue
        values[s.id] = round(float(v), 6)
    return values


def make_truth(part: GeneratedPart) -> Truth:
    """Draw the as-built part of a generated part (seeded by its parameters)."""
    p = part.params
    rng = np.random.default_rng([p.part.seed, 1])
    devs, out = draw_deviations(part.features, p.tolerance, p.truth.spread,
                                p.truth.out_of_tolerance, rng)
    asbuilt = apply_deviations(part.features, devs)
    return Truth(asbuilt, build_mesh(asbuilt), true_values(part.specs, part.features, asbuilt),
                 devs, out, p.part.seed)


def write_truth(part_dir: Path, truth: Truth) -> None:
    """Write `truth` under `<part_dir>/truth/` (mesh, as-built features, values)."""
    d = Path(part_dir) / TRUTH_DIR
    d.mkdir(parents=True, exist_ok=True)
    truth.mesh.export(d / MESH_FILE)
    (d / FEATURES_FILE).write_text(json.dumps([feature_to_dict(f) for f in truth.features]))
    (d / VALUES_FILE).write_text(json.dumps({
        "seed": truth.seed, "out_of_tolerance": list(truth.out_of_tolerance),
        "values": truth.values, "deviations": truth.deviations}, indent=1, sort_keys=True))


def require_truth(part_dir: Path) -> None:
    """InputError (before any long work) when the part in `part_dir` has no as-built truth,
    which the simulated workcell needs."""
    d = Path(part_dir) / TRUTH_DIR
    missing = [n for n in (MESH_FILE, FEATURES_FILE, VALUES_FILE) if not (d / n).is_file()]
    if missing:
        raise InputError([(Location(str(d)), f"no as-built truth here (missing {', '.join(missing)}); "
                           "only generated parts carry one, and the simulated workcell needs it")])


def load_truth(part_dir: Path) -> Truth:
    """The as-built truth of the part in `part_dir`; InputError when it has none."""
    d = Path(part_dir) / TRUTH_DIR
    require_truth(part_dir)
    try:
        data = json.loads((d / VALUES_FILE).read_text())
        features = tuple(feature_from_dict(x) for x in json.loads((d / FEATURES_FILE).read_text()))
    except (ValueError, KeyError, TypeError) as exc:
        raise InputError([(Location(str(d)), f"corrupt truth files: {exc}")]) from None
    mesh = trimesh.load_mesh(d / MESH_FILE, process=False)
    return Truth(features, mesh, {k: float(v) for k, v in data["values"].items()},
                 data["deviations"], tuple(data["out_of_tolerance"]), int(data["seed"]))


ASBUILT_STEM = "asbuilt"   # a user's as-built mesh beside the nominal one: asbuilt.stl (.obj, .ply)


@dataclass(frozen=True, eq=False)
class SimulatedPart:
    """The part the simulated workcell holds: its mesh (mm), the holes whose rims the
    simulator takes as exact circles (a generated part's as-built holes along +Z; none for
    a mesh), and where it came from: "generated" (the part's as-built truth, with true
    values), "as-built mesh" (the user's asbuilt.stl) or "nominal mesh" (no as-built
    given: the part is simulated as designed).  description says it in a sentence."""

    mesh: trimesh.Trimesh
    holes: tuple[Hole, ...]
    source: str
    description: str


def asbuilt_mesh_path(part_dir: Path) -> Path | None:
    """A user's as-built mesh in the part directory (asbuilt.stl, .obj or .ply), if any."""
    found = sorted(p for p in Path(part_dir).glob(f"{ASBUILT_STEM}.*") if p.suffix.lower() in (".stl", ".obj", ".ply"))
    return found[0] if found else None


def simulated_part(part_dir: Path, nominal: trimesh.Trimesh) -> SimulatedPart:
    """What the simulator holds for the part in `part_dir` (nominal: its nominal mesh): the
    as-built truth when it has one, else the user's as-built mesh, else the nominal mesh."""
    d = Path(part_dir) / TRUTH_DIR
    if all((d / n).is_file() for n in (MESH_FILE, FEATURES_FILE, VALUES_FILE)):
        t = load_truth(part_dir)
        return SimulatedPart(t.mesh, tuple(f for f in t.features if isinstance(f, Hole)), "generated",
                             f"the generated part's as-built truth (seed {t.seed}); results are scored against it")
    own = asbuilt_mesh_path(part_dir)
    if own is not None:
        mesh = read_mesh(own, "the as-built mesh")
        gap = float(np.max(np.abs(np.asarray(mesh.bounds) - np.asarray(nominal.bounds))))
        if gap > 0.05 * float(np.max(nominal.extents)) + 5.0:
            raise InputError([(Location(str(own)), f"the as-built mesh's box is {gap:.1f} mm off the nominal's: "
                                                    "it must be the same part in the same frame and units (mm)")])
        made = (Path(part_dir) / ASBUILT_STATEMENT).is_file()
        return SimulatedPart(mesh, (), "as-built mesh", f"the as-built mesh {own.name} ("
                             f"{'made by ita part asbuilt, asbuilt.json says how' if made else 'the user’s'}); "
                             "true values are its own, found with exact rays")
    return SimulatedPart(nominal, (), "nominal mesh", "the nominal mesh (no as-built part given: simulated as "
                                                      "designed); true values are its own, found with exact rays")


ASBUILT_STATEMENT = "asbuilt.json"   # the stated deviations of an as-built mesh the program made


def _cylinder(centre: np.ndarray, axis: np.ndarray, radius: float, length: float) -> trimesh.Trimesh:
    """A 256-sided cylinder of `length` along unit `axis`, centred on `centre` (a cutter)."""
    rot = trimesh.geometry.align_vectors([0.0, 0.0, 1.0], axis)
    rot[:3, 3] = centre
    return trimesh.creation.cylinder(radius=radius, height=length, sections=256, transform=rot)


def perturbed_asbuilt(mesh: trimesh.Trimesh, specs: Sequence[MeasurementSpec], features: Sequence[Feature],
                      seed: int, spread: float = 0.25, out_of_tolerance: float = 0.05
                      ) -> tuple[trimesh.Trimesh, dict[str, Any]]:
    """An as-built part of a mesh part: each hole the specs name (found on the mesh) redrilled
    with its diameter and position off nominal by normal draws (one sigma = `spread` x the
    spec's tolerance: the diameter's half band, the position zone's radius / sqrt 2 per
    axis, clipped to 0.9 of it), and a seeded `out_of_tolerance` share of them pushed 1.15
    to 1.6 tolerances off, as the generator does for its bulkheads.  The hole is filled
    (a plug a little wider than it, over its depth) and cut again.  Then the flat faces the
    thickness, height and width specs end on are moved off nominal the same way
    (ita.part.faces.offset_faces).  Returns the mesh and the statement of what was done
    (per hole: the diameter change and the shift, mm; per face: its specs and offset)."""
    rng = np.random.default_rng([seed, 3])
    by_feature: dict[str, dict[K, MeasurementSpec]] = {}
    for s in specs:
        by_feature.setdefault(s.feature, {})[s.kind] = s
    holes = [f for f in features if isinstance(f, Hole) and f.id in by_feature]
    devs: dict[str, dict[str, float]] = {}
    for h in holes:
        mine = by_feature[h.id]
        d_tol = mine[K.HOLE_DIAMETER].upper if K.HOLE_DIAMETER in mine else 0.0
        zone = mine[K.HOLE_POSITION].upper if K.HOLE_POSITION in mine else 0.0
        dd = float(np.clip(rng.normal(0.0, spread * d_tol), -0.9 * d_tol, 0.9 * d_tol)) if d_tol else 0.0
        shift = np.clip(rng.normal(0.0, spread * zone / 2 / math.sqrt(2), 2), -0.6 * zone / 2, 0.6 * zone / 2) \
            if zone else np.zeros(2)
        devs[h.id] = {"diameter": dd, "du": float(shift[0]), "dv": float(shift[1])}
    out = sorted(rng.choice([h.id for h in holes], size=int(round(out_of_tolerance * len(holes))),
                            replace=False).tolist()) if holes else []
    for hid in out:
        mine = by_feature[hid]
        size = float(rng.uniform(1.15, 1.6))
        if K.HOLE_DIAMETER in mine and (K.HOLE_POSITION not in mine or rng.random() < 0.5):
            devs[hid]["diameter"] = float(rng.choice([-1.0, 1.0])) * size * mine[K.HOLE_DIAMETER].upper
        elif K.HOLE_POSITION in mine:
            ang = float(rng.uniform(0, 2 * math.pi))
            r = size * mine[K.HOLE_POSITION].upper / 2
            devs[hid]["du"], devs[hid]["dv"] = r * math.cos(ang), r * math.sin(ang)
    rays = MeshRays(mesh)
    plugs, cutters, statement = [], [], {}
    for h in holes:
        n = np.asarray(h.axis, dtype=float)
        c = np.asarray(h.center, dtype=float)
        u, v = basis(n)
        d = devs[h.id]
        r = h.diameter / 2
        through = float(rays.first((c + n)[None], (-n)[None])[0]) > h.depth + 1.5
        plugs.append(_cylinder(c - n * h.depth / 2, n, r + 0.3, h.depth))
        new_c = c + d["du"] * u + d["dv"] * v
        if through:
            cutters.append(_cylinder(new_c - n * (h.depth / 2), n, r + d["diameter"] / 2, h.depth + 2.0))
        else:
            cutters.append(_cylinder(new_c - n * (h.depth - 1.0) / 2, n, r + d["diameter"] / 2, h.depth + 1.0))
        shift = d["du"] * u + d["dv"] * v
        statement[h.id] = {"diameter_change_mm": round(d["diameter"], 6),
                           "shift_mm": [round(float(x), 6) for x in shift]}
    made = mesh
    if holes:
        made = trimesh.boolean.union([mesh, *plugs]).difference(trimesh.boolean.union(cutters))
    made, faces = offset_faces(made, specs, np.random.default_rng([seed, 4]), spread, out_of_tolerance)
    return made, {"seed": seed, "spread": spread, "out_of_tolerance": out_of_tolerance,
                  "pushed_out_of_tolerance": out, "holes": statement, "faces": faces,
                  "unchanged": "everything but the holes the specs name and the flat faces their thicknesses, "
                               "heights and widths end on (every true value is the mesh's own)"}


def write_perturbed(part_dir: Path, mesh: trimesh.Trimesh, specs: Sequence[MeasurementSpec],
                    features: Sequence[Feature], seed: int, spread: float, out_of_tolerance: float) -> Path:
    """Make the part's as-built mesh (asbuilt.stl) and its statement (asbuilt.json) with
    :func:`perturbed_asbuilt`; an existing asbuilt.* is refused (never overwritten)."""
    part_dir = Path(part_dir)
    own = asbuilt_mesh_path(part_dir)
    if own is not None:
        raise InputError([(Location(str(own)), "the part already has an as-built mesh; remove it first")])
    made, statement = perturbed_asbuilt(mesh, specs, features, seed, spread, out_of_tolerance)
    if not made.is_watertight:
        raise InputError([(Location(str(part_dir)), "the redrilled as-built mesh is not watertight (holes too "
                                                    "close to each other or to an edge to redrill)")])
    statement_path = part_dir / ASBUILT_STATEMENT
    had_statement = statement_path.exists()
    try:  # a failed write (a full disk) leaves neither a temporary file nor half a pair
        write_atomic(statement_path, json.dumps(statement, indent=1, sort_keys=True))
        write_with(part_dir / f"{ASBUILT_STEM}.stl", made.export, suffix=".stl")
    except BaseException:
        if not had_statement:
            statement_path.unlink(missing_ok=True)
        raise
    return part_dir / f"{ASBUILT_STEM}.stl"
