"""A network adjustment of hole centres over overlapping SLRA frames.

Each frame shows several holes; each hole is seen in one frame or several.  A frame's
pose error (the arm's repeatability, a new draw at every approach) moves everything it
shows: in the part's plane, a shift (2) and a turn about the frame's centre (1).  One
linear least-squares adjustment over every frame's pose error and every hole's centre:

    sighting of hole h in frame f:  m_fh = nominal_h + d_h + t_f + theta_f * perp(nominal_h - c_f) + e
    prior of each frame:           t_f ~ N(0, pose_sigma^2 I),  theta_f ~ N(0, turn_sigma^2)
    datum holes (B, C):            d_h = 0 (they define the part frame)

solved on the sparse normal equations with :mod:`scipy.sparse.linalg`; each hole's
deviation d_h and its covariance come from the adjustment (the a-posteriori variance
factor scales it when the sightings scatter more than their sigmas say, never less).
A hole seen in one frame is decided from that frame's adjusted pose: its uncertainty is
the frame pose's, as the other holes in the frame tie it.

A frame whose sightings do not fit the others (a wrong hole match, a mis-fitted rim) is
found by its residuals' chi-square and left out, one at a time, worst first, and the
network solved again.  A hole's systematic term (the edge model: the same in every frame
that sees it, so the adjustment cannot average it) adds to its covariance afterwards.

    solution = solve_network(sightings, nominal, pose_sigma=0.083, fixed={"TH-B", "TH-C"})
    solution.holes["OF-017"].deviation, .cov, .frames
    solution.left_out      # frame -> why
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field, replace

import numpy as np
import scipy.sparse as sp
from numpy.typing import NDArray
from scipy.sparse.linalg import splu
from scipy.stats import chi2

FloatArray = NDArray[np.float64]

#: a frame whose residual chi-square has a p-value below this is left out (worst first)
OUTLIER_P = 1e-4
#: the turn of a frame about its view axis (rad, 1 sigma): the arm's repeatability spread
#: over its reach gives about 1e-4; generous, the sightings decide it
TURN_SIGMA_RAD = 5e-4
#: at most this many frames are left out of one network
MAX_LEFT_OUT = 20
#: variance components: a group's factor is estimated where its share of the redundancy is
#: at least this, in at most COMPONENT_ITERATIONS rounds, within [MIN_FACTOR, MAX_FACTOR]
MIN_COMPONENT_REDUNDANCY = 10.0
COMPONENT_ITERATIONS = 12
MIN_FACTOR, MAX_FACTOR = 0.1, 1.0
POSE_GROUP, TURN_GROUP = "frame pose", "frame turn"


@dataclass(frozen=True)
class Sighting:
    """Hole `hole` seen in frame `frame`: its fitted centre (x, y) in the part frame as the
    frame's REPORTED pose places it (mm), the standard uncertainty per axis of the fit
    that is new in every frame (`sigma`, mm) and of what is the same in every frame that
    sees the hole (`systematic`, mm: the edge model); `group`: sightings alike (a whole
    rim, half a rim) share a variance component (see :func:`solve_network`)."""

    frame: str
    hole: str
    xy: tuple[float, float]
    sigma: float
    systematic: float = 0.0
    group: str = ""


@dataclass(frozen=True)
class HoleEstimate:
    """A hole's adjusted deviation from nominal (dx, dy mm), its covariance (2, 2 mm^2,
    systematic term included), the frames that saw it, and the budget: the standard
    uncertainty (per axis, mm) of each term."""

    hole: str
    deviation: tuple[float, float]
    cov: tuple[tuple[float, float], tuple[float, float]]
    frames: tuple[str, ...]
    budget: Mapping[str, float] = field(default_factory=dict)

    @property
    def sigma_axis(self) -> float:
        """Standard uncertainty of the position along its worst axis (mm)."""
        return math.sqrt(max(float(np.linalg.eigvalsh(np.asarray(self.cov)).max()), 0.0))


@dataclass(frozen=True)
class NetworkSolution:
    """The adjusted network: hole estimates, frame pose errors (tx, ty mm, turn rad), frames
    left out with why, the a-posteriori variance factor (sigma0^2), the redundancy, and the
    variance components' factors on the sigmas (group -> factor)."""

    holes: Mapping[str, HoleEstimate]
    frames: Mapping[str, tuple[float, float, float]]
    left_out: Mapping[str, str]
    variance_factor: float
    redundancy: int
    factors: Mapping[str, float] = field(default_factory=dict)


def solve_network(sightings: Iterable[Sighting], nominal: Mapping[str, Sequence[float]], *, pose_sigma: float,
                  fixed: Iterable[str] = (), turn_sigma: float = TURN_SIGMA_RAD, outlier_p: float = OUTLIER_P,
                  max_left_out: int = MAX_LEFT_OUT) -> NetworkSolution:
    """Adjust the network of `sightings` (see the module docstring).  nominal: hole id ->
    nominal centre (x, y) mm; pose_sigma: a frame's shift in the part's plane (mm, 1 sigma
    per axis); fixed: datum holes whose centres are their nominal ones."""
    obs = [s for s in sightings if s.hole in nominal]
    fixed = {h for h in fixed if h in nominal}
    left: dict[str, str] = {}
    while True:
        sol, chi_by_frame = _components(obs, nominal, pose_sigma, turn_sigma, fixed)
        worst = _worst_frame(chi_by_frame, outlier_p)
        if worst is None or len(left) >= max_left_out:
            return replace(sol, left_out=dict(left))
        frame, c2, dof = worst
        left[frame] = (f"sightings do not fit the network: chi-square {c2:.1f} on {dof} degrees of freedom "
                       f"(p < {outlier_p:g}); a wrong hole match or a mis-fitted rim")
        obs = [s for s in obs if s.frame != frame]


def _components(obs: Sequence[Sighting], nominal: Mapping[str, Sequence[float]], pose_sigma: float,
                turn_sigma: float, fixed: set[str]) -> tuple[NetworkSolution, dict[str, tuple[float, int]]]:
    """The adjustment with its variance components estimated (Foerstner's iteration): each
    group of sightings (:attr:`Sighting.group`) and the frames' pose priors get a factor on
    their sigmas, their weighted residuals' sum over their share of the redundancy, where
    that share is at least :data:`MIN_COMPONENT_REDUNDANCY`.  The pose prior's factor is
    never below 1 (the arm is no better than its repeatability); a sighting group's lies
    in [:data:`MIN_FACTOR`, :data:`MAX_FACTOR`]: never above its own sigmas, so a gross
    error cannot inflate them and hide from the outlier test.  Sightings that scatter
    more than their sigmas say all the same scale the covariance by the variance factor."""
    factors: dict[str, float] = {}
    for _ in range(COMPONENT_ITERATIONS):
        sol, chi, groups = _adjust(obs, nominal, pose_sigma, turn_sigma, fixed, factors)
        new = dict(factors)
        for g, (ssr, red) in groups.items():
            if red < MIN_COMPONENT_REDUNDANCY:
                continue
            f = factors.get(g, 1.0) * math.sqrt(ssr / red)
            new[g] = max(f, 1.0) if g == POSE_GROUP else min(max(f, MIN_FACTOR), MAX_FACTOR)
        if all(abs(new[g] / factors.get(g, 1.0) - 1) < 0.02 for g in new):
            break
        factors = new
    return replace(sol, factors=dict(factors)), chi


def _worst_frame(chi_by_frame: Mapping[str, tuple[float, int]], p: float) -> tuple[str, float, int] | None:
    """The frame whose residual chi-square is furthest beyond its degrees of freedom, of
    those whose p-value is below `p`; None when there is none."""
    worst, worst_z = None, -math.inf
    for frame, (c2, dof) in chi_by_frame.items():
        if dof <= 0 or float(chi2.sf(c2, dof)) >= p:
            continue
        z = (c2 - dof) / math.sqrt(2 * dof)      # ranks them where the p-values all underflow
        if z > worst_z:
            worst, worst_z = (frame, c2, dof), z
    return worst


def _adjust(obs: Sequence[Sighting], nominal: Mapping[str, Sequence[float]], pose_sigma: float, turn_sigma: float,
            fixed: set[str], factors: Mapping[str, float]
            ) -> tuple[NetworkSolution, dict[str, tuple[float, int]], dict[str, tuple[float, float]]]:
    """One adjustment (no outlier test) with the sigmas of each group times its factor: the
    solution, per frame (chi-square of its sightings' residuals, their redundancy) and per
    group (weighted residuals' sum of squares, share of the redundancy)."""
    frames = sorted({s.frame for s in obs})
    holes = sorted({s.hole for s in obs} - fixed)
    f_ix = {f: i for i, f in enumerate(frames)}
    h_ix = {h: 3 * len(frames) + 2 * i for i, h in enumerate(holes)}
    n = 3 * len(frames) + 2 * len(holes)
    centre = {f: np.mean([nominal[s.hole][:2] for s in obs if s.frame == f], axis=0) for f in frames}
    rows, cols, vals, rhs, owner, group = [], [], [], [], [], []
    r = 0
    for s in obs:
        w = 1.0 / max(s.sigma * factors.get(s.group, 1.0), 1e-9)
        nom = np.asarray(nominal[s.hole][:2], dtype=float)
        rel = nom - centre[s.frame]
        perp = (-rel[1], rel[0])
        fx = 3 * f_ix[s.frame]
        for axis in (0, 1):
            rows += [r, r]
            cols += [fx + axis, fx + 2]
            vals += [w, w * perp[axis]]
            if s.hole in h_ix:
                rows.append(r)
                cols.append(h_ix[s.hole] + axis)
                vals.append(w)
            rhs.append(w * (s.xy[axis] - nom[axis]))
            owner.append(s.frame)
            group.append(s.group)
            r += 1
    n_obs = r
    pose = pose_sigma * factors.get(POSE_GROUP, 1.0)
    for f in frames:                       # the priors: the arm's repeatability
        fx = 3 * f_ix[f]
        for k, sig in ((0, pose), (1, pose), (2, turn_sigma)):
            rows.append(r)
            cols.append(fx + k)
            vals.append(1.0 / sig)
            rhs.append(0.0)
            group.append(POSE_GROUP if k < 2 else TURN_GROUP)
            r += 1
    jac = sp.csr_matrix((vals, (rows, cols)), shape=(r, n))
    b = np.asarray(rhs)
    lu = splu((jac.T @ jac).tocsc())
    x = lu.solve(jac.T @ b)
    res = jac @ x - b
    # each row's leverage (diagonal of J N^-1 J^T): its share of the redundancy is 1 minus it
    jt = jac.T.toarray()
    leverage = np.einsum("ij,ij->j", jt, lu.solve(jt))
    redundancy = r - n
    vf = float(res @ res) / redundancy if redundancy > 0 else 1.0
    groups: dict[str, tuple[float, float]] = {}
    for g, e, h in zip(group, res, leverage):
        ssr, red = groups.get(g, (0.0, 0.0))
        groups[g] = (ssr + float(e) ** 2, red + 1.0 - float(h))
    seen: dict[str, list[str]] = {}
    for s in obs:
        seen.setdefault(s.hole, []).append(s.frame)
    est: dict[str, HoleEstimate] = {}
    if holes:
        cols_h = np.array([h_ix[h] + a for h in holes for a in (0, 1)])
        e = np.zeros((n, len(cols_h)))
        e[cols_h, np.arange(len(cols_h))] = 1.0
        inv = lu.solve(e)                  # the hole columns of the inverse normal matrix
    for i, h in enumerate(holes):
        k = h_ix[h]
        cov = inv[k:k + 2, 2 * i:2 * i + 2] * max(vf, 1.0)
        sys_u = max(s.systematic for s in obs if s.hole == h)
        net_u = math.sqrt(max(float(np.linalg.eigvalsh(cov).max()), 0.0))
        total = cov + np.eye(2) * sys_u ** 2
        budget = {"network (frame poses and rim fits)": net_u, "edge model": sys_u}
        (c_xx, c_xy), (c_yx, c_yy) = total.tolist()
        est[h] = HoleEstimate(h, (float(x[k]), float(x[k + 1])), ((c_xx, c_xy), (c_yx, c_yy)),
                              tuple(sorted(set(seen[h]))), budget)
    chi: dict[str, tuple[float, int]] = {}
    for f, ri in zip(owner, range(n_obs)):
        c2, dof = chi.get(f, (0.0, 0))
        chi[f] = (c2 + float(res[ri]) ** 2, dof + 1)
    # a frame's own redundancy: its sightings less its three pose unknowns
    chi = {f: (c2, dof - 3) for f, (c2, dof) in chi.items()}
    frame_est = {f: (float(x[3 * i]), float(x[3 * i + 1]), float(x[3 * i + 2])) for f, i in f_ix.items()}
    return NetworkSolution(est, frame_est, {}, vf, redundancy), chi, groups
