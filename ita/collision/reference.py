"""Exact reference checkers on the same scene, for tests and benchmarks (not the planner).

`BulletScene` (pybullet, a DIRECT client of its own) and `FclScene` (python-fcl, a test
and bench extra) hold the workcell's boxes, the parked tools' boxes, the part's triangle
mesh (exact, no margin) and, in pybullet, the arm from its URDF with its real cylinders
and capsules.  Each import happens only when a scene is made.

Both see a triangle mesh as its surface: a point or segment wholly inside the part's
material is not a collision for them (the region tree says it is).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ita.bullet import import_pybullet
from ita.collision.arm import urdf_tubes  # noqa: F401  (its home was here; tests import it from here)
from ita.workcell.frames import homogeneous, matrix_to_quaternion, quaternion_to_matrix
from ita.workcell.model import Workcell


def _part_world(cell: Workcell, mesh: Any) -> tuple[np.ndarray, np.ndarray]:
    return cell.part.to_world(np.asarray(mesh.vertices)), np.asarray(mesh.faces, dtype=np.int64)


def _world_boxes(cell: Workcell, parked_tools: bool) -> list[tuple[str, np.ndarray, np.ndarray]]:
    """(name, (4, 4) pose of the box centre, full size (3,))."""
    out = [(b.name, b.pose.matrix(), np.asarray(b.size)) for b in cell.static_boxes()]
    if parked_tools:
        for slot in cell.rack.slots:
            if slot.tool:
                tool = cell.tool(slot.tool)
                pose = slot.pose.matrix() @ homogeneous(np.eye(3), tool.body_center)
                out.append((tool.name, pose, np.asarray(tool.body_size)))
    return out


class BulletScene:
    """The scene in a private pybullet DIRECT client; close() (or use as a context manager)."""

    LINKS = ("base_link", "link1", "link2", "link3", "link4", "link5", "link6", "flange")

    def __init__(self, cell: Workcell, part_mesh: Any | None = None, parked_tools: bool = True) -> None:
        p = import_pybullet()
        self.p = p
        self.cid = p.connect(p.DIRECT)
        self.bodies: dict[int, str] = {}
        for name, pose, size in _world_boxes(cell, parked_tools):
            shape = p.createCollisionShape(p.GEOM_BOX, halfExtents=(size / 2).tolist(), physicsClientId=self.cid)
            body = p.createMultiBody(0, shape, basePosition=pose[:3, 3].tolist(),
                                     baseOrientation=matrix_to_quaternion(pose[:3, :3]).tolist(),
                                     physicsClientId=self.cid)
            self.bodies[body] = name
        if part_mesh is not None:
            v, f = _part_world(cell, part_mesh)
            shape = p.createCollisionShape(p.GEOM_MESH, vertices=v.tolist(), indices=f.ravel().tolist(),
                                           physicsClientId=self.cid)
            self.bodies[p.createMultiBody(0, shape, physicsClientId=self.cid)] = "part"
        base = cell.arm.base
        self.base = base.matrix()
        self.arm = p.loadURDF(str(cell.arm.urdf), list(base.position), list(base.quaternion), useFixedBase=True,
                              flags=p.URDF_USE_SELF_COLLISION, physicsClientId=self.cid)
        self.joints = [j for j in range(p.getNumJoints(self.arm, physicsClientId=self.cid))
                       if p.getJointInfo(self.arm, j, physicsClientId=self.cid)[2] == p.JOINT_REVOLUTE]
        self.sphere = None

    def close(self) -> None:
        """Disconnect the client."""
        if self.cid is not None:
            self.p.disconnect(self.cid)
            self.cid = None

    def __enter__(self) -> BulletScene:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def set_config(self, q: np.ndarray) -> None:
        """Set the six joint angles (rad)."""
        for j, v in zip(self.joints, q):
            self.p.resetJointState(self.arm, j, float(v), physicsClientId=self.cid)

    def link_frames(self, q: np.ndarray) -> np.ndarray:
        """(8, 4, 4) world frames of base_link, link1..link6, flange at configuration q."""
        self.set_config(q)
        out = [self.base]  # pybullet's base pose is the base's inertial frame, not its link frame
        for link in range(len(self.LINKS) - 1):
            st = self.p.getLinkState(self.arm, link, computeForwardKinematics=True, physicsClientId=self.cid)
            out.append(homogeneous(quaternion_to_matrix(st[5]), st[4]))
        return np.stack(out)

    def arm_collides(self, q: np.ndarray, tol: float = 1e-4) -> bool:
        """Whether the arm at q penetrates the scene or itself by more than tol (m)
        (whole-scene performCollisionDetection; the fixed base link is ignored)."""
        self.set_config(q)
        self.p.performCollisionDetection(physicsClientId=self.cid)
        for c in self.p.getContactPoints(bodyA=self.arm, physicsClientId=self.cid):
            if c[8] < -tol and not (c[3] == -1 and c[2] != self.arm):
                return True
        return False

    def points_hit(self, points: np.ndarray, radius: float = 1e-4) -> np.ndarray:
        """Bool (n,): whether a sphere of `radius` at each point touches a body other than
        the arm (whole-scene collision detection per point)."""
        p = self.p
        if self.sphere is None:
            shape = p.createCollisionShape(p.GEOM_SPHERE, radius=radius, physicsClientId=self.cid)
            self.sphere = p.createMultiBody(1.0, shape, basePosition=[0, 0, -10], physicsClientId=self.cid)
        out = np.zeros(len(points), dtype=bool)
        for i, pt in enumerate(points):
            p.resetBasePositionAndOrientation(self.sphere, pt.tolist(), [0, 0, 0, 1], physicsClientId=self.cid)
            p.performCollisionDetection(physicsClientId=self.cid)
            out[i] = any(c[8] <= 0.0 and c[2] != self.arm
                         for c in p.getContactPoints(bodyA=self.sphere, physicsClientId=self.cid))
        return out

    def segments_hit(self, p0: np.ndarray, p1: np.ndarray) -> np.ndarray:
        """Bool (n,): whether rays p0 -> p1 or p1 -> p0 hit a body other than the arm.  (A
        segment wholly inside a body is not seen; endpoints inside are checked separately.)"""
        hit = np.zeros(len(p0), dtype=bool)
        for a, b in ((p0, p1), (p1, p0)):
            for s in range(0, len(a), 4096):
                res = self.p.rayTestBatch(a[s:s + 4096].tolist(), b[s:s + 4096].tolist(),
                                          physicsClientId=self.cid)
                hit[s:s + 4096] |= np.array([r[0] >= 0 and r[0] != self.arm for r in res])
        return hit


class FclScene:
    """The scene (boxes, parked tools, part mesh) as python-fcl objects under one broadphase."""

    def __init__(self, cell: Workcell, part_mesh: Any | None = None, parked_tools: bool = True) -> None:
        import fcl
        self.fcl = fcl
        self.objects = []
        for _, pose, size in _world_boxes(cell, parked_tools):
            self.objects.append(fcl.CollisionObject(fcl.Box(*size), fcl.Transform(pose[:3, :3], pose[:3, 3])))
        if part_mesh is not None:
            v, f = _part_world(cell, part_mesh)
            model = fcl.BVHModel()
            model.beginModel(len(v), len(f))
            model.addSubModel(v, f)
            model.endModel()
            self.objects.append(fcl.CollisionObject(model, fcl.Transform()))
        self.manager = fcl.DynamicAABBTreeCollisionManager()
        self.manager.registerObjects(self.objects)
        self.manager.setup()
        self._point = fcl.CollisionObject(fcl.Sphere(1e-7), fcl.Transform())

    def _collides(self, obj: Any) -> bool:
        data = self.fcl.CollisionData(request=self.fcl.CollisionRequest())
        self.manager.collide(obj, data, self.fcl.defaultCollisionCallback)
        return bool(data.result.is_collision)

    def points_hit(self, points: np.ndarray) -> np.ndarray:
        """Bool (n,): whether each point (as a 0.1 um sphere) touches a solid."""
        out = np.zeros(len(points), dtype=bool)
        for i, pt in enumerate(points):
            self._point.setTranslation(pt)
            out[i] = self._collides(self._point)
        return out

    def segments_hit(self, p0: np.ndarray, p1: np.ndarray) -> np.ndarray:
        """Bool (n,): whether each segment (as a capsule of radius 0.1 um) touches a solid."""
        out = np.zeros(len(p0), dtype=bool)
        for i, (a, b) in enumerate(zip(p0, p1)):
            d = b - a
            length = float(np.linalg.norm(d))
            z = d / length if length > 0 else np.array([0.0, 0.0, 1.0])
            helper = np.array([1.0, 0.0, 0.0]) if abs(z[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
            x = np.cross(helper, z)
            x /= np.linalg.norm(x)
            rot = np.column_stack([x, np.cross(z, x), z])
            obj = self.fcl.CollisionObject(self.fcl.Capsule(1e-7, length), self.fcl.Transform(rot, (a + b) / 2))
            out[i] = self._collides(obj)
        return out

    def capsules_hit(self, ends: np.ndarray, radii: np.ndarray) -> bool:
        """Whether any of the capsules (ends (t, 2, 3), radii (t,)) touches a solid."""
        for (a, b), r in zip(ends, radii):
            d = b - a
            length = float(np.linalg.norm(d))
            z = d / length
            helper = np.array([1.0, 0.0, 0.0]) if abs(z[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
            x = np.cross(helper, z)
            x /= np.linalg.norm(x)
            rot = np.column_stack([x, np.cross(z, x), z])
            if self._collides(self.fcl.CollisionObject(self.fcl.Capsule(float(r), length),
                                                       self.fcl.Transform(rot, (a + b) / 2))):
                return True
        return False
