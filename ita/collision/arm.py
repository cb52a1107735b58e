"""Arm collision checks: the arm's links and the held tool as tubes against the region
tree and each other.

The caller computes the tubes' world segments per configuration (forward kinematics, e.g.
`ita.kinematics.fk.link_segments`, whose ArmModel carries the tube_links and tube_radii
this module needs); a check is then one compiled pass over a batch:

    checker = ArmChecker(tree, radii, tube_links)
    free = ~checker.collides(segments)          # segments (n, t, 2, 3) -> bool (n,)

World: every tube except those of the fixed base link (tube_links == 0), which never
moves, is walked through the tree; the objects the arm is mounted on (`mount`, e.g. the
pedestal) do not count for link 1's tubes, whose enclosing capsules reach down into them.
Self: tube pairs whose links are not adjacent in the chain (|link_i - link_j| > 1,
pybullet's default filter).

Tight tubes (`arm_tubes`, `ArmTubes`): every tube encloses the URDF shape it stands for
(conservative).  A URDF cylinder is two tubes: the capsule on its own axis and radius,
checked against the world (radially exact), and for the other links the flat-ended
cylinder itself grown by CYLINDER_PAD (`cylinder`, met by `kernels.pair_gap`: exact up
to the pad, where a folded wrist's links meet at the cylinders' flat faces).  A held
tool is the
tubes of its real shape (`tool_tubes`: the simulator's holder and bent shaft, or its body
box as 2 x 2 tubes) on the flange link; it moves with the arm, so it is not in the tree
while held (remove it from the tree at pick-up, add it back at put-down).  `tool_tube` is
the one tube that encloses the whole tool (a size for clearances, not a collision shape).
"""

from __future__ import annotations

import dataclasses
import xml.etree.ElementTree as ET
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ita.collision import kernels
from ita.collision.tree import RegionTree
from ita.workcell.frames import rpy_to_matrix
from ita.workcell.model import TIP_CLEARANCE, ToolSpec  # noqa: F401 (re-exported for the collision tests)

FREE, WORLD, SELF = 0, 1, 2

# The held tools' shapes are the workcell model's (ToolSpec.probe_shape, the body box),
# as the simulator has them (ita.sim.world.tool_shapes; the test suite checks that these
# tubes enclose those shapes).
BOX_CLIP = 0.5               # a box tool's tubes end this fraction of their cell's half diagonal inside it
CYLINDER_PAD = 0.0015        # m: a cylinder's self-check shape grown this much all round (the simulator's
                             # cylinders, convex hulls with a collision margin, reach up to 1 mm past it)


def self_pairs(tube_links: ArrayLike, skip: int = 1, exclude: ArrayLike = ()) -> NDArray[np.int64]:
    """(p, 2) tube index pairs to check against each other: links more than `skip` apart
    in the chain, minus the link pairs listed in `exclude` ((k, 2) link indices)."""
    links = np.asarray(tube_links, dtype=np.int64)
    i, j = np.triu_indices(len(links), k=1)
    keep = np.abs(links[i] - links[j]) > skip
    for a, b in np.asarray(exclude, dtype=np.int64).reshape(-1, 2):
        keep &= ~(((links[i] == a) & (links[j] == b)) | ((links[i] == b) & (links[j] == a)))
    return np.column_stack([i[keep], j[keep]]).astype(np.int64)


def tool_tube(tool: ToolSpec) -> tuple[np.ndarray, float]:
    """A tube enclosing the tool's body box: ends (2, 3) in the flange frame and radius.

    Its axis runs along the box's longest side through the box's centre, as long as that
    side; its radius is the half diagonal of the box's cross-section."""
    c, size = np.asarray(tool.body_center, dtype=float), np.asarray(tool.body_size, dtype=float)
    axis = int(np.argmax(size))
    others = [k for k in range(3) if k != axis]
    radius = float(np.linalg.norm(size[others]) / 2)
    ends = np.array([c, c])
    ends[0, axis] -= size[axis] / 2
    ends[1, axis] += size[axis] / 2
    return ends, radius


def _shape(collision: ET.Element, urdf: Path) -> ET.Element:
    """The shape of a URDF <collision>: the first element in its <geometry>."""
    geometry = collision.find("geometry")
    if geometry is None or not len(geometry):
        raise ValueError(f"{urdf}: a <collision> without a shape in its <geometry>")
    return geometry[0]


def _number(shape: ET.Element, name: str, urdf: Path) -> float:
    """A shape's numeric attribute (`length`, `radius`); ValueError when it has none."""
    value = shape.get(name)
    if value is None:
        raise ValueError(f"{urdf}: a {shape.tag} without a {name}")
    return float(value)


def urdf_tubes(urdf: Path, link_names: Sequence[str]) -> tuple[np.ndarray, np.ndarray, np.ndarray, list[str]]:
    """Collision cylinders and capsules of the listed links (chain order): tube_links (t,)
    index into link_names, ends (t, 2, 3) in the link frame, radii (t,), shape tags."""
    root = ET.parse(urdf).getroot()
    links = {link.get("name"): link for link in root.findall("link")}
    index, ends, radii, tags = [], [], [], []
    for i, name in enumerate(link_names):
        for col in links[name].findall("collision") if name in links else []:
            shape = _shape(col, urdf)
            if shape.tag not in ("cylinder", "capsule"):
                continue
            org = col.find("origin")
            xyz = [float(v) for v in (org.get("xyz", "0 0 0") if org is not None else "0 0 0").split()]
            rpy = [float(v) for v in (org.get("rpy", "0 0 0") if org is not None else "0 0 0").split()]
            axis = rpy_to_matrix(rpy)[:, 2] * _number(shape, "length", urdf) / 2
            index.append(i)
            ends.append([np.subtract(xyz, axis), np.add(xyz, axis)])
            radii.append(_number(shape, "radius", urdf))
            tags.append(shape.tag)
    return np.array(index), np.array(ends, dtype=float), np.array(radii), tags


def tool_tubes(tool: ToolSpec, tip_clearance: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """Tubes enclosing the tool's real shape: ends (k, 2, 3) in the flange frame, radii (k,).

    A contact probe (ToolSpec.probe_shape): its holder, the cylinder along the flange axis
    up to the bend (as the capsule on that axis; the first tube), and its shaft, the
    capsule along the tip axis from the bend to
    `tip_clearance` short of the tip (0: the whole probe, for free-space checks;
    TIP_CLEARANCE: the simulator's shaft, which leaves the spring-loaded tip free to touch
    the part).  Any other tool: its body box as 2 x 2 tubes along the box's longest side,
    each enclosing a quarter of the box (its cell's half diagonal, the ends clipped
    BOX_CLIP of it inside the box and the radius grown to match)."""
    shape = tool.probe_shape()
    if shape is None:
        c, size = np.asarray(tool.body_center, dtype=float), np.asarray(tool.body_size, dtype=float)
        axis = int(np.argmax(size))
        u, v = [k for k in range(3) if k != axis]
        cell = float(np.hypot(size[u], size[v]) / 4.0)
        clip = min(BOX_CLIP * cell, size[axis] / 2.0)
        ends, radii = [], []
        for su in (-1.0, 1.0):
            for sv in (-1.0, 1.0):
                mid = c.copy()
                mid[u] += su * size[u] / 4.0
                mid[v] += sv * size[v] / 4.0
                a, b = mid.copy(), mid.copy()
                a[axis] -= size[axis] / 2.0 - clip
                b[axis] += size[axis] / 2.0 - clip
                ends.append([a, b])
                radii.append(float(np.hypot(cell, clip)))
        return np.asarray(ends), np.asarray(radii)
    bend = np.asarray(shape.bend)
    tube_ends = [[np.asarray(shape.holder_start), bend]]
    radii = [shape.holder_radius]
    end = shape.shaft_end(tip_clearance)
    if np.linalg.norm(end - bend) > 1e-6:
        tube_ends.append([bend, end])
        radii.append(shape.shaft_radius)
    return np.asarray(tube_ends), np.asarray(radii, dtype=float)


@dataclass(frozen=True, eq=False)
class ArmTubes:
    """The collision tubes of the arm (and held tool), with what each is checked against.

    links (t,) index of each tube's link (0 the base, the flange dof + 1); ends (t, 2, 3)
    in the link's frame; radii (t,); world (t,) bool: walked through the tree; self_check
    (t,) bool: met against the other links' tubes; cylinder (t,): the radius of the
    flat-ended cylinder a tube stands for in self checks (0: the tube is its capsule);
    exclude (k, 2): link pairs never checked (the held tool and the wrist link it is
    bolted next to)."""

    links: np.ndarray
    ends: np.ndarray
    radii: np.ndarray
    world: np.ndarray
    self_check: np.ndarray
    cylinder: np.ndarray
    exclude: tuple[tuple[int, int], ...] = ()

    def __len__(self) -> int:
        return len(self.radii)

    def pairs(self) -> np.ndarray:
        """(p, 2) self-collision tube pairs: non-adjacent links, both tubes self_check."""
        pairs = self_pairs(self.links, exclude=self.exclude)
        keep = self.self_check[pairs[:, 0]] & self.self_check[pairs[:, 1]] if len(pairs) else np.zeros(0, bool)
        return pairs[keep]

    def with_tool(self, tool: ToolSpec, flange: int, tip_clearance: float = 0.0) -> ArmTubes:
        """These tubes and the held tool's (`tool_tubes`) on link `flange` (dof + 1),
        which are not checked against link flange - 2 (the wrist link before the last).
        A contact probe's holder (the first tube) is met by the links as its cylinder
        (`cylinder_tube`), its capsule by the world."""
        ends, radii = tool_tubes(tool, tip_clearance)
        k = len(radii)
        world, self_, cylinder = np.ones(k, bool), np.ones(k, bool), np.zeros(k)
        shape = tool.probe_shape()
        if shape is not None:
            pad_ends, pad_r = cylinder_tube(ends[0], shape.holder_radius)
            ends, radii = np.concatenate([ends, pad_ends[None]]), np.append(radii, pad_r)
            world, self_, cylinder = np.append(world, False), np.append(self_, True), np.append(cylinder, pad_r)
            self_[0] = False
            k += 1
        return ArmTubes(np.append(self.links, np.full(k, flange)).astype(np.int64),
                        np.concatenate([self.ends, ends]), np.append(self.radii, radii),
                        np.append(self.world, world), np.append(self.self_check, self_),
                        np.append(self.cylinder, cylinder), self.exclude + ((flange - 2, flange),))

    def apply(self, model: Any) -> Any:
        """An ArmModel (ita.kinematics) with these tubes instead of its own."""
        return dataclasses.replace(model, tube_links=self.links.copy(), tube_ends=self.ends.copy(),
                                   tube_radii=self.radii.copy())

    def checker(self, tree: RegionTree, mount: Iterable[str] = ()) -> ArmChecker:
        """The ArmChecker of these tubes over `tree`."""
        return ArmChecker(tree, self.radii, self.links, pairs=self.pairs(), world=self.world & (self.links != 0),
                          mount=mount, cylinder=self.cylinder)


def cylinder_tube(ends: ArrayLike, radius: float, pad: float = CYLINDER_PAD) -> tuple[np.ndarray, float]:
    """The self-check tube of the cylinder on the axis ends (2, 3) of `radius`: the
    cylinder grown by `pad` (its ends (2, 3) moved pad outward, its radius)."""
    a, b = np.asarray(ends, dtype=float)
    u = (b - a) / np.linalg.norm(b - a)
    return np.array([a - pad * u, b + pad * u]), float(radius + pad)


def arm_tubes(urdf: Path, link_names: Sequence[str], pad: float = CYLINDER_PAD) -> ArmTubes:
    """The tight tubes of the URDF's links (`link_names` in chain order, as ArmModel's).

    A capsule is itself (world and self).  A cylinder is the capsule on its axis and
    radius (world only) and the flat-ended cylinder grown by `pad` (`cylinder_tube`; self
    only)."""
    links, ends, radii, tags = urdf_tubes(urdf, link_names)
    out_l, out_e, out_r, world, self_, cyl = [], [], [], [], [], []
    for link, e, r, tag in zip(links, ends, radii, tags):
        flat = tag == "cylinder"
        out_l.append(link)
        out_e.append(e)
        out_r.append(r)
        world.append(True)
        self_.append(not flat)
        cyl.append(0.0)
        if flat:
            grown, radius = cylinder_tube(e, r, pad)
            out_l.append(link)
            out_e.append(grown)
            out_r.append(radius)
            world.append(False)
            self_.append(True)
            cyl.append(radius)
    return ArmTubes(np.asarray(out_l, dtype=np.int64), np.asarray(out_e, dtype=float).reshape(-1, 2, 3),
                    np.asarray(out_r, dtype=float), np.asarray(world, bool), np.asarray(self_, bool),
                    np.asarray(cyl, dtype=float))


def transform_points(poses: ArrayLike, points: ArrayLike) -> np.ndarray:
    """Points (k, 3) in frames (n, 4, 4) -> world (n, k, 3)."""
    t, p = np.asarray(poses, dtype=float), np.asarray(points, dtype=float)
    return np.einsum("nij,kj->nki", t[:, :3, :3], p) + t[:, None, :3, 3]


@dataclass(frozen=True)
class ArmHits:
    """Result of `ArmChecker.check`: status (n,) FREE/WORLD/SELF; node (n,) the solid
    region met (WORLD) or -1; pair (n, 2) the tubes that met (SELF) or -1; obj (n,) the
    object met (WORLD) or None."""

    status: NDArray[np.int8]
    node: NDArray[np.int64]
    pair: NDArray[np.int64]
    obj: np.ndarray

    @property
    def collides(self) -> NDArray[np.bool_]:
        """Bool (n,)."""
        return self.status != FREE


class ArmChecker:
    """Checks batches of arm configurations (as tube segments) against a RegionTree.

    radii (t,), tube_links (t,) link index in chain order (0 = the fixed base); pairs:
    self-collision tube pairs (default `self_pairs(tube_links)`); world (t,) bool: tubes
    checked against the tree (default: all but the base link's); mount: names of the
    objects the base stands on, which links 0 and 1 may touch; cylinder (t,): the radius
    of the flat-ended cylinder a tube stands for in self checks (default 0: every tube is
    its capsule).  The tree is read at each call, so updates to it are seen."""

    def __init__(self, tree: RegionTree, radii: ArrayLike, tube_links: ArrayLike,
                 pairs: ArrayLike | None = None, world: ArrayLike | None = None,
                 mount: Iterable[str] = (), cylinder: ArrayLike | None = None) -> None:
        self.tree = tree
        self.radii = np.ascontiguousarray(radii, dtype=float)
        self.tube_links = np.asarray(tube_links, dtype=np.int64)
        if self.radii.shape != self.tube_links.shape:
            raise ValueError("radii and tube_links must have the same length")
        self.pairs = np.ascontiguousarray(self_pairs(self.tube_links) if pairs is None else pairs, dtype=np.int64)
        self.world = np.ascontiguousarray(self.tube_links != 0 if world is None else world, dtype=np.bool_)
        self.mount = tuple(mount)
        self.cylinder = np.ascontiguousarray(np.zeros(len(self.radii)) if cylinder is None else cylinder,
                                             dtype=float)
        if self.cylinder.shape != self.radii.shape:
            raise ValueError("cylinder and radii must have the same length")

    def _ignore(self) -> np.ndarray:
        ignore = np.zeros((len(self.radii), self.tree.object_count), dtype=np.bool_)
        low = self.tube_links <= 1
        for name in self.mount:
            if name in self.tree.objects:
                ignore[low, self.tree.object_id(name)] = True
        return ignore

    def _run(self, segments: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
        segs = np.ascontiguousarray(segments, dtype=float)
        if segs.ndim == 3:
            segs = segs[None]
        if segs.shape[1:] != (len(self.radii), 2, 3):
            raise ValueError(f"segments must be (n, {len(self.radii)}, 2, 3), got {segs.shape}")
        return kernels.check_arm(segs, self.radii, self.cylinder, self.world, self._ignore(), self.pairs, *self.tree.arrays())

    def collides(self, segments: ArrayLike) -> NDArray[np.bool_]:
        """Bool (n,): whether each configuration's tubes (n, t, 2, 3) meet the world or each other."""
        return self._run(segments)[0] != FREE

    def check(self, segments: ArrayLike) -> ArmHits:
        """Status and culprit per configuration (see ArmHits)."""
        status, detail = self._run(segments)
        node = np.where(status == WORLD, detail, -1)
        pair = np.full((len(status), 2), -1, dtype=np.int64)
        is_self = status == SELF
        pair[is_self] = self.pairs[detail[is_self]]
        return ArmHits(status, node, pair, self.tree.object_names(node))
