"""The network adjustment of hole centres over overlapping frames (ita.vision.network), on
synthetic rows of holes whose frame errors and as-built deviations are known."""

from __future__ import annotations

import math

import numpy as np

from ita.vision.network import Sighting, solve_network

POSE = 0.083        # mm, a frame's shift (1 sigma per axis)
FIT = 0.01          # mm, a rim fit's scatter per axis


def _row(n: int, rng: np.random.Generator, *, pitch: float = 58.0, turn: float = 1e-4, pose: float = POSE,
         fit: float = FIT, stated: float = FIT):
    """n holes on a line, frame i centred on hole i seeing holes i-1, i, i+1; returns
    (nominal, true deviations, true frame errors (tx, ty, turn), sightings)."""
    nominal = {f"H{i:02d}": (pitch * i, 0.0) for i in range(n)}
    dev = {h: tuple(rng.normal(0.0, 0.08, 2)) for h in nominal}
    frames = {f"F{i:02d}": (*rng.normal(0.0, pose, 2), rng.normal(0.0, turn)) for i in range(n)}
    sightings = []
    for i in range(n):
        f = f"F{i:02d}"
        tx, ty, th = frames[f]
        c = np.asarray(nominal[f"H{i:02d}"])
        for j in (i - 1, i, i + 1):
            if 0 <= j < n:
                h = f"H{j:02d}"
                nom = np.asarray(nominal[h])
                rel = nom - c
                true = nom + dev[h]
                m = true + (tx, ty) + th * np.array([-rel[1], rel[0]]) + rng.normal(0.0, fit, 2)
                sightings.append(Sighting(f, h, (float(m[0]), float(m[1])), stated))
    return nominal, dev, frames, sightings


def test_adjustment_recovers_known_frame_errors_and_hole_positions():
    rng = np.random.default_rng(3)
    nominal, dev, frames, sightings = _row(40, rng)
    sol = solve_network(sightings, nominal, pose_sigma=POSE)
    assert not sol.left_out
    shift_err = [math.dist(sol.frames[f][:2], frames[f][:2]) for f in frames]
    # each frame's error is recovered far better than the prior's 0.083 mm
    assert np.sqrt(np.mean(np.square(shift_err))) < 0.03
    normalized, within = [], 0
    for h, (dx, dy) in dev.items():
        est = sol.holes[h]
        e = np.subtract(est.deviation, (dx, dy))
        normalized.append(float(e @ np.linalg.solve(np.asarray(est.cov), e)))
        within += abs(e[0]) <= 2 * math.sqrt(est.cov[0][0])
    # the covariance is honest: chi-square of 2 per hole on average, and U = 2 sigma covers
    assert 1.0 < np.mean(normalized) < 3.0
    assert within >= 0.85 * len(dev)
    # and the positions are far better than the 0.083 mm of one frame's pose alone
    assert max(h.sigma_axis for h in sol.holes.values()) < 0.06


def test_a_frame_with_a_wrong_hole_match_is_left_out_not_averaged_in():
    rng = np.random.default_rng(5)
    nominal, dev, frames, sightings = _row(30, rng)
    # frame F10 took hole H11's rim for H10's neighbour: its sighting of H09 is H11's centre
    bad = [s if not (s.frame == "F10" and s.hole == "H09") else
           Sighting("F10", "H09", (s.xy[0] + 2 * 58.0, s.xy[1]), s.sigma) for s in sightings]
    sol = solve_network(bad, nominal, pose_sigma=POSE)
    assert list(sol.left_out) == ["F10"]
    assert "wrong hole match" in sol.left_out["F10"]
    for h in ("H09", "H10", "H11"):
        e = np.subtract(sol.holes[h].deviation, dev[h])
        assert np.all(np.abs(e) <= 2 * np.sqrt(np.diag(sol.holes[h].cov)) + 1e-9)
        assert "F10" not in sol.holes[h].frames
    # a smaller gross error (a mis-fitted rim, 0.4 mm) is caught as well
    off = [s if not (s.frame == "F20" and s.hole == "H21") else
           Sighting("F20", "H21", (s.xy[0], s.xy[1] + 0.4), s.sigma) for s in sightings]
    assert "F20" in solve_network(off, nominal, pose_sigma=POSE).left_out


def test_a_hole_seen_once_is_decided_from_its_frames_adjusted_pose():
    rng = np.random.default_rng(7)
    nominal, dev, frames, sightings = _row(20, rng)
    # a hole off the row, seen only in frame F05 (beside H05)
    nominal["X"] = (5 * 58.0, 30.0)
    dev["X"] = (0.12, -0.05)
    tx, ty, th = frames["F05"]
    rel = np.subtract(nominal["X"], nominal["H05"])
    m = np.add(nominal["X"], dev["X"]) + (tx, ty) + th * np.array([-rel[1], rel[0]])
    sightings.append(Sighting("F05", "X", (float(m[0]), float(m[1])), FIT))
    sol = solve_network(sightings, nominal, pose_sigma=POSE)
    est = sol.holes["X"]
    assert est.frames == ("F05",)
    # better than the frame's prior pose alone (0.083 mm): the other holes in the frame tie it
    assert est.sigma_axis < 0.06
    assert np.all(np.abs(np.subtract(est.deviation, dev["X"])) <= 3 * np.sqrt(np.diag(est.cov)))


def test_datum_holes_anchor_the_network():
    rng = np.random.default_rng(11)
    nominal, dev, frames, sightings = _row(12, rng)
    dev["H00"] = (0.0, 0.0)                     # a datum does not move: it defines the frame
    redo = []
    for s in sightings:
        if s.hole == "H00":
            tx, ty, th = frames[s.frame]
            rel = np.subtract(nominal["H00"], nominal[f"H{int(s.frame[1:]):02d}"])
            m = np.asarray(nominal["H00"]) + (tx, ty) + th * np.array([-rel[1], rel[0]])
            s = Sighting(s.frame, s.hole, (float(m[0]), float(m[1])), FIT)
        redo.append(s)
    free = solve_network(redo, nominal, pose_sigma=POSE)
    anchored = solve_network(redo, nominal, pose_sigma=POSE, fixed={"H00"})
    assert "H00" not in anchored.holes
    assert anchored.holes["H01"].sigma_axis < free.holes["H01"].sigma_axis


def test_variance_components_make_the_uncertainty_honest_when_the_sigmas_are_not():
    """Rim fits stated three times too large and a pose prior a fifth too small: the
    adjustment's variance components put both right, so U = 2 sigma covers about 95 %."""
    within, n, factors = 0, 0, []
    for seed in range(6):
        rng = np.random.default_rng(100 + seed)
        nominal, dev, frames, sightings = _row(60, rng, pose=1.2 * POSE, fit=FIT, stated=3 * FIT)
        sol = solve_network(sightings, nominal, pose_sigma=POSE)
        factors.append(sol.factors[""])
        for h, d in dev.items():
            e = np.subtract(sol.holes[h].deviation, d)
            within += int(np.sum(np.abs(e) <= 2 * np.sqrt(np.diag(sol.holes[h].cov))))
            n += 2
    assert 0.25 < np.mean(factors) < 0.45          # the sightings' sigmas were 3 times too large
    assert 0.92 <= within / n <= 0.98
