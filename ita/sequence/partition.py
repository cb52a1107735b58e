"""Partition measurements by the tool that will take them (the Sequence Planner's first step).

The decision is Prolog's (``kb/tools.pl``: tool rules, meta-level preferences, the world
model's tool availability); this module computes the facts about each measurement that
the rules need, sends all measurements in ONE bridge call (``tools:select_tools/2``) and
groups the answers::

    facts = reach_facts(workcell, specs)               # list of fact lists, one per spec
    part = partition_specs(kb, specs, feature_kinds, facts, done=("WT-P01-1",))
    part.groups      # one ToolGroup per physical tool to be used
    part.done        # ids already done (not sent to the rules)
    part.cannot      # (id, reason) of those no rule and tool can do

Facts (see kb/tools.pl): ``reach(ToolType, Verdict)`` from the arm's geometric reach test
(ita.workcell.reach_report) for the pose the measurement needs with that tool type.  The
ultrasonic probe touches the spec point, except for a rib's width, where it touches the
rib's side wall a little below the top (either side; the better verdict counts:
ita.geometry.configurations.contact_poses).  A
later facts function may add ``pose(ToolType, Verdict)`` from the inverse kinematics:
pass it as `facts` in place of :func:`reach_facts`.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from ita.geometry.configurations import contact_poses
from ita.logic.terms import Term, Var
from ita.specs.model import MeasurementSpec, Tool
from ita.workcell.reach import Reach, reach_report

if TYPE_CHECKING:
    from ita.logic.bridge import KnowledgeBase
    from ita.workcell.model import Workcell

#: feature kind sent for a spec whose feature the part does not describe
UNKNOWN_FEATURE = "unknown"

FactsFunction = Callable[["Workcell", Sequence[MeasurementSpec]], list[list[Term]]]


@dataclass(frozen=True)
class Selection:
    """The rules' answer for one measurement.

    tool_class/tool/rule: the chosen tool type, physical tool and rule (None when it
    cannot be done); reason: why it cannot be done (Prolog text, e.g.
    ``no_working_tool(us_tool)``), None when it can; why: the steps of the choice as
    Prolog text (``chosen(Rule, How)``, ``rejected(Rule, Reason)``).
    """

    spec_id: str
    tool_class: str | None
    tool: str | None
    rule: str | None
    reason: str | None
    why: tuple[str, ...]


@dataclass(frozen=True)
class ToolGroup:
    """The measurements one physical tool takes (unordered: input order)."""

    tool: str
    tool_class: str
    spec_ids: tuple[str, ...]
    rules: tuple[tuple[str, int], ...]  # (rule, count), most used first


@dataclass(frozen=True)
class Partition:
    """Measurements grouped by tool, plus the done and the cannot-be-done groups.

    groups: one per physical tool used, sorted by tool name; done: ids already done;
    cannot: (id, reason) pairs, input order; selections: spec id -> Selection for every
    measurement that was not done.
    """

    groups: tuple[ToolGroup, ...]
    done: tuple[str, ...]
    cannot: tuple[tuple[str, str], ...]
    selections: Mapping[str, Selection]

    def cannot_counts(self) -> dict[str, int]:
        """Reason -> number of measurements that cannot be done for it, commonest first."""
        return dict(Counter(r for _, r in self.cannot).most_common())

    def group_of(self, tool: str) -> ToolGroup | None:
        """The group of physical tool `tool`, or None."""
        return next((g for g in self.groups if g.tool == tool), None)


def term_text(value: Any) -> str:
    """Prolog-like text of a decoded term: ``no_working_tool(us_tool)``, ``[a, b]``."""
    if isinstance(value, Term):
        return f"{value.name}({', '.join(term_text(a) for a in value.args)})"
    if isinstance(value, list):
        return "[" + ", ".join(term_text(v) for v in value) + "]"
    return str(value)


def feature_kinds_of(features: Iterable[Any]) -> dict[str, str]:
    """Feature id -> feature kind spelling, for a part's features."""
    return {f.id: f.kind.value for f in features}


def reach_facts(workcell: Workcell, specs: Sequence[MeasurementSpec]) -> list[list[Term]]:
    """``[reach(us_tool, V1), reach(slra_tool, V2), ...]`` for each spec: one fact per tool
    class the workcell has a tool of (vectorised reach test; a probe on either contact
    pose)."""
    n = len(specs)
    if n == 0:
        return []
    pa, na, pb, nb = contact_poses(specs)
    points = np.array([s.point for s in specs], dtype=float)
    normals = np.array([s.normal for s in specs], dtype=float)
    out: list[list[Term]] = [[] for _ in specs]
    for tool_class in Tool:
        if not workcell.tools_of_class(tool_class):
            continue
        if tool_class.ultrasonic:
            a = reach_report(workcell, pa, na, [tool_class] * n).verdicts
            b = reach_report(workcell, pb, nb, [tool_class] * n).verdicts
            verdicts = [x if x is Reach.REACHABLE or y is not Reach.REACHABLE else y for x, y in zip(a, b)]
        else:
            verdicts = list(reach_report(workcell, points, normals, [tool_class] * n).verdicts)
        for row, v in zip(out, verdicts):
            row.append(Term("reach", (tool_class.value, v.value)))
    return out


def select_tools(
    kb: KnowledgeBase, specs: Sequence[MeasurementSpec], feature_kinds: Mapping[str, str],
    facts: Sequence[Sequence[Term]],
) -> list[Selection]:
    """The rules' choice for each spec, in input order: one call of ``tools:select_tools/2``."""
    if len(facts) != len(specs):
        raise ValueError(f"{len(specs)} specs but {len(facts)} fact lists")
    if not specs:
        return []
    requests = [Term("request", (s.id, s.kind.value, feature_kinds.get(s.feature, UNKNOWN_FEATURE), list(f)))
                for s, f in zip(specs, facts)]
    answer = kb.once("tools", "select_tools", requests, Var("Choices"))
    if answer is None:  # select_tools/2 is det: failing is a bug in the rule base
        raise RuntimeError("tools:select_tools/2 failed")
    return [_selection(c) for c in answer["Choices"]]


def _selection(choice: Term) -> Selection:
    spec_id, decided, why = choice.args
    steps = tuple(term_text(w) for w in why)
    if decided.name == "use":
        tool_class, tool, rule = (str(a) for a in decided.args)
        return Selection(str(spec_id), tool_class, tool, rule, None, steps)
    return Selection(str(spec_id), None, None, None, term_text(decided.args[0]), steps)


def alternative_tools(
    kb: KnowledgeBase, workcell: Workcell, specs: Sequence[MeasurementSpec], feature_kinds: Mapping[str, str],
    chosen: Mapping[str, str],
) -> dict[str, tuple[str, ...]]:
    """Spec id -> the tools of the OTHER types the tool rules allow for it
    (``tools:candidate_tool_types/3``), one per type (the workcell's first tool of that
    type), for each spec of `chosen` (spec id -> its tool).  A resequencing may move a
    measurement to one of them; the MKB places it for them beforehand."""
    types_of: dict[tuple[str, str], list[str]] = {}
    out: dict[str, tuple[str, ...]] = {}
    for s in specs:
        tool = chosen.get(s.id)
        if tool is None:
            continue
        key = (s.kind.value, feature_kinds.get(s.feature, UNKNOWN_FEATURE))
        if key not in types_of:
            found = kb.once("tools", "candidate_tool_types", key[0], key[1], Var("Types"))
            types_of[key] = [str(t) for t in found["Types"]] if found else []
        own = workcell.tool(tool).tool_class.value
        others = []
        for tool_type in types_of[key]:
            if tool_type == own:
                continue
            tools = workcell.tools_of_class(Tool(tool_type))
            if tools:
                others.append(tools[0].name)
        if others:
            out[s.id] = tuple(others)
    return out


def partition_specs(
    kb: KnowledgeBase, specs: Sequence[MeasurementSpec], feature_kinds: Mapping[str, str],
    facts: Sequence[Sequence[Term]], done: Iterable[str] = (),
) -> Partition:
    """Group `specs` by tool; `done` ids form the done group and are not decided.

    facts: one fact list per spec (parallel to `specs`, e.g. from :func:`reach_facts`).
    The world model's current tool state (in `kb`) decides which physical tools are usable.
    """
    if len(facts) != len(specs):
        raise ValueError(f"{len(specs)} specs but {len(facts)} fact lists")
    done_set = set(done)
    todo = [i for i, s in enumerate(specs) if s.id not in done_set]
    chosen = select_tools(kb, [specs[i] for i in todo], feature_kinds, [facts[i] for i in todo])
    by_tool: dict[str, list[Selection]] = {}
    cannot: list[tuple[str, str]] = []
    for sel in chosen:
        if sel.tool is None:
            cannot.append((sel.spec_id, sel.reason or "unknown"))
        else:
            by_tool.setdefault(sel.tool, []).append(sel)
    groups = tuple(
        ToolGroup(tool=tool, tool_class=sels[0].tool_class or "", spec_ids=tuple(s.spec_id for s in sels),
                  rules=tuple(Counter(s.rule or "" for s in sels).most_common()))
        for tool, sels in sorted(by_tool.items())
    )
    return Partition(
        groups=groups,
        done=tuple(s.id for s in specs if s.id in done_set),
        cannot=tuple(cannot),
        selections={s.spec_id: s for s in chosen},
    )
