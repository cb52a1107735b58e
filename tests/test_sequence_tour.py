"""Ordering: valid tours, open paths, asymmetric costs, determinism, quality on TSPLIB, the CLI."""

from __future__ import annotations

import itertools
import json
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from ita.cli.sequence import sequence
from ita.sequence.tour import METHODS, solve_tour, tour_cost
from ita.sequence.tsplib import read_tsplib

TSPLIB = Path(__file__).resolve().parents[1].parent / "shared" / "tsplib"
BERLIN = TSPLIB / "berlin52.tsp"
needs_tsplib = pytest.mark.skipif(not BERLIN.exists(), reason=f"TSPLIB instances not found in {TSPLIB}")
BERLIN_OPTIMUM = 7542
OPTIMA = {"berlin52": 7542, "kroA100": 21282, "ch150": 6528}  # TSPLIB95's published optima


def brute_force(D: np.ndarray, start: int | None = None, end: int | None = None) -> float:
    """Least cost of a closed tour (no start/end) or an open path, by enumeration."""
    n = D.shape[0]
    if start is None and end is None:
        return min(tour_cost(D, (0,) + p) for p in itertools.permutations(range(1, n)))
    best = np.inf
    for p in itertools.permutations(range(n)):
        if (start is None or p[0] == start) and (end is None or p[-1] == end):
            best = min(best, tour_cost(D, p, closed=False))
    return best


def random_points(n: int, seed: int) -> np.ndarray:
    return np.random.default_rng(seed).uniform(0, 100, size=(n, 2))


def distances(xy: np.ndarray) -> np.ndarray:
    return np.linalg.norm(xy[:, None] - xy[None], axis=2)


@pytest.mark.parametrize("method", list(METHODS))
@pytest.mark.parametrize("n", [1, 2, 3, 5, 9, 40])
def test_tour_is_a_permutation_with_its_cost(method, n):
    xy = random_points(n, n)
    D = distances(xy)
    t = solve_tour(D, method=method, coords=xy)
    assert sorted(t.order) == list(range(n))
    assert t.cost == pytest.approx(tour_cost(D, t.order))
    assert t.closed and t.method == method and t.seconds >= 0


@pytest.mark.parametrize("method", list(METHODS))
@pytest.mark.parametrize("seed", range(4))
def test_asymmetric_matches_brute_force(method, seed):
    rng = np.random.default_rng(seed)
    D = rng.uniform(1, 10, size=(8, 8))
    t = solve_tour(D, method=method)
    assert sorted(t.order) == list(range(8))
    if method in ("default", "fast"):
        assert t.cost == pytest.approx(brute_force(D))
    else:
        assert t.cost <= 1.5 * brute_force(D)


@pytest.mark.parametrize("method", list(METHODS))
@pytest.mark.parametrize("seed", range(3))
def test_open_paths_respect_start_and_end(method, seed):
    rng = np.random.default_rng(10 + seed)
    D = rng.uniform(1, 10, size=(7, 7))
    D_sym = D + D.T
    for M in (D, D_sym):
        for start, end in ((2, None), (2, 5), (None, 4)):
            t = solve_tour(M, method=method, start=start, end=end)
            assert not t.closed and sorted(t.order) == list(range(7))
            assert start is None or t.order[0] == start
            assert end is None or t.order[-1] == end
            assert t.cost == pytest.approx(tour_cost(M, t.order, closed=False))
            if method in ("default", "fast"):
                assert t.cost == pytest.approx(brute_force(M, start, end))


def test_start_equal_to_end_is_a_closed_tour_from_start():
    D = distances(random_points(12, 3))
    t = solve_tour(D, start=4, end=4)
    assert t.closed and t.order[0] == 4
    assert t.cost == pytest.approx(tour_cost(D, t.order))


def test_asymmetric_circle_is_travelled_the_cheap_way():
    # Points on a circle; going clockwise costs 10 extra per step.  The optimum is the
    # counter-clockwise circle, found only by a method that charges reversals correctly.
    n = 60
    angle = np.random.default_rng(5).permutation(n) * 2 * np.pi / n
    xy = np.c_[np.cos(angle), np.sin(angle)] * 100
    D = distances(xy)
    ccw_step = (angle[None, :] - angle[:, None]) % (2 * np.pi)
    D = D + np.where(ccw_step > np.pi, 10.0, 0.0)
    optimum = n * 2 * 100 * np.sin(np.pi / n)
    t = solve_tour(D)
    assert t.cost == pytest.approx(optimum, rel=1e-9)
    path = solve_tour(D, start=int(np.argmin(angle)))
    assert path.order[0] == int(np.argmin(angle))
    assert path.cost == pytest.approx(optimum * (n - 1) / n, rel=1e-9)


@pytest.mark.parametrize("method", list(METHODS))
@pytest.mark.parametrize("symmetric", [True, False])
def test_larger_open_paths_respect_start_and_end(method, symmetric):
    # Past the exact sizes: the dummy node (and, asymmetric, the 2n-node transform) at work.
    xy = random_points(60, 13)
    D = distances(xy)
    if not symmetric:
        D = D + np.random.default_rng(14).uniform(0, 20, size=D.shape)
    for start, end in ((4, None), (4, 17), (None, 9)):
        t = solve_tour(D, method=method, coords=xy, start=start, end=end)
        assert not t.closed and sorted(t.order) == list(range(60))
        assert start is None or t.order[0] == start
        assert end is None or t.order[-1] == end
        assert t.cost == pytest.approx(tour_cost(D, t.order, closed=False))


def test_classic_is_unchanged():
    # The seed's method gives the orders it gave before the default method changed.
    xy = np.random.default_rng(21).uniform(0, 100, size=(80, 2))
    D = distances(xy)
    t = solve_tour(D, method="classic", coords=xy)
    assert t.cost == pytest.approx(696.7419929462561, rel=1e-12)
    assert t.order[:10] == (0, 7, 4, 21, 47, 78, 62, 37, 67, 25)
    A = D + np.random.default_rng(22).uniform(0, 10, size=(80, 80))
    path = solve_tour(A, method="classic", start=3)
    assert path.cost == pytest.approx(976.8574030728034, rel=1e-12)
    assert path.order[:10] == (3, 14, 36, 68, 74, 35, 8, 18, 72, 20)


@pytest.mark.parametrize("method", list(METHODS))
def test_same_input_same_order(method):
    # classic and default always; fast up to 20 nodes, where fast-tsp solves exactly (above
    # that it has no seed: a stored plan is what keeps a run's order).
    for n, start, end in ((12, None, None), (15, 0, 0), (19, 2, None), (18, 1, 5)):
        xy = random_points(n, 30 + n)
        D = distances(xy)
        a = solve_tour(D, method=method, coords=xy, start=start, end=end)
        b = solve_tour(D, method=method, coords=xy, start=start, end=end)
        assert a.order == b.order
    if method == "classic":
        xy = random_points(150, 7)
        assert solve_tour(distances(xy), method=method, coords=xy).order == \
            solve_tour(distances(xy), method=method, coords=xy).order


def test_default_closed_tour_is_listed_canonically():
    # A closed symmetric tour from node 0 runs towards the smaller of 0's two neighbours.
    xy = random_points(100, 15)
    t = solve_tour(distances(xy))
    assert t.order[0] == 0 and t.order[1] < t.order[-1]


def test_interchangeable_stops_are_visited_together():
    # Stops measured from one pose (identical rows of costs) follow each other, in index
    # order, and cost what the tour without the copies costs.
    xy = random_points(40, 16)
    copies = {40: 3, 41: 3, 42: 25, 43: 0}
    full = np.vstack([xy, xy[list(copies.values())]])
    t = solve_tour(distances(full), start=0, end=0)
    base = solve_tour(distances(xy), start=0, end=0)
    assert t.cost == pytest.approx(base.cost, rel=1e-9)
    pos = {v: k for k, v in enumerate(t.order)}
    assert pos[41] == pos[40] + 1 and pos[40] == pos[3] + 1 and pos[42] == pos[25] + 1
    assert pos[43] == 1  # the start's copy comes right after it


def test_time_budget_is_accepted():
    D = distances(random_points(300, 8))
    t = solve_tour(D, time_budget=0.3)
    assert sorted(t.order) == list(range(300))


def test_default_beats_classic_on_random_points():
    xy = random_points(200, 9)
    D = distances(xy)
    assert solve_tour(D).cost <= solve_tour(D, method="classic", coords=xy).cost


def test_classic_without_coordinates_uses_cheapest_insertion():
    xy = random_points(60, 11)
    D = distances(xy)
    with_hull = solve_tour(D, method="classic", coords=xy)
    without = solve_tour(D, method="classic")
    assert sorted(without.order) == list(range(60))
    assert without.cost <= 1.2 * with_hull.cost


def test_three_dimensional_coordinates_are_projected():
    rng = np.random.default_rng(12)
    xyz = np.c_[rng.uniform(0, 100, size=(50, 2)), np.zeros(50)] @ np.linalg.qr(rng.normal(size=(3, 3)))[0]
    t = solve_tour(distances(xyz), method="classic", coords=xyz)
    assert sorted(t.order) == list(range(50))


def test_bad_arguments():
    D = np.ones((4, 4))
    with pytest.raises(ValueError, match="unknown method"):
        solve_tour(D, method="magic")
    with pytest.raises(ValueError, match="square"):
        solve_tour(np.ones((3, 4)))
    with pytest.raises(ValueError, match="finite"):
        solve_tour(np.full((3, 3), np.inf))
    with pytest.raises(ValueError, match="start"):
        solve_tour(D, start=4)
    with pytest.raises(ValueError, match="coords"):
        solve_tour(D, coords=np.zeros((3, 2)))


@needs_tsplib
@pytest.mark.parametrize("method, max_gap", [("classic", 0.05), ("default", 0.004), ("fast", 0.003)])
@pytest.mark.parametrize("name", list(OPTIMA))
def test_tsplib_within_stated_gap(method, max_gap, name):
    p = read_tsplib(TSPLIB / f"{name}.tsp")
    t = solve_tour(p.matrix(), method=method, coords=p.coords)
    assert sorted(t.order) == list(range(p.dimension))
    assert t.cost <= OPTIMA[name] * (1 + max_gap)


@needs_tsplib
def test_cli_prints_tour_and_length():
    result = CliRunner().invoke(sequence, ["tsp", str(BERLIN)])
    assert result.exit_code == 0, result.output
    lines = dict(line.split(": ", 1) for line in result.output.splitlines()[1:])
    ids = [int(v) for v in lines["tour"].split()]
    assert sorted(ids) == list(range(1, 53))
    D = read_tsplib(BERLIN).matrix()
    assert int(lines["length"]) == round(tour_cost(D, [i - 1 for i in ids])) == BERLIN_OPTIMUM


@needs_tsplib
def test_cli_json():
    result = CliRunner().invoke(sequence, ["tsp", str(BERLIN), "--method", "classic", "--json"])
    assert result.exit_code == 0, result.output
    out = json.loads(result.output)
    assert out["method"] == "classic" and out["dimension"] == 52
    assert sorted(out["tour"]) == list(range(1, 53)) and out["length"] >= BERLIN_OPTIMUM


def test_cli_bad_file_exits_2_with_location(tmp_path):
    bad = tmp_path / "bad.tsp"
    bad.write_text("NAME: x\nTYPE: TSP\nDIMENSION: 3\nEDGE_WEIGHT_TYPE: GEO\nNODE_COORD_SECTION\n")
    result = CliRunner().invoke(sequence, ["tsp", str(bad)])
    assert result.exit_code == 2
    assert f"{bad}:4: unsupported EDGE_WEIGHT_TYPE GEO" in result.output
