"""Building the region tree from the workcell and the part, conservatively.

Every point of the real geometry lies inside some solid region:

- Workcell boxes (floor, pedestal, fixture, rack, stations, fence) and the parked tools'
  body boxes are regions as they are: exact, margin `box_margin` (default 0).
- The part, from its features (`feature_regions`, part frame, mm): the web as box tiles
  (a grid of `tile_mm` cells, each cut to the web's outline and as thick as the thickest
  pocket floor), each flange segment's wall and cap as chains of boxes that enclose the
  strip between its path and the path moved along its normals, each stiffener as a box;
  every box grown by `margin_mm` (default 2 mm) on every side.  Holes are not carved out
  (a lightening hole counts as solid web; conservative).
- A user part without features (or with features found on its mesh, which are only the
  specs'), from its mesh (`mesh_regions`): the mesh's bounding box is cut into cubes of
  `cell_mm` (`mesh_cell`: 40 mm, finer for a small part); a cube that any triangle's
  bounding box touches becomes the box bounding that cube's share of the triangles'
  boxes and of its corners that lie inside the solid; a cube with no triangle becomes a
  whole box if it lies inside the solid (a watertight mesh; without one, touched cubes
  are kept whole).  A cube whose surface pieces face different ways is covered again by
  its eight halves (`REFINE_LEVELS` times at most).  Grown by `margin_mm`.  Soundness:
  the part of the solid inside a cube is bounded by its surface pieces and its inside
  corners.  Looseness: up to a cube's width where a slanted or curved edge crosses it
  (a probe beside a flange cap's rounded corner can find its contact blocked).

Parts are placed with the workcell's PartPlacement (mm to world metres).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import manifold3d as m3d
import numpy as np
from numpy.typing import NDArray

from ita.collision.tree import Regions, RegionTree
from ita.part import geometry2d as g2
from ita.part.model import FlangeSegment, Pocket, Stiffener
from ita.workcell.frames import homogeneous
from ita.workcell.model import Box, PartPlacement, ToolSpec, Workcell

FloatArray = NDArray[np.float64]

PART_MARGIN_MM = 2.0      # growth of every part region, mm
WEB_TILE_MM = 100.0       # web tiles' grid
CHAIN_SLACK_MM = 1.0      # how much wider than the strip a flange chain box may be
MESH_CELL_MM = 40.0       # largest cubes of a user part's mesh cover
MESH_CELLS_ACROSS = 20    # a smaller part's cubes: its largest extent over this (a curved surface's boxes
MIN_MESH_CELL_MM = 4.0    # bulge by their sagitta), down to this
REFINE_LEVELS = 2         # a loose cube is covered again by its eight halves this many times at most
LOOSE_SPREAD = 0.5        # a cube's surface normals spreading this much (|max - min|) make it loose


def _boxes_2d(centres: list, axes: list, lengths: list, widths: list, z0: list, z1: list,
              margin: float) -> Regions:
    """Boxes from a 2-D rectangle (centre, unit axis along its length) and a z range."""
    if not centres:
        return Regions.empty()
    c2, u = np.asarray(centres, dtype=float), np.asarray(axes, dtype=float)
    z0, z1 = np.asarray(z0, dtype=float), np.asarray(z1, dtype=float)
    rot = np.zeros((len(c2), 3, 3))
    rot[:, :2, 0] = u
    rot[:, 0, 1], rot[:, 1, 1] = -u[:, 1], u[:, 0]
    rot[:, 2, 2] = 1.0
    centre = np.column_stack([c2, (z0 + z1) / 2])
    size = np.column_stack([lengths, widths, z1 - z0])
    return Regions.boxes(centre, rot, size, margin)


def _loop(segments: Sequence[FlangeSegment]) -> np.ndarray:
    parts = [s.path_array[:-1] for s in sorted(segments, key=lambda s: s.s_range[0])]
    return g2.ccw(np.vstack(parts))


def web_tiles(features: Sequence[Any], tile_mm: float = WEB_TILE_MM, margin_mm: float = PART_MARGIN_MM) -> Regions:
    """Boxes (part frame, mm) covering the web: the region inside the outer flange's path
    and outside the inner one's, z 0 .. the thickest pocket floor, grown by margin_mm."""
    outer = [f for f in features if isinstance(f, FlangeSegment) and f.side == "outer"]
    inner = [f for f in features if isinstance(f, FlangeSegment) and f.side == "inner"]
    pockets = [f for f in features if isinstance(f, Pocket)]
    if not outer or not pockets:
        return Regions.empty()
    web = m3d.CrossSection([_loop(outer)])
    if inner:
        web = web - m3d.CrossSection([_loop(inner)])
    top = max(p.web_thickness for p in pockets)
    x0, y0, x1, y1 = web.bounds()
    lo, hi = [], []
    for xa in np.arange(x0, x1, tile_mm):
        for ya in np.arange(y0, y1, tile_mm):
            xb, yb = min(xa + tile_mm, x1), min(ya + tile_mm, y1)
            cell = m3d.CrossSection([np.array([[xa, ya], [xb, ya], [xb, yb], [xa, yb]])])
            piece = cell ^ web
            if piece.area() > 0.0:
                bx0, by0, bx1, by1 = piece.bounds()
                lo.append((bx0, by0, 0.0))
                hi.append((bx1, by1, top))
    lo, hi = np.asarray(lo), np.asarray(hi)
    return Regions.boxes((lo + hi) / 2, np.eye(3), hi - lo, margin_mm)


def _strip_chain(path: np.ndarray, normals: np.ndarray, width: float, slack: float) -> list[tuple]:
    """Rectangles (centre, axis, length, width) covering the band path .. path + width *
    normals: runs of consecutive path points, each enclosed by the rectangle aligned with
    its chord, a run grown while that rectangle stays within width + slack across."""
    far = path + width * normals

    def rect(i: int, j: int) -> tuple:
        pts = np.vstack([path[i:j + 1], far[i:j + 1]])
        chord = path[j] - path[i]
        u = chord / np.linalg.norm(chord)
        v = np.array([-u[1], u[0]])
        pu, pv = pts @ u, pts @ v
        centre = (pu.min() + pu.max()) / 2 * u + (pv.min() + pv.max()) / 2 * v
        return centre, u, pu.max() - pu.min(), pv.max() - pv.min()

    out, i, n = [], 0, len(path)
    while i < n - 1:
        j = i + 1
        while j + 1 < n and rect(i, j + 1)[3] <= width + slack:
            j += 1
        out.append(rect(i, j))
        i = j
    return out


def feature_regions(features: Sequence[Any], margin_mm: float = PART_MARGIN_MM, tile_mm: float = WEB_TILE_MM,
                    slack_mm: float = CHAIN_SLACK_MM) -> Regions:
    """Solid boxes (part frame, mm) enclosing a part described by its features (web,
    flange walls and caps, stiffeners), each grown by margin_mm.  Holes are not carved."""
    cols: dict[str, list] = {k: [] for k in ("c", "u", "l", "w", "z0", "z1")}

    def put(rects: list, z0: float, z1: float) -> None:
        for centre, u, length, width in rects:
            for key, val in zip(cols, (centre, u, length, width, z0, z1)):
                cols[key].append(val)

    for f in features:
        if isinstance(f, FlangeSegment):
            put(_strip_chain(f.path_array, f.normals_array, f.wall_thickness, slack_mm), 0.0, f.height)
            put(_strip_chain(f.path_array, f.normals_array, f.cap_width, slack_mm),
                f.height - f.cap_thickness, f.height)
        elif isinstance(f, Stiffener):
            s, e = np.asarray(f.start), np.asarray(f.end)
            put([((s + e) / 2, f.direction, float(np.linalg.norm(e - s)), f.width)], 0.0, f.height)
    walls = _boxes_2d(cols["c"], cols["u"], cols["l"], cols["w"], cols["z0"], cols["z1"], margin_mm)
    return Regions.concat([web_tiles(features, tile_mm, margin_mm), walls])


def mesh_regions(mesh: Any, margin_mm: float = PART_MARGIN_MM, cell_mm: float = MESH_CELL_MM,
                 refine: int = REFINE_LEVELS) -> Regions:
    """Solid boxes (mesh frame and units) covering a triangle mesh's solid (see the module
    docstring), each grown by margin_mm.  A cube whose surface pieces face different ways
    (a floor meeting a wall: its box would fill the empty corner between them) is covered
    again by its eight sub-cubes, `refine` times at most."""
    verts = np.asarray(mesh.vertices, dtype=float)
    faces = np.asarray(mesh.faces)
    edges = np.linalg.norm(verts[faces] - verts[np.roll(faces, 1, axis=1)], axis=2)
    if len(faces) and float(edges.max()) > cell_mm:   # a triangle's box spans no more than a cube
        import trimesh

        verts, faces = trimesh.remesh.subdivide_to_size(verts, faces, max_edge=cell_mm)
    tri = verts[np.asarray(faces)]
    normals = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    normals /= np.maximum(np.linalg.norm(normals, axis=1, keepdims=True), 1e-12)
    # grid origin off any round coordinate, so that grid corners avoid axis-aligned faces
    origin = verts.min(axis=0) - 0.2718281828 * cell_mm
    watertight = bool(getattr(mesh, "is_watertight", False))
    los, his = [], []
    parents: NDArray[np.int64] | None = None            # the loose cubes of the level above (their index there)
    cell = cell_mm
    for level in range(refine + 1):
        lo, hi, loose, idx = _cover_level(mesh, tri, normals, origin, cell, watertight, parents)
        last = level == refine
        keep = np.ones(len(lo), dtype=bool) if last else ~loose
        los.append(lo[keep])
        his.append(hi[keep])
        if last or not loose.any():
            break
        parents = idx[loose]
        cell /= 2.0
    lo, hi = np.vstack(los), np.vstack(his)
    return Regions.boxes((lo + hi) / 2, np.eye(3), hi - lo, margin_mm)


def _cover_level(mesh: Any, tri: FloatArray, normals: FloatArray, origin: FloatArray, cell_mm: float,
                 watertight: bool, parents: NDArray[np.int64] | None
                 ) -> tuple[FloatArray, FloatArray, NDArray[np.bool_], NDArray[np.int64]]:
    """One level of the mesh's cover: the boxes (lo, hi) of the cubes of `cell_mm` (the
    touched ones and the whole ones inside), whether each is loose (its surface pieces'
    normals spread more than LOOSE_SPREAD), and each cube's grid index (n, 3).  parents:
    only the cubes inside these cubes of twice the size (grid indices at that level)."""
    shape = np.floor((tri.max(axis=(0, 1)) - origin) / cell_mm).astype(np.int64) + 1
    tlo, thi = tri.min(axis=1), tri.max(axis=1)
    i0 = np.floor((tlo - origin) / cell_mm).astype(np.int64)
    i1 = np.floor((thi - origin) / cell_mm).astype(np.int64)
    allowed = None
    if parents is not None:
        allowed = np.zeros(tuple((shape + 1) // 2 + 1), dtype=bool)
        allowed[parents[:, 0], parents[:, 1], parents[:, 2]] = True
        near = allowed[tuple((np.clip(i0 // 2, 0, None)).T)] | allowed[tuple((np.clip(i1 // 2, 0, None)).T)]
        span_parent = (i1 // 2 - i0 // 2).max(axis=1) > 0
        use = near | span_parent
        tri, normals, tlo, thi, i0, i1 = tri[use], normals[use], tlo[use], thi[use], i0[use], i1[use]
    span = i1 - i0 + 1
    counts = span.prod(axis=1)
    tri_of = np.repeat(np.arange(len(tri)), counts)
    k = np.arange(counts.sum()) - np.repeat(np.cumsum(counts) - counts, counts)
    sy, sz = span[tri_of, 1], span[tri_of, 2]
    cells = i0[tri_of] + np.column_stack([k // (sy * sz), (k // sz) % sy, k % sz])
    if allowed is not None:
        inside_parent = allowed[cells[:, 0] // 2, cells[:, 1] // 2, cells[:, 2] // 2]
        cells, tri_of = cells[inside_parent], tri_of[inside_parent]
    key = np.ravel_multi_index(cells.T, shape)
    keys, inv = np.unique(key, return_inverse=True)
    lo = np.full((len(keys), 3), np.inf)
    hi = np.full((len(keys), 3), -np.inf)
    np.minimum.at(lo, inv, tlo[tri_of])
    np.maximum.at(hi, inv, thi[tri_of])
    n_lo = np.full((len(keys), 3), np.inf)
    n_hi = np.full((len(keys), 3), -np.inf)
    np.minimum.at(n_lo, inv, normals[tri_of])
    np.maximum.at(n_hi, inv, normals[tri_of])
    loose = np.linalg.norm(n_hi - n_lo, axis=1) > LOOSE_SPREAD
    idx = np.column_stack(np.unravel_index(keys, shape))
    cell_lo = origin + idx * cell_mm
    cell_hi = cell_lo + cell_mm
    if not watertight:
        return cell_lo, cell_hi, loose, idx
    gshape = shape + 1
    octants = np.stack(np.meshgrid([0, 1], [0, 1], [0, 1], indexing="ij"), axis=-1).reshape(-1, 3)
    if allowed is None:
        grid = np.stack(np.meshgrid(*(np.arange(s) for s in gshape), indexing="ij"), axis=-1).reshape(-1, 3)
    else:                        # only the corners of the cubes inside the loose parents
        children = (parents[:, None, :] * 2 + octants[None]).reshape(-1, 3)
        children = children[np.all(children < shape, axis=1)]
        grid = np.unique((children[:, None, :] + octants[None]).reshape(-1, 3), axis=0)
    inside = np.zeros(tuple(gshape), dtype=bool)
    if len(grid):
        inside[grid[:, 0], grid[:, 1], grid[:, 2]] = np.asarray(mesh.contains(origin + grid * cell_mm), dtype=bool)
    for corner in octants:
        c = idx + corner
        inn = inside[c[:, 0], c[:, 1], c[:, 2]]
        p = origin + c * cell_mm
        lo[inn] = np.minimum(lo[inn], p[inn])
        hi[inn] = np.maximum(hi[inn], p[inn])
    lo, hi = np.maximum(lo, cell_lo), np.minimum(hi, cell_hi)
    # cubes with no triangle lie wholly inside or outside: whole boxes if inside
    touched = np.zeros(tuple(shape), dtype=bool)
    touched[idx[:, 0], idx[:, 1], idx[:, 2]] = True
    whole = ~touched & inside[:-1, :-1, :-1]
    if allowed is not None:
        a = np.indices(tuple(shape)).reshape(3, -1).T
        whole &= allowed[a[:, 0] // 2, a[:, 1] // 2, a[:, 2] // 2].reshape(tuple(shape))
    full = np.argwhere(whole)
    lo = np.vstack([lo, origin + full * cell_mm])
    hi = np.vstack([hi, origin + (full + 1) * cell_mm])
    idx = np.vstack([idx, full])
    loose = np.concatenate([loose, np.zeros(len(full), dtype=bool)])
    return lo, hi, loose, idx


def part_regions(part: Any, margin_mm: float = PART_MARGIN_MM) -> Regions:
    """Solid regions (part frame, mm) of a loaded Part: from its features when they describe
    the whole part (a features.json of the generator's), else from its mesh (features found
    on the mesh are only the ones the specs name)."""
    if any(isinstance(f, FlangeSegment) for f in part.features) and not getattr(part, "found", ()):
        return feature_regions(part.features, margin_mm)
    return mesh_regions(part.mesh, margin_mm, mesh_cell(part.mesh))


def mesh_cell(mesh: Any) -> float:
    """The cube size (mm) of a part mesh's cover: MESH_CELL_MM for a large part, finer for a
    small one (at least MESH_CELLS_ACROSS cubes across it, at most MIN_MESH_CELL_MM)."""
    size = float(np.max(np.asarray(mesh.extents, dtype=float)))
    return float(np.clip(size / MESH_CELLS_ACROSS, MIN_MESH_CELL_MM, MESH_CELL_MM))


def placement_pose(placement: PartPlacement) -> np.ndarray:
    """(4, 4) world pose of the part frame (its scale is applied separately)."""
    return homogeneous(placement.rotation_matrix(), placement.translation)


def box_regions(box: Box, margin: float = 0.0) -> Regions:
    """The workcell box as one region (world)."""
    return Regions.boxes(box.pose.position, box.pose.rotation(), box.size, margin)


def tool_regions(tool: ToolSpec, flange_pose: np.ndarray, margin: float = 0.0) -> Regions:
    """The tool's body box (world) when its flange frame is at flange_pose (4, 4)."""
    local = Regions.boxes(tool.body_center, np.eye(3), tool.body_size, margin)
    return local.transformed(flange_pose)


def build_tree(cell: Workcell, part: Any | None = None, *, margin_mm: float = PART_MARGIN_MM,
               box_margin: float = 0.0, parked_tools: bool = True, groups: bool = True) -> RegionTree:
    """The region tree of the workcell: its static boxes, the parked tools (each object
    named after its tool, its frame the slot's flange pose) and, given a Part, the part
    (object "part", frame the part frame).  groups: fixture and part, rack and tools,
    and the stations each under one bounding box."""
    tree = RegionTree()
    for box in cell.static_boxes():
        tree.add(box.name, box_regions(box, box_margin), box.pose.matrix())
    tools = []
    if parked_tools:
        for slot in cell.rack.slots:
            if slot.tool:
                pose = slot.pose.matrix()
                tree.add(slot.tool, tool_regions(cell.tool(slot.tool), pose, box_margin), pose)
                tools.append(slot.tool)
    has_part = part is not None
    if has_part:
        pose = placement_pose(cell.part)
        tree.add("part", part_regions(part, margin_mm).transformed(pose, cell.part.scale), pose)
    if groups:
        tree.add_group("fixture", [b.name for b in cell.fixture] + (["part"] if has_part else []))
        tree.add_group("rack", [cell.rack.box.name] + tools)
        tree.add_group("stations", [cell.couplant_station.name, cell.cal_block.name] + [s.name for s in cell.stands])
    return tree
