"""The true values a simulated run is scored against, and the faults injected into it.

Only this package (and the simulator) may read the as-built truth; the report receives
true values from here as a plain mapping and never reads them itself.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import TypeGuard

from ita.part import truth
from ita.part.mesh_values import mesh_values
from ita.part.store import load_part
from ita.sim.inject import injected_log
from ita.specs.io import read_specs

__all__ = ["has_true_values", "injected_faults", "run_part_truth", "true_values", "truth_source"]


def run_part_truth(part_dir: Path | str | None, settings: object) -> Path | str | None:
    """Where the true values of a run of the part in `part_dir` are: the part itself, or
    the serial's own as-built part the run held (its settings' ``asbuilt``, a directory
    under the part's ``serials/``; ita.part.serials)."""
    asbuilt = settings.get("asbuilt") if isinstance(settings, dict) else None
    if part_dir is None or not isinstance(asbuilt, str):
        return part_dir
    root = (Path(part_dir) / "serials").resolve()
    target = (Path(part_dir) / asbuilt).resolve()
    return target if target.parent == root else None


def has_true_values(part_dir: Path | str | None) -> TypeGuard[Path | str]:
    """Whether the part in `part_dir` has true values to score against: a generated part's
    as-built truth, or the mesh the simulator held (its asbuilt.stl or nominal mesh), whose
    values exact rays find (:func:`ita.part.mesh_values.mesh_values`)."""
    if part_dir is None:
        return False
    d = Path(part_dir) / truth.TRUTH_DIR
    if all((d / n).is_file() for n in (truth.MESH_FILE, truth.FEATURES_FILE, truth.VALUES_FILE)):
        return True
    return Path(part_dir).is_dir() and (Path(part_dir) / "specs.csv").is_file()


def true_values(part_dir: Path | str) -> dict[str, float]:
    """Spec id -> true value in mm of the part in `part_dir`: its as-built truth's, else the
    values of the mesh the simulator held (see :func:`has_true_values`); InputError when
    there is no part there."""
    d = Path(part_dir) / truth.TRUTH_DIR
    if all((d / n).is_file() for n in (truth.MESH_FILE, truth.FEATURES_FILE, truth.VALUES_FILE)):
        return dict(truth.load_truth(Path(part_dir)).values)

    part = load_part(Path(part_dir))
    held = truth.simulated_part(part.directory, part.mesh)
    return mesh_values(held.mesh, read_specs(part.specs_path), {f.id: f for f in part.features})


def truth_source(part_dir: Path | str | None) -> str:
    """Where the true values of the part in `part_dir` come from, in words."""
    if not has_true_values(part_dir):
        return "none"
    d = Path(part_dir) / truth.TRUTH_DIR
    if all((d / n).is_file() for n in (truth.MESH_FILE, truth.FEATURES_FILE, truth.VALUES_FILE)):
        return "the generated part's as-built truth"
    own = truth.asbuilt_mesh_path(Path(part_dir))
    return (f"the values of {own.name if own else 'the nominal mesh'}, the part the simulated cell held, "
            "found with exact rays")


def injected_faults(runs_dir: Path | str, run_id: str) -> list[dict]:
    """The faults injected into run `run_id` (ita.sim.inject's log beside the archive), in
    order, each with ``cleared_time``: the simulated time it was found gone (None: on to
    the end); empty when none were injected."""
    path = injected_log(Path(runs_dir), run_id)
    if not path.is_file():
        return []
    records = [json.loads(line) for line in path.read_text(encoding="utf-8").splitlines() if line.strip()]
    out: list[dict] = []
    for r in records:
        if "cleared" in r:
            hit = next((f for f in out if f["fault"] == r["cleared"] and f["target"] == r["target"]
                        and f["cleared_time"] is None), None)
            if hit is not None:
                hit["cleared_time"] = r["sim_time"]
        else:
            out.append({**r, "cleared_time": None})
    return out
