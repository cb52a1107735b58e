"""The Geometric Reasoner's first job: building the Measurement Knowledge Base.

    mkb = build_mkb(cell, part, specs, tools, part_name="bulkhead", digest=d,
                    alternatives={"SW-RV01-1": ("us_probe_1",)})

Constraints and preferences (seed: "derived from geometric constraint and preference
information"):

- the tool's axis along the surface normal (the probe perpendicular to the surface, the
  SLRA looking straight down its normal), from ita.kinematics.tool_poses;
- one configuration per measurement, away from the joint limits and close to its
  neighbours': exactly the Sequence Planner's choice (ita.geometry.configurations
  .measurement_configurations: common IK branch, centred reference, nearest solution),
  so the tours the sequence plan costs are the ones the arm flies;
- the probe: in contact with the tip pressed :data:`PRESS_M` into its spring travel; the
  approach point :attr:`ToolSpec.approach_distance` back along the normal, which must be
  collision-free for the Path Planner (else the measurement cannot be done:
  ``approach_blocked``, or ``contact_blocked`` when the probe on the point itself
  collides at every roll and arm branch);
- the SLRA: the viewing pose at the chosen stand-off, the scan window Vision asks for
  (ita.vision.scan.scan_for) scaled to that stand-off; measurements of one feature
  whose windows fit, all together, into one frame no more than :data:`GROUP_GROWTH` times
  wider than the narrowest of them, share one frame (a view group), taken from the pose
  of the member with the widest window (the anchor).  The growth bound keeps every
  member's pixels, and so Vision's accuracy, nearly what a frame of its own would give
  (a fastener hole's position needs its neighbours in view, a window three times its
  diameter's: grouping those two made the diameter's uncertainty six times larger).
"""

from __future__ import annotations

import hashlib
import math
import time
from collections.abc import Mapping, Sequence
from dataclasses import replace
from types import ModuleType
from typing import TYPE_CHECKING, Any, TypedDict

import numpy as np
from numpy.typing import NDArray

import ita.collision.build as collision_rules
import ita.collision.mesh_cover as cover_rules
import ita.vision.context as context_rules
import ita.vision.scan as scan_rules
from ita.collision import TIP_CLEARANCE, arm_tubes
from ita.geometry.configurations import (
    ROLLS,
    candidate_poses,
    contact_poses,
    measurement_configurations,
)
from ita.geometry.mkb import MKB_VERSION, MeasurementKB, MkbEntry, ViewGroup
from ita.kinematics import (
    arm_model,
    choose_centred,
    choose_nearest,
    ik_flange,
    ik_tool,
    link_segments,
    measurement_poses,
    move_time,
    tcp_poses,
)
from ita.path import planners_for as make
from ita.specs.model import MeasurementSpec
from ita.vision.for_part import vision_context
from ita.vision.scan import MAX_RASTER, MIN_HOLE_PIXELS, RASTER_STEP, scan_for

if TYPE_CHECKING:
    from ita.path import PathPlanner
    from ita.workcell.model import ToolSpec, Workcell

FloatArray = NDArray[np.float64]

PRESS_M = 0.0015          # the probe tip pushed this far into its spring travel at contact
GROUP_GROWTH = 1.25       # a view group's window at most this times its widest member's
APPROACH_LADDER_M = (0.08, 0.10, 0.12, 0.15, 0.20)  # m, tried in turn for the probe
APPROACH_TILTS_DEG = (0.0, 10.0, 20.0)  # approach directions off the normal, tried in turn
SHORT_APPROACH_M = (0.03, 0.02, 0.015, 0.01)  # m, nearer approach points, tried after the ladder
APPROACH_MARGIN_M = 0.002  # an approach pose stays free this far off it along every axis
COUPLANT_OFFSET_M = 0.003  # the couplant, squirted along the probe's axis from the approach point, must land
                           # this near the contact point (half the dispenser's 6 mm spot)
TILT_AZIMUTHS = 8         # directions about the normal per tilt
FALLBACK_ROLLS = 36       # rolls about the normal tried when the plan's own are blocked
CONTACT_STEPS = 12        # configurations checked along the straight approach-to-contact move

__all__ = [
    "GROUP_GROWTH",
    "PRESS_M",
    "build_mkb",
    "group_pixels",
    "mkb_digest",
    "rack_configurations",
    "view_groups",
]


def _source_file(module: ModuleType) -> str:
    """The file a module of ita's was imported from."""
    assert module.__file__ is not None, module.__name__   # not a namespace package
    return module.__file__


def mkb_digest(specs_digest: str, cell: Workcell) -> str:
    """Digest of what an MKB depends on: the specs (their file's digest), the workcell,
    Vision's rules for a frame's window and pixels (the source of ita.vision.scan and of
    the context it asks, ita.vision.context) and the part's collision model's rules
    (ita.collision.build and its mesh cover, ita.collision.mesh_cover), so a changed rule never meets a stored MKB made with the old one.
    (The part's mesh is in the store's key, ita.part.store.part_key.)  The cell's other
    arm is not: the MKB is the working arm's, and the other stands outside its world."""
    from pathlib import Path

    raster = f"{MIN_HOLE_PIXELS},{RASTER_STEP},{MAX_RASTER},{SHORT_APPROACH_M},{COUPLANT_OFFSET_M},{APPROACH_MARGIN_M}"
    rules = hashlib.sha256(b"".join(Path(_source_file(m)).read_bytes()
                                    for m in (scan_rules, context_rules, collision_rules, cover_rules))).hexdigest()
    alone = replace(cell, second_arm=None, second_pedestal=None, second_stations=None)
    text = f"{MKB_VERSION}|{PRESS_M}|{GROUP_GROWTH}|{raster}|{rules}|{specs_digest}|{alone!r}"
    return hashlib.sha256(text.encode()).hexdigest()


# -- building -----------------------------------------------------------------------------

class _Base(TypedDict):
    """What every entry of a spec measured with a tool starts with (MkbEntry's first fields)."""

    spec_id: str
    tool: str
    tool_class: str


def _probe_entries(cell: Workcell, tool: ToolSpec, specs: Sequence[MeasurementSpec],
                   planner: PathPlanner | None) -> list[MkbEntry]:
    """Contact and approach configurations of the probe's measurements.

    The approach point is the first of :data:`APPROACH_LADDER_M` (the tool's own
    approach distance first), then of the nearer :data:`SHORT_APPROACH_M`, that the Path
    Planner finds collision-free with the probe held, along the normal or, failing that,
    along directions tilted :data:`APPROACH_TILTS_DEG` off it (the probe keeps the contact
    pose's orientation, so it still meets the surface along its normal, as the gauge needs;
    a tilted approach point is near enough that the couplant squirted along the probe's
    axis from there lands within :data:`COUPLANT_OFFSET_M` of the contact point); and from which the
    straight move to contact keeps the arm and the probe (all but its spring-loaded tip)
    off everything (:func:`_contact_free`).  When none is, :data:`FALLBACK_ROLLS` rolls of
    the probe about the normal are tried, nearest to the chosen configuration first; when
    every one of them collides at contact already, no approach can help:
    ``contact_blocked``.
    """

    model = arm_model(cell.arm)
    tcp = tool.tcp.matrix()
    if not len(specs):
        return []
    conf = measurement_configurations(cell, model, tool, specs)
    q0 = np.nan_to_num(conf.q)
    surface = tcp_poses(model, q0, tcp)                                   # tip on the point
    ladder = [tool.approach_distance] + [d for d in APPROACH_LADDER_M if d > tool.approach_distance]
    contact_free = _contact_free(cell, planner, tool) if planner is not None else None
    chosen = _probe_at(model, planner, tool, surface, q0, ladder, contact_free)
    out: list[MkbEntry] = []
    for i, spec in enumerate(specs):
        base = _Base(spec_id=spec.id, tool=tool.name, tool_class=tool.tool_class.value)
        if not conf.found[i]:
            out.append(MkbEntry(**base, status="no_pose", reason=f"no arm configuration ({conf.status[i]})"))
            continue
        found = chosen[i]
        every = np.zeros((0, model.dof))
        if found is None:  # other rolls, nearest to the chosen configuration first
            pa, na, pb, nb = contact_poses([spec])      # where the probe must touch (a rib's side walls)
            sides = [(pa, na)] if np.allclose(pa, pb) and np.allclose(na, nb) else [(pa, na), (pb, nb)]
            poses = np.concatenate([measurement_poses(cell.part, p, n, tool, max(ROLLS, FALLBACK_ROLLS),
                                                      standoff=0.0)[0] for p, n in sides])
            ik = ik_tool(model, poses, tcp)
            every = ik.q[ik.valid]
            if len(every):
                qs = every[np.argsort(move_time(model, q0[i], every), kind="stable")][:24]
                alt = _probe_at(model, planner, tool, tcp_poses(model, qs, tcp), qs, ladder, contact_free)
                found = next((a for a in alt if a is not None), None)
        if found is None and len(every) and contact_free is not None and not contact_free(every, every).any():
            out.append(MkbEntry(**base, status="contact_blocked",
                                reason=f"the probe on the point collides in every arm configuration "
                                       f"({len(every)}: {max(ROLLS, FALLBACK_ROLLS)} rolls, every arm branch)"))
            continue
        if found is None:
            out.append(MkbEntry(**base, status="approach_blocked",
                                reason=f"no collision-free approach point up to {ladder[-1] * 1000:.0f} mm "
                                       f"off the surface, {max(APPROACH_TILTS_DEG):.0f} deg off the normal, "
                                       "at any roll"))
            continue
        q_c, pressed, q_a, approach = found
        out.append(MkbEntry(**base, q=q_c, pose=pressed, q_approach=q_a, pose_approach=approach, press_m=PRESS_M))
    return out


def _tilted(normal_dirs: FloatArray, tilt_deg: float) -> list[FloatArray]:
    """Unit directions (n, 3) tilted `tilt_deg` off each of `normal_dirs` (n, 3), one
    array per azimuth (just the normals for 0)."""
    if tilt_deg == 0.0:
        return [normal_dirs]
    ref = np.where(np.abs(normal_dirs[:, :1]) < 0.9, [[1.0, 0.0, 0.0]], [[0.0, 1.0, 0.0]])
    u = np.cross(normal_dirs, ref)
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    v = np.cross(normal_dirs, u)
    t = math.radians(tilt_deg)
    return [math.cos(t) * normal_dirs + math.sin(t) * (math.cos(a) * u + math.sin(a) * v)
            for a in np.linspace(0.0, 2.0 * math.pi, TILT_AZIMUTHS, endpoint=False)]


def _free_around(model: Any, planner: PathPlanner, tool: ToolSpec, poses: FloatArray, q: FloatArray
                 ) -> NDArray[np.bool_]:
    """Whether the approach poses (n, 4, 4) stay collision-free when the arm ends up to
    :data:`APPROACH_MARGIN_M` off them along any axis (a retract settles with the arm's
    repeatability; a start configuration on the edge of a collision blocks every move after
    it), their configurations near q (n, 6)."""
    tcp = tool.tcp.matrix()
    ok = np.ones(len(poses), dtype=bool)
    for axis in range(3):
        for sign in (-1.0, 1.0):
            moved = poses.copy()
            moved[:, axis, 3] += sign * APPROACH_MARGIN_M
            q_m, found = choose_nearest(model, ik_tool(model, moved[:, None], tcp).flatten_batch(), q)
            ok &= found
            if ok.any():
                ok[ok] = planner.config_free(q_m[ok], tool)
    return ok


def _contact_free(cell: Workcell, planner: PathPlanner, tool: ToolSpec) -> Any:
    """``(q_a (n, 6), q_c (n, 6)) -> bool (n,)``: whether the straight joint move from the
    approach point to contact (the controller's CONTACT) keeps the arm and the probe off the
    part and the cell, the probe's last TIP_CLEARANCE (its spring-loaded tip, which the
    gauge models) excepted.  Tight tubes (ita.collision.arm_tubes) over the planner's tree."""

    tubes = arm_tubes(cell.arm.urdf, planner.model.link_names).with_tool(tool, planner.model.dof + 1,
                                                                         TIP_CLEARANCE)
    model = tubes.apply(planner.model)
    checker = tubes.checker(planner.tree, planner.checker.mount)
    s = np.linspace(0.0, 1.0, CONTACT_STEPS + 1)

    def free(q_a: FloatArray, q_c: FloatArray) -> NDArray[np.bool_]:
        path = q_a[:, None] + s[None, :, None] * (q_c - q_a)[:, None]          # (n, k, 6)
        hit = checker.collides(link_segments(model, path.reshape(-1, 6)))
        blocked = hit.reshape(len(q_a), -1).any(axis=1)
        assert isinstance(blocked, np.ndarray)   # (n,): one row of the 2-D array each
        return ~blocked

    return free


def _probe_at(model: Any, planner: PathPlanner | None, tool: ToolSpec, surface: FloatArray, q0: FloatArray,
              ladder: Sequence[float], contact_free: Any = None
              ) -> list[tuple[FloatArray, FloatArray, FloatArray, FloatArray] | None]:
    """Per tip-on-surface pose (n, 4, 4) near q0 (n, 6): (q contact, pressed pose, q approach,
    approach pose) at the first free distance of `ladder` along the normal, then along the
    tilted directions of :data:`APPROACH_TILTS_DEG`, or None."""
    tcp = tool.tcp.matrix()
    n = len(surface)
    pressed = surface.copy()
    pressed[:, :3, 3] += PRESS_M * surface[:, :3, 2]                      # z points into the part
    q_c, ok_c = choose_nearest(model, ik_tool(model, pressed[:, None], tcp).flatten_batch(), q0)
    out: list[Any] = [None] * n
    todo = ok_c.copy()
    normal_dirs = surface[:, :3, 2]
    for tilt in APPROACH_TILTS_DEG:
        # off the normal the probe's axis misses the contact point by d sin(tilt) at the
        # approach point, where the couplant is squirted: only approaches near enough
        reach = COUPLANT_OFFSET_M / math.sin(math.radians(tilt)) if tilt else math.inf
        distances = [d for d in [*ladder, *SHORT_APPROACH_M] if d <= reach]
        for direction in _tilted(normal_dirs, tilt):
            for d in distances:
                if not todo.any():
                    return out
                approach = surface.copy()
                approach[:, :3, 3] -= d * direction
                q_a, ok_a = choose_nearest(model, ik_tool(model, approach[:, None], tcp).flatten_batch(), q0)
                good = todo & ok_a
                free = np.zeros(n, dtype=bool)
                if good.any():
                    free[good] = planner.config_free(q_a[good], tool) if planner is not None else True
                if planner is not None and free.any():
                    free[free] = _free_around(model, planner, tool, approach[free], q_a[free])
                if contact_free is not None and free.any():
                    free[free] = contact_free(q_a[free], q_c[free])
                for i in np.flatnonzero(free):
                    out[i] = (q_c[i], pressed[i], q_a[i], approach[i])
                todo &= ~free
    return out


def _window_mm(spec: MeasurementSpec, vctx: Any) -> float:
    """The width (mm, at the nominal stand-off) of the window Vision asks for `spec`."""

    ang = scan_for(spec, vctx).fov_deg[0]
    return 2.0 * vctx.standoff_m * 1000.0 * math.tan(math.radians(ang) / 2.0)


def _rasters(specs: Sequence[MeasurementSpec], vctx: Any) -> dict[str, tuple[int, int]]:
    """Spec id -> the pixels (rows, cols) Vision asks for its frame (`scan_for`)."""

    return {s.id: scan_for(s, vctx).shape for s in specs}


def group_pixels(rasters: Sequence[tuple[int, int]]) -> tuple[int, int]:
    """The pixels (rows, cols) of a view group's frame: per axis the most any member's
    `scan_for` asks for.  The group's window is at most :data:`GROUP_GROWTH` times a
    member's own (see :func:`view_groups`), so no member's pixels are more than that
    coarser than it asked for."""
    return max(r[0] for r in rasters), max(r[1] for r in rasters)


def view_groups(specs: Sequence[MeasurementSpec], windows: Mapping[str, float], max_window_mm: float,
                growth: float = GROUP_GROWTH) -> list[tuple[str, tuple[str, ...], float]]:
    """Group SLRA specs into shared frames: (anchor id, member ids, window mm) each.

    Within one feature, widest window first, a spec joins the first group whose window,
    grown to hold the spec's own window centred on its point, stays within `growth`
    times the window of the group's narrowest member (so no member is seen with pixels
    much coarser than in a frame of its own) and within `max_window_mm`; else it starts
    one.
    """
    by_feature: dict[str, list[MeasurementSpec]] = {}
    for s in specs:
        by_feature.setdefault(s.feature, []).append(s)
    out: list[tuple[str, tuple[str, ...], float]] = []
    for feature_specs in by_feature.values():
        groups: list[dict[str, Any]] = []
        for s in sorted(feature_specs, key=lambda s: -windows[s.id]):
            p = np.asarray(s.point, dtype=float)
            placed = False
            for g in groups:
                offset = float(np.linalg.norm(p[:2] - g["centre"][:2])) + abs(p[2] - g["centre"][2])
                need = max(g["window"], 2.0 * offset + windows[s.id])
                narrowest = min(g["narrowest"], windows[s.id])
                if need <= growth * narrowest and need <= max_window_mm:
                    g["narrowest"] = narrowest
                    g["members"].append(s.id)
                    g["window"] = need
                    placed = True
                    break
            if not placed:
                groups.append({"anchor": s.id, "centre": p, "members": [s.id], "window": windows[s.id],
                               "narrowest": windows[s.id]})
        out += [(g["anchor"], tuple(g["members"]), g["window"]) for g in groups]
    return out


def _view_candidates(cell: Workcell, tool: ToolSpec, spec: MeasurementSpec) -> FloatArray:
    """Viewing poses (c, 4, 4) of one SLRA spec: the Sequence Planner's candidates, then
    :data:`FALLBACK_ROLLS` rolls at stand-offs every 25 mm over the tool's whole range."""

    poses, _ = candidate_poses(cell, tool, [spec])
    standoffs = np.linspace(tool.standoff_min, tool.standoff_max,
                            max(2, round((tool.standoff_max - tool.standoff_min) / 0.025) + 1))
    more = [measurement_poses(cell.part, np.array([spec.point]), np.array([spec.normal]), tool, FALLBACK_ROLLS,
                              standoff=float(d))[0] for d in standoffs]
    return np.concatenate([poses[0], *more])


def _free_views(cell, model, tool, specs, planner, q, found):
    """The viewing configurations (n, 6) with each one the Path Planner finds in
    collision replaced by the candidate (another roll or stand-off, see
    :func:`_view_candidates`) nearest to it that is free; `found` False where there is none."""

    q, found = q.copy(), found.copy()
    blocked = np.flatnonzero(found)
    if len(blocked):
        blocked = blocked[~planner.config_free(q[blocked], tool)]
    for i in blocked:
        ik = ik_tool(model, _view_candidates(cell, tool, specs[i]), tool.tcp.matrix())
        qs = ik.q[ik.valid]
        found[i] = False
        if len(qs):
            qs = qs[np.argsort(move_time(model, q[i], qs), kind="stable")]
            ok = planner.config_free(qs, tool)
            if ok.any():
                q[i], found[i] = qs[int(np.argmax(ok))], True
    return q, found


def _slra_entries(cell: Workcell, tool: ToolSpec, specs: Sequence[MeasurementSpec], vctx: Any,
                  planner: PathPlanner | None = None) -> tuple[list[MkbEntry], list[ViewGroup]]:
    """Viewing poses, scan windows and view groups of the SLRA's measurements (each
    viewing configuration collision-free for the Path Planner, see :func:`_free_views`)."""

    model = arm_model(cell.arm)
    if not len(specs):
        return [], []
    conf = measurement_configurations(cell, model, tool, specs)
    q_view = np.nan_to_num(conf.q)
    found = conf.found.copy()
    if planner is not None:
        q_view, found = _free_views(cell, model, tool, specs, planner, q_view, found)
    poses = tcp_poses(model, q_view, tool.tcp.matrix())
    points = cell.part.to_world(np.array([s.point for s in specs], dtype=float).reshape(-1, 3))
    standoff = np.linalg.norm(poses[:, :3, 3] - points, axis=1)
    index = {s.id: i for i, s in enumerate(specs)}
    placed = [s for i, s in enumerate(specs) if found[i]]
    windows = {s.id: _window_mm(s, vctx) for s in placed}
    rasters = _rasters(placed, vctx)
    max_window = 2.0 * vctx.standoff_m * 1000.0 * math.tan(math.radians(min(vctx.max_fov_deg)) / 2.0)
    groups: list[ViewGroup] = []
    group_of: dict[str, str] = {}
    for anchor, members, window in view_groups(placed, windows, max_window):
        d_mm = standoff[index[anchor]] * 1000.0
        ang = math.degrees(2.0 * math.atan(window / 2.0 / d_mm))
        fov = (min(ang, vctx.max_fov_deg[0]), min(ang, vctx.max_fov_deg[1]))
        gid = f"view-{anchor}"
        groups.append(ViewGroup(gid, anchor, members, fov, group_pixels([rasters[m] for m in members])))
        group_of.update(dict.fromkeys(members, gid))
    by_id = {g.id: g for g in groups}
    out: list[MkbEntry] = []
    for i, spec in enumerate(specs):
        base = _Base(spec_id=spec.id, tool=tool.name, tool_class=tool.tool_class.value)
        if not conf.found[i]:
            out.append(MkbEntry(**base, status="no_pose", reason=f"no arm configuration ({conf.status[i]})"))
            continue
        if not found[i]:
            out.append(MkbEntry(**base, status="view_blocked",
                                reason="no collision-free viewing configuration at any roll or stand-off "
                                       f"({tool.standoff_min * 1000:.0f}..{tool.standoff_max * 1000:.0f} mm)"))
            continue
        g = by_id[group_of[spec.id]]
        a = index[g.anchor]                         # every member is measured from the anchor's view
        out.append(MkbEntry(**base, q=q_view[a], pose=poses[a], q_approach=q_view[a], pose_approach=poses[a],
                            standoff_m=float(standoff[a]), fov_deg=g.fov_deg, pixels=g.pixels, group=g.id))
    return out, groups


def rack_configurations(cell: Workcell) -> dict[str, FloatArray]:
    """Slot name -> the configuration (6,) with the bare flange the rack's approach_m above
    the slot along its axis (where the tool changer starts), furthest from the limits."""
    model = arm_model(cell.arm)
    out = {}
    for slot in cell.rack.slots:
        above = slot.pose.matrix().copy()
        above[:3, 3] -= cell.rack.approach_m * above[:3, 2]
        q, ok = choose_centred(model, ik_flange(model, above))
        if ok:
            out[slot.name] = np.asarray(q, dtype=float).reshape(6)
    return out


def build_mkb(
    cell: Workcell,
    part: Any,
    specs: Sequence[MeasurementSpec],
    tools: Mapping[str, str],
    *,
    part_name: str,
    digest: str,
    planner_for: Any = None,
    alternatives: Mapping[str, Sequence[str]] | None = None,
    reuse: MeasurementKB | None = None,
) -> MeasurementKB:
    """The MKB of `specs`; tools: spec id -> tool name (the Sequence Planner's partition).
    Specs without a tool are left out.  alternatives: spec id -> other tools (of other
    types) the tool rules allow for it; each gets an alternative entry.  planner_for:
    ``held tool -> (PathPlanner, ToolSpec)`` (ita.path.planners_for) to check approach
    points (default: made here).  reuse: an MKB of the same specs and workcell whose
    entries of a tool are taken as they are when that tool has exactly the same
    measurements to place (a tool's placements depend on its own measurements only), as
    after a re-plan that moved a few measurements to another tool; and what it could not
    place stays as an alternative entry where the new MKB has no entry of that tool class
    (so the tool rules still know it)."""
    t0 = time.perf_counter()
    if planner_for is None:

        planner_for = make(cell, part)
    vctx_cache: dict[str, Any] = {}

    def place(by_tool: Mapping[str, list[MeasurementSpec]], old: Mapping[str, list[MkbEntry]]
              ) -> tuple[dict[str, MkbEntry], dict[str, ViewGroup]]:

        entries: dict[str, MkbEntry] = {}
        groups: dict[str, ViewGroup] = {}
        for tool_name, tool_specs in sorted(by_tool.items()):
            kept = old.get(tool_name, [])
            if reuse is not None and sorted(e.spec_id for e in kept) == sorted(s.id for s in tool_specs):
                entries.update({e.spec_id: e for e in kept})
                used = {e.group for e in kept if e.group}
                groups.update({k: g for k, g in reuse.groups.items() if k in used})   # in the earlier MKB's order
                continue
            tool = cell.tool(tool_name)
            planner, _ = planner_for(tool_name)
            if tool.tool_class.ultrasonic:
                found = _probe_entries(cell, tool, tool_specs, planner)
            else:
                if "vctx" not in vctx_cache:
                    vctx_cache["vctx"] = vision_context(part, cell, tool=tool_name, specs=list(specs))
                found, made = _slra_entries(cell, tool, tool_specs, vctx_cache["vctx"], planner)
                groups.update({g.id: g for g in made})
            entries.update({e.spec_id: e for e in found})
        return entries, groups

    by_tool: dict[str, list[MeasurementSpec]] = {}
    alt_by_tool: dict[str, list[MeasurementSpec]] = {}
    for s in specs:
        if s.id in tools:
            by_tool.setdefault(tools[s.id], []).append(s)
            for other in (alternatives or {}).get(s.id, ()):
                alt_by_tool.setdefault(other, []).append(s)
    spec_ids = {s.id for s in specs}
    old_own: dict[str, list[MkbEntry]] = {}
    old_alt: dict[str, list[MkbEntry]] = {}
    if reuse is not None:
        for e in reuse.entries.values():
            old_own.setdefault(e.tool, []).append(e)
        for alts in reuse.alternatives.values():
            for e in alts:
                old_alt.setdefault(e.tool, []).append(e)
    entries, groups = place(by_tool, old_own)
    alt_entries: dict[str, list[MkbEntry]] = {}
    alt_groups: dict[str, ViewGroup] = {}
    for tool_name, tool_specs in alt_by_tool.items():   # one tool at a time: no id clashes
        found, made = place({tool_name: tool_specs}, old_alt)
        for e in found.values():
            alt_entries.setdefault(e.spec_id, []).append(e)
        alt_groups.update(made)
    if reuse is not None:   # what the earlier MKB could not place stays known (kb/tools.pl's placed/2)
        old_problems = [*reuse.problems(), *(a for alts in reuse.alternatives.values() for a in alts if not a.ok)]
        for e in old_problems:
            known = [*alt_entries.get(e.spec_id, []), *([entries[e.spec_id]] if e.spec_id in entries else [])]
            if e.spec_id in spec_ids and all(a.tool_class != e.tool_class for a in known):
                alt_entries.setdefault(e.spec_id, []).append(e)
    order = {s.id: i for i, s in enumerate(specs)}
    entries = dict(sorted(entries.items(), key=lambda kv: order[kv[0]]))
    groups.update({k: g for k, g in alt_groups.items() if k not in groups})
    alternatives_out = {k: tuple(v) for k, v in sorted(alt_entries.items(), key=lambda kv: order[kv[0]])}
    return MeasurementKB(part_name, digest, entries, groups, rack_configurations(cell),
                         time.perf_counter() - t0, alternatives=alternatives_out)
