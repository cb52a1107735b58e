"""An HTN plan as values, and the IPC 2020 plan format.

The format (the HTN IPC 2020's, read by its verifier)::

    ==>
    0 drive truck_0 city_loc_2 city_loc_1
    1 pick_up truck_0 city_loc_1 package_0 capacity_0 capacity_1
    root 2
    2 deliver package_0 city_loc_0 -> m_deliver_ordering_0 3 0 1
    3 get_to truck_0 city_loc_1 -> m_drive_to_ordering_0 0
    <==

one line per action (its id, name and arguments, in execution order), a ``root`` line
with the ids of the initial task network, and one line per compound task: its id, name
and arguments, ``->``, the method and the ids of the subtasks in order.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass

#: a ground task or action: its name and arguments
Atom = tuple[str, ...]


class PlanFormatError(ValueError):
    """A plan text that is not in the IPC format; says which line."""

    def __init__(self, line: int, message: str):
        self.line = line
        super().__init__(f"line {line}: {message}")


@dataclass(frozen=True)
class Decomposition:
    """A compound task `task` (id `id`) done by `method` with the subtasks `children`."""

    id: int
    task: Atom
    method: str
    children: tuple[int, ...]


@dataclass(frozen=True)
class HtnPlan:
    """The actions in execution order (id, action), the root task ids and the
    decompositions of the compound tasks, each id naming one task."""

    actions: tuple[tuple[int, Atom], ...]
    roots: tuple[int, ...]
    decompositions: tuple[Decomposition, ...]

    def renumbered(self) -> HtnPlan:
        """The same plan with the actions numbered 0.. in order and the compound tasks
        after them in the order of the decompositions."""
        ids: dict[int, int] = {}
        for new, (old, _) in enumerate(self.actions):
            ids[old] = new
        for new, d in enumerate(self.decompositions, start=len(self.actions)):
            ids[d.id] = new
        return HtnPlan(
            actions=tuple((ids[i], a) for i, a in self.actions),
            roots=tuple(ids[r] for r in self.roots),
            decompositions=tuple(Decomposition(ids[d.id], d.task, d.method, tuple(ids[c] for c in d.children))
                                 for d in self.decompositions),
        )

    def to_dict(self) -> dict[str, object]:
        """JSON-ready: actions, root and decompositions with their ids."""
        return {
            "actions": [{"id": i, "name": a[0], "args": list(a[1:])} for i, a in self.actions],
            "root": list(self.roots),
            "decompositions": [{"id": d.id, "task": d.task[0], "args": list(d.task[1:]), "method": d.method,
                                "children": list(d.children)} for d in self.decompositions],
        }


def format_ipc(plan: HtnPlan) -> str:
    """The plan in the IPC 2020 format (``==>`` ... ``<==``), ending with a newline."""
    lines = ["==>"]
    lines += [" ".join([str(i), *action]) for i, action in plan.actions]
    lines.append(" ".join(["root", *map(str, plan.roots)]))
    for d in plan.decompositions:
        lines.append(" ".join([str(d.id), *d.task, "->", d.method, *map(str, d.children)]))
    lines.append("<==")
    return "\n".join(lines) + "\n"


def parse_ipc(text: str) -> HtnPlan:
    """The plan of an IPC-format text: the lines between ``==>`` and ``<==`` (text
    around them is ignored; without ``==>`` the whole text is read).  Symbols are
    lower-cased.  Raises :class:`PlanFormatError` naming the line."""
    lines = text.splitlines()
    start = next((n for n, line in enumerate(lines) if line.strip() == "==>"), -1) + 1
    actions: list[tuple[int, Atom]] = []
    decompositions: list[Decomposition] = []
    roots: tuple[int, ...] | None = None
    for number, raw in enumerate(lines[start:], start=start + 1):
        line = raw.split(";", 1)[0].strip()
        if not line:
            continue
        if line == "<==":
            break
        words = line.lower().split()
        if words[0] == "root":
            if roots is not None:
                raise PlanFormatError(number, "a second root line")
            roots = tuple(_ids(number, words[1:]))
            continue
        ident = _ids(number, words[:1])[0]
        if "->" in words:
            arrow = words.index("->")
            if arrow < 2 or arrow == len(words) - 1:
                raise PlanFormatError(number, "expected 'ID TASK ARGS -> METHOD SUBTASK-IDS'")
            decompositions.append(Decomposition(ident, tuple(words[1:arrow]), words[arrow + 1],
                                                tuple(_ids(number, words[arrow + 2:]))))
        else:
            if len(words) < 2:
                raise PlanFormatError(number, "expected 'ID ACTION ARGS'")
            actions.append((ident, tuple(words[1:])))
    if roots is None:
        raise PlanFormatError(len(lines), "no root line")
    return HtnPlan(tuple(actions), roots, tuple(decompositions))


def _ids(number: int, words: Iterable[str]) -> list[int]:
    try:
        return [int(w) for w in words]
    except ValueError:
        raise PlanFormatError(number, f"an integer id expected in {' '.join(words)!r}") from None
