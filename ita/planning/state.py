"""What the Operation Planner plans from: where the arm is and what it holds.

The rest of the planning state (which tool sits in which rack slot, tool conditions)
is the world model's (kb/world.pl), read by ``operators:planning_state/4`` at each
call; a held tool is out of the rack whatever the world model says.  The executive
keeps a :class:`WorldState` between measurements (:attr:`OperationPlan.final_state`).

Poses are qualitative, as in kb/operators.pl: the approach point of a place (free space
above it), the in-contact point of a measurement (ultrasonic probe on the part) or the
viewing pose of a measurement (SLRA stand-off).  The Geometric Reasoner turns them
into numbers.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from enum import Enum

from ita.logic.json_value import JsonObject
from ita.logic.terms import Term, TermValue

NOTHING = "none"  # the atom for an empty hand


class PoseKind(str, Enum):
    """The kinds of pose; the value is the Prolog functor."""

    APPROACH = "approach_point"
    CONTACT = "in_contact_point"
    VIEWING = "viewing_pose"


@dataclass(frozen=True)
class Place:
    """A place of the cell: ``Place("home")``, ``Place("meas", "WT-1")``, ``Place("rack", "slot_1")``.

    name: the place's kind (`meas`, `rack`, or a named place such as `home`,
    `couplant_station`, `cal_block`); arg: the measurement id or rack slot, None for a
    named place.
    """

    name: str
    arg: str | None = None

    @classmethod
    def meas(cls, measurement_id: str) -> "Place":
        return cls("meas", measurement_id)

    @classmethod
    def rack(cls, slot: str) -> "Place":
        return cls("rack", slot)

    def to_term(self) -> str | Term:
        return self.name if self.arg is None else Term(self.name, (self.arg,))

    @classmethod
    def from_term(cls, value: TermValue) -> "Place":
        if isinstance(value, str):
            return cls(value)
        if isinstance(value, Term) and len(value.args) == 1 and isinstance(value.args[0], str):
            return cls(value.name, value.args[0])
        raise ValueError(f"not a place: {value!r}")

    def __str__(self) -> str:
        return self.name if self.arg is None else f"{self.name}({self.arg})"


@dataclass(frozen=True)
class QualitativePose:
    """A qualitative pose of the arm's tool point: `kind` of `place`."""

    kind: PoseKind
    place: Place

    @classmethod
    def home(cls) -> "QualitativePose":
        return cls(PoseKind.APPROACH, Place("home"))

    def to_term(self) -> Term:
        return Term(self.kind.value, (self.place.to_term(),))

    def to_flat(self) -> list[str]:
        """``[kind, place]`` or ``[kind, place, arg]``: the pose in fewest JSON objects."""
        if self.place.arg is None:
            return [self.kind.value, self.place.name]
        return [self.kind.value, self.place.name, self.place.arg]

    @classmethod
    def from_term(cls, value: TermValue) -> "QualitativePose":
        if not (isinstance(value, Term) and len(value.args) == 1):
            raise ValueError(f"not a pose: {value!r}")
        return cls(PoseKind(value.name), Place.from_term(value.args[0]))

    def __str__(self) -> str:
        return f"{self.kind.value}({self.place})"


@dataclass(frozen=True)
class WorldState:
    """The arm `arm` at `pose`, holding the tool `holding` (None: empty hand)."""

    arm: str = "t3"
    pose: QualitativePose = field(default_factory=QualitativePose.home)
    holding: str | None = None

    def holding_atom(self) -> str:
        """`holding` as the planner spells it (`none` for an empty hand)."""
        return NOTHING if self.holding is None else self.holding

    def to_dict(self) -> JsonObject:
        return {"arm": self.arm, "pose": str(self.pose), "holding": self.holding}
