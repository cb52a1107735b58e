:- begin_tests(py_bridge).

:- use_module(py_bridge).

reply(Module, Goal, Reported, Limit, Reply) :-
    py_run(Module, Goal, Reported, Limit, Text),
    term_string(Reply, Text).

test(solutions_bind_variables, true(Reply == [[a], [b]])) :-
    reply(lists, member(X, [a, b]), [X], all, Reply).

test(limit_applies, true(Reply == [[a]])) :-
    reply(lists, member(X, [a, b]), [X], 1, Reply).

test(limit_of_two, true(Reply == [[a], [b]])) :-
    reply(lists, member(X, [a, b, c]), [X], 2, Reply).

test(failure_is_no_solutions, true(Reply == [])) :-
    reply(system, fail, [], all, Reply).

test(quotes_are_data, true(Reply == [['it\'s), halt']])) :-
    reply(system, =(X, 'it\'s), halt'), [X], all, Reply).

test(reply_has_no_operators,
     true(Text == "[[[:(a,b),'$VAR'(1),{}(x),-(1),\"s\",'A b','\\n']]]")) :-
    py_run(system, =(X, [a:b, '$VAR'(1), {x}, -(1), "s", 'A b', '\n']), [X], all, Text).

test(shared_variables_keep_one_name, true(A == B)) :-
    reply(system, =(X, f(Y, Y)), [X], all, [[f(A, B)]]).

test(error_reported, true(sub_atom(Message, _, _, _, 'Type error'))) :-
    reply(system, must_be(positive_integer, 0), [], all, error(Message, _)).

test(error_names_goal, true(sub_string(Goal, 0, _, _, "system:atom_length(f(x),"))) :-
    reply(system, atom_length(f(x), _), [], all, error(_, Goal)).

test(bad_limit_refused, true(Reply = error(_, _))) :-
    reply(system, true, [], 0, Reply).

test(bad_module_refused, true(Reply = error(_, _))) :-
    reply(_, true, [], all, Reply).

% In a process without Python (this one, the sandbox of `ita kb query`) no procedure
% is attached: the Python side, py_attached_call/3, is not there.
test(attached_without_python_is_an_existence_error,
     error(existence_error(attached_procedure, double/1))) :-
    attached(double, [1], _).

test(attached_name_must_be_an_atom, error(type_error(atom, "double"))) :-
    attached("double", [1], _).

test(attached_args_must_be_a_list, error(type_error(list, 1))) :-
    attached(double, 1, _).

test(attached_existence_error_message,
     true(sub_string(Message, 0, _, _, "No attached procedure double/1"))) :-
    catch(attached(double, [1], _), Error, true),
    message_text(Error, Message).

test(load_reports_syntax_error_and_unloads,
     [ setup(tmp_file_stream(text, File, S)), cleanup(delete_file(File)),
       true(Line-Loaded == 2-false) ]) :-
    format(S, ":- module(py_bridge_broken, [p/1]).~np(X) :- q(X.~nq(1).~n", []),
    close(S),
    atom_concat(File, '', Atom),
    load_source_files([Atom], Diagnostics),
    memberchk(diagnostic(error, Atom, Line, _, _), Diagnostics),
    (   catch(py_bridge_broken:q(1), _, fail) -> Loaded = true ; Loaded = false ).

:- end_tests(py_bridge).
