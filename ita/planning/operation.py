"""The Operation Planner's facade: one call per measurement.

:class:`OperationPlanner` holds a store of learned MACROPs (a Prolog file, opened in
memory by prolog/macrop.pl) and plans a measurement with one bridge call to
``macrop:measurement_plan/9``, which tries MACROP lookup and otherwise plans from
scratch, generalizes the plan and stores the MACROP.  The reply is compact: the
MACROP's number and the values of its variables.  The facade plugs them into the
MACROP's plan template, fetched once per MACROP and cached, so a lookup costs one
small bridge call (every atom that crosses the bridge costs microseconds).

The store is saved (atomically, by Prolog) when a new MACROP is learned and on
:meth:`OperationPlanner.close`, which also saves the hit and miss counts.
"""

from __future__ import annotations

import time
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from enum import Enum
from operator import itemgetter
from pathlib import Path
from typing import TYPE_CHECKING, Callable

from ita.errors import ItaError, NoSpaceLeft, PrologError
from ita.files.atomic import store_name
from ita.logic.json_value import JsonObject
from ita.logic.terms import Term, TermValue, Var
from ita.paths import ita_home
from ita.planning.state import NOTHING, Place, PoseKind, QualitativePose, WorldState

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
    return ita_home() / "macrops" / f"{store_name(part_name)}.pl"


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
    args: tuple[TermValue, ...]
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

    def to_dict(self) -> JsonObject:
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


def format_term(value: object) -> str:
    """A term as text, ``name(arg, ...)``; atoms, numbers and any other value as ``str`` gives them."""
    if isinstance(value, Term):
        return f"{value.name}({', '.join(format_term(a) for a in value.args)})"
    if isinstance(value, list):
        return "[" + ", ".join(format_term(a) for a in value) + "]"
    return str(value)


def macrop_name(macrop_id: TermValue) -> str:
    """The user-facing name of a MACROP id: ``m3`` for 3, ``kb:measured`` for kb(measured)."""
    if isinstance(macrop_id, Term) and macrop_id.name == "kb":
        return f"kb:{macrop_id.args[0]}"
    return f"m{macrop_id}"


def macrop_id(name: str) -> int | Term:
    """The store's id of a MACROP name (inverse of :func:`macrop_name`); ValueError if malformed."""
    text = name.strip()
    if text.startswith("kb:") and len(text) > 3:
        return Term("kb", (text[3:],))
    digits = text[1:] if text[:1] in ("m", "M") else text
    if digits.isdigit() and int(digits) > 0:
        return int(digits)
    raise ValueError(f"not a MACROP name: {name!r} (expected m<N> or kb:<name>)")


# -- templates ---------------------------------------------------------------------

#: a MACROP's bindings (its variables' values, in order) -> a term of its plan
_Builder = Callable[[list[TermValue]], TermValue]


def _builder(template: TermValue) -> tuple[_Builder, bool]:
    """A function from the MACROP's bindings to the term `template` with them plugged in,
    and whether `template` is ground (then the function returns one shared value)."""
    if isinstance(template, Term):
        index = _variable_index(template)
        if index is not None:
            return itemgetter(index), False
        name = template.name
        parts = [_builder(a) for a in template.args]
        if all(ground for _, ground in parts):
            value = Term(name, tuple(p([]) for p, _ in parts))
            return (lambda values: value), True
        builders = [p for p, _ in parts]
        return (lambda values: Term(name, tuple([p(values) for p in builders]))), False
    if isinstance(template, list):
        parts = [_builder(a) for a in template]
        builders = [p for p, _ in parts]
        # not ground: a list is mutable, so each plan gets its own, as before
        return (lambda values: [p(values) for p in builders]), False
    return (lambda values: template), True


def _step_builder(number: int, action: str, args: list[TermValue], preds: tuple[int, ...]
                  ) -> Callable[[list[TermValue]], PlanStep]:
    """A function from the MACROP's bindings to its step `number`."""
    parts = [_builder(a) for a in args]
    builders = [p for p, _ in parts]
    if all(ground for _, ground in parts):
        step = PlanStep(number, action, tuple(p([]) for p in builders), preds)
        return lambda values: step
    if len(args) > 1 and all(_variable_index(a) is not None for a in args):
        # the commonest step: every argument a variable; one C call picks them all
        pick = itemgetter(*(_variable_index(a) for a in args))
        return lambda values: PlanStep(number, action, pick(values), preds)
    return lambda values: PlanStep(number, action, tuple([p(values) for p in builders]), preds)


def _variable_index(template: TermValue) -> int | None:
    """N for a template variable ``'$VAR'(N)``, else None."""
    if (isinstance(template, Term) and template.name == "$VAR" and len(template.args) == 1
            and isinstance(template.args[0], int)):
        return template.args[0]
    return None


def _pose_builder(template: TermValue) -> Callable[[list[TermValue]], QualitativePose]:
    """A function from the MACROP's bindings to the pose `template`, built directly
    (the same value and errors as ``QualitativePose.from_term`` of the plugged term)."""
    build, ground = _builder(template)
    if ground:
        try:
            constant = QualitativePose.from_term(build([]))
        except ValueError:
            pass
        else:
            return lambda values: constant
    if isinstance(template, Term) and len(template.args) == 1 and template.name in _POSE_KINDS:
        kind = _POSE_KINDS[template.name]
        place = template.args[0]
        if isinstance(place, Term) and len(place.args) == 1 and place.name != "$VAR":
            name, (arg_build, _) = place.name, _builder(place.args[0])

            def pose(values: list[TermValue]) -> QualitativePose:
                arg = arg_build(values)
                if isinstance(arg, str):
                    return QualitativePose(kind, Place(name, arg))
                return QualitativePose.from_term(build(values))  # raises the error it always raised

            return pose
    return lambda values: QualitativePose.from_term(build(values))


_POSE_KINDS = {k.value: k for k in PoseKind}
_SOURCES = {s.value: s for s in PlanSource}


@dataclass(frozen=True)
class _Template:
    """A MACROP's plan and overall adders, ready to be plugged with bindings."""

    name: str                        # the MACROP's name, e.g. m3
    nvars: int
    steps: tuple[Callable[[list[TermValue]], PlanStep], ...]
    at: Callable[[list[TermValue]], QualitativePose] | None = None  # the final pose, from an adder at(Arm, QualitativePose)
    holding: _Builder | None = None  # the final tool, from an adder holding(Arm, Tool)

    @classmethod
    def from_term(cls, name: str, template: Term) -> "_Template":
        nvars, steps, adders = template.args
        compiled = []
        for step in steps:
            number, action, preds = step.args
            if isinstance(action, Term):
                compiled.append(_step_builder(number, action.name, list(action.args), tuple(preds)))
            else:
                compiled.append(_step_builder(number, action, [], tuple(preds)))
        at = holding = None
        for adder in adders:
            if isinstance(adder, Term) and adder.name == "at" and len(adder.args) == 2:
                at = _pose_builder(adder.args[1])
            elif isinstance(adder, Term) and adder.name == "holding" and len(adder.args) == 2:
                holding, _ = _builder(adder.args[1])
        return cls(name, int(nvars), tuple(compiled), at, holding)

    def plug(self, values: list[TermValue]) -> tuple[PlanStep, ...]:
        if len(values) != self.nvars:
            raise ValueError(f"MACROP template has {self.nvars} variables, got {len(values)} values")
        return tuple([step(values) for step in self.steps])

    def final_state(self, state: WorldState, values: list[TermValue]) -> WorldState:
        pose = self.at(values) if self.at else state.pose
        if self.holding:
            tool = self.holding(values)
            assert isinstance(tool, str)  # holding(Arm, Tool): a tool's name, or none
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
    _templates: dict[tuple[int, int | Term], _Template] = field(init=False, repr=False, default_factory=dict)

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
        self, spec: "MeasurementSpec", state: WorldState, tool: str, *, from_scratch: bool = False
    ) -> OperationPlan:
        """The plan that takes measurement `spec` with `tool` from `state`.

        `tool` is the Sequence Planner's choice (the tool rules of kb/tools.pl); the plan
        measures with it, whatever the arm holds.  MACROP lookup first; when no MACROP
        applies (or `from_scratch`), the Task Planner plans from scratch and the plan is
        generalized and stored.  Raises :class:`NoPlanError` when there is no plan, and
        :class:`~ita.errors.PrologError` for a tool that cannot take measurements of the
        spec's kind.
        """
        start = time.perf_counter()
        mode = "from_scratch" if from_scratch else "lookup_first"
        solution = self.kb.once(
            "macrop", "measurement_plan", self._file, spec.id, spec.kind.value, tool,
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
            final, name = template.final_state(state, values), template.name
        return OperationPlan(
            measurement=spec.id,
            steps=steps,
            source=_SOURCES.get(source) or PlanSource(source),
            macrop_name=name,
            seconds=time.perf_counter() - start,
            initial_state=state,
            final_state=final,
        )

    def plan_goals(self, goals: Sequence[TermValue], state: WorldState, *, name: str = "") -> OperationPlan:
        """A plan that achieves `goals` (terms such as ``Term("calibrated", ("us_probe_1",))``)
        from `state`: MACROP lookup first, else plan, generalize and store
        (``macrop:goal_plan/6``).  For the Exception Handler's tests and repairs.  Raises
        :class:`NoPlanError` when there is none."""
        start = time.perf_counter()
        solution = self.kb.once("macrop", "goal_plan", self._file, list(goals), state.arm, state.pose.to_flat(),
                                state.holding_atom(), Var("R"))
        reply = solution["R"] if solution else None
        label = name or ", ".join(format_term(g) for g in goals)
        if not reply or reply[0] == "no_plan":
            raise NoPlanError(label, reply[1] if reply else "the planner failed")
        source, plan, pose, holding = reply
        steps = []
        for step in plan:
            number, action, preds = step.args
            if isinstance(action, Term):
                steps.append(PlanStep(int(number), action.name, tuple(action.args), tuple(preds)))
            else:
                steps.append(PlanStep(int(number), str(action), (), tuple(preds)))
        final = WorldState(state.arm, QualitativePose.from_term(pose), None if holding == NOTHING else str(holding))
        return OperationPlan(label, tuple(sorted(steps, key=lambda s: s.number)), _SOURCES.get(source) or
                             PlanSource(source), None, time.perf_counter() - start, state, final)

    def repair_plan(self, plan: OperationPlan, completed: Iterable[int], state: WorldState) -> OperationPlan | None:
        """Plan repair: the steps of the failed `plan` not in `completed`, run from `state`
        (the arm's now) after a plan for the first one's preconditions when they do not
        hold, as one chain; None when they cannot run even so (``macrop:repair_plan/6``:
        then replan)."""
        start = time.perf_counter()
        done = set(completed)
        remaining = [st for st in plan.steps if st.number not in done]
        if not remaining:
            return None
        actions = [Term(st.action, st.args) if st.args else st.action for st in remaining]
        answer = self.kb.once("macrop", "repair_plan", self._file, actions, state.arm, state.pose.to_flat(),
                              state.holding_atom(), Var("R"))
        reply = answer["R"] if answer else None
        if not reply or reply[0] != "ok":
            return None
        _, prefix, pose, holding = reply
        steps: list[PlanStep] = []
        for step in prefix:
            _, action, _ = step.args
            name, args = (action.name, tuple(action.args)) if isinstance(action, Term) else (str(action), ())
            steps.append(PlanStep(len(steps) + 1, name, args, (len(steps),) if steps else ()))
        for st in remaining:
            steps.append(PlanStep(len(steps) + 1, st.action, st.args, (len(steps),) if steps else ()))
        final = WorldState(state.arm, QualitativePose.from_term(pose), None if holding == NOTHING else str(holding))
        return OperationPlan(plan.measurement, tuple(steps), PlanSource.SCRATCH, None, time.perf_counter() - start,
                             state, final)

    def _template(self, mid: int | Term) -> _Template:
        solution = self.kb.one("macrop", "macrop_template", self._file, mid, Var("T"))
        return _Template.from_term(macrop_name(mid), solution["T"])

    # -- the store -------------------------------------------------------------------

    def counts(self) -> StoreCounts:
        """The lookups, hits and misses of the store."""
        s = self.kb.one("macrop", "store_counts", self._file, Var("L"), Var("H"), Var("M"))
        return StoreCounts(int(s["L"]), int(s["H"]), int(s["M"]))

    def macrops(self) -> list[MacropInfo]:
        """The MACROPs of the store, learned and hand-written, in lookup order."""
        s = self.kb.one("macrop", "macrop_rows", self._file, Var("Rows"))
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
        s = self.kb.one("macrop", "macrop_text", self._file, mid, Var("T"))
        return str(s["T"])

    def clear(self) -> int:
        """Forget the learned MACROPs and the counts, and save; returns how many were forgotten."""
        learned = sum(1 for m in self.macrops() if m.learned)
        self.kb.once("macrop", "clear_store", self._file)
        self._templates.clear()
        self.save()
        return learned

    def save(self) -> None:
        """Write the store to its file (atomically); NoSpaceLeft naming it when the disk is
        full (the store's temporary file removed, its file as it was)."""
        self.path.parent.mkdir(parents=True, exist_ok=True)
        try:
            self.kb.once("macrop", "save_store", self._file)
        except PrologError as exc:
            full = NoSpaceLeft.of_message(str(self.path), exc.message)
            if full is None:
                raise
            raise full from None

    def close(self) -> None:
        """Save the store and forget it."""
        self.save()
        self.kb.once("macrop", "close_store", self._file)
