"""Crossed gauge R&R by the ANOVA method (AIAG MSA, 4th ed.), and a binomial upper bound.

    g = gauge_rr(values)        # values[(item, appraiser, trial)] = measurement
    g.percent_grr, g.ndc, g.ev, g.av, g.pv

Two-way crossed random-effects ANOVA of item x appraiser with replicates: sums of squares
for items, appraisers, their interaction and the replicates (equipment).  When the
interaction's F test has a p-value above :data:`INTERACTION_ALPHA` it is pooled into the
equipment term, as the AIAG manual and Minitab do.  Variance components from the mean
squares (negative estimates set to 0):

    repeatability    EV^2 = MS_e
    appraiser        sigma_o^2 = (MS_o - MS_io) / (n r)      (MS_io: MS_e when pooled)
    interaction      sigma_io^2 = (MS_io - MS_e) / r         (0 when pooled)
    reproducibility  AV^2 = sigma_o^2 + sigma_io^2
    part             PV^2 = (MS_p - MS_io) / (k r)
    GRR^2 = EV^2 + AV^2,  TV^2 = GRR^2 + PV^2,  %GRR = 100 GRR / TV,
    ndc = floor(1.41 PV / GRR),  %GRR of the tolerance = 100 x 6 GRR / (upper - lower)

n items, k appraisers, r trials; the design must be balanced (every item measured r times
by every appraiser).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import asdict, dataclass
from typing import Any, Hashable

import numpy as np
from scipy import stats

__all__ = ["INTERACTION_ALPHA", "GaugeRR", "gauge_rr", "upper_bound"]

#: the interaction is pooled into repeatability when its p-value is above this
INTERACTION_ALPHA = 0.05


@dataclass(frozen=True)
class GaugeRR:
    """A crossed gauge R&R study's ANOVA and figures (standard deviations, not 6 sigma)."""

    items: int
    appraisers: int
    trials: int
    ss: dict[str, float]
    df: dict[str, int]
    ms: dict[str, float]
    interaction_p: float
    pooled: bool
    ev: float
    av: float
    interaction: float
    grr: float
    pv: float
    tv: float
    percent_grr: float
    ndc: int
    percent_tolerance: float | None

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)


def gauge_rr(values: Mapping[tuple[Hashable, Hashable, Hashable], float], tolerance: float | None = None
             ) -> GaugeRR:
    """The study of `values` keyed (item, appraiser, trial); tolerance: the width of the
    tolerance zone for %GRR of the tolerance.  ValueError when unbalanced or too small."""
    items = sorted({k[0] for k in values}, key=str)
    apprs = sorted({k[1] for k in values}, key=str)
    trials = sorted({k[2] for k in values}, key=str)
    n, k, r = len(items), len(apprs), len(trials)
    if n < 2 or k < 2 or r < 2:
        raise ValueError(f"a crossed study needs 2 or more items, appraisers and trials (got {n}, {k}, {r})")
    x = np.full((n, k, r), np.nan)
    ii, aa, tt = ({v: i for i, v in enumerate(s)} for s in (items, apprs, trials))
    for (i, a, t), v in values.items():
        x[ii[i], aa[a], tt[t]] = float(v)
    if not np.isfinite(x).all():
        raise ValueError("unbalanced study: every item must be measured by every appraiser in every trial")
    grand = x.mean()
    m_i, m_a, m_ia = x.mean(axis=(1, 2)), x.mean(axis=(0, 2)), x.mean(axis=2)
    ss = {"part": k * r * float(((m_i - grand) ** 2).sum()),
          "appraiser": n * r * float(((m_a - grand) ** 2).sum()),
          "interaction": r * float(((m_ia - m_i[:, None] - m_a[None, :] + grand) ** 2).sum()),
          "equipment": float(((x - m_ia[..., None]) ** 2).sum())}
    ss["total"] = float(((x - grand) ** 2).sum())
    df = {"part": n - 1, "appraiser": k - 1, "interaction": (n - 1) * (k - 1), "equipment": n * k * (r - 1),
          "total": n * k * r - 1}
    ms = {s: ss[s] / df[s] for s in ("part", "appraiser", "interaction", "equipment")}
    if ms["equipment"] > 0:
        f_int = ms["interaction"] / ms["equipment"]
        p_int = float(stats.f.sf(f_int, df["interaction"], df["equipment"]))
    else:
        p_int = 0.0 if ms["interaction"] > 0 else 1.0
    pooled = p_int > INTERACTION_ALPHA
    if pooled:
        ms_e = (ss["interaction"] + ss["equipment"]) / (df["interaction"] + df["equipment"])
        ms_io = ms_e
        var_io = 0.0
    else:
        ms_e = ms["equipment"]
        ms_io = ms["interaction"]
        var_io = max(0.0, (ms_io - ms_e) / r)
    var_e = ms_e
    var_o = max(0.0, (ms["appraiser"] - ms_io) / (n * r))
    var_p = max(0.0, (ms["part"] - ms_io) / (k * r))
    grr = math.sqrt(var_e + var_o + var_io)
    tv = math.sqrt(grr ** 2 + var_p)
    pv = math.sqrt(var_p)
    ndc = int(math.floor(1.41 * pv / grr)) if grr > 0 else 0
    pct = 100.0 * grr / tv if tv > 0 else float("nan")
    pct_tol = 100.0 * 6.0 * grr / tolerance if tolerance else None
    return GaugeRR(n, k, r, ss, df, ms, p_int, pooled, math.sqrt(var_e), math.sqrt(var_o + var_io), math.sqrt(var_io),
                   grr, pv, tv, pct, ndc, pct_tol)


def upper_bound(successes: int, trials: int, confidence: float = 0.95) -> float:
    """The one-sided upper confidence bound of a proportion (Clopper-Pearson, exact):
    with 0 of n it is 1 - (1 - confidence)^(1/n), about 3/n at 95 %."""
    if trials <= 0:
        return 1.0
    if successes >= trials:
        return 1.0
    return float(stats.beta.ppf(confidence, successes + 1, trials - successes))
