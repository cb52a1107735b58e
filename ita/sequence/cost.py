"""The Sequence Planner's cost: seconds of arm motion between the stops of a plan.

    cost = MOTION_TIME_COST                        # the default of PlanningContext
    m = cost.tour(workcell, tool, specs)           # (n + 1, n + 1) s, stop 0 the rack slot
    s = cost.transfer(workcell, "slra_1", "us_probe_1")   # one tool change, s

Motion time (:data:`MOTION_TIME_COST`).  Each measurement gets ONE joint configuration
of the workcell's arm, chosen before the ordering
(ita.geometry.configurations.measurement_configurations: candidate poses, the group's
common IK branch, the solution nearest its reference).

The tour matrix is then ``timing.move_time_matrix`` over [rack slot, measurements]: each
joint's trapezoidal rest-to-rest time under its velocity and acceleration limits, the
joints synchronised, bounded below by the tool point's straight chord over the
controller's TCP speed limit.  It is symmetric with a zero diagonal.  Stop 0 is the tool
parked in its rack slot (the flange at the slot's pose, the tool coupled): the tour starts
there (pick-up) and ends there (put back).

Tool changes (:func:`rack_seconds`): putting a tool back = unlock the coupling
(:data:`COUPLING_S`) and lift the empty flange the rack's approach_m back along the slot's
axis (straight up); the
move to above the next slot; picking a tool up = lower the flange onto it and lock the
coupling.  The moves are joint-space move times (flange chord cap); the coupling time is
a stated constant.

Not modelled: the time to take a measurement (couplant, settling, the scan), the path
around obstacles (a joint-space move is the lower bound the path planner starts from),
and approach moves off the surface.  The configuration of a measurement is fixed before
the order is; choosing it jointly with the order (e.g. a dynamic programme over each
stop's candidates along the tour) could only shorten the tours.

The interim estimate (:data:`INTERIM_COST`, straight-line tool-point distance over the
top TCP speed) is kept as a named option (:data:`COST_MODELS`): a fast lower bound for
tests and comparisons, labelled as not the arm's motion time.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from ita.geometry.configurations import (
    POSE_OK,
    WRIST_MARGIN,
    candidate_poses,
    measurement_configurations,
)
from ita.kinematics import (
    ArmModel,
    arm_model,
    choose_centred,
    choose_nearest,
    ik_flange,
    ik_tool,
    move_time_matrix,
)
from ita.logic.terms import Term
from ita.sequence.partition import reach_facts
from ita.specs.model import MeasurementSpec, Tool

if TYPE_CHECKING:
    from ita.workcell.model import ToolSpec, Workcell

FloatArray = NDArray[np.float64]

#: seconds to lock or to unlock the tool changer's coupling (a stated constant)
COUPLING_S = 1.0

TourCost = Callable[["Workcell", "ToolSpec", Sequence[MeasurementSpec]], np.ndarray]
TransferCost = Callable[["Workcell", "str | None", "str | None"], float]


@dataclass(frozen=True)
class CostModel:
    """How many seconds the arm needs between stops.

    tour(workcell, tool, specs) -> ``(n + 1, n + 1) float`` seconds between the stops of a
    tool group: stop 0 is the tool's rack slot, stop i + 1 is specs[i] (may be
    asymmetric).  transfer(workcell, tool_a, tool_b) -> seconds at the rack between
    putting tool_a back in its slot at the end of its tour and being coupled to tool_b in
    its slot at the start of the next (None: no tool, so (None, b) is the first pick-up
    and (a, None) the last put-down).  description: what the seconds include.  `interim`
    marks an estimate that is not the arm's motion time.
    """

    name: str
    description: str
    tour: TourCost
    transfer: TransferCost
    interim: bool = False


# -- the motion-time model -----------------------------------------------------------------

def rack_configurations(workcell: Workcell, model: ArmModel, tool_name: str) -> tuple[FloatArray, FloatArray]:
    """``(6,)`` configurations at `tool_name`'s rack slot: coupled (the flange at the slot's
    pose; the solution furthest from the joint limits) and the rack's approach_m above it
    (the solution quickest to reach from the coupled one).  ValueError when the arm
    cannot reach the slot."""
    slot = workcell.slot_of(tool_name).pose.matrix()
    above = slot.copy()
    above[:3, 3] -= workcell.rack.approach_m * slot[:3, 2]      # back along the slot's axis: up
    q_slot, ok = choose_centred(model, ik_flange(model, slot, WRIST_MARGIN))
    if not ok:
        raise ValueError(f"the arm cannot reach the rack slot of {tool_name!r}")
    q_above, ok = choose_nearest(model, ik_flange(model, above, WRIST_MARGIN), q_slot)
    if not ok:
        raise ValueError(f"the arm cannot reach {workcell.rack.approach_m} m above the rack slot of {tool_name!r}")
    return q_slot, q_above


def flange_move_seconds(model: ArmModel, q_from: FloatArray, q_to: FloatArray) -> float:
    """Seconds of one joint-space move (6,) -> (6,) with the flange's chord speed cap."""
    return float(move_time_matrix(model, q_from[None, :], q_to[None, :], tcp=np.eye(4))[0, 0])


def motion_time_tour(workcell: Workcell, tool: ToolSpec, specs: Sequence[MeasurementSpec]) -> FloatArray:
    """``(n + 1, n + 1)`` seconds of arm motion between the rack slot (stop 0) and the
    measurements' configurations (symmetric, zero diagonal).  ValueError naming the
    measurements that have no configuration (the pose facts send them to cannot-be-done)."""
    model = arm_model(workcell.arm)
    conf = measurement_configurations(workcell, model, tool, specs)
    if not conf.found.all():
        missing = [f"{s.id} ({st})" for s, st, f in zip(specs, conf.status, conf.found) if not f]
        raise ValueError(f"no arm configuration for {len(missing)} measurement(s) with {tool.name}: "
                         + ", ".join(missing[:5]) + (", ..." if len(missing) > 5 else ""))
    q_slot, _ = rack_configurations(workcell, model, tool.name)
    stops = np.vstack([q_slot[None, :], conf.q])
    return move_time_matrix(model, stops, tcp=tool.tcp.matrix())


def rack_seconds(workcell: Workcell, tool_a: str | None, tool_b: str | None) -> float:
    """Seconds at the rack from tool_a coupled in its slot to tool_b coupled in its slot.

    Put tool_a back: unlock, lift the empty flange; move above tool_b's slot; pick it up:
    lower the flange, lock.  None on either side leaves out that side (and the move).
    """
    model = arm_model(workcell.arm)
    total = 0.0
    above_a = above_b = None
    if tool_a is not None:
        slot_a, above_a = rack_configurations(workcell, model, tool_a)
        total += COUPLING_S + flange_move_seconds(model, slot_a, above_a)
    if tool_b is not None:
        slot_b, above_b = rack_configurations(workcell, model, tool_b)
        total += flange_move_seconds(model, above_b, slot_b) + COUPLING_S
    if above_a is not None and above_b is not None and tool_a != tool_b:
        total += flange_move_seconds(model, above_a, above_b)
    return total


def pose_facts(workcell: Workcell, specs: Sequence[MeasurementSpec]) -> list[list[Term]]:
    """The reach facts and ``pose(ToolType, Verdict)`` per spec for each tool type, from the
    inverse kinematics of the type's first tool (Verdict ``reachable`` or the IK status):
    kb/tools.pl sends a measurement with no pose to cannot-be-done as ``no_pose``."""
    facts = reach_facts(workcell, specs)
    if not specs:
        return facts
    model = arm_model(workcell.arm)
    for tool_class in Tool:
        tools = workcell.tools_of_class(tool_class)
        if not tools:
            continue
        poses, _ = candidate_poses(workcell, tools[0], specs)
        ik = ik_tool(model, poses, tools[0].tcp.matrix(), WRIST_MARGIN).flatten_batch()
        for row, found, status in zip(facts, ik.found, ik.statuses()):
            row.append(Term("pose", (tool_class.value, POSE_OK if found else status.value)))
    return facts


@dataclass(frozen=True, eq=False)
class PlacedFacts:
    """A facts function: `base`'s facts plus, per spec, ``placed(ToolClass, Verdict)`` for
    each tool class the Geometric Reasoner's MKB tried to place it for (`placement`, from
    ita.geometry.MeasurementKB.placement: ``placed`` or why not, e.g. ``contact_blocked``).
    kb/tools.pl then leaves a tool type whose contact pose collides everywhere for the next
    rule (the straight probe's blocked flange walls for the bent probe)."""

    placement: Mapping[str, tuple[tuple[str, str], ...]]
    base: Callable[["Workcell", Sequence[MeasurementSpec]], list[list[Term]]] = pose_facts

    def __call__(self, workcell: Workcell, specs: Sequence[MeasurementSpec]) -> list[list[Term]]:
        facts = self.base(workcell, specs)
        for row, spec in zip(facts, specs):
            row.extend(Term("placed", (c, v)) for c, v in self.placement.get(spec.id, ()))
        return facts


MOTION_TIME_COST = CostModel(
    name="arm_motion_time",
    description=("seconds of arm motion: joint-space move times between one IK configuration per "
                 "measurement (joint velocity and acceleration limits, TCP speed cap), the rack slot "
                 f"at each tour's ends, tool changes at the rack (coupling {COUPLING_S:g} s each way); "
                 "not measuring time, not obstacle detours"),
    tour=motion_time_tour,
    transfer=rack_seconds,
)


# -- the interim estimate -------------------------------------------------------------------

def tool_points_world(workcell: Workcell, tool: ToolSpec, specs: Sequence[MeasurementSpec]) -> np.ndarray:
    """``(n, 3) float``: world position (m) of the tool centre point at each spec.

    The probe's tip on the spec point; the SLRA's optical centre on the normal at its
    nominal stand-off.
    """
    points = np.array([s.point for s in specs], dtype=float).reshape(-1, 3)
    normals = np.array([s.normal for s in specs], dtype=float).reshape(-1, 3)
    world = workcell.part.to_world(points)
    if tool.standoff_nominal:
        n_world = workcell.part.normals_to_world(normals)
        n_world /= np.linalg.norm(n_world, axis=1, keepdims=True)
        world = world + n_world * tool.standoff_nominal
    return world


def slot_position(workcell: Workcell, tool_name: str) -> np.ndarray:
    """``(3,) float``: world position (m) of the rack slot where `tool_name` is parked."""
    for slot in workcell.rack.slots:
        if slot.tool == tool_name:
            return np.asarray(slot.pose.position, dtype=float)
    raise ValueError(f"no rack slot holds tool {tool_name!r}")


def euclidean_tcp_seconds(workcell: Workcell, tool: ToolSpec, specs: Sequence[MeasurementSpec]) -> np.ndarray:
    """INTERIM tour cost: straight-line TCP distance / max TCP speed, ``(n + 1, n + 1)`` s."""
    stops = np.vstack([slot_position(workcell, tool.name)[None, :], tool_points_world(workcell, tool, specs)])
    diff = stops[:, None, :] - stops[None, :, :]
    return np.sqrt(np.einsum("ijk,ijk->ij", diff, diff)) / workcell.arm.max_tool_speed


def euclidean_slot_seconds(workcell: Workcell, tool_a: str | None, tool_b: str | None) -> float:
    """INTERIM transfer cost: straight-line distance between two rack slots / max TCP speed
    (0 with None on either side: no coupling time)."""
    if tool_a is None or tool_b is None:
        return 0.0
    d = np.linalg.norm(slot_position(workcell, tool_a) - slot_position(workcell, tool_b))
    return float(d / workcell.arm.max_tool_speed)


INTERIM_COST = CostModel(
    name="euclidean_tcp_interim",
    description="straight-line tool-point distance / max tool speed (interim lower bound, not arm motion time)",
    tour=euclidean_tcp_seconds,
    transfer=euclidean_slot_seconds,
    interim=True,
)

#: the cost models by name (PlanningContext.cost_model takes one of these)
COST_MODELS: dict[str, CostModel] = {m.name: m for m in (MOTION_TIME_COST, INTERIM_COST)}

__all__ = [
    "COST_MODELS", "COUPLING_S", "INTERIM_COST", "MOTION_TIME_COST",
    "CostModel", "PlacedFacts", "euclidean_slot_seconds", "euclidean_tcp_seconds",
    "flange_move_seconds", "motion_time_tour", "pose_facts",
    "rack_configurations", "rack_seconds", "slot_position", "tool_points_world",
]
