"""The Prolog bridge: typed calls, safe user queries, load errors, threads."""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor

import pytest

from ita.errors import KBLoadError, PrologError, QueryLimitExceeded, QueryRefused
from ita.logic import Severity, Str, Term, Var


def test_call_returns_python_values(knowledge_base):
    assert knowledge_base.call("world", "type", Var("T"), "us_tool") == [
        {"T": "us_probe_1"},
        {"T": "us_probe_2"},
    ]
    assert knowledge_base.once("world", "location", "slra_1", Var("W")) == {
        "W": Term("in_rack", ("slot_3",))
    }
    assert knowledge_base.once("world", "weight", "slra_1", Var("Kg")) == {"Kg": 6.0}
    assert knowledge_base.once("world", "type", "hammer", Var("T")) is None


def test_compound_and_list_arguments_are_passed_as_terms(knowledge_base):
    solution = knowledge_base.once("lists", "append", ["a", Term("f", (1, "b"))], [2], Var("L"))
    assert solution == {"L": ["a", Term("f", (1, "b")), 2]}
    shared = knowledge_base.once("system", "=", Var("X"), Term("f", (Var("Y"), Var("Y"))))
    inner = shared["X"].args
    assert isinstance(shared["Y"], Var) and inner == (shared["Y"], shared["Y"])
    assert knowledge_base.call("lists", "member", Var("X"), ["a", "b", "c"], limit=2) == [
        {"X": "a"},
        {"X": "b"},
    ]


@pytest.mark.parametrize(
    "text",
    ["it's", "us_probe_1), halt, (", "two words", "'quoted'", 'double "q"', "ünïcödé"],
)
def test_atoms_with_quotes_and_spaces_are_data_not_code(knowledge_base, text):
    assert knowledge_base.once("system", "=", Var("X"), text) == {"X": text}
    assert knowledge_base.call("world", "type", text, Var("T")) == []
    # the process and the knowledge base are still there
    assert knowledge_base.holds("world", "available", "us_probe_1")


def test_prolog_error_becomes_project_error(knowledge_base):
    with pytest.raises(PrologError, match="tool") as info:
        knowledge_base.call("world", "set_tool_condition", "hammer", "ok")
    assert "set_tool_condition" in info.value.goal


def test_concurrent_calls_from_threads(knowledge_base):
    def work(i: int) -> tuple[int, list]:
        tool = ("us_probe_1", "slra_1")[i % 2]
        return i, knowledge_base.call("world", "type", tool, Var("T"))

    with ThreadPoolExecutor(max_workers=8) as pool:
        results = list(pool.map(work, range(400)))
    for i, solutions in results:
        assert solutions == [{"T": ("us_tool", "slra_tool")[i % 2]}]


def test_user_queries_from_threads_respect_limits(knowledge_base):
    def work(i: int):
        if i % 2:
            with pytest.raises(QueryLimitExceeded):
                knowledge_base.run_user_query("repeat, fail", inference_limit=20_000)
            return None
        return knowledge_base.run_user_query("type(X, arm)").rows

    with ThreadPoolExecutor(max_workers=4) as pool:
        results = list(pool.map(work, range(20)))
    assert results[0::2] == [(("t3",),)] * 10


def test_user_query_answers(knowledge_base):
    result = knowledge_base.run_user_query("type(X, us_tool), weight(X, W)")
    assert result.variables == ("X", "W")
    assert result.rows == (("us_probe_1", "1.5"), ("us_probe_2", "1.5"))
    assert not result.truncated


def test_user_query_limit_truncates(knowledge_base):
    result = knowledge_base.run_user_query("type(X, Y)", limit=2)
    assert len(result.rows) == 2 and result.truncated


@pytest.mark.parametrize(
    ("goal", "reason"),
    [
        ("shell(ls)", "shell/1"),
        ("assertz(world:foo)", "read-only"),
        ("halt", "halt/0"),
        ("open('/etc/passwd', read, S)", "open"),
        ("consult('/tmp/x.pl')", "consult/1"),
        ("type(X,", "syntax error"),
    ],
)
def test_unsafe_or_malformed_goals_are_refused(knowledge_base, goal, reason):
    with pytest.raises(QueryRefused) as info:
        knowledge_base.run_user_query(goal)
    message = str(info.value)
    assert reason in message and "\n" not in message


def test_user_query_cannot_change_the_knowledge_base(knowledge_base):
    result = knowledge_base.run_user_query(
        "set_tool_condition(us_probe_1, broken), \\+ available(us_probe_1)"
    )
    assert result.succeeded  # inside the query the change is visible...
    assert knowledge_base.holds("world", "available", "us_probe_1")  # ...and then gone


def test_looping_goal_is_stopped_by_inference_limit(knowledge_base):
    with pytest.raises(QueryLimitExceeded, match="inference limit"):
        knowledge_base.run_user_query("repeat, fail", inference_limit=100_000)


def test_looping_goal_is_stopped_by_time_limit(knowledge_base):
    with pytest.raises(QueryLimitExceeded, match="time limit"):
        knowledge_base.run_user_query("repeat, fail", time_limit=0.2, inference_limit=10**12)


def test_explain_gives_multi_level_proof_tree(knowledge_base):
    tree = knowledge_base.explain("available(us_probe_1)")
    assert tree is not None and tree.goal == "available(us_probe_1)"
    (rule,) = tree.children
    assert rule.kind == "rule" and rule.location.file.endswith("world.pl")
    condition = rule.children[0]
    assert condition.goal == "tool_condition(us_probe_1, ok)"
    assert any(grandchild.kind in ("rule", "fact") for grandchild in condition.children)
    assert knowledge_base.explain("available(hammer)") is None


def test_check_is_clean_on_the_real_knowledge_base(knowledge_base):
    assert knowledge_base.check() == []


def test_list_predicates_shows_world_with_pldoc(knowledge_base):
    docs = {d.indicator: d for d in knowledge_base.list_predicates()}
    available = docs["world:available/1"]
    assert available.mode.startswith("available(?Tool)")
    assert "condition is `ok`" in available.summary
    assert all(d.summary for d in docs.values() if d.module == "world")


def test_syntax_error_raises_with_file_line_column(run_python, broken_kb):
    code = (
        "from pathlib import Path\n"
        "from ita.errors import KBLoadError\n"
        "from ita.logic.bridge import KnowledgeBase\n"
        f"try:\n    KnowledgeBase(kb_dir=Path({str(broken_kb)!r}))\n"
        "except KBLoadError as exc:\n    print(exc)\n"
        "else:\n    print('LOADED')\n"
        "kb = KnowledgeBase()\n"  # the real one still loads, and nothing of the broken file stays
        "print('half-loaded' if kb.holds('system', 'current_predicate', "
        "__import__('ita.logic', fromlist=['Term']).Term(':', ('broken_kb', "
        "__import__('ita.logic', fromlist=['Term']).Term('/', ('q', 1))))) else 'clean')\n"
    )
    proc = run_python("-c", code)
    assert proc.returncode == 0, proc.stderr
    assert f"{broken_kb / 'broken_kb.pl'}:3:11" in proc.stdout
    assert "Syntax error" in proc.stdout or "syntax" in proc.stdout.lower()
    assert "LOADED" not in proc.stdout
    assert proc.stdout.strip().endswith("clean")


def test_load_failure_is_a_kb_load_error():
    from ita.errors import Location
    from ita.logic.bridge import KBLoadFailed
    from ita.logic.model import Diagnostic

    error = KBLoadFailed([Diagnostic(Severity.ERROR, Location("/x/kb/a.pl", 3, 11), "boom")])
    assert isinstance(error, KBLoadError)
    assert "/x/kb/a.pl:3:11: boom" in str(error)


def test_world_updates_through_the_bridge_persist_until_reset(knowledge_base):
    try:
        knowledge_base.call("world", "set_tool_condition", "slra_1", "broken")
        assert not knowledge_base.holds("world", "available", "slra_1")
        assert knowledge_base.once("world", "replacement", "slra_1", Var("S")) == {"S": "slra_2"}
    finally:
        knowledge_base.call("world", "reset_world")
    assert knowledge_base.holds("world", "available", "slra_1")


# -- values cross the bridge as data ------------------------------------------------

_TRICKY_ATOMS = [
    "it's", "'", '"', "\\", "a\\'b", "two words", "a\nb", "tab\t", "\x00", "a\x00b", "\x01\x7f",
    "ünïcödé", "Ünï", "Δ", "→", "😀", "x\u00a0y", "\u2028", "", "[]", "{}", ",", "|", ";", "!",
    "_x", "X", "-", "a.b", ":-", "\\+", "=..", "'$VAR'", "0'a", "1", "-1", "1.0Inf", "a:b",
    "halt", "'), halt, ('", "\"), halt, (\"", "').\nhalt.\n('", "0x1F", "/*", "%", "`x`",
]


@pytest.mark.parametrize("text", _TRICKY_ATOMS)
def test_any_atom_round_trips_exactly(knowledge_base, text):
    solution = knowledge_base.once("system", "atom_length", text, Var("N"))
    assert solution == {"N": len(text)}  # one atom of exactly these characters
    assert knowledge_base.once("system", "=", Var("X"), text) == {"X": text}
    term = knowledge_base.once("system", "=", Var("X"), Term(text, (text, [text])))
    assert term == {"X": Term(text, (text, [text]))}


@pytest.mark.parametrize("text", _TRICKY_ATOMS)
def test_strings_round_trip_and_stay_strings(knowledge_base, text):
    assert knowledge_base.once("system", "string", Str(text)) == {}
    assert knowledge_base.once("system", "string_length", Str(text), Var("N")) == {"N": len(text)}
    assert knowledge_base.once("system", "=", Var("X"), Str(text)) == {"X": text}


def test_injection_attempts_run_nothing(knowledge_base):
    attempts = [
        "x), halt, (x", "x')), halt, (('x", "x\").\nhalt.\n", "halt", Term("halt", (0,)),
        Term(":", ("system", "halt")), Str("halt"), [Term("shell", ("rm -rf /",))],
    ]
    for value in attempts:
        # passed as data to a goal that only compares: never called
        assert knowledge_base.once("system", "==", value, "other") is None
        expected = value.text if isinstance(value, Str) else value
        assert knowledge_base.once("system", "=", Var("X"), value) == {"X": expected}
    # module and predicate names are names, not code
    with pytest.raises(PrologError, match="Unknown procedure"):
        knowledge_base.call("system", "true), halt, (true")
    with pytest.raises(PrologError, match="Unknown procedure"):
        knowledge_base.call("system:halt, x", "no_such_predicate")
    assert knowledge_base.holds("world", "available", "us_probe_1")  # still here


@pytest.mark.parametrize(
    "value",
    [0, 1, -5, 2**62, -(2**63), 2**63, 2**100, -(2**70), 1.5, -0.0, 1e20, 1e-7, 5e-324, 1.7976931348623157e308,
     0.1, True, False, [], [1, [2, []]], ["a", 1, 2.5, [Term("f", ("x",))]],
     Term("f", (1, "a", [2])), Term(":", ("a", "b")), Term("[|]", ("a", "b")), Term("{}", ("a",)),
     Term("-", (1,)), Term("$VAR", (1,)), Term("$VAR", ("A",)), Term("it's", ("x",))],
)
def test_values_round_trip(knowledge_base, value):
    expected = {True: "true", False: "false"}.get(value, value) if isinstance(value, bool) else value
    solution = knowledge_base.once("system", "=", Var("X"), value)
    assert solution == {"X": expected}
    assert type(solution["X"]) is type(expected)


def test_tuples_are_lists_and_special_floats_cross(knowledge_base):
    assert knowledge_base.once("system", "=", Var("X"), ("a", (1, 2))) == {"X": ["a", [1, 2]]}
    inf = knowledge_base.once("system", "=", Var("X"), [float("inf"), float("-inf")])
    assert inf == {"X": [float("inf"), float("-inf")]}
    nan = knowledge_base.once("system", "=", Var("X"), float("nan"))["X"]
    assert nan != nan
    assert knowledge_base.once("system", "is", Var("X"), Term("**", (2, 200))) == {"X": 2**200}


def test_unsupported_values_are_refused_before_prolog(knowledge_base):
    for value in (None, {"a": 1}, {1, 2}, object()):
        with pytest.raises(TypeError):
            knowledge_base.once("system", "=", Var("X"), value)
    with pytest.raises(TypeError):
        knowledge_base.once("system", None)
    assert knowledge_base.holds("system", "true")  # nothing left half-open


def test_variables_are_shared_by_name_and_unbound_ones_come_back(knowledge_base):
    solution = knowledge_base.once("system", "=", Term("f", (Var("A"), Var("B"))), Term("f", (Var("B"), 1)))
    assert solution == {"A": 1, "B": 1}
    assert knowledge_base.once("system", "=", Var("_"), 1) == {}  # _-names are not reported
    assert knowledge_base.once("system", "=", Var("lower"), 3) == {"lower": 3}
    (a, b) = knowledge_base.once("system", "length", Var("L"), 2)["L"]
    assert isinstance(a, Var) and isinstance(b, Var) and a != b
    partial = knowledge_base.once("system", "=", Var("X"), Term("[|]", ("a", Var("T"))))
    assert partial["X"] == Term("[|]", ("a", partial["T"]))
    # an unbound variable keeps its name across solutions, as in the goal
    rows = knowledge_base.call("lists", "member", Var("X"), ["a", Var("Y"), 3])
    assert rows[0]["Y"] == rows[2]["Y"] and rows[1]["X"] == rows[1]["Y"]


def test_replies_with_all_kinds_of_terms(knowledge_base):
    solution = knowledge_base.once(
        "system", "term_to_atom", Var("T"), "f(X, Y, \"s\", 'A b', [1|Z], {x}, 'q''s', -(1), - 1, a:b, 1r3)"
    )
    t = solution["T"]
    assert t.name == "f" and isinstance(t.args[0], Var) and t.args[0] != t.args[1]
    assert t.args[2:5] == ("s", "A b", Term("[|]", (1, t.args[4].args[1])))
    assert t.args[5:] == (Term("{}", ("x",)), "q's", Term("-", (1,)), Term("-", (1,)), Term(":", ("a", "b")),
                          1 / 3)
    assert knowledge_base.once("system", "atom_codes", Var("A"), [0, 97, 10, 39]) == {"A": "\x00a\n'"}
    stream = knowledge_base.once("system", "current_output", Var("S"))["S"]
    assert isinstance(stream, str) and stream.startswith("<stream>(")
    with pytest.raises(PrologError, match="cannot read"):
        knowledge_base.once("system", "term_to_atom", Var("T"), "_{a:1}")  # dicts are not supported


def test_goal_output_is_not_mixed_into_the_reply(knowledge_base, capfd):
    assert knowledge_base.call("system", "format", "hello ~w~n", [Str("world")]) == [{}]
    assert knowledge_base.call("lists", "member", Var("X"), [1, 2], limit=None) == [{"X": 1}, {"X": 2}]


def test_concurrent_calls_with_many_values(knowledge_base):
    def work(i: int):
        text = f"it's {i}\n" + "ü" * (i % 5)
        return knowledge_base.once("system", "=", Var("X"), [text, i, float(i), Term("f", (text,))])

    with ThreadPoolExecutor(max_workers=6) as pool:
        results = list(pool.map(work, range(300)))
    for i, solution in enumerate(results):
        text = f"it's {i}\n" + "ü" * (i % 5)
        assert solution == {"X": [text, i, float(i), Term("f", (text,))]}


def test_many_distinct_atoms_stay_correct(knowledge_base):
    """More distinct atoms than the bridge keeps handles for: each is still itself."""
    for i in range(9000):
        text = f"atom_{i}_é"
        assert knowledge_base.once("system", "atom_length", text, Var("N")) == {"N": len(text)}
    assert knowledge_base.once("system", "=", Var("X"), ["atom_1_é", "us_probe_1"]) == {
        "X": ["atom_1_é", "us_probe_1"]
    }
