:- use_module(planner).
:- use_module('../kb/operators').

/*  Tests of the task planner.  Toy domains isolate each property; the inspection domain
    (kb/operators.pl) pins the plans of every measurement kind.  */

% toy(+Operators, +Options, -Domain): compile a small domain.
toy(Operators, Options, Domain) :-
    compile_domain(operators(Operators, [], Options), Domain).

toy_op(Name, Pre, Add, Res, static_operator(Name, [ preconditions(Pre), adders(Add),
                                                    resources(Res) ])).

:- begin_tests(planner_properties).

test(hierarchy_low_criticality_goal_waits,
     true(Actions == [raise_high, raise_low])) :-
    toy_op(raise_low, [], [low], [r1], O1),
    toy_op(raise_high, [], [high], [r2], O2),
    toy([O1, O2], [criticalities([high-5, low-1])], D),
    plan_linear([low, high], [], [domain(D)], Actions).

test(hierarchy_without_weights_keeps_goal_order,
     true(Actions == [raise_low, raise_high])) :-
    toy_op(raise_low, [], [low], [r1], O1),
    toy_op(raise_high, [], [high], [r2], O2),
    toy([O1, O2], [], D),
    plan_linear([low, high], [], [domain(D)], Actions).

test(nonlinear_independent_steps_unordered,
     true(Plan == [step(1, paint(a), []), step(2, paint(b), [])])) :-
    toy_op(paint(X), [], [painted(X)], [X], O),
    toy([O], [], D),
    plan([painted(a), painted(b)], [], [domain(D)], Plan).

test(nonlinear_shared_resource_orders_steps,
     true(Plan == [step(1, paint(a), []), step(2, paint(b), [1])])) :-
    toy_op(paint(X), [], [painted(X)], [brush], O),
    toy([O], [], D),
    plan([painted(a), painted(b)], [], [domain(D)], Plan).

test(nonlinear_producer_orders_consumer,
     true(Plan == [step(1, prime(a), []), step(2, paint(a), [1])])) :-
    toy_op(prime(X), [], [primed(X)], [X], O1),
    toy_op(paint(X), [primed(X)], [painted(X)], [X-paint], O2),
    toy([O1, O2], [], D),
    plan([painted(a)], [], [domain(D)], Plan).

test(serendipity_goal_achieved_on_the_way_is_dropped,
     true(Actions == [both])) :-
    toy_op(both, [], [g1, g2], [r], O1),
    toy_op(only_g2, [], [g2], [r], O2),
    toy([O2, O1], [criticalities([g1-2, g2-1])], D),
    plan_linear([g1, g2], [], [domain(D)], Actions).

test(serendipity_goal_true_initially_needs_no_step,
     true(Plan == [])) :-
    toy_op(make_g, [], [g], [r], O),
    toy([O], [], D),
    plan([g], [g], [domain(D)], Plan).

test(deductive_operator_denies_rack_location_and_empty_hand,
     true(State == Expected)) :-
    sort([ at(t3, approach_point(rack(slot_1))), holding(t3, us_probe_1),
           slot_free(slot_1), tool_condition(us_probe_1, ok) ], Expected),
    compile_domain(module(operators), D),
    apply_action(D, pick_up(t3, us_probe_1, slot_1),
                 [ at(t3, approach_point(rack(slot_1))), holding(t3, none),
                   location(us_probe_1, in_rack(slot_1)), tool_condition(us_probe_1, ok) ],
                 State).

test(deductive_operator_keeps_one_pose,
     true(State == [at(t3, approach_point(meas(b)))])) :-
    compile_domain(module(operators), D),
    apply_action(D, move(t3, meas(a), meas(b)), [at(t3, approach_point(meas(a)))], State).

test(unary_constraints_generate_and_n_ary_constraints_test,
     true(Arm == strong)) :-
    Lift = static_operator(lift(Arm0, Obj),
                           [ preconditions([]), adders([lifted(Obj, Arm0)]),
                             unary_constraints([type(Arm0, arm)]),
                             n_ary_constraints([can_lift(Arm0, W1), weight(Obj, W2), W2 =< W1]),
                             resources([Arm0]) ]),
    toy([Lift], [facts([ type(weak, arm), type(strong, arm), type(box, box),
                         can_lift(weak, 5), can_lift(strong, 50), weight(box, 20) ])], D),
    plan([lifted(box, Arm)], [], [domain(D)], _).

test(n_ary_constraint_failure_means_no_plan,
     true(R = no_plan(search_exhausted(_)))) :-
    Lift = static_operator(lift(Arm0, Obj),
                           [ preconditions([]), adders([lifted(Obj, Arm0)]),
                             unary_constraints([type(Arm0, arm)]),
                             n_ary_constraints([can_lift(Arm0, W1), weight(Obj, W2), W2 =< W1]) ]),
    toy([Lift], [facts([type(weak, arm), can_lift(weak, 5), weight(box, 20)])], D),
    plan_result([lifted(box, _)], [], [domain(D)], R).

test(backtracks_after_dead_end,
     true(Actions == [make_y, make_z, slow_way])) :-
    toy_op(quick_way, [x], [g], [r], O1),        % looks best: one missing precondition
    toy_op(make_x, [unobtainable], [x], [r], O2), % but x needs what nothing makes
    toy_op(slow_way, [y, z], [g], [r], O3),
    toy_op(make_y, [], [y], [r], O4),
    toy_op(make_z, [], [z], [r], O5),
    toy([O1, O2, O3, O4, O5], [], D),
    plan_linear([g], [], [domain(D)], Actions).

test(effort_bound_gives_reason,
     true(R == no_plan(effort_exhausted(5, 5)))) :-
    toy_op(step(N), [p(s(N))], [p(N)], [r], O),   % p(0) needs p(1) needs p(2) ...
    toy([O], [], D),
    plan_result([p(0)], [], [domain(D), max_effort(5), max_depth(1000)], R).

test(no_operator_reason, true(R == no_plan(no_operator(fly)))) :-
    plan_result([fly], [], [], R).

test(bad_state_is_an_error, error(instantiation_error)) :-
    plan([g], [_], [], _).

test(bad_goals_are_an_error, error(type_error(list, g))) :-
    plan(g, [], [], _).

test(bad_domain_spec_is_an_error, error(domain_error(operator_spec, nonsense))) :-
    plan([g], [], [domain(nonsense)], _).

:- end_tests(planner_properties).


% Regression: the plans of every measurement kind, with and without a tool in hand.

in_hand(Tool, [ at(t3, in_contact_point(meas(a))), holding(t3, Tool)
              | Rack ]) :-
    rack_without(Tool, Rack).

empty_hand([ at(t3, approach_point(home)), holding(t3, none) | Rack ]) :-
    rack_without(none, Rack).

rack_without(Tool, Facts) :-
    findall(F, rack_fact(Tool, F), Facts).

rack_fact(Tool, location(T, in_rack(S))) :-
    home(T, S), T \== Tool.
rack_fact(Tool, slot_free(S)) :-
    home(Tool, S).
rack_fact(_, tool_condition(T, ok)) :-
    home(T, _).

home(us_probe_1, slot_1).
home(us_probe_2, slot_2).
home(slra_1, slot_3).
home(slra_2, slot_4).

kind_plan(Kind, State, Actions) :-
    kind_tool(Kind, Tool),
    measurement_goal(b, Kind, Tool, Goal, Constraints),
    plan_linear([Goal], State, [constraints(Constraints)], Actions).

us_in_hand([ move_retract(t3, a), move(t3, meas(a), meas(b)), apply_couplant(t3, b),
             move_contact(t3, b), us_measure(us_probe_1, t3, b) ]).
us_from_rack([ move(t3, home, rack(slot_1)), pick_up(t3, us_probe_1, slot_1),
               move(t3, rack(slot_1), meas(b)), apply_couplant(t3, b),
               move_contact(t3, b), us_measure(us_probe_1, t3, b) ]).
slra_in_hand([ move_retract(t3, a), move(t3, meas(a), meas(b)), move_view(t3, b),
               slra_scan(slra_1, t3, b), slra_measure(slra_1, t3, b) ]).
slra_from_rack([ move(t3, home, rack(slot_3)), pick_up(t3, slra_1, slot_3),
                 move(t3, rack(slot_3), meas(b)), move_view(t3, b),
                 slra_scan(slra_1, t3, b), slra_measure(slra_1, t3, b) ]).
slra_after_us([ move_retract(t3, a), move(t3, meas(a), rack(slot_1)),
                put_down(t3, us_probe_1, slot_1), move(t3, rack(slot_1), rack(slot_3)),
                pick_up(t3, slra_1, slot_3), move(t3, rack(slot_3), meas(b)),
                move_view(t3, b), slra_scan(slra_1, t3, b), slra_measure(slra_1, t3, b) ]).

kind_tool(Kind, us_probe_1) :- us_kind(Kind), !.
kind_tool(Kind, slra_1) :- slra_kind(Kind).

us_kind(web_thickness).
us_kind(flange_thickness).

slra_kind(hole_diameter).
slra_kind(hole_position).
slra_kind(flange_height).
slra_kind(flange_width).
slra_kind(stiffener_height).
slra_kind(stiffener_width).
slra_kind(edge_distance).

:- begin_tests(measurement_plans).

test(us_kinds_probe_in_hand, [forall(us_kind(K)), true(A == Expected)]) :-
    us_in_hand(Expected), in_hand(us_probe_1, S), kind_plan(K, S, A).

test(us_kinds_empty_hand, [forall(us_kind(K)), true(A == Expected)]) :-
    us_from_rack(Expected), empty_hand(S), kind_plan(K, S, A).

test(slra_kinds_slra_in_hand, [forall(slra_kind(K)), true(A == Expected)]) :-
    slra_in_hand(Expected), in_hand(slra_1, S0),
    selectchk(at(t3, in_contact_point(meas(a))), S0, S1),
    kind_plan(K, [at(t3, in_contact_point(meas(a)))|S1], A).

test(slra_kinds_empty_hand, [forall(slra_kind(K)), true(A == Expected)]) :-
    slra_from_rack(Expected), empty_hand(S), kind_plan(K, S, A).

test(slra_kinds_with_probe_in_hand_change_tools, [forall(slra_kind(K)), true(A == Expected)]) :-
    slra_after_us(Expected), in_hand(us_probe_1, S), kind_plan(K, S, A).

test(broken_probe_replaced_by_spare, true(Tool == us_probe_2)) :-
    empty_hand(S0),
    selectchk(tool_condition(us_probe_1, ok), S0, S),
    measurement_goal(b, web_thickness, _, Goal, Constraints),
    plan([Goal], S, [constraints(Constraints)], _),
    Goal = measured(Tool, _, _).

test(rib_width_with_the_probe_it_is_given, true(A == Expected)) :-
    us_from_rack(Expected), empty_hand(S),
    measurement_goal(b, stiffener_width, us_probe_1, Goal, Constraints),
    plan_linear([Goal], S, [constraints(Constraints)], A).

test(slra_measure_leaves_arm_free_for_next_scan,
     true(Plan == [ step(1, move_view(t3, b), []),
                    step(2, slra_scan(slra_1, t3, b), [1]),
                    step(3, slra_measure(slra_1, t3, b), [2]),
                    step(4, leave_view(t3, b), [2]),
                    step(5, move(t3, meas(b), meas(c)), [4]),
                    step(6, move_view(t3, c), [5]),
                    step(7, slra_scan(slra_1, t3, c), [6]),
                    step(8, slra_measure(slra_1, t3, c), [3, 7]) ])) :-
    plan([measured(slra_1, t3, meas(b)), measured(slra_1, t3, meas(c))],
         [at(t3, approach_point(meas(b))), holding(t3, slra_1)], [], Plan).

test(calibration_and_couplant_refill,
     true(A == [ move(t3, meas(a), couplant_station), refill_couplant(t3),
                 move(t3, couplant_station, cal_block),
                 us_check_calibration(us_probe_1, t3) ])) :-
    plan_linear([couplant_refilled(couplant_station), calibrated(us_probe_1)],
                [at(t3, approach_point(meas(a))), holding(t3, us_probe_1)], [], A).

:- end_tests(measurement_plans).
