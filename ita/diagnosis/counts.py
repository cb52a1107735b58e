"""How often each exception and each cause has occurred, learned across runs.

The counts live beside the world model's tool marks, ``ita_home()/world/fault_counts.json``
(``{"causes": {name: n}, "exceptions": {name: n}}``), inspectable and resettable
(``ita diagnosis counts``, ``ita diagnosis reset``).  The engine adds them to the stated
priors of kb/faults.pl, so what the cell has seen changes which test it runs first.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path

from ita.errors import InputError, Location
from ita.files.atomic import write_json_atomic
from ita.paths import ita_home

__all__ = ["FaultCounts", "counts_path"]


def counts_path() -> Path:
    """Where the learned counts are kept."""
    return ita_home() / "world" / "fault_counts.json"


@dataclass(frozen=True)
class FaultCounts:
    """Learned counts: cause name -> n, exception name -> n."""

    causes: dict[str, int] = field(default_factory=dict)
    exceptions: dict[str, int] = field(default_factory=dict)

    @classmethod
    def load(cls, path: Path | None = None) -> FaultCounts:
        """The stored counts (empty when there are none); InputError for a damaged file."""
        path = path or counts_path()
        if not path.is_file():
            return cls()
        try:
            data = json.loads(path.read_text(encoding="utf-8"))
            causes = {str(k): int(v) for k, v in data.get("causes", {}).items()}
            exceptions = {str(k): int(v) for k, v in data.get("exceptions", {}).items()}
        except (ValueError, TypeError, AttributeError) as exc:
            raise InputError([(Location(str(path)), f"damaged fault counts: {exc}")]) from None
        return cls(causes, exceptions)

    def counted(self, exception: str, cause: str | None) -> FaultCounts:
        """These counts with one more `exception` and, when isolated, one more `cause`."""
        causes = dict(self.causes)
        if cause is not None:
            causes[cause] = causes.get(cause, 0) + 1
        exceptions = dict(self.exceptions)
        exceptions[exception] = exceptions.get(exception, 0) + 1
        return FaultCounts(causes, exceptions)

    @classmethod
    def record(cls, exception: str, cause: str | None, path: Path | None = None) -> FaultCounts:
        """Add one diagnosis to the stored counts, read-modify-write under a file lock (so
        runs side by side lose none); the counts now."""
        import fcntl

        path = path or counts_path()
        path.parent.mkdir(parents=True, exist_ok=True)
        with open(path.with_suffix(".lock"), "a+") as lock:
            fcntl.flock(lock, fcntl.LOCK_EX)
            try:
                now = cls.load(path).counted(exception, cause)
                now.save(path)
            finally:
                fcntl.flock(lock, fcntl.LOCK_UN)
        return now

    def save(self, path: Path | None = None) -> Path:
        """Store the counts atomically."""
        return write_json_atomic(path or counts_path(), {"causes": dict(sorted(self.causes.items())),
                                                         "exceptions": dict(sorted(self.exceptions.items()))})
