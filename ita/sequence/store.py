"""Files of the Sequence Planner: the stored sequence plans and the tool marks.

* ``ita_home()/plans/<part>.json``: the sequence plan of a part (groups, orders, reasons,
  costs, the tool state it was made for, progress), so a later run or ``ita continue``
  picks it up.  :func:`save_plan` / :func:`load_plan`.
* ``ita_home()/world/tools.json``: the tool marks a person set by hand (``ita sequence
  tool broken us_probe_1``): {tool: {"condition": "broken"|"worn", "missing": true}}.
  A one-shot CLI forgets the world model between runs, so each command applies these
  marks to the world model when it starts (:func:`apply_tool_marks`).

Both are written atomically (temporary file in the same directory, fsync, rename).
"""

from __future__ import annotations

import contextlib
import json
from collections.abc import Iterator, Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any

from ita.errors import InputError, ItaError, Location
from ita.files.atomic import store_name, write_json_atomic
from ita.logic.world import CONDITIONS, ToolLocation, WorldModel
from ita.paths import ita_home
from ita.sequence.plan import PLAN_VERSION, PlannedGroup, SequencePlan

if TYPE_CHECKING:
    from ita.logic.bridge import KnowledgeBase

#: the marks a person can set on a tool, and what each does
MARKS: dict[str, str] = {
    "ok": "working and in its rack slot (clears every mark)",
    "broken": "condition broken: not available",
    "worn": "condition worn: not available",
    "missing": "not where it should be: not available",
    "found": "back in its rack slot (clears `missing`, keeps the condition)",
}


class PlanNotFound(ItaError):
    """No stored sequence plan for the part."""


class PlanStale(ItaError):
    """The stored plan was made for other specs than the part has now."""


def plans_dir() -> Path:
    """Directory of the stored sequence plans (created on demand)."""
    path = ita_home() / "plans"
    path.mkdir(parents=True, exist_ok=True)
    return path


def plan_path(part_name: str) -> Path:
    """Where the plan of part `part_name` is stored."""
    return plans_dir() / f"{store_name(part_name)}.json"


def tool_marks_path() -> Path:
    """Where the tool marks are stored."""
    path = ita_home() / "world"
    path.mkdir(parents=True, exist_ok=True)
    return path / "tools.json"


def _read_json(path: Path) -> Any:
    try:
        return json.loads(Path(path).read_text(encoding="utf-8"))
    except ValueError as exc:
        raise InputError([(Location(str(path)), f"not valid JSON: {exc}")]) from None


# -- plans ---------------------------------------------------------------------------

def plan_to_dict(plan: SequencePlan) -> dict[str, Any]:
    """A JSON-ready dict of a plan (the stored format)."""
    return {
        "version": plan.version, "part": plan.part, "specs_digest": plan.specs_digest,
        "method": plan.method, "cost_model": plan.cost_model, "cost_interim": plan.cost_interim,
        "created": plan.created, "build_seconds": round(plan.build_seconds, 3),
        "tool_state": {k: dict(v) for k, v in plan.tool_state.items()},
        "groups": [{"tool": g.tool, "tool_class": g.tool_class, "cost_s": g.cost_s,
                    "rules": {r: c for r, c in g.rules}, "order": list(g.order)} for g in plan.groups],
        "done": list(plan.done),
        "cannot": [{"id": i, "reason": r} for i, r in plan.cannot],
        "transfer_s": plan.transfer_s, "tool_changes": plan.tool_changes, "total_s": plan.total_s,
        "handed_out": list(plan.handed_out), "history": list(plan.history),
    }


def plan_from_dict(data: Mapping[str, Any], origin: str = "<plan>") -> SequencePlan:
    """The plan of a :func:`plan_to_dict` dict; InputError when it is not one."""
    try:
        if data.get("version") != PLAN_VERSION:
            raise ValueError(f"plan version {data.get('version')!r}, expected {PLAN_VERSION}")
        return SequencePlan(
            part=str(data["part"]), specs_digest=str(data["specs_digest"]), method=str(data["method"]),
            cost_model=str(data["cost_model"]), cost_interim=bool(data["cost_interim"]),
            created=str(data["created"]), build_seconds=float(data["build_seconds"]),
            tool_state={k: dict(v) for k, v in data["tool_state"].items()},
            groups=tuple(PlannedGroup(tool=str(g["tool"]), tool_class=str(g["tool_class"]),
                                      order=tuple(map(str, g["order"])), cost_s=float(g["cost_s"]),
                                      rules=tuple((str(r), int(c)) for r, c in g["rules"].items()))
                         for g in data["groups"]),
            done=tuple(map(str, data["done"])),
            cannot=tuple((str(c["id"]), str(c["reason"])) for c in data["cannot"]),
            transfer_s=float(data["transfer_s"]), tool_changes=int(data["tool_changes"]),
            handed_out=tuple(map(str, data["handed_out"])), history=tuple(map(str, data["history"])),
        )
    except (KeyError, TypeError, ValueError, AttributeError) as exc:
        raise InputError([(Location(origin), f"not a sequence plan: {exc}")]) from None


def save_plan(plan: SequencePlan, path: Path | None = None) -> Path:
    """Store `plan` (default: :func:`plan_path` of its part) atomically; returns the path."""
    return write_json_atomic(path or plan_path(plan.part), plan_to_dict(plan))


def load_plan(part_name: str, path: Path | None = None) -> SequencePlan:
    """The stored plan of `part_name`; PlanNotFound when there is none."""
    path = path or plan_path(part_name)
    if not path.is_file():
        raise PlanNotFound(f"no sequence plan for part {part_name!r} at {path}; run `ita sequence` first")
    return plan_from_dict(_read_json(path), str(path))


def check_current(plan: SequencePlan, specs_digest: str) -> None:
    """Raise PlanStale when `plan` was made for other specs than those of `specs_digest`."""
    if plan.specs_digest != specs_digest:
        raise PlanStale(f"the specs of part {plan.part!r} changed since its sequence plan was made "
                        f"({plan.created}); run `ita sequence` to make a new one")


# -- tool marks ----------------------------------------------------------------------

def load_tool_marks() -> dict[str, dict[str, Any]]:
    """The stored tool marks: {tool: {"condition": ..., "missing": true}} (empty when none)."""
    path = tool_marks_path()
    if not path.is_file():
        return {}
    data = _read_json(path)
    if not isinstance(data, dict) or not all(isinstance(v, dict) for v in data.values()):
        raise InputError([(Location(str(path)), "tool marks must be an object of objects")])
    return data


def marked(marks: Mapping[str, Mapping[str, Any]], tool: str, mark: str) -> dict[str, dict[str, Any]]:
    """`marks` with `mark` (one of :data:`MARKS`) set on `tool` (a new dict)."""
    if mark not in MARKS:
        raise InputError([(Location("<command line>"), f"unknown mark {mark!r} (valid: {', '.join(MARKS)})")])
    out = {k: dict(v) for k, v in marks.items()}
    entry = out.get(tool, {})
    if mark == "ok":
        entry = {}
    elif mark in ("broken", "worn"):
        entry["condition"] = mark
    elif mark == "missing":
        entry["missing"] = True
    elif mark == "found":
        entry.pop("missing", None)
    if entry:
        out[tool] = entry
    else:
        out.pop(tool, None)
    return out


def save_tool_marks(marks: Mapping[str, Mapping[str, Any]]) -> Path:
    """Store the tool marks atomically; returns the path."""
    return write_json_atomic(tool_marks_path(), {k: dict(v) for k, v in sorted(marks.items())})


def apply_tool_marks(kb: KnowledgeBase, marks: Mapping[str, Mapping[str, Any]]) -> None:
    """Reset the world model, then record the marks in it (world:set_tool_condition/2 ...).

    Raises InputError naming a tool the world model does not know.
    """
    world = WorldModel(kb)
    known = set(world.tools())
    unknown = sorted(set(marks) - known)
    if unknown:
        raise InputError([(Location(str(tool_marks_path())),
                           f"unknown tool {t!r} (tools: {', '.join(sorted(known))})") for t in unknown])
    bad = sorted(t for t, entry in marks.items() if "condition" in entry and entry["condition"] not in CONDITIONS)
    if bad:
        raise InputError([(Location(str(tool_marks_path())),
                           f"tool {t!r}: condition {marks[t]['condition']!r} is not one of "
                           f"{', '.join(CONDITIONS)}") for t in bad])
    world.reset()
    for tool, entry in sorted(marks.items()):
        condition = entry.get("condition")
        if condition in CONDITIONS:
            world.set_condition(tool, condition)
        if entry.get("missing"):
            world.set_location(tool, ToolLocation("missing"))
        elif "location" in entry:  # e.g. on_arm(t3), written by a program rather than a person
            where = entry["location"]
            if isinstance(where, str) and where.startswith("on_arm(") and where.endswith(")"):
                world.set_location(tool, ToolLocation("on_arm", where[7:-1]))


@contextlib.contextmanager
def tool_marks_applied(kb: KnowledgeBase, marks: Mapping[str, Mapping[str, Any]]) -> Iterator[None]:
    """Apply `marks` to the world model for the block, and reset the world model after it."""
    apply_tool_marks(kb, marks)
    try:
        yield
    finally:
        WorldModel(kb).reset()
