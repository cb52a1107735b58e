"""Can the arm reach a measurement?  A simple, vectorised geometric test per spec.

For each spec the tool is put where the measurement needs it: the ultrasonic probe's tip on
the point with its axis along the surface normal; the SLRA's optical centre on the normal
at a standoff in its working range, looking back along the normal.  The tool's offset from
the flange (workcell.toml) then places the flange and the wrist centre; for a straight tool
the wrist centre lies on the normal at ``standoff + tcp_length + d6`` from the point, for
the bent ultrasonic probe it depends on the tool's roll about the normal, so several rolls
are tried.  For each tool pose the test asks:

* is the wrist centre clear of the base column, above the floor and below the top of the
  working height, and (with the SLRA's optical centre) outside the part's envelope?
* for the base swivel facing the wrist centre or facing away from it (j1 = azimuth or
  azimuth + pi), and for elbow up or down: is j1 within its limits; is the wrist centre
  within the arm's radius range from the shoulder (with a margin on the stretched arm);
  are the shoulder (j2) and elbow (j3) angles that place it there within their limits;
  can the wrist pitch (j5) turn the flange from the forearm's direction onto the axis
  the tool pose needs?

These are the arm's position equations solved exactly, so a tool pose that fails here
cannot be reached: the test is a NECESSARY condition.  It ignores collisions of the links
with the part, the fixture and the arm itself and the flange roll limit (j6), and it
tries sampled standoffs and rolls only (a spec that fails every sample might still pass
in between).  The inverse kinematics and the path planner give the exact answer.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from enum import Enum

import numpy as np

from ita.specs.model import Tool
from ita.workcell.frames import unit_rows
from ita.workcell.model import ReachParams, ToolSpec, Workcell


class Reach(str, Enum):
    """Verdict of the reach test for one spec; the value is the spelling in reports."""

    REACHABLE = "reachable"
    TOO_CLOSE = "too_close"
    TOO_FAR = "too_far"
    OUTSIDE_J1 = "outside_j1"
    OUTSIDE_ARM_LIMITS = "outside_arm_limits"
    WRIST_BEND = "wrist_bend"
    BELOW_FLOOR = "below_floor"
    TOO_HIGH = "too_high"
    INSIDE_PART = "inside_part"


REACH_DESCRIPTIONS: dict[Reach, str] = {
    Reach.REACHABLE: "passes the geometric test",
    Reach.TOO_CLOSE: "wrist centre too close to the shoulder or inside the base column",
    Reach.TOO_FAR: "wrist centre beyond the arm's reach",
    Reach.OUTSIDE_J1: "direction outside the base swivel's (j1) range",
    Reach.OUTSIDE_ARM_LIMITS: "in range, but the shoulder (j2) or elbow (j3) angle is outside its limits",
    Reach.WRIST_BEND: "the wrist (j5) cannot bend far enough to align the tool with the normal",
    Reach.BELOW_FLOOR: "wrist centre or tool below the lowest working height",
    Reach.TOO_HIGH: "wrist centre above the highest working height",
    Reach.INSIDE_PART: "wrist centre or SLRA optical centre inside the part's envelope",
}

# Failure stages of one arm solution, in the order they are checked.
_STAGE_J1, _STAGE_RADIUS, _STAGE_LIMITS, _STAGE_WRIST, _STAGE_OK = range(5)


@dataclass(frozen=True)
class ReachReport:
    """Result of `reach_report`: one verdict per spec, in input order.

    verdicts: (n) Reach; standoffs: (n) the standoff (m) of the tool pose that passed,
    nearest the nominal one (0.0 for the contact probe); rolls: (n) its roll (rad) of the
    tool about the normal (0.0 for a straight tool); both nan when unreachable.
    wrist_centres: (n, 3) world wrist centres (m) of that tool pose (of the pose that came
    nearest to passing when unreachable).
    """

    verdicts: tuple[Reach, ...]
    standoffs: tuple[float, ...]
    rolls: tuple[float, ...]
    wrist_centres: np.ndarray = field(compare=False, repr=False)

    @property
    def reachable(self) -> np.ndarray:
        """Bool (n,): which specs pass."""
        return np.array([v is Reach.REACHABLE for v in self.verdicts], dtype=bool)

    @property
    def n_reachable(self) -> int:
        """How many specs pass."""
        return int(self.reachable.sum())

    @property
    def n_unreachable(self) -> int:
        """How many specs fail."""
        return len(self.verdicts) - self.n_reachable

    def counts(self) -> dict[Reach, int]:
        """Number of specs per verdict (only verdicts that occur), in Reach order."""
        return {r: c for r in Reach if (c := sum(v is r for v in self.verdicts))}

    def summary(self) -> str:
        """Lines for a user: the total, then each failure reason with its count."""
        n = len(self.verdicts)
        lines = [f"reach: {self.n_reachable} of {n} specs pass the geometric test, {self.n_unreachable} outside reach"]
        for reason, count in self.counts().items():
            if reason is not Reach.REACHABLE:
                lines.append(f"  {count:5d}  {reason.value}: {REACH_DESCRIPTIONS[reason]}")
        return "\n".join(lines)


def reach_report(
    workcell: Workcell, points_mm: np.ndarray, normals: np.ndarray, tool_classes: Sequence[Tool | str]
) -> ReachReport:
    """Test each spec's tool pose against the arm's geometry (see the module docstring).

    points_mm: (n, 3) spec points in the part frame (mm); normals: (n, 3) outward surface
    normals in the part frame; tool_classes: n of 'us_tool' / 'slra_tool'.  The first tool
    of each class in the workcell stands for its class (spares are identical).  A spec
    passes when some tried tool pose (standoff in the tool's range; roll about the normal,
    for a tool whose point is off the flange axis) passes.
    """
    points_mm = np.atleast_2d(np.asarray(points_mm, dtype=float)).reshape(-1, 3)
    normals = np.atleast_2d(np.asarray(normals, dtype=float)).reshape(-1, 3)
    classes = [Tool(c) for c in tool_classes]
    n = len(points_mm)
    if len(normals) != n or len(classes) != n:
        raise ValueError(f"{n} points, {len(normals)} normals and {len(classes)} tool classes: lengths differ")
    verdicts = np.full(n, Reach.REACHABLE, dtype=object)
    standoffs, rolls, wrists = np.full(n, np.nan), np.full(n, np.nan), np.zeros((n, 3))
    if n == 0:
        return ReachReport((), (), (), wrists)
    p_world = workcell.part.to_world(points_mm)
    n_world = unit_rows(workcell.part.normals_to_world(normals))
    for cls in sorted(set(classes), key=lambda c: c.value):
        rows = np.flatnonzero([c is cls for c in classes])
        tools = workcell.tools_of_class(cls)
        if not tools:
            raise ValueError(f"the workcell has no tool of class {cls.value!r}")
        tool = tools[0]
        poses = _tool_poses(tool, workcell.reach)
        codes, wrist_k = [], []
        for standoff, roll in poses:
            code, wrist = _verdict_codes(workcell, p_world[rows], n_world[rows], tool, standoff, roll)
            codes.append(code)
            wrist_k.append(wrist)
        # (k, m): rank of each pose's verdict; the best rank wins, the first pose on ties
        rank = _RANK[np.stack(codes)]
        pick = np.argmin(rank, axis=0)
        cols = np.arange(len(rows))
        chosen = np.stack(codes)[pick, cols]
        ok = chosen == _CODES[Reach.REACHABLE]
        verdicts[rows] = [_REASONS[c] for c in chosen]
        standoffs[rows] = np.where(ok, poses[pick, 0], np.nan)
        rolls[rows] = np.where(ok, poses[pick, 1], np.nan)
        wrists[rows] = np.stack(wrist_k)[pick, cols]
    return ReachReport(tuple(verdicts), tuple(map(float, standoffs)), tuple(map(float, rolls)), wrists)


_REASONS = tuple(Reach)
_CODES = {r: i for i, r in enumerate(_REASONS)}
# How near to passing each verdict is (0 best): when no tool pose passes, the report
# gives the reason of the pose that came nearest.
_NEARNESS = (Reach.REACHABLE, Reach.WRIST_BEND, Reach.OUTSIDE_ARM_LIMITS, Reach.OUTSIDE_J1, Reach.TOO_FAR,
             Reach.TOO_CLOSE, Reach.INSIDE_PART, Reach.TOO_HIGH, Reach.BELOW_FLOOR)
_RANK = np.array([_NEARNESS.index(r) for r in _REASONS])


def _tool_poses(tool: ToolSpec, params: ReachParams) -> np.ndarray:
    """Tool poses (k, 2) to try, as (standoff m, roll rad), the nominal standoff first.

    Standoffs: the nominal one, then `standoff_samples` evenly over [min, max].  Rolls
    about the normal: one for a straight tool (its point on the flange axis, looking along
    it), else `roll_samples` evenly over a turn.
    """
    if tool.standoff_max > tool.standoff_min:
        extra = np.linspace(tool.standoff_min, tool.standoff_max, max(params.standoff_samples, 2))
        standoffs = np.concatenate([[tool.standoff_nominal], extra[~np.isclose(extra, tool.standoff_nominal)]])
    else:
        standoffs = np.array([tool.standoff_nominal])
    rolls = np.zeros(1) if tool.is_straight else np.arange(params.roll_samples) * (2 * np.pi / params.roll_samples)
    return np.array([(s, r) for s in standoffs for r in rolls])


def _verdict_codes(
    cell: Workcell, p: np.ndarray, nrm: np.ndarray, tool: ToolSpec, standoff: float, roll: float
) -> tuple[np.ndarray, np.ndarray]:
    """Verdict codes (m,) and wrist centres (m, 3) for world points p (m, 3) with unit normals
    nrm (m, 3), the tool's point at `standoff` along the normal, its view axis along -normal
    and rolled by `roll` about it."""
    kin, reach = cell.arm.kinematics, cell.reach
    tcp = p + nrm * standoff
    tcp_rot = _frames_about(-nrm, roll)                      # (m, 3, 3), z = -normal
    offset = tool.tcp
    flange_rot = tcp_rot @ offset.rotation().T               # R_flange = R_tcp R_off^T
    flange = tcp - flange_rot @ np.asarray(offset.position)  # p_flange = p_tcp - R_flange t_off
    approach = flange_rot[:, :, 2]
    wrist = flange - approach * kin.d6
    codes = _arm_codes(cell, wrist, approach)
    part = cell.part
    lo = np.asarray(part.envelope_min_mm) - reach.part_clearance / part.scale
    hi = np.asarray(part.envelope_max_mm) + reach.part_clearance / part.scale

    def inside(points: np.ndarray) -> np.ndarray:
        local = part.to_part(points)
        return np.all((local > lo) & (local < hi), axis=1)

    in_part = inside(wrist) | (inside(tcp) if tool.tool_class is Tool.SLRA else False)
    low_z = (wrist[:, 2] < reach.wrist_min_height) | (np.minimum(tcp[:, 2], flange[:, 2]) < reach.tcp_min_height)
    base = cell.arm.base
    local = (wrist - np.asarray(base.position)) @ base.rotation()
    in_column = np.hypot(local[:, 0], local[:, 1]) < reach.base_keepout_radius
    # Cell-level failures take precedence over the arm's own (the first listed wins).
    for mask, reason in ((in_part, Reach.INSIDE_PART), (wrist[:, 2] > reach.wrist_max_height, Reach.TOO_HIGH),
                         (low_z, Reach.BELOW_FLOOR), (in_column, Reach.TOO_CLOSE)):
        codes = np.where(mask, _CODES[reason], codes)
    return codes, wrist


def _frames_about(z_axes: np.ndarray, roll: float) -> np.ndarray:
    """Rotations (m, 3, 3) whose z columns are the unit z_axes (m, 3), x rolled by `roll`.

    At roll 0, x is horizontal (perpendicular to world z), or along world x when z is vertical.
    """
    ref = np.where(np.abs(z_axes[:, 2:3]) > 0.999, np.array([[0.0, 1.0, 0.0]]), np.array([[0.0, 0.0, 1.0]]))
    e1 = unit_rows(np.cross(ref, z_axes))
    e2 = np.cross(z_axes, e1)
    x = np.cos(roll) * e1 + np.sin(roll) * e2
    y = np.cross(z_axes, x)
    return np.stack([x, y, z_axes], axis=2)


def _arm_codes(cell: Workcell, wrist_world: np.ndarray, approach_world: np.ndarray) -> np.ndarray:
    """Verdict codes (m,) of the arm alone for wrist centres (m, 3) and tool approach directions (m, 3).

    Solves j1, j2, j3 for each of the four arm solutions (base facing / facing away,
    elbow up / down): reachable when one passes every check; otherwise the reason is
    that of the facing solution that got furthest through the checks.
    """
    kin, joints, margin = cell.arm.kinematics, cell.arm.joints, cell.reach.margin
    lower, upper = np.asarray(joints.lower), np.asarray(joints.upper)
    r_min, r_max = kin.wrist_radius_limits(lower[2], upper[2])
    j5_max = max(abs(lower[4]), abs(upper[4]))
    rot = cell.arm.base.rotation()
    w = (wrist_world - np.asarray(cell.arm.base.position)) @ rot
    a = approach_world @ rot
    azimuth = np.arctan2(w[:, 1], w[:, 0])
    horizontal = np.hypot(w[:, 0], w[:, 1])
    height = w[:, 2] - kin.d1
    reachable = np.zeros(len(w), dtype=bool)
    for facing in (1.0, -1.0):
        theta = azimuth if facing > 0 else _wrap(azimuth + np.pi)
        j1_ok = _within(theta, lower[0], upper[0])
        rho = facing * horizontal - kin.a1
        radius = np.hypot(rho, height)
        radius_ok = (radius >= r_min) & (radius <= margin * r_max)
        s = np.clip((kin.a2**2 + kin.d4**2 - radius**2) / (2 * kin.a2 * kin.d4), -1.0, 1.0)
        forward = np.stack([np.cos(theta), np.sin(theta), np.zeros_like(theta)], axis=1)
        best_stage = np.full(len(w), -1)
        for q3 in (np.arcsin(s), -np.pi - np.arcsin(s)):
            psi0 = np.arctan2(kin.d4 * np.cos(q3), kin.a2 - kin.d4 * np.sin(q3))
            q2 = _wrap(np.arctan2(rho, height) - psi0)
            limits_ok = _within(q3, lower[2], upper[2]) & _within(q2, lower[1], upper[1])
            f_rho, f_h = np.cos(q2 + q3), -np.sin(q2 + q3)
            forearm = forward * f_rho[:, None] + np.array([0.0, 0.0, 1.0]) * f_h[:, None]
            bend = np.arccos(np.clip(np.sum(forearm * a, axis=1), -1.0, 1.0))
            wrist_ok = bend <= j5_max + 1e-9
            stage = np.where(~j1_ok, _STAGE_J1, np.where(~radius_ok, _STAGE_RADIUS, np.where(
                ~limits_ok, _STAGE_LIMITS, np.where(~wrist_ok, _STAGE_WRIST, _STAGE_OK))))
            best_stage = np.maximum(best_stage, stage)
        reachable |= best_stage == _STAGE_OK
        if facing > 0:  # a failure is explained by the natural, facing solutions
            front_stage, front_radius = best_stage, radius
    radius_reason = np.where(front_radius < r_min, _CODES[Reach.TOO_CLOSE], _CODES[Reach.TOO_FAR])
    table = np.array([_CODES[Reach.OUTSIDE_J1], 0, _CODES[Reach.OUTSIDE_ARM_LIMITS],
                      _CODES[Reach.WRIST_BEND], _CODES[Reach.REACHABLE]])
    codes = np.where(front_stage == _STAGE_RADIUS, radius_reason, table[front_stage])
    return np.where(reachable, _CODES[Reach.REACHABLE], codes)


def _wrap(angle: np.ndarray) -> np.ndarray:
    """Angles (m,) wrapped into [-pi, pi)."""
    return (angle + np.pi) % (2 * np.pi) - np.pi


def _within(angle: np.ndarray, low: float, high: float) -> np.ndarray:
    """Bool (m,): some angle + 2 pi k lies in [low, high] (k in -1, 0, 1)."""
    eps = 1e-9
    return np.any([(angle + k >= low - eps) & (angle + k <= high + eps) for k in (-2 * np.pi, 0.0, 2 * np.pi)], axis=0)
