"""Heights decided with the measured thickness of the web they are referenced to.

Vision measures a flange's or a rib's height above datum A (the web's back face, z = 0)
as the gap from its top face to the web face beside it, plus that web face's NOMINAL
height (ita.vision.kinds._height): the back is out of its sight.  The web's own
deviation then enters the height whole, and its uncertainty is the web's tolerance taken
as a rectangle (t / sqrt 3): U is about 0.3 of a flange height's tolerance zone on the
built-in bulkhead, and a pocket floor machined out of its tolerance makes every height
beside it read off by that much, beyond its U.

The ultrasonic gauge measures that web's thickness, which IS the web face's height above
datum A where the web's back lies on it.  This module puts the measured thickness in
place of the nominal (the seed's deductive operators: a fact derived from two
measurements):

- the floor a height's web was seen on is the floor region there
  (`VisionContext.web_region`: the pocket on a generated part, the mesh's flat facet on a
  user's own);
- the web thickness specs on that floor whose nominal is the floor's height (its back on
  datum A) stand for it; the one nearest to where the web was seen gives the thickness;
  the scatter of all of them measured on that floor (their sample standard deviation) is
  added to its uncertainty as the floor's own variation;
- height = the gap + that thickness, u = the plane fits' and the thickness's (in place of
  the tolerance term); a web whose floor has no measured thickness keeps its nominal and
  its tolerance term.

The Top Level holds a height PENDING (an archive event, like a hole position waiting for
its network) while a web thickness spec of its floor is still to be measured in the run,
and decides it when the last of them is done, or at the run's end: each result is
recorded once.  A run killed meanwhile loses nothing: `ita continue` reads the pending
heights back from their events.

    refs = web_specs(specs, ctx)                     # floor region -> web thickness spec ids
    p = HeightPending.from_value(spec_id, value, tool, t0, t1, refs, ctx)  # None: not such a height
    result = decide_height(p, spec, measured)        # measured: spec id -> (value, u) of the run
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from ita.archive import Event, Result
from ita.devices.data import MeasuredValue
from ita.specs.model import MeasurementKind as K

if TYPE_CHECKING:
    from ita.specs.model import MeasurementSpec
    from ita.vision.context import VisionContext

__all__ = ["EVENT_KIND", "HEIGHT_KINDS", "HeightPending", "WebRef", "decide_height", "web_specs"]

#: the archive event that keeps a pending height
EVENT_KIND = "height_web"

#: the kinds measured from a web face beside them
HEIGHT_KINDS = (K.FLANGE_HEIGHT, K.STIFFENER_HEIGHT)

#: a web thickness spec stands for a floor when its nominal is the floor's height within this (mm)
SAME_HEIGHT_MM = 0.01


def web_specs(specs: Sequence[MeasurementSpec], ctx: VisionContext) -> dict[str, tuple[str, ...]]:
    """Floor region -> the web thickness specs that measure it: those on the floor
    (`ctx.web_region` of their point) whose nominal is the floor's nominal height (the
    web's back on datum A)."""
    out: dict[str, list[str]] = {}
    for s in specs:
        if s.kind is not K.WEB_THICKNESS:
            continue
        xy = np.asarray(s.point[:2], dtype=float)
        region, z = ctx.web_region(xy), ctx.web_at(xy)
        if region is not None and z is not None and abs(float(z) - s.nominal) <= SAME_HEIGHT_MM:
            out.setdefault(region, []).append(s.id)
    return {k: tuple(v) for k, v in out.items()}


@dataclass(frozen=True)
class WebRef:
    """One web a height was referenced to: where it was seen (part xy, mm), its nominal
    height z, the height through it alone, and the web thickness specs of its floor."""

    xy: tuple[float, float]
    z: float
    height: float
    specs: tuple[str, ...]


@dataclass(frozen=True)
class HeightPending:
    """A measured height waiting for its webs' thicknesses (see the module doc)."""

    spec_id: str
    tool: str | None
    t0: float | None
    t1: float | None
    u_fit: float
    webs: tuple[WebRef, ...]
    frame_value: float
    frame_u: float
    why: str = ""        # how it was measured, when not in its own frame ("from the frame of ...")

    @property
    def waits_for(self) -> set[str]:
        return {s for w in self.webs for s in w.specs}

    @classmethod
    def from_value(cls, spec_id: str, value: MeasuredValue, tool: str | None, t0: float | None, t1: float | None,
                   floors: Mapping[str, tuple[str, ...]], ctx: VisionContext) -> HeightPending | None:
        """From Vision's height result with its webs' references (``webs``) when a web
        thickness spec stands for at least one of their floors; else None."""
        diag = getattr(getattr(value, "source", None), "diagnostics", None) or {}
        raw = diag.get("webs")
        if not raw or value.value is None or value.u is None or "u_fit" not in diag:
            return None
        webs = []
        for w in raw:
            xy = (float(w["xy"][0]), float(w["xy"][1]))
            region = ctx.web_region(np.asarray(xy))
            webs.append(WebRef(xy, float(w["z"]), float(w["height"]), floors.get(region, ()) if region else ()))
        if not any(w.specs for w in webs):
            return None
        return cls(spec_id, tool, t0, t1, float(diag["u_fit"]), tuple(webs), float(value.value), float(value.u))

    def to_event(self) -> Event:
        return Event(EVENT_KIND, "top", self.t1, {
            "spec": self.spec_id, "tool": self.tool, "t0": self.t0, "t1": self.t1, "u_fit": self.u_fit,
            "frame_value": self.frame_value, "frame_u": self.frame_u, "why": self.why,
            "webs": [{"xy": list(w.xy), "z": w.z, "height": w.height, "specs": list(w.specs)} for w in self.webs]},
            spec_id=self.spec_id)

    @classmethod
    def from_event(cls, event: Event) -> HeightPending:
        p = event.payload
        webs = tuple(WebRef((float(w["xy"][0]), float(w["xy"][1])), float(w["z"]), float(w["height"]),
                            tuple(map(str, w["specs"]))) for w in p["webs"])
        return cls(str(p["spec"]), p.get("tool"), p.get("t0"), p.get("t1"), float(p["u_fit"]), webs,
                   float(p["frame_value"]), float(p["frame_u"]), str(p.get("why") or ""))


def decide_height(p: HeightPending, spec: MeasurementSpec, measured: Mapping[str, tuple[float, float]],
                  points: Mapping[str, Sequence[float]], web_tolerance: float) -> Result:
    """The height's result with each web's measured thickness where its floor has one.
    measured: web thickness spec id -> (value, u) of those measured in the run; points:
    spec id -> its point (mm); web_tolerance: the +/- of a web whose floor has none."""
    heights, notes = [], []
    terms: dict[str, float] = {}    # one term per source: two webs read through one gauge point share its error
    for i, w in enumerate(p.webs):
        got = [(s, *measured[s]) for s in w.specs if s in measured]
        if not got:
            heights.append(w.height)
            terms[f"tolerance {i}"] = web_tolerance / math.sqrt(3)
            continue
        near = min(got, key=lambda g: math.dist(points[g[0]][:2], w.xy))
        spread = float(np.std([g[1] for g in got], ddof=1)) if len(got) > 1 else 0.0
        heights.append(w.height - w.z + near[1])
        terms[near[0]] = terms.get(near[0], 0.0) + math.hypot(near[2], spread)
        notes.append(f"{near[0]} {near[1]:.4f} mm" + (f" (floor's spread {spread * 1000:.1f} um over {len(got)})"
                                                     if len(got) > 1 else ""))
    u_web = math.sqrt(sum(t * t for t in terms.values())) / len(heights)
    u = math.hypot(p.u_fit, u_web)
    reason = ("web measured: " + "; ".join(notes)) if notes else \
        "its web's thickness was not measured: the nominal, with its tolerance in U"
    if p.why:
        reason = f"{p.why}; {reason}"
    return Result.measured(spec, float(np.mean(heights)), u, tool=p.tool, sim_time_start=p.t0, sim_time_end=p.t1,
                           reason=reason)
