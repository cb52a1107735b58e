"""Build the whole sequence plan: partition by tool, order each group, order the groups.

    ctx = planning_context()                 # the built-in bulkhead, its workcell, the KB
    plan = build_plan(ctx)                   # SequencePlan (frozen), ~3 s for 1000 specs
    plan.groups[0].order                     # spec ids in visiting order
    plan.total_s                             # seconds of arm motion, tool changes included

Each tool group is a closed tour that starts at the tool's rack slot (pick it up), visits
every measurement of the group and returns to the slot (put it back), solved with
ita.sequence.tour.solve_tour.  Groups are visited one after the other, one visit to the
rack per tool: the tool changes are as few as the groups (one fewer when the arm already
holds the first group's tool), and the group order is the one with the least time at the
rack (tool changes, see ita.sequence.cost.rack_seconds), the group of the tool in hand
first: the one the arm holds, else the SLRA the run registers the part with before it
measures (:func:`tool_at_start`; measuring its group first saves a trip to the rack).

COST MODEL: pluggable (:class:`ita.sequence.cost.CostModel`, by name in
:data:`COST_MODELS`).  The default, :data:`MOTION_TIME_COST`, is the arm's joint-space
motion time between one inverse-kinematics configuration per measurement (chosen before
the ordering), with the tool changes at the rack; its facts function
(:func:`ita.sequence.cost.pose_facts`) sends a measurement with no configuration to
cannot-be-done as ``no_pose``.  :data:`INTERIM_COST` (straight-line tool-point distance
over the top TCP speed, labelled an estimate) stays available for comparisons.
"""

from __future__ import annotations

import hashlib
import itertools
import time
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field, replace
from datetime import UTC, datetime
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from ita.errors import InputError, Location
from ita.geometry import load_mkb, mkb_digest
from ita.logic.bridge import KnowledgeBase
from ita.logic.terms import Term
from ita.logic.world import WorldModel
from ita.part.store import load_part, part_key
from ita.sequence.cost import (
    COST_MODELS,
    INTERIM_COST,
    MOTION_TIME_COST,
    CostModel,
    PlacedFacts,
    euclidean_slot_seconds,
    euclidean_tcp_seconds,
    pose_facts,
    slot_position,
    tool_points_world,
)
from ita.sequence.partition import (
    FactsFunction,
    Partition,
    Selection,
    feature_kinds_of,
    partition_specs,
    select_tools,
)
from ita.sequence.tour import solve_tour, tour_cost
from ita.specs.io import read_specs
from ita.specs.model import MeasurementSpec
from ita.workcell import workcell_for

if TYPE_CHECKING:
    from ita.geometry.mkb import MeasurementKB
    from ita.logic.bridge import KnowledgeBase
    from ita.part.model import Part
    from ita.workcell.model import Workcell

PLAN_VERSION = 1


# -- the plan --------------------------------------------------------------------------

@dataclass(frozen=True)
class PlannedGroup:
    """One tool's measurements in visiting order.

    order: spec ids; cost_s: seconds of the closed tour rack slot -> specs -> rack slot
    under the plan's cost model; rules: (rule, count) of the rules that chose the tool.
    """

    tool: str
    tool_class: str
    order: tuple[str, ...]
    cost_s: float
    rules: tuple[tuple[str, int], ...] = ()


@dataclass(frozen=True)
class SequencePlan:
    """A stored sequence plan and its progress.

    groups: in execution order; done: ids done before the plan was (re)made; cannot:
    (id, reason); transfer_s: seconds at the rack outside the tours (under the motion-time
    model: every pick-up, put-down and move between slots, see
    ita.sequence.cost.rack_seconds); tool_changes: tool pick-ups;
    tool_state: tool -> {"condition", "location"} the plan was made for; handed_out: ids
    handed out by next_step, in order; history: what happened to the plan (made,
    resequenced and why).
    """

    part: str
    specs_digest: str
    method: str
    cost_model: str
    cost_interim: bool
    created: str
    build_seconds: float
    tool_state: Mapping[str, Mapping[str, str]]
    groups: tuple[PlannedGroup, ...]
    done: tuple[str, ...]
    cannot: tuple[tuple[str, str], ...]
    transfer_s: float
    tool_changes: int
    handed_out: tuple[str, ...] = ()
    history: tuple[str, ...] = ()
    version: int = PLAN_VERSION

    @property
    def total_s(self) -> float:
        """Seconds of the whole plan: every tour plus the time at the rack (tool changes)."""
        return float(sum(g.cost_s for g in self.groups) + self.transfer_s)

    @property
    def measurement_count(self) -> int:
        """Every measurement of the plan: planned, done and cannot-be-done."""
        return sum(len(g.order) for g in self.groups) + len(self.done) + len(self.cannot)

    def pending(self) -> tuple[tuple[int, str], ...]:
        """(group index, spec id) of every planned measurement not handed out, in order
        (worked out once per plan; :meth:`handing_out` passes it on)."""
        found = self.__dict__.get("_pending")
        if found is None:
            out = set(self.handed_out)
            found = self.__dict__["_pending"] = tuple((k, i) for k, g in enumerate(self.groups) for i in g.order
                                                      if i not in out)
        return found

    def handing_out(self, spec_id: str) -> SequencePlan:
        """This plan with `spec_id` handed out (its pending measurements known at once when
        it is the first of them, as the Sequence Planner hands them out)."""
        pending = self.pending()
        plan = replace(self, handed_out=self.handed_out + (spec_id,))
        if pending and pending[0][1] == spec_id:
            plan.__dict__["_pending"] = pending[1:]
        return plan

    def finished(self) -> tuple[str, ...]:
        """Ids done before the plan was made or handed out since, without repeats."""
        return tuple(dict.fromkeys(self.done + self.handed_out))


@dataclass(frozen=True, eq=False)
class PlanningContext:
    """Everything building a plan needs, passed explicitly.

    feature_kinds: feature id -> kind spelling; facts: the facts function of the
    partition (by default the reach test and the inverse kinematics,
    ita.sequence.cost.pose_facts); cost_model: seconds between stops.
    """

    kb: KnowledgeBase
    part_name: str              # the key its stores go by (ita.part.store.part_key): name and content digest
    specs: tuple[MeasurementSpec, ...]
    feature_kinds: Mapping[str, str]
    workcell: Workcell
    specs_digest: str
    method: str = "default"
    cost_model: CostModel = MOTION_TIME_COST
    facts: FactsFunction = pose_facts
    unmeasurable: Mapping[str, str] = field(default_factory=dict)   # spec id -> why its feature is not on the part
    _facts_cache: dict = field(default_factory=dict, repr=False)

    def spec_facts(self) -> list:
        """The facts of every spec (computed once per specs and facts function)."""
        key = ("facts", id(self.specs), self.facts)
        if key not in self._facts_cache:
            facts = self.facts(self.workcell, self.specs)
            if self.unmeasurable:
                facts = [[*f, Term("unmeasurable", (self.unmeasurable[s.id],))] if s.id in self.unmeasurable else f
                         for s, f in zip(self.specs, facts)]
            self._facts_cache[key] = (self.specs, facts)
        return self._facts_cache[key][1]

    def spec(self, spec_id: str) -> MeasurementSpec:
        """The spec with id `spec_id`; KeyError when there is none."""
        key = ("by_id", id(self.specs))
        if key not in self._facts_cache:
            self._facts_cache[key] = (self.specs, {s.id: s for s in self.specs})
        return self._facts_cache[key][1][spec_id]


def with_mkb(ctx: PlanningContext, mkb: MeasurementKB | None) -> PlanningContext:
    """`ctx` whose facts add what the MKB `mkb` says about placing each measurement for each
    tool class (:class:`ita.sequence.cost.PlacedFacts` over ctx's own facts function);
    `ctx` itself when `mkb` is None."""
    if mkb is None:
        return ctx
    base = ctx.facts.base if isinstance(ctx.facts, PlacedFacts) else ctx.facts
    return replace(ctx, facts=PlacedFacts(mkb.placement(), base), _facts_cache={})


def specs_digest(path: Path) -> str:
    """Hex SHA-256 of a specs file: a stored plan is stale when it changes."""
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def planning_context(
    part_dir: Path | None = None, kb: KnowledgeBase | None = None, method: str = "default",
    cost_model: CostModel = MOTION_TIME_COST, part: Part | None = None, use_mkb: bool = True,
    arm: str | None = None,
) -> PlanningContext:
    """A context for the part in `part_dir` (default: the built-in bulkhead) and its
    workcell (the part's own workcell.toml when it has one).  With `use_mkb`, the facts
    add what the part's stored MKB, when current, says about placing each measurement for
    each tool class (:func:`with_mkb`).  arm: the cell as that arm works it (its second
    arm, `Workcell.seen_by`); its plan, MKB and MACROPs are stored apart (the part's key
    and ``@arm``).  InputError for an arm the cell does not have."""
    if kb is None:
        kb = KnowledgeBase()
    loaded = part if part is not None else load_part(part_dir)
    specs = tuple(read_specs(loaded.specs_path))
    cell, key = workcell_for(loaded.directory, loaded.mesh.bounds), part_key(loaded)
    if arm is not None and arm != cell.arm.name:
        try:
            cell = cell.seen_by(arm)
        except KeyError:
            raise InputError([(Location(str(cell.source), field="arm"),
                               f"the workcell has no arm {arm!r} (its arms: "
                               f"{', '.join(a.name for a in cell.arms())})")]) from None
        key = f"{key}@{arm}"
    ctx = PlanningContext(
        kb=kb, part_name=key, specs=specs, feature_kinds=feature_kinds_of(loaded.features),
        unmeasurable={n.spec_id: n.reason for n in loaded.unfound},
        workcell=cell, specs_digest=specs_digest(loaded.specs_path), method=method,
        cost_model=cost_model,
    )
    if not use_mkb:
        return ctx
    return with_mkb(ctx, load_mkb(ctx.part_name, mkb_digest(ctx.specs_digest, ctx.workcell)))


def tool_state(kb: KnowledgeBase) -> dict[str, dict[str, str]]:
    """Tool -> {"condition": ..., "location": ...} of the world model now."""
    world = WorldModel(kb)
    return {tool: {"condition": world.condition(tool), "location": str(world.location(tool))}
            for tool in world.tools()}


def held_tool(kb: KnowledgeBase) -> str | None:
    """The tool the arm holds now, or None."""
    held = WorldModel(kb).holding()
    return None if held is None else held[1]


def tool_at_start(kb: KnowledgeBase) -> str | None:
    """The tool in the arm's hand when it starts to measure: the one it holds, else the
    SLRA the Top Level registers the part with first (kb/tasks.pl ``register_part``:
    WorldModel.registering_slra), None when it has neither."""
    held = held_tool(kb)
    if held is not None:
        return held
    world = WorldModel(kb)
    return world.registering_slra(world.the_arm())


def order_group(ctx: PlanningContext, tool: str, spec_ids: Sequence[str],
                keep: Sequence[str] | None = None) -> PlannedGroup:
    """Order one tool's measurements into a closed tour from and back to its rack slot.

    keep: an order to reuse (its ids must be exactly `spec_ids`); it is costed, not solved.
    """
    spec = ctx.workcell.tool(tool)
    ids = list(spec_ids)
    specs = [ctx.spec(i) for i in ids]
    matrix = ctx.cost_model.tour(ctx.workcell, spec, specs)
    if keep is not None:
        if sorted(keep) != sorted(ids):
            raise ValueError("the order to keep does not have the group's measurements")
        pos = {i: k + 1 for k, i in enumerate(ids)}
        visit = (0, *[pos[i] for i in keep])
        cost = tour_cost(matrix, visit, closed=True)
        return PlannedGroup(tool, spec.tool_class.value, tuple(keep), float(cost))
    coords = np.vstack([slot_position(ctx.workcell, tool)[None, :], tool_points_world(ctx.workcell, spec, specs)])
    tour = solve_tour(matrix, method=ctx.method, coords=coords, start=0, end=0)
    order = tuple(ids[k - 1] for k in tour.order if k != 0)
    return PlannedGroup(tool, spec.tool_class.value, order, float(tour.cost))


def order_groups(ctx: PlanningContext, tools: Sequence[str], held: str | None) -> tuple[list[str], float]:
    """The visiting order of the tools' groups and its seconds at the rack.

    One visit to the rack per tool; the held tool's group first (no pick-up); among the
    rest the order with the least time at the rack (all orders tried: there are few
    tools), ties broken by tool name.  The time counts the first pick-up, every change
    between groups and the last put-down (``cost_model.transfer`` with None at the ends).
    """
    tools = sorted(tools)
    first = [t for t in tools if t == held]
    rest = [t for t in tools if t != held]
    transfer = {(a, b): ctx.cost_model.transfer(ctx.workcell, a, b)
                for a in [None, *tools] for b in [*tools, None] if a != b}
    best: tuple[float, list[str]] | None = None
    for perm in itertools.permutations(rest):
        seq = first + list(perm)
        ends = ([] if first else [(None, seq[0])]) + [(seq[-1], None)] if seq else []
        cost = sum(transfer[pair] for pair in [*itertools.pairwise(seq), *ends])
        if best is None or cost < best[0] - 1e-12:
            best = (cost, seq)
    return (best[1], best[0]) if best else ([], 0.0)


def build_plan(
    ctx: PlanningContext, done: Iterable[str] = (), previous: SequencePlan | None = None,
    note: str | None = None,
) -> SequencePlan:
    """Partition the not-done specs by tool, order each group and the groups: a new plan.

    The world model in ``ctx.kb`` decides tool availability (apply the stored tool state
    first, see ita.sequence.store).  With `previous` (resequencing), its progress and
    history carry over, and a group whose remaining measurements are exactly those of a
    previous group of the same tool class keeps its order (a spare continues where the
    broken tool stopped).
    """
    t0 = time.perf_counter()
    done_ids = tuple(dict.fromkeys(done))
    partition = partition_specs(ctx.kb, ctx.specs, ctx.feature_kinds, ctx.spec_facts(), done=done_ids)
    kept = _remaining_orders(previous) if previous else {}
    held = tool_at_start(ctx.kb)
    tools, transfer = order_groups(ctx, [g.tool for g in partition.groups], held)
    groups = []
    for tool in tools:
        group = partition.group_of(tool)
        assert group is not None
        keep = kept.get(group.tool_class)
        if keep is not None and sorted(keep) != sorted(group.spec_ids):
            keep = None
        planned = order_group(ctx, tool, group.spec_ids, keep=keep)
        groups.append(replace(planned, rules=group.rules))
    changes = len(groups) - (1 if groups and groups[0].tool == held else 0)
    now = datetime.now(UTC).isoformat(timespec="seconds")
    history = (previous.history if previous else ()) + (f"{now} {note or 'made'}",)
    return SequencePlan(
        part=ctx.part_name, specs_digest=ctx.specs_digest, method=ctx.method,
        cost_model=ctx.cost_model.name, cost_interim=ctx.cost_model.interim, created=now,
        build_seconds=round(time.perf_counter() - t0, 3), tool_state=tool_state(ctx.kb), groups=tuple(groups),
        done=partition.done, cannot=partition.cannot, transfer_s=transfer, tool_changes=changes,
        handed_out=previous.handed_out if previous else (), history=history,
    )


def following(plan: SequencePlan, tours: Sequence[tuple[str, Sequence[str]]], workcell: Workcell,
              cost_s: Sequence[float] = ()) -> SequencePlan:
    """`plan` with the measurements of ``tours`` ((tool, spec ids) in visiting order: the
    arm's share of a two-arm allocation, ita.sequence.allocate) taken first, in that order,
    each tour a group of its tool (``cost_s``: each tour's seconds, when known); then the
    rest of `plan`'s groups without them.  Its progress carries over."""
    taken = {i for _t, ids in tours for i in ids}
    costs = list(cost_s) + [0.0] * (len(tours) - len(cost_s))
    groups = [PlannedGroup(tool, workcell.tool(tool).tool_class.value, tuple(ids), float(c))
              for (tool, ids), c in zip(tours, costs) if ids]
    for g in plan.groups:
        rest = tuple(i for i in g.order if i not in taken)
        if rest:
            groups.append(replace(g, order=rest))
    note = f"{datetime.now(UTC).isoformat(timespec='seconds')} following the two-arm allocation's tours"
    return replace(plan, groups=tuple(groups), tool_changes=len(groups), history=plan.history + (note,))


def _remaining_orders(plan: SequencePlan) -> dict[str, tuple[str, ...]]:
    """Tool class -> the not-handed-out part of its group's order in `plan`."""
    out = set(plan.handed_out)
    return {g.tool_class: tuple(i for i in g.order if i not in out) for g in plan.groups}


def choose_tool(ctx: PlanningContext, spec_id: str) -> Selection:
    """The tool rules' choice for one measurement now (the world model's tools): the
    Sequence Planner's partition of that spec alone.  KeyError for an unknown id."""
    spec = ctx.spec(spec_id)
    return select_tools(ctx.kb, [spec], ctx.feature_kinds, ctx.facts(ctx.workcell, [spec]))[0]


def partition_only(ctx: PlanningContext, done: Iterable[str] = ()) -> Partition:
    """The partition of ``ctx.specs`` (no ordering), for reports and tests."""
    return partition_specs(ctx.kb, ctx.specs, ctx.feature_kinds, ctx.spec_facts(), done=done)


__all__ = [
    "COST_MODELS", "INTERIM_COST", "MOTION_TIME_COST", "CostModel", "PlannedGroup", "PlanningContext", "SequencePlan",
    "build_plan", "choose_tool", "following", "euclidean_slot_seconds", "euclidean_tcp_seconds", "held_tool",
    "tool_at_start", "order_group",
    "order_groups", "partition_only", "planning_context", "pose_facts", "slot_position", "specs_digest",
    "tool_points_world", "tool_state", "with_mkb",
]
