"""The Operation Planner's facade: one call per measurement.

:class:`OperationPlanner` holds a store of learned MACROPs (a Prolog file, opened in
memory by prolog/macrop.pl) and plans a measurement with one bridge call to
``macrop:measurement_plan/8``, which tries MACROP lookup and otherwise plans from
scratch, generalizes the plan and stores the MACROP.  The reply is compact: the
MACROP's number and the values of its variables.  The facade plugs them into the
MACROP's plan template, fetched once per MACROP and cached, so a lookup costs one
small bridge call (every atom that crosses the bridge costs microseconds).

The store is saved (atomically, by Prolog) when a new MACROP is learned and on
:meth:`OperationPlanner.close`, which also saves the hit and miss counts.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from enum import Enum
from pathlib import Path
from typing import TYPE_CHECKING, Any, Callable

from ita.errors import ItaError
from ita.logic.terms import Term, Var
from ita.paths import ita_home
from ita.planning.state import NOTHING, Pose, WorldState

if TYPE_CHECKING:
    from ita.logic.bridge import KnowledgeBase
    from ita.specs.model import MeasurementSpec

__all__ = [
    "MacropInfo",
    "NoPlanError",
    "OperationPlan",
    "OperationPlanner",
    "PlanSource",
    "PlanStep",
    "StoreCounts",
    "store_path",
    "format_term",
]


def store_path(part_name: str) -> Path:
    """Where the learned MACROPs of part `part_name` live: ``$ITA_HOME/macrops/<name>.pl``."""
    safe = "".join(c if c.isalnum() or c in "-_." else "_" for c in part_name) or "part"
    return ita_home() / "macrops" / f"{safe}.pl"


class NoPlanError(ItaError):
    """The planner found no plan for a measurement; `reason` is the planner's."""

    exit_code = 1

    def __init__(self, measurement: str, reason: str):
        self.measurement = measurement
        self.reason = reason
        super().__init__(f"no plan for {measurement}: {reason}")


class PlanSource(str, Enum):
    """Where a plan came from."""

    MACROP = "macrop"    # a stored MACROP applied (lookup)
    SCRATCH = "scratch"  # the Task Planner planned it (then it was generalized and stored)


@dataclass(frozen=True)
class PlanStep:
    """Step `number` of a plan: ``action(*args)`` after the steps `predecessors`.

    args: atoms as ``str``, numbers, compound arguments as :class:`~ita.logic.terms.Term`
    (e.g. ``Term("meas", ("WT-1",))``).
    """

    number: int
    action: str
    args: tuple[Any, ...]
    predecessors: tuple[int, ...]

    @property
    def text(self) -> str:
        """The action as Prolog writes it, e.g. ``move(t3, home, rack(slot_1))``."""
        return format_term(Term(self.action, self.args)) if self.args else self.action


@dataclass(frozen=True)
class OperationPlan:
    """The plan of one measurement, and where it came from.

    macrop_name: the MACROP that was applied (source MACROP) or learned from this plan
    (source SCRATCH); None for an empty plan.  seconds: wall time of the facade call.
    """

    measurement: str
    steps: tuple[PlanStep, ...]
    source: PlanSource
    macrop_name: str | None
    seconds: float
    initial_state: WorldState
    final_state: WorldState

    @property
    def matched(self) -> bool:
        """Whether a stored MACROP matched (no planning from scratch)."""
        return self.source is PlanSource.MACROP

    def to_dict(self) -> dict[str, Any]:
        return {
            "measurement": self.measurement,
            "source": self.source.value,
            "matched": self.matched,
            "macrop": self.macrop_name,
            "seconds": self.seconds,
            "initial_state": self.initial_state.to_dict(),
            "final_state": self.final_state.to_dict(),
            "steps": [
                {
                    "number": s.number,
                    "action": s.action,
                    "args": [format_term(a) for a in s.args],
                    "text": s.text,
                    "predecessors": list(s.predecessors),
                }
                for s in self.steps
            ],
        }


@dataclass(frozen=True)
class StoreCounts:
    """Lookups made in a store, and how many found a MACROP (hits) or did not (misses)."""

    lookups: int
    hits: int
    misses: int


@dataclass(frozen=True)
class MacropInfo:
    """One MACROP of a store: learned (``m<N>``) or hand-written (``kb:<name>``)."""

    name: str
    functor: str
    steps: int
    hits: int
    purpose: str

    @property
    def learned(self) -> bool:
        return not self.name.startswith("kb:")


def format_term(value: Any) -> str:
    """A term as text, ``name(arg, ...)``; atoms and numbers as they are."""
    if isinstance(value, Term):
        return f"{value.name}({', '.join(format_term(a) for a in value.args)})"
    if isinstance(value, list):
        return "[" + ", ".join(format_term(a) for a in value) + "]"
    return str(value)


def macrop_name(macrop_id: Any) -> str:
    """The user-facing name of a MACROP id: ``m3`` for 3, ``kb:measured`` for kb(measured)."""
    if isinstance(macrop_id, Term) and macrop_id.name == "kb":
        return f"kb:{macrop_id.args[0]}"
    return f"m{macrop_id}"


def macrop_id(name: str) -> Any:
    """The store's id of a MACROP name (inverse of :func:`macrop_name`); ValueError if malformed."""
    text = name.strip()
    if text.startswith("kb:") and len(text) > 3:
        return Term("kb", (text[3:],))
    digits = text[1:] if text[:1] in ("m", "M") else text
    if digits.isdigit() and int(digits) > 0:
        return int(digits)
    raise ValueError(f"not a MACROP name: {name!r} (expected m<N> or kb:<name>)")


# -- templates ---------------------------------------------------------------------

_Builder = Callable[[list[Any]], Any]


def _builder(template: Any) -> _Builder:
    """A function from the MACROP's bindings to the term `template` with them plugged in."""
    if isinstance(template, Term):
        if template.name == "$VAR" and len(template.args) == 1 and isinstance(template.args[0], int):
            index = template.args[0]
            return lambda values: values[index]
        name = template.name
        parts = [_builder(a) for a in template.args]
        return lambda values: Term(name, tuple(p(values) for p in parts))
    if isinstance(template, list):
        parts = [_builder(a) for a in template]
        return lambda values: [p(values) for p in parts]
    return lambda values: template


@dataclass(frozen=True)
class _Template:
    """A MACROP's plan and overall adders, ready to be plugged with bindings."""

    nvars: int
    steps: tuple[tuple[int, str, tuple[_Builder, ...], tuple[int, ...]], ...]
    at: _Builder | None = None       # the final pose, from an adder at(Arm, Pose)
    holding: _Builder | None = None  # the final tool, from an adder holding(Arm, Tool)

    @classmethod
    def from_term(cls, template: Term) -> "_Template":
        nvars, steps, adders = template.args
        compiled = []
        for step in steps:
            number, action, preds = step.args
            if isinstance(action, Term):
                compiled.append((number, action.name, tuple(_builder(a) for a in action.args), tuple(preds)))
            else:
                compiled.append((number, action, (), tuple(preds)))
        at = holding = None
        for adder in adders:
            if isinstance(adder, Term) and adder.name == "at" and len(adder.args) == 2:
                at = _builder(adder.args[1])
            elif isinstance(adder, Term) and adder.name == "holding" and len(adder.args) == 2:
                holding = _builder(adder.args[1])
        return cls(int(nvars), tuple(compiled), at, holding)

    def plug(self, values: list[Any]) -> tuple[PlanStep, ...]:
        if len(values) != self.nvars:
            raise ValueError(f"MACROP template has {self.nvars} variables, got {len(values)} values")
        return tuple(
            PlanStep(number, action, tuple(b(values) for b in builders), preds)
            for number, action, builders, preds in self.steps
        )

    def final_state(self, state: WorldState, values: list[Any]) -> WorldState:
        pose = Pose.from_term(self.at(values)) if self.at else state.pose
        if self.holding:
            tool = self.holding(values)
            holding = None if tool == NOTHING else tool
        else:
            holding = state.holding
        return WorldState(state.arm, pose, holding)


# -- the planner -------------------------------------------------------------------


@dataclass
class OperationPlanner:
    """The Operation Planner over the knowledge base `kb` and the MACROP store `path`.

    Opens the store (an empty one if the file does not exist); use as a context manager
    or call :meth:`close` to save the counts.  Not thread-safe: one planner per thread.
    """

    kb: "KnowledgeBase"
    path: Path
    _file: str = field(init=False, repr=False)
    _templates: dict[tuple[int, Any], _Template] = field(init=False, repr=False, default_factory=dict)

    def __post_init__(self) -> None:
        self.path = Path(self.path).expanduser().resolve()
        self._file = str(self.path)
        self.kb.once("macrop", "open_store", self._file)

    def __enter__(self) -> "OperationPlanner":
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # -- planning --------------------------------------------------------------------

    def plan_measurement(
        self, spec: "MeasurementSpec", state: WorldState, *, from_scratch: bool = False
    ) -> OperationPlan:
        """The plan that takes measurement `spec` from `state`.

        MACROP lookup first; when no MACROP applies (or `from_scratch`), the Task
        Planner plans from scratch and the plan is generalized and stored.  Raises
        :class:`NoPlanError` when there is no plan.
        """
        start = time.perf_counter()
        mode = "from_scratch" if from_scratch else "lookup_first"
        solution = self.kb.once(
            "macrop", "measurement_plan", self._file, spec.id, spec.kind.value,
            state.arm, state.pose.to_flat(), state.holding_atom(), mode, Var("R"),
        )
        reply = solution["R"] if solution else None
        if not reply or reply[0] == "no_plan":
            raise NoPlanError(spec.id, reply[1] if reply else "the planner failed")
        source, generation, mid, values = reply
        if mid == "none":
            steps: tuple[PlanStep, ...] = ()
            final, name = state, None
        else:
            key = (generation, mid)
            template = self._templates.get(key)
            if template is None:
                template = self._template(mid)
                self._templates[key] = template
                if source == "scratch":
                    self.save()  # a MACROP new to this planner: keep it even if we crash
            steps = template.plug(values)
            final, name = template.final_state(state, values), macrop_name(mid)
        return OperationPlan(
            measurement=spec.id,
            steps=steps,
            source=PlanSource(source),
            macrop_name=name,
            seconds=time.perf_counter() - start,
            initial_state=state,
            final_state=final,
        )

    def _template(self, mid: Any) -> _Template:
        solution = self.kb.once("macrop", "macrop_template", self._file, mid, Var("T"))
        return _Template.from_term(solution["T"])

    # -- the store -------------------------------------------------------------------

    def counts(self) -> StoreCounts:
        """The lookups, hits and misses of the store."""
        s = self.kb.once("macrop", "store_counts", self._file, Var("L"), Var("H"), Var("M"))
        return StoreCounts(int(s["L"]), int(s["H"]), int(s["M"]))

    def macrops(self) -> list[MacropInfo]:
        """The MACROPs of the store, learned and hand-written, in lookup order."""
        s = self.kb.once("macrop", "macrop_rows", self._file, Var("Rows"))
        return [
            MacropInfo(macrop_name(mid), str(functor), int(steps), int(hits), str(purpose))
            for mid, functor, steps, hits, purpose in s["Rows"]
        ]

    def macrop_text(self, name: str) -> str:
        """MACROP `name` (``m3``, ``3`` or ``kb:measured``) as Prolog text, Figure 4 style.

        Raises ValueError for a malformed name, KeyError for an unknown one.
        """
        mid = macrop_id(name)
        known = {m.name for m in self.macrops()}
        if macrop_name(mid) not in known:
            raise KeyError(name)
        s = self.kb.once("macrop", "macrop_text", self._file, mid, Var("T"))
        return str(s["T"])

    def clear(self) -> int:
        """Forget the learned MACROPs and the counts, and save; returns how many were forgotten."""
        learned = sum(1 for m in self.macrops() if m.learned)
        self.kb.once("macrop", "clear_store", self._file)
        self._templates.clear()
        self.save()
        return learned

    def save(self) -> None:
        """Write the store to its file (atomically)."""
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self.kb.once("macrop", "save_store", self._file)

    def close(self) -> None:
        """Save the store and forget it."""
        self.save()
        self.kb.once("macrop", "close_store", self._file)
