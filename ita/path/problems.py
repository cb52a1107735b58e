"""Start/goal problem sets for the Path Planner (the seed's offline problem-set generator).

A problem is one move of the arm in the workcell with a held tool (or none): from a
start configuration to a goal given as candidate tool poses (a measurement's approach
poses over the probe's rolls, a rack slot's approach pose, a random free configuration's
tool pose) or, in hand-written sets, as a configuration.  Kinds:

* ``measure_to_measure``: between the approach poses of two measurements, one tool;
* ``rack_to_measure``: from above the tool's rack slot (just picked up) to a measurement;
* ``measure_to_rack``: from a measurement back above the tool's slot (to put it down);
* ``random``: from a random collision-free configuration to the tool pose of another
  (with or without a tool); `goal_q` keeps the configuration the pose came from.

Approach poses: the contact probe stops PROBE_CLEARANCE off the surface along the normal
(the touch itself is the controller's guarded move); the SLRA at its nominal standoff.
Above a slot: the flange RACK_LIFT over its parked pose, same orientation.

JSON (``format`` = FORMAT): {"format", "seed", "count", "problems": [{"id", "kind",
"tool" (name or null), "start_label", "goal_label", "start_q" [6], "goal_q" [6] or null,
"goal_poses" [[4x4], ...] or null}]}; angles rad, lengths m, world frame.
"""

from __future__ import annotations

import json
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ita.errors import InputError, Location
from ita.kinematics import approach_poses, ik_tool, measurement_poses, tcp_poses
from ita.workcell.model import ToolSpec, Workcell

FloatArray = NDArray[np.float64]
FORMAT = "ita-path-problems/1"
PROBE_CLEARANCE = 0.10     # m off the surface for a contact probe's approach pose
RACK_LIFT = 0.30           # m above a slot's parked flange pose
KINDS = ("measure_to_measure", "rack_to_measure", "measure_to_rack", "random")
MIX = (0.4, 0.15, 0.15, 0.3)
TOOLS = ("us_probe_1", "slra_1")


@dataclass(frozen=True)
class Problem:
    """One start/goal query (see the module doc); arrays as nested tuples."""

    id: str
    kind: str
    tool: str | None
    start_label: str
    goal_label: str
    start_q: tuple[float, ...]
    goal_q: tuple[float, ...] | None = None
    goal_poses: tuple | None = None

    @property
    def goal(self) -> FloatArray:
        """What `PathPlanner.plan` takes: the poses (k, 4, 4) if any, else the configuration (6,)."""
        return np.asarray(self.goal_poses if self.goal_poses is not None else self.goal_q, dtype=float)

    def to_json(self) -> dict[str, Any]:
        """The problem as a JSON object."""
        return {"id": self.id, "kind": self.kind, "tool": self.tool, "start_label": self.start_label,
                "goal_label": self.goal_label, "start_q": list(self.start_q),
                "goal_q": None if self.goal_q is None else list(self.goal_q),
                "goal_poses": None if self.goal_poses is None else np.asarray(self.goal_poses).tolist()}

    @classmethod
    def from_json(cls, obj: dict[str, Any]) -> Problem:
        """A problem from its JSON object; ValueError saying what is wrong if malformed."""
        try:
            start = _floats(obj["start_q"], (6,))
            goal_q = None if obj.get("goal_q") is None else _floats(obj["goal_q"], (6,))
            poses = obj.get("goal_poses")
            goal_poses = None if poses is None else _nested(np.asarray(poses, dtype=float), (-1, 4, 4))
            if goal_q is None and goal_poses is None:
                raise ValueError("neither goal_q nor goal_poses")
            if obj["kind"] not in KINDS:
                raise ValueError(f"unknown kind {obj['kind']!r}")
            return cls(str(obj["id"]), obj["kind"], obj.get("tool"), str(obj.get("start_label", "")),
                       str(obj.get("goal_label", "")), start, goal_q, goal_poses)
        except KeyError as exc:
            raise ValueError(f"missing key {exc}") from exc
        except TypeError as exc:
            raise ValueError(str(exc)) from exc


def _floats(values: Any, shape: tuple[int, ...]) -> tuple[float, ...]:
    a = np.asarray(values, dtype=float)
    if a.shape != shape or not np.all(np.isfinite(a)):
        raise ValueError(f"expected {shape} finite numbers, got {a.shape}")
    return tuple(float(v) for v in a)


def _nested(a: np.ndarray, shape: tuple[int, ...]) -> tuple:
    if a.ndim != 3 or a.shape[1:] != shape[1:] or not np.all(np.isfinite(a)):
        raise ValueError(f"goal_poses must be (k, 4, 4) finite, got {a.shape}")
    return tuple(tuple(tuple(float(v) for v in row) for row in pose) for pose in a)


def write_problems(path: Path, problems: Sequence[Problem], seed: int | None = None) -> None:
    """Write a problem set as JSON."""
    data = {"format": FORMAT, "seed": seed, "count": len(problems), "problems": [p.to_json() for p in problems]}
    Path(path).write_text(json.dumps(data, indent=1) + "\n", encoding="utf-8")


def read_problems(path: Path) -> list[Problem]:
    """Read a problem set; InputError naming the file if it is not one."""
    where = Location(str(path))
    try:
        data = json.loads(Path(path).read_text(encoding="utf-8"))
    except (OSError, json.JSONDecodeError) as exc:
        raise InputError([(where, f"cannot read a problem set: {exc}")]) from exc
    if not isinstance(data, dict) or data.get("format") != FORMAT:
        raise InputError([(where, f"not a problem set (format {FORMAT!r} expected)")])
    out, errors = [], []
    for i, obj in enumerate(data.get("problems", [])):
        try:
            out.append(Problem.from_json(obj))
        except (ValueError, AttributeError) as exc:
            errors.append((Location(str(path), field=f"problems[{i}]"), str(exc)))
    if errors:
        raise InputError(errors)
    return out


# ---- targets ---------------------------------------------------------------------------
def measurement_targets(cell: Workcell, point_mm: Sequence[float], normal: Sequence[float], tool: ToolSpec,
                        rolls: int = 12) -> FloatArray:
    """Approach tool poses (rolls, 4, 4) of one measurement (part point mm, normal)."""
    poses = measurement_poses(cell.part, np.asarray(point_mm, float)[None], np.asarray(normal, float)[None], tool,
                              rolls)[0]
    if tool.standoff_nominal == 0.0:
        poses = approach_poses(poses, max(PROBE_CLEARANCE, tool.approach_distance))
    return poses


def rack_target(cell: Workcell, slot: str, tool: ToolSpec | None) -> FloatArray:
    """The held tool's TCP pose (1, 4, 4) with the flange RACK_LIFT above a slot's pose."""
    match = [s for s in cell.rack.slots if s.name == slot]
    if not match:
        raise KeyError(f"no rack slot {slot!r} (slots: {', '.join(s.name for s in cell.rack.slots)})")
    flange = match[0].pose.matrix()
    flange[2, 3] += RACK_LIFT
    return (flange @ (np.eye(4) if tool is None else tool.tcp.matrix()))[None]


def free_solutions(poses: FloatArray, tcp: FloatArray, model: Any, config_free: Callable) -> FloatArray:
    """Collision-free joint solutions (m, 6) of tool poses (k, 4, 4)."""
    ik = ik_tool(model, poses, tcp)
    q = ik.q[ik.valid]
    return q[config_free(q)] if len(q) else q


# ---- generation ------------------------------------------------------------------------
def generate_problems(cell: Workcell, specs: Sequence[Any], count: int, seed: int,
                      planner_for: Callable[[str | None], tuple[Any, ToolSpec | None]]) -> list[Problem]:
    """`count` problems of the four kinds (MIX), reproducible from `seed`.

    specs: measurement specs (point, normal, id); planner_for(held) -> (PathPlanner, tool):
    the planner whose validity test (`config_free`) decides what is collision-free with
    that tool held.  Starts are free configurations; goals have at least one free solution."""
    rng = np.random.default_rng(seed)
    kinds = rng.choice(len(KINDS), size=count, p=MIX)
    out: list[Problem] = []
    for i, k in enumerate(kinds):
        for _ in range(50):
            p = _one(cell, specs, KINDS[k], rng, planner_for, f"p{i:03d}")
            if p is not None:
                out.append(p)
                break
    return out


def _one(cell: Workcell, specs: Sequence[Any], kind: str, rng: np.random.Generator,
         planner_for: Callable, pid: str) -> Problem | None:
    if kind == "random":
        held = [None, *TOOLS][int(rng.integers(3))]
    else:
        held = TOOLS[int(rng.integers(len(TOOLS)))]
    planner, tool = planner_for(held)
    tcp = np.eye(4) if tool is None else tool.tcp.matrix()

    def free(q: FloatArray) -> NDArray[np.bool_]:
        return planner.config_free(q, tool)

    def measurement() -> tuple[str, FloatArray] | None:
        spec = specs[int(rng.integers(len(specs)))]
        poses = measurement_targets(cell, spec.point, spec.normal, tool)
        return (f"spec:{spec.id}", poses) if len(free_solutions(poses, tcp, planner.model, free)) else None

    def rack() -> tuple[str, FloatArray] | None:
        assert held is not None   # only the problems with a tool held go to or from the rack
        slot = cell.slot_of(held).name
        poses = rack_target(cell, slot, tool)
        return (f"rack:{slot}", poses) if len(free_solutions(poses, tcp, planner.model, free)) else None

    def random_q() -> FloatArray | None:
        q = rng.uniform(planner.model.lower, planner.model.upper, (64, planner.model.dof))
        q = q[free(q)]
        return q[0] if len(q) else None

    def start_of(target: tuple[str, FloatArray] | None) -> FloatArray | None:
        if target is None:
            return None
        q = free_solutions(target[1], tcp, planner.model, free)
        return q[int(rng.integers(len(q)))] if len(q) else None

    if kind == "random":
        a, b = random_q(), random_q()
        if a is None or b is None:
            return None
        pose = tcp_poses(planner.model, b, tcp)
        return Problem(pid, kind, held, "random", "random", tuple(map(float, a)), tuple(map(float, b)),
                       _nested(pose, (-1, 4, 4)))
    src = rack() if kind == "rack_to_measure" else measurement()
    dst = rack() if kind == "measure_to_rack" else measurement()
    q0 = start_of(src)
    if q0 is None or src is None or dst is None or src[0] == dst[0]:
        return None
    return Problem(pid, kind, held, src[0], dst[0], tuple(map(float, q0)), None, _nested(dst[1], (-1, 4, 4)))


# ---- running a set ---------------------------------------------------------------------
def run_problems(problems: Sequence[Problem], planner_for: Callable, progress: Callable[[int], None] | None = None
                 ) -> list[dict[str, Any]]:
    """Plan every problem with the planner of its held tool: one row per problem (id,
    kind, tool, ok, reason, seconds, tool_path_m, duration_s, waypoints, subgoals)."""
    rows = []
    for i, p in enumerate(problems):
        planner, tool = planner_for(p.tool)
        r = planner.plan(np.asarray(p.start_q), p.goal, tool)
        rows.append({"id": p.id, "kind": p.kind, "tool": p.tool, "ok": r.ok,
                     "reason": None if r.reason is None else r.reason.value, "seconds": r.seconds,
                     "tool_path_m": r.tool_path_length if r.ok else None,
                     "duration_s": r.duration if r.ok else None,
                     "waypoints": len(r.waypoints), "subgoals": r.stats.get("subgoals")})
        if progress is not None:
            progress(i + 1)
    return rows


def summarize(rows: Sequence[dict[str, Any]]) -> dict[str, Any]:
    """Solved count, median and 95th percentile planning time (ms), median tool path (m)
    and trajectory duration (s) of solved problems, failures by reason."""
    ok = [r for r in rows if r["ok"]]
    t = np.array([r["seconds"] for r in rows]) * 1000.0
    reasons: dict[str, int] = {}
    for r in rows:
        if not r["ok"]:
            reasons[str(r["reason"])] = reasons.get(str(r["reason"]), 0) + 1
    return {
        "problems": len(rows), "solved": len(ok),
        "median_ms": float(np.median(t)) if len(t) else None,
        "p95_ms": float(np.percentile(t, 95)) if len(t) else None,
        "median_tool_path_m": float(np.median([r["tool_path_m"] for r in ok])) if ok else None,
        "median_duration_s": float(np.median([r["duration_s"] for r in ok])) if ok else None,
        "failures": reasons,
    }
