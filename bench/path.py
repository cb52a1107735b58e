"""Benchmark the Path Planner beside OMPL's RRTConnect on one problem set, in one run.

    python bench/path.py [--problems FILE | --n 200 --seed 1] [--limit 5] [--ompl-seed S] [--out FILE]

A generated set is written beside --out (`path.json` -> `path_problems.json`), so a fresh
set never overwrites the committed one unless --out is the default.

Same problems, same collision geometry, same validity test, same timing:
- the problems: `ita.path.problems` (measurement to measurement, rack to measurement and
  back, random free configurations), generated with --n/--seed unless --problems is given;
- validity: the planner's own `config_free` (joint limits, then the region tree's
  `ArmChecker` over the arm's tubes and the held tool's) called per state by OMPL, and
  the planner's own sound motion check (`motion.MotionChecker`: conservative advancement
  on exact clearances, so a motion it accepts is free at every position) as OMPL's
  MotionValidator, called per motion from Python;
- OMPL: RRTConnect in joint space (each joint scaled by its lever arm), `simplifySolution()`
  (OMPL's shortcutting, vertex reduction and smoothing) after it.  A pose goal becomes a
  `GoalStates` holding every collision-free IK solution of every candidate pose (OMPL's
  usual way to hand a planner a pose goal); a configuration goal is one GoalState.
  A second OMPL row is given the goal configuration our planner reached, to separate the
  effect of choosing the goal solution from the path itself;
- timing: both joint paths are timed by the same `smooth.time_parameterize` (blends where
  the motion check proves them free, joint limits and the TCP speed limit), untimed for
  OMPL, included in our planning time;
- planning time: wall seconds per query (ours: `PathPlanner.plan`, all of it, its sampling
  fallback included where the two levels gave up: the check "ours_fallbacks" lists those;
  OMPL: goal states, setup, solve and simplify).  Static precomputation (the visibility graph, the
  numba compilation) is done before timing for ours;
- every returned trajectory is re-checked between its knots, exact tubes at positions no
  more than 5 mm ("valid_5mm") and 1 mm ("valid_1mm") of any tube's travel apart.

Prints a table, the acceptance checks of issue 5, and writes bench/results/path.json.
Figures are one machine's; not assertions.
"""

from __future__ import annotations

import argparse
import functools
import json
import platform
import time
from pathlib import Path

import numpy as np

from ita.kinematics import ik_tool, tcp_poses
from ita.part.store import load_part
from ita.path.lift import segments_free
from ita.path.planner import planners_for
from ita.path.problems import (
    generate_problems,
    read_problems,
    summarize,
    write_problems,
)
from ita.path.smooth import limit_violations, trajectory_free
from ita.specs.io import read_specs
from ita.workcell import load_workcell

RESULTS = Path(__file__).resolve().parent / "results"
DEFAULT_OUT = RESULTS / "path.json"
CHECKS = {"valid_5mm": 0.005, "valid_1mm": 0.001}   # m of travel between re-checked positions


def ompl_plan(ctx, start, goals, limit: float, ob, og):
    """RRTConnect + simplification from start (6,) to any of goals (m, 6); returns
    (waypoints (k, 6) or None, seconds)."""
    lever = ctx.lever
    t0 = time.perf_counter()
    space = ob.RealVectorStateSpace(6)
    bounds = ob.RealVectorBounds(6)
    for j in range(6):
        bounds.setLow(j, float(ctx.model.lower[j] * lever[j]))
        bounds.setHigh(j, float(ctx.model.upper[j] * lever[j]))
    space.setBounds(bounds)
    ss = og.SimpleSetup(space)
    free = ctx.config_free

    def valid(state) -> bool:
        q = np.array([state[j] for j in range(6)]) / lever
        return bool(free(q[None])[0])

    ss.setStateValidityChecker(valid)
    si = ss.getSpaceInformation()
    motion = _motion_validator(ob)(si, ctx.motion_free, lever)
    si.setMotionValidator(motion)
    s = space.allocState()
    for j in range(6):
        s[j] = float(start[j] * lever[j])
    ss.setStartState(s)
    goal = ob.GoalStates(si)
    keep = []
    for q in goals:
        g = space.allocState()
        for j in range(6):
            g[j] = float(q[j] * lever[j])
        goal.addState(g)
        keep.append(g)
    ss.setGoal(goal)
    ss.setPlanner(og.RRTConnect(si))
    ss.setup()
    solved = ss.solve(limit)
    if not ss.haveExactSolutionPath():
        return None, time.perf_counter() - t0
    ss.simplifySolution()
    path = ss.getSolutionPath()
    w = np.array([[st[j] for j in range(6)] for st in path.getStates()]) / lever
    del solved, keep, motion
    return w, time.perf_counter() - t0


@functools.cache
def _motion_validator(ob):
    class Motion(ob.MotionValidator):
        """OMPL's motion test: the planner's MotionChecker on the unscaled joints."""

        def __init__(self, si, motion_free, lever):
            super().__init__(si)
            self.motion_free, self.lever = motion_free, lever

        def checkMotion(self, s1, s2, *rest):   # noqa: N802 (OMPL's name)
            a = np.array([s1[j] for j in range(6)]) / self.lever
            b = np.array([s2[j] for j in range(6)]) / self.lever
            return bool(self.motion_free(a[None], b[None])[0])

    return Motion


def row_of(pid, kind, tool, ok, seconds, planner, tool_spec, waypoints) -> dict:
    row = {"id": pid, "kind": kind, "tool": tool, "ok": ok, "reason": None if ok else "not_solved",
           "seconds": seconds, "tool_path_m": None, "duration_s": None, **{k: None for k in CHECKS}}
    if ok:
        traj = planner.time(waypoints, tool_spec)
        ctx = planner.context(tool_spec)
        tcp = tcp_poses(planner.model, traj.q, ctx.tcp)[:, :3, 3]
        bounds = ctx.motion_free.bounds
        row.update(tool_path_m=float(np.linalg.norm(np.diff(tcp, axis=0), axis=1).sum()),
                   duration_s=traj.duration, waypoints=len(waypoints),
                   tool_speed_ratio=limit_violations(planner.model, traj, ctx.tcp)["tool_speed"])
        for name, res in CHECKS.items():
            row[name] = trajectory_free(traj, lambda a, b, res=res: segments_free(ctx.config_free, a, b, bounds, res))
    return row


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--problems", type=Path, default=None, help="problem set JSON (default: generate)")
    ap.add_argument("--n", type=int, default=200)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--limit", type=float, default=5.0, help="OMPL solve time limit per query (s)")
    ap.add_argument("--ompl-seed", type=int, default=None, help="OMPL's random seed (default: OMPL's own)")
    ap.add_argument("--out", type=Path, default=DEFAULT_OUT)
    args = ap.parse_args()

    from ompl import base as ob
    from ompl import geometric as og
    from ompl import util as ou
    ou.setLogLevel(ou.LogLevel.LOG_WARN)
    if args.ompl_seed is not None:
        ou.RNG.setSeed(args.ompl_seed)

    cell, part = load_workcell(), load_part(None)
    planner_for = planners_for(cell, part)
    problems_path = args.problems or args.out.with_name(f"{args.out.stem}_problems.json")
    if args.problems is None:
        problems = generate_problems(cell, read_specs(part.specs_path), args.n, args.seed, planner_for)
        problems_path.parent.mkdir(parents=True, exist_ok=True)
        write_problems(problems_path, problems, args.seed)
    else:
        problems = read_problems(args.problems)
    # static precomputation and compilation, before timing
    for held in {p.tool for p in problems}:
        planner, tool = planner_for(held)
        planner.graph(tool)
        planner.config_free(np.zeros((1, 6)), tool)

    rows: dict[str, list[dict]] = {"ours": [], "ompl": [], "ompl_same_goal": []}
    for i, p in enumerate(problems):
        planner, tool = planner_for(p.tool)
        ctx = planner.context(tool)

        start = np.asarray(p.start_q)
        r = planner.plan(start, p.goal, tool)
        rows["ours"].append(row_of(p.id, p.kind, p.tool, r.ok, r.seconds, planner, tool,
                                   r.waypoints if r.ok else None))
        rows["ours"][-1]["fallback"] = r.stats.get("sampled", 0) > 0
        if r.ok:
            rows["ours"][-1]["reason"] = None
        elif r.reason is not None:
            rows["ours"][-1]["reason"] = r.reason.value
        # OMPL: every free IK solution of the goal (the timer covers finding them)
        t0 = time.perf_counter()
        goal = p.goal
        if goal.shape == (6,):
            goals = goal[None]
        else:
            ik = ik_tool(planner.model, goal.reshape(-1, 4, 4), ctx.tcp)
            goals = ik.q[ik.valid]
            goals = goals[ctx.config_free(goals)] if len(goals) else goals
        t_goals = time.perf_counter() - t0
        w, sec = ompl_plan(ctx, start, goals, args.limit, ob, og) if len(goals) else (None, 0.0)
        rows["ompl"].append(row_of(p.id, p.kind, p.tool, w is not None, sec + t_goals, planner, tool, w))
        if r.ok:
            w2, sec2 = ompl_plan(ctx, start, r.waypoints[-1:], args.limit, ob, og)
            rows["ompl_same_goal"].append(row_of(p.id, p.kind, p.tool, w2 is not None, sec2, planner, tool, w2))
        if (i + 1) % 20 == 0:
            print(f"  {i + 1}/{len(problems)}", flush=True)

    summary = {}
    for name, rs in rows.items():
        s = summarize(rs)
        for k in CHECKS:
            s[k] = sum(1 for r in rs if r[k])
        s["max_tool_speed_ratio"] = max((r["tool_speed_ratio"] for r in rs if r["ok"]), default=None)
        summary[name] = s
    names = {"ours": "ITA path planner", "ompl": "OMPL RRTConnect+simplify",
             "ompl_same_goal": "OMPL, given our goal q"}
    print(f"\n{len(problems)} problems ({', '.join(f'{k} {v}' for k, v in _kinds(problems).items())})")
    print(f"{'planner':28s} {'solved':>7s} {'ok@5mm':>7s} {'ok@1mm':>7s} {'median ms':>10s} {'p95 ms':>9s} "
          f"{'tool path m':>12s} {'duration s':>11s}")
    for name, s in summary.items():
        print(f"{names[name]:28s} {s['solved']:>7d} {s['valid_5mm']:>7d} {s['valid_1mm']:>7d} "
              f"{s['median_ms']:>10.1f} {s['p95_ms']:>9.1f} "
              f"{_f(s['median_tool_path_m']):>12s} {_f(s['median_duration_s']):>11s}")
    ours, peer = rows["ours"], rows["ompl"]
    missed = [a["id"] for a, b in zip(ours, peer) if b["ok"] and not a["ok"]]
    both = [(a, b) for a, b in zip(ours, peer) if a["ok"] and b["ok"]]
    ratio = float(np.median([a["duration_s"] for a, _ in both]) / np.median([b["duration_s"] for _, b in both]))
    checks = {
        "every_ompl_solve_solved_by_ours": not missed,
        "missed": missed,
        "median_time_not_above_ompl": summary["ours"]["median_ms"] <= summary["ompl"]["median_ms"],
        "ours_fallbacks": [a["id"] for a in ours if a.get("fallback")],
        "median_duration_ratio_both_solved": ratio,
        "duration_ratio_at_most_0.8": ratio <= 0.8,
        "per_problem_duration_ratio_median": float(np.median([a["duration_s"] / b["duration_s"] for a, b in both])),
    }
    print("\nchecks:", json.dumps(checks))
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps({
        "machine": platform.platform(), "python": platform.python_version(),
        "problems": str(problems_path), "count": len(problems), "ompl_seed": args.ompl_seed,
        "summary": summary, "checks": checks, "rows": rows}, indent=1) + "\n", encoding="utf-8")
    print(f"wrote {args.out}")


def _kinds(problems) -> dict[str, int]:
    out: dict[str, int] = {}
    for p in problems:
        out[p.kind] = out.get(p.kind, 0) + 1
    return out


def _f(v) -> str:
    return "-" if v is None else f"{v:.2f}"


if __name__ == "__main__":
    main()
