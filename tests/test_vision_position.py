"""Hole position by Vision: a robust rim fit, a datum set that does not change with the
arm's pose error, and averaged re-approaches where the pose is the only datum."""

from __future__ import annotations

import math
from dataclasses import replace

import manifold3d as m3d
import numpy as np
import pytest

from ita.part.model import Hole, HoleRole, Stiffener
from ita.sensors.slra_frame import ScanGeometry
from ita.sim.slra import SlraParams, SlraScene, pose_error, simulate_frame
from ita.specs.model import MeasurementKind as K
from ita.specs.model import MeasurementSpec
from ita.vision.context import VisionContext, VisionException
from ita.vision.fit import fit_circle, fit_circle_fixed_radius
from ita.vision.measure import measure_frames
from ita.vision.patches import View
from ita.vision.register import rib_beneath
from ita.vision.scan import MIN_HOLE_PIXELS, RASTER_STEP, frames_for, scan_for
from tests.test_slra import PLACEMENT, looking_down
from tests.test_vision import _box, _mesh

PITCH = 40.0
ROW = [Hole(f"H{i}", HoleRole.FASTENER, (PITCH * i, 0.0, 3.0), (0.0, 0.0, 1.0), 6.35, 3.0, "P1") for i in (-1, 0, 1)]
BIG = Hole("L1", HoleRole.LIGHTENING, (0.0, 0.0, 3.0), (0.0, 0.0, 1.0), 60.0, 3.0, "P1")
HP_ROW = MeasurementSpec("HP-H0", K.HOLE_POSITION, "H0", (0.0, 0.0, 3.0), (0.0, 0.0, 1.0), 0.0, 0.0, 0.5)
HP_BIG = MeasurementSpec("HP-L1", K.HOLE_POSITION, "L1", (0.0, 0.0, 3.0), (0.0, 0.0, 1.0), 0.0, 0.0, 1.0)
TRUE_OFFSET = np.array([0.12, -0.05])          # the as-built middle hole and big hole (mm)
POSE_SIGMA_M = 0.25e-3 / 3


def _plate(holes, offsets) -> SlraScene:
    solid = _box((-100, -100, 0), (100, 100, 3)) + _box((-200, -200, -45), (200, 200, -40))
    built = []
    for h, d in zip(holes, offsets):
        c = (h.center[0] + d[0], h.center[1] + d[1])
        solid = solid - m3d.Manifold.cylinder(10.0, h.diameter / 2, circular_segments=96).translate((*c, -2))
        built.append(Hole(h.id, h.role, (*c, 3.0), h.axis, h.diameter, h.depth, h.parent))
    return SlraScene(_mesh(solid), PLACEMENT, holes=built)


@pytest.fixture(scope="module")
def row_scene() -> SlraScene:
    return _plate(ROW, [(0.0, 0.0), TRUE_OFFSET, (0.0, 0.0)])


@pytest.fixture(scope="module")
def big_scene() -> SlraScene:
    return _plate([BIG], [TRUE_OFFSET])


def _frames(scene, spec, ctx, rng, n):
    """n frames of spec, each from the commanded pose plus a new draw of the pose error."""
    pose = looking_down(0.0, 0.0, 0.45 + spec.point[2] / 1000)
    plan = frames_for(spec, ctx)
    first = scan_for(spec, ctx)
    out = []
    for k in range(n):
        g = first if k == 0 else ScanGeometry(plan.shape, first.fov_deg)
        out.append(simulate_frame(scene, pose_error(pose, rng, POSE_SIGMA_M), g, SlraParams(), rng,
                                  reported_pose=pose))
    return out


def test_circle_fit_ignores_a_cluster_of_spurious_edge_points():
    rng = np.random.default_rng(3)
    t = np.linspace(0, 2 * np.pi, 48, endpoint=False)
    xy = np.column_stack([3.2 * np.cos(t), 3.2 * np.sin(t)]) + rng.normal(0, 0.005, (48, 2))
    bad = (t > 0.6) & (t < 3.0)                    # 30 % of the rim, all pushed outward
    xy[bad] *= 1 + 0.25 / 3.2
    fit = fit_circle(xy)
    assert fit is not None
    assert math.hypot(*fit.center) < 0.01 and abs(fit.radius - 3.2) < 0.01


def test_fastener_position_registers_on_the_same_neighbours_under_pose_error(row_scene):
    ctx = VisionContext({h.id: h for h in ROW}, PLACEMENT, position_zones={h.id: 0.5 for h in ROW})
    rng = np.random.default_rng(7)
    frames = _frames(row_scene, HP_ROW, ctx, rng, 5)
    replies = [measure_frames([f], HP_ROW, ctx) for f in frames]
    assert all(r.ok for r in replies)
    assert {tuple(sorted(r.diagnostics["registered_on"])) for r in replies} == {("H-1", "H1")}
    values = np.array([r.value for r in replies])
    truth = 2 * math.hypot(*TRUE_OFFSET)
    assert values.std(ddof=1) < 0.02                  # the pose error cancels
    assert all(abs(r.value - truth) <= r.expanded for r in replies)


def test_lightening_position_averages_re_approaches(big_scene):
    ctx = VisionContext({BIG.id: BIG}, PLACEMENT, pose_datum_frames=8)
    assert frames_for(HP_BIG, ctx).count == 8
    assert frames_for(HP_ROW, VisionContext({h.id: h for h in ROW}, PLACEMENT)).count == 1
    rng = np.random.default_rng(11)
    frames = _frames(big_scene, HP_BIG, ctx, rng, 8)
    single = measure_frames(frames[:1], HP_BIG, ctx)
    averaged = measure_frames(frames, HP_BIG, ctx)
    assert single.ok and averaged.ok
    assert averaged.diagnostics["frames"] == 8
    truth = 2 * math.hypot(*TRUE_OFFSET)
    assert abs(averaged.value - truth) <= averaged.expanded
    # the pose error (0.083 mm per axis) is the single frame's main term; 8 approaches cut it
    assert averaged.diagnostics["u_random"] < 0.5 * single.diagnostics["u_random"]
    assert averaged.uncertainty <= single.uncertainty
    assert single.diagnostics["datum"] == "pose"


def test_a_small_hole_s_position_frame_is_finer():
    """A fastener position's raster follows the pixels across the hole's diameter: the row of
    6.35 mm holes keeps ctx.shape, the same row of 3 mm holes gets the first raster step
    that puts MIN_HOLE_PIXELS across one; the small hole's diameter frame (a narrow window)
    does not need it."""
    ctx = VisionContext({h.id: h for h in ROW}, PLACEMENT)
    assert scan_for(HP_ROW, ctx).shape == ctx.shape
    small = [replace(h, diameter=3.0) for h in ROW]
    sctx = VisionContext({h.id: h for h in small}, PLACEMENT)
    fine = scan_for(HP_ROW, sctx)
    assert fine.fov_deg == pytest.approx(scan_for(HP_ROW, ctx).fov_deg, rel=0.05)
    assert fine.shape[0] > ctx.shape[0] and fine.shape[1] > ctx.shape[1]
    window_mm = 2 * sctx.standoff_m * 1000 * math.tan(math.radians(fine.fov_deg[0]) / 2)
    assert 3.0 * fine.shape[1] / window_mm >= MIN_HOLE_PIXELS
    assert 3.0 * (fine.shape[1] - RASTER_STEP) / window_mm < MIN_HOLE_PIXELS
    hd = MeasurementSpec("HD-H0", K.HOLE_DIAMETER, "H0", (0.0, 0.0, 3.0), (0.0, 0.0, 1.0), 3.0, -0.076, 0.076)
    assert scan_for(hd, sctx).shape == sctx.shape


def test_mostly_failed_frames_are_an_exception_not_a_value(big_scene):
    ctx = VisionContext({BIG.id: BIG}, PLACEMENT, pose_datum_frames=4)
    rng = np.random.default_rng(5)
    good = _frames(big_scene, HP_BIG, ctx, rng, 1)
    far = looking_down(400.0, 0.0, 0.453)              # the hole is out of these frames
    away = [simulate_frame(big_scene, far, scan_for(HP_BIG, ctx), SlraParams(), rng) for _ in range(3)]
    reply = measure_frames(good + away, HP_BIG, ctx)
    assert isinstance(reply, VisionException)
    assert "3 of 4 frames failed" in reply.detail



# a rib (3 mm wide, top 10 mm below the face) runs under H1, 0.8 mm off its centre: its edge
# lies 0.9 mm inside the rim, so through
# the hole the beam sees the rib's top on one side and the floor 40 mm down on the other
RIB_UNDER = Stiffener("S1", (PITCH - 0.8, -60.0), (PITCH - 0.8, 60.0), 3.0, -7.0)
HD_H1 = MeasurementSpec("HD-H1", K.HOLE_DIAMETER, "H1", (PITCH, 0.0, 3.0), (0.0, 0.0, 1.0), 6.35, -0.076, 0.076)


@pytest.fixture(scope="module")
def rib_row_scene() -> SlraScene:
    solid = _box((-100, -100, 0), (100, 100, 3)) + _box((-200, -200, -45), (200, 200, -40))
    solid = solid + _box((PITCH - 0.8 - 1.5, -60, -40), (PITCH - 0.8 + 1.5, 60, -7.0))
    for h in ROW:
        solid = solid - m3d.Manifold.cylinder(10.0, h.diameter / 2, circular_segments=96).translate(
            (h.center[0], h.center[1], -2))
    return SlraScene(_mesh(solid), PLACEMENT, holes=ROW)


def test_circle_of_known_radius_from_half_a_rim_with_outliers():
    rng = np.random.default_rng(4)
    t = np.linspace(-np.pi / 2, np.pi / 2, 17)                # the half of the rim in view
    xy = np.column_stack([2.4 * np.cos(t), 2.4 * np.sin(t)]) + rng.normal(0, 0.01, (17, 2))
    xy[[2, 9, 14]] *= 1 + 0.3 / 2.4                           # three points half a pixel out
    fit = fit_circle_fixed_radius(xy, 2.4)
    assert fit is not None and fit.n == 14
    assert math.hypot(*fit.center) < 0.02 and fit.radius == 2.4


def test_datum_set_leaves_out_a_neighbour_with_a_rib_beneath_in_every_frame(rib_row_scene):
    """The datum set is fixed by the nominal part (the rib is a nominal feature) and the
    commanded pose: the same in every frame, whatever the rib does to H1's rim."""
    ctx = VisionContext({f.id: f for f in ROW + [RIB_UNDER]}, PLACEMENT, position_zones={h.id: 0.5 for h in ROW})
    rng = np.random.default_rng(9)
    spec = replace(HP_ROW, feature="H-1", id="HP-H-1", point=(-PITCH, 0.0, 3.0))
    pose = looking_down(-PITCH, 0.0, 0.453)
    frames = [simulate_frame(rib_row_scene, pose_error(pose, rng, POSE_SIGMA_M), scan_for(spec, ctx), SlraParams(),
                             rng, reported_pose=pose) for _ in range(3)]
    replies = [measure_frames([f], spec, ctx) for f in frames]
    assert all(r.ok for r in replies)
    assert {tuple(r.diagnostics["registered_on"]) for r in replies} == {("H0",)}
    assert all(rib_beneath(View(f, PLACEMENT), ROW[2], ctx) for f in frames)
    assert not any(rib_beneath(View(f, PLACEMENT), ROW[1], ctx) for f in frames)


def test_diameter_of_a_rim_with_a_rib_beneath_part_of_it(rib_row_scene):
    """Where the rib's top shows just inside the rim on one side and the floor beyond the rim
    pixels there, the rib is no reference for them: those radii give no rim points."""
    ctx = VisionContext({f.id: f for f in ROW + [RIB_UNDER]}, PLACEMENT)
    rng = np.random.default_rng(12)
    pose = looking_down(PITCH, 0.0, 0.453)
    for _ in range(4):
        frame = simulate_frame(rib_row_scene, pose_error(pose, rng, POSE_SIGMA_M), scan_for(HD_H1, ctx),
                               SlraParams(), rng, reported_pose=pose)
        reply = measure_frames([frame], HD_H1, ctx)
        assert reply.ok, reply
        assert abs(reply.value - 6.35) < 0.02
        assert abs(reply.value - 6.35) < reply.expanded
        # most of the points off by the wrong reference (about 45 % of all) no longer reach
        # the fit, where only its robust start stood between them and the radius (those
        # where the rib's edge lies nearer the rim than the check still do)
        assert reply.diagnostics["edge_points"] >= 0.65 * len(reply.diagnostics["rim_xy"])


def test_a_diameter_from_several_frames_averages_its_own_fits_only(row_scene):
    """A reinspection's more frames of a size: the mean of the values; the frames' own fits
    fall by the square root of their number, the other terms stay as they were."""
    spec = MeasurementSpec("HD-H0", K.HOLE_DIAMETER, "H0", (0.0, 0.0, 3.0), (0.0, 0.0, 1.0), 6.35, -0.076, 0.076)
    ctx = VisionContext({h.id: h for h in ROW}, PLACEMENT)
    rng = np.random.default_rng(5)
    frames = _frames(row_scene, spec, ctx, rng, 8)
    single = measure_frames(frames[:1], spec, ctx)
    averaged = measure_frames(frames, spec, ctx)
    assert single.ok and averaged.ok
    assert averaged.diagnostics["frames"] == 8
    assert abs(averaged.value - 6.35) <= averaged.expanded
    own = [t for t in averaged.diagnostics["budget"] if t.startswith("the frames' own fits")]
    assert own and averaged.diagnostics["budget"][own[0]] < single.uncertainty
    fixed = {t: u for t, u in single.diagnostics["budget"].items() if t not in ("rim fit", "the frame's own fits")}
    assert fixed and all(averaged.diagnostics["budget"][t] >= u for t, u in fixed.items())
    assert averaged.uncertainty <= single.uncertainty


def test_a_fastener_position_from_several_frames_keeps_each_frames_sightings(row_scene):
    """For the network: every frame's rims, each under its own frame number."""
    ctx = VisionContext({h.id: h for h in ROW}, PLACEMENT, position_zones={h.id: 0.5 for h in ROW})
    frames = _frames(row_scene, HP_ROW, ctx, np.random.default_rng(8), 4)
    reply = measure_frames(frames, HP_ROW, ctx)
    assert reply.ok
    sightings = reply.diagnostics["sightings"]
    assert sorted({s["frame"] for s in sightings}) == [0, 1, 2, 3]
    assert all(sum(1 for s in sightings if s["frame"] == k and s["hole"] == "H0") == 1 for k in range(4))


def test_a_frame_that_lost_most_of_its_returns_gives_no_value(row_scene):
    """A dirty window loses about 97 % of the returns: Vision refuses the frame (too few
    pixels) instead of measuring the rim in what is left."""
    from ita.vision.context import VisionFailure

    spec = MeasurementSpec("HD-H0", K.HOLE_DIAMETER, "H0", (0.0, 0.0, 3.0), (0.0, 0.0, 1.0), 6.35, -0.076, 0.076)
    ctx = VisionContext({h.id: h for h in ROW}, PLACEMENT)
    rng = np.random.default_rng(4)
    frame = _frames(row_scene, spec, ctx, rng, 1)[0]
    assert measure_frames([frame], spec, ctx).ok
    lost = frame.range_m.copy()
    lost[rng.random(lost.shape) < 0.97] = np.nan
    reply = measure_frames([replace(frame, range_m=lost)], spec, ctx)
    assert isinstance(reply, VisionException) and reply.reason is VisionFailure.TOO_FEW_PIXELS
    assert "returns at" in reply.detail
