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
  specs'), from its mesh: `mesh_cover.mesh_regions`, boxes around the mesh's surface
  pieces cube by cube, grown by `margin_mm`.

Parts are placed with the workcell's PartPlacement (mm to world metres).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import manifold3d as m3d
import numpy as np
from numpy.typing import NDArray

from ita.collision.mesh_cover import mesh_cell, mesh_regions
from ita.collision.tree import Regions, RegionTree
from ita.part import geometry2d as g2
from ita.part.model import FlangeSegment, Pocket, Stiffener
from ita.workcell.frames import homogeneous
from ita.workcell.model import Box, PartPlacement, ToolSpec, Workcell

FloatArray = NDArray[np.float64]

PART_MARGIN_MM = 2.0      # growth of every part region, mm
WEB_TILE_MM = 100.0       # web tiles' grid
CHAIN_SLACK_MM = 1.0      # how much wider than the strip a flange chain box may be


def _boxes_2d(centres: Sequence[FloatArray], axes: Sequence[FloatArray], lengths: Sequence[float],
              widths: Sequence[float], z0: Sequence[float], z1: Sequence[float], margin: float) -> Regions:
    """Boxes from a 2-D rectangle (centre, unit axis along its length) and a z range."""
    if not centres:
        return Regions.empty()
    c2, u = np.asarray(centres, dtype=float), np.asarray(axes, dtype=float)
    bottom, top = np.asarray(z0, dtype=float), np.asarray(z1, dtype=float)
    rot = np.zeros((len(c2), 3, 3))
    rot[:, :2, 0] = u
    rot[:, 0, 1], rot[:, 1, 1] = -u[:, 1], u[:, 0]
    rot[:, 2, 2] = 1.0
    centre = np.column_stack([c2, (bottom + top) / 2])
    size = np.column_stack([lengths, widths, top - bottom])
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
    lo: list[tuple[float, float, float]] = []
    hi: list[tuple[float, float, float]] = []
    for xa in np.arange(x0, x1, tile_mm):
        for ya in np.arange(y0, y1, tile_mm):
            xb, yb = min(xa + tile_mm, x1), min(ya + tile_mm, y1)
            cell = m3d.CrossSection([np.array([[xa, ya], [xb, ya], [xb, yb], [xa, yb]])])
            piece = cell ^ web
            if piece.area() > 0.0:
                bx0, by0, bx1, by1 = piece.bounds()
                lo.append((bx0, by0, 0.0))
                hi.append((bx1, by1, top))
    lows, highs = np.asarray(lo), np.asarray(hi)
    return Regions.boxes((lows + highs) / 2, np.eye(3), highs - lows, margin_mm)


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


def part_regions(part: Any, margin_mm: float = PART_MARGIN_MM) -> Regions:
    """Solid regions (part frame, mm) of a loaded Part: from its features when they describe
    the whole part (a features.json of the generator's), else from its mesh (features found
    on the mesh are only the ones the specs name)."""
    if any(isinstance(f, FlangeSegment) for f in part.features) and not getattr(part, "found", ()):
        return feature_regions(part.features, margin_mm)
    return mesh_regions(part.mesh, margin_mm, mesh_cell(part.mesh))


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
