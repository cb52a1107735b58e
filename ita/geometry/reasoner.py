"""The Geometric Reasoner's second job: answering the Executive's questions about the
qualitative parameters of a plan from the MKB (:mod:`ita.geometry.build` makes it).

    reasoner = GeometricReasoner(mkb, cell, specs)
    reasoner.resolve(Term("in_contact_point", (Term("meas", ("WT-P01-1",)),)), "us_probe_1")  # Target
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from ita.geometry.mkb import MeasurementKB, MkbEntry
from ita.logic.terms import Term
from ita.specs.model import MeasurementSpec

if TYPE_CHECKING:
    from ita.workcell.model import Workcell

FloatArray = NDArray[np.float64]

__all__ = ["GeometricReasoner", "Target"]


@dataclass(frozen=True, eq=False)
class Target:
    """A quantitative pose: the joint configuration q (6,) and, when known, the TCP pose
    (4, 4, world, m) it puts the held tool at; press_m: how far a contact pose pushes the
    probe's spring-loaded tip in (0 elsewhere)."""

    q: FloatArray
    pose: FloatArray | None = None
    press_m: float = 0.0


class GeometricReasoner:
    """Turns the plans' qualitative parameters into numbers (the Executive's PoseResolver).

        approach_point(meas(Id)), in_contact_point(meas(Id)), viewing_pose(meas(Id)) -> Target
        approach_point(rack(Slot)), approach_point(home)                       -> Target
        goal_point(meas(Id))                     -> (3,) world point (m) of the spec
        patches(meas(Id))                        -> the ViewGroup of the frame to take
        min_value(meas(Id)), max_value(meas(Id)) -> the spec's tolerance limits (mm)

    A pose of a measurement depends on the tool that takes it: `tool`, the tool the arm
    holds, picks the MKB entry of its class (:meth:`MeasurementKB.entry_for`), and must
    have the shape of the tool the entry was made for (a spare of the same make);
    without one the entry of the tool the sequence plan chose is used.  KeyError for a
    term it does not know or a measurement the MKB could not place for that tool.
    """

    def __init__(self, mkb: MeasurementKB, cell: Workcell, specs: Sequence[MeasurementSpec]) -> None:
        self.mkb = mkb
        self.cell = cell
        self.specs = {s.id: s for s in specs}
        self.home = np.asarray(cell.arm.home, dtype=float)

    def entry(self, spec_id: str, tool: str | None = None) -> MkbEntry:
        """The placed entry of `spec_id` for `tool` (None: the sequence plan's tool);
        KeyError when there is none."""
        e = self.mkb.entries.get(spec_id)
        if tool is not None:
            spec = self.cell.tool(tool)
            e = self.mkb.entry_for(spec_id, spec.tool_class.value)
            if e is None:
                raise KeyError(f"{spec_id}: no MKB entry for a {spec.tool_class.value} ({tool})")
            if e.tool != tool and not spec.same_shape(self.cell.tool(e.tool)):
                raise KeyError(f"{spec_id}: placed for {e.tool}, whose shape {tool} does not have")
        if e is None:
            raise KeyError(f"{spec_id}: not in the measurement knowledge base")
        if not e.ok:
            raise KeyError(f"{spec_id}: {e.status} ({e.reason})")
        return e

    def resolve(self, term: Any, tool: str | None = None) -> Any:
        if not (isinstance(term, Term) and len(term.args) == 1):
            raise KeyError(f"not a qualitative parameter: {term!r}")
        kind, place = term.name, term.args[0]
        if isinstance(place, Term) and place.name == "meas" and len(place.args) == 1:
            spec_id = str(place.args[0])
            if kind in ("min_value", "max_value"):
                spec = self.specs[spec_id]
                return spec.low_limit if kind == "min_value" else spec.high_limit
            if kind == "goal_point":
                spec = self.specs[spec_id]
                return self.cell.part.to_world(np.asarray(spec.point, dtype=float)[None])[0]
            e = self.entry(spec_id, tool)
            if kind == "approach_point":
                return Target(e.q_approach, e.pose_approach)
            if kind == "in_contact_point":
                return Target(e.q, e.pose, e.press_m)
            if kind == "viewing_pose":
                return Target(e.q, e.pose)
            if kind == "patches":
                group = self.mkb.groups.get(e.group or "")
                if group is None:
                    raise KeyError(f"{spec_id} has no SLRA view")
                return group
        elif kind == "approach_point":
            if place == "home":
                return Target(self.home)
            if isinstance(place, Term) and place.name == "rack" and len(place.args) == 1:
                return Target(np.asarray(self.mkb.rack[str(place.args[0])]))
        raise KeyError(f"the Geometric Reasoner does not know {term!r}")
