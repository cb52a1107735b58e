:- begin_tests(kb_check).

:- use_module(kb_check).

:- dynamic kb_check_test_sample:p/1.

test(reports_call_to_undefined_predicate,
     [ setup(assertz((kb_check_test_sample:p(X) :- kb_check_test_sample:no_such(X)))),
       cleanup(retractall(kb_check_test_sample:p(_))),
       true(Callee == kb_check_test_sample:no_such/1)
     ]) :-
    undefined_calls([kb_check_test_sample], Undefined),
    member(undefined(Callee, _, _, _), Undefined).

test(clean_module_has_no_undefined_calls, true(Undefined == [])) :-
    undefined_calls([kb_check], Undefined).

test(rejects_non_list, error(type_error(list(atom), foo))) :-
    undefined_calls(foo, _).

:- end_tests(kb_check).
