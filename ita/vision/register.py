"""Registration of a frame on references in it: the part-frame shift t (2,) mm that takes
measured points to where they belong (p_true = p_measured + t).

The arm's pose error moves everything a frame shows by nearly the same (x, y) (its rotation
error is 0.05 mrad: 0.003 mm across 60 mm), so a translation is the model.  Each reference
seen in the frame is a `Constraint` in information form (J (2, 2), g (2,), with
J t = g its normal equations), so that references that fix one direction only (a straight
edge) and references that fix both (a hole, a curved edge) combine by adding:

* `point_constraint`: a feature whose position is known to within a covariance (a
  neighbouring hole: its own position scatter plus its centre's measurement error);
* `edge_constraint`: edge points with their signed distances to a nominal edge and the
  edge's normals there; a common bias of the whole edge (the sub-pixel model's residual,
  or the edge's own tolerance) is a nuisance marginalised out, so it counts once, not
  once per point;
* `centreline_constraint`: the two sides of a rib, whose width deviation (which moves
  the sides apart, symmetrically) cancels.

`solve` adds them, drops point references whose residual is beyond `reject_chi2`
(a neighbour out of its tolerance zone, a misfitted rim) one at a time, and returns t
with its covariance.  The arm's repeatability is a prior only in the directions the
references leave loose (beyond LOOSE times it).  Pure numpy.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]

REJECT_CHI2 = 9.21   # chi-square, 2 dof, 99 %
LOOSE = 2.0          # references looser than this many prior sigmas leave a direction to the prior


@dataclass(frozen=True)
class Constraint:
    """One reference: information J (2, 2), J t = g (2,) alone; `point`: for a point
    reference, its shift estimate (2,) and covariance (2, 2) (for the outlier test)."""

    name: str
    info: FloatArray
    g: FloatArray
    kind: str = "point"
    point: tuple[FloatArray, FloatArray] | None = field(default=None, compare=False)


@dataclass(frozen=True)
class Registration:
    """Shift t (2,) mm and its covariance (2, 2); which references were used and which
    were dropped as outliers."""

    shift: FloatArray
    cov: FloatArray
    used: tuple[str, ...]
    rejected: tuple[str, ...]

    @property
    def sigma(self) -> FloatArray:
        """(2,) standard uncertainties along x and y."""
        return np.sqrt(np.diag(self.cov))


def point_constraint(name: str, nominal: FloatArray, measured: FloatArray, cov: FloatArray) -> Constraint:
    """A reference at part point `nominal` (2,) seen at `measured` (2,); cov (2, 2): its own
    position scatter plus the measurement's."""
    t = np.asarray(nominal, dtype=float) - np.asarray(measured, dtype=float)
    info = np.linalg.inv(np.asarray(cov, dtype=float))
    return Constraint(name, info, info @ t, "point", (t, np.asarray(cov, dtype=float)))


def edge_constraint(name: str, offsets: FloatArray, normals: FloatArray, sigma: float,
                    bias_sigma: float) -> Constraint:
    """Edge points at signed distances `offsets` (n,) mm from the nominal edge along its
    unit normals (n, 2) there (measured minus nominal); sigma: each point's scatter;
    bias_sigma: a shift common to all the points (marginalised: Sherman-Morrison)."""
    n = np.asarray(normals, dtype=float)
    z = -np.asarray(offsets, dtype=float)          # n . t = -offset
    k = len(z)
    s2, f2 = max(sigma, 1e-3) ** 2, bias_sigma ** 2
    w = f2 / (s2 + k * f2)
    n1, z1 = n.sum(0), z.sum()
    info = (n.T @ n - w * np.outer(n1, n1)) / s2
    g = (n.T @ z - w * n1 * z1) / s2
    return Constraint(name, info, g, "edge")


def centreline_constraint(name: str, offset_a: float, var_a: float, offset_b: float, var_b: float,
                          normal_a: FloatArray) -> Constraint:
    """The two sides of a rib: mean offsets (measured minus nominal, along each side's own
    outward normal; side b's normal is -normal_a) and their variances.  A width deviation
    moves both outward by the same amount and cancels in (a - b) / 2."""
    n = np.asarray(normal_a, dtype=float)
    z = -(offset_a - offset_b) / 2                  # n_a . t
    var = (var_a + var_b) / 4
    return Constraint(name, np.outer(n, n) / var, n * z / var, "edge")


def _combine(active: list[Constraint], prior_var: float | None) -> tuple[FloatArray, FloatArray] | None:
    active = [c for c in active if np.all(np.isfinite(c.info)) and np.all(np.isfinite(c.g))]
    info = sum((c.info for c in active), np.zeros((2, 2)))
    g = sum((c.g for c in active), np.zeros(2))
    if prior_var is not None:
        # the prior only in directions the references leave looser than LOOSE times it, so
        # that wherever they say something the shift is theirs alone: the same every
        # repeat, where a blend with the pose would move with the arm's error
        lam, vec = np.linalg.eigh(info)
        add = np.where(lam < 1.0 / (LOOSE ** 2 * prior_var), 1.0 / prior_var, 0.0)
        info = info + (vec * add) @ vec.T
    if np.linalg.cond(info) > 1e10:
        return None
    cov = np.linalg.inv(info)
    return cov @ g, cov


def solve(constraints: list[Constraint], prior_sigma: float | None = None,
          reject_chi2: float = REJECT_CHI2) -> Registration | None:
    """Combined shift of `constraints` (a zero shift of `prior_sigma` per axis, the arm's
    repeatability, is added in the directions they leave looser than LOOSE times it); None when nothing fixes both
    directions.  Point references beyond `reject_chi2` of the rest are dropped, worst
    first."""
    prior_var = None if prior_sigma is None else prior_sigma ** 2
    active = list(constraints)
    rejected: list[str] = []
    while True:
        sol = _combine(active, prior_var)
        if sol is None:
            return None
        t, cov = sol
        worst, worst_chi2 = None, reject_chi2
        for c in active:
            if c.kind != "point":
                continue
            rest = _combine([d for d in active if d is not c], prior_var)
            if rest is None:
                continue
            e = c.point[0] - rest[0]
            chi2 = float(e @ np.linalg.solve(c.point[1] + rest[1], e))
            if chi2 > worst_chi2:
                worst, worst_chi2 = c, chi2
        if worst is None:
            return Registration(t, cov, tuple(c.name for c in active), tuple(rejected))
        active.remove(worst)
        rejected.append(worst.name)
