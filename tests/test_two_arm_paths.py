"""The Path Planner of one arm of a two-arm run keeps clear of where the other arm may
stand folded (ita.executive.conductor.folded_ground), so that with the other arm folded
the zone conductor grants every motion it plans."""

from __future__ import annotations

import numpy as np
import pytest

from ita.executive.conductor import Conductor, conducted_arms, folded_ground, standing_ground, zone_grid
from ita.geometry.configurations import measurement_configurations
from ita.kinematics import arm_model, tcp_poses
from ita.path import planners_for
from ita.sequence.cost import rack_configurations
from ita.sequence.plan import planning_context
from ita.workcell import load_workcell


@pytest.fixture(scope="module")
def cell():
    return load_workcell()


def test_the_ground_holds_the_other_arm_folded_whatever_its_base_joint(cell) -> None:
    ground = folded_ground(cell, margin=0.0)
    other = next(a for a in conducted_arms(cell) if a.name != cell.arm.name)
    base = np.asarray(cell.second_arm.base.position[:2])
    tops = ground.position[:, 2] + ground.half[:, 0]
    bottoms = ground.position[:, 2] - ground.half[:, 0]
    for theta in np.linspace(-np.pi, np.pi, 13):
        q = np.asarray(other.fold, dtype=float).copy()
        q[0] = theta
        ends = other.body.tubes(q[None])[0]                                   # (T, 2, 3)
        for (a, b), r in zip(ends, other.body.radii):
            for p in a + np.linspace(0.0, 1.0, 9)[:, None] * (b - a):
                band = (bottoms <= p[2] + 1e-9) & (p[2] <= tops + 1e-9)
                if not band.any():
                    continue                        # below the lowest band: inside its pedestal
                rho = float(np.hypot(*(p[:2] - base)))
                assert rho + r <= ground.rad[band].max() + 1e-9, f"a tube at {p} leaves the ground (base {theta:.2f})"


def test_a_path_to_the_rack_keeps_out_of_the_zones_of_the_other_arm_folded(cell) -> None:
    """The first arm from rack slot 1 to a measurement at the part's far end: planned
    without the ground, the way passes where the second arm stands folded; with it, its
    zones never meet those of the second arm folded at any base joint."""
    ctx = planning_context(None, arm=cell.arm.name)
    model = arm_model(cell.arm)
    tool = cell.tool("us_probe_1")
    conf = measurement_configurations(cell, model, tool, [ctx.spec("FT-OFL04-W1")])
    assert conf.found[0]
    goal = tcp_poses(model, conf.q[:1], tool.tcp.matrix())[0].copy()
    goal[:3, 3] -= 0.03 * goal[:3, 2]                                         # 3 cm off the part
    _slot, above = rack_configurations(cell, model, "us_probe_1")
    conductor = Conductor(zone_grid(cell), conducted_arms(cell))
    a, b = conductor.order
    fold = np.asarray(conductor.state[b].arm.fold, dtype=float)

    def meets_folded(path) -> bool:
        swept = conductor.swept(a, path.times, path.q)
        for theta in np.linspace(-np.pi, np.pi, 25):
            q = fold.copy()
            q[0] = theta
            if swept & conductor.body(b, q):
                return True
        return False

    planner, held = planners_for(cell, None, keep_clear=folded_ground(cell))("us_probe_1")
    got = planner.plan(above, goal, held)
    assert got.ok, got.message
    assert not meets_folded(got.trajectory)
    bare, held = planners_for(cell, None)("us_probe_1")
    before = bare.plan(above, goal, held)
    assert before.ok and meets_folded(before.trajectory)             # the case the ground is for


def test_a_hand_over_plans_around_the_other_arm_where_it_stands(cell) -> None:
    """Once the other arm stands still for good (a hand-over), the Path Planner keeps clear
    of its body there, not of every place it might fold to: a configuration inside the
    folded ground but clear of the standing body is free again."""
    other = next(a for a in conducted_arms(cell) if a.name != cell.arm.name)
    stands = np.asarray(other.fold, dtype=float).copy()
    stands[0] = np.pi / 2                                       # folded, turned to one side
    standing = standing_ground(cell, {other.name: stands})
    ends = other.body.tubes(stands[None])[0]
    assert len(standing) == len(ends) and np.all(standing.rad > np.asarray(other.body.radii))
    folded, _ = planners_for(cell, None, keep_clear=folded_ground(cell))(None)
    around, _ = planners_for(cell, None, keep_clear=standing)(None)
    rng = np.random.default_rng(3)
    lo, hi = np.asarray(cell.arm.joints.lower), np.asarray(cell.arm.joints.upper)
    q = lo + (hi - lo) * rng.random((4000, 6))
    free_folded, free_around = folded.config_free(q), around.config_free(q)
    assert np.all(free_around[free_folded])                     # the standing body lies within the folded ground
    assert np.any(free_around & ~free_folded)                   # and frees some of it
