"""Benchmark the Path Planner beside OMPL's RRTConnect on one problem set, in one run.

    python bench/path.py [--problems FILE | --n 200 --seed 1] [--limit 5] [--out FILE]

Same problems, same collision geometry, same validity test, same timing:
- the problems: `ita.path.problems` (measurement to measurement, rack to measurement and
  back, random free configurations), generated with --n/--seed unless --problems is given;
- validity: the planner's own `config_free` (joint limits, then the region tree's
  `ArmChecker` over the arm's tubes and the held tool's) called per state by OMPL;
- OMPL: RRTConnect in joint space (each joint scaled by its lever arm, so that OMPL's
  motion-check resolution is the same 0.02 m of sweep as ours), `simplifySolution()`
  (OMPL's shortcutting, vertex reduction and smoothing) after it.  A pose goal becomes a
  `GoalStates` holding every collision-free IK solution of every candidate pose (OMPL's
  usual way to hand a planner a pose goal); a configuration goal is one GoalState.
  A second OMPL row is given the goal configuration our planner reached, to separate the
  effect of choosing the goal solution from the path itself;
- timing: both joint paths are timed by the same `smooth.time_parameterize` (blends where
  safe), untimed for OMPL, included in our planning time;
- planning time: wall seconds per query (ours: `PathPlanner.plan`, all of it; OMPL: goal
  states, setup, solve and simplify).  Static precomputation (the visibility graph, the
  numba compilation) is done before timing for ours;
- every returned trajectory is re-checked at 5 mm of sweep between its knots ("valid").

Prints a table, the acceptance checks of issue 5, and writes bench/results/path.json.
Figures are one machine's; not assertions.
"""

from __future__ import annotations

import argparse
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
from ita.path.smooth import trajectory_free
from ita.specs.io import read_specs
from ita.workcell import load_workcell

RESULTS = Path(__file__).resolve().parent / "results"
DEFAULT_OUT = RESULTS / "path.json"
DEFAULT_PROBLEMS = RESULTS / "path_problems.json"
CHECK_RESOLUTION = 0.005   # m of sweep for the final re-check of every trajectory


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
    si.setStateValidityCheckingResolution(0.02 / si.getMaximumExtent())
    ss.setup()
    solved = ss.solve(limit)
    if not ss.haveExactSolutionPath():
        return None, time.perf_counter() - t0
    ss.simplifySolution()
    path = ss.getSolutionPath()
    w = np.array([[st[j] for j in range(6)] for st in path.getStates()]) / lever
    del solved, keep
    return w, time.perf_counter() - t0


def row_of(pid, kind, tool, ok, seconds, planner, tool_spec, waypoints, check) -> dict:
    row = {"id": pid, "kind": kind, "tool": tool, "ok": ok, "reason": None if ok else "not_solved",
           "seconds": seconds, "tool_path_m": None, "duration_s": None, "valid": None}
    if ok:
        traj = planner.time(waypoints, tool_spec)
        ctx = planner.context(tool_spec)
        tcp = tcp_poses(planner.model, traj.q, ctx.tcp)[:, :3, 3]
        row.update(tool_path_m=float(np.linalg.norm(np.diff(tcp, axis=0), axis=1).sum()),
                   duration_s=traj.duration, valid=trajectory_free(traj, check), waypoints=len(waypoints))
    return row


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--problems", type=Path, default=None, help="problem set JSON (default: generate)")
    ap.add_argument("--n", type=int, default=200)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--limit", type=float, default=5.0, help="OMPL solve time limit per query (s)")
    ap.add_argument("--out", type=Path, default=DEFAULT_OUT)
    args = ap.parse_args()

    from ompl import base as ob
    from ompl import geometric as og
    from ompl import util as ou
    ou.setLogLevel(ou.LogLevel.LOG_WARN)

    cell, part = load_workcell(), load_part(None)
    planner_for = planners_for(cell, part)
    if args.problems is None:
        problems = generate_problems(cell, read_specs(part.specs_path), args.n, args.seed, planner_for)
        RESULTS.mkdir(parents=True, exist_ok=True)
        write_problems(DEFAULT_PROBLEMS, problems, args.seed)
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

        def check(a, b, ctx=ctx):
            return segments_free(ctx.config_free, a, b, ctx.lever, CHECK_RESOLUTION)

        start = np.asarray(p.start_q)
        r = planner.plan(start, p.goal, tool)
        rows["ours"].append(row_of(p.id, p.kind, p.tool, r.ok, r.seconds, planner, tool,
                                   r.waypoints if r.ok else None, check))
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
        rows["ompl"].append(row_of(p.id, p.kind, p.tool, w is not None, sec + t_goals, planner, tool, w, check))
        if r.ok:
            w2, sec2 = ompl_plan(ctx, start, r.waypoints[-1:], args.limit, ob, og)
            rows["ompl_same_goal"].append(row_of(p.id, p.kind, p.tool, w2 is not None, sec2, planner, tool, w2,
                                                 check))
        if (i + 1) % 20 == 0:
            print(f"  {i + 1}/{len(problems)}", flush=True)

    summary = {}
    for name, rs in rows.items():
        s = summarize(rs)
        s["valid"] = sum(1 for r in rs if r["valid"])
        summary[name] = s
    names = {"ours": "ITA path planner", "ompl": "OMPL RRTConnect+simplify",
             "ompl_same_goal": "OMPL, given our goal q"}
    print(f"\n{len(problems)} problems ({', '.join(f'{k} {v}' for k, v in _kinds(problems).items())})")
    print(f"{'planner':28s} {'solved':>7s} {'valid':>6s} {'median ms':>10s} {'p95 ms':>9s} "
          f"{'tool path m':>12s} {'duration s':>11s}")
    for name, s in summary.items():
        print(f"{names[name]:28s} {s['solved']:>7d} {s['valid']:>6d} {s['median_ms']:>10.1f} {s['p95_ms']:>9.1f} "
              f"{_f(s['median_tool_path_m']):>12s} {_f(s['median_duration_s']):>11s}")
    ours, peer = rows["ours"], rows["ompl"]
    missed = [a["id"] for a, b in zip(ours, peer) if b["ok"] and not a["ok"]]
    both = [(a, b) for a, b in zip(ours, peer) if a["ok"] and b["ok"]]
    ratio = float(np.median([a["duration_s"] for a, _ in both]) / np.median([b["duration_s"] for _, b in both]))
    checks = {
        "every_ompl_solve_solved_by_ours": not missed,
        "missed": missed,
        "median_time_not_above_ompl": summary["ours"]["median_ms"] <= summary["ompl"]["median_ms"],
        "median_duration_ratio_both_solved": ratio,
        "duration_ratio_at_most_0.8": ratio <= 0.8,
        "per_problem_duration_ratio_median": float(np.median([a["duration_s"] / b["duration_s"] for a, b in both])),
    }
    print("\nchecks:", json.dumps(checks))
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps({
        "machine": platform.platform(), "python": platform.python_version(),
        "problems": str(args.problems or DEFAULT_PROBLEMS), "count": len(problems),
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
