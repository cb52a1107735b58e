"""What a run's serial number or operator's name may be, wherever one is given:
`ita inspect --serial/--operator` and the System Monitor's form.

1 to LABEL_MAX printable characters once trimmed: no line breaks or control characters,
which would forge lines in a table, a CSV or a terminal.
"""

from __future__ import annotations

LABEL_MAX = 64
LABEL_RULE = f"1 to {LABEL_MAX} printable characters, no line breaks or control characters"


def label_problem(text: str) -> str:
    """Why `text` (trimmed) is not a label ("" when it is one)."""
    stripped = text.strip()
    return "" if 1 <= len(stripped) <= LABEL_MAX and stripped.isprintable() else LABEL_RULE
