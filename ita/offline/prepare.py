"""Offline preparation of a part for inspection (the seed's preprocessing).

Builds (or loads) the part and its specs, validates the specs against the part, tests
the arm's reach for every spec, loads and checks the knowledge bases, and reports what
it found.  Later stages (measurement knowledge base, sequence plan, MACROPs) are added
here as they are built.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable

from ita.part.summary import PartSummary


@dataclass(frozen=True)
class PrepareReport:
    """What `prepare` built and found."""

    part: PartSummary
    reach_counts: tuple[tuple[str, int], ...]
    reach_text: str
    kb_files: tuple[str, ...]
    kb_predicates: int
    kb_problems: tuple[str, ...]
    seconds: tuple[tuple[str, float], ...] = field(default=())

    @property
    def ok(self) -> bool:
        """True when the specs are valid and the knowledge bases are clean."""
        return not self.kb_problems

    def to_dict(self) -> dict[str, Any]:
        """A JSON-ready dict."""
        return {
            "part": self.part.to_dict(),
            "reach": dict(self.reach_counts),
            "knowledge_bases": {"files": list(self.kb_files), "predicates": self.kb_predicates,
                                "problems": list(self.kb_problems)},
            "seconds": dict(self.seconds),
            "ok": self.ok,
        }


def prepare(part_dir: Path | None, progress: Callable[[str], None] = lambda _msg: None) -> PrepareReport:
    """Prepare the part in `part_dir` (None: the built-in bulkhead) for inspection.

    Raises InputError (with file, line, field) when the part or its specs are bad.
    """
    from ita.logic.bridge import KnowledgeBase
    from ita.offline.reach import spec_reach, workcell_for
    from ita.part.store import load_part
    from ita.part.summary import summarize
    from ita.specs import service

    seconds: list[tuple[str, float]] = []

    def step(name: str, message: str, func: Callable[[], Any]) -> Any:
        progress(message)
        t0 = time.perf_counter()
        value = func()
        seconds.append((name, round(time.perf_counter() - t0, 3)))
        return value

    part = step("part", "building/loading the part", lambda: load_part(part_dir))
    step("specs", "validating the specs against the part", lambda: service.validate_file(part))
    specs = service.load(part)
    kb = step("knowledge_bases", "loading the knowledge bases", KnowledgeBase)
    diagnostics = step("kb_check", "checking the knowledge bases", kb.check)
    predicates = kb.list_predicates()
    cell = step("workcell", "loading the workcell", lambda: workcell_for(part.directory))
    reach = step("reach", "testing the arm's reach for every spec", lambda: spec_reach(specs, cell, kb))
    summary = summarize(part, specs, unreachable=reach.n_unreachable)
    return PrepareReport(
        part=summary,
        reach_counts=tuple((r.value, n) for r, n in reach.counts().items()),
        reach_text=reach.summary(),
        kb_files=tuple(str(p.name) for p in (*kb.engine_files, *kb.kb_files)),
        kb_predicates=len(predicates),
        kb_problems=tuple(str(d) for d in diagnostics),
        seconds=tuple(seconds),
    )
