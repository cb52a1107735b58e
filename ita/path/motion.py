"""Validity of configurations and of motions: compiled end to end over the region tree.

`ConfigChecker` answers "is this configuration free?" (joint limits, every tube of the
arm and the held tool against the tree and against each other).  `MotionChecker`
answers "is this joint segment free at every position?", soundly, by conservative
advancement on exact clearances:

* a tube's axis points move no faster than W_k = sum_j |b_j - a_j| R'[j, k] per unit of
  the segment's parameter, where R'[j, k] bounds tube k's distance from joint j's axis
  along the segment: the smaller of the bound over all configurations (`sweep_bounds`)
  and (r_a + r_b + V) / 2, r_a and r_b the tube's actual lever arm at the segment's ends
  (forward kinematics) and V the most the joints past j can change it;
* two tubes of a self-collision pair move relative to each other no faster than the
  joints between their links move the outer one (the joints below move both alike; a
  tube met as its flat-ended cylinder reaches its radius farther from their axes);
* at a position s with clearances c_k (tube to the tree) and c_p (pair), the stretch
  s +- min(c_k / W_k, c_p / P_p) is free.  The segment's middle is checked first (a short
  segment is done in one step); the rest is covered by advancing from both ends toward
  it, each step as long as the clearance allows.  A few exact probes along a long
  segment go first, so a collision is usually found at once.

Every accepted segment is free at every position.  The ends themselves may be as close to
contact as they are (a start a few micrometres from the arm touching itself can move
away: its steps grow with the clearance); elsewhere a segment is refused where it passes
closer than `floor` to contact, and after `budget` clearance evaluations.
"""

from __future__ import annotations

import numpy as np
from numba import njit
from numpy.typing import ArrayLike, NDArray

from ita.collision import ArmChecker
from ita.collision.kernels import check_arm, pair_gap, tube_clearance
from ita.cores import SecondCore
from ita.kinematics import JOINT_LIMIT_TOL, ArmModel

FloatArray = NDArray[np.float64]


class ConfigChecker:
    """`config_free` for an ArmModel and its ArmChecker, compiled end to end.

    The same test as ``model.within_limits(q) & ~checker.collides(link_segments(model,
    q))`` (the checker's own compiled kernel over the tree's current arrays), with the
    forward kinematics compiled too, so that one configuration costs microseconds rather
    than the numpy overhead of a batch: what a sampling planner calling it per state needs.
    """

    def __init__(self, model: ArmModel, checker: ArmChecker) -> None:
        if len(checker.radii) != len(model.tube_radii):
            raise ValueError("the checker's tubes are not the model's")
        self.model, self.checker = model, checker
        self._fk = (np.ascontiguousarray(model.base), np.ascontiguousarray(model.origins),
                    np.ascontiguousarray(model.axes), np.ascontiguousarray(model.flange_offset),
                    np.ascontiguousarray(model.tube_links), np.ascontiguousarray(model.tube_ends))
        self._limits = (np.ascontiguousarray(model.lower), np.ascontiguousarray(model.upper))
        self._objects = -1
        self._ignore = np.zeros((0, 0), dtype=np.bool_)

    def ignore(self) -> NDArray[np.bool_]:
        """(t, objects) the mount objects that links 0 and 1 may touch (as ArmChecker)."""
        tree = self.checker.tree
        if tree.object_count != self._objects:
            ignore = np.zeros((len(self.checker.radii), tree.object_count), dtype=np.bool_)
            low = self.checker.tube_links <= 1
            for name in self.checker.mount:
                if name in tree.objects:
                    ignore[low, tree.object_id(name)] = True
            self._ignore, self._objects = ignore, tree.object_count
        return self._ignore

    def __call__(self, q: ArrayLike) -> NDArray[np.bool_]:
        """Bool (n,): configurations q (n, 6) (or (6,)) within the limits and collision-free."""
        q = _rows(q)
        c = self.checker
        return _configs_free(q, *self._limits, *self._fk, c.radii, c.cylinder, c.world, self.ignore(), c.pairs,
                             *c.tree.arrays())


def _rows(q: ArrayLike) -> FloatArray:
    """q as configurations (n, 6) in a C-ordered, writable float array (a read-only or
    strided one would make numba compile its kernels once more for that type)."""
    return np.require(np.atleast_2d(np.asarray(q, dtype=float)), requirements=("C", "W"))


@njit(cache=True)
def _link_segments(q, base, origins, axes, flange_offset, tube_links, tube_ends, frames, joint, out):
    """Compiled `fk.link_segments` of one configuration q (6,) into out (t, 2, 3);
    frames (dof + 2, 4, 4) and joint (4, 4) are scratch."""
    dof = q.shape[0]
    frames[0] = base
    for j in range(dof):
        kx, ky, kz = axes[j, 0], axes[j, 1], axes[j, 2]
        c, s = np.cos(q[j]), np.sin(q[j])
        v = 1.0 - c
        r00, r01, r02 = c + kx * kx * v, kx * ky * v - kz * s, kx * kz * v + ky * s
        r10, r11, r12 = ky * kx * v + kz * s, c + ky * ky * v, ky * kz * v - kx * s
        r20, r21, r22 = kz * kx * v - ky * s, kz * ky * v + kx * s, c + kz * kz * v
        o = origins[j]
        for r in range(3):
            joint[r, 0] = o[r, 0] * r00 + o[r, 1] * r10 + o[r, 2] * r20
            joint[r, 1] = o[r, 0] * r01 + o[r, 1] * r11 + o[r, 2] * r21
            joint[r, 2] = o[r, 0] * r02 + o[r, 1] * r12 + o[r, 2] * r22
            joint[r, 3] = o[r, 3]
        joint[3, 0], joint[3, 1], joint[3, 2], joint[3, 3] = 0.0, 0.0, 0.0, 1.0
        _mul(frames[j], joint, frames[j + 1])
    _mul(frames[dof], flange_offset, frames[dof + 1])
    for k in range(tube_links.shape[0]):
        f = frames[tube_links[k]]
        for e in range(2):
            for r in range(3):
                out[k, e, r] = (f[r, 0] * tube_ends[k, e, 0] + f[r, 1] * tube_ends[k, e, 1]
                                + f[r, 2] * tube_ends[k, e, 2] + f[r, 3])


@njit(cache=True)
def _mul(a, b, out):
    for r in range(4):
        for k in range(4):
            out[r, k] = a[r, 0] * b[0, k] + a[r, 1] * b[1, k] + a[r, 2] * b[2, k] + a[r, 3] * b[3, k]


@njit(cache=True)
def _configs_free(q, lower, upper, base, origins, axes, flange_offset, tube_links, tube_ends, radii, cyl, world,
                  ignore, pairs, kind, pos, rot, half, rad, bound, solid, obj, active, child_ptr, child_idx, roots):
    n, dof = q.shape
    inside = np.ones(n, dtype=np.bool_)
    segs = np.empty((n, tube_links.shape[0], 2, 3))
    frames = np.empty((dof + 2, 4, 4))
    joint = np.empty((4, 4))
    for i in range(n):
        for j in range(dof):
            if q[i, j] < lower[j] - JOINT_LIMIT_TOL or q[i, j] > upper[j] + JOINT_LIMIT_TOL:
                inside[i] = False
        _link_segments(q[i], base, origins, axes, flange_offset, tube_links, tube_ends, frames, joint, segs[i])
    hit, _ = check_arm(segs, radii, cyl, world, ignore, pairs, kind, pos, rot, half, rad, bound, solid, obj,
                       active, child_ptr, child_idx, roots)
    return inside & (hit == 0)


def sweep_bounds(model: ArmModel) -> FloatArray:
    """(dof, t) m/rad: R[j, k] bounds the distance of any point of tube k's axis from joint
    j's axis in every configuration, so no such point moves faster than R[j, k] per radian
    of joint j (0 for joints that do not move the tube's link).

    Exact for a tube on the joint's own child link (its largest distance from the axis);
    otherwise the next joint's (fixed) distance from the axis plus the chain's length from
    that joint's origin to the tube's farthest end."""
    dof = model.dof
    steps = [np.linalg.norm(model.origins[m][:3, 3]) for m in range(dof)]
    steps.append(np.linalg.norm(model.flange_offset[:3, 3]))       # frame dof -> flange
    out = np.zeros((dof, len(model.tube_links)))
    for k, link in enumerate(model.tube_links):
        ends = model.tube_ends[k]
        reach = float(np.linalg.norm(ends, axis=1).max())
        for j in range(min(int(link), dof)):
            axis = model.axes[j]
            if link == j + 1:
                perp = ends - np.outer(ends @ axis, axis)
                out[j, k] = float(np.linalg.norm(perp, axis=1).max())
            else:              # frame j+2's origin is rigid on link j+1; then the chain
                nxt = model.origins[j + 1][:3, 3] if j + 1 < dof else model.flange_offset[:3, 3]
                offset = float(np.linalg.norm(nxt - (nxt @ axis) * axis))
                out[j, k] = offset + float(sum(steps[m] for m in range(j + 2, int(link)))) + reach
    return out


@njit(cache=True)
def _configs_clear(q, margin, moving, lower, upper, base, origins, axes, flange_offset, tube_links, tube_ends, radii,
                   cyl, world,
                   ignore, pairs, kind, pos, rot, half, rad, bound, solid, obj, active, child_ptr, child_idx, roots):
    """Bool (n,): configurations q (n, dof) within the limits and free with every moving
    tube (moving (t,) 1.0, else 0.0) grown by margin."""
    n, dof = q.shape
    t = tube_links.shape[0]
    out = np.zeros(n, dtype=np.bool_)
    segs = np.empty((1, t, 2, 3))
    frames = np.empty((dof + 2, 4, 4))
    joint = np.empty((4, 4))
    grown = radii + margin * moving
    for i in range(n):
        inside = True
        for j in range(dof):
            if q[i, j] < lower[j] - JOINT_LIMIT_TOL or q[i, j] > upper[j] + JOINT_LIMIT_TOL:
                inside = False
        if not inside:
            continue
        _link_segments(q[i], base, origins, axes, flange_offset, tube_links, tube_ends, frames, joint, segs[0])
        hit, _ = check_arm(segs, grown, cyl, world, ignore, pairs, kind, pos, rot, half, rad, bound, solid, obj, active,
                           child_ptr, child_idx, roots)
        out[i] = hit[0] == 0
    return out




@njit(cache=True)
def _axis_distance(frame, axis, ends):
    """m: the farthest of a tube's ends (2, 3) from a joint's axis (through frame's
    origin along frame's rotation of axis)."""
    ux = frame[0, 0] * axis[0] + frame[0, 1] * axis[1] + frame[0, 2] * axis[2]
    uy = frame[1, 0] * axis[0] + frame[1, 1] * axis[1] + frame[1, 2] * axis[2]
    uz = frame[2, 0] * axis[0] + frame[2, 1] * axis[1] + frame[2, 2] * axis[2]
    out = 0.0
    for e in range(2):
        vx, vy, vz = ends[e, 0] - frame[0, 3], ends[e, 1] - frame[1, 3], ends[e, 2] - frame[2, 3]
        along = vx * ux + vy * uy + vz * uz
        out = max(out, np.sqrt(max(vx * vx + vy * vy + vz * vz - along * along, 0.0)))
    return out


@njit(cache=True)
def _speeds(a, b, bounds, tube_links, cyl, pairs, frames_a, frames_b, ends_a, ends_b, axes, lever, speed, pspeed):
    """Fill speed (t,) and pspeed (p,): the most tube k's axis points (and a pair's tubes
    relative to each other) move per unit of the segment a -> b's parameter; lever
    (dof, t): R' (see the module doc).  A pair's outer tube met as a cylinder (cyl > 0)
    has points up to its radius off its axis: as much farther from every joint's axis."""
    dof, t = bounds.shape
    for k in range(t):
        for j in range(dof - 1, -1, -1):
            if bounds[j, k] == 0.0:
                lever[j, k] = 0.0
                continue
            v = 0.0
            for m in range(j + 1, dof):
                v += abs(b[m] - a[m]) * lever[m, k]
            ra = _axis_distance(frames_a[j + 1], axes[j], ends_a[k])
            rb = _axis_distance(frames_b[j + 1], axes[j], ends_b[k])
            lever[j, k] = min(bounds[j, k], max(max(ra, rb), 0.5 * (ra + rb + v)))
        s = 0.0
        for j in range(dof):
            s += abs(b[j] - a[j]) * lever[j, k]
        speed[k] = s
    for p in range(pairs.shape[0]):
        i, j = pairs[p, 0], pairs[p, 1]
        outer = j if tube_links[j] >= tube_links[i] else i
        low = min(tube_links[i], tube_links[j])
        s = 0.0
        for m in range(low, dof):
            s += abs(b[m] - a[m]) * (lever[m, outer] + cyl[outer])
        pspeed[p] = s


@njit(cache=True)
def _clearance_step(segs, need, floor, speed, pspeed, radii, cyl, world, ignore, pairs, kind, pos, rot, half, rad, bound,
                    solid, obj, active, child_ptr, child_idx, roots, stack, a, d, bp):
    """(step, low) at one position (tubes segs (t, 2, 3)): the parameter distance proven
    free either side (capped at need), and the least clearance (m; <= 0: a collision)."""
    step, low = need, np.inf
    for k in range(segs.shape[0]):
        if not world[k]:
            continue
        cap = max(speed[k] * need, 2.0 * floor)
        c = tube_clearance(segs[k, 0], segs[k, 1], radii[k], cap, kind, pos, rot, half, rad, bound, solid, obj,
                            active, child_ptr, child_idx, roots, stack, a, d, bp, ignore[k])
        if c <= 0.0:
            return 0.0, c
        low = min(low, c)
        if speed[k] > 0.0:
            step = min(step, c / speed[k])
    for p in range(pairs.shape[0]):
        i, j = pairs[p, 0], pairs[p, 1]
        c = pair_gap(segs[i, 0], segs[i, 1], radii[i], cyl[i], segs[j, 0], segs[j, 1], radii[j], cyl[j])
        if c <= 0.0:
            return 0.0, c
        low = min(low, c)
        if pspeed[p] > 0.0:
            step = min(step, c / pspeed[p])
    return step * (1.0 - 1e-9), low


@njit(cache=True, nogil=True)
def _motions_free(a, b, bounds, floor, budget, probe, lower, upper, base, origins, axes, flange_offset, tube_links,
                  tube_ends, radii, cyl, world, ignore, pairs, kind, pos, rot, half, rad, bound, solid, obj, active,
                  child_ptr, child_idx, roots):
    """Bool (n,): segments a -> b (n, dof) proven free (see the module doc); counts (n,)
    int64: clearance evaluations spent on each."""
    n, dof = a.shape
    t = tube_links.shape[0]
    out = np.zeros(n, dtype=np.bool_)
    spent = np.zeros(n, dtype=np.int64)
    segs = np.empty((1, t, 2, 3))
    ends_a, ends_b = np.empty((t, 2, 3)), np.empty((t, 2, 3))
    frames_a, frames_b = np.empty((dof + 2, 4, 4)), np.empty((dof + 2, 4, 4))
    joint = np.empty((4, 4))
    q = np.empty(dof)
    lever = np.empty((dof, t))
    speed, pspeed = np.empty(t), np.empty(pairs.shape[0])
    stack = np.empty(child_idx.shape[0] + roots.shape[0] + 1, dtype=np.int64)
    wa, wd, bp = np.empty(3), np.empty(3), np.empty(8)
    for i in range(n):
        ok = True
        for j in range(dof):
            if (a[i, j] < lower[j] - JOINT_LIMIT_TOL or a[i, j] > upper[j] + JOINT_LIMIT_TOL
                    or b[i, j] < lower[j] - JOINT_LIMIT_TOL or b[i, j] > upper[j] + JOINT_LIMIT_TOL):
                ok = False
        if not ok:
            continue
        _link_segments(a[i], base, origins, axes, flange_offset, tube_links, tube_ends, frames_a, joint, ends_a)
        _link_segments(b[i], base, origins, axes, flange_offset, tube_links, tube_ends, frames_b, joint, ends_b)
        _speeds(a[i], b[i], bounds, tube_links, cyl, pairs, frames_a, frames_b, ends_a, ends_b, axes, lever, speed, pspeed)
        fastest = 0.0
        for k in range(t):
            fastest = max(fastest, speed[k])
        # exact probes along a long segment: most collisions are found here, cheaply
        probes = min(8, int(fastest / probe) + 1)
        for c in range(1, probes):
            s = c / probes
            for j in range(dof):
                q[j] = a[i, j] + s * (b[i, j] - a[i, j])
            _link_segments(q, base, origins, axes, flange_offset, tube_links, tube_ends, frames_a, joint, segs[0])
            hit, _ = check_arm(segs, radii, cyl, world, ignore, pairs, kind, pos, rot, half, rad, bound, solid, obj,
                               active, child_ptr, child_idx, roots)
            if hit[0] != 0:
                ok = False
                break
        if not ok:
            continue
        # the middle, then advancement from both ends toward the stretch it proved free
        lo, hi = 0.0, 1.0              # [0, lo] and [hi, 1] proven free so far
        m_lo, m_hi = 0.5, 0.5          # the middle's stretch
        prev_lo, prev_hi = 0.0, 0.0    # least clearance at each side's last step
        evals, side = 0, -1
        while lo < m_lo or hi > m_hi:
            if evals >= budget:
                ok = False
                break
            evals += 1
            if side < 0:
                s, need = 0.5, 0.5
            elif (side == 0 and lo < m_lo) or hi <= m_hi:
                s, need, side = lo, m_lo - lo, 0
            else:
                s, need, side = hi, hi - m_hi, 1
            for j in range(dof):
                q[j] = a[i, j] + s * (b[i, j] - a[i, j])
            _link_segments(q, base, origins, axes, flange_offset, tube_links, tube_ends, frames_a, joint, segs[0])
            step, low = _clearance_step(segs[0], need, floor, speed, pspeed, radii, cyl, world, ignore, pairs, kind, pos,
                                        rot, half, rad, bound, solid, obj, active, child_ptr, child_idx, roots, stack,
                                        wa, wd, bp)
            if low <= 0.0:
                ok = False
                break
            if side < 0:
                if low < floor:
                    ok = False
                    break
                m_lo, m_hi = 0.5 - step, 0.5 + step
                side = 0
            elif side == 0:
                # below the floor only while escaping the start (clearance growing)
                if low < floor and low <= prev_lo:
                    ok = False
                    break
                lo, prev_lo, side = s + step, low, 1
            else:
                if low < floor and low <= prev_hi:
                    ok = False
                    break
                hi, prev_hi, side = s - step, low, 0
        out[i] = ok
        spent[i] = evals
    return out, spent


#: segments of one check from which a second core takes half (a segment costs about 0.2 ms)
SPLIT_SEGMENTS = 8


class MotionChecker:
    """`motion_free(a (n, 6), b (n, 6)) -> bool (n,)`: joint segments free at every position
    (see the module doc), compiled end to end over a ConfigChecker's arm and tree.

    floor: m, the closest approach to contact accepted away from a segment's ends;
    budget: clearance evaluations per segment before it is refused (a motion grazing an
    obstacle over a long stretch would need many); probe: m of the fastest tube's travel
    between the exact probes that go first (at most 7 per segment)."""

    def __init__(self, config_free: ConfigChecker, floor: float = 1e-5, budget: int = 400,
                 probe: float = 0.1) -> None:
        if floor <= 0.0 or budget < 1 or probe <= 0.0:
            raise ValueError(f"floor and probe must be > 0 and budget >= 1, got {floor}, {budget}, {probe}")
        self.config_free = config_free
        self.bounds = np.ascontiguousarray(sweep_bounds(config_free.model).astype(float))
        self.floor, self.budget, self.probe = float(floor), int(budget), float(probe)
        self.checks = 0
        self.evaluations = 0
        self.core = SecondCore(SPLIT_SEGMENTS, "motion")    # many segments: half on a second core

    def clear(self, q: ArrayLike) -> NDArray[np.bool_]:
        """Bool (n,): configurations q (n, 6) free with every tube a joint moves grown by
        `floor`: those a motion can leave or reach without first escaping near-contact."""
        q = _rows(q)
        cf = self.config_free
        c = cf.checker
        moving = (self.bounds.sum(axis=0) > 0.0).astype(float)
        return _configs_clear(q, self.floor, moving, *cf._limits, *cf._fk, c.radii, c.cylinder, c.world, cf.ignore(),
                              c.pairs, *c.tree.arrays())

    def __call__(self, a: ArrayLike, b: ArrayLike) -> NDArray[np.bool_]:
        """Bool (n,): whether each segment a -> b ((n, 6) or (6,)) is free everywhere."""
        a, b = (_rows(x) for x in np.broadcast_arrays(np.atleast_2d(np.asarray(a, dtype=float)),
                                                      np.atleast_2d(np.asarray(b, dtype=float))))
        cf = self.config_free
        c = cf.checker
        self.checks += len(a)
        ok, spent = self.core.in_halves(_motions_free, (a, b),
                                        self.bounds, self.floor, self.budget, self.probe, *cf._limits, *cf._fk,
                                        c.radii, c.cylinder, c.world, cf.ignore(), c.pairs, *c.tree.arrays())
        self.evaluations += int(spent.sum())
        return ok

    def speeds(self, a: ArrayLike, b: ArrayLike) -> tuple[FloatArray, FloatArray]:
        """(speed (t,), pair_speed (p,)) of the segment a -> b (6,): the most any point of
        each tube's axis, and each self-collision pair's tubes relative to each other,
        move per unit of the segment's parameter (see the module doc)."""
        a = np.ascontiguousarray(np.asarray(a, dtype=float).reshape(-1))
        b = np.ascontiguousarray(np.asarray(b, dtype=float).reshape(-1))
        cf = self.config_free
        fk = cf._fk
        m = cf.model
        t, dof = len(m.tube_links), m.dof
        frames_a, frames_b, joint = np.empty((dof + 2, 4, 4)), np.empty((dof + 2, 4, 4)), np.empty((4, 4))
        ends_a, ends_b = np.empty((t, 2, 3)), np.empty((t, 2, 3))
        _link_segments(a, *fk, frames_a, joint, ends_a)
        _link_segments(b, *fk, frames_b, joint, ends_b)
        pairs = cf.checker.pairs
        speed, pair_speed = np.empty(t), np.empty(len(pairs))
        _speeds(a, b, self.bounds, fk[4], cf.checker.cylinder, pairs, frames_a, frames_b, ends_a, ends_b, fk[2],
                np.empty((dof, t)), speed, pair_speed)
        return speed, pair_speed
