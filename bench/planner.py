"""Benchmark: the ITA Task Planner against pyperplan on the IPC STRIPS problems.

Runs every problem of ``../shared/pddl/`` (blocksworld, gripper, logistics) through

- the ITA planner (``prolog/pddl.pl`` in a ``swipl`` subprocess, one per problem), and
- pyperplan, greedy best-first search with hFF, in this process,

validates every plan with pyperplan's grounded task (an independent STRIPS simulator),
and prints solved count, plan length and time for both, beside the peer numbers of
``reference_timings.csv`` (measured with PYTHONHASHSEED=0; run this script with that
setting to compare pyperplan's plan lengths one to one).  Times are CPU seconds of the planner's process (ITA: the
swipl child's user+sys, so parsing and grounding are included; pyperplan: process time
of the search call).

    python bench/planner.py [--limit SECONDS] [--only SUBSTRING] [--pddl-dir DIR]

Needs ``swipl`` on the PATH and ``pip install pyperplan``.
"""

from __future__ import annotations

import argparse
import csv
import resource
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
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


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--limit", type=float, default=60.0, help="seconds per problem (ITA)")
    parser.add_argument("--only", default=None, help="only problems whose name contains this")
    parser.add_argument("--pddl-dir", type=Path, default=DEFAULT_PDDL)
    args = parser.parse_args(argv)
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
    if invalid:
        print("INVALID ITA plans:", ", ".join(r[1] for r in invalid))
    return 1 if invalid else 0


if __name__ == "__main__":
    sys.exit(main())
