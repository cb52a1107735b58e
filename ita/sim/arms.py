"""The cell's two arms in pybullet (DIRECT), to find where they touch.

Each arm is its URDF at its own base pose; :meth:`TwoArms.gaps` sets both arms'
configurations and asks pybullet for the closest points between the two bodies (their
links' collision shapes) within a margin: a gap of 0 or less is a contact.  The
simulator's own check of what the interference zones promise, independent of them.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Self

import numpy as np

from ita.bullet import import_pybullet
from ita.workcell import Workcell

__all__ = ["TwoArms"]


class TwoArms:
    """Both arms of `cell` in a private pybullet client; close() or use ``with``."""

    def __init__(self, cell: Workcell) -> None:
        p = import_pybullet()
        self.p = p
        arms = cell.arms()
        if len(arms) != 2:
            raise ValueError(f"the workcell {cell.source} names {len(arms)} arm(s), not two")
        self.names = tuple(a.name for a in arms)
        self.client = p.connect(p.DIRECT)
        try:
            self.bodies = [p.loadURDF(str(a.urdf), list(a.base.position), list(a.base.quaternion),
                                      useFixedBase=True, physicsClientId=self.client) for a in arms]
            self.joints = [[j for j in range(p.getNumJoints(b, physicsClientId=self.client))
                            if p.getJointInfo(b, j, physicsClientId=self.client)[2] == p.JOINT_REVOLUTE]
                           for b in self.bodies]
        except BaseException:
            p.disconnect(self.client)
            raise

    def close(self) -> None:
        if self.client is not None:
            self.p.disconnect(self.client)
            self.client = None

    def __enter__(self) -> Self:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def gap(self, q_first: Sequence[float], q_second: Sequence[float], margin: float = 0.5) -> float:
        """The least distance (m) between the two arms' links at these configurations; 0
        or less is a contact; ``margin`` when they are farther apart than that."""
        p, c = self.p, self.client
        for body, joints, q in zip(self.bodies, self.joints, (q_first, q_second)):
            for j, v in zip(joints, q):
                p.resetJointState(body, j, float(v), physicsClientId=c)
        points = p.getClosestPoints(self.bodies[0], self.bodies[1], margin, physicsClientId=c)
        return min((float(pt[8]) for pt in points), default=margin)

    def gaps(self, q_first: np.ndarray, q_second: np.ndarray, margin: float = 0.5) -> np.ndarray:
        """:meth:`gap` at each row of the two ``(n, 6)`` configuration arrays."""
        return np.array([self.gap(a, b, margin) for a, b in zip(q_first, q_second)])
