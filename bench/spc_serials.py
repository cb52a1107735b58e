"""SPC across serials: how often in-control parts are flagged, how often a shift is found.

    .venv/bin/python bench/spc_serials.py [--serials 8] [--shifted 3] [--shift WT-P05-2=0.25 ...]
                                          [--runs-dir DIR] [--workers 2] [--limit N] [--out FILE]

1. Whole runs (`ita inspect --serial SN`) of the built-in design: `--serials` in-control
   serials, then `--shifted` more with the `--shift`s (special causes) in their as-built
   parts; runs already in --runs-dir for a serial are kept.  Then `ita spc --json` over
   them: which characteristics are flagged, and at which serials.  An in-control serial is
   *flagged* when a flag points at it; a shift is *found* when its characteristic is flagged.
2. The same procedure (ita.spc.chart_all) on synthetic in-control serials (normal values,
   as many characteristics as the design has, the same count of serials), 80 trials: the
   share of in-control parts flagged, beside what plain 3-sigma rules on the individuals
   chart would flag; and the share of shifted characteristics found per shift size (in
   process sigmas) in the last `--shifted` serials.

Prints the figures and writes JSON (default bench/results/spc_serials.json).  Figures, not
assertions.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
RESULTS = ROOT / "bench" / "results"
sys.path.insert(0, str(ROOT))


def _ita(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, str(ROOT / "cli.py"), *args], capture_output=True, text=True,
                          cwd=ROOT, env={**os.environ, "OPENBLAS_NUM_THREADS": "1"})


def _run(serial: str, shifts: list[str], runs_dir: Path, limit: int | None) -> tuple[str, float, int]:
    t0 = time.perf_counter()
    args = ["inspect", "--serial", serial, "--seed", "0", "--runs-dir", str(runs_dir), "--json"]
    for s in shifts:
        args += ["--shift", s]
    if limit is not None:
        args += ["--limit", str(limit)]
    done = _ita(*args)
    return serial, time.perf_counter() - t0, done.returncode


def _synthetic(m: int, n: int, shifted: int, trials: int, sizes: list[float], q: float,
               rng: np.random.Generator) -> dict[str, object]:
    from ita.spc import Series, chart_all

    serials = tuple(f"S{i:02d}" for i in range(n))
    parts_flagged = 0
    sigma3_parts = 0
    found = {s: 0 for s in sizes}
    for t in range(trials):
        x = rng.normal(0.0, 1.0, (m, n))
        charts = chart_all([Series(f"c{j}", "k", -6.0, 6.0, serials, tuple(x[j])) for j in range(m)], q=q)
        flagged_at = {s for c in charts for f in c.flags for s in f.serials}
        parts_flagged += len(flagged_at)
        sigma3_parts += len({s for c in charts for s in c.beyond_3_sigma})
        if sizes:          # one shifted characteristic among the in-control ones, its size in turn
            size = sizes[t % len(sizes)]
            y = x.copy()
            y[0, n - shifted:] += size
            charts = chart_all([Series(f"c{j}", "k", -6.0, 6.0, serials, tuple(y[j])) for j in range(m)], q=q)
            found[size] += bool(charts[0].flags)
    per = trials // max(1, len(sizes))
    return {"characteristics": m, "serials": n, "trials": trials, "q": q,
            "in_control_parts_flagged": parts_flagged / (trials * n),
            "in_control_parts_beyond_3_sigma": sigma3_parts / (trials * n),
            "shift_found": {f"{s:g} sigma": found[s] / per for s in sizes}}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--serials", type=int, default=8)
    parser.add_argument("--shifted", type=int, default=3)
    parser.add_argument("--shift", action="append", default=None, metavar="SPEC=DELTA")
    parser.add_argument("--runs-dir", type=Path, default=RESULTS / "spc_runs")
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--limit", type=int, default=None, help="measurements per run (default: the whole part)")
    parser.add_argument("--trials", type=int, default=80)
    parser.add_argument("--q", type=float, default=0.05)
    parser.add_argument("--out", type=Path, default=RESULTS / "spc_serials.json")
    args = parser.parse_args(argv)
    shifts = args.shift if args.shift is not None else ["WT-P05-2=0.25", "HD-OF-017=0.06"]

    args.runs_dir.mkdir(parents=True, exist_ok=True)
    plan = [(f"SN-{i + 1:03d}", []) for i in range(args.serials)] + \
           [(f"SN-{args.serials + i + 1:03d}", shifts) for i in range(args.shifted)]
    have: set[str] = set()
    listed = _ita("runs", "--runs-dir", str(args.runs_dir), "--json")
    if listed.returncode == 0 and listed.stdout.strip():
        have = {r["serial"] for r in json.loads(listed.stdout) if r.get("serial") and r["state"] == "completed"}
    todo = [(s, sh) for s, sh in plan if s not in have]
    print(f"{len(plan)} serials ({len(todo)} to inspect, {args.workers} at a time) in {args.runs_dir}", flush=True)
    walls: list[float] = []
    with ThreadPoolExecutor(args.workers) as pool:
        for serial, wall, rc in pool.map(lambda p: _run(p[0], p[1], args.runs_dir, args.limit), todo):
            walls.append(wall)
            print(f"  {serial}: exit {rc}, {wall:.0f} s", flush=True)
    out = _ita("spc", "--runs-dir", str(args.runs_dir), "--json", "--q", str(args.q))
    if out.returncode != 0:
        print(out.stderr, file=sys.stderr)
        return 1
    spc = json.loads(out.stdout)
    chars = spc["characteristics"]
    in_control = [s for s, sh in plan if not sh]
    shifted_serials = [s for s, sh in plan if sh]
    flagged_at = {s for c in chars for f in c["flags"] for s in f["serials"]}
    from ita.part.store import load_part
    from ita.specs.io import read_specs

    part_specs = read_specs(load_part(None).specs_path)
    asked = {t.split("=")[0] for t in shifts}
    # a shift moves the feature's dimension: every spec of that feature and kind measures it
    moved = {(s.feature, s.kind) for s in part_specs if s.id in asked}
    shifted_ids = {s.id for s in part_specs if (s.feature, s.kind) in moved}
    found = {i: any(c["id"] == i and c["flags"] for c in chars) for i in sorted(asked)}
    found_with_feature = sorted(c["id"] for c in chars if c["id"] in shifted_ids and c["flags"])
    false_flags = [(c["id"], f["rule"], f["serials"]) for c in chars for f in c["flags"] if c["id"] not in shifted_ids]
    real = {"serials": spc["serials"], "characteristics": len(chars),
            "in_control_serials": len(in_control),
            "in_control_serials_flagged": sorted(set(in_control) & flagged_at),
            "shifts": shifts, "shifted_serials": shifted_serials, "shift_found": found,
            "same_feature_flagged": found_with_feature,
            "other_characteristics_flagged": false_flags,
            "beyond_3_sigma_characteristics": sum(1 for c in chars if c["chart"]["beyond_3_sigma"]),
            "run_wall_s": walls}
    print(f"real runs: {len(spc['serials'])} serials, {len(chars)} characteristics charted")
    print(f"  in-control serials flagged: {len(real['in_control_serials_flagged'])} of {len(in_control)}"
          f" {real['in_control_serials_flagged']}")
    print(f"  shifts {shifts} in {shifted_serials}: found {found}; with the specs of the same features: "
          f"{found_with_feature}")
    print(f"  other characteristics flagged: {false_flags}")
    print(f"  characteristics with a point beyond 3 sigma (plain Shewhart): {real['beyond_3_sigma_characteristics']}")
    n = len(spc["serials"])
    synthetic = _synthetic(len(chars), n, args.shifted, args.trials, [4.0, 6.0, 8.0, 10.0], args.q,
                           np.random.default_rng(20261129))
    print(f"synthetic in-control serials ({synthetic['characteristics']} characteristics x {n} serials, "
          f"{args.trials} trials): parts flagged {100 * synthetic['in_control_parts_flagged']:.1f} %; "
          f"plain 3-sigma would flag {100 * synthetic['in_control_parts_beyond_3_sigma']:.1f} %")
    print(f"  a characteristic shifted in the last {args.shifted} serials, found: {synthetic['shift_found']}")
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps({"real": real, "synthetic": synthetic}, indent=1))
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
