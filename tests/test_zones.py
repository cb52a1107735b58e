"""Interference zones (ita.executive.zones): two arms never hold one zone at once, their
bodies stay apart, and no pair of claims deadlocks: not with the arms sent across each
other, not on random work."""

from __future__ import annotations

import numpy as np
import pytest

from ita.executive.zones import (
    RADIUS_M,
    ArmJob,
    Deadlock,
    Move,
    ZoneGrid,
    coordinate,
    min_separation,
    segment_distance,
)

A, B = (0.0, 0.0), (0.0, -2.0)          # two bases 2 m apart, a wall of work at x = 1.7


def job(name: str, base, targets, move_s: float = 1.0, dwell_s: float = 2.0) -> ArmJob:
    return ArmJob(name, base, (base[0] + 0.5, base[1]),
                  tuple(Move((float(x), float(y)), move_s, dwell_s, f"{name}{k}") for k, (x, y) in enumerate(targets)))


def held_apart(schedule, grid: ZoneGrid, jobs) -> None:
    """No zone is held by both arms in overlapping time (the table's own promise) ..."""
    by = {j.name: j for j in jobs}
    spans = {}
    for name, steps in schedule.timeline.items():
        rows = []
        for s, e, end, a, b, _ in steps:
            rows.append((s, e, grid.swept(by[name].base, a, b)))
            rows.append((e, end, grid.at_rest(by[name].base, b)))
        spans[name] = rows
    (n1, r1), (n2, r2) = spans.items()
    for s1, e1, z1 in r1:
        for s2, e2, z2 in r2:
            if s1 < e2 and s2 < e1 and e1 > s1 and e2 > s2:
                assert not z1 & z2, (n1, s1, e1, n2, s2, e2)
    # ... and, checked by geometry alone, the bodies keep twice the radius between them
    assert min_separation(schedule, jobs) >= 2 * RADIUS_M - 1e-9


def test_arms_sent_across_each_other_finish_without_deadlock_or_contact() -> None:
    ta = [(1.7, y) for y in (-0.2, -0.6, -1.0, -1.4, -1.8, -2.2)]   # A works toward B's base
    tb = [(1.7, y) for y in (-1.8, -1.4, -1.0, -0.6, -0.2, 0.2)]    # B toward A's
    jobs = [job("a", A, ta), job("b", B, tb)]
    grid = ZoneGrid.around([A, B, *ta, *tb])
    s = coordinate(grid, jobs)
    assert [len(s.timeline[n]) - s.retreats[n] for n in ("a", "b")] == [6, 6]      # every move made
    assert s.retreats["b"] >= 1                   # the lower priority gave way ...
    kinds = [e.kind for e in s.events if e.arm == "b"]
    assert "wait" in kinds and "continue" in kinds          # ... waited, and went on when cleared
    assert s.waiting_s["b"] > 0
    held_apart(s, grid, jobs)


def test_arms_working_apart_never_wait() -> None:
    ta = [(1.7, y) for y in (0.6, 0.3, 0.0, 0.4)]
    tb = [(1.7, y) for y in (-2.6, -2.3, -2.0, -2.4)]
    jobs = [job("a", A, ta), job("b", B, tb)]
    s = coordinate(ZoneGrid.around([A, B, *ta, *tb]), jobs)
    assert s.waiting_s == {"a": 0.0, "b": 0.0} and s.retreats == {"a": 0, "b": 0}
    assert s.makespan_s == pytest.approx(4 * 3.0)            # both at once: one arm's time


@pytest.mark.parametrize("seed", range(12))
def test_random_work_always_ends_with_the_arms_apart(seed: int) -> None:
    rng = np.random.default_rng(seed)
    n = int(rng.integers(3, 9))
    ta = [(1.7, float(y)) for y in rng.uniform(-1.6, 0.8, n)]
    tb = [(1.7, float(y)) for y in rng.uniform(-2.8, -0.4, n)]
    jobs = [job("a", A, ta, float(rng.uniform(0.3, 2)), float(rng.uniform(0.5, 3))),
            job("b", B, tb, float(rng.uniform(0.3, 2)), float(rng.uniform(0.5, 3)))]
    grid = ZoneGrid.around([A, B, *ta, *tb])
    s = coordinate(grid, jobs)
    assert all(len(s.timeline[j.name]) - s.retreats[j.name] == len(j.moves) for j in jobs)
    held_apart(s, grid, jobs)
    # the makespan is no less than either arm's own work, no more than both in turn plus retreats
    own = [sum(m.move_s + m.dwell_s for m in j.moves) for j in jobs]
    assert max(own) - 1e-9 <= s.makespan_s <= sum(own) + 10.0


def test_a_target_at_the_other_arms_base_is_refused_not_waited_for_ever() -> None:
    jobs = [job("a", A, [(1.7, -0.5), (0.3, -1.9)]), job("b", B, [(1.7, -2.5)])]
    with pytest.raises(Deadlock, match="base zone"):
        coordinate(ZoneGrid.around([A, B, (1.7, -2.5), (1.7, -0.5)]), jobs)


def test_a_tool_change_a_downed_arm_bars_bars_the_moves_made_with_that_tool() -> None:
    """The downed arm b stands at (1.0, -1.0): a taking a tool from a slot beside it is
    barred, and with it every measurement of that tool, up to its next tool change."""
    down = ArmJob("b", B, (1.0, -1.0), (), down=True)
    moves = (Move((1.7, 0.6), 1.0, 2.0, "a0"),
             Move((1.0, -0.9), 1.0, 0.0, "pick up t2", tool_change=True),     # beside the downed arm
             Move((1.7, 0.4), 1.0, 2.0, "a1"), Move((1.7, 0.2), 1.0, 2.0, "a2"),
             Move((0.3, 0.8), 1.0, 0.0, "pick up t3", tool_change=True),
             Move((1.7, 0.5), 1.0, 2.0, "a3"))
    jobs = [ArmJob("a", A, (0.5, 0.0), moves), down]
    s = coordinate(ZoneGrid.around([A, B, *(m.target for m in moves), down.start]), jobs)
    assert s.skipped["a"] == ("pick up t2", "a1", "a2")
    assert [row[-1] for row in s.timeline["a"]] == ["a0", "pick up t3", "a3"]


def test_segment_distance() -> None:
    p = lambda x, y: np.array([x, y], dtype=float)  # noqa: E731
    assert segment_distance(p(0, 0), p(2, 0), p(1, -1), p(1, 1)) == 0.0          # crossing
    assert segment_distance(p(0, 0), p(2, 0), p(0, 1), p(2, 1)) == pytest.approx(1.0)
    assert segment_distance(p(0, 0), p(1, 0), p(2, 1), p(3, 1)) == pytest.approx(np.sqrt(2))


def _tube_gap(A: np.ndarray, ra: np.ndarray, B: np.ndarray, rb: np.ndarray, samples: int = 15) -> float:
    """The least distance between two sets of tubes' surfaces ((T, 2, 3) ends, radii),
    their axes sampled (never less than the true distance)."""
    t = np.linspace(0.0, 1.0, samples)[:, None]
    pa = (A[:, None, 0] + t[None] * (A[:, None, 1] - A[:, None, 0])).reshape(-1, 3)
    pb = (B[:, None, 0] + t[None] * (B[:, None, 1] - B[:, None, 0])).reshape(-1, 3)
    d = np.linalg.norm(pa[:, None] - pb[None], axis=2) - np.repeat(ra, samples)[:, None] - np.repeat(rb, samples)[None]
    return float(d.min())


@pytest.fixture(scope="module")
def two_bodies():
    from ita.collision.zones import arm_body, folded_configuration
    from ita.kinematics import arm_model
    from ita.workcell import load_workcell

    cell = load_workcell()
    arms = [cell.seen_by(a.name).arm for a in cell.arms()]
    bodies = [arm_body(arm_model(a), cell.tools) for a in arms]
    fold = folded_configuration(bodies[1].model, arms[1].joints.lower, arms[1].joints.upper, bodies[1])[0]
    return cell, arms, bodies, fold


def test_zones_that_do_not_meet_keep_the_arms_tubes_the_margin_apart_in_3d(two_bodies) -> None:
    """Random pairs of poses of the default cell's two arms: whenever their zones do not
    meet, their collision tubes (and the tools') are at least MARGIN_M apart; and poses
    whose tubes touch always share a zone."""
    from ita.collision.zones import MARGIN_M

    cell, arms, bodies, _fold = two_bodies
    grid = ZoneGrid.around([a.base.position[:2] for a in arms], margin=2.0)
    rng = np.random.default_rng(5)
    apart = touching = 0
    for _ in range(1500):
        q = [rng.uniform(a.joints.lower, a.joints.upper) for a in arms]
        tubes = [b.tubes(x[None])[0] for b, x in zip(bodies, q)]
        radii = [np.asarray(b.model.tube_radii).tolist() + b.tool_radii.tolist() for b in bodies]
        gap = _tube_gap(tubes[0], np.asarray(radii[0]), tubes[1], np.asarray(radii[1]))
        meet = grid.near_tubes(tubes[0], bodies[0].radii) & grid.near_tubes(tubes[1], bodies[1].radii)
        if not meet:
            apart += 1
            assert gap >= MARGIN_M - 1e-9, gap          # (sampled axes: never nearer than they are)
        if gap <= 0:
            touching += 1
            assert meet
    assert apart > 50 and touching > 5                # both cases were tried


def test_the_folded_arm_turned_any_way_is_never_nearer_than_its_field_says(two_bodies) -> None:
    """Revolved: the clearance of a point is a lower bound of its distance to the folded
    arm's tubes, whatever that arm's base joint, and a tight one (within a few cm)."""
    from ita.collision.zones import Revolved

    cell, arms, bodies, fold = two_bodies
    base = (float(arms[1].base.position[0]), float(arms[1].base.position[1]))
    field = Revolved.of(bodies[1], fold, base)
    rng = np.random.default_rng(2)
    points = np.column_stack([base[0] + rng.uniform(-1.5, 1.5, 400), base[1] + rng.uniform(-1.5, 1.5, 400),
                              rng.uniform(0.0, 3.5, 400)])
    turned = np.array([fold] * 24)
    turned[:, 0] = np.linspace(arms[1].joints.lower[0], arms[1].joints.upper[0], 24)
    tubes = bodies[1].tubes(turned)                                  # (24, T, 2, 3)
    t = np.linspace(0.0, 1.0, 61)[:, None, None, None]
    axis = tubes[None, :, :, 0] + t * (tubes[None, :, :, 1] - tubes[None, :, :, 0])    # (61, 24, T, 3)
    radii = bodies[1].radii
    true = np.min(np.linalg.norm(points[:, None, None, None] - axis[None], axis=-1) - radii, axis=(1, 2, 3))
    bound = field.clearance(points)
    assert np.all(bound <= true + 1e-9)
    near = true < 1.0
    assert near.sum() > 20 and np.max(true[near] - bound[near]) < 0.15     # the turning sampled in 24 steps


def test_near_tubes_marks_exactly_the_zones_whose_centre_is_within_reach() -> None:
    """The compiled marking (it skips columns the segment cannot reach) against every zone
    centre's distance to every segment, brute force: tilted, upright, flat, point-like
    and out-of-box segments."""
    grid = ZoneGrid((-1.0, -1.0), (1.0, 1.2), 0.1, 0.3, 2.0)
    rng = np.random.default_rng(3)
    ends = rng.uniform((-1.4, -1.4, -0.3), (1.4, 1.5, 2.4), size=(60, 2, 3))
    ends[0, 1] = ends[0, 0]                                        # a point
    ends[1, 1, :2] = ends[1, 0, :2]                                # upright
    ends[2, 1, 2] = ends[2, 0, 2]                                  # level
    radii = rng.uniform(0.0, 0.35, size=60)
    nx, ny = grid.shape
    i, j, k = np.meshgrid(np.arange(nx), np.arange(ny), np.arange(grid.levels), indexing="ij")
    centres = np.stack([grid.low[0] + (i + 0.5) * grid.cell, grid.low[1] + (j + 0.5) * grid.cell,
                        (k + 0.5) * grid.cell], -1).reshape(-1, 3)
    for s in range(60):
        a, b = ends[s]
        lo, hi = (*grid.low, 0.0), (*grid.high, grid.z_high)
        a, b = np.clip(a, lo, hi), np.clip(b, lo, hi)              # (the kernel brings ends into the box)
        v = b - a
        t = np.clip((centres - a) @ v / max(float(v @ v), 1e-300), 0.0, 1.0) if v @ v > 0 else np.zeros(len(centres))
        d = np.linalg.norm(centres - (a + t[:, None] * v), axis=1)
        want = d <= radii[s] + grid.cell * np.sqrt(0.75)
        got = grid.near_tubes(ends[s][None, None], radii[s:s + 1])
        raw = np.frombuffer(got.to_bytes((len(centres) + 7) // 8, "little"), dtype=np.uint8)
        marked = np.unpackbits(raw, bitorder="little")[:len(centres)].astype(bool)
        assert np.array_equal(marked, want), (s, int(np.sum(marked != want)))


def test_tubes_meet_answers_as_the_zones_of_the_tubes_would() -> None:
    """ZoneGrid.tubes_meet (the conductor's way-back test: only the given zones' cells
    tried, the first hit ending it) against near_tubes(...) & zones, on random tubes and
    random zone sets, near and far, met and missed."""
    grid = ZoneGrid((-1.0, -1.0), (1.0, 1.2), 0.1, 0.3, 2.0)
    rng = np.random.default_rng(11)
    met = missed = 0
    for _ in range(300):
        tubes = rng.uniform((-1.3, -1.3, -0.2), (1.3, 1.4, 2.3), size=(int(rng.integers(1, 6)), 3, 2, 3))
        radii = rng.uniform(0.0, 0.2, size=3)
        centre = rng.uniform((-1.0, -1.0, 0.0), (1.0, 1.2, 2.0))
        other = grid.near_tubes(np.array([[[centre, centre + rng.normal(0.0, 0.2, 3)]]]), rng.uniform(0.0, 0.3, 1))
        want = bool(grid.near_tubes(tubes, radii) & other)
        assert grid.tubes_meet(tubes, radii, other) == want
        met, missed = met + want, missed + (not want)
    assert met > 30 and missed > 30                      # both answers were tried
    assert not grid.tubes_meet(tubes, radii, 0)
