"""The Collision Avoidance Model: primitives, conservative cover of the part, the region
tree's skipping, updates, and no missed collision against exact references."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from ita.collision import (
    TIP_CLEARANCE,
    ArmChecker,
    Regions,
    RegionTree,
    arm_tubes,
    build_tree,
    kernels,
    mesh_regions,
    shapes,
    tool_tube,
    tool_tubes,
)
from ita.collision.reference import BulletScene, FclScene, urdf_tubes
from ita.workcell import load_workcell


@pytest.fixture(scope="module")
def cell():
    return load_workcell()


@pytest.fixture(scope="module")
def part():
    from ita.part.store import load_part
    return load_part(None)


@pytest.fixture(scope="module")
def tree(cell, part):
    return build_tree(cell, part)


def _random_rotations(rng, n):
    q = rng.normal(size=(n, 4))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    x, y, z, w = q.T
    return np.stack([
        np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)], -1),
        np.stack([2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)], -1),
        np.stack([2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)], -1)], -2)


def _random_regions(rng, n):
    kinds = rng.integers(0, 3, n)
    return Regions(kinds.astype(np.int8), rng.uniform(-1, 1, (n, 3)), _random_rotations(rng, n),
                   rng.uniform(0.05, 0.5, (n, 3)) * np.where(kinds[:, None] == 0, 0.0, 1.0),
                   np.where(kinds == 2, rng.uniform(0, 0.1, n) * (rng.random(n) < 0.3), rng.uniform(0.02, 0.4, n)))


def _queries(rng, n, point_share=0.3):
    p0 = rng.uniform(-1.5, 1.5, (n, 3))
    p1 = p0 + rng.normal(size=(n, 3)) * rng.uniform(0, 1.0, (n, 1))
    points = rng.random(n) < point_share
    p1[points] = p0[points]
    r = np.where(rng.random(n) < 0.5, 0.0, rng.uniform(0, 0.2, n))
    return p0, p1, r


# ---- primitives ------------------------------------------------------------------------

def _box_point_distance(p, c, rot, half):
    local = np.einsum("...ji,...j->...i", rot, p - c)
    return np.linalg.norm(np.maximum(np.abs(local) - half, 0.0), axis=-1)


def test_segment_box_distance_matches_dense_sampling():
    rng = np.random.default_rng(1)
    n = 300
    p0, p1 = rng.uniform(-2, 2, (n, 3)), rng.uniform(-2, 2, (n, 3))
    c, rot, half = rng.uniform(-0.5, 0.5, (n, 3)), _random_rotations(rng, n), rng.uniform(0.05, 1, (n, 3))
    exact = shapes.segment_box_distance(p0, p1, c, rot, half)
    t = np.linspace(0, 1, 4001)[:, None, None]
    sampled = _box_point_distance(p0 + t * (p1 - p0), c, rot, half).min(axis=0)
    assert np.all(exact <= sampled + 1e-12)
    assert np.all(sampled - exact < 2e-3)       # the sampling's own step
    assert np.array_equal(shapes.segment_hits_box(p0, p1, c, rot, half), exact == 0.0)
    assert (exact == 0.0).any() and (exact > 0.0).any()


def test_segment_segment_distance_matches_dense_sampling():
    rng = np.random.default_rng(2)
    n = 200
    p0, p1, q0, q1 = (rng.uniform(-1, 1, (n, 3)) for _ in range(4))
    p1[:20] = p0[:20]            # points
    q1[10:30] = q0[10:30]
    exact = shapes.segment_segment_distance(p0, p1, q0, q1)
    s = np.linspace(0, 1, 401)
    a = p0[:, None, :] + s[None, :, None] * (p1 - p0)[:, None, :]
    b = q0[:, None, :] + s[None, :, None] * (q1 - q0)[:, None, :]
    sampled = np.linalg.norm(a[:, :, None] - b[:, None, :], axis=-1).min(axis=(1, 2))
    assert np.all(exact <= sampled + 1e-12)
    assert np.all(sampled - exact < 1e-2)


def test_point_tests_agree_with_distances():
    rng = np.random.default_rng(3)
    pts = rng.uniform(-1, 1, (500, 3))
    c, rot, half = np.zeros(3), _random_rotations(rng, 1)[0], np.array([0.5, 0.3, 0.2])
    assert np.array_equal(shapes.points_in_boxes(pts, c, rot, half), _box_point_distance(pts, c, rot, half) == 0)
    a, b = np.array([-0.5, 0, 0]), np.array([0.5, 0.2, 0])
    assert np.array_equal(shapes.points_in_tubes(pts, a, b, 0.3), shapes.point_segment_distance(pts, a, b) <= 0.3)
    assert np.array_equal(shapes.points_in_spheres(pts, c, 0.6), np.linalg.norm(pts, axis=1) <= 0.6)


def test_compiled_overlaps_equal_numpy_reference():
    rng = np.random.default_rng(4)
    reg = _random_regions(rng, 60)
    p0, p1, r = _queries(rng, 400)
    ref = shapes.queries_hit_regions(p0, p1, r, reg.kind, reg.position, reg.rotation, reg.half, reg.rad)
    got = kernels.query_pairs(p0, p1, r, reg.kind, reg.position, reg.rotation, reg.half, reg.rad,
                              reg.bounding_radius(), np.arange(len(reg)))
    assert ref.mean() > 0.01
    assert np.array_equal(got, ref)


# ---- the tree ----------------------------------------------------------------------------

def test_skipping_children_equals_brute_force():
    rng = np.random.default_rng(5)
    reg = _random_regions(rng, 400)
    reg = Regions(reg.kind, reg.position * 4, reg.rotation, reg.half * 0.3, reg.rad * 0.3)
    t = RegionTree(leaf_size=4)
    for k, idx in enumerate(np.array_split(np.arange(400), 7)):
        t.add(f"o{k}", Regions(*(getattr(reg, f)[idx] for f in ("kind", "position", "rotation", "half", "rad"))),
              np.eye(4) if k % 2 else np.block([[_random_rotations(rng, 1)[0], np.zeros((3, 1))], [0, 0, 0, 1]]))
    t.add_group("g", ["o0", "o1", "o2"])
    assert t.containment_gaps() == []
    p0, p1, r = _queries(rng, 5000)
    p0, p1 = p0 * 3, p1 * 3
    got = t.first_hits(p0, p1, r) >= 0
    assert 0.03 < got.mean() < 0.9
    assert np.array_equal(got, t.brute_force(p0, p1, r))


def test_built_tree_is_sound(tree):
    assert tree.containment_gaps() == []
    rng = np.random.default_rng(6)
    p0 = rng.uniform([-0.5, -2.9, -0.1], [3.3, 2.9, 2.5], (4000, 3))
    p1 = p0 + rng.normal(size=p0.shape) * 0.3
    r = rng.uniform(0, 0.1, len(p0))
    assert np.array_equal(tree.first_hits(p0, p1, r) >= 0, tree.brute_force(p0, p1, r))


@pytest.mark.parametrize("source", ["features", pytest.param("mesh", marks=pytest.mark.slow)])
# the mesh's cover of the whole bulkhead takes about 30 s: slow (a user part's run in the default
# suite, tests/test_user_mesh_scaled.py, plans against a mesh cover)
def test_part_cover_is_conservative(cell, part, source):
    """Every mesh vertex and 20,000 surface points lie inside some solid region of the part."""
    pts, _ = trimesh.sample.sample_surface(part.mesh, 20000, seed=7)
    pts = np.vstack([pts, part.mesh.vertices])
    if source == "features":
        t = build_tree(cell, part)
        hit = t.first_hits(cell.part.to_world(pts), cell.part.to_world(pts))
        assert set(t.object_names(hit)) == {"part"}
    else:
        t = RegionTree()
        t.add("part", mesh_regions(part.mesh))
        assert t.points_hit(pts).all()
        inside = part.mesh.contains(np.random.default_rng(8).uniform(*part.mesh.bounds, (20000, 3)))
        probe = np.random.default_rng(8).uniform(*part.mesh.bounds, (20000, 3))[inside]
        assert len(probe) > 100 and t.points_hit(probe).all()


def test_clipping_triangles_to_boxes_keeps_the_piece_inside():
    """Clipped pieces lie in their box and their triangle's plane; a triangle inside its box
    comes back whole, one beside it not at all; sampled points of a triangle inside the box
    lie in the piece's hull (its box, here)."""
    from ita.collision.mesh_cover import clip_to_boxes

    rng = np.random.default_rng(5)
    tri = rng.uniform(-1, 1, (400, 3, 3))
    lo = rng.uniform(-1, 0, (400, 3))
    hi = lo + rng.uniform(0.2, 1.0, (400, 3))
    tri[0] = [[0.1, 0.1, 0.1], [0.2, 0.1, 0.1], [0.1, 0.2, 0.15]]
    lo[0], hi[0] = np.zeros(3), np.ones(3)
    tri[1] = tri[0] + 5.0
    lo[1], hi[1] = np.zeros(3), np.ones(3)
    pts, owner = clip_to_boxes(tri, lo, hi)
    assert np.all(pts >= lo[owner] - 1e-9) and np.all(pts <= hi[owner] + 1e-9)
    n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    assert np.allclose(np.einsum("ij,ij->i", n[owner], pts - tri[owner, 0]), 0.0, atol=1e-9)
    assert np.allclose(pts[owner == 0], tri[0]) and not np.any(owner == 1)
    w = rng.dirichlet(np.ones(3), (400, 200))
    samples = np.einsum("tsk,tkj->tsj", w, tri)
    for t in range(2, 400):
        inside = np.all((samples[t] >= lo[t]) & (samples[t] <= hi[t]), axis=1)
        if inside.any():
            mine = pts[owner == t]
            assert len(mine) >= 3
            assert np.all(samples[t][inside] >= mine.min(axis=0) - 1e-9)
            assert np.all(samples[t][inside] <= mine.max(axis=0) + 1e-9)


def _flanged_channel(turn_deg: float) -> trimesh.Trimesh:
    """A web 2.5 mm thick, a wall 4 mm thick and 45 mm tall on its edge and a cap 3.2 mm
    thick overhanging the web by 28 mm at the wall's top, turned about z (slanted faces)."""
    web = trimesh.creation.box([200.0, 200.0, 2.5], trimesh.transformations.translation_matrix([0, 0, 1.25]))
    wall = trimesh.creation.box([4.0, 200.0, 45.0], trimesh.transformations.translation_matrix([-98.0, 0, 22.5]))
    cap = trimesh.creation.box([32.0, 200.0, 3.2], trimesh.transformations.translation_matrix([-84.0, 0, 43.4]))
    solid = trimesh.boolean.union([web, wall, cap], engine="manifold")
    solid.apply_transform(trimesh.transformations.rotation_matrix(np.radians(turn_deg), [0, 0, 1]))
    return solid


@pytest.mark.parametrize("turn_deg", [0.0, 30.0])
def test_mesh_cover_is_sound_and_leaves_room_beside_an_overhang(turn_deg):
    """The cover holds every point of the solid, and a probe's shaft (radius 8 mm) going
    down to the web 10 mm beside the cap's edge (its surface 18 mm away) is free of it,
    margin included: no box fills the empty corner under the cap or where the web meets
    the wall, and boxes over slanted faces lie along them."""
    solid = _flanged_channel(turn_deg)
    t = RegionTree()
    t.add("part", mesh_regions(solid, 2.0, cell_mm=40.0))
    rng = np.random.default_rng(3)
    surface, _ = trimesh.sample.sample_surface(solid, 20000, seed=4)
    interior = rng.uniform(*solid.bounds, (40000, 3))
    interior = interior[solid.contains(interior)]
    assert len(interior) > 1000
    assert t.points_hit(np.vstack([surface, interior, solid.vertices])).all()
    turn = trimesh.transformations.rotation_matrix(np.radians(turn_deg), [0, 0, 1])[:3, :3]
    ys = np.linspace(-80.0, 80.0, 9)
    for x in (-68.0 + 10.0 + 8.0, 0.0):          # 10 mm beside the cap's edge; mid-web
        a = np.column_stack([np.full(9, x), ys, np.full(9, 2.5 + 2.0 + 8.0 + 0.5)]) @ turn.T
        b = np.column_stack([np.full(9, x), ys, np.full(9, 120.0)]) @ turn.T
        assert not t.tubes_hit(a, b, np.full(9, 8.0)).any()


def test_updates_move_add_and_remove_without_rebuild(cell, part, tree):
    t = build_tree(cell, part)
    tool = cell.tool("us_probe_1")
    slot = cell.slot_of("us_probe_1").pose.matrix()
    centre_parked = (slot @ np.r_[tool.body_center, 1.0])[:3]
    assert t.object_names(t.first_hits(centre_parked, centre_parked))[0] == "us_probe_1"
    new = slot.copy()
    new[:3, 3] += [0.3, -1.2, 0.5]                      # into free space above the floor
    t.update("us_probe_1", new)
    centre_new = (new @ np.r_[tool.body_center, 1.0])[:3]
    assert t.object_names(t.first_hits(centre_new, centre_new))[0] == "us_probe_1"
    assert not t.points_hit(centre_parked)[0]
    assert t.containment_gaps() == []
    rng = np.random.default_rng(9)
    p0 = centre_new + rng.normal(size=(3000, 3)) * 0.2
    p1 = p0 + rng.normal(size=p0.shape) * 0.1
    assert np.array_equal(t.segments_hit(p0, p1), t.brute_force(p0, p1))
    t.remove("us_probe_1")
    assert not t.points_hit(centre_new)[0] and "us_probe_1" not in t.objects
    ends, radius = tool_tube(tool)
    t.add("held", Regions.tubes(*(new[:3, :3] @ ends.T).T + new[:3, 3], radius), new)
    assert t.points_hit(centre_new)[0]


def test_tool_tube_encloses_the_tool_box(cell):
    for tool in cell.tools:
        ends, radius = tool_tube(tool)
        corners = np.array(tool.body_center) + np.array(tool.body_size) / 2 * np.array(
            np.meshgrid([-1, 1], [-1, 1], [-1, 1])).reshape(3, -1).T
        assert shapes.points_in_tubes(corners, ends[0], ends[1], radius + 1e-12).all()


# ---- exact references ------------------------------------------------------------------

def _near_scene_queries(cell, part, rng, n):
    """Points and short segments near the part's surface, near box faces and anywhere."""
    surf, _ = trimesh.sample.sample_surface(part.mesh, n // 3, seed=int(rng.integers(1 << 30)))
    near_part = cell.part.to_world(surf) + rng.normal(size=(n // 3, 3)) * 0.004
    boxes = cell.static_boxes()
    pick = rng.integers(len(boxes), size=n // 3)
    local = rng.uniform(-0.5, 0.5, (n // 3, 3))
    face = rng.integers(3, size=n // 3)
    local[np.arange(n // 3), face] = np.sign(local[np.arange(n // 3), face]) * 0.5
    near_box = np.array([boxes[k].pose.matrix()[:3, :3] @ (np.array(boxes[k].size) * l) + boxes[k].pose.position
                         for k, l in zip(pick, local)]) + rng.normal(size=(n // 3, 3)) * 0.004
    anywhere = rng.uniform([-0.5, -2.9, -0.1], [3.3, 2.9, 2.5], (n - 2 * (n // 3), 3))
    p0 = np.vstack([near_part, near_box, anywhere])
    p1 = p0 + rng.normal(size=p0.shape) * rng.uniform(0.0, 0.05, (len(p0), 1))
    return p0, p1


def test_no_missed_collision_against_fcl(cell, part, tree):
    """Whenever python-fcl (exact part mesh and boxes) says a point or a segment touches the
    scene, the tree says so too; the false-positive rate is reported."""
    pytest.importorskip("fcl", reason="python-fcl is a test extra: pip install python-fcl")
    scene = FclScene(cell, part.mesh)
    rng = np.random.default_rng(10)
    p0, p1 = _near_scene_queries(cell, part, rng, 3000)
    in_material = part.mesh.contains(cell.part.to_part(p0))    # fcl sees the mesh's surface only
    for name, ref, got in (("points", scene.points_hit(p0) | in_material, tree.points_hit(p0)),
                           ("segments", scene.segments_hit(p0, p1), tree.segments_hit(p0, p1))):
        assert ref.sum() > 200
        assert not np.any(ref & ~got), f"{name}: {np.sum(ref & ~got)} collisions missed"
        print(f"\n{name}: fcl {ref.mean():.3f} hit, tree {got.mean():.3f}, false positives "
              f"{np.sum(got & ~ref) / max(1, np.sum(~ref)):.3f} of the free ones")


def test_no_missed_arm_collision_against_pybullet(cell, part, tree):
    """Random configurations: whenever pybullet (real cylinders, exact part mesh) finds a
    penetration deeper than 0.1 mm, the tube model finds a collision."""
    rng = np.random.default_rng(11)
    lo, hi = np.array(cell.arm.joints.lower), np.array(cell.arm.joints.upper)
    q = rng.uniform(lo, hi, (400, 6))
    with BulletScene(cell, part.mesh) as scene:
        links, ends, radii, _ = urdf_tubes(cell.arm.urdf, BulletScene.LINKS)
        frames = np.stack([scene.link_frames(c)[links] for c in q])          # (n, t, 4, 4)
        segs = np.einsum("ntij,tkj->ntki", frames[..., :3, :3], ends) + frames[:, :, None, :3, 3]
        ref = np.array([scene.arm_collides(c) for c in q])
    got = ArmChecker(tree, radii, links, mount=[cell.pedestal.name]).collides(segs)
    assert 0.05 < ref.mean() < 0.95
    assert not np.any(ref & ~got), f"{np.sum(ref & ~got)} arm collisions missed"
    print(f"\narm: pybullet {ref.mean():.3f} collide, tree {got.mean():.3f}, false positives "
          f"{np.sum(got & ~ref) / max(1, np.sum(~ref)):.3f} of the free ones")


def _shape_samples(kind, centre, axis_or_size, radius, length, rng, n=4000):
    """Points (n, 3) on the surface of one of ita.sim.world.tool_shapes' shapes."""
    if kind == "box":
        local = rng.uniform(-0.5, 0.5, (n, 3))
        face = rng.integers(3, size=n)
        local[np.arange(n), face] = np.sign(local[np.arange(n), face]) * 0.5
        return centre + local * axis_or_size
    axis = axis_or_size / np.linalg.norm(axis_or_size)
    u = np.cross(axis, [1.0, 0.0, 0.0] if abs(axis[0]) < 0.9 else [0.0, 1.0, 0.0])
    u /= np.linalg.norm(u)
    v = np.cross(axis, u)
    ang = rng.uniform(0.0, 2 * np.pi, n)
    s = rng.uniform(-0.5, 0.5, n) * length
    rim = centre + s[:, None] * axis + radius * (np.cos(ang)[:, None] * u + np.sin(ang)[:, None] * v)
    if kind == "cylinder":   # the rims' corners and the flat faces too
        rho = radius * np.sqrt(rng.uniform(0.0, 1.0, n))
        face = centre + np.sign(s)[:, None] * length / 2 * axis + rho[:, None] * (
            np.cos(ang)[:, None] * u + np.sin(ang)[:, None] * v)
        return np.vstack([rim, face])
    d = rng.normal(size=(n, 3))
    cap = centre + np.sign(s)[:, None] * length / 2 * axis + radius * d / np.linalg.norm(d, axis=1, keepdims=True)
    return np.vstack([rim, cap])


def test_tool_tubes_enclose_the_simulators_tool_shapes(cell):
    """Plan and simulator see the same tool: every point of each pybullet shape of a tool
    (ita.sim.world.tool_shapes) lies in its tubes, and the tubes are much tighter than the
    one enclosing tube."""
    from ita.sim.world import TIP_CLEARANCE as SIM_TIP_CLEARANCE
    from ita.sim.world import tool_shapes

    assert TIP_CLEARANCE == SIM_TIP_CLEARANCE
    rng = np.random.default_rng(12)
    for tool in cell.tools:
        ends, radii = tool_tubes(tool, TIP_CLEARANCE)
        pts = np.vstack([_shape_samples(*shape, rng) for shape in tool_shapes(tool)])
        inside = shapes.points_in_tubes(pts[:, None], ends[None, :, 0], ends[None, :, 1], radii[None] + 1e-9)
        assert inside.any(axis=1).all(), tool.name
        full, _ = tool_tubes(tool)                      # the whole probe, tip included
        assert shapes.point_segment_distance(np.array(tool.tcp.position), full[-1, 0], full[-1, 1]) <= radii[-1] + 1e-9
        assert radii.max() < 0.9 * tool_tube(tool)[1]


def test_wrist_self_collision_is_the_urdfs_not_the_capsules():
    """Links 4 and 6 meet where pybullet's real cylinder and capsule meet (j5 near 100 deg
    folded): within 20 mrad of pybullet's first contact (link 6 met as its flat-ended
    cylinder), not 18 mm earlier as the enclosing capsules did; the tight tubes stay on
    the conservative side of pybullet at every fold."""
    import pybullet as p

    from ita.kinematics import arm_model, link_segments

    cell = load_workcell()
    model = arm_model(cell.arm)
    tubes = arm_tubes(cell.arm.urdf, model.link_names)
    checker = tubes.checker(RegionTree())
    tight = tubes.apply(model)
    folds = np.linspace(1.3, 2.09, 396)                          # every 2 mrad
    q = np.column_stack([np.zeros((len(folds), 4)), folds, np.full(len(folds), 0.3)])
    cid = p.connect(p.DIRECT)
    try:
        arm = p.loadURDF(str(cell.arm.urdf), useFixedBase=True, physicsClientId=cid)
        real = []
        for c in q:
            for j, v in enumerate(c):
                p.resetJointState(arm, j, float(v), physicsClientId=cid)
            pts = p.getClosestPoints(arm, arm, 0.5, linkIndexA=3, linkIndexB=5, physicsClientId=cid)
            real.append(min(x[8] for x in pts) < 0.0)
    finally:
        p.disconnect(cid)
    real = np.array(real)
    model_says = checker.collides(link_segments(tight, q))
    loose = ArmChecker(RegionTree(), model.tube_radii, model.tube_links).collides(link_segments(model, q))
    assert real.any() and not real.all()
    assert not np.any(real & ~model_says)                     # never free where pybullet collides
    assert folds[np.argmax(model_says)] > folds[np.argmax(loose)] + 0.2   # much later than the capsules
    assert folds[np.argmax(model_says)] > folds[np.argmax(real)] - 0.02   # hardly before pybullet


def test_no_missed_collision_with_the_held_tool_against_the_simulator(cell, part):
    """Random configurations with a tool held: whenever the simulator (pybullet, the tool's
    real shapes, the nominal part) finds a contact deeper than 0.1 mm, the tight tubes do."""
    from ita.kinematics import arm_model, link_segments
    from ita.sim.world import SimWorld

    model = arm_model(cell.arm)
    rng = np.random.default_rng(13)
    lo, hi = np.array(cell.arm.joints.lower), np.array(cell.arm.joints.upper)
    with SimWorld(cell, asbuilt_mesh=part.mesh) as world:
        for name in ("us_probe_1", "us_probe_90", "slra_1"):
            tool = cell.tool(name)
            t = build_tree(cell, part)
            t.remove(name)
            tubes = arm_tubes(cell.arm.urdf, model.link_names).with_tool(tool, model.dof + 1, TIP_CLEARANCE)
            checker = tubes.checker(t, mount=[cell.pedestal.name])
            q = rng.uniform(lo, hi, (300, 6))
            world.attach(name)
            ref = []
            for c in q:
                world.set_q(c)
                ref.append(any(x.distance < -1e-4 for x in world.contacts()))
            world.detach()
            ref = np.array(ref)
            got = checker.collides(link_segments(tubes.apply(model), q))
            assert 0.05 < ref.mean() < 0.95
            assert not np.any(ref & ~got), f"{name}: {np.sum(ref & ~got)} collisions missed"


def test_no_missed_arm_collision_with_tight_tubes_against_pybullet(cell, part, tree):
    """The tight link tubes (the cylinders met as flat-ended cylinders by the other links)
    find every collision pybullet finds, self-collisions of non-adjacent links included."""
    from ita.kinematics import arm_model, link_segments

    model = arm_model(cell.arm)
    tubes = arm_tubes(cell.arm.urdf, model.link_names)
    rng = np.random.default_rng(14)
    lo, hi = np.array(cell.arm.joints.lower), np.array(cell.arm.joints.upper)
    q = rng.uniform(lo, hi, (400, 6))
    q[::2, 4] = rng.choice([-1.0, 1.0], 200) * rng.uniform(1.5, 2.09, 200)     # folded wrists
    with BulletScene(cell, part.mesh) as scene:
        ref = np.array([scene.arm_collides(c) for c in q])
    got = tubes.checker(tree, mount=[cell.pedestal.name]).collides(link_segments(tubes.apply(model), q))
    assert not np.any(ref & ~got), f"{np.sum(ref & ~got)} arm collisions missed"


def test_pair_gap_meets_a_flat_cylinder_exactly_and_never_late():
    """A capsule against a flat-ended cylinder: the gap is a lower bound of the true
    distance (dense samples of the segment against the exact point-cylinder distance)
    and within the samples' spacing of it."""
    from ita.collision.kernels import pair_gap

    rng = np.random.default_rng(21)
    t = np.linspace(0.0, 1.0, 20001)[:, None]
    for _ in range(60):
        p0, p1, q0, q1 = rng.normal(size=(4, 3)) * 0.2
        rq, rc = rng.uniform(0.01, 0.1), rng.uniform(0.02, 0.15)
        u = (q1 - q0) / np.linalg.norm(q1 - q0)
        w = p0 + t * (p1 - p0) - (q0 + q1) / 2
        h = w @ u
        rho = np.sqrt(np.maximum((w * w).sum(axis=1) - h * h, 0.0))
        along = np.maximum(np.abs(h) - np.linalg.norm(q1 - q0) / 2, 0.0)
        true = np.hypot(along, np.maximum(rho - rc, 0.0)).min() - rq
        got = pair_gap(p0, p1, rq, 0.0, q0, q1, rc, rc)
        assert got <= true + 1e-12
        assert got >= true - 1e-5                  # the samples' own spacing
