"""The part and its workcell as the 3-D views draw them, loaded once per part directory.

    scene = PartScene.load(part_dir)          # mesh (mm), specs, the workcell in the world (m)
    scene.mesh                                # (vertices (n, 3) mm, faces (m, 3))
    scene.arm_links(q)                        # the arm's tubes at q, (t, 2, 3) world m
    scene.arm_at_rest("t3_b")                 # either arm of a two-arm cell at its home

Loading the part takes seconds (its mesh and specs): `ita serve` keeps the scenes it has
loaded; a report loads its run's once.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ita.kinematics import arm_model
from ita.kinematics.fk import link_segments
from ita.part import specfile
from ita.part.store import load_part
from ita.workcell import workcell_for

_BOX_FACES = np.array([[0, 1, 3], [0, 3, 2], [4, 6, 7], [4, 7, 5], [0, 4, 5], [0, 5, 1],
                       [2, 3, 7], [2, 7, 6], [0, 2, 6], [0, 6, 4], [1, 5, 7], [1, 7, 3]])


def box_mesh(box: Any) -> tuple[np.ndarray, np.ndarray]:
    """(vertices (8, 3), faces (12, 3)) of a workcell Box (pose, full size), world m."""
    half = np.asarray(box.size, dtype=float) / 2
    corners = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)]) * half
    m = box.pose.matrix()
    return corners @ m[:3, :3].T + m[:3, 3], _BOX_FACES


@dataclass(frozen=True, eq=False)
class PartScene:
    """A part's mesh (part frame, mm), its specs, and its workcell (world frame, m)."""

    directory: Path | None
    mesh: tuple[np.ndarray, np.ndarray]
    specs: tuple[Any, ...]
    workcell: Any
    arm_model: Any

    @classmethod
    def load(cls, part_dir: Path | str | None) -> PartScene:
        """The scene of the part in `part_dir` (None: the built-in bulkhead)."""
        part = load_part(None if part_dir is None else Path(part_dir))
        mesh = part.mesh
        cell = workcell_for(part.directory, part.mesh.bounds)
        return cls(part.directory, (np.asarray(mesh.vertices, dtype=float), np.asarray(mesh.faces, dtype=int)),
                   tuple(specfile.load(part)), cell, arm_model(cell.arm))

    def boxes(self) -> list[tuple[np.ndarray, np.ndarray]]:
        """The workcell's fixed boxes as meshes (world m), the floor left out."""
        return [box_mesh(b) for b in self.workcell.static_boxes() if "floor" not in b.name]

    def mesh_world(self) -> tuple[np.ndarray, np.ndarray]:
        """The part's mesh in the world frame (m)."""
        v, f = self.mesh
        return self.workcell.part.to_world(v), f

    def to_world(self, point_mm: Any) -> np.ndarray:
        return self.workcell.part.to_world(np.asarray([point_mm], dtype=float))[0]

    def arm_links(self, q: Any) -> np.ndarray:
        """The arm's collision tubes at configuration q (6,): segment ends (t, 2, 3), world m."""
        return link_segments(self.arm_model, np.asarray([q], dtype=float))[0]

    def second_arm_boxes(self) -> list[tuple[np.ndarray, np.ndarray]]:
        """The second arm's own equipment (its pedestal, and its stations when it has
        them) as meshes (world m): outside the first arm's world, drawn for a two-arm run."""
        cell = self.workcell
        boxes = [] if cell.second_pedestal is None else [cell.second_pedestal]
        if cell.second_stations is not None:
            own = cell.second_stations
            boxes += [own.couplant_station, own.cal_block, *own.stands]
        return [box_mesh(b) for b in boxes]

    def arm_at_rest(self, arm_name: str) -> np.ndarray:
        """Arm `arm_name`'s tubes where it starts and parks (its home): (t, 2, 3), world m;
        KeyError for an arm the cell does not have."""
        arm = self.workcell.seen_by(arm_name).arm
        model = self.arm_model if arm_name == self.workcell.arm.name else arm_model(arm)
        return link_segments(model, np.asarray([arm.home], dtype=float))[0]
