"""An HDDL reader of its own, for the verifier (ita/htn/verify.py): the verifier does not
trust the engine's reader (prolog/hddl.pl).

It reads the same total-order HDDL into plain values: formulas as nested tuples,

    ("and", (f, ...))   ("or", (f, ...))   ("not", f)   ("imply", f, g)
    ("=", a, b)         ("atom", name, (arg, ...))
    ("forall", ((var, type), ...), f)      ("exists", ((var, type), ...), f)

where an argument is a ``?variable`` (kept with its ``?``) or an object name.  Symbols
are lower-cased.  Errors are :class:`~ita.errors.InputError` with file and line.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Union

from ita.errors import InputError, Location

Formula = tuple[Any, ...]
TRUE: Formula = ("and", ())
#: a task or an action as written in a method: its name and arguments (variables or objects)
TaskRef = tuple[str, tuple[str, ...]]
Params = tuple[tuple[str, str], ...]


class SList(list["SExpr"]):
    """A parenthesised list of the text, with the line it starts on."""

    def __init__(self, items: list[SExpr], line: int):
        super().__init__(items)
        self.line = line


SExpr = Union[str, SList]


@dataclass(frozen=True)
class Action:
    name: str
    params: Params
    pre: Formula
    #: (True, atom) adds, (False, atom) deletes; an atom is (name, args)
    effects: tuple[tuple[bool, TaskRef], ...]


@dataclass(frozen=True)
class Method:
    name: str
    params: Params
    task: TaskRef
    pre: Formula
    subtasks: tuple[TaskRef, ...]


@dataclass(frozen=True)
class Domain:
    name: str
    #: type -> its parent types
    parents: dict[str, tuple[str, ...]]
    constants: dict[str, tuple[str, ...]]
    tasks: dict[str, Params]
    actions: dict[str, Action]
    methods: dict[str, Method]


@dataclass(frozen=True)
class Problem:
    name: str
    #: object -> its declared types
    objects: dict[str, tuple[str, ...]]
    init: frozenset[tuple[str, tuple[str, ...]]]
    params: Params
    tasks: tuple[TaskRef, ...]
    goal: Formula


_TOKEN = re.compile(r"\(|\)|[^\s();]+|;[^\n]*|\n")


def parse_sexprs(text: str, file: str) -> list[SExpr]:
    """The s-expressions of an HDDL text."""
    stack: list[SList] = [SList([], 1)]
    line = 1
    for match in _TOKEN.finditer(text):
        token = match.group()
        if token == "\n":
            line += 1
        elif token.startswith(";"):
            continue
        elif token == "(":
            stack.append(SList([], line))
        elif token == ")":
            if len(stack) == 1:
                raise InputError([(Location(file, line), "unbalanced parentheses: unexpected ')'")])
            done = stack.pop()
            stack[-1].append(done)
        else:
            stack[-1].append(token.lower())
    if len(stack) > 1:
        raise InputError([(Location(file, stack[-1].line), "unbalanced parentheses: '(' is never closed")])
    return list(stack[0])


class _Reader:
    def __init__(self, file: str):
        self.file = file

    def error(self, where: SExpr | int, message: str) -> InputError:
        line = where if isinstance(where, int) else getattr(where, "line", 0)
        return InputError([(Location(self.file, line), message)])

    def define(self, exprs: list[SExpr], kind: str) -> tuple[str, list[SList]]:
        for e in exprs:
            if isinstance(e, SList) and len(e) >= 2 and e[0] == "define" and isinstance(e[1], SList) \
                    and len(e[1]) == 2 and e[1][0] == kind:
                sections = [s for s in e[2:] if isinstance(s, SList) and s and isinstance(s[0], str)]
                return str(e[1][1]), sections
        raise self.error(1, f"not an HDDL {kind}: (define ({kind} NAME) ...) expected")

    def typed(self, items: SExpr, line: int) -> Params:
        if not isinstance(items, SList):
            raise self.error(line, "a list of (typed) names expected")
        out: list[tuple[str, str]] = []
        pending: list[str] = []
        i = 0
        while i < len(items):
            item = items[i]
            if item == "-":
                if i + 1 >= len(items):
                    raise self.error(items, "a '-' without a type after it")
                kind = self.type_name(items[i + 1], items)
                out += [(n, kind) for n in pending]
                pending = []
                i += 2
                continue
            if not isinstance(item, str):
                raise self.error(item, "a name expected, not a list")
            pending.append(item)
            i += 1
        out += [(n, "object") for n in pending]
        return tuple(out)

    def type_name(self, item: SExpr, where: SExpr) -> str:
        if isinstance(item, str):
            return item
        if item and item[0] == "either" and all(isinstance(t, str) for t in item[1:]):
            return "either " + " ".join(sorted(str(t) for t in item[1:]))
        raise self.error(where, "a type name expected")

    def keywords(self, body: list[SExpr], where: SExpr) -> dict[str, SExpr]:
        if len(body) % 2:
            raise self.error(where, "keywords with values expected")
        pairs: dict[str, SExpr] = {}
        for k, v in zip(body[::2], body[1::2]):
            if not (isinstance(k, str) and k.startswith(":")):
                raise self.error(where, f"a keyword expected, not {k}")
            pairs[k] = v
        return pairs

    def ref(self, item: SExpr, where: SExpr) -> TaskRef:
        if isinstance(item, str):
            return item, ()
        if item and isinstance(item[0], str) and all(isinstance(a, str) for a in item[1:]):
            return item[0], tuple(str(a) for a in item[1:])
        raise self.error(item if isinstance(item, SList) else where, "(name arg ...) expected")

    def formula(self, e: SExpr, where: SExpr) -> Formula:
        if isinstance(e, str):
            return ("atom", e, ())
        if not e:
            return TRUE
        head = e[0]
        if head == "and":
            return ("and", tuple(self.formula(f, e) for f in e[1:]))
        if head == "or":
            return ("or", tuple(self.formula(f, e) for f in e[1:]))
        if head == "not" and len(e) == 2:
            return ("not", self.formula(e[1], e))
        if head == "imply" and len(e) == 3:
            return ("imply", self.formula(e[1], e), self.formula(e[2], e))
        if head == "=" and len(e) == 3:
            return ("=", str(e[1]), str(e[2]))
        if head in ("forall", "exists") and len(e) == 3:
            return (head, self.typed(e[1], e.line), self.formula(e[2], e))
        name, args = self.ref(e, where)
        return ("atom", name, args)

    def effects(self, e: SExpr) -> tuple[tuple[bool, TaskRef], ...]:
        if isinstance(e, SList) and not e:
            return ()
        if isinstance(e, SList) and e[0] == "and":
            return tuple(x for f in e[1:] for x in self.effects(f))
        if isinstance(e, SList) and e[0] == "not" and len(e) == 2:
            return ((False, self.ref(e[1], e)),)
        if isinstance(e, SList) and e[0] in ("when", "forall"):
            raise self.error(e, f"{e[0]} effects are not supported")
        return ((True, self.ref(e, e)),)

    def network(self, pairs: dict[str, SExpr], where: SExpr) -> tuple[TaskRef, ...]:
        for key in (":ordered-subtasks", ":ordered-tasks", ":subtasks", ":tasks"):
            if key in pairs:
                labelled = self.subtasks(pairs[key], where)
                if key in (":ordered-subtasks", ":ordered-tasks"):
                    return tuple(t for _, t in labelled)
                return self.ordered(labelled, pairs.get(":ordering", SList([], 0)), where)
        return ()

    def subtasks(self, e: SExpr, where: SExpr) -> list[tuple[str, TaskRef]]:
        if isinstance(e, str):
            return [(e, (e, ()))]
        if not e:
            return []
        items = e[1:] if e[0] == "and" else [e]
        out = []
        for n, item in enumerate(items):
            if isinstance(item, SList) and len(item) == 2 and isinstance(item[0], str) and isinstance(item[1], SList):
                out.append((item[0], self.ref(item[1], item)))
            else:
                out.append((f"#{n}", self.ref(item, e)))
        return out

    def ordered(self, labelled: list[tuple[str, TaskRef]], ordering: SExpr,
                where: SExpr) -> tuple[TaskRef, ...]:
        before: list[tuple[str, str]] = []

        def walk(o: SExpr) -> None:
            if isinstance(o, SList) and o and o[0] == "and":
                for x in o[1:]:
                    walk(x)
            elif isinstance(o, SList) and len(o) == 3 and o[0] in ("<", ">"):
                a, b = str(o[1]), str(o[2])
                before.append((a, b) if o[0] == "<" else (b, a))
            elif isinstance(o, SList) and not o:
                return
            else:
                raise self.error(o if isinstance(o, SList) else where, "(< task1 task2) expected")

        walk(ordering)
        left = [label for label, _ in labelled]
        order: list[str] = []
        while left:
            free = [x for x in left if not any(b == x and a in left for a, b in before)]
            if len(free) != 1:
                raise self.error(where, "the subtasks are not totally ordered" if free else "the ordering has a cycle")
            order.append(free[0])
            left.remove(free[0])
        tasks = dict(labelled)
        return tuple(tasks[x] for x in order)


def read_domain(path: Path) -> Domain:
    """The domain of an HDDL file."""
    reader = _Reader(str(path))
    name, sections = reader.define(parse_sexprs(path.read_text(encoding="utf-8"), str(path)), "domain")
    parents: dict[str, tuple[str, ...]] = {}
    constants: dict[str, tuple[str, ...]] = {}
    tasks: dict[str, Params] = {}
    actions: dict[str, Action] = {}
    methods: dict[str, Method] = {}
    for s in sections:
        key = s[0]
        if key == ":types":
            for t, p in reader.typed(SList(s[1:], s.line), s.line):
                parents[t] = parents.get(t, ()) + tuple(p.split()[1:] if p.startswith("either ") else [p])
        elif key == ":constants":
            for o, t in reader.typed(SList(s[1:], s.line), s.line):
                constants[o] = constants.get(o, ()) + (t,)
        elif key == ":task":
            pairs = reader.keywords(s[2:], s)
            tasks[str(s[1])] = reader.typed(pairs.get(":parameters", SList([], s.line)), s.line)
        elif key == ":action":
            pairs = reader.keywords(s[2:], s)
            actions[str(s[1])] = Action(
                str(s[1]), reader.typed(pairs.get(":parameters", SList([], s.line)), s.line),
                reader.formula(pairs.get(":precondition", SList([], s.line)), s),
                reader.effects(pairs.get(":effect", SList([], s.line))))
        elif key == ":method":
            pairs = reader.keywords(s[2:], s)
            if ":task" not in pairs:
                raise reader.error(s, f"method {s[1]} has no :task")
            pre = reader.formula(pairs.get(":precondition", SList([], s.line)), s)
            if ":constraints" in pairs:
                pre = ("and", (pre, reader.formula(pairs[":constraints"], s)))
            methods[str(s[1])] = Method(
                str(s[1]), reader.typed(pairs.get(":parameters", SList([], s.line)), s.line),
                reader.ref(pairs[":task"], s), pre, reader.network(pairs, s))
    return Domain(name, parents, constants, tasks, actions, methods)


def read_problem(path: Path) -> Problem:
    """The problem of an HDDL file."""
    reader = _Reader(str(path))
    name, sections = reader.define(parse_sexprs(path.read_text(encoding="utf-8"), str(path)), "problem")
    objects: dict[str, tuple[str, ...]] = {}
    init: set[tuple[str, tuple[str, ...]]] = set()
    params: Params = ()
    tasks: tuple[TaskRef, ...] = ()
    goal = TRUE
    for s in sections:
        key = s[0]
        if key == ":objects":
            for o, t in reader.typed(SList(s[1:], s.line), s.line):
                objects[o] = objects.get(o, ()) + (t,)
        elif key == ":init":
            init |= {reader.ref(f, s) for f in s[1:]}
        elif key == ":htn":
            pairs = reader.keywords(s[1:], s)
            params = reader.typed(pairs.get(":parameters", SList([], s.line)), s.line)
            tasks = reader.network(pairs, s)
        elif key == ":goal" and len(s) == 2:
            goal = reader.formula(s[1], s)
    return Problem(name, objects, frozenset(init), params, tasks, goal)
