"""Small joint changes that move a tool's TCP by a small world offset.

    dq = joint_offset(model, q, tcp, offset)       # least-norm (turns the tool a little)
    dq = joint_translation(model, q, tcp, offset)  # keeping the tool's orientation
    q1 = settled(model, q, tcp, offset)            # where an arm sent to q settles

The robot controller settles its moves with them (the repeatability draw and drift), the
arm device jogs with them, and the SLRA's calibration on a part's master draws its frames'
pose errors the way a run does.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ita.kinematics.fk import ArmModel, flange_poses

FloatArray = NDArray[np.float64]

__all__ = ["joint_offset", "joint_translation", "settled"]


def settled(model: ArmModel, q: ArrayLike, tcp: ArrayLike, offset: ArrayLike) -> FloatArray:
    """The joints (6,) an arm sent to q settles at when its TCP (4, 4 in the flange frame)
    ends off by the world offset (3,) m: the least-norm joint change (joint_offset), which
    turns the tool a little too, never past a joint's limit.  The SLRA's calibration on a
    part's master draws its frames' pose errors through this too (ita.offline.master)."""
    q = np.asarray(q, dtype=float)
    return np.clip(q + joint_offset(model, q, tcp, offset), model.lower, model.upper)


def joint_offset(model: ArmModel, q: ArrayLike, tcp: ArrayLike, offset: ArrayLike) -> FloatArray:
    """The least-norm joint change (6,) that moves the TCP (4, 4 in the flange frame) at
    joints q (6,) by the small world offset (3,) m (position Jacobian pseudo-inverse)."""
    q = np.asarray(q, dtype=float)
    eps = 1e-6
    qs = np.vstack([q, q + eps * np.eye(model.dof)])
    points = (flange_poses(model, qs) @ np.asarray(tcp, dtype=float))[:, :3, 3]
    jac = ((points[1:] - points[0]) / eps).T                     # (3, 6)
    return np.linalg.pinv(jac) @ np.asarray(offset, dtype=float)


def joint_translation(model: ArmModel, q: ArrayLike, tcp: ArrayLike, offset: ArrayLike,
                      iterations: int = 5) -> FloatArray:
    """The joint change (6,) that moves the TCP (4, 4 in the flange frame) at joints q (6,)
    by the world offset (3,) m keeping its orientation: Newton steps on the position and
    rotation error together (a least-norm position step alone turns the tool by a degree or
    two over a few centimetres)."""
    q0 = np.asarray(q, dtype=float)
    tcp = np.asarray(tcp, dtype=float)
    start = flange_poses(model, q0[None])[0] @ tcp
    target, rot0 = start[:3, 3] + np.asarray(offset, dtype=float), start[:3, :3]

    def error(pose: FloatArray) -> FloatArray:
        m = rot0.T @ pose[:3, :3]
        return np.concatenate([pose[:3, 3] - target, 0.5 * np.array([m[2, 1] - m[1, 2], m[0, 2] - m[2, 0],
                                                                       m[1, 0] - m[0, 1]])])

    eps = 1e-6
    qk = q0.copy()
    for _ in range(iterations):
        poses = flange_poses(model, np.vstack([qk, qk + eps * np.eye(model.dof)])) @ tcp
        e0 = error(poses[0])
        if float(np.abs(e0).max()) < 1e-9:
            break
        jac = np.stack([(error(p) - e0) / eps for p in poses[1:]], axis=1)       # (6, 6)
        qk = qk - np.linalg.pinv(jac) @ e0
    return qk - q0
