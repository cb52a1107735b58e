"""The range of a seed, wherever one is given: `--seed`, a part file's `part.seed`, a
campaign's part and appraiser seeds.

Seeds feed numpy's generators (any non-negative integer) and are stored in SQLite's
INTEGER columns (signed 64-bit): 0 to 2^63 - 1 suits both, and is what the System
Monitor's form takes too.
"""

from __future__ import annotations

SEED_MIN = 0
SEED_MAX = 2**63 - 1


def seed_problem(value: object) -> str:
    """Why `value` is not a seed ("" when it is one)."""
    if isinstance(value, bool) or not isinstance(value, int):
        return f"a seed is an integer from {SEED_MIN} to {SEED_MAX}, got {value!r}"
    if not SEED_MIN <= value <= SEED_MAX:
        return f"a seed is an integer from {SEED_MIN} to {SEED_MAX}, got {value}"
    return ""
