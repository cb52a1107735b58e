"""Where a tool stands to take a measurement: its candidate tool poses and the one arm
configuration chosen per measurement (geometric knowledge the Sequence Planner's cost and
the Geometric Reasoner's MKB share, so the tours the sequence plan costs are the ones the
arm flies).

    pa, na, pb, nb = contact_poses(specs)          # where the probe must touch (two sides of a rib)
    poses, preferred = candidate_poses(cell, tool, specs)
    conf = measurement_configurations(cell, model, tool, specs)   # conf.q (n, 6), conf.found

Configurations, per tool group:

1. candidates: the tool poses that take the measurement (ita.kinematics.tool_poses):
   :data:`ROLLS` rolls about the normal; for the SLRA also the stand-offs of its working
   range that the reach test tries (the nominal one preferred); for the probe on a rib's
   width both side walls (:func:`contact_poses`).  Every exact inverse-kinematics
   solution of every candidate within the joint limits is a choice.
2. the group's common branch: the IK branch (shoulder, elbow, wrist) that the most
   measurements of the group can use (ties: the first in slot order, front/up/j5 >= 0);
   its reference configuration: the joint-wise median of each measurement's solution in
   that branch furthest from the joint limits (``choose_centred``).
3. per measurement: the solution in the common branch quickest to reach from the
   reference (``choose_nearest``); a measurement without one in that branch takes the
   quickest of all its solutions.  So neighbours share a branch, a roll and a j6 turn, and
   stay away from the joint limits.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from ita.kinematics import (
    ArmModel,
    IKSolutions,
    choose_centred,
    choose_nearest,
    ik_tool,
    measurement_poses,
    roll_angles,
    slot_count,
)
from ita.specs.model import MeasurementKind, MeasurementSpec

if TYPE_CHECKING:
    from ita.workcell.model import ToolSpec, Workcell

FloatArray = NDArray[np.float64]

#: rolls about the normal tried per tool pose (evenly over a turn)
ROLLS = 12
#: IK solutions with |j5| below this (rad) are not used (0: the exact limits only)
WRIST_MARGIN = 0.0
#: the pose fact's verdict for a measurement with a configuration (kb/tools.pl)
POSE_OK = "reachable"
#: the probe touches a rib's side wall this far below the rib's top (mm)
RIB_CONTACT_BELOW_TOP_MM = 8.0

__all__ = ["POSE_OK", "RIB_CONTACT_BELOW_TOP_MM", "ROLLS", "WRIST_MARGIN", "Configurations", "candidate_poses",
           "contact_poses", "measurement_configurations", "standoffs_to_try"]


def contact_poses(specs: Sequence[MeasurementSpec]) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Where the ultrasonic probe must touch for each spec: two candidate poses.

    Returns (points_a, normals_a, points_b, normals_b), each ``(n, 3) float``, part frame,
    mm.  For most kinds both candidates are the spec's point and normal; for a rib's
    width they are the two side walls, :data:`RIB_CONTACT_BELOW_TOP_MM` below the top,
    normals along -/+ the measuring direction.
    """
    p = np.array([s.point for s in specs], dtype=float).reshape(-1, 3)
    nrm = np.array([s.normal for s in specs], dtype=float).reshape(-1, 3)
    pa, na, pb, nb = p.copy(), nrm.copy(), p.copy(), nrm.copy()
    for i, s in enumerate(specs):
        if s.kind is MeasurementKind.STIFFENER_WIDTH and s.direction is not None:
            d = np.asarray(s.direction, dtype=float)
            below = p[i] - nrm[i] * RIB_CONTACT_BELOW_TOP_MM
            half = 0.5 * s.nominal
            pa[i], na[i] = below - d * half, -d
            pb[i], nb[i] = below + d * half, d
    return pa, na, pb, nb


@dataclass(frozen=True, eq=False)
class Configurations:
    """One arm configuration per measurement of a tool (see the module docstring).

    q: ``(n, 6) float`` rad, nan where `found` is False; found: ``(n,) bool``;
    status: per measurement :data:`POSE_OK` or the IK status of the candidate nearest to
    having a solution (``out_of_reach``, ``joint_limits``, ``wrist_singularity``);
    branch: the common IK branch (0..7, slot order of ita.kinematics.ik); q_ref: ``(6,)``
    its reference configuration (nan when no measurement has a solution);
    in_branch: ``(n,) bool`` whether the chosen solution is in the common branch.
    """

    q: FloatArray
    found: NDArray[np.bool_]
    status: tuple[str, ...]
    branch: int
    q_ref: FloatArray
    in_branch: NDArray[np.bool_]


def standoffs_to_try(tool: ToolSpec, samples: int) -> FloatArray:
    """Stand-offs (k,) m of a tool, the nominal one first, then `samples` evenly over its
    range (the reach test's samples, ita.workcell.reach); (1,) for a contact probe."""
    if tool.standoff_max > tool.standoff_min:
        extra = np.linspace(tool.standoff_min, tool.standoff_max, max(samples, 2))
        return np.concatenate([[tool.standoff_nominal], extra[~np.isclose(extra, tool.standoff_nominal)]])
    return np.array([tool.standoff_nominal])


def candidate_poses(workcell: Workcell, tool: ToolSpec,
                    specs: Sequence[MeasurementSpec]) -> tuple[FloatArray, NDArray[np.bool_]]:
    """World TCP poses ``(n, c, 4, 4)`` that take each measurement with `tool`, and
    ``(n, c) bool`` which of them are preferred (the nominal stand-off).

    The ultrasonic probe: both contact poses of ita.sequence.partition.contact_poses
    (different only on a rib's width) x :data:`ROLLS` rolls.  The SLRA: the spec point
    seen along its normal at :func:`standoffs_to_try` x :data:`ROLLS` rolls.
    """
    n = len(specs)
    rolls = roll_angles(ROLLS)
    if tool.tool_class.ultrasonic:
        pa, na, pb, nb = contact_poses(specs)
        side_a = measurement_poses(workcell.part, pa, na, tool, rolls, standoff=0.0)
        side_b = measurement_poses(workcell.part, pb, nb, tool, rolls, standoff=0.0)
        two_sided = np.array([s.kind is MeasurementKind.STIFFENER_WIDTH for s in specs], dtype=bool)
        poses = np.concatenate([side_a, side_b], axis=1)
        preferred = np.ones(poses.shape[:2], dtype=bool)
        preferred[~two_sided, len(rolls):] = False  # the same pose twice: count it once
        return poses, preferred
    points = np.array([s.point for s in specs], dtype=float).reshape(-1, 3)
    normals = np.array([s.normal for s in specs], dtype=float).reshape(-1, 3)
    standoffs = standoffs_to_try(tool, workcell.reach.standoff_samples)
    poses = np.concatenate([measurement_poses(workcell.part, points, normals, tool, rolls, standoff=float(d))
                            for d in standoffs], axis=1)
    preferred = np.zeros((n, poses.shape[1]), dtype=bool)
    preferred[:, : len(rolls)] = True
    return poses, preferred


def measurement_configurations(workcell: Workcell, model: ArmModel, tool: ToolSpec,
                               specs: Sequence[MeasurementSpec]) -> Configurations:
    """Choose one configuration per measurement (steps 1 to 3 of the module docstring)."""
    n = len(specs)
    if n == 0:
        empty = np.zeros((0, model.dof))
        return Configurations(empty, np.zeros(0, bool), (), 0, np.full(model.dof, np.nan), np.zeros(0, bool))
    poses, preferred = candidate_poses(workcell, tool, specs)
    ik = ik_tool(model, poses, tool.tcp.matrix(), WRIST_MARGIN)             # batch (n, c), K slots
    flat = ik.flatten_batch()                                                # batch (n,), c*K slots
    k = slot_count(model)
    # a preferred candidate's solutions when there are any, else all of them
    pref = ik.valid & preferred[..., None]
    any_pref = pref.any(axis=(1, 2))
    assert isinstance(any_pref, np.ndarray)   # (n,): pref is 3-D
    use = np.where(any_pref[:, None, None], pref, ik.valid).reshape(n, -1)
    branch_of = (np.arange(flat.valid.shape[1]) % k) // (k // 8)             # (c*K,) branch 0..7
    per_branch = np.array([(use & (branch_of == b)).any(axis=1).sum() for b in range(8)])
    branch = int(np.argmax(per_branch))
    in_common = use & (branch_of == branch)
    q_ref = np.full(model.dof, np.nan)
    if in_common.any():
        centred, has = choose_centred(model, _masked(flat, in_common))
        q_ref = np.median(centred[has], axis=0)
    choose_from = np.where(in_common.any(axis=1)[:, None], in_common, use)
    ref = q_ref if np.isfinite(q_ref).all() else np.zeros(model.dof)
    q, found = choose_nearest(model, _masked(flat, choose_from), ref)
    status = tuple(POSE_OK if f else s.value for f, s in zip(found, flat.statuses()))
    return Configurations(q, found, status, branch, q_ref, found & in_common.any(axis=1))


def _masked(solutions: IKSolutions, keep: NDArray[np.bool_]) -> IKSolutions:
    """The solutions with only the `keep` slots valid."""
    return replace(solutions, valid=solutions.valid & keep)
