"""Attached procedures: Prolog goals answered by Python through the bridge."""

from __future__ import annotations

import math
import threading
import time
from concurrent.futures import ThreadPoolExecutor

import pytest

from ita.errors import PrologError, QueryRefused
from ita.logic import Str, Term, Var
from ita.logic.attached import nondet


def attached(name: str, args: list, result: object) -> Term:
    """The goal ``py_bridge:attached(name, args, result)`` as a term."""
    return Term(":", ("py_bridge", Term("attached", (name, args, result))))


def both(first: Term, second: Term) -> tuple[str, str, Term, Term]:
    """The arguments of kb.once for the conjunction ``first, second``."""
    return ("system", ",", first, second)


def test_semidet_procedure_answers_or_fails(knowledge_base):
    seen = []

    def double(x):
        seen.append(x)
        return 2 * x if x < 100 else None

    with knowledge_base.attached({"double": double}):
        assert knowledge_base.call("py_bridge", "attached", "double", [21], Var("R")) == [{"R": 42}]
        assert knowledge_base.call("py_bridge", "attached", "double", [500], Var("R")) == []
        # a given result is checked by unification
        assert knowledge_base.holds("py_bridge", "attached", "double", [4], 8)
        assert not knowledge_base.holds("py_bridge", "attached", "double", [4], 9)
    assert seen == [21, 500, 4, 4]


def test_nondet_procedure_gives_each_solution_on_backtracking(knowledge_base):
    def divisors(n):
        return (d for d in range(1, n + 1) if n % d == 0)

    with knowledge_base.attached({"divisors": nondet(divisors), "none": nondet(lambda: None)}):
        rows = knowledge_base.call("py_bridge", "attached", "divisors", [12], Var("D"))
        assert [r["D"] for r in rows] == [1, 2, 3, 4, 6, 12]
        assert knowledge_base.call("py_bridge", "attached", "divisors", [7], Var("D"), limit=1) == [{"D": 1}]
        assert knowledge_base.call("py_bridge", "attached", "none", [], Var("D")) == []
        # findall in Prolog sees them all, in order
        found = knowledge_base.once("system", "findall", Var("_D"), attached("divisors", [6], Var("_D")), Var("L"))
        assert found == {"L": [1, 2, 3, 6]}


def test_no_choice_point_after_the_last_solution(knowledge_base):
    """``call_cleanup(G, Det = yes)`` binds Det as soon as G leaves no choice point."""

    def deterministic(goal: Term) -> tuple[str, str, Term, Term]:
        return both(Term("call_cleanup", (goal, Term("=", (Var("Det"), "yes")))), Term("==", (Var("Det"), "yes")))

    with knowledge_base.attached({"one": lambda: "a", "two": nondet(lambda: ["a", "b"])}):
        assert knowledge_base.once(*deterministic(attached("one", [], Var("X")))) == {"X": "a", "Det": "yes"}
        # the first of two leaves a choice point, the last does not
        assert knowledge_base.once(*deterministic(attached("two", [], Var("X")))) == {"X": "b", "Det": "yes"}
        # the check can fail: X = b ; fail leaves a choice point after its last solution
        leaves_one = Term(";", (Term("=", (Var("X"), "b")), "fail"))
        assert knowledge_base.once(*deterministic(leaves_one)) is None


def test_python_exception_is_a_prolog_error_naming_the_procedure(knowledge_base):
    def broken(x):
        raise ValueError(f"no tour through {x}")

    with knowledge_base.attached({"tours": broken}):
        with pytest.raises(PrologError, match=r"Attached procedure tours/1 raised ValueError: no tour through it's") as info:
            knowledge_base.call("py_bridge", "attached", "tours", ["it's"], Var("T"))
        assert isinstance(info.value.__cause__, ValueError)  # the original, for the traceback
        assert "attached(tours" in info.value.goal
        # Prolog can catch it like any error term
        caught = knowledge_base.once("system", "catch", attached("tours", [1], Var("T")),
                                     Term("error", (Term("attached_procedure_error", (Var("PI"), Var("Type"), Var("M"))),
                                                    Var("_"))),
                                     "true")
        assert caught == {"T": caught["T"], "PI": Term("/", ("tours", 1)), "Type": "ValueError",
                          "M": "no tour through 1"}
        assert knowledge_base.holds("world", "available", "us_probe_1")  # the bridge still works


def test_a_result_that_is_no_term_is_an_error_naming_the_procedure(knowledge_base):
    with knowledge_base.attached({"bad": lambda: {"a": 1}, "text": nondet(lambda: "abc")}):
        with pytest.raises(PrologError, match=r"bad/0 raised TypeError: cannot pass dict"):
            knowledge_base.call("py_bridge", "attached", "bad", [], Var("R"))
        with pytest.raises(PrologError, match=r"text/0 raised TypeError: a nondet procedure returns an iterable"):
            knowledge_base.call("py_bridge", "attached", "text", [], Var("R"))


def test_keyboard_interrupt_in_a_procedure_reaches_the_caller(knowledge_base):
    def interrupted():
        raise KeyboardInterrupt

    # even where Prolog catches every error, the interrupt goes on in Python
    with knowledge_base.attached({"stop": interrupted}), pytest.raises(KeyboardInterrupt):
        knowledge_base.call("system", "catch", attached("stop", [], Var("_")), Var("_"), "true")
    assert knowledge_base.holds("system", "true")


def test_procedure_may_call_the_knowledge_base(knowledge_base):
    def usable(tool):
        return "yes" if knowledge_base.holds("world", "available", tool) else None

    def tool_type(tool):
        found = knowledge_base.once("world", "type", tool, Var("T"))
        return found["T"] if found else None

    with knowledge_base.attached({"usable": usable, "type_of": tool_type}):
        assert knowledge_base.once("py_bridge", "attached", "usable", ["us_probe_1"], Var("U")) == {"U": "yes"}
        assert knowledge_base.once("py_bridge", "attached", "usable", ["hammer"], Var("U")) is None
        both_answers = knowledge_base.once(*both(attached("type_of", ["slra_1"], Var("T")),
                                                 attached("usable", ["slra_1"], Var("U"))))
        assert both_answers == {"T": "slra_tool", "U": "yes"}


def test_an_error_of_a_nested_call_names_both(knowledge_base):
    def condition(tool):
        return knowledge_base.call("world", "set_tool_condition", tool, "ok")

    with knowledge_base.attached({"condition": condition}):
        with pytest.raises(PrologError, match=r"condition/1 raised PrologError: world:set_tool_condition") as info:
            knowledge_base.call("py_bridge", "attached", "condition", ["hammer"], Var("R"))
        assert isinstance(info.value.__cause__, PrologError)


def test_deep_nesting_prolog_python_prolog_python(knowledge_base):
    bottom: list[BaseException] = []

    def factorial(n):
        if n == 0:
            if bottom:
                raise bottom[0]
            return 1
        inner = knowledge_base.one("py_bridge", "attached", "factorial", [n - 1], Var("F"))
        return n * inner["F"]

    with knowledge_base.attached({"factorial": factorial}):
        assert knowledge_base.one("py_bridge", "attached", "factorial", [60], Var("F")) == {"F": _factorial(60)}
        # an error at the bottom comes up through every level, each naming the procedure
        bottom.append(ZeroDivisionError("at the bottom"))
        with pytest.raises(PrologError, match="factorial/1 raised PrologError") as info:
            knowledge_base.once("py_bridge", "attached", "factorial", [3], Var("F"))
        assert str(info.value).count("factorial/1 raised") == 4
        assert str(info.value).endswith("factorial/1 raised ZeroDivisionError: at the bottom")
        cause = info.value
        while cause.__cause__ is not None:
            cause = cause.__cause__
        assert cause is bottom[0]
        bottom.clear()
        assert knowledge_base.one("py_bridge", "attached", "factorial", [3], Var("F")) == {"F": 6}


def _factorial(n: int) -> int:
    return 1 if n == 0 else n * _factorial(n - 1)


def test_registration_lasts_for_the_block_only(knowledge_base):
    outer = {"which": lambda: "outer"}
    with knowledge_base.attached(outer):
        with knowledge_base.attached({"which": lambda: "inner", "extra": lambda: 1}):
            assert knowledge_base.once("py_bridge", "attached", "which", [], Var("W")) == {"W": "inner"}
        assert knowledge_base.once("py_bridge", "attached", "which", [], Var("W")) == {"W": "outer"}
        with pytest.raises(PrologError, match="No attached procedure extra/0"):
            knowledge_base.once("py_bridge", "attached", "extra", [], Var("W"))
    with pytest.raises(PrologError, match="No attached procedure which/0"):
        knowledge_base.once("py_bridge", "attached", "which", [], Var("W"))
    # the existence error is an ISO error term that Prolog can catch
    caught = knowledge_base.once("system", "catch", attached("which", [1], Var("_")),
                                 Term("error", (Var("E"), Var("_"))), "true")
    assert caught == {"E": Term("existence_error", ("attached_procedure", Term("/", ("which", 1))))}


def test_registration_is_refused_for_bad_names_or_values(knowledge_base):
    for procedures in ({"": lambda: 1}, {1: lambda: 1}, {"x": 3}):
        with pytest.raises(TypeError), knowledge_base.attached(procedures):
            pass
    with pytest.raises(TypeError):
        nondet(None)


def test_another_thread_sees_none_of_them(knowledge_base):
    with knowledge_base.attached({"mine": lambda: 1}):
        with ThreadPoolExecutor(max_workers=1) as pool:
            future = pool.submit(knowledge_base.once, "py_bridge", "attached", "mine", [], Var("X"))
            with pytest.raises(PrologError, match="No attached procedure mine/0"):
                future.result()
        assert knowledge_base.once("py_bridge", "attached", "mine", [], Var("X")) == {"X": 1}


def test_another_thread_waits_while_one_is_inside_a_procedure(knowledge_base):
    inside = threading.Event()
    events: list[str] = []

    def slow(x):
        inside.set()
        time.sleep(0.3)  # the other thread asks Prolog meanwhile
        events.append("nested call")
        value = knowledge_base.one("system", "=", Var("Y"), [x, "it's"])["Y"]
        events.append("procedure returns")
        return value

    def other() -> list:
        inside.wait(10)
        answers = [knowledge_base.once("system", "=", Var("Z"), [i, "z"]) for i in range(20)]
        events.append("other thread done")
        return answers

    with ThreadPoolExecutor(max_workers=1) as pool:
        future = pool.submit(other)
        with knowledge_base.attached({"slow": slow}):
            result = knowledge_base.once("py_bridge", "attached", "slow", [Str("s")], Var("R"))
        answers = future.result(timeout=30)
    assert result == {"R": ["s", "it's"]}
    assert answers == [{"Z": [i, "z"]} for i in range(20)]
    assert events == ["nested call", "procedure returns", "other thread done"]


def test_threads_each_with_their_own_procedures(knowledge_base):
    def work(i: int):
        def mine(x):
            return knowledge_base.one("system", "=", Var("Y"), Term("f", (i, x)))["Y"]

        with knowledge_base.attached({"mine": mine}):
            return [knowledge_base.once("py_bridge", "attached", "mine", [j], Var("R")) for j in range(5)]

    with ThreadPoolExecutor(max_workers=4) as pool:
        results = list(pool.map(work, range(16)))
    for i, rows in enumerate(results):
        assert rows == [{"R": Term("f", (i, j))} for j in range(5)]


_HOSTILE = [
    "it's", "'), halt, ('", "\"), halt, (\"", "').\nhalt.\n('", "a\x00b", "ünïcödé 😀", "", "[]", "{}",
    "_X", "X", ":-", "\\+", "'$VAR'", "1.0Inf",
    2**200, -(2**100), 2**63, -(2**63), 0, 1.5, -0.0, 5e-324, float("inf"), float("-inf"),
    [], [[[[["deep"]]]]], [1, [2, [3, [4, [5, []]]]]], list(range(500)),
    Term("it's", ("x", [Term("f", (1,))])), Term("halt", (0,)), Term(":", ("system", "halt")),
    Term("[|]", ("a", "b")), Term("$VAR", (1,)), Term("{}", ("a",)), Term("-", (1,)),
]


@pytest.mark.parametrize("value", _HOSTILE)
def test_hostile_values_round_trip_exactly(knowledge_base, value):
    received = []

    def identity(x):
        received.append(x)
        return x

    with knowledge_base.attached({"id": identity}):
        solution = knowledge_base.once("py_bridge", "attached", "id", [value], Var("R"))
        assert solution == {"R": value}
        assert received == [value]  # Python got exactly the value
        assert type(received[0]) is type(value) and type(solution["R"]) is type(value)
        # and what Python gave back is the same term as the one Prolog passed
        assert knowledge_base.holds("py_bridge", "attached", "id", [value], value)


def test_strings_variables_and_nan_cross(knowledge_base):
    received = []

    def pair(x):
        received.append(x)
        return Term("f", (Var("A"), Var("A"), Var("B")))

    with knowledge_base.attached({"pair": pair}):
        solution = knowledge_base.once(*both(attached("pair", [[Str("text"), float("nan"), Var("Free")]],
                                                      Term("f", (Var("X"), Var("Y"), Var("Z")))),
                                             Term("==", (Var("X"), Var("Y")))))
    assert solution is not None and solution["Z"] != solution["X"]
    text, nan, free = received[0]
    assert text == "text" and math.isnan(nan) and isinstance(free, Var)


def test_the_sandbox_cannot_call_attached_procedures(knowledge_base):
    """`ita kb query` runs in a separate swipl: no Python there, and the goal is refused."""
    with knowledge_base.attached({"secret": lambda: "leaked"}):
        for goal in ("py_bridge:attached(secret, [], X)", "attached(secret, [], X)",
                     "py_bridge:py_attached_call(secret, \"[]\", X)"):
            with pytest.raises((QueryRefused, PrologError)):
                knowledge_base.run_user_query(goal)


def test_a_thread_that_prolog_starts_cannot_call_them(knowledge_base):
    """Its call is refused with an error (it runs outside the bridge's lock), and the
    thread that runs the goal goes on."""
    goal = attached("mine", [], Var("_"))
    with knowledge_base.attached({"mine": lambda: 1}):
        joined = knowledge_base.once("system", ",", Term("thread_create", (goal, Var("_Id"))),
                                     Term("thread_join", (Var("_Id"), Var("Status"))))
        assert joined == {"Status": Term("exception", (Term("error", (
            Term("permission_error", ("call", "attached_procedure", "outside_a_bridge_call")),
            joined["Status"].args[0].args[1])),))}
        assert knowledge_base.once("py_bridge", "attached", "mine", [], Var("R")) == {"R": 1}
