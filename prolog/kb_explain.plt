:- begin_tests(kb_explain).

:- use_module(kb_explain).
:- use_module('../kb/world').

test(proof_tree_of_rule,
     [ true(Kinds == [rule, rule, negation, negation]) ]) :-
    explain_query("available(us_probe_1)", [world], [],
                  proof(node(query, "available(us_probe_1)", '', 0,
                             [node(Kind1, _, File, Line, [node(Kind2, _, _, _, _), node(Kind3, _, _, _, _),
                                                          node(Kind4, _, _, _, _)])]))),
    Kinds = [Kind1, Kind2, Kind3, Kind4],
    sub_atom(File, _, _, 0, 'world.pl'),
    Line > 0.

test(bindings_shown_in_tree, true(Text == "type(t3, arm)")) :-
    explain_query("type(A, arm)", [world], [], proof(node(query, Text, _, _, _))).

test(no_proof_for_false_goal, true(R == no_proof)) :-
    explain_query("available(hammer)", [world], [], R).

test(unsafe_goal_refused, true(R = refused(_))) :-
    explain_query("shell(ls)", [world], [], R).

test(builtins_are_leaves, true(Kind == builtin)) :-
    prove(kb_explain:atom_length(abc, 3), [world], 10, [proof(Kind, _, _, _, [])]).

test(depth_limit_stops_expansion, true(Kind == depth_limit)) :-
    prove(world:available(us_probe_1), [world], 0, [proof(Kind, _, _, _, [])]).

test(cut_commits_to_clause, all(X == [a])) :-
    prove(kb_explain_test_sample:first(X), [kb_explain_test_sample], 5, _).

kb_explain_test_sample:first(X) :- kb_explain_test_sample:item(X), !.
kb_explain_test_sample:item(a).
kb_explain_test_sample:item(b).

test(bad_modules_argument, error(type_error(list(atom), world))) :-
    prove(world:available(_), world, 3, _).

:- end_tests(kb_explain).
