"""Timed joint trajectories: what the robot controller executes.

A `TimedTrajectory` is knots (times (m,) s from 0, strictly increasing; q (m, 6) rad);
between knots the controller interpolates linearly, so a builder puts knots densely
enough that the straight pieces follow the intended profile.  It is the one trajectory
type of the system, defined in `ita.path.trajectory` (so that planning imports no
simulator) and re-exported here: the path planner's `time_parameterize` makes them,
the controller runs them.

`from_waypoints` is a simple builder for tests and benchmarks (the path planner makes
the real ones): rest-to-rest segments through joint waypoints, every joint following
one trapezoidal speed profile scaled to its own distance (synchronised: all joints start
and stop together).  The profile's peak speed and acceleration are the largest that keep
every joint within its velocity and acceleration limits, so a segment takes at least as
long as `ita.kinematics.move_time` says (exactly as long when one joint limits both).
The TCP speed limit is not applied (`time_parameterize` applies it).
"""

from __future__ import annotations

from itertools import pairwise

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ita.kinematics import ArmModel, flange_poses
from ita.kinematics.settle import joint_translation
from ita.path.trajectory import TimedTrajectory

__all__ = ["KNOT_PERIOD", "TimedTrajectory", "from_waypoints", "profile_position", "profile_time"]

FloatArray = NDArray[np.float64]
KNOT_PERIOD = 0.02  # s between the knots the builder writes


def profile_time(distance: ArrayLike, velocity: ArrayLike, acceleration: ArrayLike) -> tuple[float, float, float]:
    """Synchronised rest-to-rest profile for joint distances (dof,): (T, V, A) where every
    joint moves s(t) * distance with s rising 0 -> 1 at peak rate V (1/s) and A (1/s^2)."""
    d = np.abs(np.asarray(distance, dtype=float))
    if not np.any(d > 0.0):
        return 0.0, 0.0, 0.0
    moving = d > 0.0
    vmax = float(np.min(np.asarray(velocity, float)[moving] / d[moving]))
    amax = float(np.min(np.asarray(acceleration, float)[moving] / d[moving]))
    if vmax * vmax / amax >= 1.0:  # triangle: never reaches the speed limit
        return 2.0 / np.sqrt(amax), float(np.sqrt(amax)), amax
    return 1.0 / vmax + vmax / amax, vmax, amax


def profile_position(t: ArrayLike, duration: float, peak: float, accel: float) -> FloatArray:
    """Normalised position s(t) in [0, 1] of a trapezoidal (or triangular) profile."""
    tc: FloatArray = np.clip(np.asarray(t, dtype=float), 0.0, duration)
    ta = peak / accel if accel > 0 else 0.0
    rise = 0.5 * accel * tc * tc
    cruise = 0.5 * accel * ta * ta + peak * (tc - ta)
    back = duration - tc
    fall = 1.0 - 0.5 * accel * back * back
    return np.where(tc < ta, rise, np.where(tc > duration - ta, fall, cruise))


def from_waypoints(model: ArmModel, waypoints: ArrayLike, knot_period: float = KNOT_PERIOD,
                   speed_scale: float = 1.0, accel_scale: float | None = None) -> TimedTrajectory:
    """A rest-to-rest trajectory through joint waypoints (k, 6), k >= 1 (see module doc).

    speed_scale in (0, 1] slows every segment (velocity x s, acceleration x s^2, as a
    time-scaled trajectory; accel_scale in (0, 1] instead: the acceleration x that, as a
    speed override that leaves the drives' acceleration alone).
    A single waypoint (or all equal) gives a one-knot trajectory of duration 0.
    """
    w = np.asarray(waypoints, dtype=float).reshape(-1, model.dof)
    if not 0.0 < speed_scale <= 1.0:
        raise ValueError(f"speed_scale must be in (0, 1], got {speed_scale}")
    a_scale = speed_scale ** 2 if accel_scale is None else accel_scale
    if not 0.0 < a_scale <= 1.0:
        raise ValueError(f"accel_scale must be in (0, 1], got {accel_scale}")
    times, qs = [0.0], [w[0]]
    for a, b in pairwise(w):
        total, peak, accel = profile_time(b - a, model.velocity * speed_scale,
                                          model.acceleration * a_scale)
        if total <= 0.0:
            continue
        n = max(2, int(np.ceil(total / knot_period)))
        local = np.linspace(0.0, total, n + 1)[1:]
        s = profile_position(local, total, peak, accel)
        qs.extend(a + s[:, None] * (b - a))
        times.extend(times[-1] + local)
    return TimedTrajectory(np.array(times), np.array(qs))


#: a retreat may first back the tool straight out along its axis by this much (m), clear
#: of a rack's cradle or the part's surface, then fold in joint space
RETREAT_BACK_M = 0.2


def retreat_paths(model: ArmModel, q: ArrayLike, fold: ArrayLike,
                  back_m: float = RETREAT_BACK_M) -> list[TimedTrajectory]:
    """The ways an arm may retreat from joints `q` to `fold` (rest-to-rest trajectories),
    the first preferred: the flange backed straight out along its axis `back_m` keeping
    its orientation, then straight
    in joint space to the fold (when the joints allow); and straight in joint space
    alone.  The controller flies the first its world finds clear, and the zone conductor
    claims them all (ita.robot.controller, ita.executive.conductor)."""
    q0 = np.asarray(q, dtype=float)
    goal = np.asarray(fold, dtype=float)
    frame = np.eye(4)
    axis = flange_poses(model, q0[None])[0][:3, 2]
    backed = q0 + joint_translation(model, q0, frame, -back_m * axis / np.linalg.norm(axis))
    inside = bool(np.all(backed >= np.asarray(model.lower) - 1e-9) and np.all(backed <= np.asarray(model.upper) + 1e-9))
    ways = []
    if inside and np.all(np.isfinite(backed)) and float(np.max(np.abs(backed - q0))) < 1.0:
        ways.append(from_waypoints(model, np.stack([q0, backed, goal])))
    ways.append(from_waypoints(model, np.stack([q0, goal])))
    return ways
