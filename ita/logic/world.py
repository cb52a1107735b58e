"""The world model (kb/world.pl) through typed calls: the cell's tools, their conditions
and locations, and the arm.

    world = WorldModel(kb)
    world.tools()                       # ('slra_1', 'slra_2', 'us_probe_1', ...)
    world.condition("us_probe_1")       # 'ok' | 'worn' | 'broken'
    world.location("slra_1")            # ToolLocation('in_rack', 'slot_3')
    world.usable("t3", "us_tool")       # ('us_probe_1', 'us_probe_2'): available, liftable
    world.set_condition("us_probe_1", "broken")

Every other module reaches the world model through this facade, never by a predicate's
name as text: a change of kb/world.pl shows here, and the answers come back as Python
values (the bridge's terms decoded and checked).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

from ita.errors import PrologError
from ita.logic.bridge import KnowledgeBase
from ita.logic.terms import Term, Var

__all__ = ["CONDITIONS", "Condition", "ToolLocation", "WorldModel"]

WORLD = "world"

Condition = Literal["ok", "worn", "broken"]
#: the conditions a tool can be in
CONDITIONS: tuple[Condition, ...] = ("ok", "worn", "broken")


@dataclass(frozen=True)
class ToolLocation:
    """Where a tool is: ``in_rack`` (at `place`, a slot), ``on_arm`` (at `place`, an arm)
    or ``missing`` (`place` empty)."""

    kind: Literal["in_rack", "on_arm", "missing"]
    place: str = ""

    @staticmethod
    def from_term(value: object) -> ToolLocation:
        """The location of a decoded ``in_rack(Slot)``, ``on_arm(Arm)`` or ``missing``."""
        if value == "missing":
            return ToolLocation("missing")
        if isinstance(value, Term) and len(value.args) == 1 and value.name in ("in_rack", "on_arm"):
            kind: Literal["in_rack", "on_arm"] = "in_rack" if value.name == "in_rack" else "on_arm"
            return ToolLocation(kind, str(value.args[0]))
        raise PrologError("world:location/2", f"not a tool location: {value!r}")

    def to_term(self) -> str | Term:
        """The term kb/world.pl writes for this location."""
        return "missing" if self.kind == "missing" else Term(self.kind, (self.place,))

    def __str__(self) -> str:
        return "missing" if self.kind == "missing" else f"{self.kind}({self.place})"


class WorldModel:
    """Typed calls on the world model of `kb` (a loaded KnowledgeBase)."""

    def __init__(self, kb: KnowledgeBase) -> None:
        self.kb = kb

    # -- what the cell is ----------------------------------------------------------
    def tools(self) -> tuple[str, ...]:
        """The measuring tools the arm can pick up, in the knowledge base's order."""
        return tuple(str(row["T"]) for row in self.kb.call(WORLD, "tool", Var("T")))

    def arms(self) -> tuple[str, ...]:
        """The arms of the cell."""
        return tuple(str(row["A"]) for row in self.kb.call(WORLD, "type", Var("A"), "arm"))

    def the_arm(self) -> str:
        """The cell's one arm (the first, when there are several)."""
        arms = self.arms()
        if not arms:
            raise PrologError("world:type/2", "the world model has no arm")
        return arms[0]

    def tool_type(self, tool: str) -> str:
        """The type of `tool` (``us_tool``, ``us_bent``, ``slra_tool``)."""
        return str(self.kb.one(WORLD, "type", tool, Var("T"))["T"])

    def is_a(self, thing: str, kind: str) -> bool:
        """Whether `thing` is of type `kind` or of a subtype of it."""
        return self.kb.holds(WORLD, "is_a", thing, kind)

    # -- its state -----------------------------------------------------------------
    def condition(self, tool: str) -> Condition:
        """The condition of `tool`."""
        value = str(self.kb.one(WORLD, "tool_condition", tool, Var("C"))["C"])
        if value not in CONDITIONS:
            raise PrologError("world:tool_condition/2", f"not a condition: {value!r}")
        return value

    def location(self, tool: str) -> ToolLocation:
        """Where `tool` is."""
        return ToolLocation.from_term(self.kb.one(WORLD, "location", tool, Var("W"))["W"])

    def missing(self, tool: str) -> bool:
        """Whether `tool` is not where it should be."""
        return self.kb.holds(WORLD, "missing", tool)

    def available(self, tool: str) -> bool:
        """Whether `tool` can be used: condition ``ok`` and not missing."""
        return self.kb.holds(WORLD, "available", tool)

    def holding(self) -> tuple[str, str] | None:
        """(arm, tool) when an arm holds a tool, else None."""
        found = self.kb.once(WORLD, "holding", Var("A"), Var("T"))
        return None if found is None else (str(found["A"]), str(found["T"]))

    def usable(self, arm: str, tool_type: str) -> tuple[str, ...]:
        """The tools of `tool_type` that `arm` can measure with now (available, liftable)."""
        return tuple(str(row["T"]) for row in self.kb.call(WORLD, "usable", arm, tool_type, Var("T")))

    def registering_slra(self, arm: str, held: str | None = None) -> str | None:
        """The SLRA `arm` registers the part with: `held` (the tool in its hand) when that
        is a usable one, else the first usable one; None when it has none
        (ita.toplevel.registration)."""
        usable = self.usable(arm, "slra_tool")
        if held in usable:
            return held
        return usable[0] if usable else None

    def is_usable(self, arm: str, tool_type: str, tool: str) -> bool:
        """Whether `arm` can measure with `tool` as a tool of `tool_type` now."""
        return self.kb.holds(WORLD, "usable", arm, tool_type, tool)

    # -- changes -------------------------------------------------------------------
    def set_condition(self, tool: str, condition: Condition) -> None:
        """Record that `tool` is now in `condition`."""
        if condition not in CONDITIONS:
            raise ValueError(f"not a tool condition: {condition!r} (one of {', '.join(CONDITIONS)})")
        self.kb.one(WORLD, "set_tool_condition", tool, condition)

    def set_location(self, tool: str, where: ToolLocation) -> None:
        """Record that `tool` is now at `where`."""
        self.kb.one(WORLD, "set_location", tool, where.to_term())

    def reserved(self, tool: str) -> bool:
        """Whether `tool` is kept for another arm (a two-arm run): never available to this one."""
        return self.kb.once(WORLD, "reserved", tool, Var("Arm")) is not None

    def set_reserved(self, tool: str, arm: str) -> None:
        """Record that `tool` is kept for `arm`, the other arm of a two-arm run: it stays in
        its slot and is not available to this one."""
        self.kb.one(WORLD, "set_reserved", tool, arm)

    def reset(self) -> None:
        """Forget every recorded change: the cell as built."""
        self.kb.one(WORLD, "reset_world")
