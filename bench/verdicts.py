"""Score one inspection run against the part's as-built truth, per measurement kind.

    .venv/bin/python bench/verdicts.py RUNS_DIR[:RUN] [--part DIR] [--out FILE] [--all]

For each kind (and over the whole run): counts by decision, the share uncertain and the
share decided, false accepts and false rejects, the coverage of U (the share of results
whose error against the truth lies within U; k = 2 promises about 95 %), the mean and
standard deviation of the error, the standard deviation of error / U (0.5 for an honest
k = 2 with normal errors) and the mean U over the tolerance zone.  The verdicts issue's
targets are checked and printed: overall coverage 93..98 %, at least 90 % per kind, at
most 99.5 % for a kind with 150 or more results, at most 2 % uncertain, at least 90 % of
each kind decided, 0 false accepts.  --all pools every run of the directory (a small
part's few values per run settle no coverage; several simulator seeds do).  Scoring: it
reads the truth.  Figures, not
assertions; writes JSON (default bench/results/verdicts.json).
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from collections import Counter, defaultdict
from pathlib import Path

RESULTS = Path(__file__).resolve().parent / "results"


def _open(text: str):
    from ita.archive import Archive, archive_path

    path, _, ref = text.partition(":")
    archive = Archive.open(archive_path(Path(path)), create=False)
    run_id = archive.resolve(ref) if ref else archive.runs()[-1].id
    return archive, run_id


def _label(r) -> str:
    d = getattr(r.decision, "value", r.decision)
    return d if d else getattr(r.outcome, "value", str(r.outcome))


def figures(rows: list[tuple[object, float]]) -> dict:
    """The figures of one group of (result, true value) pairs."""
    counts = Counter(_label(r) for r, _ in rows)
    measured = [(r, t) for r, t in rows if r.value is not None and r.u]
    err = [r.value - t for r, t in measured]
    norm = [(r.value - t) / r.U for r, t in measured]
    zone = [r.U / (r.high_limit - r.low_limit) for r, _ in measured if r.high_limit > r.low_limit]
    fa = [r.spec_id for r, t in rows if _label(r) == "conforms" and not r.low_limit <= t <= r.high_limit]
    fr = [r.spec_id for r, t in rows if _label(r) == "does_not_conform" and r.low_limit <= t <= r.high_limit]
    n = len(rows)
    decided = counts.get("conforms", 0) + counts.get("does_not_conform", 0)

    def sd(xs):
        if len(xs) < 2:
            return math.nan
        m = sum(xs) / len(xs)
        return math.sqrt(sum((x - m) ** 2 for x in xs) / (len(xs) - 1))

    return {"n": n, "counts": dict(counts), "uncertain_percent": 100.0 * counts.get("uncertain", 0) / n if n else 0,
            "decided_percent": 100.0 * decided / n if n else 0, "false_accepts": fa, "false_rejects": fr,
            "measured": len(measured),
            "coverage_percent": 100.0 * sum(abs(x) <= 1.0 for x in norm) / len(norm) if norm else math.nan,
            "error_mean_mm": sum(err) / len(err) if err else math.nan, "error_sd_mm": sd(err),
            "sd_error_over_U": sd(norm), "mean_U_over_zone": sum(zone) / len(zone) if zone else math.nan}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("run", help="runs directory[:run] (default run: the last)")
    parser.add_argument("--part", type=Path, default=None, help="part directory (default: the run's own)")
    parser.add_argument("--out", type=Path, default=RESULTS / "verdicts.json")
    parser.add_argument("--all", action="store_true", help="pool every run of the runs directory")
    args = parser.parse_args(argv)
    from ita.part.store import load_part
    from ita.scoring.truth import run_part_truth, true_values

    archive, run_id = _open(args.run)
    rows, results = [], []
    with archive:
        for rid in [r.id for r in archive.runs()] if args.all else [run_id]:
            info = archive.run(rid)
            mine = archive.results(rid)
            part_dir = args.part or (Path(info.part_dir) if info.part_dir else load_part(None).directory)
            truth = true_values(run_part_truth(part_dir, dict(info.settings)) or part_dir)
            rows += [(r, truth[r.spec_id]) for r in mine if r.spec_id in truth]
            results += mine
    if args.all:
        run_id = f"{run_id} and every run before it in {args.run.partition(':')[0]}"
    by_kind: dict[str, list] = defaultdict(list)
    for r, t in rows:
        by_kind[r.kind or "?"].append((r, t))
    table = {k: figures(v) for k, v in sorted(by_kind.items())}
    whole = figures(rows)
    checks = {
        "0 false accepts": not whole["false_accepts"],
        "at most 2 % uncertain": whole["uncertain_percent"] <= 2.0,
        "at least 90 % of each kind decided": all(f["decided_percent"] >= 90.0 for f in table.values()),
        "coverage 93..98 % over the run": 93.0 <= whole["coverage_percent"] <= 98.0,
        "coverage >= 90 % per kind": all(not f["measured"] or f["coverage_percent"] >= 90.0 for f in table.values()),
        "coverage <= 99.5 % per kind of >= 150": all(f["measured"] < 150 or f["coverage_percent"] <= 99.5
                                                     for f in table.values()),
        "0 cannot be done": whole["counts"].get("cannot_be_done", 0) == 0,
    }
    print(f"run {run_id} ({info.status.value if hasattr(info.status, 'value') else info.status}), "
          f"{len(results)} results, {len(rows)} with a true value, cycle {info.sim_time or 0:.0f} s")
    head = f"{'kind':22} {'n':>5} {'conf':>5} {'nonc':>5} {'unc':>4} {'other':>5} {'FA':>3} {'FR':>3} " \
           f"{'cov%':>6} {'mean e':>8} {'sd e':>7} {'sd e/U':>6} {'U/zone':>6}"
    print(head)
    for name, f in [*table.items(), ("ALL", whole)]:
        c = f["counts"]
        other = f["n"] - c.get("conforms", 0) - c.get("does_not_conform", 0) - c.get("uncertain", 0)
        print(f"{name:22} {f['n']:5d} {c.get('conforms', 0):5d} {c.get('does_not_conform', 0):5d} "
              f"{c.get('uncertain', 0):4d} {other:5d} {len(f['false_accepts']):3d} {len(f['false_rejects']):3d} "
              f"{f['coverage_percent']:6.1f} {1000 * f['error_mean_mm']:7.1f}u {1000 * f['error_sd_mm']:6.1f}u "
              f"{f['sd_error_over_U']:6.2f} {f['mean_U_over_zone']:6.3f}")
    for name, ok in checks.items():
        print(f"  {'yes' if ok else 'NO ':3} {name}")
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps({"run": run_id, "cycle_s": info.sim_time, "kinds": table, "all": whole,
                                    "checks": checks}, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
