:- use_module(macrop).
:- use_module(planner).
:- use_module('../kb/operators', [measurement_goal/5, planning_state/4]).

/*  Tests of plan generalization, MACROP lookup and the MACROP store.  */

figure_4(macrop(measured(Id1, Tool1, Arm1, Id2),
                [ purpose([ measured(Tool1, Arm1, meas(Id2)) ]),
                  preconditions([ at(Arm1, in_contact_point(meas(Id1))),
                                  holding(Arm1, Tool1) ]),
                  adders([ at(Arm1, in_contact_point(meas(Id2))),
                           measured(Tool1, Arm1, meas(Id2)) ]),
                  unary_constraints([ type(Tool1, us_tool), type(Arm1, arm) ]),
                  n_ary_constraints([ can_lift(Arm1, W1), weight(Tool1, W2), W2 =< W1 ]),
                  resources([ Tool1, Arm1 ]),
                  plan([ step(1, move_retract(Arm1, Id1), []),
                         step(2, move(Arm1, meas(Id1), meas(Id2)), [1]),
                         step(3, apply_couplant(Arm1, Id2), [2]),
                         step(4, move_contact(Arm1, Id2), [3]),
                         step(5, us_measure(Tool1, Arm1, Id2), [4]) ])
                ])).

%   same_macrop(+M1, +M2) is semidet.
%
%   M1 and M2 are the same MACROP up to variable names: the same steps in the same
%   order, the other fields the same sets, the name the same variables.

same_macrop(M1, M2) :-
    copy_term(M1, macrop(N1, F1)),
    copy_term(M2, macrop(N2, F2)),
    term_variables(F1, V1), length(V1, L1),
    term_variables(F2, V2), length(V2, L2),
    L1 =:= L2,
    memberchk(plan(P1), F1), memberchk(plan(P2), F2), P1 = P2,
    maplist(same_set_field(F1, F2), [purpose, preconditions, adders, unary_constraints,
                                     n_ary_constraints, resources]),
    N1 =.. [Name|A1], N2 =.. [Name|A2],
    permutation(A1, A2),
    term_variables(F1, W1), length(W1, L1),      % no two variables merged
    !.

same_set_field(F1, F2, Name) :-
    T1 =.. [Name, S1], T2 =.. [Name, S2],
    memberchk(T1, F1), memberchk(T2, F2),
    permutation(S1, S2).

figure_4_problem([measured(us_probe_1, t3, meas(b))],
                 [at(t3, in_contact_point(meas(a))), holding(t3, us_probe_1)]).

store_file(File) :-
    tmp_file(macrops, Base),
    atom_concat(Base, '.pl', File).

slra_state([ at(t3, approach_point(home)), holding(t3, none),
             location(slra_1, in_rack(slot_3)), tool_condition(slra_1, ok) ]).

:- begin_tests(lookup).

test(figure_4_lookup_binds_tool_and_points,
     true(Plan == [ step(1, move_retract(t3, b), []),
                    step(2, move(t3, meas(b), meas(c)), [1]),
                    step(3, apply_couplant(t3, c), [2]),
                    step(4, move_contact(t3, c), [3]),
                    step(5, us_measure(us_probe_2, t3, c), [4]) ])) :-
    figure_4(M),
    macrop_applies(M, [measured(_, t3, meas(c))],
                   [at(t3, in_contact_point(meas(b))), holding(t3, us_probe_2)], [], Plan).

test(unary_constraint_rejects_wrong_tool, fail) :-
    figure_4(M),
    macrop_applies(M, [measured(_, t3, meas(c))],
                   [at(t3, in_contact_point(meas(b))), holding(t3, slra_1)], [], _).

test(goal_constraint_rejects_wrong_kind, fail) :-
    figure_4(M),
    macrop_applies(M, [measured(T, t3, meas(c))],
                   [at(t3, in_contact_point(meas(b))), holding(t3, us_probe_1)],
                   [constraints([type(T, slra_tool)])], _).

test(precondition_missing_rejects, fail) :-
    figure_4(M),
    macrop_applies(M, [measured(_, t3, meas(c))],
                   [at(t3, approach_point(meas(b))), holding(t3, us_probe_1)], [], _).

:- end_tests(lookup).

:- begin_tests(store).

test(plan_then_learn_then_hit, true(Sources-Counts == [planned-1, macrop-1]-c(2, 1, 1))) :-
    store_file(File),
    open_store(File),
    slra_state(S),
    operation_plan(File, [measured(slra_1, t3, meas(c))], S, [], R1),
    operation_plan(File, [measured(slra_1, t3, meas(d))], S, [], R2),
    store_counts(File, L, H, M),
    close_store(File),
    R1 = planned(Id1, _), R2 = macrop(Id2, _),
    Sources = [planned-Id1, macrop-Id2],
    Counts = c(L, H, M).

test(hand_written_macrop_hit, true(Found = found(kb(_), _))) :-
    store_file(File),
    open_store(File),
    lookup(File, [measured(_, t3, meas(c))],
           [at(t3, in_contact_point(meas(b))), holding(t3, us_probe_1)], [], Found),
    close_store(File).

test(store_persists_between_runs, true(X == [1-1, c(2, 1, 1)])) :-
    store_file(File),
    open_store(File),
    slra_state(S),
    operation_plan(File, [measured(slra_1, t3, meas(c))], S, [], _),
    operation_plan(File, [measured(slra_1, t3, meas(d))], S, [], _),
    save_store(File),
    close_store(File),
    open_store(File),
    store_macrops(File, [macrop(Id, _, _, hits(Hits))]),
    store_counts(File, L, H, M),
    close_store(File),
    delete_file(File),
    X = [Id-Hits, c(L, H, M)].

test(saved_store_is_readable_prolog, true(Names == [macrop, store_counts])) :-
    store_file(File),
    open_store(File),
    slra_state(S),
    operation_plan(File, [measured(slra_1, t3, meas(c))], S, [], _),
    save_store(File),
    close_store(File),
    read_file_to_terms(File, Terms, []),
    delete_file(File),
    findall(N, (member(T, Terms), functor(T, N, _)), Names0),
    sort(Names0, Names).

test(unopened_store_is_an_error, error(existence_error(macrop_store, '/nonexistent/x.pl'))) :-
    lookup('/nonexistent/x.pl', [g], [], [], _).

:- end_tests(store).

:- begin_tests(measurement_lookup).

%   The compiled lookup of measurement_plan/9 finds what lookup/5 finds in the whole
%   planning state, and counts what it finds.

grid_state(Kind-Tool, Pose, Holding) :-
    member(Kind-Tool, [web_thickness-us_probe_1, web_thickness-us_probe_2,
                       stiffener_height-slra_1, stiffener_width-us_probe_1]),
    member(Pose, [[approach_point, home], [approach_point, meas, a],
                  [in_contact_point, meas, a], [viewing_pose, meas, a],
                  [approach_point, rack, slot_2]]),
    member(Holding, [none, us_probe_1, us_probe_2, slra_1]).

%   learned_store(-File): a store that has learned the MACROPs of the grid's states.

learned_store(File) :-
    store_file(File),
    open_store(File),
    forall(grid_state(Kind-Tool, Pose, Holding),
           measurement_plan(File, b, Kind, Tool, t3, Pose, Holding, lookup_first, _)).

%   lookup_agrees(+File, +Kind-Tool, +Pose, +Holding) is semidet.
%
%   measurement_plan/9 and lookup/5 on the planning state find the same MACROP and plan.

lookup_agrees(File, Kind-Tool, PoseSpec, Holding) :-
    macrop:pose_term(PoseSpec, Pose),
    measurement_goal(c, Kind, Tool, Goal, Constraints),
    planning_state(t3, Pose, Holding, State),
    lookup(File, [Goal], State, [constraints(Constraints)], Found),
    measurement_plan(File, c, Kind, Tool, t3, PoseSpec, Holding, lookup_first, Reply),
    (   Found = found(Id, Plan)
    ->  Reply = [macrop, _, Id, Vars],
        macrop:candidate_plan(File, Id, Vars, Plan, _)
    ;   Reply \= [macrop|_]
    ).

test(agrees_with_lookup_in_the_planning_state, true(Disagree == [])) :-
    learned_store(File),
    findall(K-P-H, ( grid_state(K, P, H), \+ lookup_agrees(File, K, P, H) ), Disagree),
    close_store(File).

test(agrees_with_a_broken_tool_in_the_rack, [ true(Disagree == []),
                                              cleanup(world:reset_world) ]) :-
    learned_store(File),
    world:set_tool_condition(us_probe_1, broken),
    findall(K-P-H, ( grid_state(K, P, H), \+ lookup_agrees(File, K, P, H) ), Disagree),
    close_store(File).

test(rack_macrop_takes_a_tool_from_the_rack,
     true(Reply-Tool == [macrop, 1, [t3, home, slot_1, us_probe_1, c]]-us_probe_1)) :-
    store_file(File),
    open_store(File),
    measurement_plan(File, b, web_thickness, us_probe_1, t3, [approach_point, home], none,
                     lookup_first, [scratch, _, 1, _]),
    measurement_plan(File, c, web_thickness, us_probe_1, t3, [approach_point, home], none,
                     lookup_first, [Source, _, Id, Vars]),
    close_store(File),
    Reply = [Source, Id, Vars],
    nth1(4, Vars, Tool).

test(lookups_are_counted_and_saved, true(X == [c(3, 2, 1), c(3, 2, 1), 2])) :-
    store_file(File),
    open_store(File),
    Contact = [in_contact_point, meas, a],
    measurement_plan(File, b, web_thickness, us_probe_1, t3, Contact, us_probe_1, lookup_first, _),
    measurement_plan(File, c, web_thickness, us_probe_1, t3, Contact, us_probe_1, lookup_first, _),
    measurement_plan(File, d, stiffener_height, slra_1, t3, [approach_point, home], none,
                     lookup_first, _),
    store_counts(File, L1, H1, M1),
    save_store(File),
    close_store(File),
    open_store(File),
    store_counts(File, L2, H2, M2),
    macrop_rows(File, Rows),
    close_store(File),
    delete_file(File),
    memberchk([kb(measured), _, _, KbHits, _], Rows),
    X = [c(L1, H1, M1), c(L2, H2, M2), KbHits].

test(counts_add_to_the_saved_ones, true(C == c(4, 3, 1))) :-
    store_file(File),
    open_store(File),
    Contact = [in_contact_point, meas, a],
    measurement_plan(File, b, web_thickness, us_probe_1, t3, Contact, us_probe_1, lookup_first, _),
    measurement_plan(File, d, stiffener_height, slra_1, t3, [approach_point, home], none,
                     lookup_first, _),
    measurement_plan(File, c, web_thickness, us_probe_1, t3, Contact, us_probe_1, lookup_first, _),
    save_store(File),
    close_store(File),
    open_store(File),
    measurement_plan(File, e, web_thickness, us_probe_1, t3, Contact, us_probe_1, lookup_first, _),
    store_counts(File, L, H, M),
    close_store(File),
    delete_file(File),
    C = c(L, H, M).

test(clear_store_zeroes_the_counts, true(C-Rows == c(0, 0, 0)-[0])) :-
    store_file(File),
    open_store(File),
    measurement_plan(File, b, web_thickness, us_probe_1, t3, [in_contact_point, meas, a],
                     us_probe_1, lookup_first, _),
    clear_store(File),
    store_counts(File, L, H, M),
    macrop_rows(File, Rows0),
    close_store(File),
    findall(Hits, member([_, _, _, Hits, _], Rows0), Rows),
    C = c(L, H, M).

test(unknown_tool_in_hand, error(existence_error(tool, spanner))) :-
    store_file(File),
    open_store(File),
    call_cleanup(measurement_plan(File, b, web_thickness, us_probe_1, t3, [approach_point, home],
                                  spanner, lookup_first, _),
                 close_store(File)).

test(malformed_pose, error(type_error(atomic, f(7)))) :-
    store_file(File),
    open_store(File),
    call_cleanup(measurement_plan(File, b, web_thickness, us_probe_1, t3, [approach_point, meas, f(7)],
                                  none, lookup_first, _),
                 close_store(File)).

test(the_tool_given_is_the_tool_used, true(Tools == [us_probe_2, us_probe_2])) :-
    store_file(File),
    open_store(File),
    Contact = [in_contact_point, meas, a],
    % learned with probe 1 in hand: a MACROP that measures with the held tool
    measurement_plan(File, b, web_thickness, us_probe_1, t3, Contact, us_probe_1, lookup_first, _),
    measurement_plan(File, c, web_thickness, us_probe_2, t3, Contact, us_probe_1, lookup_first,
                     [_, _, Id1, Vars1]),
    measurement_plan(File, d, web_thickness, us_probe_2, t3, Contact, us_probe_1, lookup_first,
                     [macrop, _, Id2, Vars2]),
    findall(T, ( member(Id-Vars, [Id1-Vars1, Id2-Vars2]),
                 macrop:candidate_plan(File, Id, Vars, Steps, _),
                 last(Steps, step(_, us_measure(T, _, _), _)) ), Tools),
    close_store(File).

test(rib_width_with_the_probe, true(Last = us_measure(us_probe_1, t3, b))) :-
    store_file(File),
    open_store(File),
    measurement_plan(File, b, stiffener_width, us_probe_1, t3, [approach_point, home], none,
                     lookup_first, [_, _, Id, Vars]),
    macrop:candidate_plan(File, Id, Vars, Steps, _),
    last(Steps, step(_, Last, _)),
    close_store(File).

test(tool_that_cannot_measure_the_kind, error(domain_error(tool_for(hole_diameter), us_probe_1))) :-
    store_file(File),
    open_store(File),
    call_cleanup(measurement_plan(File, b, hole_diameter, us_probe_1, t3, [approach_point, home],
                                  none, lookup_first, _),
                 close_store(File)).

test(unknown_tool_to_measure_with, error(existence_error(tool, spanner))) :-
    store_file(File),
    open_store(File),
    call_cleanup(measurement_plan(File, b, web_thickness, spanner, t3, [approach_point, home],
                                  none, lookup_first, _),
                 close_store(File)).

:- end_tests(measurement_lookup).
