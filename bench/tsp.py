"""Benchmark the sequence planner's ordering on TSPLIB EUC_2D instances with known optima.

    python bench/tsp.py [--tsplib DIR] [--out FILE] [--methods default,classic] [--no-peers]

For every ``*.tsp`` in the TSPLIB directory (default ``../shared/tsplib`` beside the
checkout) listed in its ``optima.csv``, runs ``default`` (LKH bounded by work with a
fixed seed, ita.sequence.lkh) and ``classic`` (the seed's method; ``--methods`` may add
``fast``, fast-tsp through ita.sequence.fasttsp) and, as peers in the same run,
fast-tsp called directly and, when importable (``pip install -e '.[bench]'``), OR-Tools
guided local search, each peer given the wall time ``default`` took on that instance.
Prints a table (length, gap to the optimum in %, seconds) with the means, and the
targets (``default``: at most 0.1 % mean above optimum, at most 1 s an instance); writes
JSON.

Also times one plan-sized ordering: 1000 random poses in a 6-joint space, cost the
slowest joint's travel time (asymmetric speeds are not modelled), open path from a fixed
start.  The first call of each method in the process is timed separately: it includes
loading (or, without a numba cache, compiling) the compiled kernels.
Figures, not assertions: nothing here fails on a slow machine.
"""

from __future__ import annotations

import argparse
import csv
import json
import platform
import time
from pathlib import Path
from typing import Callable

import numpy as np

from ita.sequence.tour import solve_tour, tour_cost
from ita.sequence.tsplib import read_tsplib

DEFAULT_TSPLIB = Path(__file__).resolve().parents[1].parent / "shared" / "tsplib"
DEFAULT_OUT = Path(__file__).resolve().parent / "results" / "tsp.json"

Peer = Callable[[np.ndarray, float], list[int]]


TARGET_MEAN_GAP = 0.1  # % above optimum, mean over the instances (issue 17)
TARGET_SECONDS = 1.0  # per instance


def fast_tsp_peer() -> Peer | None:
    """fast-tsp (MIT) called directly on the integer matrix, given a wall-clock budget."""
    import fast_tsp

    def solve(D: np.ndarray, budget: float) -> list[int]:
        return list(fast_tsp.find_tour(D.astype(np.int64), duration_seconds=max(budget, 0.01)))

    return solve


def ortools_peer() -> Peer | None:
    """OR-Tools routing (Apache-2.0): cheapest arc, then guided local search for the budget."""
    try:
        from ortools.constraint_solver import pywrapcp, routing_enums_pb2
    except ImportError:
        return None

    def solve(D: np.ndarray, budget: float) -> list[int]:
        n = D.shape[0]
        manager = pywrapcp.RoutingIndexManager(n, 1, 0)
        routing = pywrapcp.RoutingModel(manager)
        transit = routing.RegisterTransitMatrix(D.astype(int).tolist())
        routing.SetArcCostEvaluatorOfAllVehicles(transit)
        params = pywrapcp.DefaultRoutingSearchParameters()
        params.first_solution_strategy = routing_enums_pb2.FirstSolutionStrategy.PATH_CHEAPEST_ARC
        params.local_search_metaheuristic = routing_enums_pb2.LocalSearchMetaheuristic.GUIDED_LOCAL_SEARCH
        params.time_limit.FromMilliseconds(max(int(budget * 1000), 1))
        solution = routing.SolveWithParameters(params)
        order, index = [], routing.Start(0)
        while not routing.IsEnd(index):
            order.append(manager.IndexToNode(index))
            index = solution.Value(routing.NextVar(index))
        return order

    return solve


def read_optima(tsplib: Path) -> dict[str, int]:
    with open(tsplib / "optima.csv", newline="") as f:
        return {row["name"]: int(row["optimal_length"]) for row in csv.DictReader(f)}


def plan_sized_ordering(method: str, n: int = 1000, seed: int = 1) -> dict:
    """Order ``n`` random 6-joint poses by slowest-joint travel time, open path from pose 0."""
    rng = np.random.default_rng(seed)
    q = rng.uniform(-np.pi, np.pi, size=(n, 6))
    speed = np.array([2.0, 2.0, 2.5, 4.0, 4.0, 6.0])  # rad/s
    D = (np.abs(q[:, None, :] - q[None, :, :]) / speed).max(axis=2)
    t0 = time.perf_counter()
    tour = solve_tour(D, method=method, start=0)
    return {"method": method, "n": n, "cost_s": round(tour.cost, 3),
            "seconds": round(time.perf_counter() - t0, 3)}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--tsplib", type=Path, default=DEFAULT_TSPLIB,
                        help="folder with *.tsp and optima.csv (default: ../shared/tsplib beside "
                             "the checkout)")
    parser.add_argument("--out", type=Path, default=DEFAULT_OUT)
    parser.add_argument("--methods", default="default,classic")
    parser.add_argument("--no-peers", action="store_true")
    args = parser.parse_args()

    optima = read_optima(args.tsplib)
    methods = [m for m in args.methods.split(",") if m]
    peers: dict[str, Peer] = {}
    if not args.no_peers:
        for name, make in (("fast-tsp", fast_tsp_peer), ("ortools-gls", ortools_peer)):
            peer = make()
            if peer is not None:
                peers[name] = peer
            else:
                print(f"(peer {name} not installed: skipped)")

    first_call = {}
    warm = read_tsplib(args.tsplib / "berlin52.tsp")
    for method in methods:
        t = solve_tour(warm.matrix(), method=method, coords=warm.coords)
        first_call[method] = round(t.seconds, 3)

    names = sorted((p.stem for p in args.tsplib.glob("*.tsp") if p.stem in optima),
                   key=lambda s: read_tsplib(args.tsplib / f"{s}.tsp").dimension)
    columns = methods + list(peers)
    rows = []
    header = f"{'instance':10s} {'n':>5s} {'optimum':>8s}" + "".join(
        f" | {c:>11s} {'gap%':>6s} {'s':>5s}" for c in columns)
    print(f"TSPLIB from {args.tsplib}; peers get the wall time default took on the instance")
    print(header)
    print("-" * len(header))
    for name in names:
        problem = read_tsplib(args.tsplib / f"{name}.tsp")
        D = problem.matrix()
        row = {"instance": name, "n": problem.dimension, "optimum": optima[name], "results": {}}
        for method in methods:
            cpu = time.process_time()
            t = solve_tour(D, method=method, coords=problem.coords)
            row["results"][method] = {"length": t.cost, "seconds": t.seconds,
                                      "cpu_seconds": time.process_time() - cpu}
        budget = row["results"].get("default", {}).get("seconds", 1.0)
        for peer_name, peer in peers.items():
            t0 = time.perf_counter()
            order = peer(D, budget)
            seconds = time.perf_counter() - t0
            assert sorted(order) == list(range(problem.dimension)), f"{peer_name}: not a tour"
            row["results"][peer_name] = {"length": tour_cost(D, order), "seconds": seconds,
                                         "budget": budget}
        line = f"{name:10s} {problem.dimension:5d} {optima[name]:8d}"
        for c in columns:
            r = row["results"][c]
            r["gap_percent"] = 100.0 * (r["length"] - optima[name]) / optima[name]
            line += f" | {r['length']:11.0f} {r['gap_percent']:6.3f} {r['seconds']:5.2f}"
        print(line, flush=True)
        rows.append(row)

    summary = {}
    for c in columns:
        gaps = [r["results"][c]["gap_percent"] for r in rows]
        secs = [r["results"][c]["seconds"] for r in rows]
        summary[c] = {"mean_gap_percent": float(np.mean(gaps)), "max_gap_percent": float(np.max(gaps)),
                      "max_seconds": float(np.max(secs))}
        cpu = [r["results"][c].get("cpu_seconds") for r in rows]
        if None not in cpu:
            summary[c]["max_cpu_seconds"] = float(np.max(cpu))
    print("-" * len(header))
    mean_line = f"{'mean':10s} {'':5s} {'':8s}" + "".join(
        f" | {np.mean([r['results'][c]['length'] for r in rows]):11.0f} {summary[c]['mean_gap_percent']:6.3f}"
        f" {np.mean([r['results'][c]['seconds'] for r in rows]):5.2f}" for c in columns)
    print(mean_line)
    for c, s in summary.items():
        print(f"{c:12s} mean gap {s['mean_gap_percent']:6.3f} %   max gap {s['max_gap_percent']:6.3f} %"
              f"   slowest {s['max_seconds']:5.2f} s"
              + (f" ({s['max_cpu_seconds']:.2f} s CPU)" if "max_cpu_seconds" in s else ""))
    if "default" in summary:
        d = summary["default"]
        met = d["mean_gap_percent"] <= TARGET_MEAN_GAP and d["max_seconds"] <= TARGET_SECONDS
        print(f"target (default): mean gap <= {TARGET_MEAN_GAP} % and <= {TARGET_SECONDS:g} s an instance: "
              f"{'met' if met else 'NOT met'} (mean {d['mean_gap_percent']:.3f} %, slowest {d['max_seconds']:.2f} s)")
    print("first call in this process (berlin52, includes loading/compiling kernels): "
          + ", ".join(f"{m} {s:.2f} s" for m, s in first_call.items()))
    plan = [plan_sized_ordering(m) for m in methods]
    for p in plan:
        print(f"plan-sized ordering, {p['n']} poses (6 joints, open path): {p['method']} "
              f"{p['seconds']:.2f} s, travel {p['cost_s']:.1f} s")

    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps({
        "machine": {"python": platform.python_version(), "processor": platform.machine(),
                    "cpus": __import__("os").cpu_count()},
        "tsplib": str(args.tsplib),
        "targets": {"mean_gap_percent": TARGET_MEAN_GAP, "seconds": TARGET_SECONDS},
        "first_call_seconds": first_call, "instances": rows, "summary": summary,
        "plan_sized": plan,
    }, indent=2) + "\n")
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
