"""Calibrating the SLRA on a part's master: the substitution method for a user's own part.

The cell's SLRA calibration (ita.vision.calibration) was made on generated bulkheads and
stands for their features only.  For another part, the part's own master stands in: a
workpiece of the part's nominal geometry whose dimensions are known (its calibration
certificate; in the simulated cell, the nominal mesh, whose values exact rays give,
ita.part.mesh_values).  Each size the SLRA measures on the part (the calibrated kinds:
hole diameters, edge distances, flange and rib widths) is measured on the master `repeats`
times (more where a pool has few specs: `repeats_for`) the way a run measures it (from its
view group's frame, the MKB's viewing pose, window and pixels), each frame after its own
approach (a new draw of the arm's pose error, settled as the controller settles in a run:
`_settled_pose`), without any calibration.  Per spec: the bias
(mean error), corrected in every later result of that spec; per kind seen along one
direction (`scatter_pools`), the residuals about each spec's bias give the scatter of one
frame, and the u of a corrected result (see :func:`spec_classes`).  What the master cannot tell: how
the bias changes between the master and an as-built part (their differences are within the
tolerances, far smaller than the features; a perturbed as-built part measures it,
`ita part asbuilt`).

    calibration = calibrate_on_master(part, workcell, repeats=4, seed=0)
    calibration.save(part.directory / "slra_calibration.json")
"""

from __future__ import annotations

import json
import math
from collections import Counter, defaultdict
from collections.abc import Callable, Sequence
from datetime import datetime, timezone
from typing import Any

import numpy as np

from ita.files.atomic import write_json_atomic
from ita.kinematics import arm_model, flange_poses
from ita.kinematics.settle import settled
from ita.kinematics.tool_poses import measurement_poses
from ita.part.mesh_values import mesh_values
from ita.sensors.slra_frame import ScanGeometry
from ita.sim.slra import SlraParams, SlraScene, pose_error, simulate_frame
from ita.specs.io import read_specs
from ita.specs.model import MeasurementSpec
from ita.vision.calibration import (
    CALIBRATED_KINDS,
    RANDOM_TERMS,
    REFERENCE_U_MM,
    CalibrationClass,
    SlraCalibration,
    coverage_level,
    spec_class,
)
from ita.vision.context import VisionResult
from ita.vision.for_part import (
    like_the_references,
    part_calibration_path,
    vision_context,
)
from ita.vision.measure import measure_frames
from ita.vision.scan import scan_for

ROTATION_SIGMA = 0.05e-3   # rad: the pose error's rotation part (as bench/vision.py draws it)
MIN_KIND_FRAMES = 64       # frames of the master per scatter pool at least (more repeats where it has few specs)
SAME_DIRECTION_COS = math.cos(math.radians(10.0))   # specs seen along normals this close share a scatter pool
#: the way a master calibration is made; a stored one made another way is made again
METHOD = 3   # 2: frames' pose errors drawn as the controller settles (_settled_pose); 3: 64 frames a pool


def master_errors(part: Any, workcell: Any, specs: Sequence[MeasurementSpec], repeats: int, seed: int,
                  progress: Callable[[str], None] = lambda _m: None, mkb: Any = None
                  ) -> dict[str, list[tuple[float, float]]]:
    """Spec id -> [(error, u_frame)] of `repeats` uncalibrated measurements on the master
    (the part's nominal mesh in the cell), error = measured - the master's value.  With the
    part's MKB, each from its view group's frame as a run takes it (the anchor's viewing
    pose, the group's window and pixels: one frame serves every member); without, a frame
    of the spec's own window square on to it."""
    from dataclasses import replace

    features = {f.id: f for f in part.features}
    certificate = mesh_values(part.mesh, specs, features)
    scene = SlraScene(part.mesh, workcell.part, tuple(workcell.static_boxes()))
    ctx = replace(vision_context(part, workcell, specs=list(specs)), calibration=SlraCalibration())
    tool = next(t for t in workcell.tools if t.tool_class.value == "slra_tool")
    params = SlraParams()
    rng = np.random.default_rng([seed, 7])
    out: dict[str, list[tuple[float, float]]] = defaultdict(list)
    todo = [s for s in specs if s.kind in CALIBRATED_KINDS and s.id in certificate and s.feature in features]
    views: dict[str, tuple[Any, Any, ScanGeometry, list[MeasurementSpec]]] = {}
    for spec in todo:
        group = mkb.group_of(spec.id) if mkb is not None else None
        anchor = mkb.entries.get(group.anchor) if group is not None else None
        if group is not None and anchor is not None and anchor.pose is not None:
            key, pose, geometry = group.id, np.asarray(anchor.pose), ScanGeometry(tuple(group.pixels),
                                                                                  tuple(group.fov_deg))
            q = None if anchor.q is None else np.asarray(anchor.q, dtype=float)
        else:
            key, geometry = spec.id, scan_for(spec, ctx)
            pose = measurement_poses(workcell.part, [spec.point], [spec.normal], tool, rolls=[0.0])[0, 0]
            q = None
        views.setdefault(key, (pose, q, geometry, []))[3].append(spec)
    pools = scatter_pools(todo)
    per_pool = Counter(pools.values())
    settle = _settled_pose(workcell, tool)
    for i, (pose, q, geometry, members) in enumerate(views.values()):
        for _ in range(repeats_for([pools[s.id] for s in members], per_pool, repeats)):
            true_pose = settle(pose, q, rng)
            frame = simulate_frame(scene, true_pose, geometry, params, rng, reported_pose=pose, timestamp=0.0)
            for spec in members:
                reply = measure_frames([frame], spec, ctx)
                if isinstance(reply, VisionResult):   # reply.ok
                    budget = reply.diagnostics.get("budget", {})
                    u_frame = math.sqrt(sum(float(budget[t]) ** 2 for t in RANDOM_TERMS if t in budget))
                    out[spec.id].append((reply.value - certificate[spec.id], u_frame))
        if (i + 1) % 25 == 0 or i + 1 == len(views):
            progress(f"{i + 1}/{len(views)} views of the master measured")
    return dict(out)


def _settled_pose(workcell: Any, tool: Any) -> Callable[[Any, Any, np.random.Generator], np.ndarray]:
    """true pose (4, 4) of a frame taken at the reported `pose` (4, 4), joints `q` (6,) or
    None: with q, the arm's settle error as the controller makes it in a run (a normal TCP
    offset of repeatability / 3 per axis, reached by the least-norm joint change, which
    turns the tool too: 0.12 to 0.15 mrad rms at the box's views, where the drawn rotation
    of ROTATION_SIGMA per axis gives 0.09); without, a drawn translation and rotation."""
    model, tcp = arm_model(workcell.arm), tool.tcp.matrix()
    sigma = workcell.arm.repeatability_m / 3

    def draw(pose: Any, q: Any, rng: np.random.Generator) -> np.ndarray:
        if q is None:
            return pose_error(pose, rng, sigma, ROTATION_SIGMA)
        return flange_poses(model, settled(model, q, tcp, rng.normal(0.0, sigma, 3))[None])[0] @ tcp

    return draw


def scatter_pools(specs: Sequence[MeasurementSpec]) -> dict[str, str]:
    """Spec id -> the pool its frames' scatter is estimated in: its kind, split by the
    direction it is seen along (normals within 10 degrees together).  A hole seen from the
    side scatters several times more than one seen square on; pooled, the side holes'
    scatter made the U of every other hole of the plate about 3 times too large."""
    reps: dict[str, list[np.ndarray]] = defaultdict(list)
    out = {}
    for s in specs:
        n = np.asarray(s.normal, dtype=float)
        n = n / max(float(np.linalg.norm(n)), 1e-12)
        kind = s.kind.value
        same = [i for i, r in enumerate(reps[kind]) if float(r @ n) > SAME_DIRECTION_COS]
        if not same:
            reps[kind].append(n)
        out[s.id] = f"{kind}@{same[0] if same else len(reps[kind]) - 1}"
    return out


def repeats_for(pools: Sequence[str], per_pool: Counter, repeats: int) -> int:
    """Frames to take of a view whose specs are in `pools` (`scatter_pools`): `repeats`,
    or more where a pool has few specs, so that every pool's scatter and each spec's bias
    rest on at least MIN_KIND_FRAMES frames (a few specs measured 4 times each give a
    scatter of 12 degrees of freedom and a U that falls short)."""
    return max([repeats] + [math.ceil(MIN_KIND_FRAMES / per_pool[p]) for p in pools if per_pool[p]])


def spec_classes(errors: dict[str, list[tuple[float, float]]], pool_of: dict[str, str]) -> dict[str, CalibrationClass]:
    """One class per spec measured at least twice: its bias, and u = the pooled scatter of
    its pool's frames (pool_of: `scatter_pools`, its kind seen along one direction) about
    their specs' biases, taken as the tolerance bound that covers 95 % of them with 90 %
    confidence (ita.vision.calibration.coverage_level, over the pool's specs), combined
    with the bias's own uncertainty (scatter / sqrt(repeats)) and the master's certificate."""
    residuals: dict[str, list[float]] = defaultdict(list)
    dof: dict[str, int] = defaultdict(int)
    count: dict[str, int] = defaultdict(int)
    for sid, rows in errors.items():
        if len(rows) < 2:
            continue
        e = np.array([r[0] for r in rows])
        residuals[pool_of[sid]] += list(e - e.mean())
        dof[pool_of[sid]] += len(e) - 1
        count[pool_of[sid]] += 1
    out: dict[str, CalibrationClass] = {}
    for sid, rows in errors.items():
        if len(rows) < 2:
            continue
        pool = pool_of[sid]
        e = np.array([r[0] for r in rows])
        r = np.abs(np.asarray(residuals[pool]))
        scatter = math.sqrt(float((r ** 2).sum()) / max(dof[pool], 1))
        # residuals about a mean of n are sqrt((n - 1) / n) of the errors' own scatter
        q95 = float(np.quantile(r, coverage_level(count[pool]))) * math.sqrt(len(e) / (len(e) - 1))
        u = math.sqrt((q95 / 2) ** 2 + scatter ** 2 / len(e) + REFERENCE_U_MM ** 2)
        rms = math.sqrt(float(np.mean([x[1] ** 2 for x in rows])))
        out[spec_class(sid)] = CalibrationClass(spec_class(sid), len(e), 1, float(e.mean()), scatter, rms, u)
    return out


def calibrate_on_master(part: Any, workcell: Any, repeats: int = 4, seed: int = 0,
                        progress: Callable[[str], None] = lambda _m: None, mkb: Any = None) -> SlraCalibration:
    """The SLRA calibration of `part` on its master (see the module doc; mkb: the part's
    measurement knowledge base, whose views the master is measured from)."""
    specs = read_specs(part.specs_path)
    errors = master_errors(part, workcell, specs, repeats, seed, progress, mkb)
    measured = [s for s in specs if s.id in errors]
    pools = scatter_pools(measured)
    classes = spec_classes(errors, pools)
    per_pool = Counter(pools.values())
    planned = {s.id: repeats_for([pools[s.id]], per_pool, repeats) for s in measured}
    provenance = {"what": "SLRA calibration on the part's master (ita.offline.master): per spec, the bias measured "
                          "on the nominal part, corrected",
                  "made_by": f"ita part calibrate --repeats {repeats} --seed {seed}", "part": part.name,
                  "made": datetime.now(timezone.utc).isoformat(timespec="seconds"),
                  "specs_measured": len(errors),
                  "failed_frames": sum(max(0, planned[k] - len(v)) for k, v in errors.items())}
    return SlraCalibration(classes, provenance)


def ensure_master_calibration(part: Any, workcell: Any, key: str, progress: Callable[[str], None] = lambda _m: None,
                              force: bool = False, repeats: int = 4, mkb: Any = None, seed: int = 0) -> str:
    """Calibrate a user part on its master when its calibration is missing or was made for
    other content (`key`: ita.part.store.part_key: mesh, specs, features, workcell); what
    was done, in words.  A generated bulkhead has the cell's calibration."""

    if like_the_references(part):
        return "the cell's (made on generated bulkheads)"
    path = part_calibration_path(part.directory)
    if not force and path.is_file():
        try:
            stored = json.loads(path.read_text(encoding="utf-8"))
            made_for, stored_mkb, method = stored.get("part_key"), stored.get("mkb_digest"), stored.get("method")
        except (OSError, ValueError, AttributeError):
            made_for = stored_mkb = method = None
        if made_for == key and method == METHOD and (mkb is None or stored_mkb == getattr(mkb, "digest", None)):
            return f"the part's own, on its master ({path.name}, stored and current)"
    if not any(s.kind in CALIBRATED_KINDS for s in read_specs(part.specs_path)):
        return "none needed (no hole diameter, edge distance or width among the specs)"
    progress("calibrating the SLRA on the part's master")
    calibration = calibrate_on_master(part, workcell, repeats, seed, progress, mkb)
    data = {**calibration.to_dict(), "part_key": key, "mkb_digest": getattr(mkb, "digest", None), "method": METHOD}
    write_json_atomic(path, data, what="calibration")
    failed = calibration.provenance.get("failed_frames", 0)
    return (f"the part's own, on its master ({len(calibration.classes)} specs, made now"
            + (f"; {failed} frames failed" if failed else "") + ")")
