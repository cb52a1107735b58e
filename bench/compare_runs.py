"""Compare two inspection runs result by result: what a refactoring must not change.

    .venv/bin/python bench/compare_runs.py A_RUNS_DIR[:RUN] B_RUNS_DIR[:RUN] [--tol 0]

Each side is a runs directory (its archive.sqlite) and optionally a run id or a unique
prefix of one (default: the last run).  Prints, per spec, every difference of outcome,
decision, tool, value, uncertainty and simulated start and end times (beyond --tol), the
counts by decision on each side and the cycle times; writes the comparison as JSON to
bench/results/compare_runs.json.  Exit 0 when the runs are identical within --tol, 1
otherwise.  Not a timed benchmark: a check.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from collections import Counter
from pathlib import Path

RESULTS = Path(__file__).resolve().parent / "results"
FIELDS = ("outcome", "decision", "tool", "value", "u", "sim_time_start", "sim_time_end")


def _side(text: str):
    from ita.archive import Archive, archive_path

    path, _, ref = text.partition(":")
    archive = Archive.open(archive_path(Path(path)), create=False)
    run_id = archive.resolve(ref) if ref else archive.runs()[-1].id
    return archive, run_id


def _plain(value):
    return getattr(value, "value", value)


def _differs(a, b, tol: float) -> bool:
    if isinstance(a, float) and isinstance(b, float):
        return not (a == b or (math.isnan(a) and math.isnan(b)) or abs(a - b) <= tol)
    return a != b


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("a", help="runs directory[:run] of the first run")
    parser.add_argument("b", help="runs directory[:run] of the second run")
    parser.add_argument("--tol", type=float, default=0.0, help="absolute tolerance on numbers (default 0: exact)")
    args = parser.parse_args(argv)
    (arch_a, run_a), (arch_b, run_b) = _side(args.a), _side(args.b)
    with arch_a, arch_b:
        ra = {r.spec_id: r for r in arch_a.results(run_a)}
        rb = {r.spec_id: r for r in arch_b.results(run_b)}
        info_a, info_b = arch_a.run(run_a), arch_b.run(run_b)
    diffs = []
    for spec_id in sorted(set(ra) | set(rb)):
        a, b = ra.get(spec_id), rb.get(spec_id)
        if a is None or b is None:
            diffs.append({"spec": spec_id, "field": "present", "a": a is not None, "b": b is not None})
            continue
        for f in FIELDS:
            va, vb = _plain(getattr(a, f)), _plain(getattr(b, f))
            if _differs(va, vb, args.tol):
                diffs.append({"spec": spec_id, "field": f, "a": va, "b": vb})
    counts = {"a": dict(Counter(r.status_label for r in ra.values())),
              "b": dict(Counter(r.status_label for r in rb.values()))}
    cycle = {"a": info_a.sim_time, "b": info_b.sim_time}
    print(f"A {args.a} run {run_a}: {len(ra)} results, cycle {cycle['a']}")
    print(f"B {args.b} run {run_b}: {len(rb)} results, cycle {cycle['b']}")
    print(f"counts A {counts['a']}")
    print(f"counts B {counts['b']}")
    by_field = Counter(d["field"] for d in diffs)
    print(f"{len({d['spec'] for d in diffs})} specs differ" + (f" ({dict(by_field)})" if diffs else ""))
    for d in diffs[:60]:
        print(f"  {d['spec']:14} {d['field']:15} {d['a']!s:>24} -> {d['b']!s}")
    RESULTS.mkdir(parents=True, exist_ok=True)
    (RESULTS / "compare_runs.json").write_text(json.dumps(
        {"a": {"ref": args.a, "run": run_a}, "b": {"ref": args.b, "run": run_b}, "tol": args.tol,
         "counts": counts, "cycle_s": cycle, "differences": diffs}, indent=1, default=str) + "\n")
    return 0 if not diffs else 1


if __name__ == "__main__":
    sys.exit(main())
