"""Offline preparation of a part for inspection (the seed's preprocessing).

Builds (or loads) the part and its specs, validates the specs against the part, tests
the arm's reach for every spec, loads and checks the knowledge bases; then prepares the
inspection itself (:func:`prepare_inspection`): the sequence plan
(ita_home()/plans/<part>.json), the Measurement Knowledge Base (ita_home()/mkb/<part>.json)
and the MACROP store warmed by planning every measurement in sequence order
(ita_home()/macrops/<part>.pl), so that `ita inspect` starts at once.  It reports what
cannot be done and why (the Sequence Planner's cannot-be-done group, measurements the
Geometric Reasoner could not place, measurements without a plan).
"""

from __future__ import annotations

import functools
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ita.errors import InputError, ItaError, Location
from ita.executive.two_arms import arranged
from ita.geometry import MeasurementKB, build_mkb, load_mkb, mkb_digest, mkb_path, save_mkb
from ita.logic.bridge import KnowledgeBase
from ita.offline.master import ensure_master_calibration
from ita.offline.spec_reach import spec_reach
from ita.part import specfile
from ita.part.store import load_part
from ita.part.summary import PartSummary, summarize
from ita.planning import NoPlanError, OperationPlanner, WorldState, store_path
from ita.sequence.next_step import the_arm
from ita.sequence.allocate import Allocation
from ita.sequence.allocation_store import stored_allocation
from ita.sequence.partition import alternative_tools
from ita.sequence.plan import PlanningContext, SequencePlan, build_plan, planning_context, with_mkb
from ita.sequence.store import (
    apply_tool_marks,
    load_plan,
    load_tool_marks,
    plan_path,
    save_plan,
)

#: times the plan and the MKB are made again with what the MKB could not place
PLACEMENT_ROUNDS = 2


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
    inspection: InspectionPrep | None = None

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
            "inspection": None if self.inspection is None else self.inspection.to_dict(),
            "ok": self.ok,
        }


@dataclass(frozen=True)
class InspectionPrep:
    """What the inspection's preparation built or found current.

    plan/mkb: the stored sequence plan and MKB (``rebuilt``: made now, else reused);
    cannot: (spec id, reason) of every measurement that cannot be done; frames: SLRA
    frames the run will take (view groups) for `slra_specs` SLRA measurements; macrops:
    {"planned", "lookups", "hits", "learned", "no_plan"} of the warming pass.
    """

    plan_path: str
    plan_rebuilt: bool
    mkb_path: str
    mkb_rebuilt: bool
    groups: tuple[tuple[str, int], ...]
    slra_specs: int
    frames: int
    cannot: tuple[tuple[str, str], ...]
    macrops: dict[str, int]
    plan_total_s: float
    calibration: str = "the cell's (generated bulkheads)"

    def to_dict(self) -> dict[str, Any]:
        reasons: dict[str, int] = {}
        for _, r in self.cannot:
            reasons[r] = reasons.get(r, 0) + 1
        return {"plan": {"path": self.plan_path, "rebuilt": self.plan_rebuilt, "motion_s": round(self.plan_total_s, 1),
                         "groups": dict(self.groups)},
                "mkb": {"path": self.mkb_path, "rebuilt": self.mkb_rebuilt, "slra_specs": self.slra_specs,
                        "frames": self.frames},
                "cannot_be_done": {"count": len(self.cannot), "reasons": reasons,
                                   "specs": [{"id": i, "reason": r} for i, r in self.cannot]},
                "macrops": dict(self.macrops), "slra_calibration": self.calibration}

    def text(self) -> str:
        made = {True: "made now", False: "stored and current"}
        lines = [
            (f"sequence    {' + '.join(f'{t} {n}' for t, n in self.groups)} measurements, "
             f"{self.plan_total_s:.0f} s of arm motion (plan {made[self.plan_rebuilt]})"),
            (f"mkb         {self.slra_specs} SLRA measurements in {self.frames} frames "
             f"(MKB {made[self.mkb_rebuilt]})"),
            (f"macrops     {self.macrops.get('planned', 0)} plans: {self.macrops.get('hits', 0)} MACROP hits, "
             f"{self.macrops.get('learned', 0)} learned"),
            f"slra cal    {self.calibration}",
        ]
        lines.append(f"cannot      {len(self.cannot)} measurements cannot be done" + (":" if self.cannot else ""))
        lines += cannot_lines(self.cannot)
        return "\n".join(lines)


def cannot_lines(cannot: Any, indent: str = "  ", width: int = 92) -> list[str]:
    """The measurements that cannot be done, named, grouped by reason (most common first);
    `ita prepare` and `ita sequence show` print the same."""
    import textwrap

    by_reason: dict[str, list[str]] = {}
    for spec_id, reason in cannot:
        by_reason.setdefault(str(reason), []).append(str(spec_id))
    out = []
    for reason, ids in sorted(by_reason.items(), key=lambda kv: (-len(kv[1]), kv[0])):
        out.append(f"{indent}{len(ids):>5}  {reason}:")
        out += textwrap.wrap(", ".join(sorted(ids)), width=width, initial_indent=indent + "       ",
                             subsequent_indent=indent + "       ")
    return out


def stored_cannot(plan: Any, part_name: str) -> list[tuple[str, str]]:
    """What cannot be done by the stored plan and MKB of a part: the plan's cannot-be-done
    group (tool rules) and the measurements the MKB could not place (as `prepare` says)."""
    cannot = list(plan.cannot)
    mkb = load_mkb(part_name)
    if mkb is not None:
        seen = {i for i, _ in cannot}
        cannot += [(e.spec_id, e.status) for e in mkb.problems() if e.spec_id not in seen]
    return cannot


def prepare_inspection(ctx: Any, part: Any, *, progress: Callable[[str], None] = lambda _m: None,
                       force: bool = False, warm: bool = True, calibrate: bool = True
                       ) -> tuple[Any, Any, InspectionPrep]:
    """Make (or reuse, when current) the sequence plan and the MKB of the part of
    planning context `ctx`, and warm the MACROP store.  Returns (plan, mkb, report).

    The plan is reused when its specs digest is current; the MKB when its digest (specs
    and workcell) is.  `force` remakes both.  `calibrate`: a user part's SLRA calibration
    on its master is made when missing or stale (ita.offline.master).
    """
    from dataclasses import replace as _replace

    plan = None
    if not force:
        try:
            plan = load_plan(ctx.part_name)
        except ItaError:
            plan = None
        if plan is not None and plan.specs_digest != ctx.specs_digest:
            plan = None
    plan_rebuilt = plan is None
    if plan is None:
        progress("making the sequence plan")
        plan = build_plan(ctx)
        save_plan(plan)
    elif plan.handed_out:
        plan = _replace(plan, handed_out=())
    digest = mkb_digest(ctx.specs_digest, ctx.workcell)
    mkb = None if force else load_mkb(ctx.part_name, digest)
    mkb_rebuilt = mkb is None

    def make_mkb(plan: Any, reuse: Any = None) -> Any:
        tools = {i: g.tool for g in plan.groups for i in g.order}
        others = alternative_tools(ctx.kb, ctx.workcell, ctx.specs, ctx.feature_kinds, tools)
        made = build_mkb(ctx.workcell, part, ctx.specs, tools, part_name=ctx.part_name, digest=digest,
                         alternatives=others, reuse=reuse)
        save_mkb(made)
        return made

    if mkb is None:
        progress("building the measurement knowledge base")
        mkb = make_mkb(plan)
    # What the MKB could not place with the plan's tool goes back to the tool rules as
    # placed/2 facts (kb/tools.pl): a flange wall the probe cannot touch moves to the bent
    # probe.  The plan and the MKB are made again while that moves a measurement.
    for _ in range(PLACEMENT_ROUNDS):
        if not mkb.problems():
            break
        placed = with_mkb(ctx, mkb)
        replanned = build_plan(placed, note="made again with the MKB's placements")
        if _assignment(replanned) == _assignment(plan) and replanned.cannot == plan.cannot:
            break
        progress(f"{len(mkb.problems())} measurements the MKB could not place: planning again")
        plan, plan_rebuilt, mkb_rebuilt = replanned, True, True
        save_plan(plan)
        mkb = make_mkb(plan, reuse=mkb)
    cannot = list(plan.cannot) + [(e.spec_id, e.status) for e in mkb.problems()]
    calibration = ensure_master_calibration(part, ctx.workcell, ctx.part_name, progress, force, mkb=mkb) \
        if calibrate else "not checked"
    macrops = {"planned": 0, "lookups": 0, "hits": 0, "learned": 0, "no_plan": 0}
    if warm:
        progress("warming the MACROP store")
        macrops, no_plan = warm_macrops(ctx, plan, mkb)
        cannot += [(i, "no_plan") for i in no_plan]
    slra = [e for e in mkb.entries.values() if e.ok and e.group is not None]
    report = InspectionPrep(
        plan_path=str(plan_path(ctx.part_name)), plan_rebuilt=plan_rebuilt, mkb_path=str(mkb_path(ctx.part_name)),
        mkb_rebuilt=mkb_rebuilt, groups=tuple((g.tool, len(g.order)) for g in plan.groups),
        slra_specs=len(slra), frames=mkb.frames_needed(), cannot=tuple(cannot), macrops=macrops,
        plan_total_s=plan.total_s, calibration=calibration)
    return plan, mkb, report


def _assignment(plan: Any) -> dict[str, str]:
    """Spec id -> the tool a sequence plan takes it with."""
    return {i: g.tool for g in plan.groups for i in g.order}


def warm_macrops(ctx: Any, plan: Any, mkb: Any) -> tuple[dict[str, int], list[str]]:
    """Plan every placed measurement in sequence order (each from the state the one before
    leaves), so the MACROP store holds what the run will look up.  Returns the counts and
    the ids that have no plan."""
    state = WorldState(arm=the_arm(ctx.kb))
    planned = learned = 0
    no_plan: list[str] = []
    with OperationPlanner(ctx.kb, store_path(ctx.part_name)) as planner:
        before = planner.counts()
        for group in plan.groups:
            for spec_id in group.order:
                entry = mkb.entries.get(spec_id)
                if entry is None or not entry.ok:
                    continue
                try:
                    op = planner.plan_measurement(ctx.spec(spec_id), state, group.tool)
                except NoPlanError:
                    no_plan.append(spec_id)
                    continue
                planned += 1
                learned += not op.matched
                state = op.final_state
        after = planner.counts()
    return {"planned": planned, "lookups": after.lookups - before.lookups, "hits": after.hits - before.hits,
            "learned": learned, "no_plan": len(no_plan)}, no_plan


def prepare(part_dir: Path | None, progress: Callable[[str], None] = lambda _msg: None,
            *, inspection: bool = True, force: bool = False, arm: str | None = None) -> PrepareReport:
    """Prepare the part in `part_dir` (None: the built-in bulkhead) for inspection; by the
    cell's arm `arm` (default its first: ita.sequence.plan.planning_context).

    Raises InputError (with file, line, field) when the part or its specs are bad.
    """
    seconds: list[tuple[str, float]] = []

    def step(name: str, message: str, func: Callable[[], Any]) -> Any:
        progress(message)
        t0 = time.perf_counter()
        value = func()
        seconds.append((name, round(time.perf_counter() - t0, 3)))
        return value

    part = step("part", "building/loading the part", lambda: load_part(part_dir))
    step("specs", "validating the specs against the part", lambda: specfile.validate_file(part))
    specfile.check_measurable(part)      # a spec whose feature is not there: cannot be done; none measurable: refused
    specs = specfile.load(part)
    kb = step("knowledge_bases", "loading the knowledge bases", KnowledgeBase)
    diagnostics = step("kb_check", "checking the knowledge bases", kb.check)
    predicates = kb.list_predicates()
    cell = step("workcell", "loading the workcell",
                lambda: planning_context(part_dir, kb=kb, part=part, use_mkb=False, arm=arm).workcell)
    reach = step("reach", "testing the arm's reach for every spec", lambda: spec_reach(specs, cell, kb))
    summary = summarize(part, specs, unreachable=reach.n_unreachable)
    prep = None
    if inspection and not diagnostics:
        apply_tool_marks(kb, load_tool_marks())
        ctx = planning_context(part_dir, kb=kb, part=part, arm=arm)
        _, _, prep = step("inspection", "preparing the inspection (sequence plan, MKB, MACROPs)",
                          lambda: prepare_inspection(ctx, part, progress=progress, force=force))
    return PrepareReport(
        part=summary,
        reach_counts=tuple((r.value, n) for r, n in reach.counts().items()),
        reach_text=reach.summary(),
        kb_files=tuple(str(p.name) for p in (*kb.engine_files, *kb.kb_files)),
        kb_predicates=len(predicates),
        kb_problems=tuple(str(d) for d in diagnostics),
        seconds=tuple(seconds),
        inspection=prep,
    )


def prepared_arms(part_dir: Path | None, kb: KnowledgeBase, part: Any,
                  progress: Callable[[str], None] = lambda _m: None) -> tuple[Any, Any, dict[str, Any]]:
    """For a cell with two arms: the first arm's planning context (with its MKB) and
    sequence plan, and each arm's MKB (arm name -> MKB), each made as that arm works the
    cell (prepared, or reused when current; ita.sequence.plan.planning_context's ``arm``):
    what ita.sequence.allocate needs to know which arm can place which measurement."""
    first: tuple[Any, Any] | None = None
    mkbs: dict[str, Any] = {}
    for arm in planning_context(part_dir, kb=kb, part=part, use_mkb=False).workcell.arms():
        ctx = planning_context(part_dir, kb=kb, part=part, arm=arm.name)
        progress(f"preparing the cell as {arm.name} works it (sequence plan, MKB)")
        plan, mkb, _ = prepare_inspection(ctx, part, progress=progress, warm=False)
        mkbs[arm.name] = mkb
        if first is None:
            first = (with_mkb(ctx, mkb), plan)
    assert first is not None
    return first[0], first[1], mkbs


def prepare_two_arms(part_dir: Path | None, progress: Callable[[str], None] = lambda _msg: None,
                     *, force: bool = False) -> tuple[list[PrepareReport], Any | None, bool]:
    """`ita prepare --arms 2`: prepare the part as each of the cell's two arms works it
    (:func:`prepare`: its sequence plan, MKB and MACROPs) and store the allocation between
    them (ita.sequence.allocation_store), made as `ita inspect --arms 2` makes it, so that
    the two-arm run starts at once.  Each arm's report, the allocation (None when a report is
    not ok), and whether a stored one was current.  InputError when the workcell names one arm."""
    kb = KnowledgeBase()
    apply_tool_marks(kb, load_tool_marks())
    part = load_part(part_dir)
    cell = planning_context(part_dir, kb=kb, part=part, use_mkb=False).workcell
    arms = [a.name for a in cell.arms()]
    if len(arms) != 2:
        raise InputError([(Location(str(cell.source)), "--arms 2: this workcell names one arm; a second is a "
                                                       "[robot_b] table in its workcell.toml")])
    reports = []
    for arm in arms:
        progress(f"preparing the part as {arm} works it")
        reports.append(prepare(part_dir, progress, force=force, arm=arm))
    if not all(r.ok for r in reports):
        return reports, None, False
    ctx, plan, mkbs = prepared_arms(part_dir, kb, part, progress=progress)
    progress("allocating the measurements between the arms")
    allocation, kept = two_arm_allocation(ctx, plan, mkbs)
    return reports, allocation, kept


def two_arm_allocation(ctx: PlanningContext, plan: SequencePlan,
                       mkbs: Mapping[str, MeasurementKB]) -> tuple[Allocation, bool]:
    """The two-arm allocation of the prepared part (ita.sequence.allocate), its tours
    arranged in the order of its best coordinated schedule (ita.executive.two_arms.arranged:
    the order the arms' runs follow); the stored one when current, and whether it was."""
    return stored_allocation(ctx, plan, mkbs=mkbs, arrange=functools.partial(arranged, ctx))
