"""ISO 14253-1 conformance decisions: a measured value, its expanded uncertainty, a tolerance.

Conformance is proven only inside the tolerance zone shrunk by the expanded uncertainty
U on both sides; nonconformance is proven only outside the zone grown by U; in between
the measurement cannot tell, and the result says so (UNCERTAIN).  The boundaries belong
to the proven sides: a value exactly at low + U conforms, a value exactly at low - U is
uncertain.  When U is half the band or more, nothing can be proven to conform.

This is the project's canonical decision rule; the archive stores its spelling.
"""

from __future__ import annotations

import math
from enum import Enum


class Decision(str, Enum):
    """ISO 14253-1 decision on a measured value.  The value is the spelling in the archive."""

    CONFORMS = "conforms"
    DOES_NOT_CONFORM = "does_not_conform"
    UNCERTAIN = "uncertain"

    @property
    def label(self) -> str:
        """How a person reads it: "conforms", "does not conform", "uncertain"."""
        return self.value.replace("_", " ")


def decide(value: float, expanded_uncertainty: float, low: float, high: float, *,
           bounded_below: bool = False) -> Decision:
    """Decide on `value` (mm) with expanded uncertainty U (mm) against [low, high] (mm).

    CONFORMS when low + U <= value <= high - U; DOES_NOT_CONFORM when value < low - U or
    value > high + U; UNCERTAIN otherwise.  bounded_below: the low limit is the
    quantity's natural bound, not a specification limit (a true position is a zone's
    diameter, 0 at best; ISO 14253-1 applies its upper limit only): only the high limit
    is tested.  Raises ValueError for a non-finite value or
    uncertainty, a negative uncertainty, or low > high.
    """
    for name, x in (("value", value), ("expanded uncertainty", expanded_uncertainty),
                    ("low limit", low), ("high limit", high)):
        if not isinstance(x, (int, float)) or not math.isfinite(x):
            raise ValueError(f"{name} must be a finite number, got {x!r}")
    if expanded_uncertainty < 0:
        raise ValueError(f"expanded uncertainty must be >= 0, got {expanded_uncertainty}")
    if low > high:
        raise ValueError(f"low limit {low} is above high limit {high}")
    u = expanded_uncertainty
    if bounded_below:
        return Decision.CONFORMS if value <= high - u else \
            Decision.DOES_NOT_CONFORM if value > high + u else Decision.UNCERTAIN
    if low + u <= value <= high - u:
        return Decision.CONFORMS
    if value < low - u or value > high + u:
        return Decision.DOES_NOT_CONFORM
    return Decision.UNCERTAIN
