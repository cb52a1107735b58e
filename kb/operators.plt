:- use_module(operators).

/*  Tests of the operator knowledge base: every operator has the fields of the seed's
    Figure 3, deductive operators are well formed, measurement goals choose the tool.  */

figure_3_fields([ preconditions, adders, unary_constraints, n_ary_constraints, resources,
                  message_pattern, command_stream, reply_pattern, result_pattern ]).

field_names(Description, Names) :-
    findall(N, ( member(F, Description), functor(F, N, 1) ), Names).

:- begin_tests(operators).

test(every_operator_has_the_figure_3_fields_in_order,
     [forall(static_operator(Op, D)), true(Names-Op == Fields-Op)]) :-
    figure_3_fields(Fields),
    field_names(D, Names).

test(list_fields_are_lists, [forall(static_operator(_, D))]) :-
    forall(( member(F, D), F =.. [Name, V],
             memberchk(Name, [preconditions, adders, unary_constraints,
                              n_ary_constraints, resources]) ),
           is_list(V)).

test(us_measure_is_figure_3,
     true(Pre-Add-Unary-Nary-Res ==
          [ couplant_applied(goal_point(meas(I))), at(A, in_contact_point(meas(I))),
            holding(A, T) ]-[measured(T, A, meas(I))]-[type(A, arm), type(T, us_tool)]-
          [can_lift(A, W1), weight(T, W2), W2 =< W1]-[T, A])) :-
    static_operator(us_measure(T, A, I), D),
    memberchk(preconditions(Pre), D), memberchk(adders(Add), D),
    memberchk(unary_constraints(Unary), D), memberchk(n_ary_constraints(Nary), D),
    memberchk(resources(Res), D),
    Nary = [can_lift(_, W1), weight(_, W2), _].

test(reply_and_result_share_the_value, true(V1 == V2)) :-
    static_operator(us_measure(_, _, _), D),
    memberchk(reply_pattern('VALUE'(V1)), D),
    memberchk(result_pattern(dimension(_, _, V2, _)), D).

test(operator_names_are_unique, true(L1 == L2)) :-
    findall(N/A, ( static_operator(Op, _), functor(Op, N, A) ), Names),
    sort(Names, Set),
    length(Names, L1),
    length(Set, L2).

test(picking_up_denies_rack_and_other_tools,
     true(Denied =@= [location(us_probe_1, in_rack(_)), holding(t3, neq(us_probe_1))])) :-
    deductive_operator(holding(t3, us_probe_1), [denied(Denied)]).

test(every_kind_has_a_tool, true(Kinds == [])) :-
    findall(K, ( tools:measurement_kind(K), \+ domain_fact(can_measure(_, K)) ), Kinds).

test(measurement_goal_with_the_chosen_tool,
     true(G-C =@= measured(us_probe_2, A, meas(p7))-[can_measure(us_probe_2, web_thickness), type(A, arm)])) :-
    measurement_goal(p7, web_thickness, us_probe_2, G, C).

test(rib_width_by_either_tool_type, true(Tools == [slra_1, slra_2, us_probe_1, us_probe_2])) :-
    setof(T, domain_fact(can_measure(T, stiffener_width)), Tools).

test(bent_probe_measures_flange_thickness_only,
     true(Kinds == [flange_thickness])) :-
    setof(K, domain_fact(can_measure(us_probe_90, K)), Kinds).

test(bent_probe_passes_the_ultrasonic_operators_type_constraint, nondet) :-
    domain_fact(type(us_probe_90, us_tool)).

test(measurement_goal_with_the_bent_probe,
     true(G =@= measured(us_probe_90, _, meas(w1)))) :-
    measurement_goal(w1, flange_thickness, us_probe_90, G, _).

test(hole_only_by_the_slra, true(Tools == [slra_1, slra_2])) :-
    setof(T, domain_fact(can_measure(T, hole_diameter)), Tools).

test(measurement_goal_unknown_kind, error(domain_error(measurement_kind, color))) :-
    measurement_goal(p7, color, _, _, _).

test(measurement_goal_tool_that_cannot, error(domain_error(tool_for(hole_position), us_probe_1))) :-
    measurement_goal(p7, hole_position, us_probe_1, _, _).

test(constraints_come_from_the_world_model, true(W == 1.5)) :-
    domain_fact(weight(us_probe_1, W)).

test(world_state_has_an_empty_hand_and_tools_in_the_rack,
     true(Facts == [holding(t3, none), location(us_probe_1, in_rack(slot_1))])) :-
    world_state(t3, approach_point(home), S),
    include([F]>>memberchk(F, [holding(t3, none), location(us_probe_1, in_rack(slot_1))]),
            S, Facts).

test(planning_state_facts_are_the_states_facts_of_a_kind,
     true(Facts == Expected)) :-
    planning_state(t3, approach_point(home), us_probe_1, State),
    include([F]>>(F = location(_, _)), State, Expected),
    planning_state_facts(us_probe_1, location(_, _), Facts).

test(planning_state_facts_leave_out_the_held_tool, true(Facts == [])) :-
    planning_state_facts(us_probe_1, location(us_probe_1, _), Facts).

test(planning_state_facts_leave_out_the_arms_own_facts, true(Facts == [])) :-
    planning_state_facts(none, at(_, _), Facts).

test(planning_state_of_an_unknown_tool, error(existence_error(tool, spanner))) :-
    must_be_planning_state(t3, approach_point(home), spanner).

test(criticality_of_measured_above_pose, true(M > P)) :-
    criticality(measured(_, _, _), M),
    criticality(at(_, _), P).

test(a_persons_jobs_go_to_the_persons_stream,
     true(Jobs =@= [ reclamp_part-'CALL'(reclamp_part),
                     remove_obstacles-'CALL'(remove_obstacles),
                     replace_tool-'CALL'(replace_tool(_)),
                     straighten_probe-'CALL'(straighten_probe(_)) ])) :-
    findall(Name-M, ( static_operator(Op, D),
                      memberchk(command_stream(command_stream(person, P)), D),
                      memberchk(unary_constraints(U), D),
                      memberchk(type(P, person), U),
                      arg(1, Op, P),
                      functor(Op, Name, _),
                      memberchk(message_pattern(M), D) ),
            Jobs0),
    msort(Jobs0, Jobs).

test(a_person_is_no_tool_and_no_arm, true(Types == [person])) :-
    findall(T, domain_fact(type(technician, T)), Types).

:- end_tests(operators).
