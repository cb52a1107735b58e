"""The timed joint trajectory: what the path planner makes and the robot controller runs.

A `TimedTrajectory` is knots (times (m,) s from 0, strictly increasing; q (m, dof) rad);
between knots the controller interpolates linearly, so a builder puts knots densely
enough that the straight pieces follow the intended profile.  A builder may also say
when the path's waypoints are passed (`vias`, s) and at which of them the arm is at rest
(`stops`); the controller ignores both.  `ita.robot.waypoints` re-exports it beside its
simple rest-to-rest builder.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ita.kinematics import ArmModel, tcp_poses

FloatArray = NDArray[np.float64]


@dataclass(frozen=True, eq=False)
class TimedTrajectory:
    """Joint configurations q (m, 6) rad to pass at times (m,) s (times[0] = 0); optionally
    vias (k,) s, the times the path's waypoints (or their blends' middles) are passed, and
    stops (k,) bool, whether the arm rests there (both empty when not given)."""

    times: FloatArray
    q: FloatArray
    vias: FloatArray | None = None
    stops: NDArray[np.bool_] | None = None

    def __post_init__(self) -> None:
        t = np.array(self.times, dtype=float).reshape(-1)
        q = np.array(self.q, dtype=float)
        if q.ndim != 2 or q.shape[0] != t.size or t.size < 1:
            raise ValueError(f"times (m,) and q (m, dof) must agree, got {t.shape} and {q.shape}")
        if not np.all(np.isfinite(t)) or not np.all(np.isfinite(q)):
            raise ValueError("times and q must be finite")
        if t[0] != 0.0 or np.any(np.diff(t) <= 0.0):
            raise ValueError("times must start at 0 and increase strictly")
        vias = np.zeros(0) if self.vias is None else np.array(self.vias, dtype=float).reshape(-1)
        stops = np.zeros(len(vias), dtype=bool) if self.stops is None else np.array(self.stops, dtype=bool).reshape(-1)
        if len(stops) != len(vias):
            raise ValueError(f"vias and stops must agree, got {vias.shape} and {stops.shape}")
        if len(vias) and (vias.min() < 0.0 or vias.max() > t[-1] * (1.0 + 1e-12) + 1e-12):
            raise ValueError("vias must lie within the trajectory's duration")
        for name, value in (("times", t), ("q", q), ("vias", vias), ("stops", stops)):
            value.setflags(write=False)
            object.__setattr__(self, name, value)

    @property
    def duration(self) -> float:
        """Total time (s)."""
        return float(self.times[-1])

    @property
    def start(self) -> FloatArray:
        """First configuration (dof,)."""
        return self.q[0].copy()

    @property
    def end(self) -> FloatArray:
        """Last configuration (dof,)."""
        return self.q[-1].copy()

    def sample(self, t: ArrayLike) -> FloatArray:
        """Configurations (k, dof) at times t (k,) (clamped to [0, duration]), linearly
        interpolated between knots."""
        tt = np.clip(np.atleast_1d(np.asarray(t, dtype=float)), 0.0, self.duration)
        return np.stack([np.interp(tt, self.times, self.q[:, j]) for j in range(self.q.shape[1])], axis=-1)

    def velocities(self) -> FloatArray:
        """Joint speeds (m - 1, dof) rad/s of the straight pieces between knots."""
        return np.diff(self.q, axis=0) / np.diff(self.times)[:, None]

    def tool_speeds(self, model: ArmModel, tcp: ArrayLike | None = None) -> FloatArray:
        """Speeds (m - 1,) m/s of the tool point (tcp (4, 4) in the flange frame; default
        the flange) between knots: chord over time."""
        if len(self.times) < 2:
            return np.zeros(0)
        p = tcp_poses(model, self.q, np.eye(4) if tcp is None else tcp)[:, :3, 3]
        return np.linalg.norm(np.diff(p, axis=0), axis=1) / np.diff(self.times)
