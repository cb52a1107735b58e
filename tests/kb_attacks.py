"""The attacks of tests/test_kb_attacks.py: goals a hostile but fair user might type at
`ita kb query`, `ita kb why` or `ita kb shell`.

Each attack is (group, goal, expectation).  `{t}` in a goal stands for the test's own
temporary directory: every file an attack tries to create, change or delete is there, so
the test can check that nothing happened.  Expectations:

- ``refused``: exit 2 with ``error: refused: ...``;
- ``stopped``: exit 2 with ``error: stopped: ...`` (a limit);
- ``clean``: exit 2 with a refusal, a limit or the goal's own error;
- ``harmless``: may succeed or fail (exit 0 or 1): the goal is allowed, and the test
  checks that it changed nothing.
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class Attack:
    group: str
    goal: str
    expect: str = "clean"

    def text(self, tmp: str) -> str:
        return self.goal.replace("{t}", tmp)


GROUPS = ("side effects", "escapes", "thrown formats", "kb changes", "threads", "limits", "memory",
          "deep terms", "encodings")

# --- side effects: files, processes, environment, loading code, leaving -----------------
_SIDE_PRIMITIVES = (
    "shell('touch {t}/pwned')",
    "shell('touch {t}/pwned', _)",
    "shell",
    "process_create(path(touch), ['{t}/pwned'], [])",
    "open('{t}/pwned', write, S), write(S, x), close(S)",
    "open('{t}/victim', append, S), write(S, x), close(S)",
    "open('{t}/victim', write, S)",
    "tell('{t}/pwned')",
    "append('{t}/victim')",
    "see('{t}/victim'), read(X)",
    "read_file_to_string('{t}/victim', S, [])",
    "delete_file('{t}/victim')",
    "make_directory('{t}/pwned')",
    "rename_file('{t}/victim', '{t}/pwned')",
    "copy_file('{t}/victim', '{t}/pwned')",
    "tmp_file_stream(text, F, S)",
    "setenv(ita_attack, 1)",
    "unsetenv('PATH')",
    "working_directory(_, '{t}')",
    "chdir('{t}')",
    "halt",
    "halt(0)",
    "abort",
    "consult('{t}/victim')",
    "ensure_loaded('{t}/victim')",
    "load_files(['{t}/victim'], [])",
    "[user]",
    "qcompile('{t}/victim')",
    "tcp_connect(localhost:1, S, [])",
    "set_stream(user_output, alias(x))",
    "format(user_error, 'x', [])",
    "with_output_to(string(_), shell('touch {t}/pwned'))",
    "use_module(library(process)), process_create(path(touch), ['{t}/pwned'], [])",
    "getenv('HOME', _), shell('touch {t}/pwned')",
)
_SIDE_WRAPPERS = ("{g}", "once(({g}))", "catch(({g}), _, true)")

# --- escapes through meta-calls and messages ---------------------------------------------
_PWN = "shell('touch {t}/pwned')"
_ESCAPES = (
    f"print_message(error, format('~@', [{_PWN}]))",
    f"print_message(informational, format('~@', [{_PWN}]))",
    f"print_message(silent, format('~@', [{_PWN}]))",
    f"F = format('~@', [{_PWN}]), print_message(error, F)",
    f"atom_concat('~', '@', F), print_message(error, format(F, [{_PWN}]))",
    f"atom_codes(F, [0'~, 0'@]), print_message(error, format(F, [{_PWN}]))",
    f"string_concat(\"~\", \"@\", F), print_message(error, format(F, [{_PWN}]))",
    f"message_to_codes(format('~@', [{_PWN}]), [], _)",
    f"print_message_lines(user_error, '', ['~@'-[{_PWN}]])",
    f"format('~@', [{_PWN}])",
    f"format(atom(_), '~@', [{_PWN}])",
    f"format(string(_), \"~@\", [{_PWN}])",
    f"format(codes(_), `~@`, [{_PWN}])",
    f"with_output_to(string(_), format('~@', [{_PWN}]))",
    f"atom_concat('~', '@', F), format(F, [{_PWN}])",
    f"atom_concat('~', '@', F), format(atom(_), F, [{_PWN}])",
    f"G = {_PWN}, call(G)",
    f"G = {_PWN}, G",
    f"X = {_PWN}, findall(_, X, _)",
    f"member(G, [{_PWN}]), call(G)",
    f"maplist(call, [{_PWN}])",
    f"forall(member(G, [{_PWN}]), G)",
    f"foldl([G, _, _]>>call(G), [{_PWN}], _, _)",
    f"[G]>>call(G) = L, call(L, {_PWN})",
    "apply(shell, ['touch {t}/pwned'])",
    "call(shell, 'touch {t}/pwned')",
    "G =.. [shell, 'touch {t}/pwned'], call(G)",
    "functor(G, shell, 1), arg(1, G, 'touch {t}/pwned'), call(G)",
    "term_to_atom(G, 'shell(\\'touch {t}/pwned\\')'), call(G)",
    "term_string(G, \"shell('touch {t}/pwned')\"), call(G)",
    "read_term_from_atom('shell(\\'touch {t}/pwned\\')', G, []), call(G)",
    f"assertion({_PWN})",
    f"assertion((fail, {_PWN}))",
    "system:shell('touch {t}/pwned')",
    "'$syspreds':shell('touch {t}/pwned')",
    "user:shell('touch {t}/pwned')",
    "M = system, M:shell('touch {t}/pwned')",
    f"@({_PWN}, system)",
    f"call_cleanup(true, {_PWN})",
    f"setup_call_cleanup({_PWN}, true, true)",
    f"catch(throw(x), _, {_PWN})",
    f"\\+ \\+ {_PWN}",
    f"not({_PWN})",
    f"ignore({_PWN})",
    f"call_with_depth_limit({_PWN}, 10, _)",
    f"call_with_time_limit(1, {_PWN})",
    f"call_with_inference_limit({_PWN}, 1000, _)",
    f"findall(x, {_PWN}, _)",
    f"aggregate_all(count, {_PWN}, _)",
    f"write_term(x, [portray_goal({_PWN})])",
    "write_term(x, [portray_goal(shell)])",
    "format('~W', [x, [portray_goal(shell)]])",
    f"print_message(error, {_PWN})",
    f"format_predicate('X', {_PWN})",
    "format_predicate('X', shell(_, _))",
    f"expand_goal({_PWN}, G), call(G)",
    f"tabled_call({_PWN})",
    f"snapshot({_PWN})",
    f"at_halt({_PWN})",
    f"prolog_listen(halt, {_PWN})",
    f"freeze(X, {_PWN}), X = 1",
    f"when(nonvar(X), {_PWN}), X = 1",
    f"dif(X, a), put_attr(Y, freeze, {_PWN}), Y = 1",
    f"catch(call_with_time_limit(0.001, repeat), E, (print_message(error, E), {_PWN}))",
)

# --- format directives built at run time, in terms the goal throws -----------------------
# The escape of issue 28: a `~@` made at run time (never in the goal's text) inside a term
# that is thrown, so that turning the exception into text ran the goal.  Each builder
# makes F = '~@'; each payload is a goal that does harm; each wrapper throws a term that
# carries format(F, [Payload]) somewhere a message translation would format it.
_FORMAT_BUILDERS = (
    "X is 63+1, atom_codes(F, [126, X])",
    "atom_codes(F, [0'~, 0'@])",
    "char_code(T, 126), char_code(A, 64), atom_concat(T, A, F)",
    "string_codes(F, [126, 64])",
    "format(atom(F), '~c~c', [126, 64])",
)
_FORMAT_PAYLOADS = (
    "open('{t}/pwned', write, S)",
    "shell('touch {t}/pwned')",
    "delete_file('{t}/victim')",
    "read_file_to_string('/etc/passwd', S, [])",
)
_THROWS = (
    "throw(format(F, [P]))",
    "throw(error(format(F, [P]), _))",
    "throw(error(type_error(format(F, [P]), x), _))",
    "throw(error(domain_error(x, format(F, [P])), _))",
    "throw(error(existence_error(x, y), context(format(F, [P]), _)))",
    "throw(error(foo, context(_, format(F, [P]))))",
    "throw(error(permission_error(a, b, c), context(x/1, format(F, [P]))))",
    "throw(error(syntax_error(format(F, [P])), _))",
    "throw(error(resource_error(format(F, [P])), _))",
    "catch(throw(format(F, [P])), E, throw(E))",
    "catch(throw(error(format(F, [P]), _)), E, throw(wrapped(E)))",
    "catch(Y = 1, _, true), Y == 1, throw(error(evaluation_error(format(F, [P])), context(_, _)))",
    "E = error(format(F, [P]), context(format(F, [P]), format(F, [P]))), throw(E)",
    "T = format(F, [P])",                       # an answer: printed with ~W, never formatted
)

# --- changes to the knowledge bases ------------------------------------------------------
_KB_CHANGES = (
    ("assertz(world:tool_condition(us_probe_2, broken))", "refused"),
    ("asserta(world:tool_condition(us_probe_2, broken))", "refused"),
    ("assert(world:tool_condition(us_probe_2, broken))", "refused"),
    ("retract(world:tool_condition(us_probe_2, _))", "refused"),
    ("retractall(world:tool_condition(_, _))", "refused"),
    ("abolish(world:tool_condition/2)", "refused"),
    ("world:assertz(tool_condition(us_probe_2, broken))", "clean"),
    ("world:retract(tool_condition(us_probe_2, _))", "clean"),
    ("assertz(tool_condition(us_probe_2, broken))", "clean"),
    ("retract(tool_condition(us_probe_2, _))", "clean"),
    ("assertz(world:type(hammer, us_tool))", "refused"),
    ("assertz(faults:cause(x, y))", "refused"),
    ("assertz((world:available(X) :- true))", "refused"),
    ("assertz(user:term_expansion(_, _))", "refused"),
    ("assertz(user:message_hook(_, _, _))", "refused"),
    ("assertz(user:portray(_))", "refused"),
    ("assertz(system:foo)", "refused"),
    ("M = world, assertz(M:tool_condition(us_probe_2, broken))", "clean"),
    ("dynamic(world:foo/1)", "refused"),
    ("world:dynamic(foo/1)", "refused"),
    ("redefine_system_predicate(shell(_))", "refused"),
    ("erase(_)", "clean"),
    ("recorda(k, v)", "clean"),
    ("flag(k, _, 1)", "clean"),
    ("nb_setval(k, v)", "refused"),
    ("b_setval(k, v)", "refused"),
    ("set_prolog_flag(double_quotes, atom)", "refused"),
    ("set_prolog_flag(unknown, fail)", "refused"),
    ("op(700, xfx, ===>)", "refused"),
    ("set_tool_condition(us_probe_2, broken)", "harmless"),
    ("set_tool_condition(us_probe_2, broken), tool_condition(us_probe_2, broken)", "harmless"),
    ("snapshot(set_tool_condition(us_probe_2, broken))", "harmless"),
    ("transaction(set_tool_condition(us_probe_2, broken))", "clean"),
    ("print_message(error, format('~@', [assertz(world:tool_condition(us_probe_2, broken))]))",
     "refused"),
    ("'$set_source_module'(_, world)", "refused"),
    ("world:'$set_predicate_attribute'(tool_condition(_, _), system, true)", "refused"),
)

# --- threads -----------------------------------------------------------------------------
_THREADS = (
    "thread_create(true, _, [])",
    "thread_create(set_tool_condition(us_probe_2, broken), _, [detached(true)])",
    "thread_create(shell('touch {t}/pwned'), Id, []), thread_join(Id, _)",
    "thread_create(sleep(100), _, [detached(true)])",
    "thread_signal(main, shell('touch {t}/pwned'))",
    "thread_self(Me), thread_signal(Me, shell('touch {t}/pwned'))",
    "thread_send_message(main, x)",
    "thread_get_message(_)",
    "message_queue_create(Q), thread_send_message(Q, x)",
    "mutex_create(_)",
    "with_mutex(m, shell('touch {t}/pwned'))",
    "concurrent(2, [shell('touch {t}/pwned')], [])",
    "concurrent_forall(member(_, [1]), shell('touch {t}/pwned'))",
    "concurrent_maplist(shell, ['touch {t}/pwned'])",
    "first_solution(_, [shell('touch {t}/pwned')], [])",
    "call_in_thread(main, shell('touch {t}/pwned'))",
    "alarm(0.01, shell('touch {t}/pwned'), _), sleep(0.1)",
    "thread_exit(x)",
    "thread_detach(main)",
    "print_message(error, format('~@', [thread_create(set_tool_condition(us_probe_2, broken), _, [])]))",
    "engine_create(X, shell('touch {t}/pwned'), E), engine_next(E, X)",
    "thread_create_in_pool(p, true, _, [])",
)

# --- limits: time, inferences, swallowed limits, huge formats ----------------------------
_LIMITS = (
    ("sleep(1000)", "stopped"),
    ("repeat, fail", "stopped"),
    ("between(1, inf, _), fail", "stopped"),
    ("catch((between(1, inf, _), fail), _, true)", "harmless"),   # caught, and it ends
    ("repeat, catch((between(1, inf, _), fail), _, true), fail", "stopped"),
    ("catch(sleep(1000), _, sleep(1000))", "stopped"),
    ("repeat, catch(sleep(1000), _, true), fail", "stopped"),
    ("catch(call_with_time_limit(1000, (repeat, fail)), _, (repeat, fail))", "stopped"),
    ("catch(call_with_inference_limit((repeat, fail), 1000000000000, _), _, true), (repeat, fail)", "stopped"),
    ("call_cleanup((repeat, fail), (repeat, fail))", "stopped"),
    ("setup_call_cleanup(true, (repeat, fail), sleep(1000))", "stopped"),
    ("length(L, N), N > 100000000", "stopped"),
    ("format(atom(A), '~`xt~2000000000|', [])", "refused"),
    ("format(atom(A), '~2000000000|', [])", "refused"),
    ("format(atom(A), '~t~2000000000|', [])", "refused"),
    ("format(string(A), \"~`-t~1000000001+\", [])", "refused"),
    ("format(atom(A), '~*c', [2000000000, 0'x])", "stopped"),
    ("format(atom(A), '~a~2000000000|', [x])", "refused"),
    ("format(atom(A), '~e', [1.0e308])", "harmless"),
    ("format(atom(A), '~2000000000e', [1.0])", "refused"),
    ("findall(X, between(1, inf, X), _)", "stopped"),
    ("forall(between(1, inf, _), true)", "stopped"),
    ("catch((repeat, fail), time_limit_exceeded, (repeat, fail))", "stopped"),
    ("catch((repeat, fail), _, true), fail ; repeat, fail", "stopped"),
)

# --- memory ------------------------------------------------------------------------------
_MEMORY = (
    "numlist(1, 100000000, L)",
    "length(L, 500000000)",
    "findall(X, between(1, 100000000, X), L)",
    "numlist(1, 40, L), foldl([_, A, B]>>atomic_list_concat([A, A], B), L, x, _)",
    "numlist(1, 40, L), foldl([_, A, B]>>string_concat(A, A, B), L, \"x\", _)",
    "length(L, 100000000), maplist(=(x), L)",
    "numlist(1, 30, L), foldl([_, A, [A, A]]>>true, L, x, T), term_to_atom(T, _)",
    "numlist(1, 60, L), foldl([_, A, f(A, A)]>>true, L, x, T), copy_term(T, _)",
    "length(L, 50000000), atom_codes(_, L)",
    "format(atom(A), '~*c', [900000000, 0'x])",
    "between(1, inf, N), atom_length(_, N), fail",
    "numlist(1, 10000000, L), msort(L, _)",
    "numlist(1, 40, L), foldl([_, A, B]>>append(A, A, B), L, [x], _)",
    "length(L, 100000000), sum_list(L, _)",
    "tab(2000000000)",
    "string_code(1, S, _), length(L, 100000000), string_codes(S, L)",
)

# --- deep terms --------------------------------------------------------------------------
_DEPTH = 20_000
_DEEP = (
    ("X = " + "f(" * _DEPTH + "a" + ")" * _DEPTH, "clean"),
    ("X = " + "[" * _DEPTH + "]" * _DEPTH, "clean"),
    ("X = " + "- " * _DEPTH + "a", "clean"),
    ("X is " + "1+" * _DEPTH + "1", "clean"),
    ("X = " + "g(a," * _DEPTH + "b" + ")" * _DEPTH, "clean"),
    (f"length(L, {_DEPTH}), foldl([_, A0, f(A0)]>>true, L, a, X)", "clean"),
    (f"length(L, {_DEPTH}), foldl([_, A0, [A0]]>>true, L, a, X)", "clean"),
    (f"length(L, {_DEPTH * 10}), foldl([_, A0, f(A0)]>>true, L, a, X), copy_term(X, Y)", "clean"),
    (f"length(L, {_DEPTH * 10}), foldl([_, A0, f(A0)]>>true, L, a, X), term_to_atom(X, A)", "clean"),
    (f"length(L, {_DEPTH * 10}), foldl([_, A0, f(A0)]>>true, L, a, X), X == X", "harmless"),
    (f"length(L, {_DEPTH * 10}), foldl([_, A0, f(A0)]>>true, L, a, X), ground(X)", "harmless"),
    (f"length(L, {_DEPTH * 10}), foldl([_, A0, f(A0)]>>true, L, a, X), numbervars(X, 0, _)",
     "harmless"),
    (f"length(L, {_DEPTH * 10}), foldl([_, A0, f(A0)]>>true, L, a, X), "
     "format(atom(A), '~w', [X])", "clean"),
    (f"length(L, {_DEPTH}), foldl([_, A0, B]>>(B = f(A0)), L, a, X), term_variables(X, V)",
     "harmless"),
    ("X = f(X)", "harmless"),
    ("X = [a|X]", "harmless"),
    ("X = f(X), copy_term(X, Y)", "harmless"),
    ("X = f(X), Y = f(Y), X == Y", "harmless"),
    ("X = f(X), term_to_atom(X, A)", "harmless"),
    ("X = f(X), format(atom(A), '~w', [X])", "harmless"),
    ("X = f(X), length(X, N)", "clean"),
    ("X = f(X, X), ground(X)", "harmless"),
    (f"length(L, {_DEPTH}), foldl([_, A0, f(A0)]>>true, L, a, X), type(X, _)", "harmless"),
    ("atom_to_term('" + "f(" * _DEPTH + "a" + ")" * _DEPTH + "', T, _)", "clean"),
    ("term_string(T, \"" + "[" * _DEPTH + "]" * _DEPTH + "\")", "clean"),
)

# --- encodings ---------------------------------------------------------------------------
_ENCODINGS = (
    ("type(X, '\udcff')", "refused"),              # a byte that is not UTF-8 (surrogate escape)
    ("\udcff(X)", "refused"),
    ("type(X, us_tool)\udce9", "refused"),
    ("type(X, 'é')", "harmless"),
    ("type(X, '日本')", "harmless"),
    ("type(X, '\U0001F600')", "harmless"),
    ("X = '\\e]0;pwned\\a'", "harmless"),             # a terminal escape must come back escaped
    ("X = '\\x1b\\[2J'", "harmless"),
    ("X = '\u202eevil'", "harmless"),
    ("X = 'a\\x00\\b'", "harmless"),
    ("X = \"\\x0\\\"", "harmless"),
    ("\ufefftype(X, us_tool)", "clean"),
    ("type(X, us_tool) % comment", "harmless"),
    ("type(X, /* unterminated", "refused"),
    ("type(X, 'unterminated)", "refused"),
    ("type(X, \"unterminated)", "refused"),
    ("X = '\\xZZ\\'", "refused"),
    ("X = 0'", "harmless"),
    ("X = '\\u{D800}'", "clean"),
    ("X = \"\\x{D800}\\\"", "clean"),
    ("", "refused"),
    ("   ", "refused"),
    ("X", "refused"),
    ("end_of_file", "refused"),
    ("type(X, us_tool). shell(ls)", "refused"),
    ("type(X, us_tool).\nshell('touch {t}/pwned')", "refused"),
    ("a" * 1_000_000, "clean"),
    ("X = '" + "a" * 1_000_000 + "'", "harmless"),
    ("X = \"\\u0000\"", "harmless"),
    ("X = 'tab\there'", "harmless"),
)


def all_attacks() -> list[Attack]:
    """Every attack, grouped."""
    attacks = [Attack("side effects", w.format(g=p), "clean")
               for p in _SIDE_PRIMITIVES for w in _SIDE_WRAPPERS]
    attacks += [Attack("escapes", g) for g in _ESCAPES]
    attacks += thrown_formats()
    attacks += [Attack("kb changes", g, e) for g, e in _KB_CHANGES]
    attacks += [Attack("threads", g) for g in _THREADS]
    attacks += [Attack("limits", g, e) for g, e in _LIMITS]
    attacks += [Attack("memory", g) for g in _MEMORY]
    attacks += [Attack("deep terms", g, e) for g, e in _DEEP]
    attacks += [Attack("encodings", g, e) for g, e in _ENCODINGS]
    return attacks


def thrown_formats() -> list[Attack]:
    """The family of format directives built at run time and thrown (issue 28)."""
    attacks = []
    for builder in _FORMAT_BUILDERS:
        for payload in _FORMAT_PAYLOADS:
            for throw in _THROWS:
                goal = f"{builder}, P = ({payload}), {throw}"
                attacks.append(Attack("thrown formats", goal, "harmless" if throw.startswith("T =") else "clean"))
    return attacks
