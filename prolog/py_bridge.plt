:- begin_tests(py_bridge).

:- use_module(py_bridge).
:- use_module(library(http/json)).

reply(Request, Dict) :-
    py_call(Request, Text),
    atom_json_dict(Text, Dict, [value_string_as(atom)]).

test(solutions_bind_variables, true(Xs == [a, b])) :-
    reply("{\"module\":\"lists\",\"name\":\"member\",\"args\":[{\"var\":\"X\"},[\"a\",\"b\"]],\"limit\":null}",
          Dict),
    get_dict(solutions, Dict, Solutions),
    findall(X, (member(S, Solutions), get_dict('X', S, X)), Xs).

test(limit_applies, true(N == 1)) :-
    reply("{\"module\":\"lists\",\"name\":\"member\",\"args\":[{\"var\":\"X\"},[\"a\",\"b\"]],\"limit\":1}",
          Dict),
    get_dict(solutions, Dict, Solutions),
    length(Solutions, N).

test(quotes_are_data, true(X == 'it\'s), halt')) :-
    reply("{\"module\":\"system\",\"name\":\"=\",\"args\":[{\"var\":\"X\"},\"it's), halt\"],\"limit\":null}",
          Dict),
    get_dict(solutions, Dict, [Solution]),
    get_dict('X', Solution, X).

test(compound_round_trip, true(Name-Args == in_rack-[slot_1])) :-
    reply("{\"module\":\"system\",\"name\":\"=\",\"args\":[{\"var\":\"X\"},{\"functor\":\"in_rack\",\"args\":[\"slot_1\"]}],\"limit\":null}",
          Dict),
    get_dict(solutions, Dict, [Solution]),
    get_dict('X', Solution, F),
    get_dict(functor, F, Name),
    get_dict(args, F, Args).

test(error_reported, true(sub_atom(Message, _, _, _, 'Type error'))) :-
    reply("{\"module\":\"system\",\"name\":\"must_be\",\"args\":[\"positive_integer\",0],\"limit\":null}",
          Dict),
    get_dict(error, Dict, Message).

test(json_term_shares_variables, true(T = f(X, X))) :-
    json_term(_{functor: f, args: [_{var: 'A'}, _{var: 'A'}]}, T, []-_).

test(load_reports_syntax_error_and_unloads,
     [ setup(tmp_file_stream(text, File, S)), cleanup(delete_file(File)),
       true(Line-Loaded == 2-false) ]) :-
    format(S, ":- module(py_bridge_broken, [p/1]).~np(X) :- q(X.~nq(1).~n", []),
    close(S),
    atom_concat(File, '', Atom),
    load_source_files([Atom], Diagnostics),
    memberchk(diagnostic(error, Atom, Line, _, _), Diagnostics),
    (   catch(py_bridge_broken:q(1), _, fail) -> Loaded = true ; Loaded = false ).

test(bad_request, error(type_error(text, 42))) :-
    py_call(42, _).

:- end_tests(py_bridge).
