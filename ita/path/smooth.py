"""Shortcutting, corner blending and the velocity profile of a joint path.

* `shortcut`: replaces runs of waypoints by straight joint segments where those are free
  (greedy, farthest first), then pulls each remaining corner toward its neighbours'
  midpoint as far as stays free.  Only free segments are ever accepted, so shortcutting
  never introduces a collision.
* `reshape_path`: cuts every segment into pieces and moves the pieces' ends by random
  descent on the estimated duration (a speed that varies along the path, a shorter
  tool-point path where the TCP speed limit binds); kept only where every new segment
  is free.
* `estimate_durations`: what `time_parameterize` would give paths without stops, in
  batch and without collision checks (the objective of both of the above; a short
  segment costs what it really takes from rest, so a tiny move is never "sped up" by a
  detour).
* `time_parameterize`: linear segments with parabolic blends (LSPB).  Each segment is
  crossed at the highest constant joint velocity the slowest joint and the tool point's
  speed limit allow (synchronised: every joint's speed is |dq_j| / T_i <= its limit, and
  T_i is at least the segment's longest tool-point stretch per unit of its parameter over
  `model.max_tool_speed`); at each via point the velocity changes linearly from one
  segment's to the next's in a blend of duration max_j |dv_j| / a_j, so every joint stays
  within its acceleration limit; a segment too short for its two half blends is slowed
  until they fit.  Start and end, and every via marked as a stop, are passed at rest.
  The knots (what the controller interpolates linearly) are then measured: a rest-to-rest
  piece whose tool point would still exceed the speed limit between two knots (a blend
  cutting a corner) is slowed uniformly until it does not.
  A blend cuts its corner: with `segments_free` given, the straight pieces between the
  knots of every blend are checked (the rest lie on the path's own, checked segments) and
  a via whose blend is not free becomes a stop ("blend where safe").  Consecutive
  commands given together (the Executive's lookahead queue) are blended through their
  intermediate goals the same way.
* The result is a `TimedTrajectory` (knots at a fixed period, vias, stops);
  `limit_violations` measures joint speeds and accelerations and the tool point's speed
  numerically from the knots.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from itertools import pairwise

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ita.kinematics import ArmModel, move_time, tcp_poses
from ita.path.trajectory import TimedTrajectory

FloatArray = NDArray[np.float64]
SegmentsFree = Callable[[FloatArray, FloatArray], NDArray[np.bool_]]
KNOT_PERIOD = 0.01   # s
_MIN_STEP = 1e-9     # rad: waypoints closer than this on every joint are merged


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


def cruise_times(model: ArmModel, a: ArrayLike, b: ArrayLike, tcp: ArrayLike | None = None,
                 tool_speed: float | None = None, samples: int = 8) -> FloatArray:
    """(...) s: the least time to cross each joint segment a -> b ((..., 6)) at constant
    joint velocity: the slowest joint's |dq| / v, or the tool point's longest stretch per
    unit of parameter over the speed limit, whichever is longer (what `lspb` starts from)."""
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    shape = np.broadcast_shapes(a.shape, b.shape)
    a, b = np.broadcast_to(a, shape).reshape(-1, shape[-1]), np.broadcast_to(b, shape).reshape(-1, shape[-1])
    joint = (np.abs(b - a) / model.velocity).max(axis=1)
    vmax = model.max_tool_speed if tool_speed is None else float(tool_speed)
    if np.isfinite(vmax) and len(a):
        s = np.linspace(0.0, 1.0, samples + 1)
        q = a[:, None, :] + s[None, :, None] * (b - a)[:, None, :]
        p = tcp_poses(model, q.reshape(-1, shape[-1]), np.eye(4) if tcp is None else tcp)[:, :3, 3]
        p = p.reshape(len(a), samples + 1, 3)
        joint = np.maximum(joint, np.linalg.norm(np.diff(p, axis=1), axis=2).max(axis=1) * samples / vmax)
    return joint.reshape(shape[:-1])


def estimate_durations(model: ArmModel, paths: ArrayLike, tcp: ArrayLike | None = None,
                       tool_speed: float | None = None, settle: int = 8) -> FloatArray:
    """(B,) s: the blended duration `time_parameterize` gives joint paths (B, k, 6) with no
    stops, estimated without its collision checks: each segment's cruise time
    (`cruise_times`), slowed as `lspb` slows a segment too short for its two half blends
    (at most `settle` rounds of its update, all paths at once), plus half of the start and
    end blends.  A segment too short to reach its cruise speed thus costs what it really
    takes (2 sqrt(|dq| / a) from rest to rest), not its cruise time plus full-speed blends."""
    w = np.asarray(paths, dtype=float)
    if w.ndim == 2:
        w = w[None]
    if w.shape[1] < 2:
        return np.zeros(len(w))
    T = np.maximum(cruise_times(model, w[:, :-1], w[:, 1:], tcp, tool_speed), 1e-6)   # (B, n)
    d = np.diff(w, axis=1)
    for _ in range(settle + 1):
        tb, need = _blends(model, d, T)
        short = need > T * (1.0 + 1e-12)
        if not short.any():
            break
        T = np.where(short, T * np.maximum(np.sqrt(need / T), 1.0005), T)
    return np.maximum(T, need).sum(axis=1) + (tb[:, 0] + tb[:, -1]) / 2.0


def _blends(model: ArmModel, d: FloatArray, T: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Blend durations (B, n+1) at the vias of paths with segment steps d (B, n, 6) crossed
    in times T (B, n) from rest to rest, and the time (B, n) each segment's half blends need."""
    v = d / T[..., None]
    zero = np.zeros_like(v[:, :1])
    tb = (np.abs(np.diff(np.concatenate([zero, v, zero], axis=1), axis=1)) / model.acceleration).max(axis=2)
    return tb, (tb[:, :-1] + tb[:, 1:]) / 2.0


def shortcut(model: ArmModel, waypoints: ArrayLike, segments_free: SegmentsFree, rounds: int = 2,
             rng: np.random.Generator | None = None, refine_rounds: int = 0, spread: float = 0.15,
             tcp: ArrayLike | None = None) -> FloatArray:
    """A joint path (m, 6), m <= k, with the same ends as `waypoints` (k, 6), every segment
    of which `segments_free` accepts (given a path whose segments it accepts).  Corners
    move only where that shortens the estimated blended duration (`estimate_durations`,
    the tool point tcp (4, 4) within the TCP speed limit).

    With rng and refine_rounds, each remaining corner is then moved by random steps
    (spread rad, halving each round) where that makes the path quicker and stays free."""
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
                if _local_cost(model, w, m, c[k:k + 1], tcp)[0] < _local_cost(model, w, m, w[m][None], tcp)[0] - 1e-9:
                    w[m] = c[k]
                    moved = True
        if not moved:
            break
    if rng is not None:
        w = _refine(model, w, segments_free, rng, refine_rounds, spread, tcp)
    return w


def _local_cost(model: ArmModel, w: FloatArray, m: int, c: FloatArray, tcp: ArrayLike | None) -> FloatArray:
    """(B,) s: estimated duration of the path w (k, 6) with waypoint m replaced by each of c (B, 6)."""
    paths = np.repeat(w[None], len(c), axis=0)
    paths[:, m] = c
    return estimate_durations(model, paths, tcp)


def _refine(model: ArmModel, w: FloatArray, segments_free: SegmentsFree, rng: np.random.Generator,
            rounds: int, spread: float, tcp: ArrayLike | None = None, batch: int = 8) -> FloatArray:
    """Random local descent of each interior waypoint on the estimated duration."""
    for r in range(rounds):
        step = spread * 0.5**r
        for m in range(1, len(w) - 1):
            c = np.clip(w[m] + rng.normal(size=(batch, w.shape[1])) * step, model.lower, model.upper)
            old = _local_cost(model, w, m, w[m][None], tcp)[0]
            new = _local_cost(model, w, m, c, tcp)
            better = np.flatnonzero(new < old - 1e-6)
            if len(better) == 0:
                continue
            c = c[better][np.argsort(new[better])]
            for k in range(0, len(c), 2):          # quickest first: the first free one wins
                part = c[k:k + 2]
                n = len(part)
                ok = segments_free(np.vstack([np.broadcast_to(w[m - 1], part.shape), part]),
                                   np.vstack([part, np.broadcast_to(w[m + 1], part.shape)]))
                good = np.flatnonzero(ok[:n] & ok[n:])
                if len(good):
                    w[m] = part[good[0]]
                    break
    return w


def subdivide(waypoints: ArrayLike, k: int) -> FloatArray:
    """The joint path (k(n-1)+1, 6) with each segment of waypoints (n, 6) cut into k equal pieces."""
    w = np.asarray(waypoints, dtype=float)
    s = np.arange(1, k + 1) / k
    inner = (w[:-1, None, :] + s[None, :, None] * (w[1:] - w[:-1])[:, None, :]).reshape(-1, w.shape[1])
    return np.vstack([w[:1], inner])


def reshape_path(model: ArmModel, waypoints: ArrayLike, segments_free: SegmentsFree, rng: np.random.Generator,
                 rounds: int = 6, spread: float = 0.15, tcp: ArrayLike | None = None, splits: int = 2,
                 batch: int = 8) -> FloatArray:
    """A quicker joint path with the same ends: every segment of `waypoints` (whose segments
    `segments_free` accepts) cut into `splits` pieces, then each interior waypoint moved by
    random descent on the estimated duration (`estimate_durations`; a varying speed along
    the path and a shorter tool-point path where the TCP speed limit binds).  The descent
    first runs unchecked and the result is kept only if every segment is free; otherwise
    the checked descent (`_refine`) runs from the cut path.  Returns `waypoints` (k, 6)
    unless the result ((k - 1) splits + 1, 6) is quicker by the estimate; every returned
    segment is accepted by `segments_free`.  The estimate leaves out the tool point's speed
    between knots and the blends found unsafe, so a caller that times both keeps the quicker.

    A path already as quick by the estimate as the least time any path between its ends
    can take (`move_time`: each joint from rest to rest at its own limits; most short
    moves) is returned at once."""
    w0 = np.asarray(waypoints, dtype=float)
    base = estimate_durations(model, w0, tcp)[0]
    if base <= float(move_time(model, w0[0], w0[-1])) * (1.0 + 1e-6):
        return w0
    cut = subdivide(w0, splits)
    w = cut.copy()
    for r in range(rounds):
        step = spread * 0.5**r
        for m in range(1, len(w) - 1):
            c = np.clip(w[m] + rng.normal(size=(batch, w.shape[1])) * step, model.lower, model.upper)
            c = np.vstack([w[m][None], c])
            w[m] = c[int(np.argmin(_local_cost(model, w, m, c, tcp)))]
    if not segments_free(w[:-1], w[1:]).all():
        half = (cut + w) / 2.0
        w = half if segments_free(half[:-1], half[1:]).all() else _refine(model, cut, segments_free, rng, rounds,
                                                                           spread, tcp)
    return w if estimate_durations(model, w, tcp)[0] < base - 1e-9 else w0


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
        tc: FloatArray = np.clip(np.asarray(t, dtype=float), 0.0, self.duration)
        n = len(self.T)
        vpad = np.vstack([np.zeros((1, self.w.shape[1])), self.v, np.zeros((1, self.w.shape[1]))])
        # the via at or before t, and the next: t lies in one's blend or on the segment between
        i = np.clip(np.searchsorted(self.tv, tc, side="right") - 1, 0, n)
        nxt = np.minimum(i + 1, n)
        eps = 1e-9 * (1.0 + self.duration)
        via = np.where(np.abs(tc - self.tv[nxt]) <= self.tb[nxt] / 2.0 + eps, nxt, i)
        dt = tc - self.tv[via]
        in_blend = ((np.abs(dt) <= self.tb[via] / 2.0 + eps) | ((via == n) & (dt > 0))
                    | ((via == 0) & (dt < 0)))
        before, after = vpad[via], vpad[via + 1]                          # v_{via-1}, v_via
        tb = np.where(self.tb[via] > 0, self.tb[via], 1.0)
        blend = (self.w[via] + before * dt[:, None]
                 + (after - before) * ((dt + self.tb[via] / 2.0) ** 2 / (2.0 * tb))[:, None])
        seg = np.clip(np.where(dt >= 0, via, via - 1), 0, n - 1)
        linear = self.w[seg] + self.v[seg] * (tc - self.tv[seg])[:, None]
        return np.where(in_blend[:, None], blend, linear)


def lspb(model: ArmModel, waypoints: ArrayLike, max_iter: int = 300, t_min: ArrayLike | None = None) -> Lspb | None:
    """Linear segments with parabolic blends through waypoints (n+1, 6), rest at both ends
    (see the module doc), or None if slowing short segments did not settle in max_iter
    rounds (never for one segment).  Never exceeds a joint's velocity or acceleration limit.
    t_min (n,): least crossing time of each segment (s), e.g. from the tool speed limit."""
    w = np.asarray(waypoints, dtype=float)
    vel, acc = np.asarray(model.velocity), np.asarray(model.acceleration)
    d = np.diff(w, axis=0)
    T = np.maximum((np.abs(d) / vel).max(axis=1), 1e-6)
    if t_min is not None:
        T = np.maximum(T, np.asarray(t_min, dtype=float))
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
                      segments_free: SegmentsFree | None = None, tcp: ArrayLike | None = None,
                      tool_speed: float | None = None, period: float = KNOT_PERIOD) -> TimedTrajectory:
    """A trajectory through joint waypoints (k, 6), at rest at both ends and at every via
    flagged in `stops` (k,); blended elsewhere, unless segments_free finds a blend unsafe.

    tcp (4, 4): the tool point in the flange frame (default the flange); tool_speed: its
    speed limit (m/s, default model.max_tool_speed; inf: none)."""
    w, stop = dedupe(waypoints, stops)
    stop[0] = stop[-1] = True
    tcp = np.eye(4) if tcp is None else np.asarray(tcp, dtype=float)
    vmax = model.max_tool_speed if tool_speed is None else float(tool_speed)
    t_min = cruise_times(model, w[:-1], w[1:], tcp, vmax, samples=16)
    while True:
        pieces = _pieces(model, w, stop, t_min)
        traj, label, near = _knots(model, pieces, w, stop, period, tcp, vmax)
        if segments_free is None:
            return traj
        unsafe = _unsafe_blends(traj, label, near, stop, segments_free)
        if not unsafe:
            return traj
        stop[unsafe] = True


def _one_segment(model: ArmModel, w: FloatArray, t_min: FloatArray) -> Lspb:
    """The Lspb of one segment (w (2, 6)), which always settles."""
    p = lspb(model, w, t_min=t_min)
    assert p is not None, "lspb of one segment always settles"
    return p


def _pieces(model: ArmModel, w: FloatArray, stop: NDArray[np.bool_], t_min: FloatArray) -> list[tuple[int, Lspb]]:
    """(first waypoint index, Lspb) of each rest-to-rest piece between stops; a piece
    whose blends do not settle is split at every via (stop is updated)."""
    out: list[tuple[int, Lspb]] = []
    idx = np.flatnonzero(stop)
    for a, b in pairwise(idx):
        p = lspb(model, w[a:b + 1], t_min=t_min[a:b])
        if p is None:
            stop[a:b + 1] = True
            out.extend((k, _one_segment(model, w[k:k + 2], t_min[k:k + 1])) for k in range(a, b))
        else:
            out.append((int(a), p))
    return out


def _knots(model: ArmModel, pieces: list[tuple[int, Lspb]], w: FloatArray, stop: NDArray[np.bool_],
           period: float, tcp: FloatArray, vmax: float) -> tuple[TimedTrajectory, NDArray[np.int64], NDArray[np.int64]]:
    """Knots at (about) `period` through every piece, joined at their rests; each piece
    slowed uniformly where its tool point would exceed vmax between knots.  Also, per knot:
    label, the path segment whose line it lies on (-1 inside an interior blend), and near,
    the interior via whose blend is nearest in time (-1 for none)."""
    times, qs, vias = [np.zeros(1)], [w[:1]], [np.zeros(1)]
    labels, nears = [np.zeros(1, dtype=np.int64)], [np.full(1, -1, dtype=np.int64)]
    offset = 0.0
    for first, p in pieces:
        n = max(2, int(np.ceil(p.duration / period)))
        t = np.linspace(0.0, p.duration, n + 1)
        q = p.positions(t)
        stretch = 1.0
        if np.isfinite(vmax):
            pts = tcp_poses(model, q, tcp)[:, :3, 3]
            speed = np.linalg.norm(np.diff(pts, axis=0), axis=1) / np.diff(t)
            stretch = max(1.0, float(speed.max()) / vmax * (1.0 + 1e-9))
        seg = np.clip(np.searchsorted(p.tv, t, side="right") - 1, 0, len(p.T) - 1)
        label = first + seg
        near = np.full(len(t), -1, dtype=np.int64)
        if len(p.T) > 1:
            inner = np.arange(1, len(p.T))
            gap = np.abs(t[:, None] - p.tv[inner][None, :]) - p.tb[inner][None, :] / 2.0
            k = np.argmin(gap, axis=1)
            near = first + inner[k]
            label = np.where(gap[np.arange(len(t)), k] <= 1e-12, -1, label)
        times.append(offset + stretch * t[1:])
        qs.append(q[1:])
        labels.append(label[1:])
        nears.append(near[1:])
        vias.append(offset + stretch * np.concatenate([p.tv[1:-1], [p.duration]]))
        offset += stretch * p.duration
    traj = TimedTrajectory(np.concatenate(times), np.vstack(qs), np.concatenate(vias), stop.copy())
    return traj, np.concatenate(labels), np.concatenate(nears)


def _unsafe_blends(traj: TimedTrajectory, label: NDArray[np.int64], near: NDArray[np.int64],
                   stop: NDArray[np.bool_], segments_free: SegmentsFree) -> list[int]:
    """Waypoint indices of interior vias whose blend's straight knot pieces are not all
    free.  A knot piece is checked unless both its knots lie on the same path segment."""
    if len(traj.q) < 2:
        return []
    pick = (label[:-1] < 0) | (label[1:] < 0) | (label[:-1] != label[1:])
    via = np.where(near[:-1] >= 0, near[:-1], near[1:])
    pick &= via >= 0
    pick[pick] &= ~stop[via[pick]]
    idx = np.flatnonzero(pick)
    if len(idx) == 0:
        return []
    ok = segments_free(traj.q[idx], traj.q[idx + 1])
    return sorted(set(via[idx[~ok]].tolist()))


def limit_violations(model: ArmModel, traj: TimedTrajectory, tcp: ArrayLike | None = None,
                     tool_speed: float | None = None) -> dict[str, float]:
    """Largest ratios of joint speed, joint acceleration and tool-point speed (tcp, default
    the flange) to their limits, measured by finite differences of the knots:
    {'velocity', 'acceleration', 'tool_speed'} (<= 1 + tol means within the limits)."""
    t, q = traj.times, traj.q
    vmax = model.max_tool_speed if tool_speed is None else float(tool_speed)
    if len(t) < 3:
        return {"velocity": 0.0, "acceleration": 0.0, "tool_speed": 0.0}
    dt = np.diff(t)
    v = np.diff(q, axis=0) / dt[:, None]
    a = np.diff(v, axis=0) / ((dt[:-1] + dt[1:]) / 2.0)[:, None]
    return {"velocity": float((np.abs(v) / model.velocity).max()),
            "acceleration": float((np.abs(a) / model.acceleration).max()),
            "tool_speed": float(traj.tool_speeds(model, tcp).max() / vmax)}


def trajectory_free(traj: TimedTrajectory, segments_free: SegmentsFree) -> bool:
    """Whether the straight pieces between all knots of a trajectory are free (the
    controller interpolates linearly between knots); segments_free as in `shortcut`."""
    if len(traj.q) < 2:
        return True
    return bool(segments_free(traj.q[:-1], traj.q[1:]).all())
