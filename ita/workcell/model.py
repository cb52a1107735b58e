"""Value types of the workcell: the arm, the part's placement, fixture, rack, tools.

All lengths are metres and all angles radians in the world frame (z up, floor at z = 0),
except where a name says otherwise (`_mm`, `_deg`, `_kg`).  Quaternions are (x, y, z, w).
`load.load_workcell` builds these from `bulkhead/workcell.toml` and `bulkhead/t3_arm.urdf`.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from ita.specs.model import Tool
from ita.workcell import frames

Vec3 = tuple[float, float, float]

#: the arm's home configuration (rad) unless a workcell.toml says otherwise (robot.home_rad)
HOME_Q = (0.0, -0.6, 0.9, 0.0, 0.9, 0.0)
#: the flange above a rack slot along its axis at a tool change (m), unless rack.approach_m says
RACK_APPROACH_M = 0.15
Quat = tuple[float, float, float, float]


@dataclass(frozen=True)
class Pose:
    """A rigid placement: position (m) and orientation quaternion (x, y, z, w)."""

    position: Vec3 = (0.0, 0.0, 0.0)
    quaternion: Quat = (0.0, 0.0, 0.0, 1.0)

    @classmethod
    def from_rpy(cls, position: Vec3, rpy: Vec3) -> "Pose":
        """Pose from a position (m) and fixed-axis roll, pitch, yaw (rad)."""
        q = frames.matrix_to_quaternion(frames.rpy_to_matrix(rpy))
        x, y, z = (float(v) for v in position)
        qx, qy, qz, qw = (float(v) for v in q)
        return cls((x, y, z), (qx, qy, qz, qw))

    def rotation(self) -> np.ndarray:
        """Rotation matrix (3, 3)."""
        return frames.quaternion_to_matrix(self.quaternion)

    def matrix(self) -> np.ndarray:
        """Homogeneous transform (4, 4)."""
        return frames.homogeneous(self.rotation(), self.position)



@dataclass(frozen=True)
class Box:
    """A solid oriented box: `pose` is its centre, `size` its full extents (m)."""

    name: str
    pose: Pose
    size: Vec3


@dataclass(frozen=True)
class JointLimits:
    """Per-joint limits of the arm, in joint order j1..j6.

    lower/upper: position limits (rad); velocity (rad/s) and effort (N m) from the URDF;
    acceleration (rad/s^2) from workcell.toml (URDF has no place for it).
    """

    names: tuple[str, ...]
    lower: tuple[float, ...]
    upper: tuple[float, ...]
    velocity: tuple[float, ...]
    acceleration: tuple[float, ...]
    effort: tuple[float, ...]

    @property
    def count(self) -> int:
        """Number of joints."""
        return len(self.names)

    def contains(self, q: np.ndarray) -> np.ndarray:
        """Whether joint vectors q (..., 6) lie within the position limits: bool (...)."""
        q = np.asarray(q, dtype=float)
        return np.all((q >= np.asarray(self.lower)) & (q <= np.asarray(self.upper)), axis=-1)


@dataclass(frozen=True)
class ArmKinematics:
    """The arm's kinematic structure, read from the URDF's joint origins.

    Zero pose: upper arm vertical, forearm horizontal along the base's +x.  In the base
    frame: j1 about z through the origin; j2 (shoulder, about y) at (a1, 0, d1); j3 (elbow,
    about y) a2 above j2; the wrist centre, where j4 (forearm roll, about x), j5 (pitch,
    about y) and j6 (roll, about x) intersect, d4 ahead of j3 along the forearm; the tool
    flange d6 beyond the wrist centre along j6, its z axis along j6 (the approach axis).
    """

    d1: float
    a1: float
    a2: float
    d4: float
    d6: float

    def wrist_radius_limits(self, elbow_lower: float, elbow_upper: float) -> tuple[float, float]:
        """Least and greatest shoulder-to-wrist-centre distance (m) over j3 in [lower, upper].

        |SW|^2 = a2^2 + d4^2 - 2 a2 d4 sin(q3); q3 = -pi/2 is the straight arm.
        """
        q3 = np.linspace(elbow_lower, elbow_upper, 2001)
        r = np.sqrt(self.a2**2 + self.d4**2 - 2 * self.a2 * self.d4 * np.sin(q3))
        return float(r.min()), float(r.max())


@dataclass(frozen=True)
class ArmSpec:
    """The 6-DOF arm `t3`: its model file, base pose, limits and performance; home: the
    configuration (rad) it starts and parks in, folded back clear of the cell;
    tool_classes: the classes of tool it is fitted to work with (``tool_classes`` in
    workcell.toml; None: every class): a two-arm allocation gives it no other work."""

    name: str
    urdf: Path
    base: Pose
    joints: JointLimits
    kinematics: ArmKinematics
    flange_link: str
    payload_kg: float
    repeatability_m: float
    max_tool_speed: float
    home: tuple[float, ...] = HOME_Q
    tool_classes: tuple[str, ...] | None = None

    def works_with(self, tool_class: str) -> bool:
        """Whether the arm is fitted to work with tools of this class."""
        return self.tool_classes is None or tool_class in self.tool_classes


@dataclass(frozen=True)
class PartPlacement:
    """Where the part sits: world = rotation @ (scale * p_mm) + translation (m).

    envelope_min_mm/envelope_max_mm: the part's bounding box in its own frame (mm).
    """

    scale: float
    rotation: tuple[Vec3, Vec3, Vec3]
    translation: Vec3
    envelope_min_mm: Vec3
    envelope_max_mm: Vec3

    def rotation_matrix(self) -> np.ndarray:
        """Rotation (3, 3), part axes as columns in world coordinates."""
        return np.asarray(self.rotation, dtype=float)

    def to_world(self, points_mm: np.ndarray) -> np.ndarray:
        """World points (n, 3) m of part points (n, 3) mm."""
        return frames.part_to_world_points(points_mm, self.rotation_matrix(), self.translation, self.scale)

    def to_part(self, points_m: np.ndarray) -> np.ndarray:
        """Part points (n, 3) mm of world points (n, 3) m."""
        return frames.world_to_part_points(points_m, self.rotation_matrix(), self.translation, self.scale)

    def normals_to_world(self, normals: np.ndarray) -> np.ndarray:
        """World directions (n, 3) of part directions (n, 3) (unit in, unit out)."""
        return frames.rotate_vectors(normals, self.rotation_matrix())

    def moved(self, rotation: np.ndarray, shift_mm: np.ndarray) -> PartPlacement:
        """This placement with the part first moved in its own frame: the part point p (mm)
        goes where ``rotation @ p + shift_mm`` was (a rigid motion of the part, as a fixture
        error or a registration states it)."""
        r0 = self.rotation_matrix()
        rot = r0 @ np.asarray(rotation, dtype=float)
        t = np.asarray(self.translation, dtype=float) + self.scale * (r0 @ np.asarray(shift_mm, dtype=float))
        r = [(float(row[0]), float(row[1]), float(row[2])) for row in rot]
        return PartPlacement(self.scale, (r[0], r[1], r[2]), (float(t[0]), float(t[1]), float(t[2])),
                             self.envelope_min_mm, self.envelope_max_mm)

    def offset_from(self, other: PartPlacement) -> tuple[np.ndarray, np.ndarray]:
        """(rotation (3, 3), shift (3,) mm) that :meth:`moved` applies to `other` to give
        this placement: where this placement puts the part, in `other`'s part frame."""
        r0 = other.rotation_matrix()
        rot = r0.T @ self.rotation_matrix()
        shift = r0.T @ (np.asarray(self.translation, dtype=float) - np.asarray(other.translation, dtype=float))
        return rot, shift / other.scale


#: A contact probe's shape (the simulator's and the collision model's one definition):
PROBE_HOLDER_RADIUS = 0.03   # m: the holder, a cylinder along the flange axis up to the bend
PROBE_SHAFT_RADIUS = 0.008   # m: the shaft, along the tip axis from the bend to the tip
TOOL_GAP = 0.002             # m: tool shapes start this far off the flange face
TIP_CLEARANCE = 0.008        # m: the shaft's solid shape stops this far short of the
                             # spring-loaded tip, which the gauge models


@dataclass(frozen=True)
class ProbeShape:
    """A contact probe's solid shape in the flange frame (m): a holder, the cylinder of
    `holder_radius` along the flange's z axis from `holder_start` to the `bend`, then a
    shaft of `shaft_radius` along the tip `axis` from the bend to the `tip` (the TCP).
    A probe bent 90 degrees has a horizontal shaft; a straight one has no shaft."""

    holder_start: Vec3
    bend: Vec3
    tip: Vec3
    axis: Vec3
    holder_radius: float = PROBE_HOLDER_RADIUS
    shaft_radius: float = PROBE_SHAFT_RADIUS

    def shaft_end(self, clearance: float = 0.0) -> np.ndarray:
        """(3,) where the shaft's solid part ends: `clearance` (plus the shaft's radius)
        short of the tip along its axis."""
        return np.asarray(self.tip) - (clearance + self.shaft_radius) * np.asarray(self.axis)


@dataclass(frozen=True)
class ToolSpec:
    """A tool that the arm can pick up from the rack.

    tcp: the tool centre point in the flange frame: the probe tip (ultrasonic) or the
    optical centre (SLRA); its z axis is the approach / view axis into the surface.
    body_center/body_size: a box (m) in the flange frame that encloses the tool, for
    collision checks.
    standoff_*: SLRA working range along the view axis (m), 0 for a contact probe;
    approach_distance: free-space approach point off the surface (m); fov_deg: SLRA
    field of view (horizontal, vertical), (0, 0) for a probe; holder_radius,
    shaft_radius: a contact probe's holder and shaft (m, :meth:`probe_shape`).
    """

    name: str
    tool_class: Tool
    weight_kg: float
    tcp: Pose
    body_center: Vec3
    body_size: Vec3
    standoff_min: float
    standoff_nominal: float
    standoff_max: float
    approach_distance: float
    fov_deg: tuple[float, float]
    holder_radius: float = PROBE_HOLDER_RADIUS
    shaft_radius: float = PROBE_SHAFT_RADIUS

    @property
    def tcp_length(self) -> float:
        """Distance (m) from the flange to the TCP along the flange's z axis."""
        return float(self.tcp.position[2])

    def same_shape(self, other: "ToolSpec") -> bool:
        """Whether `other` is a tool of the same make: everything but the name and weight
        equal (a spare takes the first one's poses)."""
        from dataclasses import replace

        return replace(self, name=other.name, weight_kg=other.weight_kg) == other

    def probe_shape(self) -> ProbeShape | None:
        """The contact probe's shape (None for a tool with a stand-off, which is its body
        box): the holder runs up the flange axis to the bend, the point of the tip axis
        nearest it; the shaft from there to the tip."""
        if self.standoff_nominal > 0.0 or self.tcp_length <= TOOL_GAP:
            return None
        tip = np.asarray(self.tcp.position, dtype=float)
        axis = self.tcp.rotation()[:, 2]
        xy = axis[:2] @ axis[:2]
        s = float(tip[:2] @ axis[:2] / xy) if xy > 1e-12 else 0.5 * tip[2]
        bend = tip - s * axis
        bend[:2] = 0.0
        def as_tuple(v: np.ndarray) -> Vec3:
            return (float(v[0]), float(v[1]), float(v[2]))

        return ProbeShape((0.0, 0.0, TOOL_GAP), as_tuple(bend), as_tuple(tip), as_tuple(axis),
                          self.holder_radius, self.shaft_radius)

    @property
    def is_straight(self) -> bool:
        """Whether the TCP lies on the flange axis and looks along it."""
        return bool(np.allclose(self.tcp.position[:2], 0.0, atol=1e-9)
                    and np.allclose(self.tcp.rotation()[:, 2], (0.0, 0.0, 1.0), atol=1e-9))


@dataclass(frozen=True)
class RackSlot:
    """A rack slot: the world pose of the parked tool's flange frame, and its tool (or '')."""

    name: str
    pose: Pose
    tool: str


@dataclass(frozen=True)
class Rack:
    """The tool rack: a box and its slots; approach_m: how far back along a slot's axis
    (above it: the tools hang tip down) the flange stands before and after a tool change
    (the tool changer's path, the Geometric Reasoner's rack pose, the sequence cost)."""

    name: str
    box: Box
    slots: tuple[RackSlot, ...]
    approach_m: float = RACK_APPROACH_M


@dataclass(frozen=True)
class ReachParams:
    """Figures of the simple geometric reach test (see reach.py).

    margin: fraction of the fully stretched wrist radius that counts as reachable;
    base_keepout_radius: no wrist centre closer than this to the j1 axis (m);
    wrist_min_height/wrist_max_height: world z range of the wrist centre (m);
    tcp_min_height: lowest world z of the tool point (m); part_clearance: how far the
    SLRA optical centre and the wrist centre must stay outside the part envelope (m);
    standoff_samples: SLRA standoffs tried between min and max; roll_samples: rolls about
    the normal tried for a tool whose point is off the flange axis (an angled probe).
    """

    margin: float
    base_keepout_radius: float
    wrist_min_height: float
    wrist_max_height: float
    tcp_min_height: float
    part_clearance: float
    standoff_samples: int
    roll_samples: int


@dataclass(frozen=True)
class Stations:
    """A couplant station and a calibration block, and the stands they sit on."""

    couplant_station: Box
    cal_block: Box
    stands: tuple[Box, ...]


@dataclass(frozen=True)
class Workcell:
    """Everything in the cell: arm, part placement, fixture, rack, tools, stations.

    stands: the tables the couplant station and calibration block sit on; fence: the
    safety fence's walls; pedestal: the riser under the arm's base.  second_arm and
    second_pedestal: a second arm (``[robot_b]``) that a two-arm plan may use; the one-arm
    system leaves it out of the cell (it is not among :meth:`static_boxes`).
    second_stations: the second arm's own couplant station and calibration block, when it
    has them (else it shares the first's); like its pedestal, they are the second arm's
    equipment, outside the first arm's world.
    """

    source: Path
    arm: ArmSpec
    part: PartPlacement
    fixture: tuple[Box, ...]
    rack: Rack
    tools: tuple[ToolSpec, ...]
    couplant_station: Box
    cal_block: Box
    floor: Box
    pedestal: Box
    stands: tuple[Box, ...]
    fence: tuple[Box, ...]
    reach: ReachParams
    second_arm: ArmSpec | None = None
    second_pedestal: Box | None = None
    second_stations: Stations | None = None

    def arms(self) -> tuple[ArmSpec, ...]:
        """The cell's arms: the first, then the second when there is one."""
        return (self.arm,) if self.second_arm is None else (self.arm, self.second_arm)

    def seen_by(self, arm_name: str) -> "Workcell":
        """The cell as arm `arm_name` works it: that arm (and its pedestal, and its own
        stations when it has them) in the first place, so reach, kinematics, paths and the
        stations it calibrates and wets its probe at apply to it; KeyError for no such arm."""
        if arm_name == self.arm.name:
            return self
        if self.second_arm is None or self.second_pedestal is None or arm_name != self.second_arm.name:
            raise KeyError(arm_name)
        view = replace(self, arm=self.second_arm, pedestal=self.second_pedestal,
                       second_arm=self.arm, second_pedestal=self.pedestal)
        own = self.second_stations
        if own is None:
            return view
        return replace(view, couplant_station=own.couplant_station, cal_block=own.cal_block, stands=own.stands,
                       second_stations=Stations(self.couplant_station, self.cal_block, self.stands))

    def tool(self, name: str) -> ToolSpec:
        """The tool named `name`; KeyError if there is none."""
        for t in self.tools:
            if t.name == name:
                return t
        raise KeyError(name)

    def tools_of_class(self, tool_class: Tool | str) -> tuple[ToolSpec, ...]:
        """The tools of a class ('us_tool' or 'slra_tool'), in file order."""
        cls = Tool(tool_class)
        return tuple(t for t in self.tools if t.tool_class is cls)

    def slot_of(self, tool_name: str) -> RackSlot:
        """The rack slot that holds `tool_name`; KeyError if none does."""
        for s in self.rack.slots:
            if s.tool == tool_name:
                return s
        raise KeyError(tool_name)

    def static_boxes(self) -> tuple[Box, ...]:
        """All fixed solid boxes of the cell (floor, pedestal, fixture, rack, stations, fence)."""
        return (
            (self.floor, self.pedestal)
            + self.fixture
            + (self.rack.box, self.couplant_station, self.cal_block)
            + self.stands
            + self.fence
        )
