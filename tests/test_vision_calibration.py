"""The SLRA's calibration on reference workpieces (ita.vision.calibration)."""

from __future__ import annotations

import json
import math

import pytest

from ita.part.model import Hole, HoleRole
from ita.specs.model import MeasurementKind as K
from ita.vision.calibration import (
    CALIBRATION_TERM,
    CalibrationClass,
    SlraCalibration,
    class_of,
    default_path,
)
from ita.vision.context import VisionResult


def _hole(diameter: float) -> Hole:
    return Hole("H1", HoleRole.FASTENER, (0.0, 0.0, 45.0), (0.0, 0.0, 1.0), diameter, 3.2, "F1")


def test_classes_by_kind_size_and_what_lies_beyond_the_rim():
    assert class_of(K.HOLE_DIAMETER, _hole(6.35), {"far_other_share": 0.0}) == "hole_diameter/small, clear rim"
    assert class_of(K.HOLE_DIAMETER, _hole(6.35), {"far_other_share": 0.2}) == "hole_diameter/small, surfaces beyond"
    assert class_of(K.HOLE_DIAMETER, _hole(120.0), {}) == "hole_diameter/large"
    assert class_of(K.EDGE_DISTANCE, _hole(5.0), {}) == "edge_distance"
    assert class_of(K.STIFFENER_WIDTH, None, {}) == "stiffener_width"
    assert class_of(K.HOLE_POSITION, _hole(5.0), {}) is None       # positions: the network decides them
    assert class_of(K.FLANGE_HEIGHT, None, {}) is None


def test_a_class_from_errors_takes_its_coverage_interval_from_the_errors_own_distribution():
    import numpy as np

    rng = np.random.default_rng(1)
    normal = list(0.010 + rng.normal(0.0, 0.003, 4000))
    c = CalibrationClass.from_errors("x", normal, [0.001] * 4000, features=400)
    assert c.bias == pytest.approx(0.010, abs=2e-4) and c.scatter == pytest.approx(0.003, rel=0.05)
    # normal errors: about 2 sigma, a little more for the study's own finite size (400 features)
    assert 1.96 * 0.003 < 2 * c.u < 2.2 * 0.003
    # heavy tails (a tenth of the features far out): U covers 95 % of them, wider than 2 sd would
    tails = list(rng.normal(0.0, 0.002, 3600)) + list(rng.normal(0.0, 0.012, 400))
    c = CalibrationClass.from_errors("y", tails, [0.001] * 4000, features=400)
    e = np.abs(np.asarray(tails) - c.bias)
    assert 0.95 <= np.mean(e <= 2 * c.u) <= 0.975
    assert c.u > c.scatter                                            # 2 sd would cover less


def test_the_coverage_level_bounds_the_95th_percentile_with_90_percent_confidence():
    from ita.vision.calibration import coverage_level

    assert coverage_level(10) == 1.0                      # too few features: the largest error
    assert 0.96 < coverage_level(500) < 0.97
    assert coverage_level(100000) == pytest.approx(0.95, abs=0.002)


def test_apply_corrects_the_bias_and_replaces_the_type_b_terms():
    cal = SlraCalibration({"hole_diameter/small, clear rim": CalibrationClass("hole_diameter/small, clear rim",
                                                                              300, 150, -0.001, 0.0008, 0.0006,
                                                                              0.0007)})
    budget = {"rim fit": 0.0006, "edge model": 0.0013, "scanner angle scale": 0.0005,
              "rim model (wall, surfaces beyond)": 0.0}
    raw = VisionResult("HD-1", K.HOLE_DIAMETER, 6.400, math.hypot(*budget.values()),
                       {"budget": budget, "far_other_share": 0.0})
    out = cal.apply(raw, _hole(6.35))
    assert out.value == pytest.approx(6.401)
    assert out.diagnostics["budget"] == {"the frame's own fits": 0.0006, CALIBRATION_TERM: 0.0007}
    assert out.uncertainty == pytest.approx(0.0007)
    # a troubled frame (its own fits worse than the class's interval) keeps its own, larger u
    worse = VisionResult("HD-1", K.HOLE_DIAMETER, 6.400, 0.01, {"budget": {**budget, "rim fit": 0.004}})
    assert cal.apply(worse, _hole(6.35)).uncertainty == pytest.approx(0.004)
    assert out.diagnostics["budget_type_b"] == budget and out.diagnostics["correction"] == pytest.approx(0.001)
    # a class the calibration does not hold: as the measurer made it, and said so
    big = VisionResult("HD-2", K.HOLE_DIAMETER, 120.0, 0.1, {"budget": {"rim fit": 0.01, "edge model": 0.1}})
    same = cal.apply(big, _hole(120.0))
    assert same.value == 120.0 and same.uncertainty == 0.1 and same.diagnostics["calibration"].startswith("none")
    # positions are not calibrated at all
    pos = VisionResult("HP-1", K.HOLE_POSITION, 0.1, 0.05, {})
    assert cal.apply(pos, _hole(6.35)) is pos


def test_the_cells_calibration_is_made_on_other_parts_than_the_built_in_one():
    data = json.loads(default_path().read_text(encoding="utf-8"))
    assert "1987" not in data["made_by"] and data["reference_parts"]
    cal = SlraCalibration.load()
    assert {"hole_diameter/small, clear rim", "hole_diameter/large", "edge_distance", "flange_width",
            "stiffener_width"} <= set(cal.classes)
    for c in cal.classes.values():
        assert c.features >= 6 and c.u > 0 and abs(c.bias) < 0.2


def test_calibrated_diameters_of_the_built_in_part_are_closer_to_the_truth_with_a_smaller_u(builtin_part):
    """40 fastener diameters of the built-in bulkhead measured twice, raw and calibrated: the
    calibration (made on other parts) removes most of the bias and shrinks U, and the
    errors stay within U about as often as k = 2 promises."""
    from dataclasses import replace

    import numpy as np

    from ita.kinematics.tool_poses import measurement_poses
    from ita.part.truth import load_truth
    from ita.sim.slra import SlraParams, SlraScene, pose_error, simulate_frame
    from ita.specs.io import read_specs
    from ita.vision.for_part import vision_context
    from ita.vision.measure import measure
    from ita.vision.scan import scan_for
    from ita.workcell import load_workcell

    wc = load_workcell()
    specs = [s for s in read_specs(builtin_part.specs_path) if s.kind is K.HOLE_DIAMETER and "-OF-" in s.id][:40]
    truth = load_truth(builtin_part.directory).values
    ctx = vision_context(builtin_part, wc)
    raw_ctx = replace(ctx, calibration=SlraCalibration())
    scene = SlraScene.from_truth(builtin_part.directory, wc)
    rng = np.random.default_rng(5)
    tool = wc.tool("slra_1")
    raw_err, cal_err, raw_u, cal_u = [], [], [], []
    for spec in specs:
        pose = measurement_poses(wc.part, [spec.point], [spec.normal], tool, rolls=[0.0])[0, 0]
        frame = simulate_frame(scene, pose_error(pose, rng, wc.arm.repeatability_m / 3, 0.05e-3), scan_for(spec, ctx),
                               SlraParams(), rng, reported_pose=pose)
        a, b = measure(frame, spec, raw_ctx), measure(frame, spec, ctx)
        assert a.ok and b.ok
        raw_err.append(a.value - truth[spec.id])
        cal_err.append(b.value - truth[spec.id])
        raw_u.append(a.expanded)
        cal_u.append(b.expanded)
    raw_err, cal_err = np.array(raw_err), np.array(cal_err)
    assert abs(cal_err.mean()) < abs(raw_err.mean()) / 2
    assert np.mean(cal_u) < 0.7 * np.mean(raw_u)
    within = np.mean(np.abs(cal_err) <= np.array(cal_u))
    assert 0.85 <= within <= 1.0
