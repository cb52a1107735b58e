"""Least-squares fits with covariances: planes, lines and circles.

Pure numpy.  Each fit returns a frozen value with its parameters, their covariance (from
the residual scatter: sigma^2 (J^T J)^-1) and the RMS residual, or None when there are too
few points to fit.  Robust variants drop points beyond `clip` times a MAD-based sigma and
refit, a few rounds; a circle whose residuals show a cluster of outliers on one side
(spurious edge points) starts again from a trimmed fit, so that they cannot pull the start
so far that the clip keeps them.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]


def _robust_sigma(r: FloatArray) -> float:
    return float(1.4826 * np.median(np.abs(r - np.median(r)))) if len(r) else 0.0


@dataclass(frozen=True)
class PlaneFit:
    """z = a x + b y + c over n points; cov: (3, 3) of (a, b, c); rms: residual (z units)."""

    coef: tuple[float, float, float]
    cov: FloatArray
    rms: float
    n: int
    center: tuple[float, float]

    def z(self, x: float, y: float) -> float:
        """Height of the plane at (x, y)."""
        a, b, c = self.coef
        return a * x + b * y + c

    def z_sigma(self, x: float, y: float) -> float:
        """Standard uncertainty of z(x, y) from the fit."""
        g = np.array([x, y, 1.0])
        return float(np.sqrt(max(float(g @ self.cov @ g), 0.0)))

    @property
    def normal(self) -> FloatArray:
        """(3,) unit normal pointing to +z."""
        a, b, _ = self.coef
        n = np.array([-a, -b, 1.0])
        return n / np.linalg.norm(n)


def fit_plane(p: FloatArray, clip: float = 3.5, rounds: int = 3) -> PlaneFit | None:
    """Robust fit of z = a x + b y + c to points (n, 3)."""
    p = np.asarray(p, dtype=float)
    keep = np.all(np.isfinite(p), axis=1)
    fit = None
    for _ in range(rounds):
        q = p[keep]
        if len(q) < 6:
            return fit
        cx, cy = q[:, 0].mean(), q[:, 1].mean()
        a = np.column_stack([q[:, 0] - cx, q[:, 1] - cy, np.ones(len(q))])
        # centred, the normal equations are well conditioned: solved directly (a run makes
        # thousands of these fits; least squares by SVD took twice as long)
        inv = np.linalg.inv(a.T @ a)
        sol = inv @ (a.T @ q[:, 2])
        r = q[:, 2] - a @ sol
        s2 = float(r @ r) / max(len(q) - 3, 1)
        cov_c = s2 * inv
        # back to z = a x + b y + c: c = c' - a cx - b cy
        t = np.array([[1, 0, 0], [0, 1, 0], [-cx, -cy, 1]])
        coef = (float(sol[0]), float(sol[1]), float(sol[2] - sol[0] * cx - sol[1] * cy))
        fit = PlaneFit(coef, t @ cov_c @ t.T, float(np.sqrt(np.mean(r ** 2))), len(q), (float(cx), float(cy)))
        full = p[:, 2] - (coef[0] * p[:, 0] + coef[1] * p[:, 1] + coef[2])
        sig = max(_robust_sigma(r), 1e-9)
        new = np.all(np.isfinite(p), axis=1) & (np.abs(full) < clip * sig)
        if np.array_equal(new, keep):
            break
        keep = new
    return fit


@dataclass(frozen=True)
class LineFit:
    """A 2-D line through `point` along unit `direction`; offset_sigma: standard
    uncertainty of its position across itself at `point`; angle_sigma (rad)."""

    point: tuple[float, float]
    direction: tuple[float, float]
    offset_sigma: float
    angle_sigma: float
    rms: float
    n: int
    span: float

    def distance(self, xy: FloatArray) -> FloatArray:
        """Signed distance (n,) of points (n, 2) from the line (positive to the left)."""
        d = np.asarray(self.direction)
        nrm = np.array([-d[1], d[0]])
        return (np.atleast_2d(xy) - np.asarray(self.point)) @ nrm

    def offset_sigma_at(self, xy: FloatArray) -> float:
        """Standard uncertainty across the line at the foot of point (2,)."""
        s = float((np.asarray(xy) - np.asarray(self.point)) @ np.asarray(self.direction))
        return float(np.hypot(self.offset_sigma, s * self.angle_sigma))


def fit_line(xy: FloatArray, clip: float = 3.5, rounds: int = 3) -> LineFit | None:
    """Robust total-least-squares line through points (n, 2)."""
    xy = np.asarray(xy, dtype=float)
    keep = np.all(np.isfinite(xy), axis=1)
    fit = None
    for _ in range(rounds):
        q = xy[keep]
        if len(q) < 4:
            return fit
        m = q.mean(axis=0)
        _, _, vt = np.linalg.svd(q - m, full_matrices=False)
        d = vt[0]
        nrm = np.array([-d[1], d[0]])
        r = (q - m) @ nrm
        s = (q - m) @ d
        s2 = float(r @ r) / max(len(q) - 2, 1)
        fit = LineFit((float(m[0]), float(m[1])), (float(d[0]), float(d[1])), float(np.sqrt(s2 / len(q))),
                      float(np.sqrt(s2 / max(float(s @ s), 1e-12))), float(np.sqrt(np.mean(r ** 2))),
                      len(q), float(s.max() - s.min()))
        full = (xy - m) @ nrm
        sig = max(_robust_sigma(r), 1e-9)
        new = np.all(np.isfinite(xy), axis=1) & (np.abs(full) < clip * sig)
        if np.array_equal(new, keep):
            break
        keep = new
    return fit


@dataclass(frozen=True)
class CircleFit:
    """A 2-D circle; cov: (3, 3) of (cx, cy, r); coverage: angle (rad) the points span."""

    center: tuple[float, float]
    radius: float
    cov: FloatArray
    rms: float
    n: int
    coverage: float

    @property
    def radius_sigma(self) -> float:
        return float(np.sqrt(max(self.cov[2, 2], 0.0)))

    @property
    def center_sigma(self) -> tuple[float, float]:
        return float(np.sqrt(max(self.cov[0, 0], 0.0))), float(np.sqrt(max(self.cov[1, 1], 0.0)))


def circle_algebraic(xy: FloatArray) -> tuple[FloatArray, float]:
    """Kasa fit: centre (2,) and radius from x^2 + y^2 + D x + E y + F = 0."""
    m = xy.mean(axis=0)
    q = xy - m
    a = np.column_stack([q, np.ones(len(q))])
    sol, *_ = np.linalg.lstsq(a, -(q ** 2).sum(1), rcond=None)
    c = -sol[:2] / 2
    return c + m, float(np.sqrt(max(c @ c - sol[2], 0.0)))


def _coverage(xy: FloatArray, c: FloatArray) -> float:
    ang = np.sort(np.arctan2(xy[:, 1] - c[1], xy[:, 0] - c[0]))
    gaps = np.diff(np.concatenate([ang, ang[:1] + 2 * np.pi]))
    return float(2 * np.pi - gaps.max()) if len(ang) > 1 else 0.0


def _circle_gauss_newton(q: FloatArray, c: FloatArray, r: float, iterations: int,
                         fixed_radius: bool = False) -> tuple[FloatArray, float]:
    """Geometric circle fit to points q (n, 2) from the start (c, r): Gauss-Newton on the
    radial residuals |p - c| - r (the centre only when `fixed_radius`), each step from
    the normal equations (a compiled kernel: a run makes about 30,000 such fits)."""
    try:
        cx, cy, rr = _gauss_newton_kernel(np.ascontiguousarray(q, dtype=np.float64), float(c[0]), float(c[1]),
                                          float(r), int(iterations), bool(fixed_radius))
    except np.linalg.LinAlgError:   # singular normal equations (points on a line): least-norm steps
        return _gauss_newton_lstsq(q, c, r, iterations, fixed_radius)
    return np.array([cx, cy]), float(rr)


def _gauss_newton_lstsq(q: FloatArray, c: FloatArray, r: float, iterations: int,
                        fixed_radius: bool) -> tuple[FloatArray, float]:
    """:func:`_circle_gauss_newton` by least-norm least squares (degenerate point sets)."""
    for _ in range(iterations):
        v = q - c
        dist = np.linalg.norm(v, axis=1)
        step, *_ = np.linalg.lstsq(_circle_jacobian(v, dist, fixed_radius), -(dist - r), rcond=None)
        c = c + step[:2]
        if not fixed_radius:
            r = r + step[2]
        if np.abs(step).max() < 1e-10:
            break
    return c, float(r)


@njit(cache=True)
def _gauss_newton_kernel(q, cx, cy, r, iterations, fixed_radius):  # pragma: no cover - compiled
    """(cx, cy, r) after Gauss-Newton steps on |p - c| - r over q (n, 2); each step solves
    J^T J s = -J^T res (3 or 2 unknowns, np.linalg.solve); stops on a step under 1e-10."""
    n = q.shape[0]
    m = 2 if fixed_radius else 3
    for _ in range(iterations):
        a = np.zeros((3, 3))
        b = np.zeros(3)
        for i in range(n):
            vx, vy = q[i, 0] - cx, q[i, 1] - cy
            d = math.sqrt(vx * vx + vy * vy)
            if d == 0.0:
                d = 1e-300
            j0, j1, j2 = -vx / d, -vy / d, -1.0
            res = d - r
            a[0, 0] += j0 * j0
            a[0, 1] += j0 * j1
            a[1, 1] += j1 * j1
            b[0] -= j0 * res
            b[1] -= j1 * res
            if m == 3:
                a[0, 2] += j0 * j2
                a[1, 2] += j1 * j2
                a[2, 2] += j2 * j2
                b[2] -= j2 * res
        a[1, 0], a[2, 0], a[2, 1] = a[0, 1], a[0, 2], a[1, 2]
        step = np.linalg.solve(a[:m, :m], b[:m]) if n >= m else np.zeros(m)
        cx += step[0]
        cy += step[1]
        if m == 3:
            r += step[2]
        if np.abs(step).max() < 1e-10:
            break
    return cx, cy, r


def _circle_jacobian(v: FloatArray, dist: FloatArray, fixed_radius: bool) -> FloatArray:
    """d(|p - c| - r) / d(cx, cy[, r]) for offsets v = p - c (n, 2) of length dist (n,)."""
    jc = -v / dist[:, None]
    return jc if fixed_radius else np.column_stack([jc, -np.ones(len(v))])


def _concentrate(q: FloatArray, c: FloatArray, r: float, h: int, iterations: int) -> tuple[FloatArray, float, float]:
    """Concentration steps of least trimmed squares from (c, r): refit the h points (of q,
    (n, 2)) nearest the circle until that subset no longer changes.  Returns the centre,
    radius and the trimmed sum of squared residuals."""
    chosen = np.zeros(0, dtype=np.int64)
    for _ in range(10):
        best = np.sort(np.argsort(np.abs(np.linalg.norm(q - c, axis=1) - r))[:h])
        if np.array_equal(best, chosen):
            break
        chosen = best
        c, r = _circle_gauss_newton(q[chosen], c, r, iterations)
    res = np.linalg.norm(q[chosen] - c, axis=1) - r
    return c, r, float(res @ res)


def _trimmed_start(q: FloatArray, keep_share: float, iterations: int) -> tuple[FloatArray, float]:
    """A start that a minority of outliers cannot pull (least trimmed squares): from the fit
    to all points (n, 2) and from the fits to each of four half-circles of them (a cluster
    of outliers on one side spoils at most some of these), concentration steps on the
    `keep_share` of the points nearest the circle; the start of least trimmed residual wins."""
    c0, r0 = _circle_gauss_newton(q, *circle_algebraic(q), iterations)
    h = min(len(q), max(5, int(math.ceil(keep_share * len(q)))))
    ang = np.arctan2(q[:, 1] - c0[1], q[:, 0] - c0[0])
    starts = [(c0, r0)]
    for k in range(4):
        half = np.cos(ang - k * np.pi / 2) > 0
        if half.sum() >= 5:
            starts.append(_circle_gauss_newton(q[half], c0, r0, iterations))
    best = min((_concentrate(q, c, r, h, iterations) for c, r in starts), key=lambda t: t[2])
    return best[0], best[1]


def fit_circle(xy: FloatArray, clip: float = 3.5, rounds: int = 3, iterations: int = 10,
               keep_share: float = 0.6) -> CircleFit | None:
    """Robust geometric circle fit to points (n, 2): Gauss-Newton on the radial residuals
    |p - c| - r of the points within `clip` robust sigmas, a few rounds, covariance
    sigma^2 (J^T J)^-1.  Two starts: the algebraic fit to all points (the plain fit), and a
    trimmed fit (the `keep_share` nearest points, so up to 1 - keep_share outliers on one
    side cannot pull it).  The plain fit is the answer unless it lies more than 4 standard
    uncertainties from the trimmed one (a cluster of outliers on one side has pulled it):
    a clean rim keeps all its points, the same way from frame to frame."""
    xy = np.asarray(xy, dtype=float)
    finite = np.all(np.isfinite(xy), axis=1)
    if finite.sum() < 5:
        return None
    q = xy[finite]
    plain = _clipped_circle(xy, finite, *circle_algebraic(q), clip, rounds, iterations, trim_first=False)
    trimmed = _clipped_circle(xy, finite, *_trimmed_start(q, keep_share, iterations), clip, rounds, iterations)
    return trimmed if plain is None or (trimmed is not None and _apart(plain, trimmed)) else plain


def fit_circle_fixed_radius(xy: FloatArray, radius: float, clip: float = 3.5, rounds: int = 3,
                            iterations: int = 10) -> CircleFit | None:
    """Robust fit of a circle of known `radius` to points (n, 2): its centre only, from the
    robust free fit (:func:`fit_circle`) and the points it kept (within `clip` times its
    rms), Gauss-Newton on the radial residuals of the points within `clip` robust sigmas,
    a few rounds.  For a rim seen over part of its
    circle (half of it, say), where a free radius trades off against the centre along the
    arc's bisector.  cov: (3, 3) of (cx, cy, r) with the radius's row and column zero."""
    xy = np.asarray(xy, dtype=float)
    finite = np.all(np.isfinite(xy), axis=1)
    start = fit_circle(xy)
    if start is None:
        return None
    c = np.asarray(start.center, dtype=float)
    keep = finite.copy()
    keep[finite] = np.abs(np.linalg.norm(xy[finite] - c, axis=1) - start.radius) < clip * max(start.rms, 1e-9)
    return _clipped_circle(xy, finite, c, float(radius), clip, rounds, iterations, keep=keep, fixed_radius=True)


def _apart(a: CircleFit, b: CircleFit, k: float = 4.0) -> bool:
    """Whether circle a differs from b by more than k of b's standard uncertainties in a
    centre coordinate or the radius (a one-sided cluster of outliers has pulled a)."""
    d = np.abs(np.array([a.center[0] - b.center[0], a.center[1] - b.center[1], a.radius - b.radius]))
    sig = np.sqrt(np.maximum(np.diag(b.cov), 1e-18))
    return bool(np.any(d > k * sig))


def _clipped_circle(xy: FloatArray, finite: NDArray[np.bool_], c: FloatArray, r: float, clip: float, rounds: int,
                    iterations: int, trim_first: bool = True, keep: NDArray[np.bool_] | None = None,
                    fixed_radius: bool = False) -> CircleFit | None:
    """Rounds of Gauss-Newton from (c, r) on the points of xy (n, 2) within `clip` robust
    sigmas of the current circle (in the first round: the points `keep` if given, else
    those within `clip` robust sigmas of (c, r) when `trim_first`, else all finite points).
    With `fixed_radius` only the centre moves (at least 4 points; the covariance's radius
    row and column zero), else at least 5 points."""
    n_par = 2 if fixed_radius else 3
    full = np.full(len(xy), np.inf)
    full[finite] = np.linalg.norm(xy[finite] - c, axis=1) - r
    if keep is None:
        keep = np.abs(full) < clip * max(_robust_sigma(full[finite]), 1e-9) if trim_first else finite.copy()
    fit = None
    for _ in range(rounds):
        q = xy[keep]
        if len(q) < n_par + 2:
            return fit
        c, r = _circle_gauss_newton(q, c, r, iterations, fixed_radius)
        v = q - c
        dist = np.linalg.norm(v, axis=1)
        res = dist - r
        jac = _circle_jacobian(v, dist, fixed_radius)
        s2 = float(res @ res) / max(len(q) - n_par, 1)
        try:
            inv = s2 * np.linalg.inv(jac.T @ jac)
        except np.linalg.LinAlgError:
            return fit
        cov = np.zeros((3, 3))
        cov[:n_par, :n_par] = inv
        fit = CircleFit((float(c[0]), float(c[1])), float(r), cov, float(np.sqrt(np.mean(res ** 2))),
                        len(q), _coverage(q, c))
        full[finite] = np.linalg.norm(xy[finite] - c, axis=1) - r
        new = np.abs(full) < clip * max(_robust_sigma(res), 1e-9)
        if np.array_equal(new, keep):
            break
        keep = new
    return fit


@dataclass(frozen=True)
class ParallelPlanes:
    """Planes z = a x + b y + c_i sharing one tilt (faces machined parallel); cov: of
    (a, b, c_0, c_1, ...); rms: residual over all points."""

    slope: tuple[float, float]
    offsets: tuple[float, ...]
    cov: FloatArray
    rms: float
    group_rms: tuple[float, ...] = ()

    def gap_sigma(self, i: int, j: int) -> float:
        """Standard uncertainty of offsets[i] - offsets[j]."""
        g = np.zeros(len(self.cov))
        g[2 + i], g[2 + j] = 1.0, -1.0
        return float(np.sqrt(max(float(g @ self.cov @ g), 0.0)))

    def mean_gap_sigma(self, i: int, others: list[int]) -> float:
        """Standard uncertainty of offsets[i] minus the mean of offsets[others] (the mean
        of the gaps to each: the shared term counted once)."""
        g = np.zeros(len(self.cov))
        g[2 + i] = 1.0
        for j in others:
            g[2 + j] -= 1.0 / len(others)
        return float(np.sqrt(max(float(g @ self.cov @ g), 0.0)))


def fit_parallel_planes(groups: list[FloatArray]) -> ParallelPlanes:
    """Planes of one shared tilt through point groups [(n_i, 3)]; the shared tilt comes
    from all the points, so the gaps between the planes do not depend on extrapolating any
    one of them.  Each group has its own noise (a face seen farther off or more obliquely
    scatters more): least squares first, then weighted by each group's own residual
    variance (variance components), and the covariance from those; `group_rms` each
    group's residual rms.  One pooled variance made the gap's uncertainty too small where
    the smaller group is the noisier (a flange's web patch beside its cap)."""
    pts = np.vstack(groups)
    cx, cy = pts[:, 0].mean(), pts[:, 1].mean()
    cols = [pts[:, 0] - cx, pts[:, 1] - cy]
    for i, g in enumerate(groups):
        cols.append(np.concatenate([np.full(len(h), float(i == j)) for j, h in enumerate(groups)]))
    a = np.column_stack(cols)
    which = np.concatenate([np.full(len(g), i) for i, g in enumerate(groups)])
    n = np.array([len(g) for g in groups], dtype=float)
    sol, *_ = np.linalg.lstsq(a, pts[:, 2], rcond=None)
    var = np.ones(len(groups))
    for _ in range(2):
        r = pts[:, 2] - a @ sol
        # each group's share of the degrees of freedom: its offset, and the tilt's 2 in proportion
        dof = np.maximum(n - 1 - 2 * n / n.sum(), 1.0)
        var = np.bincount(which, weights=r * r, minlength=len(groups)) / dof
        var = np.maximum(var, max(float(var.max()) * 1e-6, 1e-18))
        w = np.sqrt(1.0 / var[which])
        sol, *_ = np.linalg.lstsq(a * w[:, None], pts[:, 2] * w, rcond=None)
    r = pts[:, 2] - a @ sol
    cov = np.linalg.inv(a.T @ (a / var[which][:, None]))
    rms = np.sqrt(np.bincount(which, weights=r * r, minlength=len(groups)) / n)
    return ParallelPlanes((float(sol[0]), float(sol[1])), tuple(float(c) for c in sol[2:]), cov,
                          float(np.sqrt(np.mean(r ** 2))), tuple(float(x) for x in rms))
