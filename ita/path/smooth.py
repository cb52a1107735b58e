"""Shortcutting, corner blending and the velocity profile of a joint path.

* `shortcut`: replaces runs of waypoints by straight joint segments where those are free
  (greedy, farthest first), then pulls each remaining corner toward its neighbours'
  midpoint as far as stays free.  Only free segments are ever accepted, so shortcutting
  never introduces a collision.
* `time_parameterize`: linear segments with parabolic blends (LSPB).  Each segment is
  crossed at the highest constant joint velocity the slowest joint allows (synchronised:
  every joint's speed is |dq_j| / T_i <= its limit); at each via point the velocity changes
  linearly from one segment's to the next's in a blend of duration max_j |dv_j| / a_j, so
  every joint stays within its acceleration limit; a segment too short for its two half
  blends is slowed until they fit.  Start and end, and every via marked as a stop, are
  passed at rest.  A blend cuts its corner: with `config_free` given, every blend's
  positions are checked and a via whose blend would collide becomes a stop ("blend where
  safe").  Consecutive commands given together (the Executive's lookahead queue) are
  blended through their intermediate goals the same way.
* `Trajectory`: knots (times, q) at a fixed period, as the controller interpolates;
  `limit_violations` measures speeds and accelerations numerically from the knots.

The TCP speed limit is not applied here (joint limits only).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from itertools import pairwise

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ita.kinematics import ArmModel, move_time

FloatArray = NDArray[np.float64]
SegmentsFree = Callable[[FloatArray, FloatArray], NDArray[np.bool_]]
ConfigFree = Callable[[FloatArray], NDArray[np.bool_]]
KNOT_PERIOD = 0.01   # s
_MIN_STEP = 1e-9     # rad: waypoints closer than this on every joint are merged


@dataclass(frozen=True, eq=False)
class Trajectory:
    """Joint configurations q (m, 6) rad at times (m,) s from 0; linear between knots.

    vias: (k,) the times at which the path's waypoints (or their blends' centres) are
    passed; stops: (k,) whether the arm is at rest there."""

    times: FloatArray
    q: FloatArray
    vias: FloatArray
    stops: NDArray[np.bool_]

    @property
    def duration(self) -> float:
        """Total time (s)."""
        return float(self.times[-1])

    def sample(self, t: ArrayLike) -> FloatArray:
        """Configurations (k, 6) at times t (k,), clamped to [0, duration]."""
        tt = np.clip(np.atleast_1d(np.asarray(t, dtype=float)), 0.0, self.duration)
        return np.stack([np.interp(tt, self.times, self.q[:, j]) for j in range(self.q.shape[1])], axis=-1)


def dedupe(waypoints: ArrayLike, keep: ArrayLike | None = None) -> tuple[FloatArray, NDArray[np.bool_]]:
    """Waypoints (k, 6) without consecutive repeats, and `keep` flags (k,) carried along
    (a merged waypoint keeps a flag if either had it)."""
    w = np.asarray(waypoints, dtype=float)
    flags = np.zeros(len(w), dtype=bool) if keep is None else np.asarray(keep, dtype=bool).copy()
    out, fl = [w[0]], [flags[0]]
    for q, f in zip(w[1:], flags[1:]):
        if np.all(np.abs(q - out[-1]) <= _MIN_STEP):
            fl[-1] = fl[-1] or f
        else:
            out.append(q)
            fl.append(f)
    return np.vstack(out), np.array(fl)


def shortcut(model: ArmModel, waypoints: ArrayLike, segments_free: SegmentsFree, rounds: int = 2,
             rng: np.random.Generator | None = None, refine_rounds: int = 0, spread: float = 0.15) -> FloatArray:
    """A joint path (m, 6), m <= k, with the same ends as `waypoints` (k, 6), no slower by
    the sum of its segments' move times, every segment of which `segments_free` accepts
    (given a path whose segments it accepts).

    With rng and refine_rounds, each remaining corner is then moved by random steps
    (spread rad, halving each round) where that makes its two segments quicker and free."""
    w, _ = dedupe(waypoints)
    if len(w) <= 2:
        return w
    out, i = [w[0]], 0
    while i < len(w) - 1:
        js = np.arange(len(w) - 1, i + 1, -1)
        ok = segments_free(np.broadcast_to(w[i], (len(js), w.shape[1])), w[js]) if len(js) else np.zeros(0, bool)
        j = int(js[np.argmax(ok)]) if ok.any() else i + 1
        out.append(w[j])
        i = j
    w = np.vstack(out)
    alphas = np.array([1.0, 0.75, 0.5, 0.25])
    for _ in range(rounds):
        moved = False
        for m in range(1, len(w) - 1):
            target = (w[m - 1] + w[m + 1]) / 2.0
            c = w[m] + alphas[:, None] * (target - w[m])
            n = len(c)
            ok = segments_free(np.vstack([np.broadcast_to(w[m - 1], c.shape), c]),
                               np.vstack([c, np.broadcast_to(w[m + 1], c.shape)]))
            good = np.flatnonzero(ok[:n] & ok[n:])
            if len(good):
                k = good[0]
                old = move_time(model, w[m - 1], w[m]) + move_time(model, w[m], w[m + 1])
                new = move_time(model, w[m - 1], c[k]) + move_time(model, c[k], w[m + 1])
                if new < old - 1e-9:
                    w[m] = c[k]
                    moved = True
        if not moved:
            break
    if rng is not None:
        w = _refine(model, w, segments_free, rng, refine_rounds, spread)
    return w


def _refine(model: ArmModel, w: FloatArray, segments_free: SegmentsFree, rng: np.random.Generator,
            rounds: int, spread: float, batch: int = 8) -> FloatArray:
    """Random local descent of each interior waypoint on its two segments' move time."""
    for r in range(rounds):
        step = spread * 0.5**r
        for m in range(1, len(w) - 1):
            c = np.clip(w[m] + rng.normal(size=(batch, w.shape[1])) * step, model.lower, model.upper)
            old = move_time(model, w[m - 1], w[m]) + move_time(model, w[m], w[m + 1])
            new = move_time(model, w[m - 1], c) + move_time(model, c, w[m + 1])
            better = np.flatnonzero(new < old - 1e-6)
            if len(better) == 0:
                continue
            c, new = c[better], new[better]
            order = np.argsort(new)
            c = c[order]
            n = len(c)
            ok = segments_free(np.vstack([np.broadcast_to(w[m - 1], c.shape), c]),
                               np.vstack([c, np.broadcast_to(w[m + 1], c.shape)]))
            good = np.flatnonzero(ok[:n] & ok[n:])
            if len(good):
                w[m] = c[good[0]]
    return w


@dataclass(frozen=True, eq=False)
class Lspb:
    """A blended piece: waypoints w (n+1, 6), segment times T (n,), velocities v (n, 6),
    blend durations tb (n+1,), via times tv (n+1,) (rest at both ends)."""

    w: FloatArray
    T: FloatArray
    v: FloatArray
    tb: FloatArray
    tv: FloatArray

    @property
    def duration(self) -> float:
        """Seconds from rest to rest."""
        return float(self.tv[-1] + self.tb[-1] / 2.0)

    def positions(self, t: ArrayLike) -> FloatArray:
        """Exact configurations (k, 6) at times t (k,) in [0, duration]."""
        t = np.clip(np.asarray(t, dtype=float), 0.0, self.duration)
        n = len(self.T)
        vpad = np.vstack([np.zeros((1, self.w.shape[1])), self.v, np.zeros((1, self.w.shape[1]))])
        # the via at or before t, and the next: t lies in one's blend or on the segment between
        i = np.clip(np.searchsorted(self.tv, t, side="right") - 1, 0, n)
        nxt = np.minimum(i + 1, n)
        eps = 1e-9 * (1.0 + self.duration)
        via = np.where(np.abs(t - self.tv[nxt]) <= self.tb[nxt] / 2.0 + eps, nxt, i)
        dt = t - self.tv[via]
        in_blend = ((np.abs(dt) <= self.tb[via] / 2.0 + eps) | ((via == n) & (dt > 0))
                    | ((via == 0) & (dt < 0)))
        before, after = vpad[via], vpad[via + 1]                          # v_{via-1}, v_via
        tb = np.where(self.tb[via] > 0, self.tb[via], 1.0)
        blend = (self.w[via] + before * dt[:, None]
                 + (after - before) * ((dt + self.tb[via] / 2.0) ** 2 / (2.0 * tb))[:, None])
        seg = np.clip(np.where(dt >= 0, via, via - 1), 0, n - 1)
        linear = self.w[seg] + self.v[seg] * (t - self.tv[seg])[:, None]
        return np.where(in_blend[:, None], blend, linear)


def lspb(model: ArmModel, waypoints: ArrayLike, max_iter: int = 300) -> Lspb | None:
    """Linear segments with parabolic blends through waypoints (n+1, 6), rest at both ends
    (see the module doc), or None if slowing short segments did not settle in max_iter
    rounds (never for one segment).  Never exceeds a joint's velocity or acceleration limit."""
    w = np.asarray(waypoints, dtype=float)
    vel, acc = np.asarray(model.velocity), np.asarray(model.acceleration)
    d = np.diff(w, axis=0)
    T = np.maximum((np.abs(d) / vel).max(axis=1), 1e-6)
    for _ in range(max_iter):
        v = d / T[:, None]
        vpad = np.vstack([np.zeros((1, w.shape[1])), v, np.zeros((1, w.shape[1]))])
        tb = (np.abs(np.diff(vpad, axis=0)) / acc).max(axis=1)
        need = tb[:-1] / 2.0 + tb[1:] / 2.0
        short = need > T * (1.0 + 1e-12)
        if not short.any():
            tv = tb[0] / 2.0 + np.concatenate([[0.0], np.cumsum(T)])
            return Lspb(w, T, v, tb, tv)
        T = np.where(short, T * np.maximum(np.sqrt(need / T), 1.0005), T)
    return None


def time_parameterize(model: ArmModel, waypoints: ArrayLike, stops: ArrayLike | None = None,
                      config_free: ConfigFree | None = None, lever: FloatArray | None = None,
                      resolution: float = 0.02, period: float = KNOT_PERIOD) -> Trajectory:
    """A trajectory through joint waypoints (k, 6), at rest at both ends and at every via
    flagged in `stops` (k,); blended elsewhere, unless config_free finds a blend unsafe.

    lever (6,) and resolution (m) set how densely blends are checked (see `lift`)."""
    w, stop = dedupe(waypoints, stops)
    stop[0] = stop[-1] = True
    lever = np.ones(model.dof) if lever is None else np.asarray(lever, dtype=float)
    while True:
        pieces = _pieces(model, w, stop)
        if config_free is None:
            break
        unsafe = _unsafe_blends(pieces, config_free, lever, resolution)
        if not unsafe:
            break
        stop[unsafe] = True
    return _knots(pieces, w, stop, period)


def _pieces(model: ArmModel, w: FloatArray, stop: NDArray[np.bool_]) -> list[tuple[int, Lspb]]:
    """(first waypoint index, Lspb) of each rest-to-rest piece between stops; a piece
    whose blends do not settle is split at every via (stop is updated)."""
    out: list[tuple[int, Lspb]] = []
    idx = np.flatnonzero(stop)
    for a, b in pairwise(idx):
        p = lspb(model, w[a:b + 1])
        if p is None:
            stop[a:b + 1] = True
            out.extend((k, lspb(model, w[k:k + 2])) for k in range(a, b))   # type: ignore[misc]
        else:
            out.append((int(a), p))
    return out


def _unsafe_blends(pieces: list[tuple[int, Lspb]], config_free: ConfigFree, lever: FloatArray,
                   resolution: float) -> list[int]:
    """Waypoint indices of interior vias whose blend positions are not all free."""
    bad, where, samples = [], [], []
    for first, p in pieces:
        for k in range(1, len(p.T)):
            # sample the blend at the check resolution of its sweep
            sweep = np.linalg.norm((np.abs(p.v[k]) + np.abs(p.v[k - 1])) * lever) * p.tb[k] / 2.0
            n = int(np.clip(np.ceil(sweep / resolution), 2, 200)) + 1
            t = p.tv[k] + np.linspace(-p.tb[k] / 2.0, p.tb[k] / 2.0, n)
            samples.append(p.positions(t))
            where.append(np.full(n, first + k))
    if samples:
        ok = config_free(np.vstack(samples))
        bad = sorted(set(np.concatenate(where)[~ok].tolist()))
    return bad


def _knots(pieces: list[tuple[int, Lspb]], w: FloatArray, stop: NDArray[np.bool_], period: float) -> Trajectory:
    """Knots at (about) `period` through every piece, joined at their rests."""
    times, qs, vias = [np.zeros(1)], [w[:1]], [np.zeros(1)]
    offset = 0.0
    for _, p in pieces:
        n = max(2, int(np.ceil(p.duration / period)))
        t = np.linspace(0.0, p.duration, n + 1)[1:]
        times.append(offset + t)
        qs.append(p.positions(t))
        vias.append(offset + np.concatenate([p.tv[1:-1], [p.duration]]))
        offset += p.duration
    return Trajectory(np.concatenate(times), np.vstack(qs), np.concatenate(vias), stop.copy())


def limit_violations(model: ArmModel, traj: Trajectory, tol: float = 1e-6) -> dict[str, float]:
    """Largest ratios of speed and acceleration to their limits over all joints, measured
    by finite differences of the knots: {'velocity': r_v, 'acceleration': r_a} (<= 1 + tol
    means within the limits)."""
    t, q = traj.times, traj.q
    if len(t) < 3:
        return {"velocity": 0.0, "acceleration": 0.0}
    dt = np.diff(t)
    v = np.diff(q, axis=0) / dt[:, None]
    a = np.diff(v, axis=0) / ((dt[:-1] + dt[1:]) / 2.0)[:, None]
    return {"velocity": float((np.abs(v) / model.velocity).max()),
            "acceleration": float((np.abs(a) / model.acceleration).max())}


def trajectory_free(traj: Trajectory, segments_free: SegmentsFree) -> bool:
    """Whether the straight pieces between all knots of a trajectory are free (the
    controller interpolates linearly between knots); segments_free as in `shortcut`."""
    if len(traj.q) < 2:
        return True
    return bool(segments_free(traj.q[:-1], traj.q[1:]).all())
