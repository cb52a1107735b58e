"""Statistical process control of one design's characteristics across serials.

Per characteristic, its values over the serials in the order they were inspected:

- the mean, the standard deviation, Cp and Cpk against the tolerance (Cpk's 95 %
  confidence interval by Bissell's approximation, sqrt(1/(9n) + Cpk^2/(2(n-1))), wide for
  a handful of serials; a one-sided tolerance, a position's, has Cpk only);
- an individuals and moving-range chart: centre, sigma from the mean moving range (MR/1.128),
  limits at 3 sigma, the MR chart's upper limit 3.267 MR;
- two rules, each with a p-value, for special causes:
  * *point*: one serial unlike the others (its value against the mean and standard
    deviation of the rest, Student's t with n - 2 degrees of freedom, Bonferroni over the
    serials); the point's own measurement uncertainty widens its denominator, so that a
    value measured less well than the others (a hole position seen in one frame) is not a
    special cause of the process for that alone; needs 4 serials;
  * *step*: the later serials shifted from the earlier (the last k against the first n - k,
    pooled two-sample t, k = 2 .. n - 2, Bonferroni over k); needs 5 serials.
  The characteristic's p-value is the smaller of the two, doubled (Bonferroni).

With a thousand characteristics a 3-sigma rule alone flags nearly every part that is in
control (1 - 0.9973^1000 = 93 %).  Here the characteristics' p-values go through the
Benjamini-Hochberg procedure at level q (default 0.05): when every characteristic is in
control, the chance that any is flagged is at most q, so at most about q of in-control
parts are flagged.  The 3-sigma points are still counted (``beyond_3_sigma``) for the
record, not flagged.

    charts = chart_all(series, q=0.05)     # series: Series per characteristic
    [c for c in charts if c.flags]
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field, replace

import numpy as np
from scipy import stats

__all__ = ["Chart", "Flag", "Series", "benjamini_hochberg", "chart", "chart_all"]

D2 = 1.128          # E|X1 - X2| / sigma for normal pairs: the moving range's constant
D4 = 3.267          # the MR chart's upper limit over the mean moving range (n = 2)


@dataclass(frozen=True)
class Series:
    """One characteristic's values over the serials, in inspection order: its spec id, kind,
    limits (low, high; low None for a one-sided tolerance), serials, values (mm) and their
    standard uncertainties (mm; empty: not known, taken as 0)."""

    id: str
    kind: str
    low: float | None
    high: float
    serials: tuple[str, ...]
    values: tuple[float, ...]
    u: tuple[float, ...] = ()


@dataclass(frozen=True)
class Flag:
    """A special cause found: the rule, the serials it points at, the rule's p-value and the
    Benjamini-Hochberg adjusted p-value (q-value) of the characteristic."""

    rule: str
    serials: tuple[str, ...]
    p: float
    q: float

    def to_dict(self) -> dict[str, object]:
        return {"rule": self.rule, "serials": list(self.serials), "p": self.p, "q": self.q}


@dataclass(frozen=True)
class Chart:
    """One characteristic's SPC figures (see the module docstring).  p: the characteristic's
    p-value for a special cause (1.0 when its rules cannot be applied); flags: what the
    Benjamini-Hochberg procedure kept."""

    series: Series
    mean: float
    sd: float
    cp: float | None
    cpk: float | None
    cpk_ci: tuple[float, float] | None
    centre: float
    sigma_mr: float
    ucl: float
    lcl: float
    mr_ucl: float
    beyond_3_sigma: tuple[str, ...]
    p: float
    rule: str
    rule_serials: tuple[str, ...]
    flags: tuple[Flag, ...] = field(default=())

    @property
    def n(self) -> int:
        return len(self.series.values)

    def to_dict(self) -> dict[str, object]:
        s = self.series
        return {"id": s.id, "kind": s.kind, "n": self.n, "mean": self.mean, "sd": self.sd, "cp": self.cp,
                "cpk": self.cpk, "cpk_ci": None if self.cpk_ci is None else list(self.cpk_ci),
                "low": s.low, "high": s.high, "flags": [f.to_dict() for f in self.flags], "p": self.p,
                "chart": {"serials": list(s.serials), "values": list(s.values), "centre": self.centre,
                          "ucl": self.ucl, "lcl": self.lcl, "sigma_mr": self.sigma_mr, "mr_ucl": self.mr_ucl,
                          "beyond_3_sigma": list(self.beyond_3_sigma)}}


def _capability(x: np.ndarray, low: float | None, high: float) -> tuple[float | None, float | None,
                                                                         tuple[float, float] | None]:
    n = len(x)
    if n < 2:
        return None, None, None
    sd = float(np.std(x, ddof=1))
    if not sd > 0:
        return None, None, None
    mean = float(np.mean(x))
    cp = None if low is None else (high - low) / (6 * sd)
    cpk = (high - mean) / (3 * sd) if low is None else min(high - mean, mean - low) / (3 * sd)
    half = 1.959964 * math.sqrt(1 / (9 * n) + cpk * cpk / (2 * (n - 1)))
    return cp, cpk, (cpk - half, cpk + half)


def _point_rule(x: np.ndarray, u: np.ndarray) -> tuple[float, int]:
    """The point rule's p-value and the serial it points at (p 1.0 below 4 serials); u: the
    values' standard measurement uncertainties."""
    n = len(x)
    if n < 4:
        return 1.0, -1
    best, where = 1.0, -1
    for i in range(n):
        rest = np.delete(x, i)
        s = float(np.std(rest, ddof=1))
        if not s > 0:
            continue
        t = (x[i] - float(rest.mean())) / math.sqrt(s * s * (1 + 1 / (n - 1)) + float(u[i]) ** 2)
        p = float(2 * stats.t.sf(abs(t), n - 2))
        if p < best:
            best, where = p, i
    return min(1.0, n * best), where


def _step_rule(x: np.ndarray) -> tuple[float, int]:
    """The step rule's p-value and how many of the last serials it points at (p 1.0 below 5)."""
    n = len(x)
    if n < 5:
        return 1.0, 0
    best, last = 1.0, 0
    ks = range(2, n - 1)
    for k in ks:
        a, b = x[: n - k], x[n - k:]
        sp2 = (float(np.sum((a - a.mean()) ** 2)) + float(np.sum((b - b.mean()) ** 2))) / (n - 2)
        if not sp2 > 0:
            continue
        t = (float(b.mean()) - float(a.mean())) / math.sqrt(sp2 * (1 / k + 1 / (n - k)))
        p = float(2 * stats.t.sf(abs(t), n - 2))
        if p < best:
            best, last = p, k
    return min(1.0, len(ks) * best), last


def chart(series: Series) -> Chart:
    """The SPC figures of one characteristic (no flags: see :func:`chart_all`)."""
    x = np.asarray(series.values, dtype=float)
    n = len(x)
    mean = float(x.mean()) if n else math.nan
    sd = float(np.std(x, ddof=1)) if n >= 2 else math.nan
    cp, cpk, ci = _capability(x, series.low, series.high)
    mr = np.abs(np.diff(x))
    mr_bar = float(mr.mean()) if len(mr) else math.nan
    sigma = mr_bar / D2 if len(mr) else math.nan
    ucl, lcl = mean + 3 * sigma, mean - 3 * sigma
    beyond = tuple(s for s, v in zip(series.serials, x) if len(mr) and (v > ucl or v < lcl))
    u = np.asarray(series.u, dtype=float) if len(series.u) == n else np.zeros(n)
    p_point, where = _point_rule(x, u)
    p_step, last = _step_rule(x)
    at: tuple[str, ...]
    if p_point <= p_step:
        p, rule, at = p_point, "point", (series.serials[where],) if where >= 0 else ()
    else:
        p, rule, at = p_step, "step", tuple(series.serials[n - last:])
    return Chart(series, mean, sd, cp, cpk, ci, mean, sigma, ucl, lcl, D4 * mr_bar if len(mr) else math.nan,
                 beyond, min(1.0, 2 * p), rule, at)


def benjamini_hochberg(p: Sequence[float]) -> list[float]:
    """The Benjamini-Hochberg adjusted p-values (q-values) of `p`, in the same order."""
    m = len(p)
    if m == 0:
        return []
    order = np.argsort(np.asarray(p, dtype=float))
    ranked = np.asarray(p, dtype=float)[order] * m / np.arange(1, m + 1)
    adjusted = np.minimum.accumulate(ranked[::-1])[::-1]
    out = np.empty(m)
    out[order] = np.minimum(adjusted, 1.0)
    return [float(v) for v in out]


def chart_all(series: Sequence[Series], q: float = 0.05) -> list[Chart]:
    """Every characteristic's chart, flagged where its Benjamini-Hochberg q-value is at most `q`."""
    charts = [chart(s) for s in series]
    qs = benjamini_hochberg([c.p for c in charts])
    out = []
    for c, qv in zip(charts, qs):
        flags = (Flag(c.rule, c.rule_serials, c.p, qv),) if qv <= q and c.rule_serials else ()
        out.append(replace(c, flags=flags))
    return out
