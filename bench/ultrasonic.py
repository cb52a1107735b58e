"""Benchmark of the simulated ultrasonic thickness gauge over every thickness spec.

For each web_thickness and flange_thickness spec of the built-in bulkhead: the held
probe (fetched from the rack by the tool changer) is placed at the approach point off the
spec point (a pose found by IK over the probe's rolls, the first whose contact and
approach configurations are collision-free), couplant is squirted, the controller moves
the tip onto the surface (pressed `--press` mm in, with the arm's repeatability error),
the gauge reads, the arm retracts; `--repeats` times.  Each spec is taken with the probe
the part's stored sequence plan takes it with, when there is a current one (`ita
prepare`: the 45-degree us_probe_1, or the probe bent 90 degrees, us_probe_90, where the
MKB found the first one's contact colliding), else with us_probe_1; a spec its probe has
no collision-free pose for here goes to the next probe, after a tool change.
The transit between specs is the path planner's job: the bench places the arm at each
approach point directly.

Reported per kind (and per probe): specs and readings, error against the as-built truth
(mean, sd), %GRR = 6 sigma_repeatability / tolerance band (pooled within-spec sd),
coverage of U (the share of readings whose error lies within U = 2u: k = 2 promises about
95 %), mean U over the tolerance zone, ISO 14253-1 decisions with U from the gauge's
stated uncertainty vs the truth (false accepts, false rejects, uncertain), exception
replies by reason, and the time per reading in the simulated clock (couplant, move in,
pulse, move out) and in wall-clock.  Each probe first reads the calibration block, which
sets the gauge's sound velocity for it, as a run does (`--no-calibration`: the data
sheet's velocity and its 0.15 % uncertainty).  Writes bench/results/ultrasonic.json.  This
is scoring code: it reads the truth.

    python bench/ultrasonic.py [--repeats 3] [--limit N] [--seed 1] [--press 1.5] [--no-calibration]
"""

from __future__ import annotations

import argparse
import json
import platform
import statistics
import sys
import time
from collections import Counter
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
RESULTS = ROOT / "bench" / "results"
KINDS = ("web_thickness", "flange_thickness")
TOOLS = ("us_probe_1", "us_probe_90")   # the tool rules' order: the bent probe where the first cannot touch


def _ready(world, tool):
    """A configuration with the probe 0.3 m off the middle of the part, far from limits."""
    from ita.kinematics import choose_centred, ik_tool, measurement_poses

    poses = measurement_poses(world.cell.part, np.array([[0.0, 0.0, 2.5]]), np.array([[0.0, 0.0, 1.0]]),
                              tool, standoff=0.3)
    q, found = choose_centred(world.model, ik_tool(world.model, poses, tool.tcp.matrix()).flatten_batch())
    assert found[0], "no ready pose"
    return q[0]


def _fetch_probe(world, controller, ready, tool_name):
    """Put the held tool back, pick `tool_name` up from the rack and come back to `ready`;
    returns the seconds taken.  The arm is placed above each slot first (the transit to
    the rack is the path planner's job, as between specs)."""
    from ita.geometry import rack_configurations
    from ita.robot import ToolChanger, from_waypoints

    changer = ToolChanger(controller)
    above = rack_configurations(world.cell)
    time_s = 0.0
    if world.held is not None:
        world.set_q(above[world.cell.slot_of(world.held).name])
        down = changer.put_down()
        if not down.ok:
            raise SystemExit(f"tool put-down failed: {down}")
        time_s += down.time_s
        world.set_q(above[world.cell.slot_of(tool_name).name])
    else:
        world.set_q(ready)
    reply = changer.pick_up(tool_name)
    if not reply.ok:
        raise SystemExit(f"tool pick-up failed: {reply}")
    lift = world.q + np.array([0.0, -0.5, 0.0, 0.0, 0.0, 0.0])
    back = controller.execute(from_waypoints(world.model, [world.q, lift, ready], speed_scale=0.5),
                              command="to ready")
    if not back.ok:
        raise SystemExit(f"move to ready failed: {back}")
    return time_s + reply.time_s + back.time_s


def _configurations(world, tool, spec, q_ref, press_m, max_tries=24):
    """Contact and approach configurations for `spec`, collision-free, or None."""
    from ita.kinematics import approach_poses, ik_tool, measurement_poses, move_time

    model = world.model
    poses = measurement_poses(world.cell.part, np.array([spec.point]), np.array([spec.normal]), tool,
                              standoff=-press_m)[0]                                  # (k, 4, 4)
    far = approach_poses(poses, tool.approach_distance + press_m)
    ik_c = ik_tool(model, poses, tool.tcp.matrix())
    ik_a = ik_tool(model, far, tool.tcp.matrix())
    options = []
    for k in range(len(poses)):
        for qc in ik_c.q[k][ik_c.valid[k]]:
            qa = ik_a.q[k][ik_a.valid[k]]
            if len(qa):
                qa = qa[np.argmin(move_time(model, qc, qa))]
                options.append((float(move_time(model, q_ref, qa)), qc, qa))
    options.sort(key=lambda o: o[0])
    with world.saved_state():
        for _, qc, qa in options[:max_tries]:
            world.set_q(qc)
            if world.contacts():
                continue
            world.set_q(qa)
            if world.contacts():
                continue
            return qc, qa
    return None


def _calibrate(device, gauge) -> dict:
    """The held probe reads the calibration block's step, as a run does before a probe's
    first reading, and the gauge's velocity is set from it (the move to the block is not
    simulated here)."""
    from ita.devices.stations import CAL_BLOCK_U_MM, CAL_STEP_MM
    from ita.sensors.ultrasonic import Reading, interpret, velocity_calibration

    device.dispense()
    reading = interpret(device.pulse_reference(CAL_STEP_MM), gauge.spec)
    cal = velocity_calibration(reading, CAL_STEP_MM, CAL_BLOCK_U_MM, gauge.spec) if isinstance(reading, Reading) \
        else None
    if cal is not None:
        gauge.calibrate(cal)
    return {"block_mm": CAL_STEP_MM, "reading_mm": getattr(reading, "thickness_mm", None),
            "factor": None if cal is None else cal.factor, "u_rel": None if cal is None else cal.u_rel}


def run(repeats: int = 3, limit: int | None = None, seed: int = 1, press_mm: float = 1.5,
        calibrate: bool = True) -> dict:
    from ita.archive.decision import Decision, decide
    from ita.part import truth as truth_mod
    from ita.part.store import load_part
    from ita.robot import RobotController
    from ita.sensors.ultrasonic import UltrasonicGauge
    from ita.sim.ultrasonic import UltrasonicSim
    from ita.sim.world import SimWorld
    from ita.specs.io import read_specs

    part = load_part(None)
    truth = truth_mod.load_truth(part.directory)
    specs = [s for s in read_specs(part.specs_path) if s.kind.value in KINDS]
    if limit:
        specs = specs[:limit]
    press = press_mm / 1000.0
    rows = []
    fetch_s = 0.0
    with SimWorld(seed=seed) as world:
        controller = RobotController(world)
        device = UltrasonicSim(world)
        gauge = UltrasonicGauge(device)
        calibrations: dict[str, dict] = {}
        wall0 = time.perf_counter()
        planned = _planned_tools(part)
        tools = [t for t in TOOLS if any(c.name == t for c in world.cell.tools)]
        todo: list = []
        for tool_name in tools:
            todo += [s for s in specs if planned.get(s.id, tools[0]) == tool_name
                     or (tool_name == tools[0] and planned.get(s.id) not in tools)]
            if not todo:
                continue
            tool = world.cell.tool(tool_name)
            ready = _ready(world, tool)
            fetch_s += _fetch_probe(world, controller, ready, tool_name)
            if calibrate:
                calibrations[tool_name] = _calibrate(device, gauge)
            todo = _measure_with(world, controller, gauge, tool, todo, ready, press, repeats, truth, rows)
        for spec in todo:
            rows.append({"id": spec.id, "kind": spec.kind.value, "tool": None, "nominal": spec.nominal,
                         "low": spec.low_limit, "high": spec.high_limit, "truth": truth.values[spec.id],
                         "readings": [], "u": [], "exceptions": ["no_pose"], "sim_s": [], "wall_s": []})
        wall_total = time.perf_counter() - wall0
        bias = device.velocity_bias
    order = {s.id: i for i, s in enumerate(specs)}
    rows.sort(key=lambda r: order[r["id"]])
    summary = {kind: _summarise([r for r in rows if r["kind"] == kind], decide, Decision) for kind in KINDS}
    for tool_name in TOOLS:
        mine = [r for r in rows if r["tool"] == tool_name]
        if mine:
            summary[tool_name] = _summarise(mine, decide, Decision)
    summary["all"] = _summarise(rows, decide, Decision)
    return {
        "repeats": repeats, "seed": seed, "press_mm": press_mm, "specs": len(specs),
        "tool_fetch_sim_s": round(fetch_s, 3), "wall_total_s": round(wall_total, 2),
        "simulated_velocity_bias": bias, "velocity_calibrations": calibrations, "summary": summary,
        "python": platform.python_version(), "rows": rows,
    }


def _planned_tools(part) -> dict[str, str]:
    """Spec id -> the tool of the part's stored sequence plan ({} without a current one)."""
    from ita.errors import ItaError
    from ita.sequence.plan import specs_digest
    from ita.sequence.store import load_plan

    try:
        plan = load_plan(part.name)
    except ItaError:
        return {}
    if plan is None or plan.specs_digest != specs_digest(part.specs_path):
        return {}
    return {i: g.tool for g in plan.groups for i in g.order}


def _measure_with(world, controller, gauge, tool, specs, ready, press, repeats, truth, rows) -> list:
    """Measure `specs` with the held `tool` (rows appended); returns the specs it has no
    collision-free pose for."""
    from ita.robot import from_waypoints
    from ita.sensors.ultrasonic import GaugeException, Reading, check_expected

    q_ref = ready
    left = []
    for i, spec in enumerate(specs):
        found = _configurations(world, tool, spec, q_ref, press)
        if found is None:
            left.append(spec)
            continue
        row = {"id": spec.id, "kind": spec.kind.value, "tool": tool.name, "nominal": spec.nominal,
               "low": spec.low_limit, "high": spec.high_limit, "truth": truth.values[spec.id],
               "readings": [], "u": [], "exceptions": [], "sim_s": [], "wall_s": []}
        rows.append(row)
        q_contact, q_approach = found
        q_ref = q_approach
        for _ in range(repeats):
            t_sim, t_wall = world.clock.now, time.perf_counter()
            world.set_q(q_approach)
            gauge.apply_couplant()
            move = controller.execute(from_waypoints(world.model, [world.q, q_contact], speed_scale=0.4),
                                      command="move_contact")
            if not move.ok:
                row["exceptions"].append(f"robot_{move.status.value}")
                continue
            reply = check_expected(gauge.measure(), spec.nominal, spec.high_limit - spec.nominal)
            back = controller.execute(from_waypoints(world.model, [world.q, q_approach], speed_scale=0.6),
                                      command="move_retract")
            if isinstance(reply, GaugeException):
                row["exceptions"].append(reply.reason.value)
            elif isinstance(reply, Reading):
                row["readings"].append(reply.thickness_mm)
                row["u"].append(reply.u_mm)
            if not back.ok:
                row["exceptions"].append(f"robot_{back.status.value}")
            row["sim_s"].append(world.clock.now - t_sim)
            row["wall_s"].append(time.perf_counter() - t_wall)
        if (i + 1) % 20 == 0:
            print(f"  {i + 1}/{len(specs)} specs with {tool.name}", file=sys.stderr, flush=True)
    return left


def _summarise(rows: list[dict], decide, Decision) -> dict:
    errors, within, decisions = [], [], Counter()
    covered, u_over_zone = [], []
    fa = fr = 0
    exceptions = Counter()
    sim_s, wall_s = [], []
    band = None
    for r in rows:
        exceptions.update(r["exceptions"])
        sim_s += r["sim_s"]
        wall_s += r["wall_s"]
        band = r["high"] - r["low"]
        truth_ok = r["low"] <= r["truth"] <= r["high"]
        for value, u in zip(r["readings"], r["u"]):
            errors.append(value - r["truth"])
            covered.append(abs(value - r["truth"]) <= 2.0 * u)
            u_over_zone.append(2.0 * u / (r["high"] - r["low"]))
            d = decide(value, 2.0 * u, r["low"], r["high"])
            decisions[d.value] += 1
            fa += d is Decision.CONFORMS and not truth_ok
            fr += d is Decision.DOES_NOT_CONFORM and truth_ok
        if len(r["readings"]) >= 2:
            within.append(statistics.variance(r["readings"]))
    sd_rep = float(np.sqrt(np.mean(within))) if within else float("nan")
    n_read = len(errors)
    return {
        "specs": len(rows),
        "specs_out_of_tolerance": sum(not (r["low"] <= r["truth"] <= r["high"]) for r in rows),
        "readings": n_read,
        "mean_error_mm": float(np.mean(errors)) if errors else float("nan"),
        "sd_error_mm": float(np.std(errors, ddof=1)) if n_read > 1 else float("nan"),
        "repeatability_sd_mm": sd_rep,
        "grr_percent": 100.0 * 6.0 * sd_rep / band if band else float("nan"),
        "coverage_percent": 100.0 * float(np.mean(covered)) if covered else float("nan"),
        "mean_U_over_zone": float(np.mean(u_over_zone)) if u_over_zone else float("nan"),
        "conforms": decisions["conforms"], "does_not_conform": decisions["does_not_conform"],
        "uncertain": decisions["uncertain"], "false_accepts": fa, "false_rejects": fr,
        "exceptions": dict(exceptions),
        "sim_s_per_reading": float(np.mean(sim_s)) if sim_s else float("nan"),
        "wall_ms_per_reading": 1000.0 * float(np.mean(wall_s)) if wall_s else float("nan"),
    }


def _print(result: dict) -> None:
    cols = ("kind", "specs", "reads", "mean err um", "sd um", "rep sd um", "%GRR", "cover %", "U/zone", "conf",
            "nonconf", "uncert", "FA", "FR", "exceptions", "sim s/rd", "wall ms/rd")
    print(" | ".join(cols))
    for kind, s in result["summary"].items():
        exc = ", ".join(f"{k}:{v}" for k, v in sorted(s["exceptions"].items())) or "-"
        print(" | ".join([
            kind, str(s["specs"]), str(s["readings"]), f"{1000 * s['mean_error_mm']:.2f}",
            f"{1000 * s['sd_error_mm']:.2f}", f"{1000 * s['repeatability_sd_mm']:.2f}",
            f"{s['grr_percent']:.1f}", f"{s['coverage_percent']:.1f}", f"{s['mean_U_over_zone']:.3f}",
            str(s["conforms"]), str(s["does_not_conform"]), str(s["uncertain"]),
            str(s["false_accepts"]), str(s["false_rejects"]),
            exc, f"{s['sim_s_per_reading']:.2f}", f"{s['wall_ms_per_reading']:.1f}"]))
    print(f"specs out of tolerance (truth): {result['summary']['all']['specs_out_of_tolerance']}; "
          f"simulated velocity bias {100 * result['simulated_velocity_bias']:+.3f} %; "
          f"tool fetch {result['tool_fetch_sim_s']:.1f} s simulated; wall total {result['wall_total_s']:.1f} s")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--limit", type=int, default=None, help="only the first N thickness specs")
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--press", type=float, default=1.5, help="mm the tip is pressed in")
    parser.add_argument("--out", type=Path, default=RESULTS / "ultrasonic.json")
    parser.add_argument("--no-calibration", action="store_true",
                        help="no velocity calibration on the block: the data sheet's velocity uncertainty")
    args = parser.parse_args(argv)
    result = run(args.repeats, args.limit, args.seed, args.press, calibrate=not args.no_calibration)
    _print(result)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(result, indent=1))
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
