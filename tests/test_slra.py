"""The SLRA simulator: phase wrap-around, noise, mixed pixels, dropouts, determinism, timing."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from ita.sensors.slra_frame import RangeFrame, ScanGeometry
from ita.sim.slra import SlraParams, SlraScene, pose_error, simulate_frame
from ita.workcell.model import PartPlacement

# part frame = world frame scaled to mm
PLACEMENT = PartPlacement(0.001, ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0)), (0.0, 0.0, 0.0),
                          (-500.0, -500.0, -100.0), (500.0, 500.0, 100.0))
SMALL = ScanGeometry((64, 64), (10.0, 10.0))


def looking_down(x_mm: float = 0.0, y_mm: float = 0.0, height_m: float = 0.45) -> np.ndarray:
    """Sensor pose (4, 4) at `height_m` above the part origin, looking along -z."""
    pose = np.eye(4)
    pose[:3, :3] = np.column_stack([(1.0, 0.0, 0.0), (0.0, -1.0, 0.0), (0.0, 0.0, -1.0)])
    pose[:3, 3] = (x_mm / 1000, y_mm / 1000, height_m)
    return pose


def plate(top: float = 0.0, size: float = 2000.0, tilt_deg: float = 0.0) -> trimesh.Trimesh:
    m = trimesh.creation.box(extents=(size, size, 10.0))
    m.apply_translation((0, 0, top - 5.0))
    if tilt_deg:
        m.apply_transform(trimesh.transformations.rotation_matrix(np.radians(tilt_deg), (0, 1, 0), (0, 0, top)))
    return m


def residual(frame: RangeFrame, top_m: float = 0.0) -> np.ndarray:
    """Measured minus true range (m) of the pixels on a flat plate at z = top_m."""
    d = frame.geometry.directions()                        # looking straight down: z_world = -z_sensor
    return frame.range_m - (frame.pose[2, 3] - top_m) / d[..., 2]


def test_range_wraps_beyond_the_ambiguity_interval():
    scene = SlraScene(plate(), PLACEMENT)
    params = SlraParams(min_amplitude=1e-5)
    far = 3.5                                              # beyond c / 2f = 2.998 m at 50 MHz
    frame = simulate_frame(scene, looking_down(height_m=far), SMALL, params, np.random.default_rng(0))
    assert SMALL.ambiguity_m == pytest.approx(2.998, abs=1e-3)
    centre = np.nanmedian(frame.range_m[28:36, 28:36])
    assert centre == pytest.approx(far - SMALL.ambiguity_m, abs=0.01)
    slow = ScanGeometry((64, 64), (10.0, 10.0), modulation_hz=5e6)   # 30 m interval
    frame = simulate_frame(scene, looking_down(height_m=far), slow, params, np.random.default_rng(0))
    assert np.nanmedian(frame.range_m[28:36, 28:36]) == pytest.approx(far, abs=0.1)


def test_noise_grows_with_distance_and_incidence():
    rng = np.random.default_rng(1)
    scene = SlraScene(plate(), PLACEMENT)
    near = np.nanstd(residual(simulate_frame(scene, looking_down(height_m=0.45), SMALL, SlraParams(), rng)))
    far = np.nanstd(residual(simulate_frame(scene, looking_down(height_m=0.9), SMALL, SlraParams(), rng)))
    assert 1.6 < far / near < 2.5                          # sigma ~ A^-1/2 ~ R
    assert 0.1e-3 < near < 0.5e-3
    tilted = SlraScene(plate(tilt_deg=60.0), PLACEMENT)
    f = simulate_frame(tilted, looking_down(), SMALL, SlraParams(), rng)
    d = f.geometry.directions()
    n = np.array([np.sin(np.radians(60.0)), 0.0, np.cos(np.radians(60.0))])
    dirs = np.einsum("ij,hwj->hwi", f.pose[:3, :3], d)
    true = -(f.pose[:3, 3] @ n) / (dirs @ n)
    assert np.nanstd(f.range_m - true) > 1.25 * near      # cos 60 halves the return


def test_mixed_pixels_lie_between_the_two_sides_of_a_step():
    base = plate()
    block = trimesh.creation.box(extents=(100.0, 200.0, 20.0))
    block.apply_translation((50.0, 0.0, 10.0))            # top at z = 20 for x > 0
    scene = SlraScene(trimesh.util.concatenate([base, block]), PLACEMENT)
    geo = ScanGeometry((64, 64), (3.0, 3.0))               # 0.37 mm pixels, footprint sigma 0.28 mm
    frame = simulate_frame(scene, looking_down(), geo, SlraParams(), np.random.default_rng(2))
    r = frame.range_m
    low, high = np.nanmedian(r[:, :20]), np.nanmedian(r[:, -20:])
    assert low - high == pytest.approx(0.020, abs=1e-3)
    between = (r < low - 0.002) & (r > high + 0.002)
    cols = np.nonzero(between)[1]
    assert between.sum() >= 64                              # at least a pixel per row
    assert np.all(np.abs(cols - 31.5) < 4)                  # all beside the step
    # the step mixes without bias: half-way range sits on the edge (x = 0)
    sharp = simulate_frame(scene, looking_down(), geo, SlraParams(beam_waist_m=1e-6, beam_divergence_rad=1e-7),
                           np.random.default_rng(2))
    assert not ((sharp.range_m < low - 0.002) & (sharp.range_m > high + 0.002)).any()


def test_dropouts_at_grazing_incidence():
    rng = np.random.default_rng(3)
    flat = simulate_frame(SlraScene(plate(), PLACEMENT), looking_down(), SMALL, SlraParams(), rng)
    steep = simulate_frame(SlraScene(plate(tilt_deg=84.0), PLACEMENT), looking_down(), SMALL, SlraParams(), rng)
    assert np.isnan(flat.range_m).mean() < 0.01
    assert np.isnan(steep.range_m).mean() > 0.5


def test_same_seed_same_frame_other_seed_other_frame():
    scene = SlraScene(plate(), PLACEMENT)
    a = simulate_frame(scene, looking_down(), SMALL, SlraParams(), np.random.default_rng(7))
    b = simulate_frame(scene, looking_down(), SMALL, SlraParams(), np.random.default_rng(7))
    c = simulate_frame(scene, looking_down(), SMALL, SlraParams(), np.random.default_rng(8))
    np.testing.assert_array_equal(a.range_m, b.range_m)
    np.testing.assert_array_equal(a.intensity, b.intensity)
    assert not np.array_equal(np.nan_to_num(a.range_m), np.nan_to_num(c.range_m))


def test_frame_time_stamp_and_reported_pose():
    scene = SlraScene(plate(), PLACEMENT)
    params = SlraParams(pixel_rate_hz=100e3, line_flyback_s=1e-3)
    true_pose = pose_error(looking_down(), np.random.default_rng(0), 1e-4, 1e-4)
    geo = ScanGeometry((256, 256), (20.0, 20.0))
    frame = simulate_frame(scene, true_pose, geo, params, np.random.default_rng(0),
                           reported_pose=looking_down(), timestamp=12.5)
    assert frame.frame_time == pytest.approx(256 * (256 / 100e3 + 1e-3))
    assert frame.timestamp == 12.5
    np.testing.assert_array_equal(frame.pose, looking_down())      # what the robot reports
    assert frame.range_m.shape == frame.intensity.shape == (256, 256)
    assert not frame.range_m.flags.writeable


def test_nothing_hit_is_a_dropout_with_no_intensity():
    scene = SlraScene(plate(size=20.0), PLACEMENT)                  # a small plate, void around
    frame = simulate_frame(scene, looking_down(), SMALL, SlraParams(), np.random.default_rng(0))
    assert np.isnan(frame.range_m[0, 0]) and frame.intensity[0, 0] == 0.0
    assert np.isfinite(frame.range_m[32, 32])


def test_a_ray_into_a_large_hole_meets_its_exact_wall_beside_a_small_hole():
    """A plate 10 mm thick with a 200 mm hole and a 6 mm hole whose centre is nearer the big
    hole's rim than the big hole's own centre: rays into the big hole near that rim meet
    its exact cylinder (r = 100 mm), not the mesh's polygon nor the small hole."""
    from ita.part.model import Hole, HoleRole

    big = Hole("L1", HoleRole.LIGHTENING, (0.0, 0.0, 0.0), (0.0, 0.0, 1.0), 200.0, 10.0, "P1")
    small = Hole("F1", HoleRole.FASTENER, (140.0, 0.0, 0.0), (0.0, 0.0, 1.0), 6.0, 10.0, "P1")
    solid = plate(size=600.0)
    for h, sections in ((big, 24), (small, 16)):       # coarse polygons: their chords are far inside the circles
        cutter = trimesh.creation.cylinder(radius=h.diameter / 2, height=30.0, sections=sections)
        cutter.apply_translation(h.center)
        solid = solid.difference(cutter)
    scene = SlraScene(solid, PLACEMENT, holes=(big, small))
    origin = np.array([0.0, 0.0, 450.0])
    ang = np.radians([7.5, 22.5])                        # mid-chord: the polygon's wall lies 0.86 mm inside
    target = np.column_stack([99.9 * np.cos(ang), 99.9 * np.sin(ang), [-4.0, -6.0]])
    dirs = target - origin
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    hits = scene.cast(origin, dirs)
    ends = origin + hits.dist[:, None] * dirs
    assert np.allclose(np.hypot(ends[:, 0], ends[:, 1]), 100.0, atol=1e-9)     # on the true circle
    assert np.allclose(hits.normals[:, :2], -ends[:, :2] / 100.0, atol=1e-9)  # facing the axis


def test_a_frame_cast_in_two_halves_on_two_cores_is_the_frame_cast_whole():
    """Large casts go half to a second thread (SPLIT_RAYS); every ray, its hole, its mixed
    pixel and its noise must come out as one cast gives them, in the same pixel."""
    from ita.part.model import Hole, HoleRole
    from ita.sim.slra import SPLIT_RAYS

    hole = Hole("L1", HoleRole.LIGHTENING, (10.0, -20.0, 0.0), (0.0, 0.0, 1.0), 60.0, 10.0, "P1")
    solid = plate(size=600.0).difference(trimesh.creation.cylinder(radius=30.0, height=30.0, sections=48)
                                         .apply_translation(hole.center))
    geometry = ScanGeometry((128, 160), (12.0, 12.0))
    assert geometry.shape[0] * geometry.shape[1] >= SPLIT_RAYS
    frames = []
    for split in (True, False):
        scene = SlraScene(solid, PLACEMENT, holes=(hole,))
        if split:
            assert scene.core.active, "this test needs two cores"
            calls = []
            submit = scene.core._thread.submit
            scene.core._thread.submit = lambda *a: calls.append(len(a[1]) if len(a) > 1 else 0) or submit(*a)
        else:
            scene.core._thread = None
        frames.append(simulate_frame(scene, looking_down(5.0, 3.0), geometry, SlraParams(), np.random.default_rng(4)))
    assert calls and calls[0] == geometry.shape[0] * geometry.shape[1] // 2     # the main cast went in halves
    split_frame, whole = frames
    assert np.isnan(whole.range_m).any() and np.isfinite(whole.range_m).mean() > 0.5   # the hole is in view
    assert np.array_equal(split_frame.range_m, whole.range_m, equal_nan=True)
    assert np.array_equal(split_frame.intensity, whole.intensity)
