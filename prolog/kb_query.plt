:- begin_tests(kb_query).

:- use_module(kb_query).
:- use_module('../kb/world').

test(answers_with_bindings, true(R == answers(['X'], [["us_probe_1"], ["us_probe_2"]], false))) :-
    run_query("type(X, us_tool)", [world], [], R).

test(limit_truncates, true(R == answers(['X'], [["us_probe_1"]], true))) :-
    run_query("type(X, us_tool)", [world], [limit(1)], R).

test(no_solution, true(R == answers(['X'], [], false))) :-
    run_query("type(X, hammer)", [world], [], R).

test(underscore_variables_hidden, true(Names == ['T'])) :-
    run_query("location(T, _Where)", [world], [], answers(Names, _, _)).

test(syntax_error_refused, true(sub_string(Reason, _, _, _, "syntax error"))) :-
    run_query("type(X,", [world], [], refused(Reason)).

test(shell_refused, true(sub_string(Reason, _, _, _, "shell/1"))) :-
    run_query("shell(ls)", [world], [], refused(Reason)).

test(assert_into_kb_module_refused, true(sub_string(Reason, _, _, _, "read-only"))) :-
    run_query("assertz(world:foo)", [world], [], refused(Reason)).

test(halt_refused, true(sub_string(Reason, _, _, _, "halt/0"))) :-
    run_query("halt", [world], [], refused(Reason)).

test(kb_update_is_rolled_back, true(C == ok)) :-
    run_query("set_tool_condition(us_probe_1, broken)", [world], [], answers([], [[]], false)),
    world:tool_condition(us_probe_1, C).

test(loop_stopped_by_inference_limit, true(sub_string(Reason, _, _, _, "inference limit"))) :-
    run_query("repeat, fail", [world], [inference_limit(10000)], limit_exceeded(Reason)).

test(loop_stopped_by_time_limit, true(sub_string(Reason, _, _, _, "time limit"))) :-
    run_query("repeat, fail", [world], [time_limit(0.1), inference_limit(1000000000000)],
              limit_exceeded(Reason)).

test(runtime_error_reported, true(sub_string(Reason, _, _, _, "zero_divisor"))) :-
    run_query("X is 1/0", [world], [], error(Reason)).

test(bad_limit, error(type_error(positive_integer, 0))) :-
    run_query("true", [world], [limit(0)], _).

test(term_text_names_variables, true(T == "f(_1, 'A b', _1)")) :-
    term_text(f(X, 'A b', X), T).

test(message_escape_refused, true(sub_string(Reason, _, _, _, "print_message"))) :-
    run_query("print_message(error, format('~@', [shell('id')]))", [world], [], refused(Reason)).

test(format_string_built_at_run_time_refused, true(sub_string(Reason, 0, _, _, "refused"))) :-
    run_query("atom_concat('~', '@', F), format(F, [true])", [world], [], refused(Reason)).

test(huge_format_column_refused, true(sub_string(Reason, _, _, _, "too large"))) :-
    run_query("format(atom(A), '~`xt~2000000000|', [])", [world], [], refused(Reason)).

test(thread_refused, true(sub_string(Reason, _, _, _, "thread_create"))) :-
    run_query("thread_create(true, _, [])", [world], [], refused(Reason)).

test(flag_change_refused, true(sub_string(Reason, _, _, _, "set_prolog_flag"))) :-
    run_query("set_prolog_flag(double_quotes, atom)", [world], [], refused(Reason)).

test(ordinary_format_allowed, true(R == answers(['S'], [["\"a1\""]], false))) :-
    run_query("format(string(S), \"a~d\", [1])", [world], [], R).

test(listing_prints_clauses, true(R == answers([], [[]], false))) :-
    with_output_to(string(Out), run_query("listing(available)", [world], [], R)),
    once(sub_string(Out, _, _, _, "tool_condition")).

test(listing_unknown_refused, true(sub_string(Reason, _, _, _, "no knowledge-base predicate"))) :-
    run_query("listing(nothere/3)", [world], [], refused(Reason)).

test(thrown_format_is_not_run, true(Pwned == false)) :-
    run_query("X is 63+1, atom_codes(F, [126, X]), throw(format(F, [assertz(user:kb_query_pwned)]))",
              [world], [], error(Reason)),
    once(sub_string(Reason, _, _, _, "unhandled exception: format(")),
    ( catch(user:kb_query_pwned, _, fail) -> Pwned = true ; Pwned = false ).

test(format_in_error_context_is_not_run, true(Pwned == false)) :-
    run_query("atom_codes(F, [0'~, 0'@]), \c
               throw(error(foo, context(_, format(F, [assertz(user:kb_query_pwned)]))))",
              [world], [], error(_)),
    ( catch(user:kb_query_pwned, _, fail) -> Pwned = true ; Pwned = false ).

test(format_in_formal_error_is_not_run, true(Pwned == false)) :-
    run_query("atom_codes(F, [0'~, 0'@]), \c
               throw(error(type_error(format(F, [assertz(user:kb_query_pwned)]), x), _))",
              [world], [], error(Reason)),
    sub_string(Reason, 0, _, _, "type error: "),
    ( catch(user:kb_query_pwned, _, fail) -> Pwned = true ; Pwned = false ).

test(error_text_iso_terms, true(T == "type error: integer expected, found a (in foo/1): bad")) :-
    error_text(error(type_error(integer, a), context(foo/1, bad)), T).

test(error_text_is_one_line, true(T == "unhandled exception: 'a\\nb'")) :-
    error_text('a\nb', T).

test(error_text_of_a_variable_context, true(T == "arguments are not sufficiently instantiated")) :-
    error_text(error(instantiation_error, _), T).

:- end_tests(kb_query).
