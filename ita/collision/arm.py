"""Arm collision checks: the arm's links as tubes against the region tree and each other.

The caller computes the tubes' world segments per configuration (forward kinematics, e.g.
`ita.kinematics.fk.link_segments`, whose ArmModel carries the tube_links and tube_radii
this module needs); a check is then one compiled pass over a batch:

    checker = ArmChecker(tree, radii, tube_links)
    free = ~checker.collides(segments)          # segments (n, t, 2, 3) -> bool (n,)

World: every tube except those of the fixed base link (tube_links == 0), which never
moves, is walked through the tree; the objects the arm is mounted on (`mount`, e.g. the
pedestal) do not count for link 1's tubes, whose enclosing capsules reach down into them.  Self: tube pairs whose links are not adjacent in the
chain (|link_i - link_j| > 1, pybullet's default filter).  A tool held by the arm is one
more tube (`tool_tube`) on the flange link; it moves with the arm, so it is not in the
tree while held (remove it from the tree at pick-up, add it back at put-down).
Cylinders of the URDF are checked as the capsules that enclose them (conservative).
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ita.collision import kernels
from ita.collision.tree import RegionTree
from ita.workcell.model import ToolSpec

FREE, WORLD, SELF = 0, 1, 2


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
    objects the base stands on, which links 0 and 1 may touch.  The tree is read at each
    call, so updates to it are seen."""

    def __init__(self, tree: RegionTree, radii: ArrayLike, tube_links: ArrayLike,
                 pairs: ArrayLike | None = None, world: ArrayLike | None = None,
                 mount: Iterable[str] = ()) -> None:
        self.tree = tree
        self.radii = np.ascontiguousarray(radii, dtype=float)
        self.tube_links = np.asarray(tube_links, dtype=np.int64)
        if self.radii.shape != self.tube_links.shape:
            raise ValueError("radii and tube_links must have the same length")
        self.pairs = np.ascontiguousarray(self_pairs(self.tube_links) if pairs is None else pairs, dtype=np.int64)
        self.world = np.ascontiguousarray(self.tube_links != 0 if world is None else world, dtype=np.bool_)
        self.mount = tuple(mount)

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
        return kernels.check_arm(segs, self.radii, self.world, self._ignore(), self.pairs, *self.tree.arrays())

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
