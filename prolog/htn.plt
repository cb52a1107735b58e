:- use_module(htn).

/*  Tests of the HTN planner.  Each domain is a module of its own, written here as
    module-qualified facts.  */

%   route: a robot on a line of rooms a-b-c-d; go/2 is left-recursive through via.
route:operator(move(R, A, B), [at(R, A), road(A, B)], [at(R, A)], [at(R, B)]).
route:operator(noop, [], [], []).
route:method(there, go(R, B), [at(R, B)], [noop]).
route:method(direct, go(R, B), [at(R, A), road(A, B)], [move(R, A, B)]).
route:method(via, go(R, B), [], [go(R, M), move(R, M, B)]).

route_state([at(r, a), road(a, b), road(b, c), road(c, d)]).

%   lifted: the method leaves the room to the action (a lazy typed parameter).
lifted:operator(enter(X), [room(X), free(X)], [free(X)], [in(X)]).
lifted:method(enter_any, visit, [lazy(room(X))], [enter(X)]).

%   attached: the method asks a Prolog predicate (an attached procedure) for the tool.
attached:operator(pick(T), [on_rack(T)], [on_rack(T)], [held(T)]).
attached:method(fetch, fetch(Job), [call(tool_for(Job, T)), not(broken(T))], [pick(T)]).
attached:tool_for(drill, d1).
attached:tool_for(drill, d2).
attached:tool_for(probe, p1).

%   logic: negation, equality, or and forall in preconditions.
logic:operator(mark(X), [not(marked(X))], [], [marked(X)]).
logic:method(pair, mark_pair(X, Y), [X \= Y], [mark(X), mark(Y)]).
logic:method(same, mark_pair(X, X), [], [mark(X)]).
logic:method(check, all_marked, [forall([item(I)], [marked(I)])], []).
logic:method(either, one_of(X, Y), [or([[good(X)], [good(Y)]])], []).

%   loop: recursion that only goes round in circles (no plan).
loop:operator(flip, [off], [off], [on]).
loop:operator(flop, [on], [on], [off]).
loop:method(round, spin, [], [flip, flop, spin]).
loop:method(stop, spin, [done], []).

%   grow: left recursion that never executes anything (no plan; bounded only by limits).
grow:operator(nothing, [impossible], [], []).
grow:method(deeper, t, [], [t, nothing]).

%   broken domains
undefined_subtask:method(m, t, [], [no_such_task]).
both:operator(t, [], [], []).
both:method(m, t, [], []).

route_plan(Tasks, Options, Result) :-
    route_state(S),
    htn_plan(route, S, Tasks, Options, Result).

actions(plan(Steps, _, _), Actions) :-
    pairs_values(Steps, Actions).

:- begin_tests(htn_plan).

test(left_recursion_finds_the_path, Actions == [move(r, a, b), move(r, b, c), move(r, c, d)]) :-
    route_plan([go(r, d)], [], R),
    actions(R, Actions).

test(already_there, Actions == [noop]) :-
    route_plan([go(r, a)], [], R),
    actions(R, Actions).

test(final_state, true(State == [at(r, c), road(a, b), road(b, c), road(c, d)])) :-
    route_plan([go(r, c)], [], plan(_, _, State)).

test(tree_records_methods_and_children,
     true(Nodes = [decomposed(0, go(r, b), direct, [1], []), primitive(1, move(r, a, b), [])])) :-
    route_plan([go(r, b)], [], plan(_, tree([0], Nodes), _)).

test(unreachable_with_endless_recursion_hits_the_limit, R == no_plan(time_limit(0.3))) :-
    % via recurses on the left without end: only the limit stops the search
    route_plan([go(r, nowhere)], [time_limit(0.3)], R).

test(goal_is_checked_at_the_end, Actions == [move(r, a, b), move(r, b, c)]) :-
    % go(r, X) is done first by noop (X = a); the goal makes the search go on to X = c
    route_plan([go(r, _)], [goal([at(r, c)])], R),
    actions(R, Actions).

test(unsatisfiable_goal_is_no_plan, R == no_plan(exhausted)) :-
    htn_plan(lifted, [room(k1), room(k2), free(k2)], [visit], [goal([in(k1)])], R).

test(lazy_parameter_bound_by_the_action, Actions == [enter(k2)]) :-
    htn_plan(lifted, [room(k1), room(k2), free(k2), hall(h)], [visit], [], R),
    actions(R, Actions).

test(attached_procedure_answers_and_backtracks, true(R = plan([_-pick(d2)], _, _))) :-
    htn_plan(attached, [on_rack(d1), on_rack(d2), on_rack(p1), broken(d1)], [fetch(drill)], [], R).

test(attached_calls_recorded_in_the_tree,
     true(Nodes = [decomposed(0, fetch(probe), fetch, [1], [tool_for(probe, p1)]), _])) :-
    htn_plan(attached, [on_rack(p1)], [fetch(probe)], [], plan(_, tree(_, Nodes), _)).

test(negation_and_inequality, Actions == [mark(a), mark(b)]) :-
    htn_plan(logic, [], [mark_pair(a, b)], [], R),
    actions(R, Actions).

test(equality_by_unification, Actions == [mark(a)]) :-
    htn_plan(logic, [], [mark_pair(a, a)], [], R),
    actions(R, Actions).

test(forall_holds, true(R = plan([], _, _))) :-
    htn_plan(logic, [item(a), item(b), marked(a), marked(b)], [all_marked], [], R).

test(forall_fails, R == no_plan(exhausted)) :-
    htn_plan(logic, [item(a), item(b), marked(a)], [all_marked], [], R).

test(or_holds, true(R = plan([], _, _))) :-
    htn_plan(logic, [good(b)], [one_of(a, b)], [], R).

test(cycles_end_in_no_plan, R == no_plan(exhausted)) :-
    htn_plan(loop, [off], [spin], [], R).

test(node_limit, R == no_plan(node_limit(50))) :-
    htn_plan(grow, [], [t], [max_nodes(50)], R).

test(time_limit, R == no_plan(time_limit(0.2))) :-
    htn_plan(grow, [], [t], [time_limit(0.2)], R).

test(empty_network, R == plan([], tree([], []), [])) :-
    htn_plan(route, [], [], [], R).

:- end_tests(htn_plan).

:- begin_tests(htn_replan).

test(replan_keeps_ids_and_numbers_on, true(Nodes = [decomposed(7, go(r, d), direct, [20], []), primitive(20, _, _)])) :-
    htn_replan(route, [at(r, c), road(c, d)], [7-go(r, d)], [next_id(20)], plan(_, tree([7], Nodes), _)).

test(remaining_after_one_action, Network == [4-move(r, b, c), 2-move(r, c, d)]) :-
    % 0 go(r,d) via [1, 2]; 1 go(r,c) via [3, 4]; 3 go(r,b) direct [5]
    route_plan([go(r, d)], [], plan(_, Tree, _)),
    htn_remaining(Tree, 1, Network).

test(remaining_at_start_is_the_roots, Network == [0-go(r, d)]) :-
    route_plan([go(r, d)], [], plan(_, Tree, _)),
    htn_remaining(Tree, 0, Network).

test(remaining_when_all_done, Network == []) :-
    route_plan([go(r, d)], [], plan(Steps, Tree, _)),
    length(Steps, N),
    htn_remaining(Tree, N, Network).

test(replan_the_remaining_network, Actions == [move(r, b, c), move(r, c, d)]) :-
    route_plan([go(r, d)], [], plan(_, Tree, _)),
    htn_remaining(Tree, 1, Network),
    htn_replan(route, [at(r, b), road(a, b), road(b, c), road(c, d)], Network, [], R),
    actions(R, Actions).

:- end_tests(htn_replan).

:- begin_tests(htn_errors).

test(unknown_root_task, error(existence_error(htn_task, fly/1))) :-
    htn_plan(route, [], [fly(r)], [], _).

test(unknown_subtask, error(existence_error(htn_task, no_such_task/0))) :-
    htn_check_domain(undefined_subtask).

test(task_both_primitive_and_compound, error(permission_error(define, htn_task, t/0))) :-
    htn_check_domain(both).

test(state_must_be_ground, error(type_error(ground_fact, at(r, _)))) :-
    htn_plan(route, [at(r, _)], [go(r, a)], [], _).

test(unknown_domain, error(existence_error(htn_domain, no_such_domain))) :-
    htn_plan(no_such_domain, [], [], [], _).

test(network_entries_are_id_task, error(type_error(htn_network_entry, go(r, a)))) :-
    htn_replan(route, [], [go(r, a)], [], _).

test(checks_a_good_domain) :-
    htn_check_domain(route).

:- end_tests(htn_errors).
