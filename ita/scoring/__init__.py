"""Scoring a simulated run against the as-built part the simulator made.

Only this package (and the simulator) may read the as-built truth; the report receives
true values from here as a plain mapping and never reads them itself.
"""

from __future__ import annotations

from pathlib import Path

from ita.scoring.compare import ScoredResult, Scoring, compare

__all__ = ["ScoredResult", "Scoring", "compare", "diagnosis_score", "has_true_values", "injected_faults",
           "true_values", "truth_source"]


def has_true_values(part_dir: Path | str | None) -> bool:
    """Whether the part in `part_dir` has true values to score against: a generated part's
    as-built truth, or the mesh the simulator held (its asbuilt.stl or nominal mesh), whose
    values exact rays find (:func:`ita.part.truth.mesh_values`)."""
    if part_dir is None:
        return False
    from ita.part import truth

    d = Path(part_dir) / truth.TRUTH_DIR
    if all((d / n).is_file() for n in (truth.MESH_FILE, truth.FEATURES_FILE, truth.VALUES_FILE)):
        return True
    return Path(part_dir).is_dir() and (Path(part_dir) / "specs.csv").is_file()


def true_values(part_dir: Path | str) -> dict[str, float]:
    """Spec id -> true value in mm of the part in `part_dir`: its as-built truth's, else the
    values of the mesh the simulator held (see :func:`has_true_values`); InputError when
    there is no part there."""
    from ita.part import truth

    d = Path(part_dir) / truth.TRUTH_DIR
    if all((d / n).is_file() for n in (truth.MESH_FILE, truth.FEATURES_FILE, truth.VALUES_FILE)):
        return dict(truth.load_truth(Path(part_dir)).values)
    from ita.part.store import load_part
    from ita.specs.io import read_specs

    part = load_part(Path(part_dir))
    held = truth.simulated_part(part.directory, part.mesh)
    return truth.mesh_values(held.mesh, read_specs(part.specs_path), {f.id: f for f in part.features})


def truth_source(part_dir: Path | str | None) -> str:
    """Where the true values of the part in `part_dir` come from, in words."""
    if not has_true_values(part_dir):
        return "none"
    from ita.part import truth

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
    import json

    from ita.sim.inject import injected_log

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


#: causes of the fault knowledge base that are a form of an injected fault's cause
FORMS_OF = {"obstacle_at_arm": "obstacle"}


def diagnosis_score(injected: list[dict], diagnoses: list[dict]) -> dict:
    """Whether the diagnoses named the injected causes: what only the simulation can check.

    Each diagnosis (the archive's ``diagnosis`` event payloads) is held against the
    injected faults that were on while the plan that failed ran: injected before the
    exception and not found gone (injected_faults' ``cleared_time``) before the plan
    began (the diagnosis' ``since``; a transient is spent by the command it hits).  It names the injected
    cause when its cause is one of theirs.  Returns {"diagnoses": [... each with
    "injected" (the candidates' causes) and "named"], "with_fault": diagnoses that had an
    injected fault to find, "named": those that found it, "unexplained": injected faults
    no diagnosis named (some never raised an exception: a glitch met by a command that
    did not need the device)}."""
    rows = []
    named_any: set[int] = set()
    for d in diagnoses:
        t = d.get("t0", 0.0)
        since = d.get("since", t)
        candidates = [i for i, f in enumerate(injected) if f["sim_time"] <= t + 1e-6
                      and (f.get("cleared_time") is None or f["cleared_time"] >= since - 1e-6)]
        cause = d.get("cause") or ""
        name, _, target = cause.partition("(")
        target = target.rstrip(")")
        name = FORMS_OF.get(name, name)
        hit = next((i for i in candidates if injected[i]["cause"] == name
                    and (not target or target in (injected[i]["target"], "gauge", "controller"))), None)
        if hit is not None:
            named_any.add(hit)
        rows.append({"spec": d.get("spec"), "exception": d.get("exception"), "cause": d.get("cause"),
                     "injected": [injected[i]["cause"] for i in candidates], "named": hit is not None,
                     "summary": d.get("summary")})
    with_fault = [r for r in rows if r["injected"]]
    return {"diagnoses": rows, "with_fault": len(with_fault), "named": sum(r["named"] for r in with_fault),
            "unexplained": [f for i, f in enumerate(injected) if i not in named_any]}
