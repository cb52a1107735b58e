"""The SLRA calibration study: measure reference workpieces and write the cell's calibration.

    .venv/bin/python bench/slra_calibration.py [--seeds 7,8,9] [--repeats 2] [--out FILE]

Reference workpieces are bulkheads of other generator seeds (`ita part new DIR --seed S`,
made here in a temporary directory): their as-built dimensions are their calibration
certificate.  Every spec of the calibrated kinds (ita.vision.calibration.CALIBRATED_KINDS)
is measured `repeats` times, each frame after its own approach (a new draw of the arm's pose
error), without any calibration (bench/vision.py --raw); per class: the bias, the scatter,
the frames' own random part and the u a result of the class gets.  Writes the calibration
(default bulkhead/slra_calibration.json, which Vision loads) with how it was made.

This is a calibration, not scoring: it reads the references' truth, never the part a run
inspects.  The seeds must differ from the inspected part's (the built-in bulkhead's is
1987), or the study would have seen the part it is used on.
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import platform
import sys
import tempfile
import time
from collections import defaultdict
from datetime import datetime, timezone
from pathlib import Path

HERE = Path(__file__).resolve().parent


def _bench_vision():
    spec = importlib.util.spec_from_file_location("bench_vision", HERE / "vision.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def study(seeds: list[int], repeats: int, rng_seed: int = 0):
    """(calibration, rows): the classes from measuring reference parts of `seeds`."""
    from ita.part.store import new_part
    from ita.vision.calibration import RANDOM_TERMS, CalibrationClass, SlraCalibration

    vision = _bench_vision()
    from ita.vision.calibration import CALIBRATED_KINDS

    rows = []
    with tempfile.TemporaryDirectory(prefix="ita-reference-") as tmp:
        for seed in seeds:
            part_dir = new_part(Path(tmp) / f"reference-{seed}", seed=seed)
            got, _ = vision.run(set(CALIBRATED_KINDS), None, repeats, rng_seed + seed, part_dir=part_dir, raw=True)
            rows += [{**r, "reference_seed": seed} for r in got]
            print(f"reference seed {seed}: {len(got)} measurements", flush=True)
    errors: dict[str, list[float]] = defaultdict(list)
    frames: dict[str, list[float]] = defaultdict(list)
    features: dict[str, set] = defaultdict(set)
    for r in rows:
        name = r.get("calibration_class")
        if name is None or "error" not in r:
            continue
        errors[name].append(r["error"])
        budget = r.get("budget") or {}
        frames[name].append(sum(budget.get(t, 0.0) ** 2 for t in RANDOM_TERMS) ** 0.5)
        features[name].add((r["reference_seed"], r["spec"]))
    classes = {n: CalibrationClass.from_errors(n, errors[n], frames[n], len(features[n])) for n in sorted(errors)}
    provenance = {
        "what": "SLRA calibration on reference workpieces (ita.vision.calibration)",
        "made_by": f"bench/slra_calibration.py --seeds {','.join(map(str, seeds))} --repeats {repeats}",
        "reference_parts": [f"ita part new DIR --seed {s}" for s in seeds],
        "made": datetime.now(timezone.utc).isoformat(timespec="seconds"),
        "failed_frames": sum(1 for r in rows if "error" not in r),
    }
    return SlraCalibration(classes, provenance), rows


def main(argv: list[str] | None = None) -> int:
    from ita.vision.calibration import default_path

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seeds", default="7,8,9", help="generator seeds of the reference workpieces")
    ap.add_argument("--repeats", type=int, default=2, help="frames per spec, each after its own approach")
    ap.add_argument("--out", type=Path, default=None, help="default: bulkhead/slra_calibration.json")
    ap.add_argument("--rows", type=Path, default=HERE / "results" / "slra_calibration_rows.json")
    args = ap.parse_args(argv)
    seeds = [int(s) for s in args.seeds.split(",") if s.strip()]
    if 1987 in seeds:
        ap.error("seed 1987 is the built-in bulkhead's: a reference must be another part")
    t0 = time.perf_counter()
    cal, rows = study(seeds, args.repeats)
    out = args.out or default_path()
    out.write_text(json.dumps(cal.to_dict(), indent=1) + "\n", encoding="utf-8")
    args.rows.parent.mkdir(parents=True, exist_ok=True)
    args.rows.write_text(json.dumps({"machine": platform.node(), "rows": rows}, default=str) + "\n")
    print(f"{'class':40} {'frames':>6} {'feat':>5} {'bias um':>8} {'scatter':>8} {'frame rms':>9} {'u um':>6}")
    for name, c in sorted(cal.classes.items()):
        print(f"{name:40} {c.frames:6d} {c.features:5d} {1000 * c.bias:8.2f} {1000 * c.scatter:8.2f} "
              f"{1000 * c.u_frame_rms:9.2f} {1000 * c.u:6.2f}")
    print(f"wrote {out} in {time.perf_counter() - t0:.0f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
