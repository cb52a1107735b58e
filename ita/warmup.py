"""Compile ITA's numba kernels once, so a user's first command does not pay for it.

numba caches compiled code beside the sources (`cache=True`); `setup.sh` runs this after
installing.  Without it, a fresh checkout's first inspection spends half a minute or more
compiling.  Each step runs the code a run runs, on small made-up inputs of the same types:
the classic ordering (the `default` and `fast` ones are libraries, LKH and fast-tsp), forward kinematics, path
planning with its collision and motion checks, a range frame with a hole and mixed pixels
(ray casting, phase noise, the edges' k-d tree), and a circle fit.  Run by hand:
`python -m ita.warmup`.
"""

from __future__ import annotations

import time
from collections.abc import Callable

import numpy as np

from ita.collision import Regions
from ita.kinematics import link_segments
from ita.part.model import Hole, HoleRole
from ita.path.planner import workcell_planner
from ita.sensors.slra_frame import ScanGeometry
from ita.sequence.tour import solve_tour
from ita.sim.slra import SlraParams, SlraScene, simulate_frame
from ita.vision.fit import fit_circle, fit_circle_fixed_radius
from ita.workcell import load_workcell
from ita.workcell.model import PartPlacement


def warm_tours() -> None:
    """Compile the classic ordering's kernels (closed tours and open paths, with and without coordinates)."""
    rng = np.random.default_rng(0)
    coords = rng.random((12, 2))
    cost = np.linalg.norm(coords[:, None] - coords[None], axis=-1)
    solve_tour(cost, method="classic", coords=coords)
    solve_tour(cost, method="classic", start=0)


def warm_paths() -> None:
    """Compile forward kinematics and the path planner's collision and motion kernels: the
    default workcell's planners (bare, and holding a probe) each moving the arm from home
    to one side and past a beam (a subgoal is needed)."""
    cell = load_workcell()
    home = np.asarray(cell.arm.home, dtype=float)
    for held in (None, cell.tools[0].name):
        planner, _ = workcell_planner(cell, None, held)
        planner.plan(home, home + np.array([0.6, -0.2, 0.3, 0.4, -0.3, 0.5]))
        planner.tree.add("beam", Regions.boxes([[1.5, 0.0, 2.45]], np.eye(3), [[0.3, 0.4, 0.6]]))
        planner.plan(np.array([-0.9, 0.3, -0.2, 0.0, 0.4, 0.0]), np.array([0.9, 0.3, -0.2, 0.0, 0.4, 0.0]))
        planner.checker.collides(link_segments(planner.model, home[None]))


def warm_frames() -> None:
    """Compile the range simulator's and Vision's kernels: a frame of a plate with a bore
    (hits, holes, mixed pixels, phase noise), in halves on a second core where there is
    one, and a circle fit to its rim's points."""
    import trimesh

    placement = PartPlacement(0.001, ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0)), (0.0, 0.0, 0.0),
                              (-500.0, -500.0, -100.0), (500.0, 500.0, 100.0))
    hole = Hole("W1", HoleRole.LIGHTENING, (10.0, -20.0, 0.0), (0.0, 0.0, 1.0), 60.0, 10.0, "P1")
    plate = trimesh.creation.box(extents=(600.0, 600.0, 10.0)).apply_translation((0.0, 0.0, -5.0))
    solid = plate.difference(trimesh.creation.cylinder(radius=30.0, height=30.0, sections=48)
                             .apply_translation(hole.center))
    pose = np.eye(4)
    pose[:3, :3] = np.column_stack([(1.0, 0.0, 0.0), (0.0, -1.0, 0.0), (0.0, 0.0, -1.0)])
    pose[:3, 3] = (0.005, 0.003, 0.45)
    simulate_frame(SlraScene(solid, placement, holes=(hole,)), pose, ScanGeometry((128, 160), (12.0, 12.0)),
                   SlraParams(), np.random.default_rng(0))
    t = np.linspace(0.0, 2 * np.pi, 40, endpoint=False)
    rim = np.column_stack([10.0 + 30.0 * np.cos(t), -20.0 + 30.0 * np.sin(t)])
    fit_circle(rim)
    fit_circle_fixed_radius(rim, 30.0)


STEPS: tuple[tuple[str, Callable[[], None]], ...] = (
    ("ordering", warm_tours), ("paths", warm_paths), ("range frames", warm_frames))


def main() -> None:
    t0 = time.perf_counter()
    for name, step in STEPS:
        t = time.perf_counter()
        step()
        print(f"[setup] compiled the {name} kernels in {time.perf_counter() - t:.1f} s")
    print(f"[setup] kernels compiled in {time.perf_counter() - t0:.1f} s")


if __name__ == "__main__":
    main()
