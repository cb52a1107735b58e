"""Benchmarks of the Exception Handler: test selection quality, and a fault campaign.

    .venv/bin/python bench/diagnosis.py selection [--instances 40] [--seed 1]
    .venv/bin/python bench/diagnosis.py recovery [--failures 24] [--seed 11]
    .venv/bin/python bench/diagnosis.py campaign [--seeds 31,32,33] [--rate 0.05] [--limit N]

selection: over every exception of kb/faults.pl (with the cell's tests and their own
costs) and over random instances of 4 to 20 causes and tests (uniform and skewed priors,
costs 1 to 100, 2 or 3 outcomes per test): the expected test cost of the exact optimum
(prolog/diagnosis.pl's tabled DP), of the one-step rollout (what `auto` uses beyond 20
causes), of greedy information gain per cost and of cheapest-test-first; mean and worst
percent above the optimum; CPU time per selection.  Writes bench/results/diagnosis_selection.json.

recovery: real mid-plan failures in the simulated cell (measurements of the default
bulkhead with a fault switched on: a gauge glitch, a silent controller, a controller
glitch, a dirty window), each recovered two ways from where the failure left the arm and
from where a diagnosis test would leave it (the couplant station): plan repair
(macrop:repair_plan/6, the unfinished steps after a prefix for their preconditions) and
replanning (the Operation Planner from the state to the measurement's goal, MACROP
lookup first).  Per way: wall time to the recovery plan, its length, how many steps of
the failed plan it keeps, and whether it measures when run in the cell.  Writes
bench/results/diagnosis_recovery.json.

campaign: whole inspections of the default bulkhead with `ita inspect --faults RATE` over
the seeds, each against a fault-free run of the same seed (in the same fresh ITA_HOME, so
both share the stored sequence plan): the share of the fault-free run's measured points
that are measured, the diagnoses that named the injected cause (scoring reads the
injection log; a diagnosis of the same exception on the same spec as in the fault-free
run is counted apart: the part's or the plan's, whatever fault was on), false accepts,
extra cycle time, counts by exception and by cause.
Writes bench/results/diagnosis_campaign.json.  Slow (several whole runs).

Benchmarks print figures; they are not timed assertions.
"""

from __future__ import annotations

import argparse
import json
import os
import random
import statistics
import subprocess
import sys
import tempfile
import time
from collections import Counter
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
RESULTS = ROOT / "bench" / "results"
METHODS = ("optimal", "rollout", "greedy", "cheapest")


# -- selection ------------------------------------------------------------------------------

def _instance(rng: random.Random, n: int, skewed: bool) -> tuple[list[float], list]:
    from ita.logic.terms import Term

    if skewed:
        weights = [2.0 ** -rng.uniform(0, 12) for _ in range(n)]
    else:
        weights = [rng.uniform(1, 10) for _ in range(n)]
    total = sum(weights)
    probs = [w / total for w in weights]
    tests = []
    for k in range(n):
        outcomes = rng.choice((2, 3))
        tests.append(Term("test", (f"t{k}", float(rng.randint(1, 100)), [f"o{rng.randrange(outcomes)}"
                                                                           for _ in range(n)])))
    return probs, tests


def _solve(kb, probs: list[float], tests: list, method: str) -> tuple[float, float]:
    from ita.logic.terms import Var

    t0 = time.process_time()
    solution = kb.once("diagnosis", "problem_tree", probs, tests, method, Var("T"), Var("E"))
    return float(solution["E"]), time.process_time() - t0


def selection(args: argparse.Namespace) -> dict:
    from ita.diagnosis.knowledge import FaultKnowledge
    from ita.logic.bridge import KnowledgeBase
    from ita.logic.terms import Term, Var

    kb = KnowledgeBase()
    rng = random.Random(args.seed)
    rows = []
    # the knowledge base's own exceptions, in a context with a probe and an SLRA
    context = [Term("=", ("probe", "us_probe_1")), Term("=", ("slra", "slra_1")), Term("=", ("device", "gauge")),
               Term("=", ("tool", "us_probe_1"))]
    tests = [Term("-", (name, info.seconds + 10.0)) for name, info in FaultKnowledge(kb).tests().items()]
    for row in kb.call("faults", "exception", Var("E"), Var("_")):
        exc = str(row["E"])
        posterior = kb.once("diagnosis", "posterior", exc, context, [], Var("P"))["P"]
        if len(posterior) < 2:
            continue
        figures = {}
        for method in METHODS:
            t0 = time.process_time()
            sol = kb.once("diagnosis", "decision_tree", posterior, tests, context, method, Var("T"), Var("X"))
            figures[method] = (float(sol["X"]), time.process_time() - t0)
        rows.append({"set": "kb", "case": exc, "n": len(posterior), **{m: figures[m][0] for m in METHODS},
                     "seconds": {m: figures[m][1] for m in METHODS}})
    for skewed in (False, True):
        for n in (4, 8, 12, 16, 20):
            for i in range(args.instances):
                probs, tests_i = _instance(rng, n, skewed)
                figures = {m: _solve(kb, probs, tests_i, m) for m in METHODS}
                rows.append({"set": "skewed" if skewed else "uniform", "case": f"n{n}-{i}", "n": n,
                             **{m: figures[m][0] for m in METHODS},
                             "seconds": {m: figures[m][1] for m in METHODS}})
    print(f"{'set':8} {'n':>3} {'cases':>5} | " + " | ".join(f"{m:>18}" for m in METHODS[1:])
          + " | optimal ms (mean, max)")
    print(f"{'':8} {'':>3} {'':>5} | " + " | ".join(f"{'mean %':>8} {'worst %':>9}" for _ in METHODS[1:]) + " |")
    summary = []
    groups: dict[tuple[str, int], list[dict]] = {}
    for r in rows:
        key = (r["set"], r["n"] if r["set"] != "kb" else 0)
        groups.setdefault(key, []).append(r)
    for (name, n), rs in sorted(groups.items()):
        gaps = {}
        for m in METHODS[1:]:
            g = [100.0 * (r[m] - r["optimal"]) / r["optimal"] if r["optimal"] > 0 else 0.0 for r in rs]
            gaps[m] = (statistics.mean(g), max(g))
        ms = [1000.0 * r["seconds"]["optimal"] for r in rs]
        summary.append({"set": name, "n": n, "cases": len(rs), **{f"{m}_mean_pct": gaps[m][0] for m in gaps},
                        **{f"{m}_worst_pct": gaps[m][1] for m in gaps}, "optimal_ms_mean": statistics.mean(ms),
                        "optimal_ms_max": max(ms)})
        print(f"{name:8} {n if n else '-':>3} {len(rs):5d} | "
              + " | ".join(f"{gaps[m][0]:8.2f} {gaps[m][1]:9.2f}" for m in METHODS[1:])
              + f" | {statistics.mean(ms):7.1f} {max(ms):7.1f}")
    out = {"rows": rows, "summary": summary}
    RESULTS.mkdir(parents=True, exist_ok=True)
    (RESULTS / "diagnosis_selection.json").write_text(json.dumps(out, indent=1) + "\n")
    return out


# -- recovery -------------------------------------------------------------------------------

_RECOVERY_FAULTS = (("transient", "us_gauge", "us_tool"), ("controller_silent", "controller", "us_tool"),
                    ("transient", "controller", "slra_tool"), ("dirty_window", "", "slra_tool"))


def recovery(args: argparse.Namespace) -> dict:
    """Plan repair against replanning from real mid-plan failures (module docstring)."""
    from ita.diagnosis.tests import TestBench
    from ita.logic.terms import Term, Var
    from ita.planning import NoPlanError, WorldState
    from ita.sim.faults import FaultSet
    from ita.task import MeasureStatus, measure_one, open_session
    from ita.task.measure import execute_measurement

    session = open_session(None, seed=args.seed)
    bench = TestBench(session)
    rows: list[dict] = []
    state = WorldState(arm="t3")
    try:
        by_class: dict[str, list[tuple[str, str]]] = {}
        for g in session.plan.groups:
            if g.tool is None:
                continue
            cls = session.ctx.workcell.tool(g.tool).tool_class.value
            by_class.setdefault(cls, []).extend((i, g.tool) for i in g.order)
        picks = {cls: iter(items[::max(1, len(items) // args.failures)]) for cls, items in by_class.items()}
        attempt = 0
        while len(rows) < 2 * args.failures and attempt < 6 * args.failures:
            fault, target, cls = _RECOVERY_FAULTS[attempt % len(_RECOVERY_FAULTS)]
            attempt += 1
            spec_id, tool = next(picks[cls], (None, None))
            if spec_id is None:
                continue
            session.kb.once("world", "reset_world")
            session.world.faults = FaultSet().with_fault(fault, target or tool)
            out = measure_one(session, spec_id, state, tool)
            session.world.faults = FaultSet()
            state = out.state
            if out.status is not MeasureStatus.NOT_DONE or out.report is None or out.report.failure is None:
                continue
            failed_step = out.report.failure.step.number
            done = tuple(out.report.failure.completed)
            for origin in ("where it failed", "at the couplant station"):
                start = state
                if origin != "where it failed":     # where a diagnosis test leaves the arm
                    _, report, start, note = bench.execute_goals(
                        [Term("couplant_checked", ("couplant_station",))], state, name="to the couplant station")
                    if report is None or not report.ok:
                        print(f"   no move to the couplant station: {note}", flush=True)
                        break
                row = {"spec": spec_id, "tool": tool, "fault": fault, "failed_step": failed_step,
                       "plan_steps": len(out.plan.steps), "origin": origin}
                t0 = time.perf_counter()
                repaired = session.planner.repair_plan(out.plan, done, start)
                row["repair_ms"] = 1000 * (time.perf_counter() - t0)
                kept = len(out.plan.steps) - len(done)
                row["repair_steps"] = None if repaired is None else len(repaired.steps)
                row["repair_kept"] = 0 if repaired is None else kept
                t0 = time.perf_counter()
                try:
                    replanned = session.planner.plan_measurement(session.specs[spec_id], start, tool)
                except NoPlanError:
                    replanned = None
                row["replan_ms"] = 1000 * (time.perf_counter() - t0)
                row["replan_steps"] = None if replanned is None else len(replanned.steps)
                remaining = [(st.action, st.args) for st in out.plan.steps if st.number not in set(done)]
                row["replan_kept"] = 0 if replanned is None else _kept(remaining, replanned.steps)
                lengths = ["none" if p is None else Term("steps", (len(p.steps),)) for p in (repaired, replanned)]
                way = session.kb.once("faults", "recovery_way", *lengths, Var("W"))
                row["rule"] = str(way["W"]) if way else "none"
                state = start
                for way, plan in (("repair", repaired), ("replan", replanned)):
                    if plan is None:
                        row[f"{way}_measures"] = None
                        continue
                    if state != start:       # the other way ran first: the arm back where this one starts
                        goals = [Term("holding", (start.arm, start.holding_atom())),
                                 Term("at", (start.arm, start.pose.to_term()))]
                        _, report, state, note = bench.execute_goals(goals, state, name="back")
                        if report is None or not report.ok or state != start:
                            row[f"{way}_measures"] = None
                            print(f"   could not put the arm back ({state} for {start}): {note}", flush=True)
                            continue
                    ran = execute_measurement(session, spec_id, tool, plan)
                    row[f"{way}_measures"] = ran.status is MeasureStatus.MEASURED
                    state = ran.state
                rows.append(row)
                print(f"{spec_id:12} {fault:17} step {failed_step}/{row['plan_steps']} {origin:24} "
                      f"repair {row['repair_steps']} steps ({row['repair_kept']} kept) {row['repair_ms']:.0f} ms "
                      f"{'measures' if row['repair_measures'] else 'FAILS'} | replan {row['replan_steps']} steps "
                      f"({row['replan_kept']} kept) {row['replan_ms']:.0f} ms "
                      f"{'measures' if row['replan_measures'] else 'FAILS'} | rule: {row['rule']}", flush=True)
    finally:
        session.close()
    summary = {}
    for way in ("repair", "replan"):
        ok = [r for r in rows if r[f"{way}_steps"] is not None]
        summary[way] = {"plans": len(ok), "of": len(rows),
                        "ms_median": statistics.median(r[f"{way}_ms"] for r in rows) if rows else None,
                        "ms_max": max((r[f"{way}_ms"] for r in rows), default=None),
                        "steps_mean": statistics.mean(r[f"{way}_steps"] for r in ok) if ok else None,
                        "kept_mean": statistics.mean(r[f"{way}_kept"] for r in ok) if ok else None,
                        "measured": sum(1 for r in ok if r[f"{way}_measures"])}
        s = summary[way]
        print(f"{way:7}: a plan for {s['plans']} of {s['of']}, measured {s['measured']}; wall to the plan median "
              f"{s['ms_median']:.1f} ms, max {s['ms_max']:.1f} ms; {s['steps_mean']:.2f} steps, "
              f"{s['kept_mean']:.2f} of the failed plan's kept (mean)")
    chosen = [r for r in rows if r["rule"] != "none"]
    summary["rule"] = {"repair": sum(r["rule"] == "repair" for r in rows),
                       "replan": sum(r["rule"] == "replan" for r in rows),
                       "none": len(rows) - len(chosen),
                       "steps_mean": statistics.mean(r[f"{r['rule']}_steps"] for r in chosen) if chosen else None,
                       "measured": sum(1 for r in chosen if r[f"{r['rule']}_measures"])}
    s = summary["rule"]
    print(f"the rule (kb/faults.pl recovery_way/3): repair {s['repair']}, replan {s['replan']}, none {s['none']}; "
          f"{s['steps_mean']:.2f} steps (mean), measured {s['measured']} of {len(chosen)}")
    out = {"seed": args.seed, "rows": rows, "summary": summary}
    RESULTS.mkdir(parents=True, exist_ok=True)
    (RESULTS / "diagnosis_recovery.json").write_text(json.dumps(out, indent=1, default=str) + "\n")
    return out


def _kept(remaining: list[tuple], steps) -> int:
    """How many of the failed plan's unfinished steps a new plan runs unchanged, in order
    (its longest common subsequence with them)."""
    new = [(st.action, st.args) for st in steps]
    table = [[0] * (len(new) + 1) for _ in range(len(remaining) + 1)]
    for i, a in enumerate(remaining):
        for j, b in enumerate(new):
            table[i + 1][j + 1] = table[i][j] + 1 if a == b else max(table[i][j + 1], table[i + 1][j])
    return table[-1][-1]


# -- campaign -------------------------------------------------------------------------------

def _inspect(home: Path, runs: Path, seed: int, extra: list[str], limit: int | None) -> dict:
    env = dict(os.environ, ITA_HOME=str(home))
    cmd = [sys.executable, str(ROOT / "cli.py"), "inspect", "--seed", str(seed), "--runs-dir", str(runs), "--json",
           *extra] + (["--limit", str(limit)] if limit else [])
    t0 = time.perf_counter()
    done = subprocess.run(cmd, env=env, capture_output=True, text=True, check=False)
    if done.returncode not in (0, 3):          # 3: the run stopped itself (its alarm): a finding, kept
        raise SystemExit(f"{' '.join(cmd)} failed:\n{done.stderr[-3000:]}")
    summary = json.loads(done.stdout)
    summary["wall_s_total"] = time.perf_counter() - t0
    return summary


def _scored(home: Path, runs: Path, run_id: str) -> dict:
    from ita.archive import Archive, archive_path
    from ita.scoring.compare import compare
    from ita.scoring.diagnoses import diagnosis_score
    from ita.scoring.truth import injected_faults, true_values

    os.environ["ITA_HOME"] = str(home)
    with Archive.open(archive_path(runs), create=False) as archive:
        info = archive.run(run_id)
        results = archive.results(run_id)
        diagnoses = [e.payload for e in archive.events(run_id, kinds=["diagnosis"])]
    truth = true_values(info.part_dir)
    sc = compare(results, truth)
    injected = injected_faults(runs, run_id)
    scored = diagnosis_score(injected, diagnoses)
    return {"measured": {r.spec_id for r in results if r.outcome.value == "measured"},
            "false_accepts": list(sc.false_accepts), "injected": scored, "n_injected": len(injected),
            "diagnoses": diagnoses, "cycle_s": info.sim_time}


def campaign(args: argparse.Namespace) -> dict:
    seeds = [int(s) for s in args.seeds.split(",")]
    rows = []
    for seed in seeds:
        home = Path(tempfile.mkdtemp(prefix=f"ita-campaign-{seed}-"))
        runs = home / "runs"
        clean = _inspect(home, runs, seed, [], args.limit)
        faulty = _inspect(home, runs, seed, ["--faults", str(args.rate)], args.limit)
        a, b = _scored(home, runs, clean["run_id"]), _scored(home, runs, faulty["run_id"])
        kept = len(a["measured"] & b["measured"]) / len(a["measured"]) if a["measured"] else 1.0
        # a diagnosis of the same exception on the same spec as in the fault-free run is the
        # part's or the plan's (a view that cannot see the feature), whatever was injected then
        as_clean = {(d.get("spec"), d.get("exception")) for d in a["diagnoses"]}
        to_find = [r for r in b["injected"]["diagnoses"] if r["injected"] and (r["spec"], r["exception"]) not in as_clean]
        also_clean = sum(1 for r in b["injected"]["diagnoses"] if r["injected"] and (r["spec"], r["exception"]) in as_clean)
        named = sum(1 for r in to_find if r["named"])
        with_fault = len(to_find)
        by_exc = Counter(d["exception"] for d in b["diagnoses"])
        by_cause = Counter(d.get("cause") or "unresolved" for d in b["diagnoses"])
        row = {"seed": seed, "faults_injected": b["n_injected"], "diagnoses": len(b["diagnoses"]),
               "diagnoses_with_a_fault": with_fault, "named_injected_cause": named,
               "named_pct": 100.0 * named / with_fault if with_fault else 100.0,
               "unexplained_injections": b["injected"]["unexplained"], "measured_share_pct": 100.0 * kept,
               "false_accepts_clean": len(a["false_accepts"]), "false_accepts_faulty": len(b["false_accepts"]),
               "cycle_clean_s": a["cycle_s"], "cycle_faulty_s": b["cycle_s"],
               "extra_cycle_s": b["cycle_s"] - a["cycle_s"], "by_exception": dict(by_exc), "by_cause": dict(by_cause),
               "as_in_the_fault_free_run": also_clean,
               "missed": [d for d in to_find if not d["named"]],
               "wall_s": {"clean": clean["wall_s_total"], "faulty": faulty["wall_s_total"]},
               "status": {"clean": clean["status"], "faulty": faulty["status"]},
               "alarm": {"clean": clean.get("alarm"), "faulty": faulty.get("alarm")}}
        rows.append(row)
        print(f"seed {seed}: {row['faults_injected']} faults injected, {row['diagnoses']} diagnoses, "
              f"{named}/{with_fault} of those with a fault to find named the injected cause ({also_clean} more "
              f"as in the fault-free run); measured "
              f"{row['measured_share_pct']:.2f} % of the fault-free run's points; false accepts "
              f"{row['false_accepts_faulty']} (fault-free {row['false_accepts_clean']}); cycle "
              f"{row['cycle_faulty_s']:.0f} s vs {row['cycle_clean_s']:.0f} s (+{row['extra_cycle_s']:.0f} s)",
              flush=True)
        print(f"   by exception: {dict(by_exc)}\n   by cause: {dict(by_cause)}", flush=True)
        for which in ("clean", "faulty"):
            if row["status"][which] != "completed":
                print(f"   the {which} run {row['status'][which]}: {row['alarm'][which]}", flush=True)
    out = {"rate": args.rate, "limit": args.limit, "rows": rows}
    RESULTS.mkdir(parents=True, exist_ok=True)
    (RESULTS / "diagnosis_campaign.json").write_text(json.dumps(out, indent=1, default=str) + "\n")
    return out


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    sub = parser.add_subparsers(dest="what", required=True)
    sel = sub.add_parser("selection", help="test selection quality against the exact optimum")
    sel.add_argument("--instances", type=int, default=40, help="random instances per size and prior (default 40)")
    sel.add_argument("--seed", type=int, default=1)
    rec = sub.add_parser("recovery", help="plan repair against replanning from real mid-plan failures")
    rec.add_argument("--failures", type=int, default=24, help="mid-plan failures to make (default 24)")
    rec.add_argument("--seed", type=int, default=11)
    camp = sub.add_parser("campaign", help="whole runs with injected faults against fault-free ones")
    camp.add_argument("--seeds", default="31,32,33")
    camp.add_argument("--rate", type=float, default=0.05)
    camp.add_argument("--limit", type=int, default=None, help="only the first N measurements (a quick check)")
    args = parser.parse_args(argv)
    {"selection": selection, "recovery": recovery, "campaign": campaign}[args.what](args)
    return 0


if __name__ == "__main__":
    sys.exit(main())
