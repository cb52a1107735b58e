"""A part given as a mesh, covered by boxes: the path planner's model of its solid.

The mesh's bounding box is cut into cubes of `cell_mm` (`mesh_cell`: 40 mm, finer for a
small part).  Each triangle is clipped to every cube its box touches (`clip_to_boxes`);
a cube with a surface piece becomes the box enclosing its pieces and its corners that lie
inside the solid, which together enclose the solid inside the cube (sound).  A cube with
no piece lies wholly inside or outside the solid: a whole box if inside.

How loose a box is: its air depth, how far it reaches in front of its own surface pieces
(`_air_depth`).  A box over a slanted or gently curved face reaches in front of it by its
width times the slope; such a box is turned to the face (to the pieces' mean normal, or to
the normal of the piece it reaches farthest in front of, whichever is tighter).  A box
still looser than LOOSE_MM (the empty corner where a floor meets a wall) is replaced by
its eight half cubes' boxes, `REFINE_LEVELS` times at most and not below cubes of twice
LOOSE_MM.  Every box is grown by the margin.

A mesh that is not watertight has no inside: its touched cubes are kept whole (a shell
around its surface) and not refined.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numba import njit
from numpy.typing import NDArray

from ita.collision.tree import Regions

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]

MESH_CELL_MM = 40.0       # largest cubes of a part's mesh cover
MESH_CELLS_ACROSS = 20    # a smaller part's cubes: its largest extent over this,
MIN_MESH_CELL_MM = 4.0    # down to this
REFINE_LEVELS = 3         # a loose cube is covered again by its eight halves this many times at most
LOOSE_MM = 1.0            # a box reaching this far in front of its surface pieces (mesh units) is loose
_CHUNK = 200_000          # triangle-cube pairs clipped at once (memory)
_OCTANTS = np.stack(np.meshgrid([0, 1], [0, 1], [0, 1], indexing="ij"), axis=-1).reshape(-1, 3)


def mesh_cell(mesh: Any) -> float:
    """The cube size (mm) of a part mesh's cover: MESH_CELL_MM for a large part, finer for a
    small one (at least MESH_CELLS_ACROSS cubes across it, at least MIN_MESH_CELL_MM)."""
    size = float(np.max(np.asarray(mesh.extents, dtype=float)))
    return float(np.clip(size / MESH_CELLS_ACROSS, MIN_MESH_CELL_MM, MESH_CELL_MM))


def mesh_regions(mesh: Any, margin_mm: float = 2.0, cell_mm: float = MESH_CELL_MM,
                 refine: int = REFINE_LEVELS) -> Regions:
    """Solid boxes (mesh frame and units) covering a triangle mesh's solid (see the module
    docstring), each grown by margin_mm."""
    verts = np.asarray(mesh.vertices, dtype=float)
    faces = np.asarray(mesh.faces)
    edges = np.linalg.norm(verts[faces] - verts[np.roll(faces, 1, axis=1)], axis=2)
    if len(faces) and float(edges.max()) > cell_mm:   # fewer triangle-cube pairs to clip
        import trimesh

        verts, faces = trimesh.remesh.subdivide_to_size(verts, faces, max_edge=cell_mm)
    tri = verts[np.asarray(faces)]
    normals = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    normals /= np.maximum(np.linalg.norm(normals, axis=1, keepdims=True), 1e-12)
    # grid origin off any round coordinate, so that grid corners avoid axis-aligned faces
    origin = verts.min(axis=0) - 0.2718281828 * cell_mm
    watertight = bool(getattr(mesh, "is_watertight", False))
    centres, rots, sizes = [], [], []
    parents: IntArray | None = None          # the loose cubes of the level above (their grid index there)
    cell = cell_mm
    for level in range(refine + 1):
        centre, rot, size, loose, idx = _cover_level(mesh, tri, normals, origin, cell, watertight, parents)
        last = level == refine or not watertight or cell / 2 < 2 * LOOSE_MM
        keep = np.ones(len(centre), dtype=bool) if last else ~loose
        centres.append(centre[keep])
        rots.append(rot[keep])
        sizes.append(size[keep])
        if keep.all():
            break
        parents = idx[~keep]
        cell /= 2.0
    return Regions.boxes(np.vstack(centres), np.concatenate(rots), np.vstack(sizes), margin_mm)


def clip_to_boxes(tri: FloatArray, lo: FloatArray, hi: FloatArray) -> tuple[FloatArray, IntArray]:
    """The corners of each triangle's piece inside its axis-aligned box (tri (p, 3, 3), lo
    and hi (p, 3)), by clipping it against the box's six planes: the points (m, 3) and the
    pair each belongs to (m,).  A triangle that misses its box gives none."""
    points, owner = [np.zeros((0, 3))], [np.zeros(0, dtype=np.int64)]
    for start in range(0, len(tri), _CHUNK):
        sl = slice(start, start + _CHUNK)
        pts, own = _clip_kernel(np.ascontiguousarray(tri[sl]), np.ascontiguousarray(lo[sl]),
                                np.ascontiguousarray(hi[sl]))
        points.append(pts)
        owner.append(own + start)
    return np.vstack(points), np.concatenate(owner)


@njit(cache=True)
def _clip_kernel(tri, lo, hi):  # pragma: no cover - compiled
    """Sutherland-Hodgman, one polygon at a time (at most 9 corners after six planes)."""
    p = tri.shape[0]
    out = np.empty((p * 9, 3))
    owner = np.empty(p * 9, dtype=np.int64)
    a = np.empty((10, 3))
    b = np.empty((10, 3))
    m = 0
    for i in range(p):
        # a box the triangle's plane misses: nothing to clip
        e1 = tri[i, 1] - tri[i, 0]
        e2 = tri[i, 2] - tri[i, 0]
        nx = e1[1] * e2[2] - e1[2] * e2[1]
        ny = e1[2] * e2[0] - e1[0] * e2[2]
        nz = e1[0] * e2[1] - e1[1] * e2[0]
        cx, cy, cz = (lo[i, 0] + hi[i, 0]) / 2, (lo[i, 1] + hi[i, 1]) / 2, (lo[i, 2] + hi[i, 2]) / 2
        reach = (abs(nx) * (hi[i, 0] - lo[i, 0]) + abs(ny) * (hi[i, 1] - lo[i, 1])
                 + abs(nz) * (hi[i, 2] - lo[i, 2])) / 2
        if abs(nx * (cx - tri[i, 0, 0]) + ny * (cy - tri[i, 0, 1]) + nz * (cz - tri[i, 0, 2])) > reach * (1 + 1e-9):
            continue
        for k in range(3):
            a[k] = tri[i, k]
        count = 3
        for axis in range(3):
            for side in range(2):
                if count == 0:
                    break
                bound = lo[i, axis] if side == 0 else hi[i, axis]
                sign = -1.0 if side == 0 else 1.0
                nb = 0
                for k in range(count):
                    kn = k + 1 if k + 1 < count else 0
                    dv = sign * (a[k, axis] - bound)
                    dw = sign * (a[kn, axis] - bound)
                    if dv <= 0:
                        b[nb] = a[k]
                        nb += 1
                    if (dv <= 0) != (dw <= 0):
                        t = dv / (dv - dw)
                        b[nb] = a[k] + t * (a[kn] - a[k])
                        nb += 1
                for k in range(nb):
                    a[k] = b[k]
                count = nb
        for k in range(count):
            out[m] = a[k]
            owner[m] = i
            m += 1
    return out[:m].copy(), owner[:m].copy()


@njit(cache=True)
def _group_extent(local, box_of, n):  # pragma: no cover - compiled
    """Per group (box_of (m,) in 0..n-1) the min and max of the points local (m, 3)."""
    lo = np.full((n, 3), np.inf)
    hi = np.full((n, 3), -np.inf)
    for i in range(local.shape[0]):
        g = box_of[i]
        for j in range(3):
            v = local[i, j]
            if v < lo[g, j]:
                lo[g, j] = v
            if v > hi[g, j]:
                hi[g, j] = v
    return lo, hi


def _parent_grid(parents: IntArray | None, shape: IntArray) -> NDArray[np.bool_] | None:
    """The loose parents (grid indices at the level above) as a bool grid over that level;
    None: no parents (the first level), every cube counts."""
    if parents is None:
        return None
    allowed = np.zeros(tuple((shape + 1) // 2 + 1), dtype=bool)
    allowed[parents[:, 0], parents[:, 1], parents[:, 2]] = True
    return allowed


def _pairs(tri: FloatArray, origin: FloatArray, cell_mm: float, allowed: NDArray[np.bool_] | None
           ) -> tuple[IntArray, IntArray]:
    """The (triangle, cube) pairs whose boxes touch (cubes as grid indices (n, 3)); given
    the parents' grid (`_parent_grid`), only the cubes inside them."""
    tlo, thi = tri.min(axis=1), tri.max(axis=1)
    i0 = np.floor((tlo - origin) / cell_mm).astype(np.int64)
    i1 = np.floor((thi - origin) / cell_mm).astype(np.int64)
    use = np.arange(len(tri))
    if allowed is not None:
        near = allowed[tuple((np.clip(i0 // 2, 0, None)).T)] | allowed[tuple((np.clip(i1 // 2, 0, None)).T)]
        use = np.flatnonzero(near | ((i1 // 2 - i0 // 2).max(axis=1) > 0))
    span = i1[use] - i0[use] + 1
    counts = span.prod(axis=1)
    of = np.repeat(np.arange(len(use)), counts)
    k = np.arange(counts.sum()) - np.repeat(np.cumsum(counts) - counts, counts)
    sy, sz = span[of, 1], span[of, 2]
    cells = i0[use][of] + np.column_stack([k // (sy * sz), (k // sz) % sy, k % sz])
    tri_of = use[of]
    if allowed is not None:
        inside_parent = allowed[cells[:, 0] // 2, cells[:, 1] // 2, cells[:, 2] // 2]
        cells, tri_of = cells[inside_parent], tri_of[inside_parent]
    return tri_of, cells


def _cover_level(mesh: Any, tri: FloatArray, normals: FloatArray, origin: FloatArray, cell_mm: float,
                 watertight: bool, parents: IntArray | None
                 ) -> tuple[FloatArray, FloatArray, FloatArray, NDArray[np.bool_], IntArray]:
    """One level of the cover: the boxes (centre (n, 3), rotation (n, 3, 3), size (n, 3))
    of the cubes of `cell_mm` (those with a surface piece, and the whole ones inside the
    solid), whether each is loose, and each cube's grid index (n, 3).  parents: only the
    cubes inside these cubes of twice the size (grid indices at that level)."""
    shape = np.floor((tri.max(axis=(0, 1)) - origin) / cell_mm).astype(np.int64) + 1
    allowed = _parent_grid(parents, shape)
    tri_of, cells = _pairs(tri, origin, cell_mm, allowed)
    points, pair = clip_to_boxes(tri[tri_of], origin + cells * cell_mm, origin + (cells + 1) * cell_mm)
    met = np.zeros(len(tri_of), dtype=bool)
    met[pair] = True
    keys, inv = np.unique(np.ravel_multi_index(cells[met].T, shape), return_inverse=True)
    tri_of = tri_of[met]
    renumber = np.cumsum(met) - 1
    point_cube = inv[renumber[pair]]
    idx = np.column_stack(np.unravel_index(keys, shape))
    n = len(idx)
    if not watertight:
        lo = origin + idx * cell_mm
        return lo + cell_mm / 2, _upright(n), np.full((n, 3), cell_mm), np.zeros(n, dtype=bool), idx
    corner_cube, corner_point, inside = _inside_corners(mesh, idx, origin, cell_mm, shape, parents)
    cube_of = np.concatenate([point_cube, corner_cube])
    everything = np.vstack([points, corner_point])
    surface = _Surface(normals[tri_of], tri[tri_of, 0], inv)
    rot = _upright(n).copy()
    lo, hi = _extent(rot, cube_of, everything, n)
    depth = surface.air_depth(rot, lo, hi)
    loose = np.flatnonzero(depth > LOOSE_MM)
    at = np.full(n, -1, dtype=np.int64)          # each loose cube's place among them
    at[loose] = np.arange(len(loose))
    mine = at[cube_of] >= 0
    for axis in surface.axes(loose, rot, lo, hi):
        r = _frames(axis)
        t_lo, t_hi = _extent(r, at[cube_of[mine]], everything[mine], len(loose))
        t_depth = surface.air_depth(r, t_lo, t_hi, at)
        better = t_depth < depth[loose]
        k = loose[better]
        rot[k], lo[k], hi[k], depth[k] = r[better], t_lo[better], t_hi[better], t_depth[better]
    centre = np.einsum("nij,nj->ni", rot, (lo + hi) / 2)
    size = hi - lo
    # cubes with no surface piece lie wholly inside or outside: whole boxes if inside
    touched = np.zeros(tuple(shape), dtype=bool)
    touched[idx[:, 0], idx[:, 1], idx[:, 2]] = True
    whole = ~touched & inside[:-1, :-1, :-1]
    if allowed is not None:
        whole &= allowed.repeat(2, 0).repeat(2, 1).repeat(2, 2)[:shape[0], :shape[1], :shape[2]]
    full = np.argwhere(whole)
    return (np.vstack([centre, origin + (full + 0.5) * cell_mm]),
            np.concatenate([rot, _upright(len(full))]),
            np.vstack([size, np.full((len(full), 3), cell_mm)]),
            np.concatenate([depth > LOOSE_MM, np.zeros(len(full), dtype=bool)]),
            np.vstack([idx, full]))


def _inside_corners(mesh: Any, idx: IntArray, origin: FloatArray, cell_mm: float, shape: IntArray,
                    parents: IntArray | None) -> tuple[IntArray, FloatArray, NDArray[np.bool_]]:
    """The corners of the cubes idx that lie inside the solid (cube index, point) and the
    inside flags of the grid's corners (only those of the cubes inside the parents)."""
    gshape = shape + 1
    if parents is None:
        grid = np.indices(tuple(gshape)).reshape(3, -1).T
    else:
        children = (parents[:, None, :] * 2 + _OCTANTS[None]).reshape(-1, 3)
        children = children[np.all(children < shape, axis=1)]
        grid = np.unique((children[:, None, :] + _OCTANTS[None]).reshape(-1, 3), axis=0)
    inside = np.zeros(tuple(gshape), dtype=bool)
    if len(grid):
        inside[grid[:, 0], grid[:, 1], grid[:, 2]] = np.asarray(mesh.contains(origin + grid * cell_mm), dtype=bool)
    cubes, points = [], []
    for corner in _OCTANTS:
        c = idx + corner
        inn = np.flatnonzero(inside[c[:, 0], c[:, 1], c[:, 2]])
        cubes.append(inn)
        points.append(origin + c[inn] * cell_mm)
    return np.concatenate(cubes), np.vstack(points), inside


def _upright(n: int) -> FloatArray:
    return np.broadcast_to(np.eye(3), (n, 3, 3))


def _frames(axis: FloatArray) -> FloatArray:
    """Rotations (k, 3, 3) whose first column is each unit axis (k, 3) and second level."""
    helper = np.where(np.abs(axis[:, 2:3]) < 0.9, [[0.0, 0.0, 1.0]], [[1.0, 0.0, 0.0]])
    y = np.cross(helper, axis)
    y /= np.linalg.norm(y, axis=1, keepdims=True)
    return np.stack([axis, y, np.cross(axis, y)], axis=2)


def _extent(rot: FloatArray, box_of: IntArray, points: FloatArray, n: int) -> tuple[FloatArray, FloatArray]:
    """Each box's (lo, hi) in its own frame (rot (n, 3, 3), columns its axes) around its points."""
    local = np.einsum("pi,pij->pj", points, rot[box_of])
    return _group_extent(np.ascontiguousarray(local), np.ascontiguousarray(box_of, dtype=np.int64), n)


class _Surface:
    """The surface pieces of a level's cubes: each piece's normal and a point of its plane,
    and the cube it lies in."""

    def __init__(self, normal: FloatArray, on_plane: FloatArray, cube: IntArray) -> None:
        self.normal, self.on_plane, self.cube = normal, on_plane, cube

    def air_depth(self, rot: FloatArray, lo: FloatArray, hi: FloatArray, at: IntArray | None = None) -> FloatArray:
        """How far each box (rot, lo, hi in its frame) reaches in front of its cube's pieces:
        the largest distance, over the pieces, of the box's farthest corner in front of the
        piece's plane.  0 where the box lies behind all its surface (a convex edge's quarter
        box, a floor's slab); a cube's width where it fills the empty corner of a floor
        meeting a wall.  at: the box of each cube (-1: none) when boxes are a subset."""
        box = self.cube if at is None else at[self.cube]
        mine = box >= 0
        box = box[mine]
        n = np.einsum("pi,pij->pj", self.normal[mine], rot[box])
        far = np.where(n > 0, hi[box], lo[box])
        ahead = np.einsum("pj,pj->p", n, far) - np.einsum("pi,pi->p", self.normal[mine], self.on_plane[mine])
        depth = np.zeros(len(lo))
        np.maximum.at(depth, box, ahead)
        return depth

    def axes(self, cubes: IntArray, rot: FloatArray, lo: FloatArray, hi: FloatArray) -> list[FloatArray]:
        """Two directions (k, 3) to turn the cubes' boxes to: their pieces' mean normal (a
        gently curved face) and the normal of the piece their box now reaches farthest in
        front of (a slanted face meeting a level one at a convex edge)."""
        if not len(cubes):
            return []
        at = np.full(len(lo), -1, dtype=np.int64)
        at[cubes] = np.arange(len(cubes))
        mine = np.flatnonzero(at[self.cube] >= 0)
        b = at[self.cube[mine]]
        normal = self.normal[mine]
        mean = np.zeros((len(cubes), 3))
        np.add.at(mean, b, normal)
        size = np.linalg.norm(mean, axis=1, keepdims=True)
        mean = np.where(size > 1e-9, mean / np.maximum(size, 1e-12), [[1.0, 0.0, 0.0]])
        box = self.cube[mine]
        n = np.einsum("pi,pij->pj", normal, rot[box])
        ahead = (np.einsum("pj,pj->p", n, np.where(n > 0, hi[box], lo[box]))
                 - np.einsum("pi,pi->p", normal, self.on_plane[mine]))
        order = np.lexsort((ahead, b))
        last = np.r_[b[order][1:] != b[order][:-1], True]
        worst = np.zeros((len(cubes), 3))
        worst[b[order][last]] = normal[order][last]
        return [mean, worst]
