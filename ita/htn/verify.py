"""A verifier of total-order HTN plans in the IPC 2020 format, independent of the engine.

It reads domain and problem with its own HDDL reader (ita/htn/hddl.py) and walks the
decomposition from the root ids, depth first and left to right, with the state:

- the root ids are the problem's initial task network, in order;
- every id is reached once; a compound task's line names a method of that task whose
  subtasks, in order, are the tasks of its children (the bindings of the method's
  parameters follow from the task and the children; the others must exist), whose
  parameters have their types, and whose precondition holds in the state where the
  method starts (before its first action);
- the actions are reached in the order of the plan, each applicable in the state
  (parameters typed, precondition true) and applied (deletes, then adds);
- every action and every decomposition line is reached; the goal holds at the end.

:func:`verify_plan` returns the problems found (the first one stops the walk); an
empty list means the plan is valid.
"""

from __future__ import annotations

from collections.abc import Iterator
from itertools import product
from pathlib import Path

from ita.htn.hddl import (
    Domain,
    Formula,
    Method,
    Params,
    Problem,
    TaskRef,
    read_domain,
    read_problem,
)
from ita.htn.plan import Atom, HtnPlan, parse_ipc

Fact = tuple[str, tuple[str, ...]]
Binding = dict[str, str]


class _Invalid(Exception):
    pass


class _World:
    """The objects and their types."""

    def __init__(self, domain: Domain, problem: Problem):
        declared: dict[str, tuple[str, ...]] = dict(domain.constants)
        for o, ts in problem.objects.items():
            declared[o] = declared.get(o, ()) + ts
        self.types: dict[str, set[str]] = {}
        for o, ts in declared.items():
            closed = {"object"}
            todo = [t for t in ts]
            while todo:
                t = todo.pop()
                for part in t.split()[1:] if t.startswith("either ") else [t]:
                    if part not in closed:
                        closed.add(part)
                        todo.extend(domain.parents.get(part, ()))
            self.types[o] = closed

    def is_of(self, obj: str, kind: str) -> bool:
        kinds = self.types.get(obj)
        if kinds is None:
            return False
        if kind.startswith("either "):
            return any(k in kinds for k in kind.split()[1:])
        return kind in kinds

    def objects(self, kind: str) -> list[str]:
        return sorted(o for o in self.types if self.is_of(o, kind))


def verify_plan(domain: Domain, problem: Problem, plan: HtnPlan) -> list[str]:
    """The problems of `plan` for `problem` of `domain`; [] when it is valid."""
    try:
        _Walk(domain, problem, plan).run()
    except _Invalid as exc:
        return [str(exc)]
    return []


def verify_files(domain: Path, problem: Path, plan_text: str) -> list[str]:
    """:func:`verify_plan` on files and an IPC-format text."""
    return verify_plan(read_domain(domain), read_problem(problem), parse_ipc(plan_text))


class _Walk:
    def __init__(self, domain: Domain, problem: Problem, plan: HtnPlan):
        self.domain = domain
        self.problem = problem
        self.plan = plan
        self.world = _World(domain, problem)
        self.state: set[Fact] = set(problem.init)
        self.actions = {i: a for i, a in plan.actions}
        self.lines = {d.id: d for d in plan.decompositions}
        if len(self.actions) != len(plan.actions):
            raise _Invalid("two actions have the same id")
        if len(self.lines) != len(plan.decompositions):
            raise _Invalid("two decomposition lines have the same id")
        if set(self.actions) & set(self.lines):
            raise _Invalid(f"ids both action and compound task: {sorted(set(self.actions) & set(self.lines))}")

    def task_of(self, ident: int) -> Atom:
        if ident in self.actions:
            return self.actions[ident]
        if ident in self.lines:
            return self.lines[ident].task
        raise _Invalid(f"id {ident} is neither an action nor a decomposed task")

    def run(self) -> None:
        expected = self.problem.tasks
        roots = self.plan.roots
        if len(roots) != len(expected):
            raise _Invalid(f"the root has {len(roots)} tasks, the problem's network {len(expected)}")
        binding: Binding = {}
        for ident, ref in zip(roots, expected):
            _unify_task(ref, self.task_of(ident), binding, f"root task {ident}")
        for var, kind in self.problem.params:
            if var in binding and not self.world.is_of(binding[var], kind):
                raise _Invalid(f"the root binds {var} to {binding[var]}, not of type {kind}")
        reached: set[int] = set()
        position = 0
        stack = list(reversed(roots))
        while stack:
            ident = stack.pop()
            if ident in reached:
                raise _Invalid(f"task {ident} is reached twice")
            reached.add(ident)
            if ident in self.actions:
                if position >= len(self.plan.actions) or self.plan.actions[position][0] != ident:
                    want = self.plan.actions[position][0] if position < len(self.plan.actions) else "none"
                    raise _Invalid(f"action {ident} is reached where the plan's next action is {want}")
                self.apply(ident, self.actions[ident])
                position += 1
            else:
                line = self.lines.get(ident)
                if line is None:
                    raise _Invalid(f"id {ident} is neither an action nor a decomposed task")
                self.check_method(line.id, line.task, line.method, line.children)
                stack.extend(reversed(line.children))
        if position != len(self.plan.actions):
            missing = [i for i, _ in self.plan.actions[position:]]
            raise _Invalid(f"actions never reached by the decomposition: {missing[:10]}")
        unused = sorted(set(self.lines) - reached)
        if unused:
            raise _Invalid(f"decomposition lines never reached from the root: {unused[:10]}")
        if not self.holds(self.problem.goal, {}, {}):
            raise _Invalid("the goal does not hold in the final state")

    def apply(self, ident: int, action: Atom) -> None:
        name, args = action[0], action[1:]
        schema = self.domain.actions.get(name)
        if schema is None:
            raise _Invalid(f"action {ident}: {name} is no action of the domain")
        if len(args) != len(schema.params):
            raise _Invalid(f"action {ident}: {name} takes {len(schema.params)} arguments, not {len(args)}")
        binding = dict(zip((v for v, _ in schema.params), args))
        for (var, kind), value in zip(schema.params, args):
            if not self.world.is_of(value, kind):
                raise _Invalid(f"action {ident} {' '.join(action)}: {value} is not of type {kind}")
        if not self.holds(schema.pre, binding, dict(schema.params)):
            raise _Invalid(f"action {ident} {' '.join(action)}: its precondition does not hold")
        ground = [(add, (n, tuple(binding.get(a, a) for a in xs))) for add, (n, xs) in schema.effects]
        for add, fact in ground:
            if not add:
                self.state.discard(fact)
        for add, fact in ground:
            if add:
                self.state.add(fact)

    def check_method(self, ident: int, task: Atom, name: str, children: tuple[int, ...]) -> None:
        method: Method | None = self.domain.methods.get(name)
        where = f"task {ident} {' '.join(task)}"
        if method is None:
            raise _Invalid(f"{where}: {name} is no method of the domain")
        binding: Binding = {}
        _unify_task(method.task, task, binding, f"{where} (method {name})")
        if len(children) != len(method.subtasks):
            raise _Invalid(f"{where}: method {name} has {len(method.subtasks)} subtasks, the line {len(children)}")
        for ref, child in zip(method.subtasks, children):
            _unify_task(ref, self.task_of(child), binding, f"{where}: subtask {child} (method {name})")
        types = dict(method.params)
        for var, value in binding.items():
            if var in types and not self.world.is_of(value, types[var]):
                raise _Invalid(f"{where}: method {name} binds {var} to {value}, not of type {types[var]}")
        for solution in self.satisfy(method.pre, binding, types):
            if all(v in solution or self.world.objects(k) for v, k in method.params):
                return
        raise _Invalid(f"{where}: the precondition of method {name} does not hold where it starts")

    # -- formulas ------------------------------------------------------------------

    def holds(self, f: Formula, binding: Binding, types: dict[str, str]) -> bool:
        return next(self.satisfy(f, binding, types), None) is not None

    def satisfy(self, f: Formula, b: Binding, types: dict[str, str]) -> Iterator[Binding]:
        """The extensions of binding `b` that make `f` true (variables typed by `types`)."""
        kind = f[0]
        if kind == "and":
            parts = sorted(f[1], key=lambda g: g[0] != "atom")
            yield from self._conj(parts, b, types)
        elif kind == "atom":
            name, args = f[1], f[2]
            yield from self._match(str(name), args, b, types)
        elif kind == "not":
            for g in self._ground(_free(f), b, types):
                if not self.holds(f[1], g, types):
                    yield g
        elif kind == "=":
            for g in self._ground(_free(f), b, types):
                if g.get(str(f[1]), f[1]) == g.get(str(f[2]), f[2]):
                    yield g
        elif kind == "or":
            for alt in f[1]:
                yield from self.satisfy(alt, b, types)
        elif kind == "imply":
            yield from self.satisfy(("or", (("not", f[1]), f[2])), b, types)
        elif kind in ("forall", "exists"):
            local: Params = f[1]
            inner = {**types, **dict(local)}
            for g in self._ground(_free(f), b, types):
                combos = (dict(zip((v for v, _ in local), values))
                          for values in product(*(self.world.objects(k) for _, k in local)))
                results = (self.holds(f[2], {**g, **c}, inner) for c in combos)
                if (all(results) if kind == "forall" else any(results)):
                    yield g
        else:
            raise _Invalid(f"unknown formula {kind}")

    def _conj(self, parts: list[Formula], b: Binding, types: dict[str, str]) -> Iterator[Binding]:
        if not parts:
            yield b
            return
        for g in self.satisfy(parts[0], b, types):
            yield from self._conj(parts[1:], g, types)

    def _match(self, name: str, args: tuple[str, ...], b: Binding, types: dict[str, str]) -> Iterator[Binding]:
        wanted = tuple(b.get(a, a) for a in args)
        if not any(a.startswith("?") for a in wanted):
            if (name, wanted) in self.state:
                yield b
            return
        for fact_name, values in self.state:
            if fact_name != name or len(values) != len(args):
                continue
            g = dict(b)
            for a, v in zip(wanted, values):
                if a.startswith("?"):
                    if g.setdefault(a, v) != v or (a in types and not self.world.is_of(v, types[a])):
                        break
                elif a != v:
                    break
            else:
                yield g

    def _ground(self, variables: set[str], b: Binding, types: dict[str, str]) -> Iterator[Binding]:
        unbound = sorted(v for v in variables if v not in b)
        for values in product(*(self.world.objects(types.get(v, "object")) for v in unbound)):
            yield {**b, **dict(zip(unbound, values))}


def _free(f: Formula) -> set[str]:
    """The free variables of a formula."""
    kind = f[0]
    if kind == "atom":
        return {a for a in f[2] if a.startswith("?")}
    if kind == "=":
        return {str(a) for a in f[1:] if str(a).startswith("?")}
    if kind in ("and", "or"):
        return set().union(*(_free(g) for g in f[1]))
    if kind == "not":
        return _free(f[1])
    if kind == "imply":
        return _free(f[1]) | _free(f[2])
    if kind in ("forall", "exists"):
        return _free(f[2]) - {v for v, _ in f[1]}
    return set()


def _unify_task(ref: TaskRef, task: Atom, binding: Binding, where: str) -> None:
    """Bind the variables of the written task `ref` to the ground `task`, or raise."""
    name, args = ref
    if task[0] != name or len(task) - 1 != len(args):
        raise _Invalid(f"{where}: {' '.join(task)} is not a {name}/{len(args)} task")
    for a, v in zip(args, task[1:]):
        if a.startswith("?"):
            if binding.setdefault(a, v) != v:
                raise _Invalid(f"{where}: {a} would be both {binding[a]} and {v}")
        elif a != v:
            raise _Invalid(f"{where}: argument {v} where the method has {a}")
