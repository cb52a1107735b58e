"""Hole positions decided by a network adjustment of the run's SLRA frames (the Top Level's side).

A fastener hole's position frame shows the hole and its neighbours (Vision's
``sightings``).  With the network on, the Top Level does not record such a result when
the frame is measured: it keeps it PENDING (the frame's sightings go to the archive at
once, as a ``network_frame`` event) and decides the positions of a whole network at
once when the last of its members has been measured or given up, by
:func:`ita.vision.network.solve_network`.  A network is the position specs of the
fastener holes on one face (one height above datum A).  A run killed before a network is
solved loses nothing: `ita continue` reads the pending frames back from the events, skips
their specs, and solves the network when it ends.  Nothing is decided twice: a spec's
result is recorded once, when its network is solved.

    key = network_key(spec, features)             # None: not decided by a network
    pending = Pending.from_value(spec_id, value, tool, t0, t1)   # None: the value has no sightings
    results = decide(pendings, specs, features, pose_sigma)       # Result per pending spec
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from ita.archive import Event, Outcome, Result
from ita.devices.data import MeasuredValue
from ita.part.model import Hole, HoleRole
from ita.specs.model import MeasurementKind as K
from ita.vision.network import NetworkSolution, Sighting, solve_network

if TYPE_CHECKING:
    from ita.part.model import Feature
    from ita.specs.model import MeasurementSpec

__all__ = ["EVENT_KIND", "Pending", "decide", "network_key"]

#: the archive event that keeps a pending frame's sightings
EVENT_KIND = "network_frame"


def network_key(spec: MeasurementSpec, features: Mapping[str, Feature]) -> str | None:
    """The network a spec's result is decided in: the fastener holes' positions on one face
    ("holes at z=45"); None for everything else."""
    hole = features.get(spec.feature)
    if spec.kind is not K.HOLE_POSITION or not isinstance(hole, Hole) or hole.role is not HoleRole.FASTENER:
        return None
    return f"holes at z={hole.center[2]:g}"


@dataclass(frozen=True)
class Pending:
    """A measured position waiting for its network: the frame's sightings, when and with
    what it was measured, and the frame's own value (the provisional one, kept for the
    record)."""

    spec_id: str
    tool: str | None
    t0: float | None
    t1: float | None
    sightings: tuple[Sighting, ...]
    frame_value: float
    frame_u: float

    @classmethod
    def from_value(cls, spec_id: str, value: MeasuredValue, tool: str | None, t0: float | None, t1: float | None
                   ) -> Pending | None:
        """From a measured value whose source is Vision's result with sightings; else None."""
        diag = getattr(getattr(value, "source", None), "diagnostics", None) or {}
        raw = diag.get("sightings")
        if not raw or value.value is None or value.u is None:
            return None
        sightings = tuple(Sighting(_frame_id(spec_id, s.get("frame")), str(s["hole"]),
                                   (float(s["xy"][0]), float(s["xy"][1])), float(s["sigma"]),
                                   float(s.get("systematic", 0.0)), str(s.get("group", "")))
                          for s in raw)
        return cls(spec_id, tool, t0, t1, sightings, float(value.value), float(value.u))

    def to_event(self) -> Event:
        return Event(EVENT_KIND, "top", self.t1, {
            "spec": self.spec_id, "tool": self.tool, "t0": self.t0, "t1": self.t1,
            "frame_value": self.frame_value, "frame_u": self.frame_u,
            "sightings": [{"hole": s.hole, "xy": list(s.xy), "sigma": s.sigma, "systematic": s.systematic,
                           "group": s.group, "frame": s.frame} for s in self.sightings]}, spec_id=self.spec_id)

    @classmethod
    def from_event(cls, event: Event) -> Pending:
        p = event.payload
        sightings = tuple(Sighting(str(s.get("frame", p["spec"])), str(s["hole"]), (float(s["xy"][0]), float(s["xy"][1])),
                                   float(s["sigma"]), float(s["systematic"]), str(s.get("group", "")))
                          for s in p["sightings"])
        return cls(str(p["spec"]), p.get("tool"), p.get("t0"), p.get("t1"), sightings, float(p["frame_value"]),
                   float(p["frame_u"]))


def _frame_id(spec_id: str, k: object) -> str:
    """The network's name of frame `k` of a measurement of `spec_id` (its first: the spec's id)."""
    return spec_id if not k else f"{spec_id}#{k}"


def decide(pendings: Sequence[Pending], specs: Mapping[str, MeasurementSpec], features: Mapping[str, Feature],
           pose_sigma: float, registration: Callable[[Sequence[float]], float] | None = None
           ) -> tuple[list[Result], NetworkSolution]:
    """Solve the network of `pendings` and decide each: a measured result (value 2 |d|, its
    standard uncertainty 2 sigma along the worst axis, the reason saying how the network
    decided it), or not done when its hole is in no frame the network kept.  pose_sigma:
    a frame's shift in the part's plane (mm, 1 sigma per axis); registration: the part's
    registration on its datums, the standard uncertainty (mm, per axis) of where it puts a
    part point (x, y): a network without a datum hole of its own rests on the frames'
    poses, which the registration placed, and its holes carry that term too."""
    holes = {f.id: f for f in features.values() if isinstance(f, Hole)}
    sightings = [s for p in pendings for s in p.sightings]
    nominal = {h: holes[h].center[:2] for h in {s.hole for s in sightings} if h in holes}
    fixed = {h for h in nominal if holes[h].datum}
    sol = solve_network(sightings, nominal, pose_sigma=pose_sigma, fixed=fixed)
    n_frames = len({s.frame for s in sightings})
    out: list[Result] = []
    for p in pendings:
        spec = specs[p.spec_id]
        est = sol.holes.get(spec.feature)
        why_out = sol.left_out.get(p.spec_id)
        if est is None:
            reason = f"not decided by the network of {n_frames} frames: its hole is in no frame kept"
            if why_out:
                reason += f" (its own frame left out: {why_out})"
            out.append(Result.unmeasured(spec, Outcome.NOT_DONE, reason, tool=p.tool, sim_time_start=p.t0,
                                         sim_time_end=p.t1))
            continue
        d = np.asarray(est.deviation)
        cov = np.asarray(est.cov)
        budget = dict(est.budget)
        if registration is not None and not fixed:
            u_reg = registration(holes[spec.feature].center[:2]) if spec.feature in holes else 0.0
            cov = cov + np.eye(2) * u_reg ** 2
            budget["registration on the datums"] = u_reg
        u = 2 * _radial_sigma(d, cov)  # the value is 2 |d|
        term, size = max(budget.items(), key=lambda kv: kv[1])
        zone = spec.upper - spec.lower
        note = (f"network of {n_frames} frames (seen in {len(est.frames)}); U/tolerance {2 * u / zone:.2f}; "
                f"largest term: {term} (u {2 * size:.4f} mm)")
        if why_out:
            note += "; its own frame left out (did not fit the network)"
        out.append(Result.measured(spec, 2 * float(math.hypot(*d)), u, tool=p.tool, sim_time_start=p.t0,
                                   sim_time_end=p.t1, reason=note))
    return out, sol


def _radial_sigma(d: np.ndarray, cov: np.ndarray) -> float:
    """Standard uncertainty of |d| for a deviation d (2,) with covariance cov (2, 2): along
    d where |d| is well beyond its scatter (at least twice the worst axis's sigma), else
    the worst axis's (near the centre the direction of d is not known)."""
    worst = math.sqrt(max(float(np.linalg.eigvalsh(cov).max()), 0.0))
    r = float(np.hypot(*d))
    if r < 2 * worst:
        return worst
    u = d / r
    return math.sqrt(max(float(u @ cov @ u), 0.0))
