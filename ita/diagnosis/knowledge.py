"""The Exception Handler's calls into Prolog: kb/faults.pl and prolog/diagnosis.pl.

    kn = FaultKnowledge(kb)
    step = kn.step("no_echo", context, counts, results, tests, method="auto")
    step.choice       # ("test", "read_cal_block") | ("isolated", "broken_probe(us_probe_1)") | ("unresolved", ...)
    kn.recovery("dry_couplant(us_probe_1)")   # [Term('achieve', (Term('dispenser_purged', ('us_probe_1',)),))]
    kn.holds_now(Term("spare_left", ("us_probe_1",)))      # a condition of a recovery, on the world model
    kn.update_world(Term("tool_condition", ("us_probe_1", "broken")))

Causes cross the bridge as terms and come back as text for people and the archive
(``broken_probe(us_probe_1)``); :meth:`FaultKnowledge.cause_term` turns the text back.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Literal, TypeAlias, Union

from ita.logic.terms import Term, TermValue, Var
from ita.planning.operation import format_term

if TYPE_CHECKING:
    from ita.logic.bridge import KnowledgeBase

__all__ = ["Choice", "DiagnosisStep", "FaultKnowledge", "TestInfo"]

#: the engine's choice: a test to make (its name), the cause isolated (text), or the
#: causes left unresolved (text)
Choice: TypeAlias = Union[tuple[Literal["test"], str], tuple[Literal["isolated"], str],
                          tuple[Literal["unresolved"], tuple[str, ...]]]


@dataclass(frozen=True)
class TestInfo:
    """A test of kb/faults.pl: its description, own seconds and preconditions (text)."""

    name: str
    description: str
    seconds: float
    needs: tuple[str, ...]


@dataclass(frozen=True)
class DiagnosisStep:
    """One step of a diagnosis: the choice (``test``, ``isolated`` or ``unresolved`` with
    the test name, the cause or the causes left), the decision tree's expected cost, the
    posterior before the results and what remains after them (cause text, probability)."""

    choice: Choice
    expected_s: float
    posterior: tuple[tuple[str, float], ...]
    remaining: tuple[tuple[str, float], ...]


def _pairs(value: Iterable[Term]) -> tuple[tuple[str, float], ...]:
    """``[Cause-P, ...]`` as (cause text, probability) pairs."""
    out = []
    for pair in value:
        cause, p = pair.args
        out.append((format_term(cause), float(p)))
    return tuple(out)


class FaultKnowledge:
    """Bridge calls of the diagnosis: tests, steps of the engine, recoveries."""

    def __init__(self, kb: KnowledgeBase) -> None:
        self.kb = kb
        self._tests: dict[str, TestInfo] | None = None

    def tests(self) -> dict[str, TestInfo]:
        """Every test of kb/faults.pl by name."""
        if self._tests is None:
            rows = self.kb.call("faults", "test", Var("T"), Var("D"), Var("S"))
            out = {}
            for r in rows:
                needs = self.kb.once("faults", "test_needs", r["T"], Var("N"))
                out[str(r["T"])] = TestInfo(str(r["T"]), str(r["D"]), float(r["S"]),
                                            tuple(format_term(n) for n in (needs["N"] if needs else [])))
            self._tests = out
        return self._tests

    def step(self, exception: str, context: list[Term], counts: dict[str, int],
             results: list[tuple[str, str]], tests: list[tuple[str, float]], method: str = "auto") -> DiagnosisStep:
        """The engine's next choice (``diagnosis:step/7``)."""
        counts_t = [Term("-", (k, int(v))) for k, v in sorted(counts.items())]
        results_t = [Term("-", (t, o)) for t, o in results]
        tests_t = [Term("-", (t, float(c))) for t, c in tests]
        solution = self.kb.once("diagnosis", "step", exception, context, counts_t, results_t, tests_t, method,
                                Var("R"))
        if solution is None:
            raise RuntimeError(f"diagnosis:step/7 failed for {exception}")
        choice, expected, posterior, remaining = solution["R"]
        kind = choice.name
        arg = choice.args[0]
        if kind == "test":
            parsed: Choice = ("test", str(arg))
        elif kind == "isolated":
            parsed = ("isolated", format_term(arg))
        else:
            parsed = ("unresolved", tuple(format_term(a) for a in arg))
        return DiagnosisStep(parsed, float(expected), _pairs(posterior), _pairs(remaining))

    def predicts_any(self, test: str, outcome: str, causes: list[str], context: list[Term]) -> bool:
        """Whether one of `causes` (text) predicts `outcome` of `test` (``faults:test_outcome/4``)."""
        for cause in causes:
            solution = self.kb.once("faults", "test_outcome", test, self.cause_term(cause), context, Var("O"))
            if solution is not None and str(solution["O"]) == outcome:
                return True
        return False

    def shows_a_fault(self, test: str, outcome: str) -> bool:
        """Whether some cause of kb/faults.pl predicts `outcome` of `test` (it is a fault's sign)."""
        return self.kb.once("faults", "predicts", test, Var("C"), outcome) is not None

    def recovery(self, cause: str) -> list[TermValue]:
        """The recovery actions of an isolated cause (text as :meth:`step` gives it):
        ``faults:recovery/2``, a variable left for the planner as a :class:`Var`."""
        solution = self.kb.once("faults", "recovery", self.cause_term(cause), Var("A"))
        return list(solution["A"]) if solution else []

    def holds_now(self, condition: TermValue) -> bool:
        """Whether the condition of an ``unless(Condition, Actions)`` recovery action holds
        of the world model now (``faults:holds_now/1``)."""
        return self.kb.holds("faults", "holds_now", condition)

    def update_world(self, change: TermValue) -> None:
        """Make the world model say `change`, a ``world(Change)`` recovery action
        (``faults:world_update/1``)."""
        self.kb.one("faults", "world_update", change)

    @staticmethod
    def cause_term(cause: str) -> str | Term:
        """``broken_probe(us_probe_1)`` -> Term; ``arm_drift`` -> the atom."""
        if "(" in cause and cause.endswith(")"):
            name, _, arg = cause[:-1].partition("(")
            return Term(name, (arg,))
        return cause

    @staticmethod
    def cause_name(cause: str) -> str:
        """The cause's name without its argument (what the learned counts count)."""
        return cause.partition("(")[0]
