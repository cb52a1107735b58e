"""Finding and loading parts; materialising the built-in bulkhead.

A part directory holds exactly one mesh (`*.stl`, `*.obj` or `*.ply`, millimetres, part
frame) and `specs.csv`; optionally `features.json` and `part.json` (metadata).  Features
the SLRA's specs name that features.json lacks (all of them without one) are found on the
mesh (ita.part.infer).  The
built-in bulkhead is generated on first use into `ita_home()/parts/bulkhead/` as
part.json, nominal.stl, specs.csv, features.json and truth/, and regenerated when its
generator fingerprint (part.toml plus the generator's source) changes.  A specs.csv the
user edited is never overwritten: it is kept, and the regenerated specs are written
beside it as specs.generated.csv, with a warning.

Generation writes into a temporary directory, then renames it into place, under a file
lock: a crash never leaves a half-written part, and racing processes generate it once.
Ctrl-C or SIGTERM during generation removes the temporary directory on the way out.
"""

from __future__ import annotations

import contextlib
import fcntl
import hashlib
import json
import os
import shutil
import signal
import tempfile
import threading
import uuid
import warnings
from datetime import datetime, timezone
from pathlib import Path
from typing import Any, Iterator

import numpy as np

from ita.errors import InputError, ItaWarning, Location
from ita.part import specfile
from ita.part import truth as truth_mod
from ita.part.bulkhead import default_params_path, generate, load_params
from ita.part.infer import infer_features
from ita.part.meshfile import read_mesh
from ita.part.model import Part, feature_from_dict, feature_to_dict
from ita.paths import BUILTIN_NAME, builtin_dir
from ita.specs.io import read_specs, write_specs

PART_FILE = "part.json"
MESH_FILE = "nominal.stl"
SPECS_FILE = "specs.csv"
GENERATED_SPECS_FILE = "specs.generated.csv"
FEATURES_FILE = "features.json"
MESH_SUFFIXES = (".stl", ".obj", ".ply")
ASBUILT_STEM = "asbuilt"  # asbuilt.stl beside the nominal mesh is the as-built part (the simulator's)
MIN_PART_MM = 5.0         # a mesh smaller than this across is taken for one in metres
MAX_PART_MM = 20000.0     # and larger than this (20 m) for one in micrometres
GENERATOR_MODULES = ("geometry2d", "params", "model", "layout", "mesh", "specgen", "bulkhead", "truth")


class PartWarning(ItaWarning):
    """Something about a part the user should know but that does not stop the command."""


def _sha256(path: Path) -> str:
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def fingerprint(params_path: Path) -> str:
    """Hex digest of the parameter file and the generator's source: changes when either does."""
    h = hashlib.sha256(Path(params_path).read_bytes())
    here = Path(__file__).resolve().parent
    for name in GENERATOR_MODULES:
        h.update((here / f"{name}.py").read_bytes())
    return h.hexdigest()


def _metadata(path: Path) -> dict[str, Any]:
    try:
        return json.loads((path / PART_FILE).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return {}


def _is_current(path: Path, fp: str) -> bool:
    files = (PART_FILE, MESH_FILE, SPECS_FILE, FEATURES_FILE)
    return all((path / f).is_file() for f in files) and _metadata(path).get("fingerprint") == fp


@contextlib.contextmanager
def _locked(lock_path: Path) -> Iterator[None]:
    lock_path.parent.mkdir(parents=True, exist_ok=True)
    with open(lock_path, "a+") as handle:
        fcntl.flock(handle, fcntl.LOCK_EX)
        try:
            yield
        finally:
            fcntl.flock(handle, fcntl.LOCK_UN)


@contextlib.contextmanager
def _terminated_as_exit() -> Iterator[None]:
    """While a part is generated, SIGTERM raises SystemExit(143), as Ctrl-C raises
    KeyboardInterrupt, so the `finally` that removes the temporary directory runs.  Only
    in the main thread, and only where SIGTERM still has its default action (a handler
    of the caller's is left alone)."""
    if threading.current_thread() is not threading.main_thread() \
            or signal.getsignal(signal.SIGTERM) is not signal.SIG_DFL:
        yield
        return

    def stop(signum: int, _frame: Any) -> None:
        raise SystemExit(128 + signum)

    signal.signal(signal.SIGTERM, stop)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, signal.SIG_DFL)


def _generate_into(path: Path, fp: str, params: Any = None) -> None:
    """Generate a bulkhead (nominal and truth) into the empty directory `path`: of
    `params` (ita.part.params.BulkheadParams), default the built-in part.toml's."""
    params = params if params is not None else load_params(default_params_path())
    part = generate(params)
    part.mesh.export(path / MESH_FILE)
    write_specs(path / SPECS_FILE, part.specs)
    (path / FEATURES_FILE).write_text(json.dumps([feature_to_dict(f) for f in part.features]))
    truth_mod.write_truth(path, truth_mod.make_truth(part))
    meta = {
        "name": params.part.name, "material": params.part.material, "seed": params.part.seed,
        "generator": "ita.part.bulkhead", "fingerprint": fp, "units": "mm",
        "mesh": MESH_FILE, "specs": SPECS_FILE, "features": FEATURES_FILE,
        "specs_sha256": _sha256(path / SPECS_FILE), "specs_edited": False,
        "created": datetime.now(timezone.utc).isoformat(timespec="seconds"),
    }
    (path / PART_FILE).write_text(json.dumps(meta, indent=1))


def _keep_user_specs(old: Path, new: Path) -> None:
    """Carry an edited specs.csv over from the old materialisation, with a warning."""
    recorded = _metadata(old).get("specs_sha256")
    old_specs = old / SPECS_FILE
    if not recorded or not old_specs.is_file() or _sha256(old_specs) == recorded:
        return
    shutil.move(new / SPECS_FILE, new / GENERATED_SPECS_FILE)
    shutil.copy2(old_specs, new / SPECS_FILE)
    meta = _metadata(new)
    meta["specs_sha256"] = _sha256(new / GENERATED_SPECS_FILE)
    meta["specs_edited"] = True
    (new / PART_FILE).write_text(json.dumps(meta, indent=1))
    warnings.warn(
        f"{old_specs} was edited, so it was kept; the regenerated bulkhead's specs are in "
        f"{GENERATED_SPECS_FILE} beside it", PartWarning, stacklevel=3)


def ensure_builtin() -> Path:
    """Materialise the built-in bulkhead if missing or stale; returns its directory."""
    target = builtin_dir()
    fp = fingerprint(default_params_path())
    if _is_current(target, fp):
        return target
    with _locked(target.parent / f".{BUILTIN_NAME}.lock"):
        if _is_current(target, fp):
            return target
        with _terminated_as_exit():
            tmp = Path(tempfile.mkdtemp(prefix=f".{BUILTIN_NAME}-new-", dir=target.parent))
            try:
                _generate_into(tmp, fp)
                if target.exists():
                    _keep_user_specs(target, tmp)
                    old = target.with_name(f".{BUILTIN_NAME}-old-{uuid.uuid4().hex}")
                    os.rename(target, old)
                    os.rename(tmp, target)
                    shutil.rmtree(old, ignore_errors=True)
                else:
                    os.rename(tmp, target)
            finally:
                shutil.rmtree(tmp, ignore_errors=True)
    return target


def build_part(out_dir: Path) -> Path:
    """Copy the built-in bulkhead (with its truth) into `out_dir`, which must not exist
    or be empty; returns it.  The copy is a user part: edit its specs.csv freely."""
    out_dir = Path(out_dir)
    if out_dir.exists() and (not out_dir.is_dir() or any(out_dir.iterdir())):
        raise InputError([(Location(str(out_dir)), "exists and is not an empty directory")])
    source = ensure_builtin()
    out_dir.parent.mkdir(parents=True, exist_ok=True)
    tmp = out_dir.with_name(f".{out_dir.name}-{uuid.uuid4().hex}")
    shutil.copytree(source, tmp)
    if out_dir.exists():
        out_dir.rmdir()
    os.rename(tmp, out_dir)
    return out_dir


def new_part(out_dir: Path, params_path: Path | None = None, seed: int | None = None) -> Path:
    """Generate a new bulkhead into `out_dir` (must not exist, or be empty): the built-in
    part.toml's parameters or `params_path`'s (same schema), with the generator's seed
    replaced by `seed` when given (another layout of lightening holes and specs, and
    another as-built part).  The part carries its as-built truth, as the built-in one
    does.  Returns `out_dir`."""
    from dataclasses import replace as dc_replace

    out_dir = Path(out_dir)
    if out_dir.exists() and (not out_dir.is_dir() or any(out_dir.iterdir())):
        raise InputError([(Location(str(out_dir)), "exists and is not an empty directory")])
    source = Path(params_path) if params_path is not None else default_params_path()
    params = load_params(source)
    if seed is not None:
        params = dc_replace(params, part=dc_replace(params.part, seed=int(seed)))
    fp = hashlib.sha256(f"{fingerprint(source)} seed={params.part.seed}".encode()).hexdigest()
    out_dir.parent.mkdir(parents=True, exist_ok=True)
    tmp = out_dir.with_name(f".{out_dir.name}-{uuid.uuid4().hex}")
    with _terminated_as_exit():
        tmp.mkdir()
        try:
            _generate_into(tmp, fp, params)
            _check_generated(tmp, source)
            if out_dir.exists():
                out_dir.rmdir()
            os.rename(tmp, out_dir)
        finally:
            shutil.rmtree(tmp, ignore_errors=True)
    return out_dir


def _check_generated(tmp: Path, params_path: Path) -> None:
    """A generated part whose specs leave its own surface (parameters the layout does not
    fit: an opening across the ribs, ribs too close for a pocket) is refused, naming the
    parameter file and the first specs that are off."""
    try:
        _, warnings = specfile.validate_file(load_part(tmp))
        if warnings:
            raise InputError(warnings)
    except InputError as exc:
        problems = list(exc.problems)
        raise InputError([(Location(str(params_path)), f"these parameters make a part whose specs leave its surface "
                                                        f"({len(problems)} problems; the generator's layout does not "
                                                        f"fit them), e.g. {problems[0][1]}")]) from None


def make_asbuilt(part_dir: Path, seed: int, spread: float = 0.25, out_of_tolerance: float = 0.05) -> Path:
    """Give the user part in `part_dir` an as-built mesh the program makes: its specs' holes
    redrilled off nominal, seeded (ita.part.truth.perturbed_asbuilt); asbuilt.stl and the
    statement asbuilt.json beside the nominal mesh.  Returns the mesh's path."""
    part = load_part(part_dir)
    if part.metadata.get("generator") == "ita.part.bulkhead":
        raise InputError([(Location(str(part.directory)), "a generated bulkhead has its as-built truth already "
                                                          "(ita part new --seed gives another)")])
    if not 0.0 <= spread <= 1.0 or not 0.0 <= out_of_tolerance <= 1.0:
        raise InputError([(Location("--spread/--out-of-tolerance"), "must lie in 0..1")])
    return truth_mod.write_perturbed(part.directory, part.mesh, read_specs(part.specs_path), part.features, seed,
                                     spread, out_of_tolerance)


def _find_files(path: Path) -> tuple[Path, Path]:
    """The one mesh and the specs file of a user part directory; InputError otherwise."""
    loc = Location(str(path))
    if not path.exists():
        raise InputError([(loc, "part directory not found")])
    if not path.is_dir():
        raise InputError([(loc, "not a directory (a part is a directory with a mesh and specs.csv)")])
    meshes = sorted(p for p in path.iterdir() if p.is_file() and p.suffix.lower() in MESH_SUFFIXES
                    and p.stem != ASBUILT_STEM)
    problems = []
    if not meshes:
        problems.append((loc, "no mesh: expected one *.stl, *.obj or *.ply file (besides an asbuilt.*)"))
    elif len(meshes) > 1:
        problems.append((loc, f"{len(meshes)} meshes ({', '.join(p.name for p in meshes)}); expected exactly one"))
    if not (path / SPECS_FILE).is_file():
        problems.append((loc, f"no {SPECS_FILE}"))
    if problems:
        raise InputError(problems)
    return meshes[0], path / SPECS_FILE


def part_key(part: Part) -> str:
    """The name its stores go by (sequence plan, MKB, MACROPs): the part's name and a digest
    of its content (mesh, features.json, specs.csv, workcell.toml), so a copied or edited
    part never shares a stored plan with another."""
    h = hashlib.sha256()
    directory = Path(part.directory)
    files = sorted(p for p in directory.iterdir() if p.is_file() and (
        (p.suffix.lower() in MESH_SUFFIXES and p.stem != ASBUILT_STEM)
        or p.name in (FEATURES_FILE, SPECS_FILE, "workcell.toml")))
    for f in files:
        h.update(f.name.encode() + b"\0" + hashlib.sha256(f.read_bytes()).digest())
    return f"{part.name}-{h.hexdigest()[:12]}"


def _read_part(path: Path) -> Part:
    mesh_path, specs_path = _find_files(path)
    mesh = read_mesh(mesh_path)
    extent = float(np.max(mesh.extents))
    if extent < MIN_PART_MM:
        raise InputError([(Location(str(mesh_path)), f"the mesh is {extent:.4g} units across: in metres? A part's "
                                                      f"mesh is in millimetres (scale it by 1000; a part under "
                                                      f"{MIN_PART_MM:g} mm is too small for this cell)")])
    if extent > MAX_PART_MM:
        raise InputError([(Location(str(mesh_path)), f"the mesh is {extent:.4g} units across: in micrometres, or "
                                                      f"not a part? A part's mesh is in millimetres, at most "
                                                      f"{MAX_PART_MM:g} mm across for this cell")])
    features: tuple = ()
    if (path / FEATURES_FILE).is_file():
        try:
            data = json.loads((path / FEATURES_FILE).read_text(encoding="utf-8"))
            features = tuple(feature_from_dict(d) for d in data)
        except (ValueError, KeyError, TypeError) as exc:
            raise InputError([(Location(str(path / FEATURES_FILE)), f"bad features file: {exc}")]) from None
    found, unfound = _found_features(mesh, specs_path, features)
    meta = _metadata(path)
    return Part(meta.get("name", path.name), path, mesh, features + found, specs_path, meta, unfound,
                tuple(f.id for f in found))


def _found_features(mesh, specs_path: Path, features: tuple) -> tuple[tuple, tuple]:
    """The features the specs name that `features` lacks, found on the mesh, and the specs
    whose feature is not there (ita.part.infer); none while the specs file is unreadable
    (the spec commands that mend it report that)."""
    try:
        specs = read_specs(specs_path)
    except (InputError, OSError, ValueError):
        return (), ()
    return infer_features(mesh, specs, {f.id: f for f in features})


def load_part(part_dir: Path | None = None) -> Part:
    """The part in `part_dir`, or the built-in bulkhead (materialised on first use) for None."""
    if part_dir is None:
        return _read_part(ensure_builtin())
    return _read_part(Path(part_dir).expanduser().resolve())
