"""An HTN plan being carried out: the next action, what is left, planning again.

    agenda = Agenda(kb, "tasks")
    agenda.plan(["inspect_part"], state=set())       # prolog/htn.pl htn_plan/5
    while (action := agenda.next()) is not None:
        if not agenda.applicable(action, state):     # the operator's preconditions, now
            agenda.replan_parent(state)               # its task planned again from here
            continue
        ... carry it out ...
        state = agenda.done(action, state)           # the operator's effects applied

The tree of the plan (tasks, the methods that decomposed them, the attached procedures
they called) is kept whole, with the tasks planned again hung where they were, for
`ita plan --top` and the run's record.

Planning again, two reaches:

- :meth:`Agenda.replan_parent`: the task just above the next action, when none of its
  actions has run (an action whose preconditions no longer hold: the measurement that
  another's frame already measured, the reading that failed);
- :meth:`Agenda.replan_rest`: everything not yet carried out, from the current state
  (the world changed, an interrupt, a stop, an alarm: the rest of the plan is wrong).
"""

from __future__ import annotations

import time
from collections.abc import Iterable, Iterator
from dataclasses import dataclass, field

from ita.errors import PrologError
from ita.logic.bridge import KnowledgeBase
from ita.logic.terms import Term, TermValue, Var
from ita.planning.operation import format_term

__all__ = ["Action", "Agenda", "Facts", "NoPlan", "TreeNode", "fact_text", "tree_lines", "with_facts"]

HTN = "htn"


class NoPlan(PrologError):
    """The planner found no plan (or none within its limits) for a task network."""


@dataclass(frozen=True)
class Action:
    """A primitive task of the plan: its node id in the tree and the ground action."""

    id: int
    term: TermValue

    @property
    def name(self) -> str:
        return self.term.name if isinstance(self.term, Term) else str(self.term)

    @property
    def args(self) -> tuple[TermValue, ...]:
        return tuple(self.term.args) if isinstance(self.term, Term) else ()


@dataclass
class TreeNode:
    """A task of the decomposition tree: a primitive (no method) or a compound task with
    the method that decomposed it, its children and the attached procedures it called."""

    id: int
    task: TermValue
    method: TermValue | None
    children: list[int] = field(default_factory=list)
    calls: tuple[TermValue, ...] = ()
    parent: int | None = None

    @property
    def primitive(self) -> bool:
        return self.method is None


#: the state of a plan: its facts by their text
Facts = dict[str, TermValue]


def fact_text(fact: TermValue) -> str:
    """A fact of the state as text, ``name(arg, ...)`` (its key in :data:`Facts`)."""
    return format_term(fact)


def with_facts(state: Facts, facts: Iterable[TermValue]) -> Facts:
    """`state` with `facts` added."""
    return {**state, **{fact_text(f): f for f in facts}}


class Agenda:
    """The plan of a job in the HTN domain module `domain` (kb/tasks.pl), carried out
    action by action (module docstring)."""

    def __init__(self, kb: KnowledgeBase, domain: str = "tasks") -> None:
        self.kb = kb
        self.domain = domain
        self.nodes: dict[int, TreeNode] = {}
        self.roots: list[int] = []
        self.steps: list[Action] = []      # the plan's actions still to carry out, in order
        self.executed: list[int] = []      # action ids carried out, in order
        self.replans = 0
        self.plan_seconds = 0.0                 # wall time of the first plan
        self.replan_seconds: list[float] = []   # wall time of each plan made again
        self._effects: dict[str, tuple[list[TermValue], list[TermValue], list[TermValue]]] = {}

    # -- planning ---------------------------------------------------------------------------
    def plan(self, tasks: Iterable[TermValue], state: Facts) -> None:
        """Plan the ordered task network `tasks` from `state`; raises NoPlan."""
        t0 = time.perf_counter()
        found = self.kb.once(HTN, "htn_plan", self.domain, list(state.values()), list(tasks), [], Var("R"))
        steps, tree = self._result(found)
        roots, nodes = tree
        self.nodes = {}
        self._add_nodes(nodes, None)
        self.roots = [int(str(r)) for r in roots]
        self.steps = steps
        self.plan_seconds = time.perf_counter() - t0

    def replan_parent(self, state: Facts) -> bool:
        """Plan the task just above the next action again from `state`, when none of its
        actions has run; whether it could (False: plan the rest, :meth:`replan_rest`)."""
        if not self.steps:
            return False
        parent = self.nodes[self.steps[0].id].parent
        if parent is None or any(a in self._done_set() for a in self._leaves(parent)):
            return False
        try:
            self._replan([parent], state)
        except NoPlan:
            return False
        return True

    def replan_rest(self, state: Facts) -> None:
        """Plan everything not yet carried out again from `state`; raises NoPlan."""
        self._replan(self.remaining(), state)

    def remaining(self) -> list[int]:
        """The tasks not yet carried out, largest first: a task none of whose actions has
        run stays whole, one all of whose actions ran is gone, one in between gives its
        children (a task without actions counts as done once an action after it ran).
        The actions carried out are the first of the tree's leaves, in order."""
        spans = self._spans()
        ran = len(self.executed)
        out: list[int] = []
        stack = list(reversed(self.roots))
        while stack:
            nid = stack.pop()
            first, last = spans[nid]            # leaf positions [first, last)
            if first >= ran:                    # untouched (or no actions, none after it ran)
                out.append(nid)
            elif last > ran:
                stack.extend(reversed(self.nodes[nid].children))
        return out

    def _spans(self) -> dict[int, tuple[int, int]]:
        """Each node's leaf positions [first, last) in the tree's depth-first order."""
        spans: dict[int, tuple[int, int]] = {}
        position = 0
        stack: list[tuple[int, bool]] = [(r, False) for r in reversed(self.roots)]
        starts: dict[int, int] = {}
        while stack:
            nid, closing = stack.pop()
            node = self.nodes[nid]
            if closing:
                spans[nid] = (starts[nid], position)
            elif node.primitive:
                spans[nid] = (position, position + 1)
                position += 1
            else:
                starts[nid] = position
                stack.append((nid, True))
                stack.extend((c, False) for c in reversed(node.children))
        return spans

    def _replan(self, ids: list[int], state: Facts) -> None:
        """Plan the tasks `ids` (in order, none of their actions run) again from `state`;
        their subtrees and actions are replaced by the new ones."""
        self.replans += 1
        t0 = time.perf_counter()
        network = [Term("-", (i, self.nodes[i].task)) for i in ids]
        found = self.kb.once(HTN, "htn_replan", self.domain, list(state.values()), network,
                             [Term("next_id", (max(self.nodes) + 1,))], Var("R"))
        steps, (_, nodes) = self._result(found)
        old = {a for i in ids for a in self._leaves(i)}
        parents = {i: self.nodes[i].parent for i in ids}
        for i in ids:
            self._drop_below(i)
        self._add_nodes(nodes, None)
        for i, parent in parents.items():
            self.nodes[i].parent = parent
        kept = [a for a in self.steps if a.id not in old]
        # the new actions take the place of the old ones: before the first kept one that
        # followed them in the plan (the replanned tasks are the front of what is left)
        self.steps = steps + kept
        self.replan_seconds.append(time.perf_counter() - t0)

    def _result(self, found: dict[str, object] | None) -> tuple[list[Action], tuple[list[TermValue], list[TermValue]]]:
        result = None if found is None else found["R"]
        if not isinstance(result, Term) or result.name != "plan":
            raise NoPlan(f"{self.domain}: htn", f"no plan: {result}")
        steps_t, tree_t = result.args[0], result.args[1]
        assert isinstance(steps_t, list) and isinstance(tree_t, Term)
        steps = []
        for pair in steps_t:
            assert isinstance(pair, Term) and pair.name == "-"
            steps.append(Action(int(str(pair.args[0])), pair.args[1]))
        roots, nodes = tree_t.args[0], tree_t.args[1]
        assert isinstance(roots, list) and isinstance(nodes, list)
        return steps, (roots, nodes)

    def _add_nodes(self, nodes: Iterable[TermValue], parent: int | None) -> None:
        for node in nodes:
            assert isinstance(node, Term)
            if node.name == "primitive":
                nid, task, calls = node.args
                self.nodes[int(str(nid))] = TreeNode(int(str(nid)), task, None, [], _tuple(calls))
            else:
                nid, task, method, children, calls = node.args
                assert isinstance(children, list)
                self.nodes[int(str(nid))] = TreeNode(int(str(nid)), task, method, [int(str(c)) for c in children],
                                                     _tuple(calls))
        for n in list(self.nodes.values()):
            for c in n.children:
                self.nodes[c].parent = n.id

    def _drop_below(self, node_id: int) -> None:
        stack = list(self.nodes[node_id].children)
        self.nodes[node_id].children = []
        while stack:
            gone = self.nodes.pop(stack.pop())
            stack.extend(gone.children)

    # -- carrying out -------------------------------------------------------------------------
    def next(self) -> Action | None:
        """The next action to carry out (None: the plan is done)."""
        return self.steps[0] if self.steps else None

    def applicable(self, action: Action, state: Facts) -> bool:
        """Whether the operator's preconditions of `action` hold now: facts of `state`
        (as :func:`fact_text`), their negation, and attached procedures asked now."""
        pre, _, _ = self._operator(action)
        return all(self._holds(lit, state) for lit in pre)

    def done(self, action: Action, state: Facts) -> Facts:
        """Mark `action` carried out; the state with its operator's effects."""
        assert self.steps and self.steps[0].id == action.id
        self.steps.pop(0)
        self.executed.append(action.id)
        _, dels, adds = self._operator(action)
        gone = {fact_text(d) for d in dels}
        return with_facts({k: v for k, v in state.items() if k not in gone}, adds)

    def _operator(self, action: Action) -> tuple[list[TermValue], list[TermValue], list[TermValue]]:
        key = str(action.term)
        if key not in self._effects:
            found = self.kb.once(self.domain, "operator", action.term, Var("P"), Var("D"), Var("A"))
            if found is None:
                raise PrologError(f"{self.domain}:operator/4", f"no operator for {action.term}")
            pre, dels, adds = found["P"], found["D"], found["A"]
            assert isinstance(pre, list) and isinstance(dels, list) and isinstance(adds, list)
            self._effects[key] = (pre, dels, adds)
        return self._effects[key]

    def _holds(self, literal: TermValue, state: Facts) -> bool:
        if isinstance(literal, Term) and literal.name == "not" and len(literal.args) == 1:
            inner = literal.args[0]
            if isinstance(inner, list):
                return not all(self._holds(x, state) for x in inner)
            return not self._holds(inner, state)
        if isinstance(literal, Term) and literal.name == "call" and len(literal.args) == 1:
            goal = literal.args[0]
            if isinstance(goal, Term):
                return self.kb.holds(self.domain, goal.name, *goal.args)
            return self.kb.holds(self.domain, str(goal))
        return fact_text(literal) in state

    # -- the tree ------------------------------------------------------------------------------
    def _done_set(self) -> set[int]:
        return set(self.executed)

    def _leaves(self, node_id: int) -> list[int]:
        leaves: list[int] = []
        stack = [node_id]
        while stack:
            node = self.nodes[stack.pop()]
            if node.primitive:
                leaves.append(node.id)
            else:
                stack.extend(reversed(node.children))
        return leaves

    def walk(self) -> Iterator[tuple[int, TreeNode]]:
        """The tree's nodes depth first, with their depth."""
        stack = [(0, r) for r in reversed(self.roots)]
        while stack:
            depth, nid = stack.pop()
            node = self.nodes[nid]
            yield depth, node
            stack.extend((depth + 1, c) for c in reversed(node.children))


def _tuple(value: TermValue) -> tuple[TermValue, ...]:
    return tuple(value) if isinstance(value, list) else ()


def tree_lines(agenda: Agenda, limit: int | None = None) -> list[str]:
    """The decomposition tree as indented lines: each task with the method that
    decomposed it and the attached procedures its preconditions asked (`limit`: at most
    so many lines, then how many more there are).  A task's last subtask that repeats it
    (the measurements still to do) is drawn at its parent's depth, so a long job stays
    readable."""
    lines: list[str] = []
    stack: list[tuple[int, int]] = [(0, r) for r in reversed(agenda.roots)]
    while stack:
        depth, nid = stack.pop()
        if limit is not None and len(lines) >= limit:
            break
        node = agenda.nodes[nid]
        text = "  " * depth + format_term(node.task)
        if not node.primitive:
            text += f"  <- {format_term(node.method)}"
        if node.calls:
            text += "   asked: " + "; ".join(format_term(c) for c in node.calls)
        lines.append(text)
        children = node.children
        for i, child in reversed(list(enumerate(children))):
            same = i == len(children) - 1 and _functor(agenda.nodes[child].task) == _functor(node.task)
            stack.append((depth if same else depth + 1, child))
    if len(agenda.nodes) > len(lines):
        lines.append(f"... {len(agenda.nodes) - len(lines)} more tasks")
    return lines


def _functor(value: TermValue) -> str | None:
    return value.name if isinstance(value, Term) else None
