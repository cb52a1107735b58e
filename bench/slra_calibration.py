"""The SLRA calibration study: measure reference workpieces and write the cell's calibration.

    .venv/bin/python bench/slra_calibration.py [--seeds 7,8,9] [--designs 4] [--repeats 2] [--out FILE]

Reference workpieces are bulkheads of other generator seeds (`ita part new DIR --seed S`,
made here in a temporary directory) and, with --designs N, N bulkheads of other designs:
outline, opening, web, flange heights and widths, rib widths and heights, hole sizes and
pitches drawn from wide ranges round the built-in part's (:func:`design_toml`, seeded by
the design's number), so that the study sees how each class's errors change with the
design and not with one layout alone (what the part adds to the errors: the workpiece
term of ISO 15530-3).  Their as-built dimensions are their calibration certificate.  Every spec of the calibrated kinds (ita.vision.calibration.CALIBRATED_KINDS)
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


#: the built-in part's parameter file, the template of the reference designs
TEMPLATE = HERE.parent / "bulkhead" / "part.toml"


def design_toml(number: int) -> str:
    """The part.toml of reference design `number`: the built-in part's with its dimensions
    drawn from wide ranges round it (seeded by `number`; never the built-in part's seed)."""
    import re

    import numpy as np

    rng = np.random.default_rng([number, 15530])
    u = lambda lo, hi: float(rng.uniform(lo, hi))  # noqa: E731
    w = u(1400, 2600)
    h = min(u(0.55, 0.7) * w, 1600.0)
    oh = u(28, 55)
    half = w / 2
    xs = [0.25, 0.52, 0.76] if rng.random() < 0.5 else [0.3, 0.7]
    ys = [[0.0], [-0.28, 0.28], [-0.3, 0.0, 0.3]][int(rng.integers(3))]
    values = {
        ("part", "seed"): str(100_000 + number),
        ("outline", "width"): f"{w:.1f}", ("outline", "height"): f"{h:.1f}",
        ("outline", "corner_radius"): f"{u(0.12, 0.25) * min(w, h):.1f}",
        ("opening", "width"): f"{u(0.35, 0.45) * w:.1f}", ("opening", "height"): f"{u(0.25, 0.32) * h:.1f}",
        ("opening", "corner_radius"): f"{u(0.2, 0.35) * 0.25 * h:.1f}",
        ("web", "thickness"): f"{u(1.8, 3.2):.2f}",
        ("outer_flange", "height"): f"{oh:.1f}", ("outer_flange", "wall_thickness"): f"{u(3.0, 5.0):.2f}",
        ("outer_flange", "cap_width"): f"{u(24, 38):.1f}", ("outer_flange", "cap_thickness"): f"{u(2.6, 3.6):.2f}",
        ("outer_flange", "segments"): str(max(8, round(16 * (w + h) / 4000))),
        ("outer_flange", "fastener_pitch"): f"{u(40, 75):.1f}",
        ("outer_flange", "fastener_diameter"): str([4.8, 5.0, 6.35, 7.94][int(rng.integers(4))]),
        ("inner_flange", "height"): f"{u(0.8, 0.95) * oh:.1f}", ("inner_flange", "cap_width"): f"{u(22, 32):.1f}",
        ("inner_flange", "fastener_pitch"): f"{u(40, 70):.1f}",
        ("inner_flange", "fastener_diameter"): str([4.8, 5.0][int(rng.integers(2))]),
        ("stiffeners", "width"): f"{u(2.2, 4.5):.2f}", ("stiffeners", "height"): f"{u(0.6, 0.8) * oh:.1f}",
        ("stiffeners", "x"): "[" + ", ".join(f"{s * f * half:.1f}" for f in xs for s in (-1, 1)) + "]",
        ("stiffeners", "y"): "[" + ", ".join(f"{f * h:.1f}" for f in ys) + "]",
        ("holes", "tooling_diameter"): str([9.525, 10.0, 12.7, 15.875][int(rng.integers(4))]),
        ("holes", "lightening_max_diameter"): f"{u(120, 200):.1f}",
    }
    text = TEMPLATE.read_text(encoding="utf-8")
    for (section, key), value in values.items():
        start = text.index(f"[{section}]")
        end = text.find("\n[", start + 1)
        end = len(text) if end < 0 else end
        body, n = re.subn(rf"(?m)^{key}\s*=\s*[^#\n]*?(\s*(#|$))", lambda m: f"{key} = {value}" + m.group(1),
                          text[start:end], count=1)
        assert n == 1, (section, key)
        text = text[:start] + body + text[end:]
    return text


def reference_parts(tmp: Path, seeds: list[int], designs: int):
    """(label, part directory) of each reference workpiece, made in `tmp`: the built-in
    design with each of `seeds`, then `designs` other designs (a design the generator's
    limits refuse is drawn again)."""
    from ita.errors import InputError
    from ita.part.store import new_part

    for seed in seeds:
        yield f"seed {seed}", new_part(tmp / f"reference-{seed}", seed=seed)
    number = 0
    for k in range(designs):
        while True:
            number += 1
            params = tmp / f"design-{number}.toml"
            params.write_text(design_toml(number), encoding="utf-8")
            try:
                part = new_part(tmp / f"design-{number}", params_path=params)
            except InputError as exc:
                print(f"design {number} refused by the generator's limits ({str(exc)[:120]}); drawing again",
                      flush=True)
                continue
            yield f"design {number}", part
            break


def study(seeds: list[int], repeats: int, rng_seed: int = 0, designs: int = 0):
    """(calibration, rows): the classes from measuring reference parts of `seeds` and
    `designs` other designs."""
    from ita.vision.calibration import RANDOM_TERMS, CalibrationClass, SlraCalibration

    vision = _bench_vision()
    from ita.vision.calibration import CALIBRATED_KINDS

    rows = []
    with tempfile.TemporaryDirectory(prefix="ita-reference-") as tmp:
        for i, (label, part_dir) in enumerate(reference_parts(Path(tmp), seeds, designs)):
            got, _ = vision.run(set(CALIBRATED_KINDS), None, repeats, rng_seed + 1000 * i + 7, part_dir=part_dir,
                                raw=True)
            rows += [{**r, "reference_seed": label} for r in got]
            print(f"reference {label}: {len(got)} measurements", flush=True)
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
        "made_by": f"bench/slra_calibration.py --seeds {','.join(map(str, seeds))} --designs {designs} "
                   f"--repeats {repeats}",
        "reference_parts": [f"ita part new DIR --seed {s}" for s in seeds]
        + [f"{designs} other designs (bench/slra_calibration.py design_toml)"] * bool(designs),
        "made": datetime.now(timezone.utc).isoformat(timespec="seconds"),
        "failed_frames": sum(1 for r in rows if "error" not in r),
    }
    return SlraCalibration(classes, provenance), rows


def main(argv: list[str] | None = None) -> int:
    from ita.vision.calibration import default_path

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seeds", default="7,8,9", help="generator seeds of the reference workpieces")
    ap.add_argument("--designs", type=int, default=0, help="reference parts of other designs, drawn (design_toml)")
    ap.add_argument("--repeats", type=int, default=2, help="frames per spec, each after its own approach")
    ap.add_argument("--out", type=Path, default=None, help="default: bulkhead/slra_calibration.json")
    ap.add_argument("--rows", type=Path, default=HERE / "results" / "slra_calibration_rows.json")
    args = ap.parse_args(argv)
    seeds = [int(s) for s in args.seeds.split(",") if s.strip()]
    if 1987 in seeds:
        ap.error("seed 1987 is the built-in bulkhead's: a reference must be another part")
    t0 = time.perf_counter()
    cal, rows = study(seeds, args.repeats, designs=args.designs)
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
