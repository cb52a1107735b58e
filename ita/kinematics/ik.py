"""Inverse kinematics of the arm: every joint solution of a flange or tool pose, in closed form.

The arm has a spherical wrist (j4, j5, j6 meet at the wrist centre), so its inverse
kinematics separates: the wrist centre, ``d6`` behind the flange along its approach (z)
axis, fixes j1, j2, j3; the flange's orientation then fixes j4, j5, j6.  Each pose has up
to eight solutions, the branches

* shoulder: front (j1 turns the arm toward the wrist centre) or back (j1 + pi, the arm
  reaching over behind itself);
* elbow: j3 = asin(s) in [-pi/2, pi/2] ("up" when the arm faces front: the elbow above the
  shoulder-to-wrist line) or j3 = -pi - asin(s) ("down");
* wrist: j5 >= 0, or the flipped wrist (j4 + pi, -j5, j6 + pi);

and each angle is then moved by whole turns into its joint's range: a joint whose range
spans more than a turn (j6, +-270 deg) gives a second solution where both q and q +- 2 pi
lie within it.  The solutions are exact (to rounding); no numeric refinement is needed for
this arm.  At a wrist singularity (j5 = 0) only j4 + j6 is determined: j4 is set to 0 (pi
for the flipped wrist) and j6 takes the rest.

Solution slots (the K axis, K = 8 x 2 for this arm) are in a fixed order:
``slot = ((shoulder * 2 + elbow) * 2 + wrist) * A + alternative``, shoulder 0 = front,
elbow 0 = up, wrist 0 = j5 >= 0, alternative 0 = the angle nearest above each joint's lower
limit; `valid` says which slots hold a solution within the joint limits.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from enum import Enum
from itertools import product
from typing import cast

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ita.kinematics.fk import JOINT_LIMIT_TOL, ArmModel, invert_poses

FloatArray = NDArray[np.float64]
TWO_PI = 2.0 * np.pi
_ANGLE_TOL = JOINT_LIMIT_TOL   # rad: slack at the joint limits (IK at a limit and near a singularity
                               # loses up to ~4e-7 rad); solutions within it are clipped onto the limit
_REACH_TOL = 1e-12  # slack on |sin j3| <= 1 at the edge of the workspace
_TURN_SLACK = 1e-3  # rad: a range this little over a turn (j4's +-3.141593) gives no second turn


class IKStatus(str, Enum):
    """Why a pose has solutions or not; the value is the spelling in reports."""

    OK = "ok"
    OUT_OF_REACH = "out_of_reach"
    JOINT_LIMITS = "joint_limits"
    WRIST_SINGULARITY = "wrist_singularity"


IK_STATUS_DESCRIPTIONS: dict[IKStatus, str] = {
    IKStatus.OK: "at least one solution within the joint limits",
    IKStatus.OUT_OF_REACH: "the wrist centre is beyond or inside the arm's reach for every shoulder branch",
    IKStatus.JOINT_LIMITS: "the arm can place the wrist centre, but every solution breaks a joint limit",
    IKStatus.WRIST_SINGULARITY: "solutions within the limits exist, but all have j5 inside the wrist margin",
}

_STATUSES = tuple(IKStatus)
# How near to having a solution each status is, best first (for merged batches).
_NEARNESS = (IKStatus.OK, IKStatus.WRIST_SINGULARITY, IKStatus.JOINT_LIMITS, IKStatus.OUT_OF_REACH)


@dataclass(frozen=True, eq=False)
class IKSolutions:
    """All inverse-kinematics solutions of a batch of poses with batch shape B (e.g. (n,) or (n, k)).

    q: (*B, K, 6) joint angles (rad) per solution slot (see the module docstring for the
    order); slots without a solution hold nan.  valid: (*B, K) whether the slot holds a
    solution within the joint limits (and outside the wrist margin).  violations:
    (*B, K, 6) which joints break their limits in slots whose position equations solve.
    wrist_clearance: (*B, K) |sin j5| (0 at the wrist singularity).  codes: (*B) int8,
    index into `tuple(IKStatus)`; see `status`.
    """

    q: FloatArray
    valid: NDArray[np.bool_]
    violations: NDArray[np.bool_] = field(repr=False)
    wrist_clearance: FloatArray = field(repr=False)
    codes: NDArray[np.int8] = field(repr=False)

    @property
    def shape(self) -> tuple[int, ...]:
        """The batch shape B."""
        return self.codes.shape

    @property
    def found(self) -> NDArray[np.bool_]:
        """Bool (*B): whether each pose has at least one valid solution."""
        # a numpy bool when B is () (a single pose), which acts as the 0-d array here
        return cast(NDArray[np.bool_], self.valid.any(axis=-1))

    def status(self, index: int | tuple[int, ...]) -> IKStatus:
        """The status of one pose of the batch."""
        return _STATUSES[int(self.codes[index])]

    def statuses(self) -> list[IKStatus]:
        """The status of every pose, in C order of the batch."""
        return [_STATUSES[c] for c in self.codes.reshape(-1)]

    def counts(self) -> dict[IKStatus, int]:
        """Number of poses per status (statuses that occur only), in IKStatus order."""
        values, counts = np.unique(self.codes, return_counts=True)
        return {_STATUSES[v]: int(c) for v, c in zip(values, counts)}

    def solutions(self, index: int | tuple[int, ...], tol: float = 1e-9) -> FloatArray:
        """The distinct valid solutions (m, 6) of one pose, in slot order (m may be 0)."""
        q = self.q[index][self.valid[index]]
        keep: list[int] = []
        for i in range(len(q)):
            if not any(np.all(np.abs(q[i] - q[j]) <= tol) for j in keep):
                keep.append(i)
        return q[keep]

    def blocking_joints(self, index: int | tuple[int, ...]) -> tuple[int, ...]:
        """Joints (0-based) that the solvable slot with the fewest limit violations breaks.

        Empty when the pose has a valid solution or is out of reach.
        """
        if self.valid[index].any():
            return ()
        v = self.violations[index]
        n_broken = np.where(v.any(axis=-1), v.sum(axis=-1), 99)
        if n_broken.min() == 99:
            return ()
        return tuple(int(j) for j in np.flatnonzero(v[int(np.argmin(n_broken))]))

    def flatten_batch(self, axes: int = 1) -> IKSolutions:
        """Merge the last `axes` batch axes into the slot axis: e.g. (n, k) rolls x K slots
        -> (n,) with k*K slots, so that one solution can be chosen over all rolls."""
        keep = self.shape[: len(self.shape) - axes]
        return IKSolutions(
            self.q.reshape(*keep, -1, self.q.shape[-1]),
            self.valid.reshape(*keep, -1),
            self.violations.reshape(*keep, -1, self.violations.shape[-1]),
            self.wrist_clearance.reshape(*keep, -1),
            _merge_codes(self.codes, axes),
        )


def ik_flange(model: ArmModel, poses: ArrayLike, wrist_margin: float = 0.0) -> IKSolutions:
    """All joint solutions of world flange poses (*B, 4, 4) (a single (4, 4) gives B = ()).

    wrist_margin: solutions with |j5| < wrist_margin (rad), too near the wrist singularity,
    are not valid; a pose whose only solutions are such reports WRIST_SINGULARITY.
    """
    poses = np.asarray(poses, dtype=float)
    if poses.shape[-2:] != (4, 4):
        raise ValueError(f"poses must be (..., 4, 4), got {poses.shape}")
    batch = poses.shape[:-2]
    flat = poses.reshape(-1, 4, 4)
    q, solved = _branches(model, invert_poses(model.base) @ flat)          # (m, 8, 6), (m, 8)
    q, solved = _wrap_into_limits(model, q, solved)                          # (m, K, 6), (m, K)
    inside = (q >= model.lower - _ANGLE_TOL) & (q <= model.upper + _ANGLE_TOL)
    q = np.where(inside, np.clip(q, model.lower, model.upper), q)
    violations = solved[..., None] & ~inside
    clearance = np.abs(np.sin(q[..., 4]))
    in_limits = solved & inside.all(axis=-1)
    clear = np.abs(q[..., 4]) >= wrist_margin
    valid = in_limits & clear
    codes = np.where(
        valid.any(axis=-1), _STATUSES.index(IKStatus.OK),
        np.where(in_limits.any(axis=-1), _STATUSES.index(IKStatus.WRIST_SINGULARITY),
                 np.where(solved.any(axis=-1), _STATUSES.index(IKStatus.JOINT_LIMITS),
                          _STATUSES.index(IKStatus.OUT_OF_REACH)))).astype(np.int8)
    q = np.where(solved[..., None], q, np.nan)
    k = q.shape[1]
    return IKSolutions(
        q.reshape(*batch, k, 6), valid.reshape(*batch, k), violations.reshape(*batch, k, 6),
        clearance.reshape(*batch, k), codes.reshape(batch),
    )


def ik_tool(model: ArmModel, tool_poses: ArrayLike, tcp: ArrayLike, wrist_margin: float = 0.0) -> IKSolutions:
    """All joint solutions placing a tool's TCP at world poses (*B, 4, 4).

    tcp: (4, 4) the TCP frame in the flange frame (`ToolSpec.tcp.matrix()`).
    """
    flange = np.asarray(tool_poses, dtype=float) @ invert_poses(np.asarray(tcp, dtype=float))
    return ik_flange(model, flange, wrist_margin)


def slot_count(model: ArmModel) -> int:
    """K: the number of solution slots per pose (8 branches x the whole-turn alternatives)."""
    return 8 * 2 ** int(np.count_nonzero(_multi_turn(model)))


def _branches(model: ArmModel, poses: FloatArray) -> tuple[FloatArray, NDArray[np.bool_]]:
    """Raw solutions (m, 8, 6) of base-frame flange poses (m, 4, 4) and whether each
    branch's position equations solve (m, 8).  Angles are not yet wrapped into the limits."""
    kin = model.kinematics
    m = len(poses)
    rot, pos = poses[:, :3, :3], poses[:, :3, 3]
    wrist = pos - kin.d6 * rot[:, :, 2]
    azimuth = np.arctan2(wrist[:, 1], wrist[:, 0])
    horizontal = np.hypot(wrist[:, 0], wrist[:, 1])
    height = wrist[:, 2] - kin.d1
    # shoulder branch (m, 2): front, back
    q1 = np.stack([azimuth, azimuth + np.pi], axis=1)
    reach = np.stack([horizontal, -horizontal], axis=1) - kin.a1            # along the arm's x
    s = (kin.a2**2 + kin.d4**2 - reach**2 - height[:, None] ** 2) / (2.0 * kin.a2 * kin.d4)
    solved2 = np.abs(s) <= 1.0 + _REACH_TOL
    asin = np.arcsin(np.clip(s, -1.0, 1.0))
    # elbow branch (m, 2, 2): up, down
    q3 = np.stack([asin, -np.pi - asin], axis=2)
    big_a = kin.a2 - kin.d4 * np.sin(q3)
    big_b = kin.d4 * np.cos(q3)
    q2 = np.arctan2(reach, height[:, None])[:, :, None] - np.arctan2(big_b, big_a)
    q1e = np.broadcast_to(q1[:, :, None], q3.shape)
    # wrist: M = R03^T R R_f^T = Rx(q4) Ry(q5) Rx(q6), R03 = Rz(q1) Ry(q2 + q3)
    r03 = _rz(q1e) @ _ry(q2 + q3)                                            # (m, 2, 2, 3, 3)
    r_f = model.flange_offset[:3, :3]
    wrist_rot = np.swapaxes(r03, -1, -2) @ (rot @ r_f.T)[:, None, None]
    m10, m20 = wrist_rot[..., 1, 0], wrist_rot[..., 2, 0]
    q4 = np.where(np.hypot(m10, m20) > 1e-12, np.arctan2(m10, -m20), 0.0)
    q4 = np.stack([q4, q4 + np.pi], axis=-1)                                 # (m, 2, 2, 2)
    # M' = Rx(q4)^T M = Ry(q5) Rx(q6)
    c4, s4 = np.cos(q4), np.sin(q4)
    w = wrist_rot[..., None, :, :]
    row0 = w[..., 0, :]
    row1 = c4[..., None] * w[..., 1, :] + s4[..., None] * w[..., 2, :]
    row2 = -s4[..., None] * w[..., 1, :] + c4[..., None] * w[..., 2, :]
    q5 = np.arctan2(-row2[..., 0], row0[..., 0])
    q6 = np.arctan2(-row1[..., 2], row1[..., 1])
    full = np.empty((m, 2, 2, 2, 6))
    full[..., 0] = q1[:, :, None, None]
    full[..., 1] = q2[..., None]
    full[..., 2] = q3[..., None]
    full[..., 3], full[..., 4], full[..., 5] = q4, q5, q6
    solved = np.broadcast_to(solved2[:, :, None, None], (m, 2, 2, 2))
    return full.reshape(m, 8, 6), solved.reshape(m, 8)


def _wrap_into_limits(
    model: ArmModel, q: FloatArray, solved: NDArray[np.bool_]
) -> tuple[FloatArray, NDArray[np.bool_]]:
    """Move each angle by whole turns to the first value at or above its lower limit; for a
    joint with more than a turn of range, add the next turn up as an alternative slot.
    (m, 8, 6) -> (m, K, 6); solved (m, 8) -> (m, K)."""
    lower = model.lower - _ANGLE_TOL
    wrapped = lower + np.mod(q - lower, TWO_PI)
    multi = np.flatnonzero(_multi_turn(model))
    if multi.size == 0:
        return wrapped, solved
    options = []
    for turns in product((0, 1), repeat=multi.size):
        shifted = wrapped.copy()
        shifted[..., multi] += TWO_PI * np.asarray(turns)
        options.append(shifted)
    stacked = np.stack(options, axis=2)                                      # (m, 8, A, 6)
    m, branches, alternatives = stacked.shape[:3]
    solved = np.broadcast_to(solved[:, :, None], (m, branches, alternatives))
    return stacked.reshape(m, branches * alternatives, 6), solved.reshape(m, -1)


def _multi_turn(model: ArmModel) -> NDArray[np.bool_]:
    """Bool (6,): joints whose range spans clearly more than a whole turn."""
    span = model.upper - model.lower
    if np.any(span > 2.0 * TWO_PI):
        raise ValueError("joint ranges over two turns are not supported")
    return span > TWO_PI + _TURN_SLACK


def _rz(a: FloatArray) -> FloatArray:
    c, s, o, z = np.cos(a), np.sin(a), np.ones_like(a), np.zeros_like(a)
    return np.stack([np.stack([c, -s, z], -1), np.stack([s, c, z], -1), np.stack([z, z, o], -1)], -2)


def _ry(a: FloatArray) -> FloatArray:
    c, s, o, z = np.cos(a), np.sin(a), np.ones_like(a), np.zeros_like(a)
    return np.stack([np.stack([c, z, s], -1), np.stack([z, o, z], -1), np.stack([-s, z, c], -1)], -2)


def _merge_codes(codes: NDArray[np.int8], axes: int) -> NDArray[np.int8]:
    """Status codes of merged batch axes: OK if any is OK, else the nearest-to-OK failure."""
    if axes == 0:
        return codes
    by_nearness = np.array([_STATUSES.index(s) for s in _NEARNESS], dtype=np.int8)
    rank = np.argsort(by_nearness).astype(np.int8)
    flat = rank[codes].reshape(*codes.shape[: codes.ndim - axes], -1)
    return by_nearness[flat.min(axis=-1)]
