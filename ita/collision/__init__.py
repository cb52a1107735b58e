"""The Collision Avoidance Model: a region tree over the workcell, the part and the arm.

    from ita.collision import build_tree, ArmChecker
    tree = build_tree(load_workcell(), load_part(None))   # conservative, part margin 2 mm
    tree.points_hit(points)                               # (n, 3) m -> bool (n,)
    tree.segments_hit(p0, p1)                             # (n, 3), (n, 3) -> bool (n,)
    tree.update("us_probe_1", pose); tree.remove("us_probe_1")
    checker = ArmChecker(tree, model.tube_radii, model.tube_links)
    checker.collides(link_segments(model, q))              # (n, t, 2, 3) -> bool (n,)
    tubes = arm_tubes(cell.arm.urdf, model.link_names).with_tool(tool, model.dof + 1)
    tubes.checker(tree, mount=["pedestal"]); tubes.apply(model)   # tight links, real tool shape

Modules: `shapes` (numpy distance and overlap primitives, the reference), `kernels`
(compiled walks), `tree` (RegionTree, Regions), `build` (from Workcell and Part), `arm`.
"""

from ita.collision.arm import (
    FREE,
    SELF,
    TIP_CLEARANCE,
    WORLD,
    ArmChecker,
    ArmHits,
    ArmTubes,
    arm_tubes,
    self_pairs,
    tool_tube,
    tool_tubes,
    urdf_tubes,
)
from ita.collision.build import (
    PART_MARGIN_MM,
    build_tree,
    feature_regions,
    mesh_regions,
    part_regions,
    tool_regions,
)
from ita.collision.shapes import BOX, SPHERE, TUBE
from ita.collision.tree import Regions, RegionTree

__all__ = [
    "BOX",
    "FREE",
    "PART_MARGIN_MM",
    "SELF",
    "SPHERE",
    "TIP_CLEARANCE",
    "TUBE",
    "WORLD",
    "ArmChecker",
    "ArmHits",
    "ArmTubes",
    "RegionTree",
    "Regions",
    "arm_tubes",
    "build_tree",
    "feature_regions",
    "mesh_regions",
    "part_regions",
    "self_pairs",
    "tool_regions",
    "tool_tube",
    "tool_tubes",
    "urdf_tubes",
]
