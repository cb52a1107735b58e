"""One arm against two, as inspection runs: per seed, the simulated cycle, the wall time,
what was measured, the verdicts against the simulator's truth, and the arm-arm contacts.

    .venv/bin/python bench/two_arm_runs.py [--seeds 0,7,31] [--limit N] [--part DIR] [--out FILE]
        [--faults RATE] [--inject ARM:FAULT[@TARGET][:after=S] ...]

For each seed, in a fresh runs directory (the stores of ITA_HOME: prepare both arms once
first, `ita inspect --arms 2 --limit 1`, for warm figures): `ita inspect --seed S --json`
(the cell's first arm alone) and `ita inspect --arms 2 --seed S --json` (both arms, each
its share, through the zone conductor), each timed as a whole command.  Then each run's
results are scored against the as-built truth (ita.scoring: false accepts, false
rejects; how many values are off their true value by more than their U), and the two runs' decisions on the same specs compared (how many differ, and of
those how many by more than the two results' expanded uncertainties together).  Prints
a table and the ratios two/one (simulated cycle, wall time), writes JSON.  The two-arm
cycle counts the last arm's fold out of the way after its work; the ratio "to the last
measurement and check" leaves that out, as the one-arm cycle ends at its run's last
measurement and check.

Figures, not assertions; the machine is shared: the wall-time ratio is of runs made
side by side in one session.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import platform
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

from ita.archive import Archive, archive_path
from ita.scoring.compare import compare
from ita.scoring.truth import true_values

ROOT = Path(__file__).resolve().parent.parent
DEFAULT_OUT = ROOT / "bench" / "results" / "two_arm_runs.json"


def run(args: list[str], runs: Path) -> tuple[dict[str, Any], float, int]:
    """`ita inspect ARGS --json --runs-dir RUNS`: its summary, wall seconds, exit code."""
    t0 = time.perf_counter()
    done = subprocess.run([sys.executable, "-m", "ita.cli", "inspect", *args, "--json", "--runs-dir", str(runs)],
                          capture_output=True, text=True, cwd=ROOT)
    wall = time.perf_counter() - t0
    text = done.stdout
    start = text.find("{")
    if start < 0:
        raise SystemExit(f"ita inspect {' '.join(args)} printed no summary (exit {done.returncode}):\n"
                         f"{done.stderr[-3000:]}")
    return json.loads(text[start:]), wall, done.returncode


def results(runs: Path, run_ids: list[str]) -> tuple[dict[str, Any], str]:
    """The runs' results by spec, and the part's directory (where its truth is)."""
    with Archive.open(archive_path(runs), create=False) as archive:
        return ({r.spec_id: r for rid in run_ids for r in archive.results(rid)},
                str(archive.run(run_ids[0]).part_dir))


def agreement(one: dict[str, Any], two: dict[str, Any]) -> dict[str, Any]:
    """The two runs' decisions on the specs both decided."""
    same, differ, beyond_u = 0, [], []
    for spec, a in one.items():
        b = two.get(spec)
        if b is None or a.value is None or b.value is None:
            continue
        if a.decision == b.decision:
            same += 1
            continue
        differ.append(spec)
        ua, ub = a.U or 0.0, b.U or 0.0
        if abs(a.value - b.value) > math.hypot(ua, ub):
            beyond_u.append(spec)
    return {"same_decision": same, "different_decision": len(differ), "different_beyond_u": len(beyond_u),
            "different_specs": differ[:30], "beyond_u_specs": beyond_u[:30]}


def scored(found: dict[str, Any], truth: dict[str, float]) -> dict[str, Any]:
    """False accepts and rejects against the truth, and the measured values off their true
    value by more than their expanded uncertainty U (at k = 2 about 5 % of them are)."""
    s = compare(found.values(), truth)
    valued = [r for r in found.values() if r.value is not None and r.U and r.spec_id in truth]
    off = [r.spec_id for r in valued if abs(r.value - truth[r.spec_id]) > r.U]
    return {"false_accepts": len(s.false_accepts), "false_rejects": len(s.false_rejects),
            "false_accept_specs": list(s.false_accepts)[:30], "measured": sum(1 for r in found.values() if r.value is not None),
            "off_by_more_than_u": len(off), "with_u": len(valued), "off_specs": off[:30]}


def _names_an_arm(script: str) -> bool:
    """Whether an --inject script is one arm's (``ARM:FAULT...``; ita.cli.arms.scripts_of)."""
    head, colon, rest = script.partition(":")
    return bool(colon) and "@" not in head and not rest.startswith("after=")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", default="0,7,31")
    parser.add_argument("--limit", type=int, default=None, help="only the first N measurements (default all)")
    parser.add_argument("--part", type=Path, default=None)
    parser.add_argument("--faults", type=float, default=0.0, help="--faults RATE of both commands")
    parser.add_argument("--inject", action="append", default=[],
                        help="--inject SCRIPT of the two-arm command (ARM:FAULT... hits that arm; one naming no "
                             "arm goes to the one-arm command too), repeatable")
    parser.add_argument("--out", type=Path, default=DEFAULT_OUT)
    args = parser.parse_args()
    extra = (["--limit", str(args.limit)] if args.limit else []) + (["--part", str(args.part)] if args.part else [])
    extra += ["--faults", str(args.faults)] if args.faults else []
    scripts = [x for s in args.inject for x in ("--inject", s)]
    # a script naming no arm (a fault of the part both share, a fault of every arm) goes to
    # the one-arm run too: the same fault, one arm or two
    shared = [x for s in args.inject if not _names_an_arm(s) for x in ("--inject", s)]
    rows = []
    with tempfile.TemporaryDirectory(prefix="ita-two-arms-") as tmp:
        for seed in [int(s) for s in args.seeds.split(",")]:
            runs = Path(tmp) / f"seed{seed}"
            one, one_wall, one_rc = run(["--seed", str(seed), *extra, *shared], runs)
            two, two_wall, two_rc = run(["--arms", "2", "--seed", str(seed), *extra, *scripts], runs)
            r1, part_dir = results(runs, [one["run_id"]])
            r2, _ = results(runs, list(two["runs"].values()) + list(two.get("handover_runs", {}).values()))
            truth = true_values(part_dir)
            row = {"seed": seed,
                   "one_arm": {"run": one["run_id"], "exit": one_rc, "simulated_cycle_s": one["simulated_cycle_s"],
                               "wall_s": round(one_wall, 1), **scored(r1, truth)},
                   "two_arms": {"runs": two["runs"], "exit": two_rc, "simulated_cycle_s": two["simulated_cycle_s"],
                                "simulated_work_end_s": two.get("simulated_work_end_s"),
                                "wall_s": round(two_wall, 1), "arm_arm_contacts": two["arm_arm_contacts"],
                                "contact_check": two["contact_check"],
                                "per_arm": {a: {k: v for k, v in p.items() if k in ("measured", "total", "simulated_cycle_s",
                                                                                     "waiting_s", "folds", "refused",
                                                                                     "handed_over", "handover")}
                                            for a, p in two["per_arm"].items()},
                                "conductor_cpu_s": two.get("conductor_cpu_s"), **scored(r2, truth)},
                   "agreement": agreement(r1, r2)}
            row["cycle_ratio"] = round(two["simulated_cycle_s"] / one["simulated_cycle_s"], 3)
            # like for like: to the last arm's last measurement and check, as the one-arm cycle
            # (the fold out of the way after it left out)
            row["work_end_ratio"] = round(two["simulated_work_end_s"] / one["simulated_cycle_s"], 3)
            row["wall_ratio"] = round(two_wall / one_wall, 3)
            rows.append(row)
            print(f"seed {seed}: one arm {one['simulated_cycle_s']:.0f} s simulated, {one_wall:.0f} s wall, "
                  f"{row['one_arm']['measured']} measured, {row['one_arm']['false_accepts']} false accepts, "
                  f"{row['one_arm']['off_by_more_than_u']} off the truth by more than U | "
                  f"two arms {two['simulated_cycle_s']:.0f} s, {two_wall:.0f} s wall, "
                  f"{row['two_arms']['measured']} measured, {row['two_arms']['false_accepts']} false accepts, "
                  f"{row['two_arms']['off_by_more_than_u']} off by more than U, "
                  f"{two['arm_arm_contacts']} contacts | ratio cycle {row['cycle_ratio']} (to the last measurement "
                  f"and check {row['work_end_ratio']}), wall {row['wall_ratio']} | "
                  f"decisions differ {row['agreement']['different_decision']} "
                  f"({row['agreement']['different_beyond_u']} beyond U)", flush=True)
    out = {"machine": {"python": platform.python_version(), "cpus": os.cpu_count()}, "limit": args.limit,
           "faults": args.faults, "inject": args.inject, "seeds": rows}
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(out, indent=1))
    print(f"written {args.out}")


if __name__ == "__main__":
    main()
