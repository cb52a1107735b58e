"""Which specs the arm can reach, by the simple geometric test of ita.workcell.reach.

The tool class that measures each kind comes from the tool rules of kb/tools.pl (its
most preferred rule), not from Python: the rules the Sequence Planner decides by.
"""

from __future__ import annotations

from typing import Sequence

import numpy as np

from ita.logic.bridge import KnowledgeBase
from ita.logic.terms import Var
from ita.specs.model import MeasurementKind, MeasurementSpec
from ita.workcell import ReachReport, Workcell, reach_report


def tool_class_of_kinds(kb: KnowledgeBase) -> dict[MeasurementKind, str]:
    """Tool class (`us_tool`, `slra_tool`) for each measurement kind: the type of the most
    preferred tool rule of kb/tools.pl for the kind (``tools:preferred_tool_type/2``)."""
    out: dict[MeasurementKind, str] = {}
    for kind in MeasurementKind:
        found = kb.once("tools", "preferred_tool_type", kind.value, Var("Type"))
        if found is not None:
            out[kind] = str(found["Type"])
    return out


def spec_reach(specs: Sequence[MeasurementSpec], workcell: Workcell, kb: KnowledgeBase) -> ReachReport:
    """The reach verdict of every spec with the tool its kind needs."""
    tools = tool_class_of_kinds(kb)
    missing = sorted({s.kind.value for s in specs if s.kind not in tools})
    if missing:
        raise KeyError(f"no tool class in the knowledge bases for kind(s): {', '.join(missing)}")
    points = np.array([s.point for s in specs], dtype=float).reshape(-1, 3)
    normals = np.array([s.normal for s in specs], dtype=float).reshape(-1, 3)
    return reach_report(workcell, points, normals, [tools[s.kind] for s in specs])


def reach_at(workcell: Workcell, point_mm: Sequence[float], normal: Sequence[float]) -> dict[str, str]:
    """Tool class -> the arm's reach verdict for a measurement at `point_mm` along `normal`
    (part frame), for every tool class the cell has (a proposal shown before it is saved:
    ita.part.pick; which class the kind takes is the tool rules', at `ita prepare`)."""
    classes = sorted({t.tool_class.value for t in workcell.tools})
    if not classes:
        return {}
    report = reach_report(workcell, np.tile(np.asarray(point_mm, dtype=float), (len(classes), 1)),
                          np.tile(np.asarray(normal, dtype=float), (len(classes), 1)), classes)
    return {c: v.value for c, v in zip(classes, report.verdicts)}
