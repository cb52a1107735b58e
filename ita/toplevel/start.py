"""Registering a new inspection run in the archive, before the Top Level runs it.

    run_id = start_run(session, archive, limit=12)        # the first 12 of the sequence plan
"""

from __future__ import annotations

from collections.abc import Collection, Mapping
from typing import TYPE_CHECKING

from ita.archive import Outcome
from ita.archive.decision import Decision
from ita.logic.json_value import JsonValue
from ita.part.model import Hole, HoleRole

if TYPE_CHECKING:
    from ita.archive import Archive
    from ita.task.session import Session

__all__ = ["start_run"]


def unproven(archive: Archive, run_id: str) -> list[str]:
    """The measurements of run `run_id` not proven to conform: measured uncertain or not
    conforming, or not done (those that cannot be done are not tried again)."""
    return [r.spec_id for r in archive.results(run_id)
            if r.outcome is Outcome.NOT_DONE
            or (r.outcome is Outcome.MEASURED and r.decision in (Decision.UNCERTAIN, Decision.DOES_NOT_CONFORM))]


def tooling_specs(session: Session) -> list[str]:
    """The measurements of the part's tooling holes (the cell's reference artifacts on
    the part: its datums in the fixture)."""
    tooling = {f.id for f in session.part.features if isinstance(f, Hole) and f.role is HoleRole.TOOLING}
    return [s.id for s in session.ctx.specs if s.feature in tooling]


def start_run(session: Session, archive: Archive, *, limit: int | None = None, run_id: str | None = None,
              settings: Mapping[str, JsonValue] | None = None, specs: Collection[str] | None = None) -> str:
    """Register a new run of the session's part in `archive`: the measurements it sets out
    to do are the first `limit` of the sequence plan (all by default), plus those the plan
    cannot do (recorded as such); with `specs`, those of them alone (in the plan's order).
    run_id: the id to give it (the System Monitor names the runs it starts); default a
    fresh one.  `settings` adds to what the run records (the fault injection).  Returns
    the run id."""
    plan = session.plan
    order = [i for g in plan.groups for i in g.order]
    todo = order[:limit] if limit is not None else order
    if limit is None:
        todo += [i for i, _ in plan.cannot]
    if specs is not None:
        todo = [i for i in todo if i in specs]
    recorded = {"simulated": True, "simulated_part": session.simulated, "limit": limit, "part_arg": session.part_arg,
                "specs": todo, "mkb_digest": session.mkb.digest, "sequence_total_s": plan.total_s,
                **(settings or {})}
    return archive.create_run(session.part.name, session.part.directory, seed=session.seed,
                              settings=recorded, total=len(todo), run_id=run_id)
