"""Where a run's wall-clock time goes: `ita inspect` under cProfile, per component.

    .venv/bin/python bench/run.py [--limit 150] [--seed 31] [--whole] [--top 15] [--dump FILE]

Runs one inspection in this process (a fresh runs directory; the stores of ITA_HOME, so
prepare once first for a warm figure) under cProfile and gives every function's own time
to the component of the project that spends it: a function of `ita/` belongs to its
package (`ita/sim` the simulator, `ita/vision`, `ita/path` the path planner, ...); time
spent in a library (numpy, embree, pybullet, SQLite, SWI-Prolog through ctypes) goes to
the project components that called it, in proportion to what each caller spent there.
The profile is of the main thread: work a run hands to its second core (`ita/cores.py`)
shows as the main thread's own half of it, and its waits for the other half under
"second core (waiting)".
Prints the table (wall seconds and share) and the hottest project functions, and writes
bench/results/run_profile.json.  --whole: every measurement (slow).

Benchmarks print figures; they are not timed assertions.
"""

from __future__ import annotations

import argparse
import cProfile
import json
import pstats
import sys
import tempfile
import time
from collections import defaultdict
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
RESULTS = ROOT / "bench" / "results"
PACKAGE = str(ROOT / "ita") + "/"

#: component names of the project's packages (anything else of ita/ under its package name)
NAMES = {"sim": "simulator (ranges, gauge, world)", "vision": "Vision", "robot": "arm execution",
         "kinematics": "kinematics", "path": "path planning", "collision": "collision checks",
         "logic": "Prolog bridge and knowledge bases", "planning": "Operation Planner",
         "executive": "Plan Executive", "archive": "results archive", "toplevel": "Top Level",
         "devices": "device adapters", "diagnosis": "Exception Handler", "sequence": "Sequence Planner",
         "geometry": "Geometric Reasoner", "part": "part and truth", "cli": "command line",
         "scoring": "scoring", "sensors": "sensor models (gauge)", "workcell": "workcell model",
         "cores": "second core (waiting)"}

Func = tuple[str, int, str]


def component(func: Func) -> str | None:
    """The project component a function belongs to, or None (a library's, a built-in)."""
    file = func[0]
    if not file.startswith(PACKAGE):
        return None
    rel = file[len(PACKAGE):]
    top = rel.split("/", 1)[0].removesuffix(".py")
    return NAMES.get(top, top)


def attribute(stats: dict) -> dict[str, float]:
    """Own time of every function given to project components (see the module doc)."""
    memo: dict[Func, dict[str, float]] = {}

    def share(func: Func, seen: frozenset) -> dict[str, float]:
        """How a library function's time splits among components (fractions summing to 1)."""
        if func in memo:
            return memo[func]
        own = component(func)
        if own is not None:
            return {own: 1.0}
        callers = stats[func][4] if func in stats else {}
        weights = {c: v[3] for c, v in callers.items() if c not in seen}
        total = sum(weights.values())
        out: dict[str, float] = defaultdict(float)
        if total <= 0.0:
            out["start-up and other"] = 1.0
        else:
            for caller, w in weights.items():
                for name, f in share(caller, seen | {func}).items():
                    out[name] += f * w / total
        memo[func] = dict(out)
        return memo[func]

    totals: dict[str, float] = defaultdict(float)
    for func, (_cc, _nc, tt, _ct, _callers) in stats.items():
        for name, f in share(func, frozenset()).items():
            totals[name] += tt * f
    return dict(totals)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--limit", type=int, default=150, help="measurements of the run (default 150)")
    parser.add_argument("--whole", action="store_true", help="every measurement of the part")
    parser.add_argument("--seed", type=int, default=31)
    parser.add_argument("--top", type=int, default=15, help="hottest project functions to list")
    parser.add_argument("--dump", type=Path, help="also write the raw profile here (pstats format)")
    args = parser.parse_args(argv)
    from click.testing import CliRunner

    from ita.cli import main as ita

    runs = Path(tempfile.mkdtemp(prefix="ita-bench-run-"))
    cmd = ["inspect", "--seed", str(args.seed), "--runs-dir", str(runs), "--json"]
    if not args.whole:
        cmd[1:1] = ["--limit", str(args.limit)]
    profile = cProfile.Profile()
    t0 = time.perf_counter()
    profile.enable()
    result = CliRunner().invoke(ita, cmd)
    profile.disable()
    wall = time.perf_counter() - t0
    if result.exit_code != 0:
        print(result.output, file=sys.stderr)
        return 1
    summary = json.loads(result.stdout[result.stdout.index("{"):])
    if args.dump:
        profile.dump_stats(str(args.dump))
    stats = pstats.Stats(profile).stats  # type: ignore[attr-defined]
    totals = attribute(stats)
    profiled = sum(totals.values())
    print(f"ita {' '.join(cmd)}: {summary['done']} results, wall {wall:.1f} s "
          f"({1000 * wall / max(summary['done'], 1):.0f} ms a result; profiled {profiled:.1f} s)")
    print(f"{'component':<38} {'wall s':>8} {'share':>7}")
    for name, t in sorted(totals.items(), key=lambda kv: -kv[1]):
        print(f"{name:<38} {t:8.1f} {100 * t / profiled:6.1f}%")
    own = sorted(((v[2], f) for f, v in stats.items() if component(f) is not None), reverse=True)[:args.top]
    print("\nhottest project functions (own time):")
    for tt, f in own:
        print(f"  {tt:7.2f} s  {Path(f[0]).relative_to(ROOT)}:{f[1]} {f[2]}")
    RESULTS.mkdir(parents=True, exist_ok=True)
    out = {"command": cmd, "results": summary["done"], "wall_s": wall, "profiled_s": profiled,
           "components_s": {k: round(v, 3) for k, v in sorted(totals.items(), key=lambda kv: -kv[1])},
           "hottest": [{"own_s": round(tt, 3), "function": f"{Path(f[0]).relative_to(ROOT)}:{f[1]} {f[2]}"}
                       for tt, f in own]}
    (RESULTS / "run_profile.json").write_text(json.dumps(out, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
