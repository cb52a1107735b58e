"""Benchmark collision-query throughput: the region tree beside python-fcl and pybullet.

    python bench/collision.py [--points N] [--configs N] [--out FILE]

One scene for all three: the workcell's boxes, the parked tools' boxes and the built-in
bulkhead (the tree: its conservative regions, part margin 2 mm; fcl and pybullet: its exact
triangle mesh); for arm configurations the arm's URDF tubes (pybullet: its own cylinders
and capsules; the tree: enclosing capsules).  Queries are points and short segments near
the part and the boxes and anywhere in the cell, and uniform random joint configurations.

Per second figures (CPU wall time, one thread):
- points: tree batch `points_hit`; fcl a 0.1 um sphere per point through its broadphase;
  pybullet a 0.1 mm sphere body moved to each point, performCollisionDetection.
- segments: tree batch `segments_hit`; fcl a 0.1 um capsule per segment; pybullet
  rayTestBatch both ways (it does not see segments that start inside a box).
- arm: tree `ArmChecker.collides` on precomputed link segments, and with the batched FK
  of ita.kinematics.fk (when importable) included; fcl the ten link capsules against the
  scene per configuration (world only, no self check; link segments precomputed); pybullet
  six resetJointState plus the whole-scene performCollisionDetection and getContactPoints.
The first tree call (numba compile or cache load) is timed separately.  Figures, not
assertions.  Also reports, against pybullet / fcl, missed collisions and false positives.
"""

from __future__ import annotations

import argparse
import json
import platform
import time
from pathlib import Path

import numpy as np
import trimesh

from ita.collision import ArmChecker, build_tree
from ita.collision.reference import BulletScene, FclScene, urdf_tubes
from ita.part.store import load_part
from ita.workcell import load_workcell

DEFAULT_OUT = Path(__file__).resolve().parent / "results" / "collision.json"


def _timed(fn, *args, repeat: int = 1):
    best, out = np.inf, None
    for _ in range(repeat):
        t = time.perf_counter()
        out = fn(*args)
        best = min(best, time.perf_counter() - t)
    return out, best


def _queries(cell, part, rng, n):
    surf, _ = trimesh.sample.sample_surface(part.mesh, n // 3, seed=1)
    near_part = cell.part.to_world(surf) + rng.normal(size=(n // 3, 3)) * 0.01
    boxes = cell.static_boxes()
    pick = rng.integers(len(boxes), size=n // 3)
    local = rng.uniform(-0.55, 0.55, (n // 3, 3))
    near_box = np.array([boxes[k].pose.matrix()[:3, :3] @ (np.array(boxes[k].size) * l) + boxes[k].pose.position
                         for k, l in zip(pick, local)])
    anywhere = rng.uniform([-0.5, -2.9, -0.1], [3.3, 2.9, 2.5], (n - 2 * (n // 3), 3))
    p0 = np.vstack([near_part, near_box, anywhere])
    p1 = p0 + rng.normal(size=p0.shape) * rng.uniform(0.0, 0.1, (len(p0), 1))
    return p0, p1


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--points", type=int, default=30000, help="tree queries per kind (peers get a tenth)")
    ap.add_argument("--configs", type=int, default=20000, help="arm configurations for the tree (peers a tenth)")
    ap.add_argument("--out", type=Path, default=DEFAULT_OUT)
    args = ap.parse_args()

    cell, part = load_workcell(), load_part(None)
    (tree, t_build) = _timed(build_tree, cell, part)
    rng = np.random.default_rng(0)
    p0, p1 = _queries(cell, part, rng, args.points)
    m = max(1, args.points // 10)
    rows, checks = [], {}
    _, t_first = _timed(tree.points_hit, p0[:10])

    def row(kind, method, n, seconds, note=""):
        rows.append({"query": kind, "method": method, "n": int(n), "seconds": seconds, "per_second": n / seconds,
                     "note": note})

    hp, t = _timed(tree.points_hit, p0, repeat=3)
    row("points", "region tree", len(p0), t)
    hs, t = _timed(tree.segments_hit, p0, p1, repeat=3)
    row("segments", "region tree", len(p0), t)

    fcl_scene = None
    try:
        fcl_scene = FclScene(cell, part.mesh)
    except ImportError:
        print("python-fcl not installed (pip install python-fcl): fcl columns skipped")
    in_material = part.mesh.contains(cell.part.to_part(p0[:m]))
    if fcl_scene is not None:
        ref, t = _timed(fcl_scene.points_hit, p0[:m])
        row("points", "python-fcl", m, t)
        ref |= in_material
        checks["points_vs_fcl"] = {"missed": int(np.sum(ref & ~hp[:m])),
                                   "false_positive_rate": float(np.sum(hp[:m] & ~ref) / max(1, np.sum(~ref)))}
        ref, t = _timed(fcl_scene.segments_hit, p0[:m], p1[:m])
        row("segments", "python-fcl", m, t)
        checks["segments_vs_fcl"] = {"missed": int(np.sum(ref & ~hs[:m])),
                                     "false_positive_rate": float(np.sum(hs[:m] & ~ref) / max(1, np.sum(~ref)))}

    lo, hi = np.array(cell.arm.joints.lower), np.array(cell.arm.joints.upper)
    q = rng.uniform(lo, hi, (args.configs, 6))
    k = max(1, args.configs // 10)
    links, ends, radii, _ = urdf_tubes(cell.arm.urdf, BulletScene.LINKS)
    with BulletScene(cell, part.mesh) as scene:
        _, t = _timed(scene.points_hit, p0[:m])
        row("points", "pybullet", m, t, "sphere body + performCollisionDetection")
        _, t = _timed(scene.segments_hit, p0, p1)
        row("segments", "pybullet", len(p0), t, "rayTestBatch both ways")
        ref_arm, t = _timed(lambda: np.array([scene.arm_collides(c) for c in q[:k]]))
        row("arm configs", "pybullet", k, t, "resetJointState x6 + performCollisionDetection")
        frames = np.stack([scene.link_frames(c)[links] for c in q])
    segs = np.einsum("ntij,tkj->ntki", frames[..., :3, :3], ends) + frames[:, :, None, :3, 3]
    checker = ArmChecker(tree, radii, links, mount=[cell.pedestal.name])
    got, t = _timed(checker.collides, segs, repeat=3)
    row("arm configs", "region tree", len(q), t, "link segments given")
    checks["arm_vs_pybullet"] = {"missed": int(np.sum(ref_arm & ~got[:k])),
                                 "false_positive_rate": float(np.sum(got[:k] & ~ref_arm) / max(1, np.sum(~ref_arm))),
                                 "pybullet_collide_rate": float(ref_arm.mean())}
    try:
        from ita.kinematics.fk import arm_model, link_segments
        model = arm_model(cell.arm)
        fk_checker = ArmChecker(tree, model.tube_radii, model.tube_links, mount=[cell.pedestal.name])
        _, t = _timed(lambda: fk_checker.collides(link_segments(model, q)), repeat=3)
        row("arm configs", "region tree + FK", len(q), t, "ita.kinematics.fk.link_segments included")
    except ImportError:
        pass
    if fcl_scene is not None:
        _, t = _timed(lambda: [fcl_scene.capsules_hit(s, radii[links != 0]) for s in segs[:k, links != 0]])
        row("arm configs", "python-fcl", k, t, "world only; link segments given")

    print(f"region tree: {tree.node_count} regions ({len(tree.leaves())} solid), built in {t_build:.2f} s, "
          f"first query (compile/cache load) {t_first:.2f} s")
    print(f"{'query':<12} {'method':<18} {'n':>7} {'per second':>12}  note")
    for r in rows:
        print(f"{r['query']:<12} {r['method']:<18} {r['n']:>7} {r['per_second']:>12,.0f}  {r['note']}")
    for name, c in checks.items():
        print(f"{name}: {c}")
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps({
        "machine": {"python": platform.python_version(), "processor": platform.processor() or platform.machine()},
        "tree": {"regions": tree.node_count, "solid": len(tree.leaves()), "build_seconds": t_build,
                 "first_call_seconds": t_first, "part_margin_mm": 2.0},
        "rows": rows, "checks": checks}, indent=2))
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
