"""Benchmark SLRA measurement over the bulkhead's specs against the as-built truth.

    python bench/vision.py [--kinds hole_diameter,edge_distance] [--match -LH-] [--limit N] [--part DIR]
                           [--repeats 3] [--seed 0] [--out FILE] [--render DIR] [--pixels N]

For every SLRA spec (or the first N of each kind): the sensor is put at the spec's viewing
pose (roll 0, nominal standoff) plus a random pose error of the arm's repeatability
(per axis sigma = repeatability / 3, rotation sigma 0.05 mrad), scans the window Vision
asks for (`scan_for`), and Vision measures it from the REPORTED (commanded) pose.  A spec
that needs several frames (`frames_for`: a lightening hole's position, whose datum is the
pose) gets them each after its own approach, i.e. with a new pose error, and Vision
averages them (`measure_frames`); the %GRR is of that averaged result.  Each spec is
measured `repeats` times.

Per kind (and per hole role): n, mean and sd of the error against the truth; %GRR = 6 s_r /
tolerance band with s_r the pooled within-spec sd of the repeats (repeatability only); the
decision under ISO 14253-1 with U = 2u as guard band (conforms / does not conform /
uncertain) against the truth's conformance: false accepts (FA) and false rejects (FR);
how often |error| > U and the coverage of U (the share within it; k = 2 promises about 95 %),
the mean U over the tolerance zone; exceptions by reason.  Timing: wall-clock per frame (by pixels) to
simulate and to measure, the simulated frame time and scan time per measurement (the arm's
re-approach moves are not simulated here: `ita inspect` accounts them).  This is scoring: it may read the truth.
Figures, not assertions.
"""

from __future__ import annotations

import argparse
import json
import math
import platform
import time
from collections import Counter, defaultdict
from dataclasses import replace
from pathlib import Path

import numpy as np

from ita.kinematics.tool_poses import measurement_poses
from ita.part.model import Hole
from ita.part.store import load_part
from ita.scoring.truth import true_values
from ita.sensors.slra_frame import ScanGeometry
from ita.sim.slra import SlraParams, SlraScene, pose_error, simulate_frame
from ita.specs.io import read_specs
from ita.specs.model import MeasurementKind as K
from ita.vision.calibration import SlraCalibration
from ita.vision.context import SLRA_KINDS
from ita.vision.for_part import vision_context
from ita.vision.measure import measure_frames
from ita.vision.scan import frames_for, scan_for
from ita.workcell import load_workcell, workcell_for

DEFAULT_OUT = Path(__file__).resolve().parent / "results" / "vision.json"
ROTATION_SIGMA = 0.05e-3


DIAGNOSTICS = ("registered_on", "left_out", "deviation", "shift", "edge_points", "mode", "frames", "budget",
               "calibration_class", "correction")


def _plain(v):
    """A diagnostic as JSON: tuples and arrays as lists of floats, the rest as it is."""
    return [float(x) for x in v] if isinstance(v, (tuple, np.ndarray)) else v


def decide(value: float, big_u: float, low: float, high: float, kind: str = "") -> str:
    """The run's ISO 14253-1 decision (ita.archive.decide; a true position against its upper
    limit only) with guard band U: 'conforms', 'nonconforms' or 'uncertain'."""
    from ita.archive.decision import decide as archive_decide
    from ita.archive.model import BOUNDED_BELOW

    d = archive_decide(value, big_u, low, high, bounded_below=kind in BOUNDED_BELOW).value
    return {"does_not_conform": "nonconforms"}.get(d, d)


def run(kinds, limit, repeats, seed, render_dir=None, match="", pixels=None, part_dir=None, raw=False,
        pose_frames=None):
    part = load_part(part_dir)
    wc = workcell_for(part.directory, part.mesh.bounds) if part_dir is not None else load_workcell()
    specs = read_specs(part.specs_path)
    truth = true_values(part.directory)     # a generated part's truth, else the held mesh's own values
    t0 = time.perf_counter()
    scene = SlraScene.from_truth(part.directory, wc)
    scene_s = time.perf_counter() - t0
    ctx = vision_context(part, wc, specs=specs)
    if raw:      # as the calibration study measures: the measurers' own type-B terms, no correction
        ctx = replace(ctx, calibration=SlraCalibration())
    if pixels is not None:
        ctx = replace(ctx, shape=(pixels, pixels))
    if pose_frames is not None:
        ctx = replace(ctx, pose_datum_frames=pose_frames)
    tool = wc.tool("slra_1")
    params = SlraParams()
    rng = np.random.default_rng(seed)
    chosen, per_kind = [], Counter()
    for s in specs:
        if s.kind in kinds and match in s.id and (limit is None or per_kind[s.kind] < limit):
            chosen.append(s)
            per_kind[s.kind] += 1
    rows, frame_t, scan_t = [], [], []
    sim_t: dict[str, list[float]] = {}
    meas_t: dict[str, list[float]] = {}
    clock = 0.0
    for i, spec in enumerate(chosen):
        geometry = scan_for(spec, ctx)
        plan = frames_for(spec, ctx)
        shapes = [geometry] + [ScanGeometry(plan.shape, geometry.fov_deg)] * (plan.count - 1)
        pose = measurement_poses(wc.part, [spec.point], [spec.normal], tool, rolls=[0.0])[0, 0]
        for rep in range(repeats):
            frames, sim_s, spent = [], [], 0.0
            for g in shapes:        # each frame after its own approach: a new pose error
                true_pose = pose_error(pose, rng, wc.arm.repeatability_m / 3, ROTATION_SIGMA)
                a = time.perf_counter()
                frames.append(simulate_frame(scene, true_pose, g, params, rng, reported_pose=pose, timestamp=clock))
                sim_s.append(time.perf_counter() - a)
                clock += frames[-1].frame_time
                spent += frames[-1].frame_time
            b = time.perf_counter()
            reply = measure_frames(frames, spec, ctx)
            per_frame = (time.perf_counter() - b) / len(frames)
            for g, t in zip(shapes, sim_s):
                key = "x".join(map(str, g.shape))
                sim_t.setdefault(key, []).append(t)
                meas_t.setdefault(key, []).append(per_frame)
            frame_t.append(frames[0].frame_time)
            scan_t.append(spent)
            f = ctx.features.get(spec.feature)
            role = f.role.value if isinstance(f, Hole) else ""
            row = {"spec": spec.id, "kind": spec.kind.value, "role": role, "repeat": rep, "frames": len(frames),
                   "scan_time_s": spent,
                   "truth": truth[spec.id], "low": spec.low_limit, "high": spec.high_limit,
                   "band": spec.tolerance_band, "fov_deg": geometry.fov_deg[0]}
            if reply.ok:
                row.update(value=reply.value, u=reply.uncertainty, error=reply.value - truth[spec.id])
                row.update({k: _plain(reply.diagnostics[k]) for k in DIAGNOSTICS if k in reply.diagnostics})
                if render_dir is not None and rep == 0:
                    from ita.vision.render import render_measurement
                    render_measurement(frames[0], spec, ctx, reply, Path(render_dir) / f"{spec.id}.png")
            else:
                row.update(reason=reply.reason.value, detail=reply.detail)
            rows.append(row)
        if (i + 1) % 50 == 0:
            print(f"  {i + 1}/{len(chosen)} specs", flush=True)
    return rows, {"scene_build_s": scene_s, "sim_s": sim_t, "measure_s": meas_t, "frame_time_s": frame_t,
                  "scan_time_s": scan_t}


def summarize(rows):
    groups = defaultdict(list)
    for r in rows:
        groups[r["kind"]].append(r)
        if r["role"]:
            groups[f"{r['kind']}/{r['role']}"].append(r)
    table = {}
    for name, rs in sorted(groups.items()):
        ok = [r for r in rs if "value" in r]
        err = np.array([r["error"] for r in ok])
        by_spec = defaultdict(list)
        for r in ok:
            by_spec[r["spec"]].append(r)
        ratios = [np.var([r["value"] for r in v], ddof=1) / v[0]["band"] ** 2 for v in by_spec.values() if len(v) > 1]
        grr = 600 * math.sqrt(float(np.mean(ratios))) if ratios else float("nan")
        dec = Counter()
        outside = 0
        for r in ok:
            d = decide(r["value"], 2 * r["u"], r["low"], r["high"], r["kind"])
            true_ok = r["low"] <= r["truth"] <= r["high"]
            dec[d] += 1
            dec["FA"] += d == "conforms" and not true_ok
            dec["FR"] += d == "nonconforms" and true_ok
            outside += abs(r["error"]) > 2 * r["u"]
        table[name] = {
            "n": len(ok), "specs": len({r["spec"] for r in rs}),
            "mean_error": float(err.mean()) if len(err) else float("nan"),
            "sd_error": float(err.std(ddof=1)) if len(err) > 1 else float("nan"),
            "mean_u": float(np.mean([r["u"] for r in ok])) if ok else float("nan"),
            "grr_percent": grr, "conforms": dec["conforms"], "nonconforms": dec["nonconforms"],
            "uncertain": dec["uncertain"], "FA": dec["FA"], "FR": dec["FR"],
            "error_beyond_U": outside,
            "coverage_percent": 100.0 * (1 - outside / len(ok)) if ok else float("nan"),
            "mean_U_over_zone": float(np.mean([2 * r["u"] / r["band"] for r in ok])) if ok else float("nan"),
            "exceptions": dict(Counter(r["reason"] for r in rs if "reason" in r)),
            "frames_per_measurement": float(np.mean([r.get("frames", 1) for r in rs])),
        }
    return table


def print_table(table, timing):
    head = f"{'kind':28s} {'n':>5s} {'mean err':>9s} {'sd err':>8s} {'mean u':>8s} {'%GRR':>6s} " \
           f"{'conf':>5s} {'nonc':>5s} {'unc':>5s} {'FA':>3s} {'FR':>3s} {'>U':>4s} {'cov%':>6s} {'U/zone':>6s}" \
           f"  exceptions"
    print(head)
    print("-" * len(head))
    for name, t in table.items():
        print(f"{name:28s} {t['n']:5d} {t['mean_error']:9.4f} {t['sd_error']:8.4f} {t['mean_u']:8.4f} "
              f"{t['grr_percent']:6.1f} {t['conforms']:5d} {t['nonconforms']:5d} {t['uncertain']:5d} "
              f"{t['FA']:3d} {t['FR']:3d} {t['error_beyond_U']:4d} {t['coverage_percent']:6.1f} "
              f"{t['mean_U_over_zone']:6.3f}  {t['exceptions'] or ''}")
    print()
    for shape in sorted(timing["sim_s"]):
        for key in ("sim_s", "measure_s"):
            v = np.array(timing[key][shape])
            print(f"{shape:8s} {key:10s} wall per frame: mean {v.mean() * 1e3:6.1f} ms, median "
                  f"{np.median(v) * 1e3:6.1f} ms, p95 {np.percentile(v, 95) * 1e3:6.1f} ms ({len(v)} frames)")
        tot = np.array(timing["sim_s"][shape]) + np.array(timing["measure_s"][shape])
        print(f"{shape:8s} simulate + measure: mean {tot.mean() * 1e3:.1f} ms, p95 {np.percentile(tot, 95) * 1e3:.1f} ms")
    scan = np.array(timing["scan_time_s"])
    print(f"simulated frame time (first frame) {np.mean(timing['frame_time_s']):.3f} s; simulated scan time per "
          f"measurement: mean {scan.mean():.3f} s, max {scan.max():.3f} s (re-approach moves not included); "
          f"scene build {timing['scene_build_s']:.2f} s")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--kinds", default=",".join(k.value for k in SLRA_KINDS))
    ap.add_argument("--limit", type=int, default=None, help="at most this many specs per kind")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--out", type=Path, default=DEFAULT_OUT)
    ap.add_argument("--pose-frames", type=int, default=None, help="re-approached frames averaged for a position "
                    "whose datum is the pose (default: Vision's own, POSE_DATUM_FRAMES)")
    ap.add_argument("--raw", action="store_true", help="without the SLRA calibration (the measurers' "
                    "type-B terms, no bias correction), as bench/slra_calibration.py measures")
    ap.add_argument("--part", type=Path, default=None, help="a part directory with an as-built truth "
                    "(default: the built-in bulkhead), e.g. a reference workpiece from `ita part new DIR --seed S`")
    ap.add_argument("--match", default="", help="only specs whose id contains this (e.g. -LH-)")
    ap.add_argument("--render", type=Path, default=None, help="write a PNG per spec (first repeat) here")
    ap.add_argument("--pixels", type=int, default=None,
                    help="override VisionContext.shape with (N, N) (scan_for may still ask for more)")
    args = ap.parse_args()
    kinds = [K.parse(k) for k in args.kinds.split(",") if k.strip()]
    rows, timing = run(kinds, args.limit, args.repeats, args.seed, args.render, args.match, args.pixels, args.part, args.raw,
                       args.pose_frames)
    table = summarize(rows)
    print_table(table, timing)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    def stats(v):
        return {"mean": float(np.mean(v)), "p95": float(np.percentile(v, 95)), "n": len(v)}

    summary_t = {k: stats(v) for k, v in timing.items() if isinstance(v, list) and v}
    summary_t.update({f"{k}_{shape}": stats(v) for k in ("sim_s", "measure_s") for shape, v in timing[k].items()})
    args.out.write_text(json.dumps({
        "machine": platform.platform(), "python": platform.python_version(),
        "args": {"kinds": args.kinds, "match": args.match, "limit": args.limit, "repeats": args.repeats, "seed": args.seed,
                 "pixels": args.pixels},
        "table": table, "timing": {**summary_t, "scene_build_s": timing["scene_build_s"]},
        "rows": rows}, indent=1))
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
