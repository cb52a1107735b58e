"""Benchmark of the HTN planner on the total-order IPC 2020 instances of ``../shared/hddl/``.

For every problem of every domain folder (``domain.hddl`` beside its problems):

- ITA: ``prolog/hddl.pl`` + ``prolog/htn.pl`` in a ``swipl`` child per problem (as
  ``ita htn solve`` runs it), killed at the per-instance limit; its plan is checked by
  the independent verifier (ita/htn/verify.py).  Time: the child's wall time, from
  start to answer (reading and swipl's start-up included);
- the peer, in this process: Aries through the Unified Planning framework (``pip install
  unified-planning up-aries``; the Aries binary ships in the wheel and runs as a local
  server process, nothing is downloaded), on the same files read by UP's HDDL reader,
  with the same limit.  Its plans are not re-verified here.

Prints coverage and time per domain beside the IPC 2020 published figures, and writes
``bench/results/htn_ipc.json`` (or ``--out``).

    python bench/htn_ipc.py [--limit SECONDS] [--only SUBSTRING] [--no-peer]
                            [--hddl-dir DIR] [--out FILE]
"""

from __future__ import annotations

import argparse
import json
import platform
import statistics
import time
from dataclasses import asdict, dataclass
from pathlib import Path

from ita.htn import format_ipc, solve_hddl
from ita.htn.verify import verify_files

ROOT = Path(__file__).resolve().parent.parent
RESULTS = ROOT / "bench" / "results"
DEFAULT_HDDL = ROOT.parent / "shared" / "hddl"

#: IPC 2020, total-order track: (instances in the track, HyperTensioN's score, Lilotane's
#: score) per domain, from the table of HyperTensioN's docs/IPC.md (the organisers'
#: "results-fixed"; the IPC's agile score: 1 for a plan within 1 s, falling with log time
#: to 0 at 1800 s).  A score is not a coverage; a score equal to the instance count means
#: every instance was solved.  The exact per-planner coverage was not found.
IPC2020 = {
    "Barman-BDI": (20, 20.0, 16.0),
    "Blocksworld-GTOHP": (30, 16.0, 22.1),
    "Robot": (20, 20.0, 11.0),
    "Rover-GTOHP": (30, 30.0, 21.3),
    "Satellite-GTOHP": (20, 20.0, 15.0),
    "Snake": (20, 20.0, 17.1),
    "Towers": (20, 17.0, 10.0),
    "Transport": (40, 40.0, 35.0),
}


@dataclass(frozen=True)
class Outcome:
    """One planner on one problem."""

    solved: bool
    seconds: float
    length: int | None = None
    valid: bool | None = None
    note: str = ""


def problems(hddl_dir: Path, only: str | None) -> list[tuple[str, Path, Path]]:
    """(domain name, domain file, problem file) of every instance, in name order."""
    found = []
    for domain in sorted(hddl_dir.glob("*/domain.hddl")):
        for problem in sorted(domain.parent.glob("*.hddl")):
            if problem.name == "domain.hddl" or (only and only not in f"{domain.parent.name}/{problem.name}"):
                continue
            found.append((domain.parent.name, domain, problem))
    return found


def run_ita(domain: Path, problem: Path, limit: float) -> Outcome:
    outcome = solve_hddl(domain, problem, time_limit=limit)
    if outcome.plan is None:
        return Outcome(False, outcome.seconds, note=outcome.explain())
    problems_found = verify_files(domain, problem, format_ipc(outcome.plan))
    return Outcome(True, outcome.seconds, len(outcome.plan.actions), not problems_found,
                   problems_found[0] if problems_found else "")


class Aries:
    """Aries through Unified Planning, in this process."""

    def __init__(self) -> None:
        from unified_planning.io import PDDLReader
        from unified_planning.shortcuts import OneshotPlanner, get_environment

        get_environment().credits_stream = None
        self.reader = PDDLReader
        self.planner_factory = OneshotPlanner

    def run(self, domain: Path, problem: Path, limit: float) -> Outcome:
        start = time.monotonic()
        try:
            task = self.reader().parse_problem(str(domain), str(problem))
            with self.planner_factory(name="aries") as planner:
                result = planner.solve(task, timeout=limit)
        except Exception as exc:  # a peer's failure is a figure of the bench, not its end
            return Outcome(False, time.monotonic() - start, note=f"{type(exc).__name__}: {str(exc)[:120]}")
        seconds = time.monotonic() - start
        solved = result.plan is not None and "SOLVED" in result.status.name
        return Outcome(solved, seconds, _length(result.plan) if solved else None, None,
                       "" if solved else result.status.name)


def _length(plan: object) -> int | None:
    """The number of actions of a UP plan (hierarchical, sequential or time-triggered)."""
    inner = getattr(plan, "action_plan", plan)
    for attribute in ("actions", "timed_actions"):
        if hasattr(inner, attribute):
            return len(getattr(inner, attribute))
    return None


def peer() -> Aries | None:
    try:
        return Aries()
    except ImportError:
        return None


def summary(rows: list[dict[str, object]], key: str) -> dict[str, dict[str, object]]:
    per: dict[str, dict[str, object]] = {}
    for name in sorted({str(r["domain"]) for r in rows}):
        mine = [r[key] for r in rows if r["domain"] == name and r.get(key)]
        solved = [o for o in mine if o["solved"]]  # type: ignore[index]
        times = [float(o["seconds"]) for o in solved]  # type: ignore[index]
        per[name] = {
            "instances": sum(1 for r in rows if r["domain"] == name),
            "solved": len(solved),
            "valid": sum(1 for o in solved if o.get("valid")),  # type: ignore[union-attr]
            "median_s": round(statistics.median(times), 3) if times else None,
            "max_s": round(max(times), 3) if times else None,
        }
    return per


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--limit", type=float, default=60.0, help="seconds per instance and planner")
    parser.add_argument("--only", default=None, help="only the instances whose Domain/problem contains this")
    parser.add_argument("--no-peer", action="store_true", help="run the ITA planner alone")
    parser.add_argument("--hddl-dir", type=Path, default=DEFAULT_HDDL)
    parser.add_argument("--out", type=Path, default=RESULTS / "htn_ipc.json")
    args = parser.parse_args()

    instances = problems(args.hddl_dir, args.only)
    if not instances:
        raise SystemExit(f"no HDDL instances under {args.hddl_dir}")
    aries = None if args.no_peer else peer()
    if aries is None and not args.no_peer:
        print("peer: unified-planning / up-aries not installed (pip install unified-planning up-aries); ITA alone")
    rows: list[dict[str, object]] = []
    print(f"{'instance':40} {'ITA':>22} {'Aries (UP)':>22}")
    for name, domain, problem in instances:
        ita = run_ita(domain, problem, args.limit)
        other = aries.run(domain, problem, args.limit) if aries else None
        rows.append({"domain": name, "problem": problem.name, "ita": asdict(ita),
                     "aries": asdict(other) if other else None})
        print(f"{name + '/' + problem.name:40} {_cell(ita):>22} {_cell(other) if other else '-':>22}", flush=True)

    ita_sum = summary(rows, "ita")
    aries_sum = summary(rows, "aries") if aries else {}
    print()
    print(f"{'domain':18} {'n':>3} | {'ITA solved':>10} {'valid':>5} {'median s':>8} {'max s':>7} | "
          f"{'Aries':>5} {'median s':>8} | IPC 2020 (track size, HyperTensioN, Lilotane agile scores)")
    for name, s in ita_sum.items():
        a = aries_sum.get(name, {})
        ipc = IPC2020.get(name)
        print(f"{name:18} {s['instances']:>3} | {s['solved']:>10} {s['valid']:>5} {_num(s['median_s']):>8} "
              f"{_num(s['max_s']):>7} | {a.get('solved', '-'):>5} {_num(a.get('median_s')):>8} | "
              f"{'%d, %.1f, %.1f' % ipc if ipc else 'not in the table'}")
    total = sum(int(s["solved"]) for s in ita_sum.values())  # type: ignore[call-overload]
    print(f"ITA: {total}/{len(rows)} solved, {sum(int(s['valid']) for s in ita_sum.values())} verified"  # type: ignore[call-overload]
          + (f"; Aries: {sum(int(s['solved']) for s in aries_sum.values())}/{len(rows)}" if aries else ""))  # type: ignore[call-overload]
    print("IPC 2020 figures: agile scores (not coverage) over the whole track, from HyperTensioN's "
          "docs/IPC.md; the instances here are the smallest few of each domain.")

    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps({
        "limit_s": args.limit, "machine": platform.platform(), "python": platform.python_version(),
        "instances": rows, "ita": ita_sum, "aries": aries_sum,
        "ipc2020_agile_scores": {k: {"track_instances": v[0], "hypertension": v[1], "lilotane": v[2]}
                                 for k, v in IPC2020.items()},
    }, indent=1) + "\n")
    print(f"wrote {args.out}")


def _cell(o: Outcome | None) -> str:
    if o is None:
        return "-"
    if not o.solved:
        return f"no ({o.seconds:.2f} s)"
    mark = "" if o.valid is None else (" ok" if o.valid else " INVALID")
    return f"{o.length} steps {o.seconds:.2f} s{mark}"


def _num(x: object) -> str:
    return "-" if x is None else f"{x}"


if __name__ == "__main__":
    main()
