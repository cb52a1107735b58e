"""Forward kinematics of the workcell's arm, vectorised over joint configurations.

An `ArmModel` is the arm read once from its URDF (joint origins and axes, the flange's
fixed offset, the collision shapes) and from the workcell (base pose, joint limits):

    model = arm_model(load_workcell().arm)
    flange = flange_poses(model, q)             # (n, 6) rad -> (n, 4, 4) world
    tubes = link_segments(model, q)             # (n, t, 2, 3) world, radii model.tube_radii

Frames: every pose is a 4x4 homogeneous transform in the WORLD frame (metres, z up); the
arm's base pose on its pedestal is included.  Joint i turns its child link by q[i] about
its URDF axis, right-handed; the zero configuration is the URDF's (upper arm vertical,
forearm along the base's +x).  The flange frame's z axis is the approach axis, along j6.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from dataclasses import dataclass
from typing import TypeVar, overload

import numpy as np
from numba import njit
from numpy.typing import ArrayLike, NDArray

from ita.workcell.frames import homogeneous, rpy_to_matrix
from ita.workcell.model import ArmKinematics, ArmSpec

FloatArray = NDArray[np.float64]
_ScalarT = TypeVar("_ScalarT", bound=np.generic)
#: rad: the one slack at the joint limits, for every check that a configuration is within
#: them (IK, path planning, the motion kernels, the controller); IK snaps solutions within it
#: onto the limit, and the arm never settles outside the limits
JOINT_LIMIT_TOL = 1e-6


@dataclass(frozen=True, eq=False, repr=False)
class ArmModel:
    """The arm as numbers, for kinematics and collision checks (arrays are read-only).

    base: (4, 4) world pose of the base link.  joint_names: the six joints, j1..j6.
    origins: (6, 4, 4) each joint's origin in its parent link's frame, with any fixed
    joints before it folded in; axes: (6, 3) unit joint axes in the joint frames;
    flange_offset: (4, 4) the flange frame in the last link's frame.
    link_names: (7 + 1) base_link, the six moving links and the flange.
    lower, upper, velocity, acceleration: (6,) joint limits (rad, rad/s, rad/s^2);
    max_tool_speed: the controller's TCP speed limit (m/s).  kinematics: the analytic
    parameters (d1, a1, a2, d4, d6) the inverse kinematics uses.
    tube_links: (t,) index into link_names of each collision tube; tube_ends: (t, 2, 3)
    the tube's segment ends in its link's frame; tube_radii: (t,) its radius (m).
    tubes_complete: whether the tubes enclose every collision shape of every link that
    moves (the URDF's moving links have capsules and cylinders only, all on the chain).
    """

    base: FloatArray
    joint_names: tuple[str, ...]
    origins: FloatArray
    axes: FloatArray
    flange_offset: FloatArray
    link_names: tuple[str, ...]
    lower: FloatArray
    upper: FloatArray
    velocity: FloatArray
    acceleration: FloatArray
    max_tool_speed: float
    kinematics: ArmKinematics
    tube_links: NDArray[np.int64]
    tube_ends: FloatArray
    tube_radii: FloatArray
    tubes_complete: bool

    def __repr__(self) -> str:
        return f"ArmModel({', '.join(self.joint_names)}; {len(self.tube_radii)} tubes)"

    @property
    def dof(self) -> int:
        """Number of joints (6)."""
        return len(self.joint_names)

    def within_limits(self, q: ArrayLike, tol: float = JOINT_LIMIT_TOL) -> NDArray[np.bool_]:
        """Bool (...): whether configurations q (..., 6) lie within the position limits."""
        q = np.asarray(q, dtype=float)
        return np.all((q >= self.lower - tol) & (q <= self.upper + tol), axis=-1)


def arm_model(arm: ArmSpec) -> ArmModel:
    """Build the ArmModel of a workcell arm, reading its URDF for origins and collision shapes.

    The chain runs from the URDF's root link through the arm's six joints (in the order of
    `arm.joints.names`) to `arm.flange_link`; fixed joints on the way are folded into the
    next origin.  Raises ValueError if the URDF's chain does not match.
    """
    root = ET.parse(arm.urdf).getroot()
    by_child = {_joint_link(j, "child"): j for j in root.findall("joint")}
    chain: list[ET.Element] = []
    link = arm.flange_link
    while link in by_child:
        joint = by_child[link]
        chain.append(joint)
        link = _joint_link(joint, "parent")
    chain.reverse()
    moving = [j for j in chain if j.get("type") != "fixed"]
    names = tuple(j.get("name", "") for j in moving)
    if names != tuple(arm.joints.names):
        raise ValueError(f"{arm.urdf}: chain to {arm.flange_link!r} has joints {names}, expected {arm.joints.names}")
    origins, axes, pending = [], [], np.eye(4)
    link_names = [link]  # the root
    for joint in chain:
        pending = pending @ _origin(joint)
        if joint.get("type") == "fixed":
            continue
        origins.append(pending)
        pending = np.eye(4)
        axis = _floats(joint.find("axis"), "xyz", "1 0 0")
        axes.append(axis / np.linalg.norm(axis))
        link_names.append(_joint_link(joint, "child"))
    link_names.append(arm.flange_link)
    tube_links, tube_ends, tube_radii = _tubes(root, link_names)
    lim = arm.joints
    return ArmModel(
        base=_frozen(arm.base.matrix()),
        joint_names=names,
        origins=_frozen(np.stack(origins)),
        axes=_frozen(np.stack(axes)),
        flange_offset=_frozen(pending),
        link_names=tuple(link_names),
        lower=_frozen(lim.lower),
        upper=_frozen(lim.upper),
        velocity=_frozen(lim.velocity),
        acceleration=_frozen(lim.acceleration),
        max_tool_speed=float(arm.max_tool_speed),
        kinematics=arm.kinematics,
        tube_links=_frozen(tube_links, np.int64),
        tube_ends=_frozen(tube_ends),
        tube_radii=_frozen(tube_radii),
        tubes_complete=_only_tubes(root, link_names),
    )


def link_frames(model: ArmModel, q: ArrayLike) -> FloatArray:
    """World frames (n, 8, 4, 4) of base_link, link1..link6 and the flange for configs q (n, 6).

    A single configuration (6,) gives (1, 8, 4, 4).
    """
    q = np.ascontiguousarray(_configs(q, model.dof))
    return _link_frames_kernel(np.ascontiguousarray(model.base), np.ascontiguousarray(model.origins),
                               np.ascontiguousarray(model.axes), np.ascontiguousarray(model.flange_offset), q)


@njit(cache=True)
def _link_frames_kernel(base, origins, axes, flange_offset, q):  # pragma: no cover - compiled
    """link_frames, compiled: per configuration, the chain base @ (origin_i with its
    rotation turned by Rodrigues about axis_i) ... @ flange_offset."""
    n, dof = q.shape
    frames = np.empty((n, dof + 2, 4, 4))
    joint = np.empty((4, 4))
    rot = np.empty((3, 3))
    for c in range(n):
        frames[c, 0] = base
        for i in range(dof):
            kx, ky, kz = axes[i, 0], axes[i, 1], axes[i, 2]
            sa, ca = np.sin(q[c, i]), np.cos(q[c, i])
            v = 1.0 - ca
            # eye + s K + (1 - c) K K, K the axis's skew matrix
            rot[0, 0] = 1.0 + v * (-kz * kz - ky * ky)
            rot[0, 1] = -sa * kz + v * (kx * ky)
            rot[0, 2] = sa * ky + v * (kx * kz)
            rot[1, 0] = sa * kz + v * (kx * ky)
            rot[1, 1] = 1.0 + v * (-kz * kz - kx * kx)
            rot[1, 2] = -sa * kx + v * (ky * kz)
            rot[2, 0] = -sa * ky + v * (kx * kz)
            rot[2, 1] = sa * kx + v * (ky * kz)
            rot[2, 2] = 1.0 + v * (-ky * ky - kx * kx)
            for r in range(3):
                for k in range(3):
                    joint[r, k] = origins[i, r, 0] * rot[0, k] + origins[i, r, 1] * rot[1, k] \
                        + origins[i, r, 2] * rot[2, k]
                joint[r, 3] = origins[i, r, 3]
            joint[3, 0], joint[3, 1], joint[3, 2], joint[3, 3] = 0.0, 0.0, 0.0, 1.0
            for r in range(4):
                for k in range(4):
                    frames[c, i + 1, r, k] = frames[c, i, r, 0] * joint[0, k] + frames[c, i, r, 1] * joint[1, k] \
                        + frames[c, i, r, 2] * joint[2, k] + frames[c, i, r, 3] * joint[3, k]
        for r in range(4):
            for k in range(4):
                frames[c, dof + 1, r, k] = frames[c, dof, r, 0] * flange_offset[0, k] \
                    + frames[c, dof, r, 1] * flange_offset[1, k] + frames[c, dof, r, 2] * flange_offset[2, k] \
                    + frames[c, dof, r, 3] * flange_offset[3, k]
    return frames


def flange_poses(model: ArmModel, q: ArrayLike) -> FloatArray:
    """World poses (n, 4, 4) of the flange for joint configurations q (n, 6) (or (6,))."""
    return link_frames(model, q)[:, -1]


def tcp_poses(model: ArmModel, q: ArrayLike, tcp: ArrayLike) -> FloatArray:
    """World poses (n, 4, 4) of a tool's TCP, given as a (4, 4) pose in the flange frame."""
    return flange_poses(model, q) @ np.asarray(tcp, dtype=float)


def link_segments(model: ArmModel, q: ArrayLike) -> FloatArray:
    """World segment ends (n, t, 2, 3) of the arm's collision tubes for configs q (n, 6).

    Tube k belongs to link `model.link_names[model.tube_links[k]]` and has radius
    `model.tube_radii[k]`: the URDF's capsules exactly, its cylinders as the capsule that
    encloses them (same axis segment and radius).
    """
    return frame_segments(model, link_frames(model, q))


def frame_segments(model: ArmModel, frames: FloatArray) -> FloatArray:
    """`link_segments` from the link frames (n, 8, 4, 4) of `link_frames`."""
    frames = frames[:, model.tube_links]                          # (n, t, 4, 4)
    ends = np.matmul(model.tube_ends, np.swapaxes(frames[:, :, :3, :3], -1, -2))   # (n, t, k, 3)
    return ends + frames[:, :, None, :3, 3]


def axis_rotations(axis: ArrayLike, angles: ArrayLike) -> FloatArray:
    """Rotations (n, 3, 3) by angles (n,) rad about one unit axis (3,) (Rodrigues)."""
    k = np.asarray(axis, dtype=float)
    a = np.asarray(angles, dtype=float).reshape(-1)
    skew = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    c, s = np.cos(a)[:, None, None], np.sin(a)[:, None, None]
    return np.eye(3) + s * skew + (1.0 - c) * (skew @ skew)


def invert_poses(poses: ArrayLike) -> FloatArray:
    """Inverses (..., 4, 4) of rigid transforms (..., 4, 4)."""
    t = np.asarray(poses, dtype=float)
    out = np.zeros_like(t)
    rt = np.swapaxes(t[..., :3, :3], -1, -2)
    out[..., :3, :3] = rt
    out[..., :3, 3] = -np.einsum("...ij,...j->...i", rt, t[..., :3, 3])
    out[..., 3, 3] = 1.0
    return out


def _configs(q: ArrayLike, dof: int) -> FloatArray:
    q = np.asarray(q, dtype=float)
    if q.ndim == 1:
        q = q[None, :]
    if q.ndim != 2 or q.shape[1] != dof:
        raise ValueError(f"joint configurations must be (n, {dof}), got {q.shape}")
    return q


@overload
def _frozen(values: ArrayLike) -> FloatArray: ...
@overload
def _frozen(values: ArrayLike, dtype: type[_ScalarT]) -> NDArray[_ScalarT]: ...
def _frozen(values: ArrayLike, dtype: type[np.generic] = np.float64) -> np.ndarray:
    a = np.array(values, dtype=dtype)
    a.setflags(write=False)
    return a


def _joint_link(joint: ET.Element, end: str) -> str:
    """The link a URDF joint's <parent> or <child> (`end`) names; ValueError when it names none."""
    element = joint.find(end)
    link = element.get("link") if element is not None else None
    if link is None:
        raise ValueError(f"URDF joint {joint.get('name')!r} has no {end} link")
    return link


def _floats(element: ET.Element | None, attr: str, default: str) -> FloatArray:
    text = element.get(attr, default) if element is not None else default
    return np.array([float(v) for v in text.split()], dtype=float)


def _origin(element: ET.Element) -> FloatArray:
    origin = element.find("origin")
    return homogeneous(rpy_to_matrix(_floats(origin, "rpy", "0 0 0")), _floats(origin, "xyz", "0 0 0"))


def _only_tubes(root: ET.Element, link_names: list[str]) -> bool:
    """Whether every collision shape of a moving link is a capsule or a cylinder on a link
    of the chain (`link_names`), so that the tubes `_tubes` reads enclose all of them.  The
    moving links: all but the root and what hangs from it by fixed joints."""
    fixed_to: dict[str, list[str]] = {}
    for joint in root.findall("joint"):
        if joint.get("type") == "fixed":
            fixed_to.setdefault(_joint_link(joint, "parent"), []).append(_joint_link(joint, "child"))
    still, todo = set(), [link_names[0]]
    while todo:
        name = todo.pop()
        if name not in still:
            still.add(name)
            todo.extend(fixed_to.get(name, []))
    chain = set(link_names)
    for link in root.findall("link"):
        if link.get("name") in still:
            continue
        for collision in link.findall("collision"):
            shapes = list(collision.iterfind("geometry/*"))
            if link.get("name") not in chain or len(shapes) != 1 or shapes[0].tag not in ("capsule", "cylinder"):
                return False
    return True


def _tubes(root: ET.Element, link_names: list[str]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Collision capsules and cylinders of the chain's links as (link index, ends (2, 3), radius)."""
    links = {link.get("name"): link for link in root.findall("link")}
    index, ends, radii = [], [], []
    for i, name in enumerate(link_names):
        link = links.get(name)
        if link is None:
            continue
        for collision in link.findall("collision"):
            shapes = [s for s in collision.iterfind("geometry/*") if s.tag in ("capsule", "cylinder")]
            if not shapes:
                continue
            shape = shapes[0]
            pose = _origin(collision)
            half = 0.5 * float(shape.get("length", "0")) * pose[:3, 2]
            index.append(i)
            ends.append([pose[:3, 3] - half, pose[:3, 3] + half])
            radii.append(float(shape.get("radius", "0")))
    return np.array(index, dtype=np.int64), np.array(ends, dtype=float).reshape(-1, 2, 3), np.array(radii)
