"""Hand out the next measurement of a stored sequence plan; resequence when needed.

The seed: "Looking up the next step consists of popping the next measurement
specification off the stored sequence plan, and verifying the required resources are
available.  If not, resequencing is performed and the next measurement (if any) from the
new sequence is returned."

    result = next_step(ctx, plan)       # ctx: ita.sequence.plan.PlanningContext
    result.step                         # Step, or None when nothing is left to do
    result.plan                         # the plan with the step handed out (store it)
    result.resequenced, result.reason   # whether and why the plan was remade

The resources of a step are its tool and the arm (``world:usable(Arm, ToolType, Tool)``:
the tool available, the arm able to lift it).  When they are not available, the
measurements not yet handed out are partitioned and ordered anew
(ita.sequence.plan.build_plan with the handed-out ones as done): a broken tool with a
usable spare gives the spare its group, in the same order (the arm returns to the rack,
swaps, and continues); without a spare its measurements move to the cannot-be-done group
with the reason.  The plan is also remade when a tool that some cannot-be-done
measurements lacked is usable again.  A handed-out measurement counts as done (results
live in the archive; a failed one comes back through a new plan).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

from ita.logic.terms import Var
from ita.logic.world import WorldModel
from ita.sequence.plan import PlanningContext, SequencePlan, build_plan

if TYPE_CHECKING:
    from ita.logic.bridge import KnowledgeBase


@dataclass(frozen=True)
class Step:
    """One measurement handed out: its spec id and kind, the tool, where it is in the plan.

    group: index of its tool group; position: 1-based place in that group's order;
    remaining: measurements of the plan still to hand out after this one.
    """

    spec_id: str
    kind: str
    tool: str
    tool_class: str
    arm: str
    group: int
    position: int
    remaining: int


@dataclass(frozen=True)
class NextResult:
    """The answer of :func:`next_step`: the step (None: nothing left), the updated plan,
    and whether (and why) the plan was resequenced."""

    step: Step | None
    plan: SequencePlan
    resequenced: bool
    reason: str | None


def the_arm(kb: KnowledgeBase) -> str:
    """The arm of the world model (the first object of type `arm`)."""
    return WorldModel(kb).the_arm()


def resources_available(kb: KnowledgeBase, arm: str, tool_class: str, tool: str) -> bool:
    """True when `arm` can measure with `tool` now (``world:usable/3``)."""
    return WorldModel(kb).is_usable(arm, tool_class, tool)


def resequence_reason(ctx: PlanningContext, plan: SequencePlan, arm: str) -> str | None:
    """Why `plan` must be remade before the next step, or None when it need not be.

    The next measurement's tool is not usable; or a tool type that cannot-be-done
    measurements lacked (``no_working_tool(T)``) has a usable tool again.
    """
    pending = plan.pending()
    if pending:
        group = plan.groups[pending[0][0]]
        if not resources_available(ctx.kb, arm, group.tool_class, group.tool):
            world = WorldModel(ctx.kb)
            state = "missing" if world.missing(group.tool) else world.condition(group.tool)
            return f"tool {group.tool} not available ({state})"
    lacking = {r[len("no_working_tool("):-1] for _, r in plan.cannot if r.startswith("no_working_tool(")}
    for tool_class in sorted(lacking):
        if ctx.kb.holds("tools", "tool_of_type", tool_class, Var("_T"), Var("_H")):
            return f"a {tool_class} is available again"
    return None


def resequence(ctx: PlanningContext, plan: SequencePlan, reason: str) -> SequencePlan:
    """A new plan of the measurements not done or handed out, keeping `plan`'s progress."""
    return build_plan(ctx, done=plan.finished(), previous=plan, note=f"resequenced: {reason}")


def next_step(ctx: PlanningContext, plan: SequencePlan, arm: str | None = None) -> NextResult:
    """Pop the next measurement off `plan` after checking its resources (see module doc).
    arm: the world model's arm, when the caller knows it.

    The returned plan has the step handed out (and is the new plan when resequenced):
    store it.
    """
    arm = arm or the_arm(ctx.kb)
    reason = resequence_reason(ctx, plan, arm)
    if reason is not None:
        plan = resequence(ctx, plan, reason)
    pending = plan.pending()
    if not pending:
        return NextResult(None, plan, reason is not None, reason)
    k, spec_id = pending[0]
    group = plan.groups[k]
    # resequence_reason checked this tool when the plan was not remade
    if reason is not None and not resources_available(ctx.kb, arm, group.tool_class, group.tool):
        # the rules chose this tool just now: only a world change in between gets here
        raise RuntimeError(f"tool {group.tool} chosen by the rules is not usable")
    step = Step(spec_id=spec_id, kind=ctx.spec(spec_id).kind.value, tool=group.tool,
                tool_class=group.tool_class, arm=arm, group=k, position=group.order.index(spec_id) + 1,
                remaining=len(pending) - 1)
    return NextResult(step, plan.handing_out(spec_id), reason is not None, reason)


def peek(plan: SequencePlan, count: int = 1) -> list[tuple[int, str]]:
    """The next `count` (group index, spec id) of `plan` as stored, without checks."""
    return list(plan.pending()[:count])
