"""Benchmarks of the Exception Handler: test selection quality, and a fault campaign.

    .venv/bin/python bench/diagnosis.py selection [--instances 40] [--seed 1]
    .venv/bin/python bench/diagnosis.py campaign [--seeds 31,32,33] [--rate 0.05] [--limit N]

selection: over every exception of kb/faults.pl (with the cell's tests and their own
costs) and over random instances of 4 to 20 causes and tests (uniform and skewed priors,
costs 1 to 100, 2 or 3 outcomes per test): the expected test cost of the exact optimum
(prolog/diagnosis.pl's tabled DP), of the one-step rollout (what `auto` uses beyond 20
causes), of greedy information gain per cost and of cheapest-test-first; mean and worst
percent above the optimum; CPU time per selection.  Writes bench/results/diagnosis_selection.json.

campaign: whole inspections of the default bulkhead with `ita inspect --faults RATE` over
the seeds, each against a fault-free run of the same seed (in the same fresh ITA_HOME, so
both share the stored sequence plan): the share of the fault-free run's measured points
that are measured, the diagnoses that named the injected cause (scoring reads the
injection log), false accepts, extra cycle time, counts by exception and by cause.
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


# -- campaign -------------------------------------------------------------------------------

def _inspect(home: Path, runs: Path, seed: int, extra: list[str], limit: int | None) -> dict:
    env = dict(os.environ, ITA_HOME=str(home))
    cmd = [sys.executable, str(ROOT / "cli.py"), "inspect", "--seed", str(seed), "--runs-dir", str(runs), "--json",
           *extra] + (["--limit", str(limit)] if limit else [])
    t0 = time.perf_counter()
    done = subprocess.run(cmd, env=env, capture_output=True, text=True, check=False)
    if done.returncode != 0:
        raise SystemExit(f"{' '.join(cmd)} failed:\n{done.stderr[-3000:]}")
    summary = json.loads(done.stdout)
    summary["wall_s_total"] = time.perf_counter() - t0
    return summary


def _scored(home: Path, runs: Path, run_id: str) -> dict:
    from ita.archive import Archive, archive_path
    from ita.scoring import compare, diagnosis_score, injected_faults, true_values

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
        named = b["injected"]["named"]
        with_fault = b["injected"]["with_fault"]
        by_exc = Counter(d["exception"] for d in b["diagnoses"])
        by_cause = Counter(d.get("cause") or "unresolved" for d in b["diagnoses"])
        row = {"seed": seed, "faults_injected": b["n_injected"], "diagnoses": len(b["diagnoses"]),
               "diagnoses_with_a_fault": with_fault, "named_injected_cause": named,
               "named_pct": 100.0 * named / with_fault if with_fault else 100.0,
               "unexplained_injections": b["injected"]["unexplained"], "measured_share_pct": 100.0 * kept,
               "false_accepts_clean": len(a["false_accepts"]), "false_accepts_faulty": len(b["false_accepts"]),
               "cycle_clean_s": a["cycle_s"], "cycle_faulty_s": b["cycle_s"],
               "extra_cycle_s": b["cycle_s"] - a["cycle_s"], "by_exception": dict(by_exc), "by_cause": dict(by_cause),
               "missed": [d for d in b["injected"]["diagnoses"] if d["injected"] and not d["named"]],
               "wall_s": {"clean": clean["wall_s_total"], "faulty": faulty["wall_s_total"]}}
        rows.append(row)
        print(f"seed {seed}: {row['faults_injected']} faults injected, {row['diagnoses']} diagnoses, "
              f"{named}/{with_fault} of those with a fault to find named the injected cause; measured "
              f"{row['measured_share_pct']:.2f} % of the fault-free run's points; false accepts "
              f"{row['false_accepts_faulty']} (fault-free {row['false_accepts_clean']}); cycle "
              f"{row['cycle_faulty_s']:.0f} s vs {row['cycle_clean_s']:.0f} s (+{row['extra_cycle_s']:.0f} s)",
              flush=True)
        print(f"   by exception: {dict(by_exc)}\n   by cause: {dict(by_cause)}", flush=True)
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
    camp = sub.add_parser("campaign", help="whole runs with injected faults against fault-free ones")
    camp.add_argument("--seeds", default="31,32,33")
    camp.add_argument("--rate", type=float, default=0.05)
    camp.add_argument("--limit", type=int, default=None, help="only the first N measurements (a quick check)")
    args = parser.parse_args(argv)
    selection(args) if args.what == "selection" else campaign(args)
    return 0


if __name__ == "__main__":
    sys.exit(main())
