"""Micro-benchmark of the Prolog bridge: what one call from Python costs.

Times, per call, the median over many calls of

- ``kb.once("system", "true")``: the bridge's floor;
- a fact lookup, ``kb.once("world", "type", "slra_1", Var("T"))``;
- a call with a list of 50 numbers in and out (``lists:append/3``);
- decoding a MACROP lookup's reply text alone;
- the Operation Planner on one bulkhead measurement: MACROP lookup and planning from
  scratch through the facade (``OperationPlanner.plan_measurement``), and their ratio;

each as wall time and as CPU time of this thread (``time.thread_time``), which a busy
machine disturbs less: a call that is preempted shows in its wall time only.  Prints
the figures in microseconds and writes bench/results/bridge.json.

    python bench/bridge.py [--calls N]
"""

from __future__ import annotations

import argparse
import json
import platform
import statistics
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parent.parent
RESULTS = ROOT / "bench" / "results"


def per_call(function: Callable[[], Any], calls: int) -> dict[str, float]:
    """Median wall and thread-CPU microseconds of `calls` calls of `function`."""
    wall, cpu = [], []
    clock, cpu_clock = time.perf_counter, time.thread_time
    for _ in range(calls):
        w0, c0 = clock(), cpu_clock()
        function()
        c1, w1 = cpu_clock(), clock()
        wall.append(w1 - w0)
        cpu.append(c1 - c0)
    return {"wall_us": statistics.median(wall) * 1e6, "cpu_us": statistics.median(cpu) * 1e6}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--calls", type=int, default=5000, help="calls per figure")
    args = parser.parse_args(argv)

    from ita.logic.bridge import KnowledgeBase
    from ita.logic.terms import Var, read_term
    from ita.part.store import load_part
    from ita.planning import OperationPlanner, WorldState
    from ita.specs.io import read_specs

    kb = KnowledgeBase()
    n = args.calls
    numbers = [float(i) for i in range(50)]
    figures: dict[str, dict[str, float]] = {
        "true": per_call(lambda: kb.once("system", "true"), n),
        "fact": per_call(lambda: kb.once("world", "type", "slra_1", Var("T")), n),
        "list_50": per_call(lambda: kb.once("lists", "append", numbers, [], Var("L")), n),
    }
    from ita.sequence.plan import partition_only, planning_context

    chosen = partition_only(planning_context(None, kb=kb)).selections
    specs = [s for s in read_specs(load_part(None).specs_path) if chosen[s.id].tool is not None]
    tools = [chosen[s.id].tool for s in specs]
    with tempfile.TemporaryDirectory() as tmp, OperationPlanner(kb, Path(tmp) / "m.pl") as planner:
        states, state = [], WorldState()
        for spec, tool in zip(specs, tools):  # the learning pass: the executive's chain of states
            states.append(state)
            state = planner.plan_measurement(spec, state, tool).final_state
        picks = range(0, len(specs), max(1, len(specs) // 20))
        lookup = [per_call(lambda i=i: planner.plan_measurement(specs[i], states[i], tools[i]), max(1, n // 20))
                  for i in picks]
        scratch = [per_call(lambda i=i: planner.plan_measurement(specs[i], states[i], tools[i], from_scratch=True),
                            max(1, n // 100)) for i in picks]
    reply = "[[[macrop,0,kb(measured),[t3,'WT-P04-4','WT-P05-1',us_probe_1]]]]"
    figures["read_lookup_reply"] = per_call(lambda: read_term(reply), n)
    for name, rows in (("operation_lookup", lookup), ("operation_scratch", scratch)):
        figures[name] = {k: statistics.median(r[k] for r in rows) for k in ("wall_us", "cpu_us")}
    ratio = {k: figures["operation_scratch"][k] / figures["operation_lookup"][k]
             for k in ("wall_us", "cpu_us")}

    print(f"Prolog bridge, per call (median of {n} calls; operation planner: median over "
          f"{len(picks)} measurements)")
    print(f"{'':34} {'wall us':>9} {'cpu us':>9}")
    for name, figure in figures.items():
        print(f"{name:34} {figure['wall_us']:9.1f} {figure['cpu_us']:9.1f}")
    print(f"{'ratio scratch/lookup':34} {ratio['wall_us']:9.1f} {ratio['cpu_us']:9.1f}")
    RESULTS.mkdir(parents=True, exist_ok=True)
    result = {
        "calls": n,
        "figures_us": figures,
        "operation_ratio": ratio,
        "machine": {"python": platform.python_version(), "processor": platform.machine()},
    }
    (RESULTS / "bridge.json").write_text(json.dumps(result, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
