"""The simulated workcell: a pybullet DIRECT world, its simulated clock and its state.

    with SimWorld(seed=1) as world:          # the built-in workcell and as-built bulkhead
        world.set_q(q)                       # kinematic: joints are set, not driven
        world.contacts()                     # what the arm or its tool touches now
        with world.saved_state():            # try something, then put the world back
            world.attach("us_probe_1")

The world owns one pybullet client (never a global one); every call names it.  Bodies:
the arm (its URDF at the base pose, fixed base), the AS-BUILT part as a static concave
triangle mesh (part millimetres scaled to metres and placed by the `PartPlacement`), a
box per static box of the workcell (floor, pedestal, fixture, rack, stations, stands,
fence), and one body per tool.  A tool is parked at its rack slot or held: then its
frame is the flange frame, updated whenever the joints are.

Tool collision shapes: a straight tool is its `ToolSpec` body box; a contact probe is a
holder cylinder along the flange axis up to the bend and a shaft capsule along the tip
axis that stops `tip_clearance` short of the tip, so the spring-loaded tip (which the
gauge models, see ita.sim.ultrasonic) can touch the part without a bump while an
over-travel of the holder does bump.

Physical state beyond the joints (the couplant spots on the part, the arm's accumulated
drift) lives here too, so that `saved_state` restores it; the clock never runs back.
"""

from __future__ import annotations

import contextlib
import math
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass
from typing import Self

import numpy as np
import trimesh
from numpy.typing import NDArray

from ita.bullet import import_pybullet
from ita.kinematics import ArmModel, arm_model, flange_poses, link_frames
from ita.part.store import load_part
from ita.part.truth import simulated_part as _simulated
from ita.sim.faults import FaultSet
from ita.workcell import Box, Pose, ToolSpec, Workcell, load_workcell
from ita.workcell.frames import homogeneous, matrix_to_quaternion, quaternion_to_matrix
from ita.workcell.model import TIP_CLEARANCE, PartPlacement

p = import_pybullet()   # the pybullet module (its build-time line silenced)

FloatArray = NDArray[np.float64]
PART = "part"


class SimClock:
    """Simulated time in seconds since the world was built; it only moves forward."""

    def __init__(self) -> None:
        self._now = 0.0
        #: told the new time after every advance (a two-arm run's gate: the conductor then
        #: knows this arm makes no claim before it); None: no one
        self.on_advance: Callable[[float], None] | None = None

    @property
    def now(self) -> float:
        """The current simulated time (s)."""
        return self._now

    def advance(self, seconds: float) -> float:
        """Let `seconds` (>= 0) pass; returns the new time."""
        if seconds < 0.0:
            raise ValueError(f"the clock cannot run back ({seconds} s)")
        self._now += float(seconds)
        if self.on_advance is not None:
            self.on_advance(self._now)
        return self._now


@dataclass(frozen=True)
class Contact:
    """Something touching (or within the margin of) something it should not.

    moving: the arm link's name or the held tool's name; obstacle: the other body's name
    (a workcell box, 'part', a tool, or an arm link for the held tool); point: a world
    point of the contact (m) on the moving body; distance: signed gap (m), < 0 penetrating.
    """

    moving: str
    obstacle: str
    point: tuple[float, float, float]
    distance: float


@dataclass(frozen=True)
class CouplantSpot:
    """Couplant put on the part: centre (part frame, mm), radius (mm), when (s)."""

    center_mm: tuple[float, float, float]
    radius_mm: float
    time_s: float


@dataclass(frozen=True)
class SimSnapshot:
    """What `SimWorld.saved_state` saves and restores."""

    q: tuple[float, ...]
    held: str | None
    couplant: tuple[CouplantSpot, ...]
    drift_m: tuple[float, float, float]


class SimWorld:
    """The simulated workcell.  Use as a context manager (or call `close`).

    cell: the workcell (None: the built-in one); part_dir: the part whose as-built mesh
    to load (None: the built-in bulkhead, materialised on first use); asbuilt_mesh: a mesh
    (part frame, mm) to use instead (tests); seed: of every random draw in the simulator;
    faults: the faults switched on (replace `world.faults` to change them later).
    q0: the initial configuration (default zeros).  part_placement: where the part really
    sits (ita.sim.fixture; default: exactly at the cell's nominal placement); only the
    simulator knows it (:meth:`place_part` moves it).
    """

    def __init__(
        self,
        cell: Workcell | None = None,
        part_dir=None,
        *,
        asbuilt_mesh: trimesh.Trimesh | None = None,
        seed: int = 0,
        faults: FaultSet | None = None,
        q0: Iterable[float] | None = None,
        part_placement: PartPlacement | None = None,
    ) -> None:
        self.cell = cell if cell is not None else load_workcell()
        self.part_placement: PartPlacement = part_placement if part_placement is not None else self.cell.part
        self.model: ArmModel = arm_model(self.cell.arm)
        self.asbuilt_mesh = asbuilt_mesh if asbuilt_mesh is not None else _load_asbuilt(part_dir)
        self.seed = int(seed)
        self.rng = np.random.default_rng([self.seed, 0])
        self.faults = faults if faults is not None else FaultSet()
        self.clock = SimClock()
        self.couplant: tuple[CouplantSpot, ...] = ()
        self.drift_m = np.zeros(3)
        self.held: str | None = None
        self.obstacles: dict[str, int] = {}       # name -> pybullet body of an unknown obstacle
        self.client = p.connect(p.DIRECT)
        try:
            self._build()
            self.set_q(np.zeros(6) if q0 is None else np.asarray(list(q0), dtype=float))
        except BaseException:
            p.disconnect(self.client)
            raise

    # -- building -----------------------------------------------------------------------
    def _build(self) -> None:
        c = self.client
        self.body_names: dict[int, str] = {}
        self.bodies: dict[str, int] = {}
        for box in self.cell.static_boxes():
            self._add(box.name, _box_body(box, c))
        self._add(PART, _mesh_body(self.asbuilt_mesh, self.part_placement, c))
        arm = self.cell.arm
        self.arm = p.loadURDF(str(arm.urdf), arm.base.position, arm.base.quaternion,
                              useFixedBase=True, physicsClientId=c)
        self.body_names[self.arm] = arm.name
        joints = {}
        self.link_names: dict[int, str] = {-1: p.getBodyInfo(self.arm, physicsClientId=c)[0].decode()}
        for j in range(p.getNumJoints(self.arm, physicsClientId=c)):
            info = p.getJointInfo(self.arm, j, physicsClientId=c)
            joints[info[1].decode()] = j
            self.link_names[j] = info[12].decode()
        self.joint_indices = tuple(joints[n] for n in self.model.joint_names)
        self.flange_link = next(j for j, n in self.link_names.items() if n == arm.flange_link)
        self._arm_links = tuple(j for j in range(p.getNumJoints(self.arm, physicsClientId=c))
                                if p.getCollisionShapeData(self.arm, j, physicsClientId=c))
        self._self_links = frozenset(self._arm_links[:-1])     # what a held tool may touch of the arm
        self.link_reach = self._link_reach()
        self.tools: dict[str, int] = {}
        for tool in self.cell.tools:
            body = _tool_body(tool, c)
            self.tools[tool.name] = body
            self._add(tool.name, body)
            slot = self.cell.slot_of(tool.name)
            p.resetBasePositionAndOrientation(body, slot.pose.position, slot.pose.quaternion, physicsClientId=c)
        self._static = [b for n, b in self.bodies.items() if n not in self.tools]
        self._static_aabbs = {b: np.array(p.getAABB(b, physicsClientId=c)) for b in self._static}

    def _link_reach(self) -> FloatArray:
        """Per link of the arm model's chain (`model.link_names`), how far (m) its collision
        shapes, and those of the links fixed to it, reach from the link's origin: the
        farthest corner of pybullet's boxes around them, as the arm is loaded (all joints
        at 0).  How far a turn of the link can move a point of it, whatever the shapes."""
        c = self.client
        frames = link_frames(self.model, np.zeros(self.model.dof))[0]
        index = {name: k for k, name in enumerate(self.model.link_names)}
        reach = np.zeros(len(index))
        for j in self._arm_links:
            up = j                                 # up the tree to the link of the chain it is fixed to
            while up >= 0 and self.link_names[up] not in index:
                up = p.getJointInfo(self.arm, up, physicsClientId=c)[16]
            k = index[self.link_names[up]] if up >= 0 else 0
            lo, hi = (np.asarray(v, dtype=float) for v in p.getAABB(self.arm, j, physicsClientId=c))
            corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
            reach[k] = max(reach[k], float(np.linalg.norm(corners - frames[k, :3, 3], axis=1).max()))
        return reach

    def place_part(self, placement: PartPlacement) -> None:
        """Move the part to `placement` (a knock on the fixture, a person clamping it again)."""
        self.part_placement = placement
        quat = matrix_to_quaternion(placement.rotation_matrix())
        p.resetBasePositionAndOrientation(self.bodies[PART], placement.translation, quat.tolist(),
                                          physicsClientId=self.client)
        body = self.bodies[PART]
        self._static_aabbs[body] = np.array(p.getAABB(body, physicsClientId=self.client))

    def _add(self, name: str, body: int) -> None:
        self.bodies[name] = body
        self.body_names[body] = name

    # -- context ------------------------------------------------------------------------
    def close(self) -> None:
        """Disconnect the pybullet client (idempotent)."""
        if self.client >= 0 and p.isConnected(self.client):
            p.disconnect(self.client)
        self.client = -1

    def __enter__(self) -> Self:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def state(self) -> SimSnapshot:
        """A snapshot of the world's state (not the clock)."""
        return SimSnapshot(tuple(map(float, self.q)), self.held, self.couplant,
                          tuple(map(float, self.drift_m)))  # type: ignore[arg-type]

    def restore(self, state: SimSnapshot) -> None:
        """Put the world back into a snapshot: tools parked or held, joints, couplant, drift."""
        if self.held is not None and self.held != state.held:
            self.detach()
        self.held = state.held
        self.couplant = state.couplant
        self.drift_m = np.array(state.drift_m)
        self.set_q(np.array(state.q))

    @contextlib.contextmanager
    def saved_state(self) -> Iterator[SimWorld]:
        """Context manager: whatever happens inside, the world's state is restored after."""
        saved = self.state()
        try:
            yield self
        finally:
            self.restore(saved)

    # -- arm and tools ------------------------------------------------------------------
    @property
    def q(self) -> FloatArray:
        """The arm's joint angles (6,) rad (a copy)."""
        return self._q.copy()

    def set_q(self, q: Iterable[float], flange: FloatArray | None = None) -> None:
        """Place the arm at joint angles q (6,) (kinematically); a held tool follows.
        flange: the flange's pose at q when the caller has it (forward kinematics of a
        whole trajectory at once)."""
        q = np.asarray(list(q) if not isinstance(q, np.ndarray) else q, dtype=float).reshape(6)
        p.resetJointStatesMultiDof(self.arm, self.joint_indices, [[value] for value in q.tolist()],
                                   physicsClientId=self.client)
        self._q = q.copy()
        if self.held is not None:
            self._place_tool(self.held, self.flange_pose() if flange is None else flange)

    def flange_pose(self, q: Iterable[float] | None = None) -> FloatArray:
        """World pose (4, 4) of the flange at q (default: the current joints)."""
        return flange_poses(self.model, self._q if q is None else np.asarray(q, dtype=float))[0]

    def tcp_pose(self, q: Iterable[float] | None = None) -> FloatArray:
        """World pose (4, 4) of the held tool's TCP (the flange without a tool)."""
        pose = self.flange_pose(q)
        return pose @ self.held_tool.tcp.matrix() if self.held_tool is not None else pose

    @property
    def held_tool(self) -> ToolSpec | None:
        """The ToolSpec of the held tool, or None."""
        return self.cell.tool(self.held) if self.held is not None else None

    def tool_pose(self, name: str) -> FloatArray:
        """World pose (4, 4) of a tool's frame (its flange coupling), as pybullet has it."""
        pos, quat = p.getBasePositionAndOrientation(self.tools[name], physicsClientId=self.client)
        return _matrix(pos, quat)

    def attach(self, name: str) -> None:
        """The tool `name` is now held: it moves with the flange."""
        if self.held is not None:
            raise RuntimeError(f"already holding {self.held!r}")
        if name not in self.tools:
            raise KeyError(name)
        self.held = name
        self._place_tool(name, self.flange_pose())

    def detach(self) -> str:
        """Let go of the held tool; it is back in its rack slot.  Returns its name."""
        if self.held is None:
            raise RuntimeError("no tool is held")
        name, self.held = self.held, None
        slot = self.cell.slot_of(name)
        p.resetBasePositionAndOrientation(self.tools[name], slot.pose.position, slot.pose.quaternion,
                                          physicsClientId=self.client)
        return name

    def _place_tool(self, name: str, pose: FloatArray) -> None:
        p.resetBasePositionAndOrientation(self.tools[name], pose[:3, 3].tolist(),
                                          matrix_to_quaternion(pose[:3, :3]).tolist(),
                                          physicsClientId=self.client)

    def link_pose(self, link: int) -> FloatArray:
        """World pose (4, 4) of an arm link's URDF frame, as pybullet computes it."""
        state = p.getLinkState(self.arm, link, computeForwardKinematics=True, physicsClientId=self.client)
        return _matrix(state[4], state[5])

    # -- contacts -----------------------------------------------------------------------
    def contacts(self, margin: float = 0.0, ignore: Iterable[str] = ()) -> list[Contact]:
        """What the arm and the held tool touch now, closer than `margin` (m).

        Checked: every arm link but the base (which sits on its pedestal) against every
        static body, the part and every parked tool; the held tool against the same and
        against the arm's links except the last (which carries it).  Bodies named in
        `ignore` are left out (an intended contact, e.g. the tool being picked up).
        """
        return self.contacts_and_gaps(margin, ignore, margin)[0]

    def contacts_and_gaps(self, margin: float = 0.0, ignore: Iterable[str] = (),
                          upto: float = 0.0) -> tuple[list[Contact], float, float]:
        """:meth:`contacts`, and the smallest gaps (m) of the same pairs, as far as `upto`
        (>= margin; `upto` when every pair is farther): the arm's and the held tool's to
        the cell (the static bodies, the part, the parked tools), and the held tool's to the
        arm's links (infinite without a tool).  How far the arm may move before a contact is
        possible."""
        c = self.client
        skip = set(ignore)
        found: list[Contact] = []
        gap = tool_gap = upto = max(float(upto), float(margin))
        if self.held is None:
            tool_gap = math.inf
        others = [b for b in self._static] + [b for n, b in self.tools.items() if n != self.held]
        others = [b for b in others if self.body_names[b] not in skip]
        lo, hi = self._moving_aabb(upto)
        if others:
            boxes = np.array([self._static_aabbs[b] if b in self._static_aabbs else p.getAABB(b, physicsClientId=c)
                              for b in others])
            apart = np.asarray((boxes[:, 0] > hi).any(axis=1) | (boxes[:, 1] < lo).any(axis=1), dtype=bool)
            others = [b for b, away in zip(others, apart.tolist()) if not away]
        for body in others:
            for pt in p.getClosestPoints(self.arm, body, upto, physicsClientId=c):
                if pt[3] >= 0:
                    gap = min(gap, pt[8])
                    if pt[8] <= margin:
                        found.append(Contact(self.link_names[pt[3]], self.body_names[body], pt[5], pt[8]))
            if self.held is not None:
                for pt in p.getClosestPoints(self.tools[self.held], body, upto, physicsClientId=c):
                    gap = min(gap, pt[8])
                    if pt[8] <= margin:
                        found.append(Contact(self.held, self.body_names[body], pt[5], pt[8]))
        if self.held is not None:         # the held tool against the arm's links but the last (one query)
            for pt in p.getClosestPoints(self.tools[self.held], self.arm, upto, physicsClientId=c):
                if pt[4] in self._self_links:
                    tool_gap = min(tool_gap, pt[8])
                    if pt[8] <= margin:
                        found.append(Contact(self.held, self.link_names[pt[4]], pt[5], pt[8]))
        return found, gap, tool_gap

    def _moving_aabb(self, margin: float) -> tuple[FloatArray, FloatArray]:
        c = self.client
        boxes = [p.getAABB(self.arm, j, physicsClientId=c) for j in self._arm_links]
        if self.held is not None:
            boxes.append(p.getAABB(self.tools[self.held], physicsClientId=c))
        arr = np.array(boxes)
        return arr[:, 0].min(axis=0) - margin, arr[:, 1].max(axis=0) + margin

    # -- obstacles the collision model does not know ------------------------------------------
    def add_obstacle(self, name: str, center: Iterable[float], size: Iterable[float]) -> None:
        """Put a box `name` (centre, size in m, world frame) in the cell: the arm bumps it."""
        cx, cy, cz = map(float, center)
        sx, sy, sz = map(float, size)
        box = Box(name, Pose((cx, cy, cz), (0.0, 0.0, 0.0, 1.0)), (sx, sy, sz))
        body = _box_body(box, self.client)
        self._add(name, body)
        self.obstacles[name] = body
        self._static.append(body)
        self._static_aabbs[body] = np.array(p.getAABB(body, physicsClientId=self.client))

    def remove_obstacle(self, name: str) -> bool:
        """Take obstacle `name` out of the cell; whether there was one."""
        body = self.obstacles.pop(name, None)
        if body is None:
            return False
        p.removeBody(body, physicsClientId=self.client)
        self._static.remove(body)
        self._static_aabbs.pop(body, None)
        self.bodies.pop(name, None)
        self.body_names.pop(body, None)
        return True

    # -- couplant -----------------------------------------------------------------------
    def add_couplant(self, spot: CouplantSpot) -> None:
        """Couplant now lies on the part at `spot`."""
        self.couplant = self.couplant + (spot,)


def _load_asbuilt(part_dir) -> trimesh.Trimesh:
    part = load_part(part_dir)
    return simulated_part(part.directory, part.mesh).mesh


def simulated_part(part_dir, nominal: trimesh.Trimesh):
    """What the simulated cell holds for the part in `part_dir` (ita.part.truth.SimulatedPart):
    its as-built truth, else the user's asbuilt mesh, else the nominal mesh `nominal`."""
    return _simulated(part_dir, nominal)


def _matrix(pos, quat) -> FloatArray:
    return homogeneous(quaternion_to_matrix(quat), pos)


def _box_body(box: Box, client: int) -> int:
    half = [s / 2.0 for s in box.size]
    shape = p.createCollisionShape(p.GEOM_BOX, halfExtents=half, physicsClientId=client)
    return p.createMultiBody(0.0, shape, basePosition=box.pose.position,
                             baseOrientation=box.pose.quaternion, physicsClientId=client)


def _mesh_body(mesh: trimesh.Trimesh, placement: PartPlacement, client: int) -> int:
    """The part as a static concave triangle mesh: vertices scaled to m, placed in the world."""
    vertices = (np.asarray(mesh.vertices, dtype=float) * placement.scale).tolist()
    indices = np.asarray(mesh.faces, dtype=np.int64).reshape(-1).tolist()
    shape = p.createCollisionShape(p.GEOM_MESH, vertices=vertices, indices=indices,
                                   flags=p.GEOM_FORCE_CONCAVE_TRIMESH, physicsClientId=client)
    quat = matrix_to_quaternion(placement.rotation_matrix())
    return p.createMultiBody(0.0, shape, basePosition=placement.translation,
                             baseOrientation=quat.tolist(), physicsClientId=client)


def tool_shapes(tool: ToolSpec) -> list[tuple[str, FloatArray, FloatArray, float, float]]:
    """A tool's collision shapes in its (flange) frame: (kind, centre (3,), axis (3,),
    radius, length) for 'cylinder'/'capsule' along `axis`, or ('box', centre, size, 0, 0).

    Tools with a stand-off are their body box; contact probes their ProbeShape
    (ita.workcell.model): the holder a cylinder, the shaft a capsule that stops
    TIP_CLEARANCE (plus its radius) short of the tip.
    """
    shape = tool.probe_shape()
    if shape is None:
        return [("box", np.asarray(tool.body_center, float), np.asarray(tool.body_size, float), 0.0, 0.0)]
    start, bend = np.asarray(shape.holder_start), np.asarray(shape.bend)
    holder_len = bend[2] - start[2]
    shapes = [("cylinder", np.array([0.0, 0.0, start[2] + holder_len / 2]), np.array([0.0, 0.0, 1.0]),
               shape.holder_radius, holder_len)]
    end = shape.shaft_end(TIP_CLEARANCE)
    shaft = end - bend
    length = float(np.linalg.norm(shaft))
    if length > 1e-6:
        shapes.append(("capsule", (bend + end) / 2, shaft / length, shape.shaft_radius, length))
    return shapes


def _tool_body(tool: ToolSpec, client: int) -> int:
    types, radii, halves, lengths, positions, orientations = [], [], [], [], [], []
    for kind, centre, axis_or_size, radius, length in tool_shapes(tool):
        positions.append(centre.tolist())
        if kind == "box":
            types.append(p.GEOM_BOX)
            halves.append((axis_or_size / 2).tolist())
            orientations.append([0.0, 0.0, 0.0, 1.0])
        else:
            types.append(p.GEOM_CYLINDER if kind == "cylinder" else p.GEOM_CAPSULE)
            halves.append([0.0, 0.0, 0.0])
            orientations.append(_z_to(axis_or_size).tolist())
        radii.append(radius)
        lengths.append(length)
    shape = p.createCollisionShapeArray(types, radii=radii, halfExtents=halves, lengths=lengths,
                                        collisionFramePositions=positions,
                                        collisionFrameOrientations=orientations, physicsClientId=client)
    return p.createMultiBody(0.0, shape, physicsClientId=client)


def _z_to(axis: FloatArray) -> FloatArray:
    """Quaternion (4,) turning +z onto the unit vector `axis` (3,)."""
    z = np.array([0.0, 0.0, 1.0])
    a = np.asarray(axis, dtype=float) / np.linalg.norm(axis)
    v = np.cross(z, a)
    w = 1.0 + float(z @ a)
    if w < 1e-9:
        return np.array([1.0, 0.0, 0.0, 0.0])
    q = np.array([*v, w])
    return q / np.linalg.norm(q)
