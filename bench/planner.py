"""Benchmarks of the Operation Planner: PDDL problems, and bulkhead measurements.

*Operation planning* (``--suite operation``): every measurement of the built-in
bulkhead planned through the Python facade (ita.planning.OperationPlanner), each from
the state the previous one leaves (the executive's chain, in specs order): first a
learning pass from an empty MACROP store, then ``--repeat`` rounds of a MACROP-lookup
pass and a from-scratch pass (plan, generalize, store) over the same states.  Prints
median and 95th percentile per measurement (each measurement's median over the rounds),
their ratio, the wall time of a whole lookup pass, and the bridge's own per-call cost;
writes bench/results/operation_planner.json.  The store lives in a temporary directory.

*PDDL* (``--suite pddl``): runs every problem of ``../shared/pddl/`` (blocksworld, gripper, logistics) through

- the ITA planner (``prolog/pddl.pl`` in a ``swipl`` subprocess, one per problem), and
- pyperplan, greedy best-first search with hFF, in this process,

validates every plan with pyperplan's grounded task (an independent STRIPS simulator),
and prints solved count, plan length and time for both, beside the peer numbers of
``reference_timings.csv`` (measured with PYTHONHASHSEED=0; run this script with that
setting to compare pyperplan's plan lengths one to one).  Times are CPU seconds of the planner's process (ITA: the
swipl child's user+sys, so parsing and grounding are included; pyperplan: process time
of the search call).

    python bench/planner.py [--suite all|operation|pddl] [--repeat N]
                            [--limit SECONDS] [--only SUBSTRING] [--pddl-dir DIR]

Needs ``swipl`` on the PATH and ``pip install pyperplan`` (PDDL suite).
"""

from __future__ import annotations

import argparse
import csv
import json
import platform
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
RESULTS = ROOT / "bench" / "results"
DEFAULT_PDDL = ROOT.parent / "shared" / "pddl"
DOMAINS = ("blocks", "gripper", "logistics00")


@dataclass(frozen=True)
class Outcome:
    """One planner on one problem."""

    solved: bool
    length: int | None
    seconds: float
    valid: bool | None = None
    note: str = ""


def problems(pddl_dir: Path, only: str | None) -> list[tuple[str, Path, Path]]:
    """(domain name, domain file, problem file) for every problem, sorted by size."""
    found = []
    for name in DOMAINS:
        directory = pddl_dir / name
        for problem in sorted(directory.glob("prob*.pddl"), key=_size_key):
            if only and only not in problem.stem:
                continue
            found.append((name, directory / "domain.pddl", problem))
    return found


def _size_key(path: Path) -> tuple[int, ...]:
    digits = [int(p) for p in path.stem.replace("-", " ").replace("prob", " ").split() if p.isdigit()]
    return tuple(digits) or (0,)


def run_ita(domain: Path, problem: Path, limit: float) -> tuple[Outcome, list[str]]:
    """Solve with the ITA planner in a swipl child; return the outcome and plan lines."""
    query = (
        f"use_module('{ROOT / 'prolog' / 'pddl'}'),"
        f"(solve_and_print('{domain}','{problem}',[time_limit({limit})]) -> halt(0) ; halt(1))"
    )
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    try:
        done = subprocess.run(
            ["swipl", "-q", "-g", query, "-t", "halt(2)"],
            capture_output=True, text=True, timeout=limit + 30,
        )
        out, note = done.stdout, ""
    except subprocess.TimeoutExpired:
        out, note = "", "killed"
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    lines = [line.strip() for line in out.splitlines() if line.startswith("(")]
    reason = next((line for line in out.splitlines() if line.startswith("; no plan")), note)
    solved = bool(lines) or "length 0" in out
    return Outcome(solved, len(lines) if solved else None, cpu, note=reason), lines


def run_pyperplan(domain: Path, problem: Path) -> tuple[Outcome, object, list[str]]:
    """Solve with pyperplan gbf + hFF; also return its grounded task for validation."""
    from pyperplan.heuristics.relaxation import hFFHeuristic
    from pyperplan.planner import _ground, _parse
    from pyperplan.search import greedy_best_first_search

    start = time.process_time()
    task = _ground(_parse(str(domain), str(problem)))
    plan = greedy_best_first_search(task, hFFHeuristic(task))
    seconds = time.process_time() - start
    names = [op.name for op in plan] if plan is not None else []
    return Outcome(plan is not None, len(names) if plan is not None else None, seconds), task, names


def validate(task, lines: list[str]) -> bool:
    """Whether the plan lines execute from the task's initial state and reach its goal."""
    operators = {op.name: op for op in task.operators}
    state = task.initial_state
    for line in lines:
        op = operators.get(" ".join(line.lower().split()))
        if op is None:
            # pyperplan drops operators that can never apply (e.g. static preconditions
            # false); such a step is invalid.
            return False
        if not op.applicable(state):
            return False
        state = op.apply(state)
    return task.goal_reached(state)


def reference(pddl_dir: Path) -> dict[tuple[str, str], tuple[str, str]]:
    """Peer gbf+hFF numbers: (domain, problem) -> (plan length, CPU seconds)."""
    path = pddl_dir / "reference_timings.csv"
    table = {}
    if path.exists():
        with path.open() as handle:
            for row in csv.DictReader(handle):
                if row["planner_config"] == "pyperplan-gbf-hff":
                    table[row["domain"], row["problem"]] = (row["plan_length"], row["cpu_seconds"])
    return table


def run_pddl(args: argparse.Namespace) -> int:
    """The PDDL suite: ITA vs pyperplan on the IPC problems; exit 1 on an invalid plan."""
    peers = reference(args.pddl_dir)
    rows = []
    header = f"{'domain':12} {'problem':20} | {'ITA':>4} {'len':>4} {'cpu s':>7} {'valid':>5} | " \
             f"{'pyperplan':>9} {'len':>4} {'cpu s':>7} | {'peer len':>8} {'peer s':>6}"
    print(header)
    print("-" * len(header))
    for name, domain, problem in problems(args.pddl_dir, args.only):
        ita, lines = run_ita(domain, problem, args.limit)
        pyp, task, _ = run_pyperplan(domain, problem)
        valid = validate(task, lines) if ita.solved else None
        peer = peers.get((name, problem.stem), ("", ""))
        rows.append((name, problem.stem, ita, valid, pyp))
        print(f"{name:12} {problem.stem:20} | {'yes' if ita.solved else 'no':>4} "
              f"{ita.length if ita.length is not None else '-':>4} {ita.seconds:7.2f} "
              f"{str(valid) if valid is not None else '-':>5} | "
              f"{'yes' if pyp.solved else 'no':>9} {pyp.length if pyp.length is not None else '-':>4} "
              f"{pyp.seconds:7.2f} | {peer[0]:>8} {peer[1]:>6}"
              + (f"   {ita.note}" if not ita.solved else ""), flush=True)
    ita_ok = [r for r in rows if r[2].solved and r[3]]
    pyp_ok = [r for r in rows if r[4].solved]
    print("-" * len(header))
    print(f"ITA: {len(ita_ok)}/{len(rows)} solved with valid plans, "
          f"total length {sum(r[2].length for r in ita_ok)}, total cpu {sum(r[2].seconds for r in rows):.1f} s")
    print(f"pyperplan gbf+hFF: {len(pyp_ok)}/{len(rows)} solved, "
          f"total length {sum(r[4].length for r in pyp_ok)}, total cpu {sum(r[4].seconds for r in rows):.1f} s")
    invalid = [r for r in rows if r[2].solved and not r[3]]
    RESULTS.mkdir(parents=True, exist_ok=True)
    (RESULTS / "planner_pddl.json").write_text(json.dumps({
        "problems": [{"domain": r[0], "problem": r[1], "ita_solved": r[2].solved,
                      "ita_length": r[2].length, "ita_cpu_s": round(r[2].seconds, 4),
                      "ita_valid": r[3], "pyperplan_solved": r[4].solved,
                      "pyperplan_length": r[4].length, "pyperplan_cpu_s": round(r[4].seconds, 4)}
                     for r in rows]}, indent=1) + "\n")
    if invalid:
        print("INVALID ITA plans:", ", ".join(r[1] for r in invalid))
    return 1 if invalid else 0


# -- Operation planning through the Python facade ------------------------------------


def percentile(values: list[float], q: float) -> float:
    """The q-quantile (0..1) of `values`, nearest rank."""
    ordered = sorted(values)
    return ordered[min(len(ordered) - 1, max(0, round(q * len(ordered) + 0.5) - 1))]


def _chain(planner, specs, states, tools, from_scratch: bool) -> tuple[list, float]:
    """Plan every measurement from its state with its tool; the plans and the wall time of the pass."""
    start = time.perf_counter()
    plans = [planner.plan_measurement(s, st, t, from_scratch=from_scratch) for s, st, t in zip(specs, states, tools)]
    return plans, time.perf_counter() - start


def run_operation(args: argparse.Namespace) -> int:
    """The operation-planning suite (see the module docstring); exit 1 if a lookup missed."""
    from ita.logic.bridge import KnowledgeBase
    from ita.part.store import load_part
    from ita.planning import OperationPlanner, WorldState
    from ita.sequence.plan import partition_only, planning_context
    from ita.specs.io import read_specs

    kb = KnowledgeBase()
    chosen = partition_only(planning_context(None, kb=kb)).selections   # the Sequence Planner's tools
    specs = [s for s in read_specs(load_part(None).specs_path) if chosen[s.id].tool is not None]
    tools = [chosen[s.id].tool for s in specs]
    bridge = []
    for _ in range(2000):
        t0 = time.perf_counter()
        kb.once("system", "true")
        bridge.append(time.perf_counter() - t0)
    with tempfile.TemporaryDirectory() as tmp, OperationPlanner(kb, Path(tmp) / "macrops.pl") as planner:
        states, state, learned = [], WorldState(), []
        start = time.perf_counter()
        for spec, tool in zip(specs, tools):             # learning pass: the executive's chain
            states.append(state)
            plan = planner.plan_measurement(spec, state, tool)
            learned.append(plan)
            state = plan.final_state
        learn_seconds = time.perf_counter() - start
        lookups, scratches, lookup_walls, scratch_walls = [], [], [], []
        for _ in range(args.repeat):
            plans, wall = _chain(planner, specs, states, tools, from_scratch=False)
            lookups.append(plans)
            lookup_walls.append(wall)
            plans, wall = _chain(planner, specs, states, tools, from_scratch=True)
            scratches.append(plans)
            scratch_walls.append(wall)
        macrops = planner.macrops()
        counts = planner.counts()
    per_lookup = [statistics.median(r[i].seconds for r in lookups) for i in range(len(specs))]
    per_scratch = [statistics.median(r[i].seconds for r in scratches) for i in range(len(specs))]
    missed = sum(not p.matched for r in lookups for p in r)
    differ = sum(a.steps != b.steps for a, b in zip(lookups[0], scratches[0]))
    figures = {
        "lookup": {"median_s": statistics.median(per_lookup), "p95_s": percentile(per_lookup, 0.95)},
        "scratch": {"median_s": statistics.median(per_scratch), "p95_s": percentile(per_scratch, 0.95)},
    }
    ratio_median = figures["scratch"]["median_s"] / figures["lookup"]["median_s"]
    ratio_p95 = figures["scratch"]["p95_s"] / figures["lookup"]["p95_s"]
    ratio_each = statistics.median(s / l for s, l in zip(per_scratch, per_lookup))
    print(f"Operation planning through the Python facade: {len(specs)} bulkhead measurements, "
          f"chained states, {args.repeat} rounds (each measurement's median)")
    print(f"{'':28} {'median ms':>10} {'p95 ms':>10}")
    for name, label in (("lookup", "MACROP lookup"), ("scratch", "from scratch (plan+learn)")):
        print(f"{label:28} {figures[name]['median_s'] * 1e3:10.3f} {figures[name]['p95_s'] * 1e3:10.3f}")
    print(f"{'ratio scratch/lookup':28} {ratio_median:10.1f} {ratio_p95:10.1f}"
          f"   (median of per-measurement ratios {ratio_each:.1f})")
    print(f"all {len(specs)} measurements by MACROP lookup: best {min(lookup_walls):.3f} s, "
          f"median {statistics.median(lookup_walls):.3f} s per pass "
          f"(from scratch: {statistics.median(scratch_walls):.3f} s; learning pass {learn_seconds:.3f} s, "
          f"{sum(not p.matched for p in learned)} planned from scratch)")
    print(f"bridge floor (kb.once('system', 'true')): median {statistics.median(bridge) * 1e6:.1f} us")
    print(f"MACROPs: {', '.join(f'{m.name}({m.steps} steps, {m.hits} hits)' for m in macrops)}")
    print(f"lookups {counts.lookups}, hits {counts.hits}, misses {counts.misses}; "
          f"lookup-pass misses {missed}; plans differing lookup vs scratch {differ}")
    RESULTS.mkdir(parents=True, exist_ok=True)
    result = {
        "measurements": len(specs),
        "rounds": args.repeat,
        "lookup": figures["lookup"],
        "scratch": figures["scratch"],
        "ratio_median": ratio_median,
        "ratio_p95": ratio_p95,
        "ratio_per_measurement_median": ratio_each,
        "lookup_pass_seconds": {"best": min(lookup_walls), "median": statistics.median(lookup_walls)},
        "scratch_pass_seconds": {"median": statistics.median(scratch_walls)},
        "learning_pass": {"seconds": learn_seconds,
                          "planned_from_scratch": sum(not p.matched for p in learned)},
        "bridge_true_median_s": statistics.median(bridge),
        "macrops": [{"name": m.name, "steps": m.steps, "hits": m.hits} for m in macrops],
        "lookup_misses": missed,
        "plans_differing": differ,
        "machine": {"python": platform.python_version(), "processor": platform.machine()},
    }
    (RESULTS / "operation_planner.json").write_text(json.dumps(result, indent=1) + "\n")
    return 1 if missed else 0


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--suite", choices=("all", "operation", "pddl"), default="all")
    parser.add_argument("--repeat", type=int, default=3, help="rounds of the operation suite")
    parser.add_argument("--limit", type=float, default=60.0, help="seconds per problem (ITA)")
    parser.add_argument("--only", default=None, help="only problems whose name contains this")
    parser.add_argument("--pddl-dir", type=Path, default=DEFAULT_PDDL)
    args = parser.parse_args(argv)
    status = 0
    if args.suite in ("all", "operation"):
        status |= run_operation(args)
        print()
    if args.suite in ("all", "pddl"):
        status |= run_pddl(args)
    return status


if __name__ == "__main__":
    sys.exit(main())
