"""The Geometric Reasoner's second job: answering the Executive's questions about the
qualitative parameters of a plan from the MKB (:mod:`ita.geometry.build` makes it).

    reasoner = GeometricReasoner(mkb, cell, specs)
    reasoner.resolve(Term("in_contact_point", (Term("meas", ("WT-P01-1",)),)), "us_probe_1")  # Target
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from ita.geometry.build import PRESS_M
from ita.geometry.mkb import MeasurementKB, MkbEntry
from ita.kinematics import IKSolutions, arm_model, choose_nearest, ik_tool
from ita.logic.terms import Term
from ita.specs.model import MeasurementSpec

if TYPE_CHECKING:
    from ita.workcell.model import PartPlacement, Workcell

FloatArray = NDArray[np.float64]

__all__ = ["STATIONS", "GeometricReasoner", "Target"]

#: the stations a plan can send the arm to (workcell boxes with a top face to work on)
STATIONS = ("cal_block", "couplant_station")
#: the bare flange this far over a station's face (m)
STATION_CLEARANCE_M = 0.15
#: rolls about the vertical tried for a pose over a station
STATION_ROLLS = 12
#: rolls (degrees, each way) about a probe's axis tried when its poses moved with the
#: registered part meet the cell or the arm itself (GeometricReasoner._probe_on_part)
PROBE_ROLLS_DEG = (5.0, 10.0, 15.0, 20.0, 30.0, 45.0)


@dataclass(frozen=True, eq=False)
class Target:
    """A quantitative pose: the joint configuration q (6,) and, when known, the TCP pose
    (4, 4, world, m) it puts the held tool at; press_m: how far a contact pose pushes the
    probe's spring-loaded tip in (0 elsewhere)."""

    q: FloatArray
    pose: FloatArray | None = None
    press_m: float = 0.0


def _configuration(spec_id: str, q: FloatArray | None) -> FloatArray:
    """A placed entry's configuration; KeyError when the entry has none (a damaged MKB)."""
    if q is None:
        raise KeyError(f"{spec_id}: its MKB entry has no arm configuration")
    return q


class GeometricReasoner:
    """Turns the plans' qualitative parameters into numbers (the Executive's PoseResolver).

        approach_point(meas(Id)), in_contact_point(meas(Id)), viewing_pose(meas(Id)) -> Target
        approach_point(rack(Slot)), approach_point(home)                       -> Target
        approach_point(cal_block), approach_point(couplant_station)            -> Target (held tool)
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
        self._stations: dict[tuple[str, str | None, bool], Target] = {}
        #: the cell's check of configurations ((n, 6), the tool in hand or None -> (n,)
        #: bool, True where free of collision) when the run has one: a station's pose is
        #: then one the arm can take without touching the cell (see :meth:`check_with`)
        self._free: Callable[[FloatArray, str | None], NDArray[np.bool_]] | None = None
        #: where the part was registered (ita.task.align; None: at its nominal placement) and
        #: the world motion from the nominal part to it, applied to every pose on the part
        self.placement: PartPlacement | None = None
        self._motion: FloatArray | None = None
        self._moved: dict[tuple[str, str, str | None], Target] = {}

    def register(self, placement: PartPlacement | None) -> None:
        """Put every pose on the part where the part was registered (`placement`, found on
        its datums; None: back to its nominal placement).  The MKB's poses were made for the
        nominal placement: each is moved with the part (the world motion from the nominal
        placement to the registered one) and its configuration solved again, nearest the
        MKB's (the arm's own branch)."""
        self._moved = {}
        if placement is None or placement == self.cell.part:
            self.placement, self._motion = None, None
            return
        nominal = self.cell.part
        r0, r1 = nominal.rotation_matrix(), placement.rotation_matrix()
        rot = r1 @ r0.T
        motion = np.eye(4)
        motion[:3, :3] = rot
        motion[:3, 3] = np.asarray(placement.translation, dtype=float) - rot @ np.asarray(nominal.translation, dtype=float)
        self.placement, self._motion = placement, motion

    def _on_part(self, spec_id: str, kind: str, tool: str | None, target: Target, tool_name: str) -> Target:
        """`target` (a pose on the nominal part) moved with the registered part."""
        if self._motion is None or target.pose is None:
            return target
        key = (spec_id, kind, tool)
        if key not in self._moved:
            pose = self._motion @ np.asarray(target.pose, dtype=float)
            model = arm_model(self.cell.arm)
            tcp = self.cell.tool(tool_name).tcp.matrix()
            solutions = ik_tool(model, pose[None], tcp)
            q, found = choose_nearest(model, solutions, target.q)
            if found[0] and self.cell.tool(tool_name).standoff_nominal > 0 and self._free is not None \
                    and not self._free(q[:1], tool_name)[0]:
                # an SLRA's pose moved with the part meets the cell (the MKB's was at the edge
                # of the arm touching itself): the nearest free solution, else the MKB's own
                # pose when free (the view then off by the registration's sub-millimetre
                # motion; the frame is read from where the sensor is).  (A probe's poses
                # are _probe_on_part's.)
                q, found = choose_nearest(model, self._free_only(solutions, tool_name), target.q)
                if not self._free(q[:1], tool_name)[0] and self._free(np.asarray(target.q)[None], tool_name)[0]:
                    self._moved[key] = target
                    return target
            if not found[0]:
                raise KeyError(f"{spec_id}: the arm cannot reach its {kind} on the part where it was registered")
            self._moved[key] = Target(np.asarray(q[0], dtype=float), pose, target.press_m)
        return self._moved[key]

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
                part = self.placement or self.cell.part
                return part.to_world(np.asarray(spec.point, dtype=float)[None])[0]
            e = self.entry(spec_id, tool)
            if kind in ("approach_point", "in_contact_point") and e.q_approach is not None \
                    and self.cell.tool(e.tool).standoff_nominal <= 0:
                approach, contact = self._probe_on_part(spec_id, tool, e)
                return approach if kind == "approach_point" else contact
            if kind == "approach_point":
                return self._on_part(spec_id, kind, tool, Target(_configuration(spec_id, e.q_approach),
                                                                 e.pose_approach), e.tool)
            if kind == "in_contact_point":
                return self._on_part(spec_id, kind, tool, Target(_configuration(spec_id, e.q), e.pose, e.press_m),
                                     e.tool)
            if kind == "viewing_pose":
                return self._on_part(spec_id, kind, tool, Target(_configuration(spec_id, e.q), e.pose), e.tool)
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
            if place in STATIONS:
                return self.station(str(place), tool)
        raise KeyError(f"the Geometric Reasoner does not know {term!r}")

    def _probe_on_part(self, spec_id: str, tool: str | None, e: MkbEntry) -> tuple[Target, Target]:
        """A probe's approach and contact targets moved with the registered part.  When the
        arm there meets the cell or itself (the MKB's pose was at the edge of the wrist
        touching itself, and the registration tipped it over), both poses are turned by
        one roll about the probe's axis (the tip touches the same spot, square to the
        surface): the least of :data:`PROBE_ROLLS_DEG` that leaves the approach free (the
        contact touches the part by design; its straight move is checked as it is made), each the
        solution nearest the MKB's (the straight move between them needs one branch); with
        none, the moved poses as they are (the move then says what it hits)."""
        approach = Target(_configuration(spec_id, e.q_approach), e.pose_approach)
        contact = Target(_configuration(spec_id, e.q), e.pose, e.press_m)
        if self._motion is None or approach.pose is None or contact.pose is None:
            return approach, contact
        key = (spec_id, "probe", tool)
        if key not in self._moved:
            model = arm_model(self.cell.arm)
            tcp = self.cell.tool(e.tool).tcp.matrix()
            moved = [self._motion @ np.asarray(t.pose, dtype=float) for t in (approach, contact)]
            chosen: list[Target] | None = None
            for deg in (0.0, *(s * d for d in PROBE_ROLLS_DEG for s in (1.0, -1.0))):
                roll = np.eye(4)
                c, s_ = np.cos(np.radians(deg)), np.sin(np.radians(deg))
                roll[:2, :2] = [[c, -s_], [s_, c]]
                poses = [m @ roll for m in moved]
                got = [choose_nearest(model, ik_tool(model, p[None], tcp), np.asarray(t.q)) for p, t in
                       zip(poses, (approach, contact))]
                if not all(f[0] for _q, f in got):
                    continue
                qs = [q[0] for q, _f in got]
                targets = [Target(np.asarray(qs[0], dtype=float), poses[0]),
                           Target(np.asarray(qs[1], dtype=float), poses[1], contact.press_m)]
                if chosen is None:
                    chosen = targets                       # unrolled (or the least roll found): kept when none is free
                if self._free is None or bool(self._free(qs[0][None], e.tool)[0]):     # (the contact touches the part)
                    chosen = targets
                    break
            if chosen is None:
                raise KeyError(f"{spec_id}: the arm cannot reach its probe poses on the part where it was registered")
            self._moved[key] = chosen[0]
            self._moved[(spec_id, "probe_contact", tool)] = chosen[1]
        return self._moved[key], self._moved[(spec_id, "probe_contact", tool)]

    def _free_only(self, solutions: IKSolutions, tool: str | None) -> IKSolutions:
        """The solutions the cell's check finds free, when there is a check and any is (else
        all: the move to the one chosen then says what it hits)."""
        if self._free is None or not solutions.valid.any():
            return solutions
        free = np.zeros_like(solutions.valid)
        free[solutions.valid] = self._free(solutions.q[solutions.valid], tool)
        return replace(solutions, valid=free) if free.any() else solutions

    def check_with(self, free: Callable[[FloatArray, str | None], NDArray[np.bool_]]) -> None:
        """Choose stations' poses, and poses on a registered part, among the configurations
        ``free`` accepts (the path planner's collision check of the cell); the poses
        chosen before are forgotten."""
        self._free = free
        self._stations.clear()
        self._moved.clear()

    def station(self, name: str, tool: str | None, *, contact: bool = False) -> Target:
        """The pose over station `name` (``cal_block``, ``couplant_station``) for `tool` in
        hand, looking straight down on its top face: the probe's tip its approach distance
        above it (pressed :data:`~ita.geometry.build.PRESS_M` into it with `contact`), the
        SLRA at its nominal stand-off, the bare flange :data:`STATION_CLEARANCE_M` above.
        The configuration quickest from home over :data:`STATION_ROLLS` rolls (of those
        free of the cell, when the reasoner has a check: :meth:`check_with`).  KeyError
        when the arm cannot take it."""
        key = (name, tool, contact)
        if key not in self._stations:
            self._stations[key] = self._station(name, tool, contact)
        return self._stations[key]

    def _station(self, name: str, tool: str | None, contact: bool) -> Target:
        box = getattr(self.cell, name)
        top = np.asarray(box.pose.position, dtype=float) + np.array([0.0, 0.0, box.size[2] / 2.0])
        spec = self.cell.tool(tool) if tool is not None else None
        if spec is None:
            up, tcp = STATION_CLEARANCE_M, np.eye(4)
        elif spec.standoff_nominal > 0.0:
            up, tcp = spec.standoff_nominal, spec.tcp.matrix()
        else:
            up, tcp = (-PRESS_M if contact else spec.approach_distance), spec.tcp.matrix()
        angles = np.linspace(0.0, 2.0 * np.pi, STATION_ROLLS, endpoint=False)
        poses = np.zeros((len(angles), 4, 4))
        poses[:, 3, 3] = 1.0
        poses[:, :3, 2] = (0.0, 0.0, -1.0)                         # looking down on the face
        poses[:, :3, 0] = np.column_stack([np.cos(angles), np.sin(angles), np.zeros_like(angles)])
        poses[:, :3, 1] = np.cross(poses[:, :3, 2], poses[:, :3, 0])
        poses[:, :3, 3] = top + np.array([0.0, 0.0, up])
        model = arm_model(self.cell.arm)
        ref = self.station(name, tool).q if contact else self.home     # contact: straight down from the approach
        solutions = ik_tool(model, poses[None], tcp).flatten_batch()
        q, found = choose_nearest(model, solutions if contact else self._free_only(solutions, tool), ref)
        if not found[0]:
            raise KeyError(f"the arm cannot reach {name} with {tool or 'no tool'}")
        return Target(np.asarray(q[0], dtype=float), None)
