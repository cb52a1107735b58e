:- use_module(macrop_generalize).
:- use_module(planner).
:- use_module('../kb/macrops', []).

/*  Tests of plan generalization: the seed's Figure 4 from its plan.  */

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

slra_state([ at(t3, approach_point(home)), holding(t3, none),
             location(slra_1, in_rack(slot_3)), tool_condition(slra_1, ok) ]).

:- begin_tests(generalization).

test(figure_4_reproduced, true(same_macrop(Macrop, Figure4))) :-
    figure_4_problem(Goals, State),
    plan(Goals, State, [], Plan),
    generalize_plan(Goals, State, Plan, [], Macrop),
    figure_4(Figure4).

test(figure_4_plan_has_five_steps_in_a_chain,
     true(Preds == [[], [1], [2], [3], [4]])) :-
    figure_4_problem(Goals, State),
    plan(Goals, State, [], Plan),
    generalize_plan(Goals, State, Plan, [], macrop(_, Fields)),
    memberchk(plan(Steps), Fields),
    findall(P, member(step(_, _, P), Steps), Preds).

test(hand_written_macrop_is_figure_4, true(same_macrop(macrop(N, F), Figure4))) :-
    macrops:macrop(N, F),
    figure_4(Figure4).

test(shared_objects_become_one_variable, true(T1-T2 == T3-T3)) :-
    slra_state(State),
    Goals = [measured(slra_1, t3, meas(c))],
    plan(Goals, State, [], Plan),
    generalize_plan(Goals, State, Plan, [], macrop(_, Fields)),
    memberchk(plan(Steps), Fields),
    memberchk(step(_, pick_up(_, T1, _), _), Steps),
    memberchk(step(_, slra_scan(T2, _, _), _), Steps),
    memberchk(step(_, slra_measure(T3, _, _), _), Steps).

test(empty_plan_is_an_error, error(domain_error(non_empty_plan, []))) :-
    generalize_plan([g], [g], [], [], _).

test(wrong_plan_is_an_error, error(domain_error(plan_for_goals, _))) :-
    generalize_plan([measured(us_probe_1, t3, meas(z))],
                    [at(t3, in_contact_point(meas(a))), holding(t3, us_probe_1)],
                    [step(1, move_retract(t3, a), [])], [], _).

:- end_tests(generalization).
