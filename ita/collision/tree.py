"""The region tree: a hierarchy of spheres, tubes and oriented boxes over the workcell.

Every node is a region (shape, size, position, orientation, solidity).  Solid nodes are
the real objects' pieces; the others bound their children, so a query that misses a node
skips everything under it.  The invariant (seed, Collision Avoidance Model): every non-root
region lies inside the union of its parents, which makes skipping sound; `containment_gaps`
checks it.  Each object (the part, a fixture post, a parked tool) owns a subtree built
from its solid regions by median splits, the bounding boxes aligned with the object's own
frame; objects can be grouped under a shared bounding box.

    tree = RegionTree()
    tree.add("post", Regions.boxes(centres, rotations, sizes), pose)
    tree.points_hit(points)                    # (n, 3) -> bool (n,)
    tree.segments_hit(p0, p1)                  # (n, 3), (n, 3) -> bool (n,)
    tree.tubes_hit(p0, p1, radius)             # a link or any capsule
    tree.update("post", new_pose)              # rigid move, no rebuild
    tree.remove("post")

Queries run in compiled walks (`kernels`), one depth-first walk per query that stops at
the first solid region met.  Poses are (4, 4) world transforms; lengths are metres.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ita.collision import kernels
from ita.collision.shapes import BOX, SPHERE, TUBE

FloatArray = NDArray[np.float64]


@dataclass(frozen=True, eq=False)
class Regions:
    """A batch of k regions as arrays (see `shapes` for the meaning of each field).

    kind (k,) int8; position (k, 3); rotation (k, 3, 3) (columns: the region's axes);
    half (k, 3) half extents (a box), half[:, 0] the half length (a tube); rad (k,) the
    radius (sphere, tube) or rounding (box).
    """

    kind: NDArray[np.int8]
    position: FloatArray
    rotation: FloatArray
    half: FloatArray
    rad: FloatArray

    def __len__(self) -> int:
        return len(self.kind)

    @classmethod
    def empty(cls) -> Regions:
        """No regions."""
        return cls(np.zeros(0, np.int8), np.zeros((0, 3)), np.zeros((0, 3, 3)), np.zeros((0, 3)), np.zeros(0))

    @classmethod
    def boxes(cls, centers: ArrayLike, rotations: ArrayLike, sizes: ArrayLike, margin: float = 0.0) -> Regions:
        """Oriented boxes: centres (k, 3), rotations (k, 3, 3), full sizes (k, 3), each
        grown by `margin` on every side."""
        c = np.atleast_2d(np.asarray(centers, dtype=float))
        rot = np.broadcast_to(np.asarray(rotations, dtype=float), (len(c), 3, 3)).copy()
        half = np.broadcast_to(np.asarray(sizes, dtype=float), c.shape) / 2.0 + margin
        return cls(np.full(len(c), BOX, np.int8), c.copy(), rot, half.copy(), np.zeros(len(c)))

    @classmethod
    def spheres(cls, centers: ArrayLike, radii: ArrayLike) -> Regions:
        """Spheres: centres (k, 3), radii (k,)."""
        c = np.atleast_2d(np.asarray(centers, dtype=float))
        r = np.broadcast_to(np.asarray(radii, dtype=float), (len(c),)).copy()
        return cls(np.full(len(c), SPHERE, np.int8), c.copy(), np.broadcast_to(np.eye(3), (len(c), 3, 3)).copy(),
                   np.zeros((len(c), 3)), r)

    @classmethod
    def tubes(cls, a: ArrayLike, b: ArrayLike, radii: ArrayLike) -> Regions:
        """Tubes (capsules) with axis a-b (k, 3) and radii (k,)."""
        a, b = np.atleast_2d(np.asarray(a, dtype=float)), np.atleast_2d(np.asarray(b, dtype=float))
        axis = b - a
        length = np.linalg.norm(axis, axis=1)
        x = np.where(length[:, None] > 0, axis / np.where(length > 0, length, 1.0)[:, None], [1.0, 0.0, 0.0])
        rot = np.stack([_frame_from_x(v) for v in x]) if len(x) else np.zeros((0, 3, 3))
        half = np.zeros((len(a), 3))
        half[:, 0] = length / 2
        r = np.broadcast_to(np.asarray(radii, dtype=float), (len(a),)).copy()
        return cls(np.full(len(a), TUBE, np.int8), (a + b) / 2, rot, half, r)

    @staticmethod
    def concat(items: Sequence[Regions]) -> Regions:
        """All regions of `items`, in order."""
        items = [r for r in items if len(r)] or [Regions.empty()]
        return Regions(*(np.concatenate([getattr(r, f) for r in items]) for f in
                         ("kind", "position", "rotation", "half", "rad")))

    def transformed(self, pose: ArrayLike, scale: float = 1.0) -> Regions:
        """These regions scaled by `scale` about the origin, then moved by pose (4, 4)."""
        t = np.asarray(pose, dtype=float)
        rot = t[:3, :3]
        return Regions(self.kind.copy(), scale * self.position @ rot.T + t[:3, 3], rot @ self.rotation,
                       scale * self.half, scale * self.rad)

    def bounds_in(self, rotation: ArrayLike) -> tuple[FloatArray, FloatArray]:
        """Exact axis-aligned bounds (k, 3), (k, 3) of each region in the frame whose axes
        are the columns of `rotation` (3, 3) (coordinates R^T x)."""
        rot = np.asarray(rotation, dtype=float)
        centre = self.position @ rot
        local = np.einsum("ji,kjl->kil", rot, self.rotation)            # R^T R_k: (k, 3, 3)
        ext = np.where(self.kind[:, None] == BOX, np.einsum("kil,kl->ki", np.abs(local), self.half), 0.0)
        ext = np.where(self.kind[:, None] == TUBE, np.abs(local[:, :, 0]) * self.half[:, :1], ext)
        ext = ext + self.rad[:, None]
        return centre - ext, centre + ext

    def bounding_radius(self) -> FloatArray:
        """(k,) radius of a sphere about each position that encloses the region."""
        core = np.where(self.kind == BOX, np.linalg.norm(self.half, axis=1),
                        np.where(self.kind == TUBE, self.half[:, 0], 0.0))
        return core + self.rad


def _frame_from_x(x: np.ndarray) -> np.ndarray:
    """A rotation (3, 3) whose first column is the unit vector x."""
    helper = np.array([0.0, 0.0, 1.0]) if abs(x[2]) < 0.9 else np.array([1.0, 0.0, 0.0])
    y = np.cross(helper, x)
    y /= np.linalg.norm(y)
    return np.column_stack([x, y, np.cross(x, y)])


@dataclass
class _Object:
    id: int
    nodes: np.ndarray          # every node of its subtree
    root: int
    pose: np.ndarray           # (4, 4) world pose of its frame
    group: str | None = None


class RegionTree:
    """The region tree of a workcell (see the module docstring).  Not thread-safe."""

    def __init__(self, leaf_size: int = 8) -> None:
        self.leaf_size = leaf_size
        self._kind = np.zeros(0, np.int8)
        self._pos = np.zeros((0, 3))
        self._rot = np.zeros((0, 3, 3))
        self._half = np.zeros((0, 3))
        self._rad = np.zeros(0)
        self._bound = np.zeros(0)
        self._solid = np.zeros(0, bool)
        self._obj = np.zeros(0, np.int32)
        self._active = np.zeros(0, bool)
        self._children: list[list[int]] = []
        self._roots: list[int] = []
        self._objects: dict[str, _Object] = {}
        self._names: list[str] = []
        self._groups: dict[str, int] = {}
        self._csr: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None

    # ---- structure -------------------------------------------------------------------
    @property
    def objects(self) -> tuple[str, ...]:
        """Names of the objects in the tree."""
        return tuple(self._objects)

    @property
    def node_count(self) -> int:
        """Number of active regions (solid and bounding)."""
        return int(self._active.sum())

    @property
    def object_count(self) -> int:
        """Number of object ids ever given (ids of removed objects are not reused)."""
        return len(self._names)

    def object_id(self, name: str) -> int:
        """The integer id of object `name` (as in the node arrays); KeyError if absent."""
        return self._objects[name].id

    def pose(self, name: str) -> np.ndarray:
        """(4, 4) world pose of object `name`'s frame; KeyError if absent."""
        return self._objects[name].pose.copy()

    def leaves(self, name: str | None = None) -> np.ndarray:
        """Node indices of the active solid regions (of one object, or all)."""
        nodes = self._objects[name].nodes if name is not None else np.arange(len(self._kind))
        return nodes[self._solid[nodes] & self._active[nodes]]

    def regions(self, nodes: ArrayLike) -> Regions:
        """The regions of the given node indices."""
        n = np.asarray(nodes, dtype=np.int64)
        return Regions(self._kind[n], self._pos[n], self._rot[n], self._half[n], self._rad[n])

    def object_names(self, nodes: ArrayLike) -> np.ndarray:
        """Object name (object array) of each node index; None for -1 or a group node."""
        n = np.asarray(nodes, dtype=np.int64)
        ids = np.where(n >= 0, self._obj[np.maximum(n, 0)], -1)
        return np.array([self._names[i] if i >= 0 else None for i in ids], dtype=object)

    def _append(self, regions: Regions, solid: bool, obj: int) -> np.ndarray:
        start = len(self._kind)
        k = len(regions)
        self._kind = np.concatenate([self._kind, regions.kind.astype(np.int8)])
        self._pos = np.concatenate([self._pos, regions.position])
        self._rot = np.concatenate([self._rot, regions.rotation])
        self._half = np.concatenate([self._half, regions.half])
        self._rad = np.concatenate([self._rad, regions.rad])
        self._bound = np.concatenate([self._bound, regions.bounding_radius()])
        self._solid = np.concatenate([self._solid, np.full(k, solid)])
        self._obj = np.concatenate([self._obj, np.full(k, obj, np.int32)])
        self._active = np.concatenate([self._active, np.ones(k, bool)])
        self._children.extend([] for _ in range(k))
        self._csr = None
        return np.arange(start, start + k)

    def _bounding_box(self, nodes: np.ndarray, rotation: np.ndarray, obj: int) -> int:
        lo, hi = self.regions(nodes).bounds_in(rotation)
        lo, hi = lo.min(axis=0), hi.max(axis=0)
        box = Regions(np.array([BOX], np.int8), (rotation @ ((lo + hi) / 2))[None], rotation[None].copy(),
                      ((hi - lo) / 2)[None], np.zeros(1))
        node = int(self._append(box, False, obj)[0])
        self._children[node] = [int(i) for i in nodes]
        return node

    def _split(self, leaves: np.ndarray, lo: np.ndarray, hi: np.ndarray, rotation: np.ndarray, obj: int,
               made: list[int]) -> int:
        """Root node of a bounding hierarchy over `leaves` (median splits along the widest
        axis of their centres); new bounding nodes are appended to `made`."""
        if len(leaves) == 1:
            return int(leaves[0])
        if len(leaves) <= self.leaf_size:
            node = self._bounding_box(leaves, rotation, obj)
            made.append(node)
            return node
        centre = (lo + hi) / 2
        axis = int(np.argmax(np.ptp(centre, axis=0)))
        order = np.argsort(centre[:, axis], kind="stable")
        halves = np.array_split(order, 2)
        kids = [self._split(leaves[h], lo[h], hi[h], rotation, obj, made) for h in halves]
        node = self._bounding_box(np.array(kids), rotation, obj)
        made.append(node)
        return node

    def add(self, name: str, regions: Regions, pose: ArrayLike | None = None, group: str | None = None) -> None:
        """Add object `name` made of the solid `regions` (world), whose frame is at `pose`
        (4, 4; default identity).  Its bounding boxes are aligned with that frame.  With
        `group`, its root goes under that group (made by `add_group`).  ValueError if the
        name is taken or there are no regions."""
        if name in self._objects:
            raise ValueError(f"object {name!r} is already in the tree")
        if len(regions) == 0:
            raise ValueError(f"object {name!r} has no regions")
        pose = np.eye(4) if pose is None else np.asarray(pose, dtype=float).copy()
        obj = len(self._names)
        self._names.append(name)
        leaves = self._append(regions, True, obj)
        made: list[int] = []
        lo, hi = regions.bounds_in(pose[:3, :3])
        root = self._split(leaves, lo, hi, pose[:3, :3], obj, made)
        self._objects[name] = _Object(obj, np.concatenate([leaves, np.array(made, dtype=np.int64)]), root, pose)
        if group is None:
            self._roots.append(root)
        else:
            self._attach(name, group)

    def add_group(self, group: str, members: Iterable[str]) -> None:
        """Put the given objects under one new bounding box (world axes) named `group`."""
        names = list(members)
        roots = np.array([self._objects[m].root for m in names])
        node = self._bounding_box(roots, np.eye(3), -1)
        self._groups[group] = node
        for m in names:
            self._detach(m)
            self._objects[m].group = group
        self._children[node] = [int(r) for r in roots]
        self._roots.append(node)
        self._csr = None

    def _attach(self, name: str, group: str) -> None:
        node, entry = self._groups[group], self._objects[name]
        lo, hi = self.regions([entry.root]).bounds_in(self._rot[node])
        glo = self._rot[node].T @ self._pos[node] - self._half[node]
        ghi = self._rot[node].T @ self._pos[node] + self._half[node]
        if np.any(lo[0] < glo - 1e-12) or np.any(hi[0] > ghi + 1e-12):
            self._roots.append(entry.root)      # not inside the group's box: a root of its own
        else:
            self._children[node].append(entry.root)
            entry.group = group
        self._csr = None

    def _detach(self, name: str) -> None:
        entry = self._objects[name]
        if entry.group is not None:
            self._children[self._groups[entry.group]].remove(entry.root)
            entry.group = None
        elif entry.root in self._roots:
            self._roots.remove(entry.root)
        self._csr = None

    def remove(self, name: str) -> None:
        """Take object `name` out of the tree (its regions go inactive); KeyError if absent."""
        self._detach(name)
        entry = self._objects.pop(name)
        self._active[entry.nodes] = False

    def update(self, name: str, pose: ArrayLike) -> None:
        """Move object `name` rigidly so that its frame is at `pose` (4, 4).  Its subtree is
        transformed in place (no rebuild); if it sat in a group it becomes a root, since the
        group's box no longer need contain it."""
        entry = self._objects[name]
        new = np.asarray(pose, dtype=float)
        delta = new @ _invert(entry.pose)
        n = entry.nodes
        self._pos[n] = self._pos[n] @ delta[:3, :3].T + delta[:3, 3]
        self._rot[n] = np.einsum("ij,kjl->kil", delta[:3, :3], self._rot[n])
        entry.pose = new.copy()
        if entry.group is not None:
            self._detach(name)
            self._roots.append(entry.root)
        self._csr = None

    def arrays(self) -> tuple:
        """The flat arrays the compiled walks take (see `kernels`)."""
        if self._csr is None:
            counts = np.array([len(c) for c in self._children], dtype=np.int64)
            ptr = np.zeros(len(counts) + 1, dtype=np.int64)
            np.cumsum(counts, out=ptr[1:])
            idx = np.array([i for c in self._children for i in c], dtype=np.int64)
            self._csr = (ptr, idx, np.array(self._roots, dtype=np.int64))
        ptr, idx, roots = self._csr
        return (self._kind, self._pos, self._rot, self._half, self._rad, self._bound, self._solid, self._obj,
                self._active, ptr, idx, roots)

    def containment_gaps(self, tol: float = 1e-9) -> list[tuple[int, int]]:
        """(parent, child) node pairs where the child is not inside its (box) parent: [] for
        a sound tree.  Exact for box parents, which are the only kind this tree makes."""
        gaps = []
        for parent, kids in enumerate(self._children):
            if not kids or not self._active[parent]:
                continue
            if self._kind[parent] != BOX:
                raise NotImplementedError("containment is checked for box parents only")
            rot = self._rot[parent]
            lo, hi = self.regions(kids).bounds_in(rot)
            c, h = rot.T @ self._pos[parent], self._half[parent]
            bad = np.any(lo < c - h - tol, axis=1) | np.any(hi > c + h + tol, axis=1)
            gaps += [(parent, kids[i]) for i in np.flatnonzero(bad)]
        return gaps

    # ---- queries ----------------------------------------------------------------------
    def first_hits(self, p0: ArrayLike, p1: ArrayLike, radius: ArrayLike = 0.0) -> np.ndarray:
        """Node index (n,) of a solid region met by each query tube (p0, p1 (n, 3), radius
        (n,) or scalar), or -1.  `object_names` turns them into object names."""
        p0 = np.ascontiguousarray(np.atleast_2d(np.asarray(p0, dtype=float)))
        p1 = np.ascontiguousarray(np.broadcast_to(np.atleast_2d(np.asarray(p1, dtype=float)), p0.shape))
        r = np.ascontiguousarray(np.broadcast_to(np.asarray(radius, dtype=float), p0.shape[:1]))
        if len(self._roots) == 0:
            return np.full(len(p0), -1, dtype=np.int64)
        return kernels.query_tree(p0, p1, r, *self.arrays())

    def points_hit(self, points: ArrayLike) -> np.ndarray:
        """Bool (n,): whether each point (n, 3) lies inside some solid region."""
        p = np.atleast_2d(np.asarray(points, dtype=float))
        return self.first_hits(p, p) >= 0

    def segments_hit(self, p0: ArrayLike, p1: ArrayLike) -> np.ndarray:
        """Bool (n,): whether each segment p0-p1 (n, 3) meets some solid region."""
        return self.first_hits(p0, p1) >= 0

    def tubes_hit(self, p0: ArrayLike, p1: ArrayLike, radius: ArrayLike) -> np.ndarray:
        """Bool (n,): whether each tube (axis p0-p1 (n, 3), radius (n,)) meets a solid region."""
        return self.first_hits(p0, p1, radius) >= 0

    def brute_force(self, p0: ArrayLike, p1: ArrayLike, radius: ArrayLike = 0.0) -> np.ndarray:
        """Bool (n,): the same answer as `first_hits(...) >= 0`, by testing every solid
        region (no skipping); for tests."""
        p0 = np.ascontiguousarray(np.atleast_2d(np.asarray(p0, dtype=float)))
        p1 = np.ascontiguousarray(np.broadcast_to(np.atleast_2d(np.asarray(p1, dtype=float)), p0.shape))
        r = np.ascontiguousarray(np.broadcast_to(np.asarray(radius, dtype=float), p0.shape[:1]))
        nodes = self.leaves()
        return kernels.query_pairs(p0, p1, r, self._kind, self._pos, self._rot, self._half, self._rad,
                                   self._bound, nodes).any(axis=1)


def _invert(pose: np.ndarray) -> np.ndarray:
    out = np.eye(4)
    out[:3, :3] = pose[:3, :3].T
    out[:3, 3] = -pose[:3, :3].T @ pose[:3, 3]
    return out
