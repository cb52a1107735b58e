"""Calibrating the SLRA on a part's master: how frames are pooled and how many are taken."""

from __future__ import annotations

from collections import Counter

import numpy as np
import pytest

from ita.offline.master import MIN_KIND_FRAMES, repeats_for, scatter_pools, spec_classes
from ita.specs.model import MeasurementKind as K
from ita.specs.model import MeasurementSpec


def _spec(sid: str, kind: K, normal: tuple[float, float, float]) -> MeasurementSpec:
    return MeasurementSpec(sid, kind, "F", (0.0, 0.0, 0.0), normal, 6.0, -0.05, 0.05)


def test_holes_seen_from_the_side_scatter_in_a_pool_of_their_own():
    specs = [_spec("HD-T1", K.HOLE_DIAMETER, (0, 0, 1)), _spec("HD-T2", K.HOLE_DIAMETER, (0.05, 0, 1)),
             _spec("HD-S1", K.HOLE_DIAMETER, (1, 0, 0)), _spec("ED-T1", K.EDGE_DISTANCE, (0, 0, 1))]
    pools = scatter_pools(specs)
    assert pools["HD-T1"] == pools["HD-T2"] != pools["HD-S1"]
    assert pools["ED-T1"] not in {pools["HD-T1"], pools["HD-S1"]}
    per_pool = Counter(pools.values())
    assert repeats_for([pools["HD-T1"]], per_pool, 4) == MIN_KIND_FRAMES // 2   # two specs share the pool
    assert repeats_for([pools["HD-S1"], pools["HD-T1"]], per_pool, 4) == MIN_KIND_FRAMES


def test_a_quiet_pool_keeps_a_small_u_beside_a_noisy_one():
    """The u of square-on holes follows their own scatter, not the side holes'."""
    rng = np.random.default_rng(1)
    errors = {"T1": [(0.004 + e, 0.0) for e in rng.normal(0, 0.002, 16)],
              "T2": [(0.003 + e, 0.0) for e in rng.normal(0, 0.002, 16)],
              "S1": [(-0.48 + e, 0.0) for e in rng.normal(0, 0.015, 16)],
              "S2": [(-0.49 + e, 0.0) for e in rng.normal(0, 0.015, 16)]}
    apart = spec_classes(errors, {"T1": "hd@0", "T2": "hd@0", "S1": "hd@1", "S2": "hd@1"})
    together = spec_classes(errors, {k: "hd" for k in errors})
    assert apart["spec/T1"].u < 0.006 < together["spec/T1"].u
    assert apart["spec/S1"].u == pytest.approx(together["spec/S1"].u, rel=0.5)
    assert apart["spec/T1"].bias == pytest.approx(0.004, abs=0.002)


def test_the_masters_frames_are_posed_as_the_controller_settles():
    """A view with joints: the TCP lands off by the arm's repeatability (sigma r / 3 per
    axis) through the controller's own least-norm joint change, which turns the tool too
    (more than the drawn rotation the master used before, at such a pose)."""
    from ita.kinematics import arm_model, flange_poses
    from ita.kinematics.settle import settled
    from ita.offline.master import ROTATION_SIGMA, _settled_pose
    from ita.workcell import load_workcell

    cell = load_workcell()
    tool = next(t for t in cell.tools if t.tool_class.value == "slra_tool")
    model, tcp = arm_model(cell.arm), tool.tcp.matrix()
    q = np.array([0.53, 0.38, 0.78, -2.05, 1.37, -1.93])
    pose = flange_poses(model, q[None])[0] @ tcp
    draw = _settled_pose(cell, tool)
    sigma = cell.arm.repeatability_m / 3
    rng, same = np.random.default_rng(4), np.random.default_rng(4)
    poses = [draw(pose, q, rng) for _ in range(400)]
    offsets = np.array([p[:3, 3] - pose[:3, 3] for p in poses])
    assert offsets.std(axis=0) == pytest.approx([sigma] * 3, rel=0.15)
    turned = [np.linalg.norm(p[:3, :3] - pose[:3, :3]) / np.sqrt(2) for p in poses]
    assert np.sqrt(np.mean(np.square(turned))) > np.sqrt(3) * ROTATION_SIGMA
    controller = flange_poses(model, settled(model, q, tcp, same.normal(0.0, sigma, 3))[None])[0] @ tcp
    assert np.allclose(controller, poses[0])
    assert not np.allclose(draw(pose, None, rng), pose, atol=1e-9, rtol=0)   # no joints: a drawn error
