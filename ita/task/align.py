"""The part registered on its datums before it is measured (and again after a knock).

No fixture puts a part where its model says: a run begins by locating it.  The part rests
on its datum face A on the fixture's pads, which set its height and tilt; its place in
the plane of A and its turn about A's normal are found from the tooling holes, datums B
and C, by the SLRA (a 3-2-1 alignment whose face-A part the fixture makes):

1. a first look: each tooling hole in one frame where the current placement puts it, its
   centre from the rim fit (which re-centres its band where the frame shows the hole when
   it is a little off) or, a hole the band misses altogether (millimetres off), from where
   the frame shows a region of its size (:func:`ita.vision.locate.find_hole`); the part's
   motion in its plane from those centres (a least-squares rigid fit, :func:`fit_motion`)
   moves every pose on the part;
2. a measurement: each tooling hole from FRAMES frames, each after its own approach (the
   arm's repeatability averages; a hole still missed is found in its frame, the part moved
   there and the hole measured again), the motion fitted again and composed;
3. again while the last fit moved a datum by more than SETTLED_MM (at most ROUNDS).
   Face A's height round each hole comes from the same frames: further than FACE_OFF_MM
   from nominal, the part does not sit on the fixture's pads and is not registered.

The result, an :class:`Alignment`, is the registered placement (what the Geometric
Reasoner puts every pose on the part by, and Vision turns frames into part points by),
the shift and turn from the nominal placement with their uncertainties (from the
centres' own scatter over the frames, or the arm's repeatability when larger), each
datum's residual (two holes for three unknowns leave one: the distance B-C as measured
against its nominal), and the features used.  With fewer than two tooling holes that
have a diameter spec to view them by, a part is measured at its nominal placement, and
the run says so.

    done = register_part(session, state, "slra_1")
    done.alignment.shift_mm, done.alignment.turn_deg, done.alignment.residuals_mm
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from ita.collision import Regions
from ita.logic.json_value import JsonObject
from ita.part.model import Feature, Hole, HoleRole
from ita.path import planners_for
from ita.specs.model import MeasurementKind, MeasurementSpec
from ita.task.measure import MeasureOutcome, MeasureStatus, measure_one
from ita.vision.context import VisionResult
from ita.vision.locate import find_hole
from ita.workcell.model import PartPlacement

if TYPE_CHECKING:
    from ita.planning.state import WorldState
    from ita.task.session import Session

FloatArray = NDArray[np.float64]

__all__ = ["FRAMES", "ROUNDS", "Alignment", "AlignDone", "DatumReading", "FACE_OFF_MM", "adopt_alignment", "apply_alignment", "datum_specs", "datums_of", "plan_around", "registered_by_peer",
           "fit_motion", "register_part"]

#: frames of each tooling hole in the measuring step (the arm's repeatability averages)
FRAMES = 10
#: at most this many measuring steps
ROUNDS = 3
#: datum face A further than this (mm) from its nominal height round a tooling hole: the
#: part does not sit on the fixture's pads (the registration in the plane of A does not hold)
FACE_OFF_MM = 0.5
#: a step whose fit moved no datum further than this (mm) ends the registration: the rim
#: fit found each hole within its band (relocated there when off), as well as the frames can
SETTLED_MM = 1.0


@dataclass(frozen=True)
class DatumReading:
    """A tooling hole as the registration's last step saw it: its centre (part x, y mm)
    where the placement of that step put it, from `frames` frames, with its standard
    uncertainty per axis."""

    feature: str
    datum: str
    spec_id: str
    nominal: tuple[float, float]
    seen: tuple[float, float]
    u_mm: float
    frames: int
    #: where it is in the registered part frame (its nominal place plus its residual)
    registered: tuple[float, float] = (math.nan, math.nan)
    #: the face round it (datum face A) as measured, less its nominal height (mm; nan: none)
    face_mm: float = math.nan


@dataclass(frozen=True)
class Alignment:
    """The part registered (module docstring): the placement; its shift (part frame mm,
    at the part's origin) and turn (degrees about face A's normal) from the nominal
    placement, their standard uncertainties (the shift's at the datums' middle);
    residuals: each datum's distance (mm) from where the fitted motion puts it; the
    datum features used; the steps taken."""

    placement: PartPlacement
    shift_mm: tuple[float, float, float]
    turn_deg: float
    u_shift_mm: float
    u_turn_deg: float
    residuals_mm: dict[str, float]
    datums: tuple[str, ...]
    readings: tuple[DatumReading, ...]
    steps: int
    seconds: float
    #: the datums' middle (part x, y mm), where the shift's uncertainty is u_shift_mm
    middle_mm: tuple[float, float] = (0.0, 0.0)

    def u_at(self, xy: Sequence[float]) -> float:
        """Standard uncertainty (mm, per axis) of where the registration puts the part
        point `xy`: the shift's and the turn's over the point's distance from the datums'
        middle."""
        r = math.dist((float(xy[0]), float(xy[1])), self.middle_mm)
        return math.hypot(self.u_shift_mm, math.radians(self.u_turn_deg) * r)

    def u_max(self, envelope_min: Sequence[float], envelope_max: Sequence[float]) -> float:
        """:meth:`u_at` of the part's farthest corner (mm)."""
        return max(self.u_at((x, y)) for x in (envelope_min[0], envelope_max[0])
                   for y in (envelope_min[1], envelope_max[1]))

    def registered(self, spec_id: str) -> tuple[float, float] | None:
        """Where the datum viewed by `spec_id` is in the registered part frame (None: no
        datum of the registration)."""
        return next((r.registered for r in self.readings if r.spec_id == spec_id), None)

    def line(self) -> str:
        """One line for people: the shift, the turn, the residuals."""
        res = ", ".join(f"{k} {v:.3f}" for k, v in self.residuals_mm.items())
        faces = ", ".join(f"{r.feature} {r.face_mm:+.3f}" for r in self.readings if math.isfinite(r.face_mm))
        return (f"part registered on {', '.join(self.datums)}: shift ({self.shift_mm[0]:+.3f}, "
                f"{self.shift_mm[1]:+.3f}) mm +/- {self.u_shift_mm:.3f}, turn {self.turn_deg:+.4f} deg "
                f"+/- {self.u_turn_deg:.4f}; residuals {res} mm" + (f"; face A round {faces} mm" if faces else ""))

    def to_dict(self) -> JsonObject:
        rot = self.placement.rotation_matrix()
        return {"registered": True, "line": self.line(),
                "shift_mm": [round(x, 4) for x in self.shift_mm], "turn_deg": round(self.turn_deg, 5),
                "u_shift_mm": round(self.u_shift_mm, 4), "u_turn_deg": round(self.u_turn_deg, 5),
                "residuals_mm": {k: round(v, 4) for k, v in self.residuals_mm.items()},
                "datums": list(self.datums), "steps": self.steps, "seconds": round(self.seconds, 1),
                "middle_mm": [round(x, 3) for x in self.middle_mm],
                "readings": [{"feature": r.feature, "datum": r.datum, "spec": r.spec_id,
                              "nominal": list(r.nominal), "seen": [round(x, 4) for x in r.seen],
                              "registered": [round(x, 4) for x in r.registered],
                              "u_mm": round(r.u_mm, 4), "frames": r.frames,
                              "face_a_mm": None if not math.isfinite(r.face_mm) else round(r.face_mm, 4)}
                             for r in self.readings],
                "placement": {"rotation": [[round(float(x), 9) for x in row] for row in rot],
                              "translation_m": [round(float(x), 9) for x in self.placement.translation]}}


@dataclass(frozen=True)
class AlignDone:
    """What a registration did: the alignment (None: the part could not be registered,
    `reason` says why), the measurements it made (for the run's record), the arm's state
    after."""

    alignment: Alignment | None
    reason: str
    outcomes: tuple[MeasureOutcome, ...]
    state: WorldState
    moved_mm: float = field(default=0.0)


def datum_specs(session: Session) -> list[tuple[Hole, str]]:
    """The tooling holes (datums B, C, ...) with a hole-diameter spec to view each by, in
    datum order."""
    return datums_of(session.part.features, session.ctx.specs)


def datums_of(features: Sequence[Feature], specs: Sequence[MeasurementSpec]) -> list[tuple[Hole, str]]:
    """:func:`datum_specs` of a part's features and specs."""
    holes = {f.id: f for f in features if isinstance(f, Hole) and f.role is HoleRole.TOOLING}
    out: dict[str, tuple[Hole, str]] = {}
    for spec in specs:
        hole = holes.get(spec.feature)
        if hole is not None and spec.kind is MeasurementKind.HOLE_DIAMETER and hole.id not in out:
            out[hole.id] = (hole, spec.id)
    return sorted(out.values(), key=lambda hs: (hs[0].datum or "~", hs[0].id))


def fit_motion(nominal: FloatArray, seen: FloatArray) -> tuple[float, FloatArray, FloatArray]:
    """The rigid motion in the plane (turn `theta` rad, shift (2,)) that best puts the
    `nominal` points (n, 2) on the `seen` ones (least squares; n >= 2), and each point's
    residual (n,) mm."""
    a, b = np.asarray(nominal, dtype=float), np.asarray(seen, dtype=float)
    ca, cb = a.mean(axis=0), b.mean(axis=0)
    p, q = a - ca, b - cb
    theta = math.atan2(float(np.sum(p[:, 0] * q[:, 1] - p[:, 1] * q[:, 0])), float(np.sum(p * q)))
    rot = _rot2(theta)
    shift = cb - rot @ ca
    residuals = np.linalg.norm(a @ rot.T + shift - b, axis=1)
    return theta, shift, residuals


def _rot2(theta: float) -> FloatArray:
    c, s = math.cos(theta), math.sin(theta)
    return np.array([[c, -s], [s, c]])


def _xy(v: FloatArray) -> tuple[float, float]:
    return float(v[0]), float(v[1])


def _motion3(theta: float, shift: FloatArray) -> tuple[FloatArray, FloatArray]:
    rot = np.eye(3)
    rot[:2, :2] = _rot2(theta)
    return rot, np.array([shift[0], shift[1], 0.0])


def apply_alignment(session: Session, placement: PartPlacement | None, u_mm: float = 0.0) -> None:
    """Measure in `placement` from now on: the Geometric Reasoner's poses on the part,
    Vision's part frame (with `u_mm`, the registration's standard uncertainty per axis at
    the part's farthest corner) and the Path Planner's collision model of the part (None:
    the nominal placement)."""
    cell = session.ctx.workcell
    session.reasoner.register(placement)
    session.slra.register(placement if placement is not None else cell.part, u_mm)
    plan_around(session, session.keep_clear)


def plan_around(session: Session, keep_clear: Regions | None) -> None:
    """The Path Planner keeps the arm out of `keep_clear` from now on, instead of what it
    kept out of before (ita.task.session.open_session's others_folded), on the part where
    it was registered."""
    cell = session.ctx.workcell
    placement = session.reasoner.placement
    session.keep_clear = keep_clear
    session.arm.planner_for = planners_for(cell if placement is None else replace(cell, part=placement),
                                           session.part, keep_clear=keep_clear)


def _centre(out: MeasureOutcome, hole: Hole, placement: PartPlacement
            ) -> tuple[FloatArray | None, float, int, bool, float]:
    """(centre (2,) or None, the scatter per axis of one frame's centre (nan: unknown),
    frames, whether its rim was measured (else only found in a frame, roughly), the
    height of the face round it less its nominal (mm; nan: not measured)) of a tooling
    hole's measurement."""
    source = out.value.source if out.value is not None else None
    if out.status is MeasureStatus.MEASURED and isinstance(source, VisionResult) \
            and source.diagnostics.get("center") is not None:
        d = source.diagnostics
        n = int(d.get("frames", 1))
        face = float(d["face_z"]) - float(hole.center[2]) if d.get("face_z") is not None else math.nan
        return np.asarray(d["center"], dtype=float)[:2], float(d.get("center_scatter", math.nan)), n, True, face
    for frame in reversed(out.frames):
        found = find_hole(frame, placement, hole)
        if found is not None:
            return np.asarray(found, dtype=float), math.nan, 1, False, math.nan
    return None, math.nan, 0, False, math.nan


def _coarse(nominal: FloatArray, seen: Sequence[FloatArray]) -> tuple[FloatArray, FloatArray]:
    """The part's motion (rotation (3, 3), shift (3,)) that puts the first holes of
    `nominal` where they were `seen`: a shift alone for one hole."""
    if len(seen) == 1:
        return np.eye(3), np.array([*(np.asarray(seen[0]) - nominal[0]), 0.0])
    theta, shift, _ = fit_motion(nominal, np.asarray(seen))
    return _motion3(theta, shift)


def _into(rot: FloatArray, shift3: FloatArray, p: FloatArray) -> FloatArray:
    """A point (2,) seen in a placement, in that placement moved by (rot, shift3)."""
    return np.asarray(rot[:2, :2].T @ (np.asarray(p) - shift3[:2]), dtype=float)


def _look(session: Session, spec_id: str, state: WorldState, tool: str, frames: int) -> MeasureOutcome:
    """Measure `spec_id` from `frames` frames, each after its own approach."""
    with session.slra.frames_for_reading(spec_id, frames):
        return measure_one(session, spec_id, state, tool)


def adopt_alignment(session: Session, found: Alignment) -> None:
    """Measure in a registration the other arm of a two-arm run made (both arms see one
    part): the session's registration from now on."""
    session.alignment = found
    nominal = session.ctx.workcell.part
    apply_alignment(session, found.placement, found.u_max(nominal.envelope_min_mm, nominal.envelope_max_mm))


def registered_by_peer(session: Session, why: str, found_s: float) -> tuple[Alignment | None, float]:
    """One arm of a two-arm run that does not register the part (its datums out of its
    view) found it displaced: it folds out of the way, asks the other arm to register it
    again (news the other hears with its next claim; ita.toplevel.shared answers it), and
    waits in simulated time for that registration, then measures in it (`found_s`: when
    the failure that showed the part displaced was seen: a registration the other arm
    began measuring after then will do).  When the other arm's news of a registration
    newer than this arm's has come in meanwhile, that one is taken and nothing asked.
    The registration
    (None: the other arm is done, or waits itself, or could not register it) and the
    seconds waited."""
    peer = session.peer
    assert peer is not None and not session.registers
    newer = [v["alignment"] for _t, v in peer.unread() if isinstance(v, dict) and v.get("kind") == "registered"
             and isinstance(v.get("alignment"), Alignment)]
    if newer and (session.alignment is None or newer[-1].to_dict() != session.alignment.to_dict()):
        # the other arm registered the part again since this arm measured in the one it has
        # (heard, not yet acted on): the failure is explained; measure in that one
        adopt_alignment(session, newer[-1])
        return newer[-1], 0.0
    session.arm.controller.give_way()
    t = session.clock.now
    key = f"registration@{t:.6f}"
    peer.tell(t, {"kind": "register", "key": key, "why": why, "found_s": float(found_s)})
    wait, found = peer.take(t, key, of_work=True)
    session.clock.advance(wait)
    if not isinstance(found, Alignment):
        return None, wait
    adopt_alignment(session, found)
    return found, wait


def register_part(session: Session, state: WorldState, tool: str, *, frames: int = FRAMES) -> AlignDone:
    """Register the part on its tooling holes with the SLRA `tool` (module docstring); the
    registered placement is applied (:func:`apply_alignment`) when it succeeds, and the
    one before stays when it does not."""
    t0 = session.clock.now
    datums = datum_specs(session)
    if len(datums) < 2:
        return AlignDone(None, "the part has no two tooling holes with a diameter spec to register on "
                               "(datums B and C): measured at its nominal placement", (), state)
    nominal_place = session.ctx.workcell.part
    start = session.reasoner.placement or nominal_place
    placement = start
    outcomes: list[MeasureOutcome] = []
    pose_u = session.slra.vctx.pose_sigma_m / nominal_place.scale
    u_before = session.slra.vctx.registration_u_mm
    readings: tuple[DatumReading, ...] = ()
    residuals = np.zeros(len(datums))
    nominal = np.array([h.center[:2] for h, _ in datums], dtype=float)
    steps = 0
    for step in range(ROUNDS + 1):          # a first look (one frame each), then the measuring steps
        n = 1 if step == 0 else frames
        seen: list[FloatArray] = []
        us: list[float] = []
        counts: list[int] = []
        faces: list[float] = []
        for i, (hole, spec_id) in enumerate(datums):
            out = _look(session, spec_id, state, tool, n)
            outcomes.append(out)
            state = out.state
            c, u, k, measured, face = _centre(out, hole, placement)
            if step == 0 and c is not None:     # a first look: where it is, roughly, is enough
                measured = True
            elif c is not None and not measured:
                # found in a frame, not where its rim was looked for: the part moved there
                # (by this hole alone, or fitted on the holes before it), and measured again
                rot, shift3 = _coarse(nominal[:i + 1], [*seen, c])
                placement = placement.moved(rot, shift3)
                apply_alignment(session, placement)
                seen = [_into(rot, shift3, p) for p in seen]
                out = _look(session, spec_id, state, tool, n)
                outcomes.append(out)
                state = out.state
                c, u, k, measured, face = _centre(out, hole, placement)
            if c is None or not measured:
                apply_alignment(session, None if start == nominal_place else start, u_before)
                return AlignDone(None, f"{hole.id} (datum {hole.datum or '?'}) not found in its view"
                                       f"{': ' + out.reason if out.reason else ''}: the part is further off its "
                                       "place than the cell can see", tuple(outcomes), state)
            if math.isfinite(face) and abs(face) > FACE_OFF_MM:
                apply_alignment(session, None if start == nominal_place else start, u_before)
                return AlignDone(None, f"datum face A is {face:+.2f} mm off its nominal height round {hole.id}: "
                                       "the part does not sit on the fixture's pads", tuple(outcomes), state)
            faces.append(face)
            seen.append(c)
            us.append(max(u if math.isfinite(u) else 0.0, pose_u) / math.sqrt(max(k, 1)))
            counts.append(k)
        theta, shift, residuals = fit_motion(nominal, np.asarray(seen))
        rot, shift3 = _motion3(theta, shift)
        fitted = nominal @ _rot2(theta).T + shift
        moved = float(np.max(np.linalg.norm(fitted - nominal, axis=1)))
        placement = placement.moved(rot, shift3)
        apply_alignment(session, placement)
        steps = step + 1
        readings = tuple(DatumReading(h.id, h.datum or "", sid, (float(h.center[0]), float(h.center[1])),
                                      (float(c[0]), float(c[1])), float(u), int(k),
                                      _xy(_rot2(theta).T @ (c - fitted[i]) + nominal[i]), faces[i])
                         for i, ((h, sid), c, u, k) in enumerate(zip(datums, seen, us, counts)))
        if step > 0 and moved <= SETTLED_MM:
            break
    rot_total, shift_total = placement.offset_from(nominal_place)
    turn = math.degrees(math.atan2(rot_total[1, 0], rot_total[0, 0]))
    u_centre = float(np.sqrt(np.mean([r.u_mm ** 2 for r in readings])))
    span = float(np.max(np.linalg.norm(nominal - nominal.mean(axis=0), axis=1)))
    u_turn = math.degrees(u_centre / (span * math.sqrt(len(readings)))) if span > 0 else math.nan
    alignment = Alignment(placement, (float(shift_total[0]), float(shift_total[1]), float(shift_total[2])), turn,
                          u_centre / math.sqrt(len(readings)), u_turn,
                          {r.feature: float(e) for r, e in zip(readings, residuals)},
                          ("A (the fixture's pads)", *(f"{r.datum} ({r.feature})" for r in readings)),
                          readings, steps, session.clock.now - t0, _xy(nominal.mean(axis=0)))
    apply_alignment(session, placement, alignment.u_max(nominal_place.envelope_min_mm, nominal_place.envelope_max_mm))
    first = start.offset_from(nominal_place)[1]
    return AlignDone(alignment, "", tuple(outcomes), state, float(np.linalg.norm(shift_total - first)))
