"""Can the arm reach a tool pose, and which of its solutions to take.

`reachable` is exact for the arm alone: a tool pose is reachable when the inverse
kinematics gives a solution within the joint limits.  It ignores collisions (with the
part, the fixture, the cell and the arm itself), which are the path planner's business.

The choosers pick one solution per pose from an `IKSolutions` (over its slot axis; merge
candidate rolls into it first with `IKSolutions.flatten_batch`):

* `choose_nearest`: the quickest to reach from a reference configuration (the motion time
  of `timing.move_time`, ties to the first slot);
* `choose_centred`: the furthest from the joint limits (the largest least margin of any
  joint, as a fraction of its range).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ita.kinematics.fk import ArmModel
from ita.kinematics.ik import IKSolutions, ik_tool
from ita.kinematics.timing import move_time

FloatArray = NDArray[np.float64]


def reachable(model: ArmModel, tool_poses: ArrayLike, tcp: ArrayLike, wrist_margin: float = 0.0) -> NDArray[np.bool_]:
    """Bool (*B): whether some joint solution within the limits puts the TCP (4, 4), given
    in the flange frame, at each world tool pose (*B, 4, 4)."""
    return ik_tool(model, tool_poses, tcp, wrist_margin).found


def choose_nearest(model: ArmModel, solutions: IKSolutions, q_ref: ArrayLike) -> tuple[FloatArray, NDArray[np.bool_]]:
    """The valid solution of each pose quickest to reach from q_ref ((6,) or (*B, 6)).

    Returns (q (*B, 6), found (*B)); rows without a solution are nan.
    """
    ref = np.asarray(q_ref, dtype=float)[..., None, :]
    cost = move_time(model, ref, np.nan_to_num(solutions.q))
    return _pick(solutions, np.where(solutions.valid, cost, np.inf))


def choose_centred(model: ArmModel, solutions: IKSolutions) -> tuple[FloatArray, NDArray[np.bool_]]:
    """The valid solution of each pose furthest from the joint limits.

    Returns (q (*B, 6), found (*B)); rows without a solution are nan.
    """
    margin = limit_margin(model, np.nan_to_num(solutions.q))
    return _pick(solutions, np.where(solutions.valid, -margin, np.inf))


def limit_margin(model: ArmModel, q: ArrayLike) -> FloatArray:
    """Least distance (...) of configs q (..., 6) to any joint limit, as a fraction of that
    joint's range (0.5 at the middle of every range, negative outside the limits)."""
    q = np.asarray(q, dtype=float)
    return (np.minimum(q - model.lower, model.upper - q) / (model.upper - model.lower)).min(axis=-1)


def _pick(solutions: IKSolutions, cost: FloatArray) -> tuple[FloatArray, NDArray[np.bool_]]:
    """Lowest-cost slot per pose: q (*B, 6) (nan where no slot is valid) and found (*B)."""
    best = np.argmin(cost, axis=-1)
    q = np.take_along_axis(solutions.q, best[..., None, None], axis=-2)[..., 0, :]
    found = solutions.found
    return np.where(found[..., None], q, np.nan), found
