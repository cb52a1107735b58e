"""Point-to-point motion time in joint space, for the Sequence Planner's cost matrix.

Each joint moves its distance |dq| from rest to rest under its velocity limit v and
acceleration limit a: a triangular speed profile when the move is too short to reach v
(|dq| <= v^2 / a: t = 2 sqrt(|dq| / a)), else a trapezoid (t = |dq| / v + v / a).  The
joints are synchronised (the faster ones are slowed to finish together), so the move takes
the longest joint time.  Joints do not wrap: a joint with limits travels the plain
difference of its angles.

Optionally the controller's TCP speed limit bounds the time from below by the straight
distance between the two TCP positions over the speed limit.  A joint move's TCP path is
no shorter than that chord, so this is a lower bound on the effect of the cap, not an
exact model of it.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ita.kinematics.fk import ArmModel, tcp_poses

FloatArray = NDArray[np.float64]


def joint_times(delta: ArrayLike, velocity: ArrayLike, acceleration: ArrayLike) -> FloatArray:
    """Rest-to-rest times (..., j) s of joint moves delta (..., j) rad under limits (j,)."""
    d = np.abs(np.asarray(delta, dtype=float))
    v = np.asarray(velocity, dtype=float)
    a = np.asarray(acceleration, dtype=float)
    return np.where(d <= v * v / a, 2.0 * np.sqrt(d / a), d / v + v / a)


def move_time(model: ArmModel, q_from: ArrayLike, q_to: ArrayLike) -> FloatArray:
    """Synchronised joint-space move times (...) s between configs (..., 6) (broadcast)."""
    delta = np.asarray(q_to, dtype=float) - np.asarray(q_from, dtype=float)
    return joint_times(delta, model.velocity, model.acceleration).max(axis=-1)


def move_time_matrix(
    model: ArmModel,
    q: ArrayLike,
    q_to: ArrayLike | None = None,
    tcp: ArrayLike | None = None,
) -> FloatArray:
    """Move times (n, m) s from each config q (n, 6) to each config q_to (m, 6) (default q).

    With q_to None the matrix is square, symmetric with a zero diagonal.  tcp: the tool's
    TCP (4, 4) in the flange frame; when given, the TCP speed limit also applies (see the
    module docstring).  Memory is O(n m): one joint at a time.
    """
    a = np.asarray(q, dtype=float).reshape(-1, model.dof)
    b = a if q_to is None else np.asarray(q_to, dtype=float).reshape(-1, model.dof)
    times = np.zeros((len(a), len(b)))
    for j in range(model.dof):
        v, acc = model.velocity[j], model.acceleration[j]
        d = np.abs(a[:, j, None] - b[None, :, j])
        t = np.where(d <= v * v / acc, 2.0 * np.sqrt(d / acc), d / v + v / acc)
        np.maximum(times, t, out=times)
    if tcp is not None:
        pa = tcp_poses(model, a, tcp)[:, :3, 3]
        pb = pa if q_to is None else tcp_poses(model, b, tcp)[:, :3, 3]
        chord = np.sqrt(np.maximum(
            (pa * pa).sum(1)[:, None] + (pb * pb).sum(1)[None, :] - 2.0 * pa @ pb.T, 0.0))
        if q_to is None:
            np.fill_diagonal(chord, 0.0)
        np.maximum(times, chord / model.max_tool_speed, out=times)
    return times
