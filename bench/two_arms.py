"""One arm against two on the same part: the plan's figures (not a run's).

    python bench/two_arms.py [--part DIR] [--step 0.5] [--out FILE]

Prepares the part as each arm works it (its sequence plan and MKB; reused when current),
allocates the first arm's plan's measurements between the workcell's two arms
(ita.sequence.allocate, each arm's MKB saying what it can place), plays the two arms' moves through the
interference zones (ita.executive.two_arms) and checks the schedule in 3-D (both URDF
arms in pybullet at each sampled moment, ita.sim.arms; a gap of 0 or less is a contact).
Prints the one-arm time, each arm's share, the makespan before and after coordination,
its lower bound, the waits and retreats, the contacts, and the seconds each step took;
then, for each arm stopped for good while it measures half way through the plan, the
hand-over (ita.executive.two_arms.hand_over: what the other takes over, what is lost,
the makespan); writes JSON.

These are planned seconds (the cost model's motion times, a dwell per measurement, the
rack), the same model for one arm and two: a ratio of plans.  Two-arm inspection runs
(the simulator's clock, the seeds' noise and faults) are not built yet, so there is no
per-seed run comparison here.  Figures, not assertions.
"""

from __future__ import annotations

import argparse
import json
import platform
import time
from pathlib import Path

import numpy as np

from ita.executive.two_arms import coordinated, hand_over
from ita.executive.zones import configurations_at
from ita.logic.bridge import KnowledgeBase
from ita.offline.prepare import prepared_arms
from ita.part.store import load_part
from ita.sequence.allocate import allocate
from ita.sim.arms import TwoArms

DEFAULT_OUT = Path(__file__).resolve().parent / "results" / "two_arms.json"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--part", type=Path, default=None, help="a part directory (default: the built-in bulkhead)")
    parser.add_argument("--step", type=float, default=0.5, help="seconds between the sampled moments")
    parser.add_argument("--out", type=Path, default=DEFAULT_OUT)
    args = parser.parse_args()

    t0 = time.perf_counter()
    kb = KnowledgeBase()
    part = load_part(args.part)
    ctx, plan, mkbs = prepared_arms(args.part, kb, part, progress=lambda m: print(f"({m} ...)", flush=True))
    t1 = time.perf_counter()
    allocation = allocate(ctx, plan, mkbs=mkbs)
    t2 = time.perf_counter()
    schedule, jobs, variant = coordinated(ctx, allocation)
    t3 = time.perf_counter()
    times = np.arange(0.0, schedule.makespan_s + args.step, args.step)
    q = configurations_at(schedule, jobs, times)
    with TwoArms(ctx.workcell) as arms:
        gaps = arms.gaps(q[jobs[0].name], q[jobs[1].name])
    t4 = time.perf_counter()

    one = allocation.one_arm_s
    print(f"part {ctx.part_name}: {len(plan.groups)} tool groups, "
          f"{sum(len(g.order) for g in plan.groups)} measurements; seconds are planned (motion, rack, "
          f"a dwell per measurement: {', '.join(f'{c} {d:.2f} s' for c, d in sorted(allocation.dwell_s.items()))})")
    print(f"one arm                      {one:8.1f} s")
    for share in allocation.shares:
        print(f"  {share.arm:8s} share       {share.time_s:8.1f} s  {share.count:5d} measurements "
              f"({', '.join(f'{t} {len(o)}' for t, o, _c in share.groups)})")
    print(f"two arms, allocated          {allocation.makespan_s:8.1f} s  ratio {allocation.makespan_s / one:.3f}  "
          f"(lower bound {allocation.bound_s:.1f} s, gap {allocation.gap_percent:.1f} %)")
    print(f"two arms, through the zones  {schedule.makespan_s:8.1f} s  ratio {schedule.makespan_s / one:.3f}  "
          f"({variant})")
    for arm in schedule.arms:
        print(f"  {arm:8s} busy {schedule.busy_s[arm]:7.1f} s  waiting {schedule.waiting_s[arm]:6.1f} s  "
              f"retreats {schedule.retreats[arm]}")
    contacts = int(np.count_nonzero(gaps <= 0.0))
    print(f"arm-arm: {contacts} contacts in {len(times)} moments (3-D, pybullet), least gap {gaps.min():.3f} m")
    print(f"seconds: prepared plans and MKBs {t1 - t0:.1f}, allocation {t2 - t1:.1f}, coordination {t3 - t2:.1f}, checks {t4 - t3:.1f}")
    downs = {}
    for job in jobs:
        at = next((moved for start, moved, _e, _a, _b, label in schedule.timeline[job.name]
                   if start >= 0.5 * schedule.makespan_s and label in allocation.assigned), None)
        if at is None:
            continue
        h = hand_over(ctx, plan, allocation, schedule, jobs, job.name, at, mkbs)
        downs[job.name] = {"at_s": round(at, 1), "made_before": len(h.done), "handed_over": len(h.handed),
                           "lost": len(h.lost), "makespan_s": round(h.makespan_s, 1)}
        print(f"{job.name} down at {at:6.1f} s: {len(h.done)} made by then, {len(h.handed)} of its own handed "
              f"over, {len(h.lost)} lost; makespan {h.makespan_s:.1f} s")
    args.out.parent.mkdir(parents=True, exist_ok=True)
    result = {
        "machine": platform.platform(), "part": ctx.part_name, "one_arm_s": one,
        "allocation": allocation.as_dict(),
        "coordinated": {"makespan_s": schedule.makespan_s, "ratio_to_one_arm": schedule.makespan_s / one,
                        "variant": variant, "busy_s": schedule.busy_s, "waiting_s": schedule.waiting_s,
                        "retreats": schedule.retreats, "zone_events": len(schedule.events)},
        "arm_arm_contacts": contacts, "moments": len(times), "least_gap_3d_m": float(gaps.min()),
        "down": downs,
        "seconds": {"plan": t1 - t0, "allocation": t2 - t1, "coordination": t3 - t2, "checks": t4 - t3},
    }
    args.out.write_text(json.dumps(result, indent=1))
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
