"""What the two arms of a two-arm run share besides space: the part and the tools.

Each arm's run has its own simulator, world model and Exception Handler.  What one arm
finds of what both share reaches the other as news (ita.robot.gate ``tell``; the other
hears it with the answer to its next claim at that simulated time or later, so what it
hears, and when, does not depend on which process runs faster):

- ``registered``: the arm that registers the part registered it again (its diagnosis
  found the part displaced, or the other arm asked).  The other arm measures in that
  registration from then on, and measures again what it recorded since the teller's last
  good interim check: the part may have moved any time after it (the teller's own
  results since then go back in its plan too, the recovery's ``remeasure(since_check)``).
- ``register``: the arm that does not register the part (its datums out of its view)
  found it displaced and waits, folded, for a registration (ita.task.align
  registered_by_peer); the registering arm registers the part again and posts it.
- ``tools``: tools' conditions a diagnosis changed (found broken, worn, replaced): the
  other arm's world model says so too (a tool may pass to it in a hand-over).

    shared = SharedCell(session)
    shared.tell_tools(changed)                # {tool: condition} after a diagnosis
    shared.tell_registered(alignment, good_s)
    heard = shared.hear()                     # Heard: what the other arm said, applied
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING, cast

from ita.logic.world import CONDITIONS, Condition, WorldModel
from ita.task.align import Alignment, adopt_alignment

if TYPE_CHECKING:
    from ita.task.session import Session

__all__ = ["Heard", "SharedCell"]


@dataclass(frozen=True)
class Heard:
    """The other arm's news since last heard, applied to this arm's session: its new
    registration (None: none); measure again what was recorded from `since_s` (None:
    nothing); the registrations it waits for (this arm registers the part): each one's key
    and when the failure that showed the part displaced was seen; the tools' conditions
    its diagnoses changed."""

    alignment: Alignment | None = None
    since_s: float | None = None
    asks: tuple[tuple[str, float], ...] = ()
    tools: tuple[tuple[str, str], ...] = ()

    #: whether a tool this arm may take up changed (else its plan stands: a tool kept for
    #: the other arm changed, which this arm never takes)
    tools_of_mine: bool = False

    @property
    def anything(self) -> bool:
        return self.alignment is not None or self.since_s is not None or bool(self.asks) or bool(self.tools)

    @property
    def changes_plan(self) -> bool:
        """Whether the rest of this arm's plan is to be made again."""
        return self.alignment is not None or self.since_s is not None or bool(self.asks) or self.tools_of_mine


class SharedCell:
    """Tells the other arm of a two-arm run what this arm found of the part and the tools,
    and hears what it found (module docstring); with one arm, nothing."""

    def __init__(self, session: Session) -> None:
        self.session = session
        #: when this arm began measuring its registration told last (None: none told)
        self.registered_from_s: float | None = None

    def still_good(self, found_s: float) -> Alignment | None:
        """The registration this arm told last when it began measuring after `found_s` (the
        other arm's failure that showed the part displaced): it saw the part where it is
        now; else None (the part is to be registered again)."""
        s = self.session
        if s.alignment is None or self.registered_from_s is None or self.registered_from_s < found_s:
            return None
        return s.alignment

    def tell_registered(self, alignment: Alignment, good_s: float) -> None:
        """This arm registered the part again; the part was where the registration before
        put it at `good_s` (this arm's last good interim check)."""
        s = self.session
        if s.peer is not None and s.registers:
            self.registered_from_s = s.clock.now - alignment.seconds
            s.peer.tell(s.clock.now, {"kind": "registered", "alignment": alignment, "good_s": float(good_s)})

    def tell_tools(self, changed: Mapping[str, str]) -> None:
        """Tools whose condition this arm's diagnosis changed."""
        s = self.session
        if s.peer is not None and changed:
            s.peer.tell(s.clock.now, {"kind": "tools", "conditions": dict(changed)})

    def hear(self) -> Heard:
        """The other arm's news since last heard, applied: its registration adopted, the
        tools' conditions set in this arm's world model."""
        s = self.session
        news = s.peer.heard() if s.peer is not None else []
        if not news:                        # (asked after every measurement: mostly nothing)
            return Heard()
        alignment: Alignment | None = None
        since: float | None = None
        asks: list[tuple[str, float]] = []
        tools: list[tuple[str, str]] = []
        world = WorldModel(s.kb)
        known = set(world.tools())
        for _at, value in news:
            if not isinstance(value, dict):
                continue
            kind = value.get("kind")
            if kind == "registered" and isinstance(value.get("alignment"), Alignment):
                found = value["alignment"]
                if s.alignment is None or s.alignment.to_dict() != found.to_dict():
                    adopt_alignment(s, found)
                alignment = found
                good = float(value.get("good_s", 0.0))
                since = good if since is None else min(since, good)
            elif kind == "register" and s.registers:
                asks.append((str(value.get("key")), float(value.get("found_s", math.inf))))
            elif kind == "tools":
                for tool, condition in dict(value.get("conditions") or {}).items():
                    if tool in known and condition in CONDITIONS and world.condition(tool) != condition:
                        world.set_condition(tool, cast(Condition, condition))
                        tools.append((str(tool), str(condition)))
        mine = any(not world.reserved(tool) for tool, _ in tools)
        return Heard(alignment, since, tuple(asks), tuple(tools), mine)
