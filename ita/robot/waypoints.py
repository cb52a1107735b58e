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

from ita.kinematics import ArmModel
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
