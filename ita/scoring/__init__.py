"""Scoring a simulated run against the as-built part the simulator made.

Only this package (and the simulator) may read the as-built truth; the report receives
true values from here as a plain mapping and never reads them itself.
"""

from __future__ import annotations

from pathlib import Path

from ita.scoring.compare import ScoredResult, Scoring, compare

__all__ = ["ScoredResult", "Scoring", "compare", "has_true_values", "true_values"]


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
