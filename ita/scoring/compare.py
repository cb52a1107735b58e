"""Score a run's results against true values: false accepts and rejects, measurement errors.

Pure: takes the results and a mapping spec id -> true value (mm); it neither knows nor
reads where true values come from (see `ita.scoring.true_values`).

- false accept: decided CONFORMS, but the true value is outside [low, high];
- false reject: decided DOES_NOT_CONFORM, but the true value is inside;
- missed: truly outside, but not measured or left UNCERTAIN (not a wrong decision, but a
  nonconformity the run did not prove);
- error = measured - true; normalized error = error / U.  With honest uncertainties
  about 95 % of |error| fall within U (k = 2).
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from typing import Any

CONFORMS = "conforms"
DOES_NOT_CONFORM = "does_not_conform"
UNCERTAIN = "uncertain"


@dataclass(frozen=True)
class ScoredResult:
    """One result beside its true value.  status: the decision, or the outcome if unmeasured."""

    spec_id: str
    status: str
    value: float | None
    true_value: float
    expanded_u: float | None
    truly_conforms: bool

    @property
    def error(self) -> float | None:
        return None if self.value is None else self.value - self.true_value


@dataclass(frozen=True)
class Scoring:
    """The comparison of a run with true values.

    confusion: (status, truly_conforms) -> count; false_accepts, false_rejects, missed:
    spec ids; errors: (measured - true) per measured spec (mm); within_u: fraction of
    measured specs with |error| <= U; unscored: result spec ids without a true value.
    """

    scored: tuple[ScoredResult, ...]
    confusion: dict[tuple[str, bool], int]
    false_accepts: tuple[str, ...]
    false_rejects: tuple[str, ...]
    missed: tuple[str, ...]
    unscored: tuple[str, ...]

    @property
    def errors(self) -> list[float]:
        return [s.error for s in self.scored if s.error is not None]

    @property
    def normalized_errors(self) -> list[float]:
        return [s.error / s.expanded_u for s in self.scored
                if s.error is not None and s.expanded_u not in (None, 0.0)]

    def error_stats(self) -> dict[str, float]:
        """n, mean, std (sample), rms, max_abs of the errors (mm), and within_u (fraction)."""
        e = self.errors
        n = len(e)
        if n == 0:
            return {"n": 0, "mean": math.nan, "std": math.nan, "rms": math.nan, "max_abs": math.nan,
                    "within_u": math.nan}
        mean = sum(e) / n
        std = math.sqrt(sum((x - mean) ** 2 for x in e) / (n - 1)) if n > 1 else 0.0
        measured = [(s.error, s.expanded_u) for s in self.scored if s.error is not None and s.expanded_u is not None]
        within = sum(abs(err) <= big_u for err, big_u in measured) / len(measured) if measured else math.nan
        return {"n": n, "mean": mean, "std": std, "rms": math.sqrt(sum(x * x for x in e) / n),
                "max_abs": max(abs(x) for x in e), "within_u": within}


def _status(r: Any) -> str:
    d = getattr(r, "decision", None)
    if d is not None:
        return getattr(d, "value", d)
    o = getattr(r, "outcome", "not_done")
    return getattr(o, "value", o)


def compare(results: Iterable[Any], true_values: Mapping[str, float]) -> Scoring:
    """Score `results` (objects with spec_id, decision, outcome, value, U, low_limit,
    high_limit, like the archive's StoredResult) against `true_values` (spec id -> mm)."""
    scored: list[ScoredResult] = []
    unscored: list[str] = []
    confusion: dict[tuple[str, bool], int] = {}
    fa: list[str] = []
    fr: list[str] = []
    missed: list[str] = []
    for r in results:
        true = true_values.get(r.spec_id)
        if true is None or not math.isfinite(true):
            unscored.append(r.spec_id)
            continue
        inside = r.low_limit <= true <= r.high_limit
        status = _status(r)
        s = ScoredResult(r.spec_id, status, r.value, float(true), r.U, inside)
        scored.append(s)
        confusion[(status, inside)] = confusion.get((status, inside), 0) + 1
        if status == CONFORMS and not inside:
            fa.append(r.spec_id)
        elif status == DOES_NOT_CONFORM and inside:
            fr.append(r.spec_id)
        elif status != CONFORMS and status != DOES_NOT_CONFORM and not inside:
            missed.append(r.spec_id)
    return Scoring(tuple(scored), confusion, tuple(fa), tuple(fr), tuple(missed), tuple(unscored))
