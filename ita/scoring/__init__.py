"""Scoring a simulated run against the as-built part the simulator made.

Only this package (and the simulator) may read the as-built truth; the report receives
true values from here as a plain mapping and never reads them itself.
"""

from __future__ import annotations

from pathlib import Path

from ita.scoring.compare import ScoredResult, Scoring, compare

__all__ = ["ScoredResult", "Scoring", "compare", "diagnosis_score", "has_true_values", "injected_faults",
           "true_values"]


def has_true_values(part_dir: Path | str | None) -> bool:
    """Whether the part in `part_dir` carries an as-built truth (generated parts do)."""
    if part_dir is None:
        return False
    from ita.part import truth

    d = Path(part_dir) / truth.TRUTH_DIR
    return all((d / n).is_file() for n in (truth.MESH_FILE, truth.FEATURES_FILE, truth.VALUES_FILE))


def true_values(part_dir: Path | str) -> dict[str, float]:
    """Spec id -> true (as-built) value in mm of the part in `part_dir`; InputError without one."""
    from ita.part.truth import load_truth

    return dict(load_truth(Path(part_dir)).values)


def injected_faults(runs_dir: Path | str, run_id: str) -> list[dict]:
    """The faults injected into run `run_id` (ita.sim.inject's log beside the archive), in
    order; empty when none were."""
    import json

    from ita.sim.inject import injected_log

    path = injected_log(Path(runs_dir), run_id)
    if not path.is_file():
        return []
    return [json.loads(line) for line in path.read_text(encoding="utf-8").splitlines() if line.strip()]


def diagnosis_score(injected: list[dict], diagnoses: list[dict]) -> list[dict]:
    """Each injected fault with the first diagnosis made at or after it that involves its
    device, and whether that diagnosis named the injected cause (``found``): what only
    the simulation can check.  diagnoses: the archive's ``diagnosis`` event payloads."""
    out = []
    used: set[int] = set()
    for fault in injected:
        match = None
        for i, d in enumerate(diagnoses):
            if i in used or d.get("t1", 0.0) < fault["sim_time"]:
                continue
            match = i
            break
        cause = None if match is None else diagnoses[match].get("cause")
        if match is not None:
            used.add(match)
        name = (cause or "").partition("(")[0]
        target = (cause or "").partition("(")[2].rstrip(")")
        found = name == fault["cause"] and (not target or target in (fault["target"], "gauge", "controller"))
        out.append({**fault, "diagnosis": None if match is None else diagnoses[match].get("summary"),
                    "cause_found": cause, "found": bool(found)})
    return out
