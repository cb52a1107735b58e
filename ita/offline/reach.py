"""Which specs the arm can reach, by the simple geometric test of ita.workcell.reach.

The tool class that measures each kind comes from the knowledge bases (Prolog), not from
Python: the same rules the planners use.
"""

from __future__ import annotations

from pathlib import Path
from typing import Sequence

import numpy as np

from ita.logic.bridge import KnowledgeBase
from ita.logic.terms import Var
from ita.specs.model import MeasurementKind, MeasurementSpec
from ita.workcell import ReachReport, Workcell, load_workcell, reach_report


def workcell_for(part_directory: Path) -> Workcell:
    """The part's own workcell.toml when it has one, else the built-in workcell."""
    own = Path(part_directory) / "workcell.toml"
    return load_workcell(own if own.is_file() else None)


def tool_class_of_kinds(kb: KnowledgeBase) -> dict[MeasurementKind, str]:
    """Tool class (`us_tool`, `slra_tool`) for each measurement kind, from kb/operators.pl."""
    rows = kb.call("operators", "kind_tool_type", Var("Kind"), Var("Type"))
    found = {str(r["Kind"]): str(r["Type"]) for r in rows}
    return {k: found[k.value] for k in MeasurementKind if k.value in found}


def spec_reach(specs: Sequence[MeasurementSpec], workcell: Workcell, kb: KnowledgeBase) -> ReachReport:
    """The reach verdict of every spec with the tool its kind needs."""
    tools = tool_class_of_kinds(kb)
    missing = sorted({s.kind.value for s in specs if s.kind not in tools})
    if missing:
        raise KeyError(f"no tool class in the knowledge bases for kind(s): {', '.join(missing)}")
    points = np.array([s.point for s in specs], dtype=float).reshape(-1, 3)
    normals = np.array([s.normal for s in specs], dtype=float).reshape(-1, 3)
    return reach_report(workcell, points, normals, [tools[s.kind] for s in specs])
