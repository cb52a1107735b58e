"""Registering a new inspection run in the archive, before the Top Level runs it.

    run_id = start_run(session, archive, limit=12)        # the first 12 of the sequence plan
"""

from __future__ import annotations

import re
from collections.abc import Collection, Mapping
from typing import TYPE_CHECKING

from ita.archive import Outcome
from ita.archive.decision import Decision
from ita.logic.json_value import JsonValue
from ita.logic.world import WorldModel
from ita.part.model import Hole, HoleRole
from ita.vision.scan import frames_for

if TYPE_CHECKING:
    from ita.archive import Archive
    from ita.task.session import Session

__all__ = ["earlier_results", "start_run", "tooling_specs", "unproven"]

#: the largest term of an uncertain result's budget, as its reason names it
_LARGEST = re.compile(r"largest term: (.+?) \(u [0-9.]+ mm\)")


def unproven(archive: Archive, run_id: str) -> list[str]:
    """The measurements of run `run_id` not proven to conform: measured uncertain or not
    conforming, or not done (those that cannot be done are not tried again)."""
    return [r.spec_id for r in archive.results(run_id)
            if r.outcome is Outcome.NOT_DONE
            or (r.outcome is Outcome.MEASURED and r.decision in (Decision.UNCERTAIN, Decision.DOES_NOT_CONFORM))]


def earlier_results(archive: Archive, run_id: str, session: Session) -> dict[str, JsonValue]:
    """What a reinspection's plan needs of run `run_id`'s unproven results (kb/tasks.pl
    better_way/3), per spec id: its decision (or outcome), the type of the tool that
    took it, its kind, the largest term of its uncertainty budget (``none`` where it
    has none: not done, does not conform) and the frames the SLRA could average for it."""
    world = WorldModel(session.kb)
    tool_types = {t: world.tool_type(t) for t in world.tools()}
    wanted = set(unproven(archive, run_id))
    out: dict[str, JsonValue] = {}
    for r in archive.results(run_id):
        spec = session.specs.get(r.spec_id)
        if r.spec_id not in wanted or spec is None:
            continue
        largest = "none"
        found = _LARGEST.search(r.reason or "") if r.decision is Decision.UNCERTAIN else None
        if found is not None:
            largest = found.group(1)
        elif r.decision is Decision.UNCERTAIN:     # a position whose datum is the pose: its frames' numbers
            numbers = archive.details(run_id, r.spec_id).get("vision", {}).get("numbers", {})
            if isinstance(numbers, dict) and "u_random" in numbers:
                largest = ("arm pose and rim fit" if float(numbers["u_random"]) >= float(numbers["u_systematic"])
                           else "edge model")
        tool_type = tool_types.get(r.tool or "", "none")
        frames = frames_for(spec, session.slra.vctx).count if tool_type == "slra_tool" else 1
        out[r.spec_id] = {"decision": (r.decision.value if r.decision is not None else r.outcome.value),
                          "tool_type": tool_type, "kind": spec.kind.value, "largest": largest, "frames": frames}
    return out


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
